#!/usr/bin/env bash
# Hostile cutouts and point clouds at the driver level, on 2 ranks: each case must exit with
# status 2, print one message naming the scene file's (or the point file's) line, the key and what
# was expected, and leave no output directory behind. One good point cloud, named relative to its
# scene file from another working directory, is read with all its rows, and as HDF5 (.h5: datasets
# x, y, z, volume, material as fixed or variable-length strings) gives the same nodes and bonds.
# usage: bad_input_geometry.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work" || exit 1
mkdir run  # the working directory of every run: not the scenes' folder
pass=0 fail=0

source "$(dirname "$0")/expect.sh"
expect_dir=run
line_of() { grep -n -m1 -F -- "$2" "$1" | cut -d: -f1; }

# plate NAME CUTOUT_LINES...: a 10 mm plate (40 x 40 nodes) with the given cutouts; prints its path.
plate() {
  local f="$work/$1.yaml"
  shift
  cat > "$f" <<'EOF'
name: plate
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000}
bodies:
  plate:
    kind: membrane
    material: rubber
    origin: [0, 0, 0]
    size: [0.01, 0.01]
    thickness: 0.0005
    spacing: 0.00025
    cutouts:
EOF
  for c in "$@"; do echo "      - $c" >> "$f"; done
  cat >> "$f" <<'EOF'
stages:
  - {name: still, steps: 2}
output: {frames: 1}
EOF
  echo "$f"
}

# Cutouts.
f=$(plate outside '{kind: circle, center: [0.005, 0.005], radius: 0.002}' '{kind: circle, center: [0.02, 0.005], radius: 0.002}')
expect cutout_outside "$f:$(line_of "$f" 'center: [0.02'): bodies.plate.cutouts.1: the circle cutout removes no node of body 'plate'" -- "$f"
f=$(plate between '{kind: box, min: [0.001, 0.001, -1], max: [0.0011, 0.0011, 1]}')
expect cutout_between_nodes "$f:$(line_of "$f" 'kind: box'): bodies.plate.cutouts.0: the box cutout removes no node" -- "$f"
f=$(plate everything '{kind: box, min: [-1, -1, -1], max: [1, 0.006, 1]}' '{kind: polygon, vertices: [[-1, 0.004], [1, 0.004], [0, 1]]}')
expect cutout_all_nodes "$f:$(line_of "$f" 'kind: membrane'): bodies.plate.cutouts: the cutouts remove all 1600 nodes of body 'plate'; expected at least one node left" -- "$f"
f=$(plate two_corners '{kind: polygon, vertices: [[0, 0], [0.005, 0.005]]}')
expect polygon_two_corners "$f:$(line_of "$f" 'vertices'): bodies.plate.cutouts.0.vertices: expected a list of at least 3 corners [[x, y], ...] [m]" -- "$f"
f=$(plate flat_polygon '{kind: polygon, vertices: [[0, 0], [0.005, 0.005], [0.01, 0.01]]}')
expect polygon_no_area "bodies.plate.cutouts.0.vertices: expected a polygon that encloses an area" -- "$f"
f=$(plate no_radius '{kind: circle, center: [0.005, 0.005]}')
expect circle_no_radius "$f:$(line_of "$f" 'kind: circle'): bodies.plate.cutouts.0: missing required key 'radius' (radius, m)" -- "$f"
f=$(plate bad_radius '{kind: circle, center: [0.005, 0.005], radius: -0.001}')
expect circle_bad_radius "bodies.plate.cutouts.0.radius: expected a positive number [m], got -0.001" -- "$f"
f=$(plate hexagon '{kind: hexagon, center: [0.005, 0.005], radius: 0.001}')
expect cutout_unknown_shape "$f:$(line_of "$f" 'hexagon'): bodies.plate.cutouts.0.kind: expected one of: circle, box, polygon, sphere, cylinder; got hexagon" -- "$f"
f=$(plate depth '{kind: circle, center: [0.005, 0.005], radius: 0.001, depth: 1}')
expect cutout_unknown_key "$f:$(line_of "$f" 'depth'): bodies.plate.cutouts.0.depth: unknown key; expected one of: kind, center, radius" -- "$f"
f=$(plate circle_min '{kind: circle, center: [0.005, 0.005], radius: 0.001, min: [0, 0, 0]}')
expect cutout_other_shape_key "bodies.plate.cutouts.0.min: not used by a circle cutout; expected one of: kind, center, radius" -- "$f"
f=$(plate sphere_sheet '{kind: sphere, center: [0.005, 0.005, 0], radius: 0.001}')
expect sphere_on_sheet "bodies.plate.cutouts.0.kind: a sphere cutout cuts solids; a sheet takes circle, box or polygon cutouts" -- "$f"
f=$(plate box_order '{kind: box, min: [0.004, 0.004, -1], max: [0.003, 0.006, 1]}')
expect box_min_max "bodies.plate.cutouts.0.max: expected min <= max in every component, got x: min 0.004 > max 0.003" -- "$f"
f=$(plate not_list)
sed -i 's/^    cutouts:$/    cutouts: {kind: circle}/' "$f"
expect cutouts_not_a_list "bodies.plate.cutouts: expected a list of cutouts" -- "$f"
expect override_cutout "--set: bodies.plate.cutouts.0.radius: expected a positive number [m], got 0" -- \
  "$(plate override '{kind: circle, center: [0.005, 0.005], radius: 0.001}')" --set bodies.plate.cutouts.0.radius=0
fiber=$src/drivers/scenes/fiber_long_range.yaml
expect cutout_on_fiber "bodies.fiber.cutouts: not used by a fiber body" -- "$fiber" \
  --set 'bodies.fiber.cutouts=[{kind: circle, center: [0, 0], radius: 1e-9}]'

# A crossing polygon whose two lobes' signed areas cancel (a bow-tie) encloses them by the
# even-odd rule: read, not refused as "corners on one line" (48 nodes inside, counted apart).
f=$(plate bow_tie '{kind: polygon, vertices: [[0, 0], [0.0031, 0], [0, 0.0021], [0.0031, 0.0021]]}')
if "${mpi[@]}" "$peridrive" "$f" --dry-run > "$work/stdout" 2> "$work/stderr" && grep -qx "plate.nodes = 1552" "$work/stdout"; then
  echo "ok   bow_tie_cutout: 1552 of 1600 nodes kept"; pass=$((pass + 1))
else
  echo "FAIL bow_tie_cutout: expected 1552 nodes kept"; cat "$work/stderr"; grep "plate.nodes" "$work/stdout"; fail=$((fail + 1))
fi

# Cutouts that cut a node off from the rest by more than the horizon: warned of (how many, where
# the first is), the run not refused.
f=$(plate lone_corner '{kind: box, min: [0.0002, -1, -1], max: [0.005, 1, 1]}' '{kind: box, min: [-1, 0.0002, -1], max: [0.0002, 1, 1]}')
if "${mpi[@]}" "$peridrive" "$f" --dry-run > "$work/stdout" 2> "$work/stderr" &&
   grep -qF "peridrive: warning: $f:$(line_of "$f" 'kind: membrane'): bodies.plate: 1 of its 801 nodes have no bond (the first at (0.000125, 0.000125, 0))" "$work/stderr" &&
   [ "$(grep -c 'have no bond' "$work/stderr")" -eq 1 ]; then
  echo "ok   lone_node_warned: $(grep 'have no bond' "$work/stderr" | cut -c1-160)"; pass=$((pass + 1))
else
  echo "FAIL lone_node_warned: expected one warning naming 1 of 801 nodes"; cat "$work/stderr"; fail=$((fail + 1))
fi

# Point clouds: a block scene beside a data folder.
mkdir -p "$work/data"
block() {  # block NAME CSV_TEXT [extra body keys]: prints the scene's path
  printf '%b' "$2" > "$work/data/$1.csv"
  local f="$work/$1.yaml"
  cat > "$f" <<EOF
name: cloud
materials:
  glass: {model: pmb, density: 2200, micromodulus: 1.0e19}
bodies:
  block: {kind: solid, material: glass, points: data/$1.csv, spacing: 0.001${3:-}}
stages:
  - {name: still, steps: 2}
output: {frames: 1}
EOF
  echo "$f"
}
good='x,y,z,volume\n0.0005,0.0005,0.0005,1e-9\n0.0015,0.0005,0.0005,1e-9\n0.0005,0.0015,0.0005,1e-9\n0.0015,0.0015,0.0005,1e-9\n'
f=$(block good "# a 2 x 2 x 1 block\n$good")
(cd run && "${mpi[@]}" "$peridrive" "$f" --dry-run > "$work/stdout" 2> "$work/stderr")
if [ $? -eq 0 ] && grep -q "^estimate: 4 nodes" "$work/stdout"; then
  echo "ok   good_cloud: $(grep '^estimate' "$work/stdout")"; pass=$((pass + 1))
else
  echo "FAIL good_cloud: expected 4 nodes read"; cat "$work/stdout" "$work/stderr"; fail=$((fail + 1))
fi
f=$(block missing "$good")
rm "$work/data/missing.csv"
expect cloud_missing_file "$f:$(line_of "$f" 'points'): bodies.block.points: cannot read the point cloud '$work/data/missing.csv': No such file or directory" -- "$f"
f=$(block bad_number 'x,y,z,volume\n0,0,0,1e-9\n0.001,abc,0,1e-9\n')
expect cloud_bad_number "$work/data/bad_number.csv:3: bodies.block.points: column y: expected a number, got 'abc'" -- "$f"
f=$(block infinite 'x,y,z,volume\n0,0,0,1e-9\n0.001,0,inf,1e-9\n')
expect cloud_infinite "$work/data/infinite.csv:3: bodies.block.points: column z: expected a finite number, got 'inf'" -- "$f"
f=$(block zero_volume 'x,y,z,volume\n0,0,0,1e-9\n\n0.001,0,0,0\n')
expect cloud_zero_volume "$work/data/zero_volume.csv:4: bodies.block.points: column volume: expected a positive volume [m^3], got '0'" -- "$f"
f=$(block negative_volume 'x,y,z,volume\n0,0,0,-1e-9\n')
expect cloud_negative_volume "$work/data/negative_volume.csv:2: bodies.block.points: column volume: expected a positive volume [m^3], got '-1e-9'" -- "$f"
f=$(block duplicate 'x,y,z,volume\n0,0,0,1e-9\n0.001,0,0,1e-9\n0.002,0,0,1e-9\n0.001,0,0,2e-9\n')
expect cloud_duplicate "$work/data/duplicate.csv:5: bodies.block.points: duplicate point (0.001, 0, 0), the same as line 3" -- "$f"
# Within 1e-8 of the points' size (1e-3 m here): one point given twice with round-off.
f=$(block near_twin 'x,y,z,volume\n0,0,0,1e-9\n0.001,0,0,1e-9\n0.002,0,0,1e-9\n0.001,0,1e-15,1e-9\n')
expect cloud_near_twin "$work/data/near_twin.csv:5: bodies.block.points: point (0.001, 0, 1e-15) within 1e-11 m of line 3 (1e-8 of the points' size, the cube root of their median volume); expected each point once" -- "$f"
# A volume beyond the horizon's ball (4/3 pi (3 mm)^3 = 1.13e-7 m^3): one stray value (it was
# named as a twin, with the median volume's tolerance grown to 1e92 m), and every volume in mm^3.
f=$(block stray_volume 'x,y,z,volume\n0,0,0,1e-9\n0.001,0,0,1e300\n')
expect cloud_volume_beyond_ball "$work/data/stray_volume.csv:3: bodies.block.points: column volume: 1e300 m^3 is more than the ball of the horizon (4/3 pi delta^3 = 1.13e-07 m^3, delta = 0.003 m); expected a point's own volume, about spacing^3 (1e-9 m^3) for points a spacing apart" -- "$f"
f=$(block volume_in_mm3 'x,y,z,volume\n0,0,0,1\n0.001,0,0,1\n0.002,0,0,1\n')
expect cloud_volume_units "$work/data/volume_in_mm3.csv:2: bodies.block.points: column volume: 1 m^3 is more than the ball of the horizon" -- "$f"
# A body none of whose nodes has a bond (points 10 mm apart, the horizon 3 mm), beside a body
# with bonds: refused, naming it (it ran before, its nodes loose).
f=$(block sparse 'x,y,z,volume\n0,0,0,1e-9\n0.01,0,0,1e-9\n0.02,0,0,1e-9\n0.03,0,0,1e-9\n')
sed -i 's|^bodies:$|bodies:\n  plate: {kind: solid, material: glass, origin: [0.1, 0, 0], size: [0.002, 0.002, 0.002], spacing: 0.0005}|' "$f"
expect body_without_bonds "$f:$(line_of "$f" 'block:'): bodies.block: none of its 4 nodes has a bond: its horizon 0.003 m reaches no other node" -- "$f"
f=$(block columns 'x,y,z,volume\n0,0,0,1e-9\n0.001,0,0\n')
expect cloud_column_count "$work/data/columns.csv:3: bodies.block.points: expected 4 columns (x,y,z,volume), got 3" -- "$f"
f=$(block header 'x,y,volume\n0,0,1e-9\n')
expect cloud_header "$work/data/header.csv:1: bodies.block.points: expected the header x,y,z,volume or x,y,z,volume,material, got 'x,y,volume'" -- "$f"
f=$(block empty 'x,y,z,volume\n')
expect cloud_no_points "$work/data/empty.csv:1: bodies.block.points: the point cloud has no points after its header" -- "$f"
f=$(block other_material 'x,y,z,volume,material\n0,0,0,1e-9,glass\n0.001,0,0,1e-9,steel\n')
expect cloud_unclaimed_material "$work/data/other_material.csv:3: bodies.block.points: material 'steel' is no body's" -- "$f"
# The same file under another name (a link): its steel rows are the second body's, not refused.
f=$(block two_materials 'x,y,z,volume,material\n0,0,0,1e-9,glass\n0.001,0,0,1e-9,glass\n0.01,0,0,1e-9,steel\n0.011,0,0,1e-9,steel\n')
ln -s two_materials.csv "$work/data/linked.csv"
sed -i 's|^bodies:$|bodies:\n  bolt: {kind: solid, material: steel, points: data/linked.csv, spacing: 0.001}|; s|^materials:$|materials:\n  steel: {model: pmb, density: 7800, micromodulus: 1.0e19}|' "$f"
if "${mpi[@]}" "$peridrive" "$f" --dry-run > "$work/stdout" 2> "$work/stderr" && grep -qx "bolt.nodes = 2" "$work/stdout" &&
   grep -qx "block.nodes = 2" "$work/stdout"; then
  echo "ok   cloud_file_linked: two rows each for block (glass) and bolt (steel, through a link)"; pass=$((pass + 1))
else
  echo "FAIL cloud_file_linked"; cat "$work/stderr"; fail=$((fail + 1))
fi
# The same cloud as HDF5 (.h5): datasets x, y, z, volume and optionally material, written here by
# h5py (SPEC: a Python expression of the dataset dict, from the good points P and volumes V).
h5block() {  # h5block NAME SPEC: prints the scene's path
  /usr/bin/python3 - "$work/data/$1.h5" "$2" <<'PY'
import sys
import h5py
import numpy as np
P = np.array([[0.0005, 0.0005, 0.0005], [0.0015, 0.0005, 0.0005], [0.0005, 0.0015, 0.0005], [0.0015, 0.0015, 0.0005]])
V = np.full(4, 1e-9)
vlen = h5py.string_dtype()
spec = eval(sys.argv[2])
with h5py.File(sys.argv[1], "w") as f:
    for name, data in spec.items():
        f[name] = data
PY
  local f="$work/$1.yaml"
  sed "s|data/good.csv|data/$1.h5|" "$work/good.yaml" > "$f"
  echo "$f"
}
xyz='"x": P[:, 0], "y": P[:, 1], "z": P[:, 2]'
(cd run && "${mpi[@]}" "$peridrive" "$work/good.yaml" --dry-run > "$work/csv.out" 2> /dev/null)
for case in good:"{$xyz, 'volume': V}" fixed_material:"{$xyz, 'volume': V, 'material': np.array([b'glass'] * 4, dtype='S8')}" \
            vlen_material:"{$xyz, 'volume': V.astype(np.float32), 'material': np.array(['glass'] * 4, dtype=object).astype(vlen)}"; do
  name=h5_${case%%:*}
  f=$(h5block "$name" "${case#*:}")
  (cd run && "${mpi[@]}" "$peridrive" "$f" --dry-run > "$work/stdout" 2> "$work/stderr")
  if [ $? -eq 0 ] && grep -q "^estimate: 4 nodes" "$work/stdout" && \
     [ "$(grep '^ordered_bonds' "$work/stdout")" = "$(grep '^ordered_bonds' "$work/csv.out")" ]; then
    echo "ok   $name: 4 nodes, $(grep '^ordered_bonds' "$work/stdout"), as the CSV cloud"; pass=$((pass + 1))
  else
    echo "FAIL $name: expected the CSV cloud's 4 nodes and bonds"; cat "$work/stdout" "$work/stderr"; fail=$((fail + 1))
  fi
done
f=$(h5block unclaimed "{$xyz, 'volume': V, 'material': np.array(['glass', 'steel', 'glass', 'glass'], dtype=object).astype(vlen)}")
expect h5_unclaimed_material "$work/data/unclaimed.h5: point 1: bodies.block.points: material 'steel' is no body's" -- "$f"
f=$(h5block no_volume "{$xyz}")
expect h5_missing_dataset "$work/data/no_volume.h5: bodies.block.points: no dataset 'volume'; expected the 1D datasets x, y, z, volume" -- "$f"
f=$(h5block short "{$xyz, 'volume': V[:3]}")
expect h5_lengths "$work/data/short.h5: bodies.block.points: dataset 'volume' has 3 values, 'x' 4; expected one length" -- "$f"
f=$(h5block matrix "{'x': P, 'y': P[:, 1], 'z': P[:, 2], 'volume': V}")
expect h5_not_1d "$work/data/matrix.h5: bodies.block.points: dataset 'x': expected a 1D dataset, one value a point" -- "$f"
f=$(h5block nan "{'x': P[:, 0], 'y': np.where(np.arange(4) == 2, np.nan, P[:, 1]), 'z': P[:, 2], 'volume': V}")
expect h5_not_finite "$work/data/nan.h5: point 2: bodies.block.points: dataset y: expected a finite number" -- "$f"
f=$(h5block zero "{$xyz, 'volume': np.where(np.arange(4) == 3, 0.0, V)}")
expect h5_zero_volume "$work/data/zero.h5: point 3: bodies.block.points: dataset volume: expected a positive volume [m^3], got 0" -- "$f"
f=$(h5block big "{$xyz, 'volume': np.where(np.arange(4) == 2, 1e-6, V)}")
expect h5_volume_beyond_ball "$work/data/big.h5: point 2: bodies.block.points: dataset volume: 1e-6 m^3 is more than the ball of the horizon" -- "$f"
f=$(h5block twice "{'x': P[[0, 1, 2, 1], 0], 'y': P[[0, 1, 2, 1], 1], 'z': P[[0, 1, 2, 1], 2], 'volume': V}")
expect h5_duplicate "$work/data/twice.h5: point 3: bodies.block.points: duplicate point (0.0015, 0.0005, 0.0005), the same as point 1; expected each point once" -- "$f"
f=$(h5block text_name "{$xyz, 'volume': V, 'material': np.array([b'glass', b'a b', b'glass', b'glass'])}")
expect h5_bad_material_name "$work/data/text_name.h5: point 1: bodies.block.points: dataset material: expected a material name" -- "$f"
f=$(h5block strings "{'x': np.array([b'a'] * 4), 'y': P[:, 1], 'z': P[:, 2], 'volume': V}")
expect h5_not_numbers "$work/data/strings.h5: bodies.block.points: dataset 'x': expected numbers" -- "$f"
f=$(h5block not_hdf5 "{}")
printf 'x,y,z,volume\n0,0,0,1e-9\n' > "$work/data/not_hdf5.h5"
expect h5_not_hdf5 "bodies.block.points: cannot read the point cloud '$work/data/not_hdf5.h5': not an HDF5 file" -- "$f"
f=$(block with_origin "$good" ', origin: [0, 0, 0]')
expect cloud_with_origin "bodies.block.origin: not with points" -- "$f"
f=$(block cloud_cut "$good" ', cutouts: [{kind: sphere, center: [0.1, 0.1, 0.1], radius: 0.001}]')
expect cloud_cutout_outside "bodies.block.cutouts.0: the sphere cutout removes no node of body 'block'" -- "$f"

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

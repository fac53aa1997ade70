#!/usr/bin/env bash
# frames.xdmf through a real reader (meshio's XDMF time-series reader, as ParaView's Xdmf3 readers
# it builds cells from the topology's connectivity), for 2-rank runs of a small membrane (velocity
# written; also with 400 frames, past those after which the XDMF is rewritten every time), a small
# PMB block (velocity not written) and a frames.h5 of the layout before
# /mesh/connectivity existed, continued by --resume (tests/restart/old_layout/): per run the
# number of points and of vertex cells (0..N-1), every step's arrays by name and size, the time
# values (those of frames.h5 exactly, those of series.csv at the same steps to its 12 digits),
# and positions and arrays equal to the HDF5 datasets, bit for bit.
# usage: xdmf_readers.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
py=/usr/bin/python3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pass=0 fail=0

cat > "$work/block.yaml" <<'YAML'
name: block
materials:
  glass: {model: pmb, density: 2500, youngs_modulus: 7.0e10, critical_stretch: 0.001}
bodies:
  block: {kind: solid, material: glass, origin: [0, 0, 0], size: [0.004, 0.003, 0.002], spacing: 0.0005}
initial: {velocity_gradient: [[2000, 0, 0], [0, 0, 0], [0, 0, 0]]}
stages:
  - {name: pull, steps: 30}
output: {frames: 5, series_every: 1, velocity: false}
YAML

# check.py DIR ARRAYS...: what meshio reads from DIR/frames.xdmf against DIR/frames.h5 and series.csv.
cat > "$work/check.py" <<'PY'
import csv, sys
import xml.etree.ElementTree as ET
import h5py, meshio, numpy as np
d, arrays = sys.argv[1], set(sys.argv[2:])
problems = []
with h5py.File(f"{d}/frames.h5", "r") as f, meshio.xdmf.TimeSeriesReader(f"{d}/frames.xdmf") as r:
    n = int(f.attrs.get("frame_nodes", f.attrs["nodes"]))  # (frame_nodes: a node selection)
    names = sorted(f["frames"])
    geometry = lambda name: f"/frames/{name}/position" if "position" in f[f"frames/{name}"] else "/mesh/reference_position"
    points, cells = r.read_points_cells()
    if points.shape != (n, 3) or not np.array_equal(points, f[geometry(names[0])][...]):
        problems.append(f"points {points.shape}, expected the {n} positions of the first frame")
    if len(cells) != 1 or cells[0].type != "vertex" or not np.array_equal(cells[0].data.ravel(), np.arange(n)):
        problems.append(f"cells {cells}, expected {n} vertex cells 0..{n - 1}")
    if r.num_steps != len(names):
        problems.append(f"{r.num_steps} steps, frames.h5 holds {len(names)}")
    grids = ET.parse(f"{d}/frames.xdmf").getroot().find("Domain/Grid").findall("Grid")
    series = {int(row["step"]): float(row["time"]) for row in csv.DictReader(open(f"{d}/series.csv"))}
    matched = 0
    for k, name in enumerate(names[:r.num_steps]):
        g = f[f"frames/{name}"]
        t, point_data, _ = r.read_data(k)
        if t != float(g.attrs["time"]):
            problems.append(f"step {k}: time {t!r}, frames.h5 {float(g.attrs['time'])!r}")
        step = int(g.attrs["step"])
        if step in series:
            matched += 1
            if abs(t - series[step]) > 1e-11 * abs(t):
                problems.append(f"step {k}: time {t!r}, series.csv {series[step]!r} at step {step}")
        if set(point_data) != arrays:
            problems.append(f"step {k}: arrays {sorted(point_data)}, expected {sorted(arrays)}")
        for a, v in point_data.items():
            ref = f["mesh/body"][...] if a == "body" else g[a][...] if a in g else None
            if ref is None or v.shape != ((n, 3) if a in ("displacement", "velocity") else (n,)) \
                    or not np.array_equal(v, ref):
                problems.append(f"step {k}: {a} {v.shape} differs from frames.h5")
        # The geometry of every step (meshio reads only the first): this frame's positions.
        geo = grids[k].find("Geometry/DataItem")
        h5name, path = geo.text.strip().split(":")
        if h5name != "frames.h5" or geo.get("Dimensions") != f"{n} 3" or path != geometry(name):
            problems.append(f"step {k}: geometry {geo.text.strip()} ({geo.get('Dimensions')})")
    if matched < 2:
        problems.append(f"only {matched} frame steps found in series.csv")
print("; ".join(problems) or f"{n} points, {n} vertex cells, {r.num_steps} steps of {len(arrays)} arrays, "
      f"{matched} times checked against series.csv")
sys.exit(1 if problems else 0)
PY

# run NAME ARRAYS -- peridrive arguments
run() {
  local name=$1 arrays=$2
  shift 3
  if ! "${mpi[@]}" "$peridrive" "$@" --out "$work/$name" --quiet > "$work/stdout" 2> "$work/stderr"; then
    echo "FAIL $name: $(head -c 300 "$work/stderr")"; fail=$((fail + 1)); return
  fi
  check "$name" "$arrays"
}
check() {
  local msg
  # shellcheck disable=SC2086
  if msg=$("$py" "$work/check.py" "$work/$1" $2 2>&1); then
    echo "ok   $1: $msg"; pass=$((pass + 1))
  else
    echo "FAIL $1: $msg"; fail=$((fail + 1))
  fi
}

all="displacement velocity damage strain_energy_density body"
run membrane "$all" -- "$src/tests/restart/tiny_sheet.yaml" --set output.frames=6 --set output.series_every=1
run block "displacement damage strain_energy_density body" -- "$work/block.yaml"
# More frames than the XDMF is rewritten after every one of (256): the frames after those are
# listed by a rewrite at most once a second and, at the end, by the writer's last rewrite.
run many_frames "$all" -- "$src/tests/restart/tiny_sheet.yaml" --set stages.pull.steps=400 --set output.frames=400 \
  --set output.series_every=1
# Frames of a node selection (every 3rd node, in a box), two fields, single precision; and frames
# without positions (the geometry is the reference positions).
run selection "damage body" -- "$src/tests/restart/tiny_sheet.yaml" --set output.frames=4 --set output.series_every=1 \
  --set 'output={frames: 4, series_every: 1, node_stride: 3, region: {min: [-1, -1, -1], max: [0.0025, 1, 1]}, fields: [position, damage], precision: single}'
run no_positions "displacement body" -- "$src/tests/restart/tiny_sheet.yaml" \
  --set 'output={frames: 4, series_every: 1, fields: [displacement]}'
"$py" - "$work/selection" <<'PY' && { echo "ok   selection_nodes: natural ids every 3rd, in the box, float32"; pass=$((pass + 1)); } || { echo "FAIL selection_nodes"; fail=$((fail + 1)); }
import sys
import h5py, numpy as np
with h5py.File(sys.argv[1] + "/frames.h5", "r") as f:
    ids, X = f["mesh/natural_id"][...], f["mesh/reference_position"][...]
    last = f["frames"][sorted(f["frames"])[-1]]
    ok = len(ids) == int(f.attrs["frame_nodes"]) > 0 and np.all(ids % 3 == 0) and np.all(np.diff(ids) > 0) \
        and np.all(X[:, 0] <= 0.0025) and last["position"].dtype == np.float32 and last["damage"].shape == ids.shape
    sys.exit(0 if ok else 1)
PY
# tools/crack_path.py takes the reference positions from the mesh, not from the frames' fields:
# frames of damage alone are analysed (spacing 0.5 mm found); frames without damage are refused
# with exit status 2 and the fields they hold (not a traceback).
run damage_only "damage body" -- "$src/tests/restart/tiny_sheet.yaml" --set 'output={frames: 2, fields: [damage]}'
if "$py" "$src/tools/crack_path.py" "$work/damage_only" --json > "$work/cp.json" 2> "$work/cp.err" &&
  "$py" -c "import json, sys; sys.exit(0 if abs(json.load(open(sys.argv[1]))['spacing'] - 5e-4) < 1e-9 else 1)" "$work/cp.json"; then
  echo "ok   crack_path_damage_only"; pass=$((pass + 1))
else
  echo "FAIL crack_path_damage_only: $(cat "$work/cp.json" "$work/cp.err" | head -c 300)"; fail=$((fail + 1))
fi
"$py" "$src/tools/crack_path.py" "$work/no_positions" > /dev/null 2> "$work/cp.err"
if [ $? -eq 2 ] && grep -qF "crack_path: the frames of $work/no_positions hold no damage" "$work/cp.err"; then
  echo "ok   crack_path_no_damage: $(cat "$work/cp.err")"; pass=$((pass + 1))
else
  echo "FAIL crack_path_no_damage: $(head -c 300 "$work/cp.err")"; fail=$((fail + 1))
fi
cp -r "$src/tests/restart/old_layout" "$work/old_layout"
if "${mpi[@]}" "$peridrive" --resume "$work/old_layout" --quiet > "$work/stdout" 2> "$work/stderr"; then
  check old_layout "$all"
else
  echo "FAIL old_layout: $(head -c 300 "$work/stderr")"; fail=$((fail + 1))
fi
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

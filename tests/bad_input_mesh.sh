#!/usr/bin/env bash
# Hostile mesh files of mesh bodies (`mesh: file`) at the driver level, on 2 ranks: each case must
# exit with status 2, print one message naming the mesh file and the element or node (or the scene
# file's line for a file that cannot be read at all), the key and what was expected, and leave no
# output directory behind. The meshes are tiny ASCII files written here (Gmsh's 2.2 format) or
# made by the gmsh program from a .geo written here. And a fiber's path file (`polyline`).
# usage: bad_input_mesh.sh PERIDRIVE GMSH MPIEXEC [MPI flags...]
set -u
peridrive=$1 gmsh=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work" || exit 1
mkdir run data  # the working directory of every run: not the scenes' folder
pass=0 fail=0

source "$(dirname "$0")/expect.sh"
expect_dir=run
line_of() { grep -n -m1 -F -- "$2" "$1" | cut -d: -f1; }

# scene NAME KIND MESH [EXTRA_BODY_KEYS [EXTRA_SECTIONS]]: a scene (in $work) with one mesh body `m`.
scene() {
  local f="$work/$1.yaml" material="{model: membrane, density: 1000, bulk_modulus: 1.0e6}"
  [ "$2" = solid ] && material="{model: pmb, density: 1000, bulk_modulus: 1.0e6}"
  printf 'name: %s\nmaterials:\n  m: %s\nbodies:\n  m: {kind: %s, material: m, mesh: %s%s%s}\n%b\nstages:\n  - {kind: dynamic, steps: 1}\noutput: {frames: 1}\n' \
    "$1" "$material" "$2" "$3" "$([ "$2" = membrane ] && echo ', thickness: 0.001')" "${4:-}" "${5:-}" > "$f"
  echo "$f"
}
# msh NAME NODES ELEMENTS: a Gmsh 2.2 ASCII mesh in data/; NODES "tag x y z" and ELEMENTS
# "tag type 2 0 1 nodes..." lines separated by ';'.
msh() {
  local f="$work/data/$1.msh"
  local nodes elements
  IFS=';' read -ra nodes <<< "$2"
  IFS=';' read -ra elements <<< "$3"
  { printf '$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n' "${#nodes[@]}"
    printf '%s\n' "${nodes[@]}"
    printf '$EndNodes\n$Elements\n%d\n' "${#elements[@]}"
    printf '%s\n' "${elements[@]}"
    printf '$EndElements\n'; } > "$f"
  echo "$f"
}
square='1 0 0 0;2 1 0 0;3 1 1 0;4 0 1 0;5 0.5 0.5 0'

# The file itself.
f=$(scene missing membrane data/none.msh)
expect missing_file "$f:$(line_of "$f" 'mesh:'): bodies.m.mesh: cannot read the mesh '$work/data/none.msh': No such file or directory" -- "$f"
echo 'this is no mesh' > data/garbage.msh
f=$(scene garbage membrane data/garbage.msh)
expect not_a_mesh "$work/data/garbage.msh: bodies.m.mesh: neither a Gmsh mesh (a .msh file starts with \$MeshFormat) nor an STL" -- "$f"
printf '$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n1 0 0 0\n2 1 0\n' > data/truncated.msh
f=$(scene truncated membrane data/truncated.msh)
expect unreadable "bodies.m.mesh: Gmsh cannot read the mesh '$work/data/truncated.msh': " -- "$f"
# Gmsh runs what it takes for a script (shell commands too), whatever the file's name, and the
# options file <mesh>.opt beside a mesh it opens: neither may run.
echo "System \"touch $work/ran_script\";" > data/script.msh
f=$(scene script_named_msh membrane data/script.msh)
expect script_named_msh "$work/data/script.msh: bodies.m.mesh: neither a Gmsh mesh" -- "$f"
[ -e "$work/ran_script" ] && { echo "FAIL script_named_msh: the script ran"; fail=$((fail + 1)); }
echo 'Point(1) = {0, 0, 0};' > data/script.geo
f=$(scene script membrane data/script.geo)
expect geo_script "bodies.m.mesh: '$work/data/script.geo' is a Gmsh script, not a mesh" -- "$f"
# No cells of the body's kind.
m=$(msh lines "$square" '1 1 2 0 1 1 2;2 1 2 0 1 2 3')
f=$(scene no_triangles membrane data/lines.msh)
expect no_triangles "bodies.m.mesh: the mesh '$m' has no triangles (expected a triangle surface mesh" -- "$f"
m=$(msh flat_triangles "$square" '1 2 2 0 1 1 2 5;2 2 2 0 1 2 3 5;3 2 2 0 1 3 4 5;4 2 2 0 1 4 1 5')
f=$(scene no_tets solid data/flat_triangles.msh)
expect no_tets "bodies.m.mesh: the mesh '$m' has no tetrahedra" -- "$f"
# Element types the body cannot take.
m=$(msh quads "$square" '1 2 2 0 1 1 2 5;7 3 2 0 1 1 2 3 4')
f=$(scene quads membrane data/quads.msh)
expect unsupported_quad "$m: element 7: bodies.m.mesh: unsupported element type 'Quadrilateral 4' (Gmsh type 3, 1 of them, this the first)" -- "$f"
tet='1 0 0 0;2 1 0 0;3 0 1 0;4 0 0 1'
m=$(msh tet "$tet" '1 4 2 0 1 1 2 3 4')
f=$(scene tet_in_membrane membrane data/tet.msh)
expect tet_in_membrane "$m: element 1: bodies.m.mesh: unsupported element type 'Tetrahedron 4' (Gmsh type 4, 1 of them, this the first); a membrane's mesh takes 3-node triangles (and points and 2-node lines for physical groups); for a volume mesh use kind: solid" -- "$f"
cat > data/second.geo <<'EOF'
Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5}; Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
EOF
"$gmsh" -2 -order 2 -format msh41 data/second.geo -o data/second.msh -v 0 > /dev/null 2>&1 || echo "gmsh failed on second.geo"
f=$(scene second_order membrane data/second.msh)
expect second_order "bodies.m.mesh: unsupported element type 'Triangle 6' (Gmsh type 9, " -- "$f"
grep -qF "$work/data/second.msh: element " "$work/stderr" || { echo "FAIL second_order: the element not named"; fail=$((fail + 1)); }
# A second-order triangle in the entity of first-order ones: Gmsh drops it without a word.
m=$(msh mixed_order "$square;6 0.5 0 0;7 0.75 0.25 0;8 0.25 0.25 0" '1 2 2 0 1 1 2 5;2 2 2 0 1 2 3 5;3 2 2 0 1 3 4 5;4 9 2 0 1 1 2 5 6 7 8')
f=$(scene mixed_order membrane data/mixed_order.msh)
expect mixed_order "$m:$(line_of "$m" '4 9 2'): element 4: bodies.m.mesh: unsupported element type 'Triangle 6' (Gmsh type 9, which Gmsh drops where it shares an entity with triangles)" -- "$f"
# STL facets Gmsh drops: a corner not a number, two corners alike.
stl() {  # NAME FACETS ("x y z x y z x y z" per facet, ';' between)
  local name=$1 facets
  IFS=';' read -ra facets <<< "$2"
  { echo "solid $name"
    for t in "${facets[@]}"; do
      set -- $t
      printf 'facet normal 0 0 1\n outer loop\n  vertex %s %s %s\n  vertex %s %s %s\n  vertex %s %s %s\n endloop\nendfacet\n' "$@"
    done
    echo "endsolid $name"; } > "data/$name.stl"
  echo "$work/data/$name.stl"
}
m=$(stl nan_corner '0 0 0 1 0 0 0 1 0;1 0 0 1 1 0 nan 1 0')
f=$(scene nan_corner membrane data/nan_corner.stl)
expect stl_not_a_number "$m:9: bodies.m.mesh: facet 2: a corner at (nan, 1, 0); expected finite coordinates below 1e100 m (after scale)" -- "$f"
m=$(stl repeated_corner '0 0 0 1 0 0 0 1 0;1 0 0 1 1 0 1 1 0')
f=$(scene repeated_corner membrane data/repeated_corner.stl)
expect stl_degenerate "$m:9: bodies.m.mesh: facet 2: degenerate facet: two corners at (1, 1, 0); expected three distinct corners" -- "$f"

# Degenerate and inverted cells, duplicate points.
m=$(msh collinear '1 0 0 0;2 1 0 0;3 2 0 0;4 0 1 0' '1 2 2 0 1 1 2 4;2 2 2 0 1 1 2 3')
f=$(scene collinear membrane data/collinear.msh)
expect degenerate_triangle "$m: element 2: bodies.m.mesh: degenerate triangle (zero area) with nodes 1, 2, 3; expected three corners not on one line" -- "$f"
m=$(msh flat_tet "$tet;5 1 1 0" '1 4 2 0 1 1 2 3 4;2 4 2 0 1 1 2 3 5')
f=$(scene flat_tet solid data/flat_tet.msh)
expect degenerate_tet "$m: element 2: bodies.m.mesh: degenerate tetrahedron (zero volume) with nodes 1, 2, 3, 5; expected four corners not in one plane" -- "$f"
m=$(msh inverted "$tet;5 1 1 1" '1 4 2 0 1 1 2 3 4;9 4 2 0 1 2 4 3 5')
f=$(scene inverted solid data/inverted.msh)
expect inverted_tet "$m: element 9: bodies.m.mesh: inverted tetrahedron (negative volume -0.3333333333333333 m^3) with nodes 2, 4, 3, 5" -- "$f"
m=$(msh duplicate "$square;6 1 0 0" '1 2 2 0 1 1 2 5;2 2 2 0 1 6 3 5;3 2 2 0 1 3 4 5;4 2 2 0 1 4 1 5')
f=$(scene duplicate membrane data/duplicate.msh)
expect duplicate_node "$m: node 6: bodies.m.mesh: at (1, 0, 0), the position of node 2 too (within 1e-8 mean edge lengths); expected each point once" -- "$f"
m=$(msh twice "$square" '1 2 2 0 1 1 2 5;2 2 2 0 1 2 3 5;3 2 2 0 1 3 4 5;4 2 2 0 1 4 1 5;7 2 2 0 1 5 2 1')
f=$(scene twice membrane data/twice.msh)
expect triangle_twice "$m: element 7: bodies.m.mesh: the same nodes as element 1; expected each triangle once" -- "$f"
m=$(msh tet_twice "$tet;5 1 1 1" '1 4 2 0 1 1 2 3 4;2 4 2 0 1 2 3 4 5;3 4 2 0 1 2 1 4 3')
f=$(scene tet_twice solid data/tet_twice.msh)
expect tetrahedron_twice "$m: element 3: bodies.m.mesh: the same nodes as element 1; expected each tetrahedron once" -- "$f"
m=$(msh not_a_number '1 0 0 0;2 1 0 0;3 1 nan 0;4 0 1 0;5 0.5 0.5 0' '1 2 2 0 1 1 2 5;2 2 2 0 1 2 3 5;3 2 2 0 1 3 4 5;4 2 2 0 1 4 1 5')
f=$(scene not_a_number membrane data/not_a_number.msh)
expect node_not_a_number "$m: node 3: bodies.m.mesh: at (1, nan, 0); expected finite coordinates below 1e100 m (after scale)" -- "$f"
# A pressure on triangles oriented unlike.
m=$(msh unlike "$square" '1 2 2 0 1 1 2 5;2 2 2 0 1 2 3 5;3 2 2 0 1 3 4 5;4 2 2 0 1 1 4 5')
f=$(scene unlike membrane data/unlike.msh ', pressure: 100')
expect pressure_orientation "$m: element 4: bodies.m.mesh: runs along the edge from node 4 to node 5 in the same direction as element 3: the triangles are not oriented alike" -- "$f"
# Physical groups as regions.
m=$(msh square "$square" '1 2 2 0 1 1 2 5;2 2 2 0 1 2 3 5;3 2 2 0 1 3 4 5;4 2 2 0 1 4 1 5')
f=$(scene no_groups membrane data/square.msh '' 'boundaries:\n  - {name: rim, region: {body: m, group: rim}}')
expect group_unknown "$f:$(line_of "$f" 'group: rim'): boundaries.0.region.group: the mesh '$m' has no physical group named 'rim'; its named groups: none" -- "$f"
cat > data/grouped.geo <<'EOF'
Point(1) = {0, 0, 0, 0.5}; Point(2) = {1, 0, 0, 0.5}; Point(3) = {1, 1, 0, 0.5}; Point(4) = {0, 1, 0, 0.5};
Point(5) = {3, 3, 3, 0.5};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Surface("sheet") = {1};
Physical Curve("left") = {4};
Physical Point("stray") = {5};
EOF
"$gmsh" -2 -format msh41 data/grouped.geo -o data/grouped.msh -v 0 > /dev/null 2>&1 || echo "gmsh failed on grouped.geo"
f=$(scene wrong_group membrane data/grouped.msh '' 'boundaries:\n  - {name: rim, region: {body: m, group: right}}')
expect group_listed "boundaries.0.region.group: the mesh '$work/data/grouped.msh' has no physical group named 'right'; its named groups: 'stray', 'left', 'sheet'" -- "$f"
f=$(scene stray_group membrane data/grouped.msh '' 'boundaries:\n  - {name: rim, region: {body: m, group: stray}}')
expect group_without_nodes "boundaries.0.region.group: physical group 'stray' of the mesh '$work/data/grouped.msh' holds no node of the body" -- "$f"
f=$(scene group_and_box membrane data/grouped.msh '' 'boundaries:\n  - {name: rim, region: {body: m, group: left, min: [0, 0, 0]}}')
expect group_with_box "boundaries.0.region.min: not with group" -- "$f"
f=$(scene group_no_body membrane data/grouped.msh '' 'boundaries:\n  - {name: rim, region: {group: left}}')
expect group_without_body "boundaries.0.region: missing required key 'body'" -- "$f"
# Two physical groups of one dimension under one name: Gmsh keeps one of them for the name.
{ printf '$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n3\n1 9 "rim"\n1 10 "rim"\n2 1 "sheet"\n$EndPhysicalNames\n'
  printf '$Nodes\n5\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n5 0.5 0.5 0\n$EndNodes\n'
  printf '$Elements\n6\n1 2 2 1 1 1 2 5\n2 2 2 1 1 2 3 5\n3 2 2 1 1 3 4 5\n4 2 2 1 1 4 1 5\n5 1 2 9 1 1 2\n6 1 2 10 2 3 4\n$EndElements\n'; } > data/same_name.msh
f=$(scene same_name membrane data/same_name.msh)
expect group_name_twice "$work/data/same_name.msh:7: bodies.m.mesh: a second physical group of dimension 1 named 'rim' (the first at line 6)" -- "$f"

# Keys that exclude each other.
f=$(scene with_origin membrane data/square.msh ', origin: [0, 0, 0]')
expect mesh_with_origin "bodies.m.origin: not with mesh" -- "$f"
f=$(scene partial membrane data/square.msh ', quadrature: partial_area')
expect mesh_partial_area "bodies.m.quadrature: expected one of: full, taper; got partial_area" -- "$f"
f=$(scene scale_zero membrane data/square.msh ', scale: 0')
expect scale_zero "bodies.m.scale: expected a positive number, got 0" -- "$f"
f=$(scene scale_tiny membrane data/square.msh ', scale: 1e-120')
expect scale_tiny "bodies.m.mesh: the mesh '$work/data/square.msh' spans 1.4142135623730951e-120 m after scale 1e-120; expected a body at least 1e-30 m across" -- "$f"

# An options file beside a good mesh (Gmsh runs <mesh>.opt when it opens <mesh>): not run, the
# mesh read.
echo "System \"touch $work/ran_options\";" > data/square.msh.opt
f=$(scene options_beside membrane data/square.msh)
if (cd run && "${mpi[@]}" "$peridrive" "$f" --dry-run > "$work/stdout" 2> "$work/stderr") && [ ! -e "$work/ran_options" ] &&
  grep -q "m.nodes = 5" "$work/stdout"; then
  echo "ok   options_beside: the mesh read, its .opt not run"; pass=$((pass + 1))
else
  echo "FAIL options_beside: exit, options run or nodes wrong"; cat "$work/stderr"; fail=$((fail + 1))
fi
rm data/square.msh.opt

# A fiber's path from a file.
fiber() {  # NAME FILE_TEXT
  printf '%b' "$2" > "data/$1.xyz"
  printf 'name: %s\nmaterials:\n  m: {model: membrane, density: 1100, youngs_modulus: 2.0e9}\nbodies:\n  f: {kind: fiber, material: m, polyline: data/%s.xyz, diameter: 0.0002, spacing: 0.0005}\nstages:\n  - {kind: dynamic, steps: 1}\noutput: {frames: 1}\n' "$1" "$1" > "$work/$1.yaml"
  echo "$work/$1.yaml"
}
f=$(fiber two_numbers '0 0 0\n0.01 0\n')
expect polyline_columns "$work/data/two_numbers.xyz:2: bodies.f.polyline: expected 3 numbers x, y, z [m], got '0.01 0'" -- "$f"
f=$(fiber word '# x y z\n0 0 0\n0.01 zero 0\n')
expect polyline_number "$work/data/word.xyz:3: bodies.f.polyline: expected 3 finite numbers x, y, z [m], got '0.01 zero 0'" -- "$f"
f=$(fiber empty_field '0 0 0\n0.01,,0,0\n')
expect polyline_empty_field "$work/data/empty_field.xyz:2: bodies.f.polyline: an empty field before a comma; expected 3 numbers x, y, z [m], got '0.01,,0,0'" -- "$f"
f=$(fiber trailing_comma '0 0 0\n0.01,0,0,\n')
expect polyline_trailing_comma "$work/data/trailing_comma.xyz:2: bodies.f.polyline: an empty field after the last comma; expected 3 numbers x, y, z [m], got '0.01,0,0,'" -- "$f"
f=$(fiber subnormal '0 0 0\n0.01 1e-320 0\n')
expect polyline_subnormal "$work/data/subnormal.xyz:2: bodies.f.polyline: '1e-320' is below the smallest normal double" -- "$f"
f=$(fiber folds_back '0 0 0\n0.01 0 0\n0.005 0 0\n')
expect polyline_folds_back "$work/data/folds_back.xyz: bodies.f.polyline: the path comes back onto itself: its nodes at arc length 0.00975 m and 0.01025 m lie at one point (0.00975, 0, 0)" -- "$f"
f=$(fiber repeated '0 0 0\n0.01 0 0\n\n0.01, 0, 0\n')
expect polyline_repeat "$work/data/repeated.xyz:4: bodies.f.polyline: the same point as line 2; expected each point different from the one before it" -- "$f"
f=$(fiber single '0 0 0\n')
expect polyline_one_point "$f:5: bodies.f.polyline: the polyline '$work/data/single.xyz' has 1 point; expected at least 2 lines x, y, z" -- "$f"
rm data/single.xyz
expect polyline_missing "$f:5: bodies.f.polyline: cannot read the polyline '$work/data/single.xyz': No such file or directory" -- "$f"

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

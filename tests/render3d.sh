#!/usr/bin/env bash
# tools/render3d.py on small runs, against values known in advance:
#  - a 20 x 20 node membrane (0.5 mm spacing) with an edge slit between rows 9 and 10 ending at
#    x = 3.9 mm and four short slits boxing in the node at (7.25, 7.25) mm (it loses all its
#    bonds, damage 1), stretched 10% along y from the start: its Delaunay triangulation has
#    2 x 19 x 19 = 722 triangles; the ones dropped for damage are exactly those touching the one
#    node of damage >= 0.99, the ones dropped for the slit are the 15 of the strip between rows 9
#    and 10 with an edge meeting it (both triangles of the 7 cells before x = 3.75 mm, one of the
#    8th), and the same ones (with the same damage) when the slit is a polygon across the sheet's
#    plane; the critical stretch of the material (1.6) drops none, --gap-stretch 1.09 every one not
#    dropped for damage (each has a y edge stretched 1.1) and 1.11 none; the picture from above is
#    not blank (the sheet covers 20-70% of a bare picture, 10-60% of the labelled one) and the gaps
#    remove 0.7 to 1.2 times the dropped triangles' share of the sheet's pixels;
#  - a small sphere (balloon scene at 20 mm spacing): a closed hull, 2N - 4 triangles, every edge in
#    exactly two, the same triangles from scipy and from the stereographic projection;
#  - a 5 mm fiber: N - 1 segments, none dropped; a clip on no axis refused (exit status 2).
# usage: render3d.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]   (KEEP=1 keeps the work directory)
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 1 "$@")
py=/usr/bin/python3
work=$(mktemp -d)
trap '[ -n "${KEEP:-}" ] || rm -rf "$work"' EXIT
[ -n "${KEEP:-}" ] && echo "keeping $work"
fail=0

cat > "$work/sheet.yaml" <<'YAML'
name: cracked-sheet
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 1.6}
bodies:
  sheet: {material: rubber, origin: [0, 0, 0], size: [0.01, 0.01], thickness: 0.0005, spacing: 0.0005}
cracks:
  - {name: slit, from: [-0.001, 0.005, 0], to: [0.0039, 0.005, 0]}
  - {name: box1, from: [0.0071, 0.0071, 0], to: [0.0074, 0.0071, 0]}
  - {name: box2, from: [0.0074, 0.0071, 0], to: [0.0074, 0.0074, 0]}
  - {name: box3, from: [0.0074, 0.0074, 0], to: [0.0071, 0.0074, 0]}
  - {name: box4, from: [0.0071, 0.0074, 0], to: [0.0071, 0.0071, 0]}
initial: {displacement_gradient: [[0, 0, 0], [0, 0.1, 0], [0, 0, 0]]}
stages:
  - {name: hold, steps: 4}
output: {frames: 2, series_every: 2}
YAML
cat > "$work/fiber.yaml" <<'YAML'
name: fiber-mm
materials:
  gum: {model: membrane, density: 1000, bulk_modulus: 1.0e9}
bodies:
  fiber: {kind: fiber, material: gum, diameter: 1.0e-4, spacing: 1.0e-4,
          path: [[0, 0, 0], [0.002, 0.001, 0], [0.004, 0, 0.001], [0.005, 0.0005, 0]]}
initial: {velocity_gradient: [[200, 0, 0], [0, 0, 0], [0, 0, 0]]}
stages:
  - {name: stretch, steps: 20}
output: {frames: 2, series_every: 10}
YAML

run() {  # run NAME peridrive-arguments...
  local name=$1
  shift
  if ! "${mpi[@]}" "$peridrive" "$@" --out "$work/$name" --quiet > "$work/$name.log" 2>&1; then
    echo "FAIL $name run: $(head -c 300 "$work/$name.log")"; fail=$((fail + 1))
  fi
}
run sheet "$work/sheet.yaml"
# The same sheet with its edge slit given as a polygon across the sheet's plane.
sed 's/  - {name: slit, from: \[-0.001, 0.005, 0\], to: \[0.0039, 0.005, 0\]}/  - {name: slit, polygon: [[-0.001, 0.005, -0.001], [0.0039, 0.005, -0.001], [0.0039, 0.005, 0.001], [-0.001, 0.005, 0.001]]}/' \
  "$work/sheet.yaml" > "$work/polysheet.yaml"
run polysheet "$work/polysheet.yaml"
run fiber "$work/fiber.yaml"
run sphere "$src/drivers/scenes/balloon.yaml" --set bodies.balloon.spacing=0.02 --set stages.0.duration=2e-4 \
  --set stages.1.duration=2e-5 --set output.frames=2

render() {  # render DIR NAME [args]: NAME.png, NAME.json, NAME.npz in the work directory
  local dir=$1 name=$2
  shift 2
  if ! "$py" "$src/tools/render3d.py" "$work/$dir" --out "$work/$name.png" --stats "$work/$name.json" \
       --mesh "$work/$name.npz" "$@" > "$work/render.log" 2>&1; then
    echo "FAIL render3d.py $dir $*:"; cat "$work/render.log"; fail=$((fail + 1))
  fi
}
render sheet gaps --frame 0 --reference --view 90,-90 --bare
render sheet nogaps --frame 0 --reference --view 90,-90 --bare --no-gaps
render polysheet polygaps --frame 0 --reference --view 90,-90 --bare
render sheet labelled --frame 0
render sheet stretch109 --frame 0 --gap-stretch 1.09
render sheet stretch111 --frame 0 --gap-stretch 1.11
render sphere hull
render sphere projection --no-scipy
render fiber fiber
# Option values it cannot use: refused with exit status 2 and one line, no picture (each gave a
# traceback before).
for bad in "--range a,b" "--range 1,0" "--view 30" "--size 8" "--dpi 0" "--clip x<abc" "--out /nonexistent/x.png" \
           "--out $work/x.jpgx" "--stats /nonexistent/x.json"; do
  "$py" "$src/tools/render3d.py" "$work/sheet" $bad > "$work/refused.log" 2>&1
  status=$?
  if [ "$status" -ne 2 ] || grep -q Traceback "$work/refused.log"; then
    echo "FAIL $bad: exit status $status (expected 2, no traceback)"; cat "$work/refused.log"; fail=$((fail + 1))
  else
    echo "ok   $bad refused: $(tail -1 "$work/refused.log")"
  fi
done
# A clip on no axis is refused with exit status 2.
"$py" "$src/tools/render3d.py" "$work/sheet" --clip 'q>1' --out "$work/refused.png" > "$work/refused.log" 2>&1
status=$?
if [ "$status" -ne 2 ] || [ -e "$work/refused.png" ]; then
  echo "FAIL --clip 'q>1': exit status $status (expected 2, no picture)"; fail=$((fail + 1))
else
  echo "ok   --clip 'q>1' refused: $(cat "$work/refused.log")"
fi

"$py" - "$work" <<'PY' || fail=$((fail + 1))
import json, sys
import h5py
import matplotlib.image as mpimg
import numpy as np
work = sys.argv[1]
checks = []
def check(name, ok, detail):
    checks.append(bool(ok))
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
def stats(name):
    return json.load(open(f"{work}/{name}.json"))
def mesh(name):
    return np.load(f"{work}/{name}.npz")
def inked(name):  # fraction of pixels that are not white
    im = mpimg.imread(f"{work}/{name}.png")[..., :3]
    return im.min(axis=2) < 0.97

with h5py.File(f"{work}/sheet/frames.h5", "r") as f:
    ref = f["mesh/reference_position"][...]
    damage = f["frames/000000/damage"][...]
full = np.nonzero(damage >= 0.99)[0]
check("sheet: one node fully damaged, at (7.25, 7.25) mm", len(full) == 1 and np.allclose(ref[full[0], :2], 0.00725),
      f"{len(full)} nodes, at {ref[full, :2].tolist()}")
s, m = stats("gaps"), mesh("gaps")
tris, rule = m["triangles"], m["triangle_rule"]
check("sheet: 722 triangles", s["triangles"] == 722 == len(tris), s["triangles"])
touching = np.isin(tris, full).any(axis=1)
check("sheet: dropped for damage = the triangles touching the fully damaged node",
      np.array_equal(rule == 2, touching) and 4 <= touching.sum() <= 8,
      f"{int((rule == 2).sum())} dropped, {int(touching.sum())} touch it")
crack = tris[rule == 4]
y = ref[crack, 1]
strip = np.all(np.isclose(y, 0.00475) | np.isclose(y, 0.00525), axis=1) & np.isclose(y.min(axis=1), 0.00475) \
    & np.isclose(y.max(axis=1), 0.00525) & (ref[crack, 0].min(axis=1) < 0.0039)
check("sheet: dropped for the slit = 15 triangles of the strip before its end", len(crack) == 15 and strip.all(),
      f"{len(crack)} dropped, {int(strip.sum())} in the strip")
with h5py.File(f"{work}/polysheet/frames.h5", "r") as f:
    poly_damage = f["frames/000000/damage"][...]
pm = mesh("polygaps")
check("sheet: the slit as a polygon drops the same triangles, with the same damage",
      "polygon" in open(f"{work}/polysheet.yaml").read() and np.array_equal(pm["triangle_rule"], rule)
      and np.array_equal(poly_damage, damage), f"{int((pm['triangle_rule'] == 4).sum())} dropped for the polygon")
d = s["triangles_dropped"]
check("sheet: nothing else dropped", d["stretch"] == d["reference_edge"] == d["clip"] == 0 and s["triangles_drawn"] == 701, d)
d9, d11 = stats("stretch109")["triangles_dropped"], stats("stretch111")["triangles_dropped"]
check("sheet: --gap-stretch 1.09 drops all the rest, 1.11 none",
      d9["stretch"] == 722 - d9["damage"] and d9["damage"] == touching.sum() and d11["stretch"] == 0,
      f"1.09: {d9}, 1.11: {d11}")
check("sheet: --no-gaps drops none", stats("nogaps")["triangles_drawn"] == 722, stats("nogaps")["triangles_dropped"])
with_gaps, without = inked("gaps"), inked("nogaps")
share = 21 / 722
gap = (without & ~with_gaps).sum() / without.sum()
check("sheet picture not blank", 0.2 <= without.mean() <= 0.7 and 0.1 <= inked("labelled").mean() <= 0.6,
      f"bare {without.mean():.3f} (0.2-0.7), labelled {inked('labelled').mean():.3f} (0.1-0.6)")
check("sheet: the gaps show", 0.7 <= gap / share <= 1.2 and (with_gaps & ~without).sum() == 0,
      f"{gap:.4f} of the sheet's pixels, {gap / share:.2f} x the dropped share {share:.4f} (0.7-1.2)")

with h5py.File(f"{work}/sphere/frames.h5", "r") as f:
    n = len(f["mesh/reference_position"])
hull, proj = mesh("hull")["triangles"], mesh("projection")["triangles"]
edges = np.sort(np.concatenate([hull[:, [0, 1]], hull[:, [1, 2]], hull[:, [2, 0]]]), axis=1)
_, uses = np.unique(edges, axis=0, return_counts=True)
same = {tuple(sorted(t)) for t in hull} == {tuple(sorted(t)) for t in proj}
check("sphere: a closed hull of 2N - 4 triangles", len(hull) == 2 * n - 4 and (uses == 2).all(),
      f"N = {n}, {len(hull)} triangles, edge uses {sorted(set(uses.tolist()))}")
check("sphere: scipy and the stereographic projection agree", same and len(proj) == len(hull), f"{len(proj)} triangles")
check("sphere picture not blank", 0.1 <= inked("hull").mean() <= 0.6, f"{inked('hull').mean():.3f} (0.1-0.6)")

with h5py.File(f"{work}/fiber/frames.h5", "r") as f:
    n = len(f["mesh/reference_position"])
s = stats("fiber")
check("fiber: N - 1 segments, all drawn", s["segments"] == n - 1 == s["segments_drawn"] and s["triangles"] == 0,
      f"N = {n}, {s['segments']} segments, {s['segments_drawn']} drawn")
check("fiber picture not blank", 0.02 <= inked("fiber").mean() <= 0.6, f"{inked('fiber').mean():.3f} (0.02-0.6)")
print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)
PY
[ "$fail" -eq 0 ]

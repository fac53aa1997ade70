#!/usr/bin/env bash
# Pictures that fit the body at hand: tools/plot_results.py, plot_fiber.py and plot_sphere.py on
# small 2-rank runs of a membrane, a PMB block, a 5 mm fiber, a 100 nm fiber and a sphere (0.1 m
# radius). Each figure's note in figures.json, read from the drawn figure (its axes' projection
# and x-label unit, the damage colouring's limits), must show: the membrane as a sheet from above
# (2D axes), the block as a mid-plane slice beside a 3D view and never as a sheet (no wrinkles),
# fibers and the sphere in 3D; lengths in mm for the membrane, block, 5 mm fiber and sphere
# (200 mm across) and in nm for the 100 nm fiber; damage on [0, 1] in every damage figure, the
# undamaged first frame too. plot_fiber.py and plot_sphere.py refuse runs without their body
# kind (exit 2). peri_view's unit and view choices against a table.
# usage: plot_views.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
py=/usr/bin/python3
tools=$src/tools
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail=0

cat > "$work/block.yaml" <<'YAML'
name: block
materials:
  glass: {model: pmb, density: 2500, youngs_modulus: 7.0e10, critical_stretch: 0.001}
bodies:
  block: {kind: solid, material: glass, origin: [0, 0, 0], size: [0.004, 0.003, 0.002], spacing: 0.0005}
initial: {velocity_gradient: [[5000, 0, 0], [0, 0, 0], [0, 0, 0]]}
stages:
  - {name: pull, steps: 60}
output: {frames: 3, series_every: 5}
YAML
cat > "$work/fiber_mm.yaml" <<'YAML'
name: fiber-mm
materials:
  gum: {model: membrane, density: 1000, bulk_modulus: 1.0e9}
bodies:
  fiber: {kind: fiber, material: gum, diameter: 1.0e-4, spacing: 1.0e-4,
          path: [[0, 0, 0], [0.002, 0.001, 0], [0.004, 0, 0.001], [0.005, 0.0005, 0]]}
initial: {velocity_gradient: [[200, 0, 0], [0, 0, 0], [0, 0, 0]]}
stages:
  - {name: stretch, steps: 100}
output: {frames: 3, series_every: 10}
YAML
cat > "$work/fiber_nm.yaml" <<'YAML'
name: fiber-nm
materials:
  protein: {model: membrane, density: 3000, bulk_modulus: 40.0e9}
bodies:
  fiber: {kind: fiber, material: protein, diameter: 1.0e-9, spacing: 1.0e-9,
          path: [[0, 0, 0], [5.0e-8, 1.0e-8, 0], [1.0e-7, 0, 5.0e-9]]}
initial: {velocity_gradient: [[1.0e8, 0, 0], [0, 0, 0], [0, 0, 0]]}
stages:
  - {name: stretch, steps: 100}
output: {frames: 3, series_every: 10}
YAML

run() {  # run NAME peridrive-arguments...
  local name=$1
  shift
  if ! "${mpi[@]}" "$peridrive" "$@" --out "$work/$name" --quiet > "$work/$name.log" 2>&1; then
    echo "FAIL $name run: $(head -c 300 "$work/$name.log")"; fail=$((fail + 1))
  fi
}
run membrane "$src/tests/restart/tiny_sheet.yaml"
run block "$work/block.yaml"
run fiber_mm "$work/fiber_mm.yaml"
run fiber_nm "$work/fiber_nm.yaml"
run sphere "$src/drivers/scenes/balloon.yaml" --set bodies.balloon.spacing=0.02 --set stages.0.duration=2e-4 \
  --set stages.1.duration=2e-5 --set output.frames=3

tool() {  # tool EXPECTED_STATUS SCRIPT DIR [args]
  local want=$1 script=$2 dir=$3
  shift 3
  "$py" "$tools/$script" "$work/$dir" "$@" > "$work/tool.log" 2>&1
  local rc=$?
  if [ "$rc" -ne "$want" ]; then
    echo "FAIL $script $dir: exit status $rc, expected $want"; cat "$work/tool.log"; fail=$((fail + 1))
  fi
}
# The undamaged first frame of the block and of the membrane first (their notes are overwritten
# by the last frame's next).
tool 0 plot_results.py block --frame 0 && cp "$work/block/figures.json" "$work/block_first.json"
tool 0 plot_results.py membrane --frame 0 && cp "$work/membrane/figures.json" "$work/membrane_first.json"
for d in membrane block fiber_mm fiber_nm sphere; do tool 0 plot_results.py "$d"; done
tool 0 plot_fiber.py fiber_mm
tool 0 plot_fiber.py fiber_nm
tool 0 plot_sphere.py sphere
tool 2 plot_fiber.py membrane
tool 2 plot_sphere.py block

"$py" - "$work" "$tools" <<'PY' || fail=$((fail + 1))
import json, os, sys
import h5py
work, tools = sys.argv[1:3]
sys.path.insert(0, tools)
import peri_view
checks = []
def check(name, ok, detail):
    checks.append(ok)
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
def notes(d):
    return json.load(open(os.path.join(work, d)))
def figure(name, d, fig, view, projections, unit, damage):
    n = notes(d).get(fig)
    if n is None:
        check(name, False, f"no note for {fig} in {d}")
        return
    got = (n["view"], n["projections"], n["axis_units"], n.get("color_limits"))
    want = (view, projections, [unit], [0.0, 1.0] if damage else None)
    check(name, got == want, f"{fig}: view {got[0]}, axes {'+'.join(got[1])}, unit {got[2]}, damage limits {got[3]}")

figure("membrane as a sheet", "membrane/figures.json", "damage.png", "sheet", ["rectilinear"], "mm", True)
figure("membrane deformed sheet", "membrane/figures.json", "deformed.png", "sheet", ["rectilinear"], "mm", False)
figure("membrane wrinkles", "membrane/figures.json", "wrinkles.png", "sheet", ["rectilinear"], "mm", False)
figure("undamaged membrane on [0, 1]", "membrane_first.json", "damage.png", "sheet", ["rectilinear"], "mm", True)
figure("block as slice and 3D", "block/figures.json", "damage.png", "solid", ["3d", "rectilinear"], "mm", True)
figure("undamaged block on [0, 1]", "block_first.json", "damage.png", "solid", ["3d", "rectilinear"], "mm", True)
figure("block deformed slice", "block/figures.json", "deformed.png", "solid", ["rectilinear"], "mm", False)
check("block: no wrinkles", "wrinkles.png" not in notes("block/figures.json")
      and not os.path.exists(f"{work}/block/wrinkles.png"), sorted(notes("block/figures.json")))
with h5py.File(f"{work}/block/frames.h5", "r") as f:
    last = sorted(f["frames"])[-1]
    hit, first = int((f["frames"][last]["damage"][...] > 0).sum()), float(f["frames/000000/damage"][...].max())
check("block: damaged at the end, undamaged at first", hit > 0 and first == 0, f"{hit} damaged nodes, first max {first}")
figure("5 mm fiber in 3D, mm", "fiber_mm/figures.json", "damage.png", "curves", ["3d"], "mm", True)
figure("5 mm fiber picture in mm", "fiber_mm/figures.json", "fiber.png", "curves", ["3d"], "mm", False)
figure("100 nm fiber in 3D, nm", "fiber_nm/figures.json", "damage.png", "curves", ["3d"], "nm", True)
figure("100 nm fiber picture in nm", "fiber_nm/figures.json", "fiber.png", "curves", ["3d"], "nm", False)
figure("sphere in 3D", "sphere/figures.json", "damage.png", "sphere", ["3d"], "mm", True)
figure("sphere picture", "sphere/figures.json", "sphere.png", "sphere", ["3d"], "mm", True)
figure("energies against time in us", "block/figures.json", "energies.png", "series", ["rectilinear"], "us", False)
figure("energies against time in ns", "fiber_nm/figures.json", "energies.png", "series", ["rectilinear"], "ns", False)

units = {9e-10: "nm", 1e-7: "nm", 9.99e-7: "nm", 1e-6: "um", 5e-6: "um", 9e-4: "um", 5e-3: "mm", 0.05: "mm",
         0.2: "mm", 1.0: "m", 3.0: "m", 5e3: "m"}
got = {x: peri_view.length_unit(x)[0] for x in units}
check("length units", got == units, got)
views = {("membrane",): "sheet", ("membrane", "lattice"): "sheet", ("solid",): "solid", ("fiber",): "curves",
         ("sphere",): "sphere", ("membrane", "solid"): "scatter3d", ("fiber", "sphere"): "scatter3d"}
got = {k: peri_view.choose_view(k) for k in views}
check("views", got == views, got)
print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)
PY

# Option values the study tools cannot use: refused with exit status 2 and a line naming the
# option, before anything runs (--m 0 divided by zero; --us 0 likewise; a negative damage
# threshold counted every node).
refused() {
  local want=$1
  shift
  "$py" "$@" > "$work/refused.log" 2>&1
  local status=$?
  if [ "$status" -ne 2 ] || ! grep -qF -- "$want" "$work/refused.log" || grep -q Traceback "$work/refused.log"; then
    echo "FAIL refused $*: status $status"; cat "$work/refused.log"; fail=1
  else echo "ok   refused $(basename "$1") ${*:2}"; fi
}
refused "--m: expected" "$tools/fig3_damage_stress.py" --m 0 --out "$work/fig3"
refused "--dl: expected" "$tools/fig3_damage_stress.py" --dl -0.1 --out "$work/fig3"
refused "--us: the switch width" "$tools/marder_phonons.py" 0.4 1.3 2.8 --us 0
refused "--damage: expected" "$tools/balloon_burst.py" "$work/sphere" --damage -1
[ ! -e "$work/fig3" ] || { echo "FAIL fig3_damage_stress.py wrote $work/fig3 for refused options"; fail=1; }
[ "$fail" -eq 0 ]

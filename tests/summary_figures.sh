#!/usr/bin/env bash
# summary.json and the console tell the truth after a resume and after a preload (2 ranks):
#  resume    a run resumed from a checkpoint at step 320 of 400 times 80 steps: steps_timed = 80,
#            bond_updates_per_second = ordered_bonds x 80 / step_seconds (not 400 steps over the
#            time of 80), within a factor 4 of the uninterrupted run's rate; the console says so
#  preload   a quasi-static preload that tears the sheet (its supports do more work than the sheet
#            stores and dissipates: the trapezoidal work misses the drop of the reactions as bonds
#            break): a warning naming the stage and both figures, the supports' work as summary.json
#            books it; summary.json keeps the explicit part's balance and adds the whole run's, which
#            counts the preload's work (more than 5% off), and the stage's work error beside it
#  control   a preload that does not tear: no warning, the whole run's balance within 5%
# usage: summary_figures.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
py=/usr/bin/python3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pass=0 fail=0
ok() { echo "ok   $1"; pass=$((pass + 1)); }
bad() { echo "FAIL $1"; fail=$((fail + 1)); }

# --- resume ------------------------------------------------------------------------------------
opts=(--set bodies.sheet.spacing=0.0005 --set stages.0.steps=400 --set output.checkpoint_every_steps=320
      --set output.checkpoint_every_seconds=0 --set output.frames=3)
"${mpi[@]}" "$peridrive" "${opts[@]}" --out "$work/whole" > "$work/whole.log" 2>&1 || { cat "$work/whole.log"; exit 1; }
cp "$work/whole/summary.json" "$work/whole.json"
"${mpi[@]}" "$peridrive" --resume "$work/whole" > "$work/resume.log" 2>&1 || { cat "$work/resume.log"; exit 1; }
if $py - "$work/whole.json" "$work/whole/summary.json" "$work/resume.log" <<'PY'
import json, re, sys
whole, resumed, log = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), open(sys.argv[3]).read()
problems = []
def rate(s):
    return s["ordered_bonds"] * s["steps_timed"] / s["step_seconds"]
if resumed.get("steps") != 400 or resumed.get("steps_timed") != 80 or whole.get("steps_timed") != 400:
    problems.append(f"steps {resumed.get('steps')}, steps_timed {resumed.get('steps_timed')} resumed, "
                    f"{whole.get('steps_timed')} uninterrupted; expected 400, 80 and 400")
else:
    for name, s in (("uninterrupted", whole), ("resumed", resumed)):
        if abs(s["bond_updates_per_second"] / rate(s) - 1) > 1e-9:
            problems.append(f"{name}: bond_updates_per_second {s['bond_updates_per_second']:.6g} is not "
                            f"ordered_bonds x steps_timed / step_seconds = {rate(s):.6g}")
    ratio = resumed["bond_updates_per_second"] / whole["bond_updates_per_second"]
    print(f"bond updates/s: {whole['bond_updates_per_second']:.4g} uninterrupted (400 steps), "
          f"{resumed['bond_updates_per_second']:.4g} resumed (80 steps timed), ratio {ratio:.2f}")
    if not 0.25 < ratio < 4:
        problems.append(f"the resumed rate is {ratio:.2f} times the uninterrupted one")
    m = re.search(r"done: 400 steps \(80 timed here\) in \S+ s \((\S+) bond updates/s\)", log)
    if not m:
        problems.append("the console's done line lacks '400 steps (80 timed here)'")
    elif abs(float(m.group(1)) / resumed["bond_updates_per_second"] - 1) > 5e-3:  # the console prints 3 digits (%.3g): up to 5e-3 apart
        problems.append(f"the console's rate {m.group(1)} is not summary.json's")
for p in problems:
    print("  " + p)
sys.exit(1 if problems else 0)
PY
then ok "resume: rates over the 80 steps timed"; else bad "resume"; cat "$work/resume.log"; fi

# --- preload -------------------------------------------------------------------------------------
cat > "$work/tear.yaml" <<'EOF'
name: tear
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2}
bodies:
  sheet: {material: rubber, origin: [-0.01, -0.01, 0], size: [0.02, 0.02], thickness: 0.0005, spacing: 0.0005}
cracks:
  - {name: slit, from: [-0.002, 0, 0], to: [0.002, 0, 0]}
boundaries:
  - {name: top, region: {min: [-1, 0.0088, -1], max: [1, 1, 1]}}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0088, 1]}}
stages:
  - {name: preload, kind: quasistatic, displacements: {top: [0, 0.005, 0], bottom: [0, -0.005, 0]}, load_steps: 4}
  - {name: hold, steps: 20, safety_factor: 0.35}
output: {frames: 1, series_every: 5}
EOF
# check_balance SUMMARY MIN MAX: the whole run's balance from the summary's own figures, in [MIN, MAX].
check_balance() {
  $py - "$@" <<'PY'
import json, sys
s, lo, hi = json.load(open(sys.argv[1])), float(sys.argv[2]), float(sys.argv[3])
f = s["final"]
e0 = s["run_initial_total_energy"]
scale = max(abs(f["kinetic_energy"]) + abs(f["strain_energy"]) + abs(f["dissipated_energy"]),
            abs(f["external_work"]), abs(e0))
expected = abs(f["total_energy"] - e0) / scale
worst = max(q["work_error"] for q in s["quasistatic"])
print(f"explicit part: from {s['initial_total_energy']:.4g} J, error {s['energy_balance_error']:.3g}; whole run: from "
      f"{e0:.4g} J to {f['total_energy']:.4g} J, error {s['run_energy_balance_error']:.3g}; "
      f"quasi-static work error {s['quasistatic_work_error']:.3g}")
ok = (abs(s["run_energy_balance_error"] - expected) <= 1e-9 * max(expected, 1e-300) and lo <= expected <= hi and
      s["quasistatic_work_error"] == worst)
sys.exit(0 if ok else 1)
PY
}
"${mpi[@]}" "$peridrive" "$work/tear.yaml" --out "$work/tear" --quiet > "$work/stdout" 2> "$work/stderr"
rc=$?
line=$(grep -n "name: preload" "$work/tear.yaml" | cut -d: -f1)
want="peridrive: warning: $work/tear.yaml:$line: stages.0 ('preload'): the quasi-static supports did "
# The warning's figures are summary.json's: the supports' work, the stored + dissipated energy and
# their relative difference.
quoted() {
  $py - "$work/tear/summary.json" "$work/stderr" <<'PY'
import json, re, sys
q = json.load(open(sys.argv[1]))["quasistatic"][0]
m = re.search(r"supports did ([0-9.e+-]+) J of work, but the body stores and dissipated ([0-9.e+-]+) J "
              r"\(([0-9.]+)% apart", open(sys.argv[2]).read())
work, stored, apart = float(m[1]), float(m[2]), float(m[3])
ok = (abs(work - q["support_work"]) <= 1e-5 * abs(q["support_work"]) and q["broken_bonds"] > 0 and
      abs(apart - 100 * abs(work - stored) / abs(work)) <= 0.06 and
      abs(q["work_error"] - abs(work - stored) / abs(work)) <= 1e-5 and apart > 5)
sys.exit(0 if ok else 1)
PY
}
if [ "$rc" -eq 0 ] && grep -qF "$want" "$work/stderr" && quoted &&
   [ "$(grep -c "peridrive: warning:" "$work/stderr")" -eq 1 ] && check_balance "$work/tear/summary.json" 0.05 1; then
  ok "preload: $(cut -c1-200 "$work/stderr")"
else bad "preload: exit status $rc, expected 0 with the warning '$want...' quoting summary.json"; cat "$work/stderr"; fi

sed 's/0.005, 0], bottom: \[0, -0.005/0.002, 0], bottom: [0, -0.002/' "$work/tear.yaml" > "$work/mild.yaml"
"${mpi[@]}" "$peridrive" "$work/mild.yaml" --out "$work/mild" > "$work/stdout" 2> "$work/stderr"
rc=$?
if [ "$rc" -eq 0 ] && ! grep -q "warning" "$work/stderr" && check_balance "$work/mild/summary.json" 0 0.05 &&
   grep -q "energy balance error .* (explicit part; whole run, quasi-static work included: " "$work/stdout"; then
  ok "control: no warning for a preload that does not tear"
else bad "control: exit status $rc"; cat "$work/stderr"; fi

# Stages that take no time after the last step: the run's last frame shows the state they leave
# (it showed the state before them), and a quasi-static stage's row starts the energy balance
# afresh before the detector reads it (the last row was checked against the energy before the
# stage: exit status 3, "energy balance error 0.056", on a stage that moves the supports).
cat > "$work/last.yaml" <<'YAML'
name: timeless-last
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2.0}
bodies:
  sheet: {kind: membrane, material: rubber, origin: [-0.005, -0.005, 0], size: [0.01, 0.01],
          thickness: 0.0005, spacing: 0.0005}
cracks:
  - {name: slit, from: [-0.002, 0, 0], to: [0.002, 0, 0]}
boundaries:
  - {name: top, region: {min: [-1, 0.0045, -1], max: [1, 1, 1]}, velocity: [0, 5, 0]}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0045, 1]}, velocity: [0, -5, 0]}
stages:
  - {name: d1, duration: 2.0e-6, safety_factor: 0.35}
  - {name: qs, kind: quasistatic, displacements: {top: [0, 0.0002, 0]}, load_steps: 2}
  - {name: cut, kind: release, cracks: [slit]}
output: {frames: 3}
YAML
"${mpi[@]}" "$peridrive" "$work/last.yaml" --out "$work/last" --quiet > "$work/stdout" 2> "$work/stderr"
rc=$?
last_frame() {
  $py - "$work/last" <<'PY'
import json, sys
import h5py
d = sys.argv[1]
s = json.load(open(d + "/summary.json"))
with h5py.File(d + "/frames.h5", "r") as f:
    g = f["frames"][sorted(f["frames"])[-1]]
    energy = float(g["strain_energy_density"][:] @ f["mesh/volume"][:])
    damaged = bool(g["damage"][:].max() > 0)
want = s["final"]["strain_energy"]
print(f"last frame: strain energy {energy:.6g} J (summary {want:.6g} J), damage {damaged}, broken {s['broken_bonds']}")
sys.exit(0 if abs(energy - want) <= 1e-9 * abs(want) and damaged and s["broken_bonds"] > 0 else 1)
PY
}
if [ "$rc" -eq 0 ] && last_frame > "$work/frame.log"; then ok "timeless_last: $(cat "$work/frame.log")"
else bad "timeless_last: exit status $rc, expected 0 and a last frame of the final state"; cat "$work/stderr" "$work/frame.log"; fi

# A quasi-static stage that moves no support (a relaxation between dynamic stages) does no work to
# compare with: its work_error is null and there is no warning (it was 3.6e+296, and a warning of
# 3.6e+298% apart, over a floor of 1e-300 J).
sed -e 's/^  - {name: qs, kind: quasistatic.*$/  - {name: relax, kind: quasistatic, load_steps: 1}/' \
    -e 's/^  - {name: cut, kind: release.*$/  - {name: d2, steps: 3}/' "$work/last.yaml" > "$work/relax.yaml"
"${mpi[@]}" "$peridrive" "$work/relax.yaml" --out "$work/relax" --quiet > "$work/stdout" 2> "$work/stderr"
rc=$?
if [ "$rc" -eq 0 ] && ! grep -q "warning" "$work/stderr" &&
   $py -c 'import json, sys; s = json.load(open(sys.argv[1])); sys.exit(0 if s["quasistatic"][0]["work_error"] is None and s["quasistatic_work_error"] is None else 1)' "$work/relax/summary.json"; then
  ok "relaxation: work_error null, no warning"
else bad "relaxation: exit status $rc, expected 0, null work errors and no warning"; cat "$work/stderr"; fi

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

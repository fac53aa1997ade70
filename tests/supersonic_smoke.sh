#!/usr/bin/env bash
# The supersonic-rubber scene at a coarse resolution (Delta = 1 mm, 1.2 ms, same u_s / Delta and
# u_c / Delta), on 2 ranks, end to end: run, crack-tip measurement, picture. The crack from the seed
# must outrun the longitudinal waves: 1.1 < v/c_l < 1.5 (the lattice's long-wave c_l ahead of the
# tip; measured 1.22 here, 1.25 in the full scene; docs/examples/supersonic-rubber.md). Then one
# case of tools/lattice_crack_map.py (stretch (1.3, 2.4), u_s = 0.1 Delta, u_c = min): the smallest
# u_c with the far field's four speeds within 3% of Mooney-Rivlin is 3.1 Delta (3.05 is not), and
# the crack there runs at 0.6-0.9 c_L (measured 0.755; the map's finding: below c_L).
# usage: supersonic_smoke.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$mpiexec" -n 2 "$@" "$peridrive" "$src/drivers/scenes/supersonic_rubber.yaml" --quiet --out "$work/out" \
  --set bodies.strip.spacing=0.001 --set materials.rubber.cutoff=2.5e-4 \
  --set materials.rubber.fracture_separation=0.003 \
  --set "bodies.strip.breakable={min: [-1, -0.0005, -1], max: [1, 0.0005, 1]}" \
  --set stages.run.duration=0.0012 --set output.frames=25
test -s "$work/out/summary.json"
/usr/bin/python3 "$src/tools/crack_tip_lattice.py" "$work/out" > "$work/tip.json"
cat "$work/tip.json"
test -s "$work/out/tip_region.png"
/usr/bin/python3 - "$work/tip.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
ok = 1.1 < r["v_over_cl"] < 1.5
print(("ok" if ok else "FAIL") + f": v/c_l = {r['v_over_cl']:.3f}, v/c_s = {r['v_over_cs']:.3f}")
sys.exit(0 if ok else 1)
PY
flags=()
for f in "$@"; do flags+=("--mpi-flag=$f"); done
printf 'lx,ly,us,uc,nu,b,duration,length\n1.3,2.4,0.1,min,0.005,0.4,0.0015,0.15\n' > "$work/cases.csv"
/usr/bin/python3 "$src/tools/lattice_crack_map.py" "$src/drivers/scenes/supersonic_rubber.yaml" "$work/cases.csv" \
  "$work/map.csv" --work "$work/map" --mpiexec "$mpiexec" --peridrive "$peridrive" "${flags[@]}" \
  --set bodies.strip.spacing=0.001 --set "bodies.strip.breakable={min: [-1, -0.0005, -1], max: [1, 0.0005, 1]}" \
  --set output.frames=25
/usr/bin/python3 - "$work/map.csv" <<'PY'
import csv, sys
r = next(csv.DictReader(open(sys.argv[1])))
uc, dev, v = float(r["uc"]), float(r["mr_deviation"]), float(r["v_mean_over_cl"])
ok = abs(uc - 3.1) < 1e-9 and 0.02 < dev <= 0.03 and 0.6 < v < 0.9
print(("ok" if ok else "FAIL") + f": u_c = {uc} Delta, Mooney-Rivlin deviation {dev:.4f}, v/c_L = {v:.3f}")
sys.exit(0 if ok else 1)
PY

#!/usr/bin/env bash
# The default scene (example 7.1) at a coarse resolution on 2 ranks: the slit must grow into a
# running crack, the outputs must be complete and readable, and the pictures must be drawn.
# usage: demo_smoke.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
out=$(mktemp -d)/demo
trap 'rm -rf "$(dirname "$out")"' EXIT
"$mpiexec" -n 2 "$@" "$peridrive" --out "$out" --quiet --set bodies.sheet.spacing=3.125e-4 --set stages.0.duration=1.8e-4
/usr/bin/python3 "$src/tools/plot_results.py" "$out"
/usr/bin/python3 - "$out" <<'PY'
import json, sys, h5py, numpy as np
out = sys.argv[1]
s = json.load(open(f"{out}/summary.json"))
checks = []
def check(name, ok, detail):
    checks.append(ok)
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
check("nodes", s["nodes"] == 160 * 160, s["nodes"])
check("ranks", s["ranks"] == 2, s["ranks"])
check("bond kernel named", s["bond_kernel"] in ("avx512", "avx2", "portable"), s["bond_kernel"])
# The slit (10 mm) grows: at least 500 bonds break beyond the pre-cracked ones.
check("crack grows", s["broken_bonds"] > 500, f'{s["broken_bonds"]} bonds broken, {s["precrack_bonds"]} pre-cracked')
check("energy balance", s["energy_balance_error"] < 0.05, s["energy_balance_error"])
with h5py.File(f"{out}/frames.h5", "r") as f:
    frames = sorted(f["frames"].keys())
    check("frames", len(frames) == 26 and s["frames"] == 26, len(frames))
    dmg = f["frames"][frames[-1]]["damage"][...]
    ref = f["mesh/reference_position"][...]
    # Crack length along the slit line: extent in x of fully separated nodes near y = 0.
    near = np.abs(ref[:, 1]) < 1e-3
    cracked = ref[near & (dmg > 0.3), 0]
    length = cracked.max() - cracked.min() if len(cracked) else 0.0
    check("crack length", length > 0.015, f"{length * 1e3:.1f} mm (slit 10 mm)")
xdmf = open(f"{out}/frames.xdmf").read()
check("xdmf", xdmf.count("<Time ") == 26, xdmf.count("<Time "))
import os
check("pictures", all(os.path.getsize(f"{out}/{p}") > 10000 for p in ("damage.png", "deformed.png", "energies.png")), "damage/deformed/energies.png")
print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)
PY

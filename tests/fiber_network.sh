#!/usr/bin/env bash
# Example 7.6 (drivers/scenes/fiber_network.yaml), its first 0.6 ns on 2 ranks: the generated
# network has its 8 129 nodes; the moving clamp has carried the network's right end 6 nm
# (10 m/s); the work it did is held as strain and kinetic energy (energy balance); no bond has
# broken at 3% stretch; the frames' strain energy density integrates to the series' strain energy;
# the picture is drawn.
# usage: fiber_network.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$mpiexec" -n 2 "$@" "$peridrive" "$src/drivers/scenes/fiber_network.yaml" --out "$tmp/net" --quiet \
  --set stages.0.duration=0.6e-9 --set output.frames=4
/usr/bin/python3 "$src/tools/plot_fiber.py" "$tmp/net" > /dev/null
/usr/bin/python3 - "$tmp/net" <<'PY'
import json, os, sys, h5py, numpy as np
out = sys.argv[1]
checks = []
def check(name, ok, detail):
    checks.append(ok)
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
s = json.load(open(f"{out}/summary.json"))
f = s["final"]
check("nodes", s["nodes"] == 8129 and s["ranks"] == 2, s["nodes"])
with h5py.File(f"{out}/frames.h5", "r") as h:
    keys = sorted(h["frames"].keys())
    x0 = h["frames"][keys[0]]["position"][()][:, 0]
    x1 = h["frames"][keys[-1]]["position"][()][:, 0]
right = x0 >= 194e-9
moved = x1[right] - x0[right]
check("clamp moved 6 nm", np.allclose(moved, 6e-9, rtol=1e-9), f"{moved.min() * 1e9:.6f}..{moved.max() * 1e9:.6f} nm")
check("energy balance", s["energy_balance_error"] < 1e-3,
      f'W = {f["external_work"]:.3e} J, strain {f["strain_energy"]:.3e}, kinetic {f["kinetic_energy"]:.3e}, error {s["energy_balance_error"]:.1e}')
check("stretched network stores the work", f["strain_energy"] > 0.5 * f["external_work"] > 0, f'{f["strain_energy"] / f["external_work"]:.2f} of the work')
check("no bond broken", s["broken_bonds"] == 0, s["broken_bonds"])
# The frames' strain energy density (bonds and long-range pairs), times the nodes' measures, sums
# to the series' strain energy at the same steps.
import csv
rows = {int(r["step"]): float(r["strain_energy"]) for r in csv.DictReader(open(f"{out}/series.csv"))}
worst, compared = 0.0, 0
with h5py.File(f"{out}/frames.h5", "r") as h:
    V = h["mesh/volume"][()]
    for k in keys:
        step = int(h["frames"][k].attrs["step"])
        if step in rows:
            total = float((h["frames"][k]["strain_energy_density"][()] * V).sum())
            worst = max(worst, abs(total - rows[step]) / abs(rows[step]))
            compared += 1
check("frames' energy density sums to the strain energy", compared >= 2 and worst < 1e-9, f"{compared} frames, largest difference {worst:.1e}")
check("picture", os.path.getsize(f"{out}/network.png") > 10000, "network.png")
print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)
PY

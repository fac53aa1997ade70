#!/usr/bin/env bash
# Example 7.5 (drivers/scenes/fiber_long_range.yaml), its first nanosecond, on 1 and 2 ranks: the
# two runs give the same frames bit for bit (each rank evaluates the long-range pairs of its own
# nodes from the same gathered positions, in the same order), and the same energies up to the
# order of their sums over ranks; the first segments
# coil (the long-range energy falls more than tenfold, the end-to-end distance by more than 10%);
# the energy balance holds; a run resumed from a checkpoint ends bit for bit where the
# uninterrupted one does; the picture is drawn.
# usage: fiber_coil.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scene="$src/drivers/scenes/fiber_long_range.yaml"
"$peridrive" "$scene" --out "$tmp/one" --quiet --set stages.0.duration=1.0e-9 --set output.frames=11
"$mpiexec" -n 2 "$@" "$peridrive" "$scene" --out "$tmp/two" --quiet --set stages.0.duration=1.0e-9 --set output.frames=11
# The same run with checkpoints every 5 000 steps, resumed from its last one (step 10 000): it must
# end where the uninterrupted run ends, bit for bit (the Verlet list is rebuilt on resume; its
# pairs are summed in table order whenever it was built).
"$peridrive" "$scene" --out "$tmp/ckpt" --quiet --set stages.0.duration=1.0e-9 --set output.frames=11 \
  --set output.checkpoint_every_steps=5000
"$peridrive" --resume "$tmp/ckpt" --quiet > /dev/null
/usr/bin/python3 "$src/tools/plot_fiber.py" "$tmp/one" > /dev/null
/usr/bin/python3 - "$tmp" <<'PY'
import csv, json, os, sys, h5py, numpy as np
tmp = sys.argv[1]
checks = []
def check(name, ok, detail):
    checks.append(ok)
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
one = json.load(open(f"{tmp}/one/summary.json"))
two = json.load(open(f"{tmp}/two/summary.json"))
check("nodes", one["nodes"] == 280 and two["ranks"] == 2, f'{one["nodes"]} nodes')
series = [list(csv.DictReader(open(f"{tmp}/{d}/series.csv"))) for d in ("one", "two")]
# Energies are sums over ranks (their order differs): equal to 1e-9 of the largest energy.
cols = ("kinetic_energy", "strain_energy", "dissipated_energy")
scale = max(abs(float(r[c])) for r in series[0] for c in cols)
worst = max(abs(float(a[c]) - float(b[c])) for a, b in zip(*series) for c in cols) / scale
check("series on 1 and 2 ranks", len(series[0]) == len(series[1]) and worst < 1e-9, f"{len(series[0])} rows, largest difference {worst:.1e}")
differ = []
with h5py.File(f"{tmp}/one/frames.h5", "r") as a, h5py.File(f"{tmp}/two/frames.h5", "r") as b:
    keys = sorted(a["frames"].keys())
    for k in keys:
        if not np.array_equal(a["frames"][k]["position"][()], b["frames"][k]["position"][()]):
            differ.append(k)
    p0 = a["frames"][keys[0]]["position"][()]
    p1 = a["frames"][keys[-1]]["position"][()]
check("frames identical on 1 and 2 ranks", not differ, f"{len(keys)} frames, differing: {differ[:3]}")
with h5py.File(f"{tmp}/one/frames.h5", "r") as a, h5py.File(f"{tmp}/ckpt/frames.h5", "r") as b:
    same = sorted(b["frames"].keys()) == keys and all(
        np.array_equal(a["frames"][k]["position"][()], b["frames"][k]["position"][()]) for k in keys)
check("resumed from a checkpoint: same frames", same, "bit for bit")
e0, e1 = float(series[0][0]["strain_energy"]), float(series[0][-1]["strain_energy"])
check("segments coil (long-range energy falls)", e1 < 10 * e0 < 0, f"{e0:.3e} -> {e1:.3e} J")
d0, d1 = np.linalg.norm(p0[-1] - p0[0]), np.linalg.norm(p1[-1] - p1[0])
check("fiber shortens", d1 < 0.9 * d0, f"end to end {d0 * 1e9:.1f} -> {d1 * 1e9:.1f} nm")
check("energy balance", one["energy_balance_error"] < 0.01, one["energy_balance_error"])
check("picture", os.path.getsize(f"{tmp}/one/fiber.png") > 10000, "fiber.png")
print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)
PY

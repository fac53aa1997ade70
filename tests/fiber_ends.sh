#!/usr/bin/env bash
# Example 7.5, Fig. 10's lower plot (drivers/scenes/fiber_attracting_ends.yaml), its first
# nanosecond, on 1 and 2 ranks: segments 1 and 12, which a segments rule makes attract (cutoff
# 12 nm, beyond the section's 5 nm), start 6.2 nm apart (mean distance of a node to the other's
# centreline) and end in contact over their whole length: mean distance within 1.5 diameters
# (measured 0.95 nm), each segment's length within 1.5 diameters of the other at least 6 of its
# 7 nm (measured 7.0), and wound about each other (Gauss linking integral of the two centrelines
# at least 0.25 in magnitude; measured 0.59 at 1 ns; 0.00 for two straight segments side by side). The
# runs on 1 and 2 ranks give the same frames bit for bit, and so does a run resumed from a
# checkpoint; the energy balance holds.
# usage: fiber_ends.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
scene="$src/drivers/scenes/fiber_attracting_ends.yaml"
short=(--set stages.0.duration=1.0e-9 --set output.frames=11)
"$peridrive" "$scene" --out "$tmp/one" --quiet "${short[@]}"
"$mpiexec" -n 2 "$@" "$peridrive" "$scene" --out "$tmp/two" --quiet "${short[@]}"
"$peridrive" "$scene" --out "$tmp/ckpt" --quiet "${short[@]}" --set output.checkpoint_every_steps=5000
"$peridrive" --resume "$tmp/ckpt" --quiet > /dev/null
/usr/bin/python3 "$src/tools/plot_fiber.py" "$tmp/one" --pair 1 12 > /dev/null
/usr/bin/python3 - "$tmp" <<'PY'
import csv, json, os, sys, h5py, numpy as np
tmp = sys.argv[1]
checks = []
def check(name, ok, detail):
    checks.append(ok)
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
one = json.load(open(f"{tmp}/one/summary.json"))
check("nodes", one["nodes"] == 196, f'{one["nodes"]} nodes')
def frames(d):
    with h5py.File(f"{tmp}/{d}/frames.h5", "r") as f:
        return {k: f["frames"][k]["position"][()] for k in f["frames"]}
a, b, c = frames("one"), frames("two"), frames("ckpt")
check("frames identical on 1 and 2 ranks", a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a),
      f"{len(a)} frames")
check("resumed from a checkpoint: same frames", a.keys() == c.keys() and all(np.array_equal(a[k], c[k]) for k in a),
      "bit for bit")
rows = list(csv.DictReader(open(f"{tmp}/one/fiber_pair.csv")))
first, last = rows[0], rows[-1]
d0, d1 = float(first["mean_distance"]), float(last["mean_distance"])
check("segments 1 and 12 start apart", d0 > 5e-9, f"mean distance {d0 * 1e9:.2f} nm")
check("and end in contact (within 1.5 diameters)", d1 < 1.5e-9 and float(last["largest_distance"]) < 1.5e-9,
      f'mean {d1 * 1e9:.2f} nm, largest {float(last["largest_distance"]) * 1e9:.2f} nm')
w = float(last["length_within_1.5d"])
check("over their length", w >= 6e-9, f"{w * 1e9:.1f} of 7 nm within 1.5 diameters")
lk = float(last["linking"])
check("wound about each other", abs(lk) >= 0.25, f"Gauss linking integral {lk:+.2f}")
check("energy balance", one["energy_balance_error"] < 0.01, one["energy_balance_error"])
check("picture", os.path.getsize(f"{tmp}/one/fiber_pair.png") > 10000, "fiber_pair.png")
print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)
PY

#!/usr/bin/env bash
# Example 7.1's crack speed against the pre-stretch (docs/examples/slit-membrane.md, "Crack speed
# against the pre-stretch"), reduced: tools/speed_vs_stretch.py at m = 3 (horizon 0.9375 mm,
# 25 600 nodes), preloaded by SNES to lambda = 1.2 and 1.4, released, 2 ranks. The faster
# pre-stretch runs the crack at least 15% faster (the study: 303 -> 391 m/s at m = 6, +29%), and
# its steady mean is within 15% of the m = 6 value, 390.9 m/s.
# usage: speed_vs_stretch.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 "$src/tools/speed_vs_stretch.py" --peridrive "$peridrive" --mpiexec "$mpiexec" \
  "--mpiexec-flags=$*" --np 2 --m 3 --stretch 1.2 1.4 --safety-factor 0.25 --out "$work"
/usr/bin/python3 - "$work/speed_vs_stretch.csv" <<'PY'
import csv, sys
rows = {float(r["stretch"]): r for r in csv.DictReader(open(sys.argv[1]))}
if set(rows) != {1.2, 1.4} or not all(rows[k]["mean_speed"] for k in rows):
    sys.exit(f"FAIL: runs missing or without a steady speed: {sorted(rows)}")
slow, fast = float(rows[1.2]["mean_speed"]), float(rows[1.4]["mean_speed"])
reference = 390.9
print(f"steady mean speed {slow:.1f} m/s at stretch 1.2, {fast:.1f} m/s at 1.4 (x{fast / slow:.3f}); "
      f"{100 * (fast / reference - 1):+.1f}% from the m = 6 value {reference} m/s")
fails = []
if not fast >= 1.15 * slow:
    fails.append("the crack at stretch 1.4 is not 15% faster than at 1.2")
if abs(fast / reference - 1) > 0.15:
    fails.append("stretch 1.4 outside 15% of the m = 6 speed")
if fails:
    sys.exit("FAIL: " + "; ".join(fails))
PY

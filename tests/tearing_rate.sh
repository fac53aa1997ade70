#!/usr/bin/env bash
# Example 7.3 (drivers/scenes/membrane_tearing.yaml) on 2 ranks, to 1.2 ms. Checks: two cracks
# nucleate at the ends of the lifted segment (x = 25 and 45 mm), and each tears into the sheet at
# a rate below, and within 20% of, the inextensible-flap rate da/dt = (v_f^2 + v_up^2) / (2 v_f)
# (the flap from the crack tips to the grip stays straight and taut:
# (a - v_f t)^2 + (v_up t)^2 = a^2; an elastic flap stretches, so it tears somewhat slower).
# usage: tearing_rate.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$mpiexec" -n 2 "$@" "$peridrive" "$src/drivers/scenes/membrane_tearing.yaml" --out "$tmp/out" --quiet \
  --set stages.0.duration=1.2e-3 --set output.frames=2
/usr/bin/python3 - "$tmp/out" <<'PY'
import csv, json, sys
out = sys.argv[1]
scene_grip_ends, v_forward, v_up = (0.025, 0.045), 10.0, 20.0
rate_inextensible = (v_forward**2 + v_up**2) / (2 * v_forward)  # 25 m/s
s = json.load(open(f"{out}/summary.json"))
checks = []
def check(name, ok, detail):
    checks.append(ok)
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
rows = list(csv.DictReader(open(f"{out}/tips.csv")))
for x_end in scene_grip_ends:
    # The track that starts at this end of the grip and runs into the sheet (-y).
    tracks = [t for t in s["crack_tips"] if abs(t["first_position"][0] - x_end) < 0.0015
              and t["position"][1] < t["first_position"][1] - 0.01]
    check(f"crack from the grip end x = {x_end * 1e3:.0f} mm", len(tracks) == 1,
          f"{len(tracks)} tip track(s) start within 1.5 mm of it and advance more than 10 mm")
    if len(tracks) != 1:
        continue
    r = [row for row in rows if int(row["track"]) == tracks[0]["track"] and 5e-4 <= float(row["time"]) <= 1.2e-3]
    t = [float(row["time"]) for row in r]
    y = [float(row["y"]) for row in r]
    n, mt, my = len(t), sum(t) / len(t), sum(y) / len(y)
    slope = sum((a - mt) * (b - my) for a, b in zip(t, y)) / sum((a - mt) ** 2 for a in t)
    rate = -slope  # least-squares tearing rate over 0.5-1.2 ms
    ratio = rate / rate_inextensible
    check(f"tearing rate at x = {x_end * 1e3:.0f} mm", 0.80 <= ratio <= 1.02,
          f"{rate:.2f} m/s over {n} samples = {ratio:.3f} of the inextensible-flap rate {rate_inextensible:.1f} m/s (band 0.80-1.02)")
e = s["energy_balance_error"]
check("energy balance", e < 1e-2, f"error {e:.2e} (limit 1e-2)")
print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)
PY

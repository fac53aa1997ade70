#!/usr/bin/env bash
# Example 7.4 (drivers/scenes/blunt_tool.yaml) on 2 ranks, to 5 ms: the crack starts at the
# notch and is cut by the tool, running just ahead of it (not a runaway dynamic crack); the
# sheet pushes back on the tool; the energy balance, with the tool's work and friction, holds.
# usage: blunt_tool.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$mpiexec" -n 2 "$@" "$peridrive" "$src/drivers/scenes/blunt_tool.yaml" --out "$tmp/out" --quiet \
  --set stages.0.duration=5.0e-3 --set output.frames=2
/usr/bin/python3 - "$tmp/out" <<'PY'
import csv, json, math, sys
out = sys.argv[1]
radius, notch_tip = 1.5e-3, (2.0e-3, 11.5e-3)
s = json.load(open(f"{out}/summary.json"))
rows = list(csv.DictReader(open(f"{out}/series.csv")))
checks = []
def check(name, ok, detail):
    checks.append(ok)
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
first = min(s["crack_tips"], key=lambda t: t["first_time"])
d = math.dist(first["first_position"][:2], notch_tip)
check("crack starts at the notch", d < 1e-3, f"first tip at {[round(c * 1e3, 2) for c in first['first_position'][:2]]} mm, {d * 1e3:.2f} mm from the notch tip")
last = rows[-1]
rod_x = float(last["rod_x"])
tips = [float(last[f"tip{k}_x"]) for k in range(4) if last.get(f"tip{k}_x")]
front = max(tips) if tips else float("nan")
ahead = front - (rod_x + radius)
check("crack cut by the tool", front > rod_x + 0.5 * radius and ahead < 3e-3,
      f"front tip at x = {front * 1e3:.2f} mm, tool axis at {rod_x * 1e3:.2f} mm: {ahead * 1e3:.2f} mm ahead of the tool's front (limits: past the axis by R/2, at most 3 mm ahead)")
late = [float(r["rod_force_x"]) for r in rows if float(r["time"]) >= 2.5e-3]
mean = sum(late) / len(late)
check("sheet resists the tool", mean > 0, f"mean force on the sheet along the tool's motion over 2.5-5 ms: {mean:.4f} N")
e = s["energy_balance_error"]
check("energy balance", e < 5e-3, f"error {e:.2e} (limit 5e-3; tool work {float(last['external_work']):.3e} J)")
print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)
PY

#!/usr/bin/env bash
# drivers/scenes/plate_with_hole.yaml at half the resolution (2 ranks): the nodes are the grid's
# cell centres outside the hole and the notch (counted here), the energy balance holds, and the
# sheet tears from the hole's rim at its horizontal diameter and from the notch tip.
# usage: plate_with_hole.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 src=$2 mpiexec=$3
shift 3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$mpiexec" -n 2 "$@" "$peridrive" "$src/drivers/scenes/plate_with_hole.yaml" --set bodies.plate.spacing=0.0005 \
  --out "$work/out" --quiet
/usr/bin/python3 - "$work/out" <<'PY'
import json, sys
import h5py
import numpy as np
out = sys.argv[1]
s = json.load(open(out + "/summary.json"))
# The cell centres of a 40 mm square at 0.5 mm outside the circle r = 5 mm and the V-notch.
notch = [(-0.0201, -0.0008), (-0.014, 0.0), (-0.0201, 0.0008)]
def in_polygon(x, y):
    inside = False
    for (ax, ay), (bx, by) in zip(notch, notch[-1:] + notch[:-1]):
        if (ay > y) != (by > y) and x < (bx - ax) * (y - ay) / (by - ay) + ax:
            inside = not inside
    return inside
count = 0
for j in range(80):
    for i in range(80):
        x, y = -0.02 + (i + 0.5) * 0.0005, -0.02 + (j + 0.5) * 0.0005
        if x * x + y * y > 0.005 ** 2 and not in_polygon(x, y):
            count += 1
f = h5py.File(out + "/frames.h5", "r")
X = f["mesh/reference_position"][:]
damage = f["frames/" + sorted(f["frames"])[-1]]["damage"][:]
r = np.hypot(X[:, 0], X[:, 1])
torn = damage > 0.35
rim = torn & (r < 0.0065)
at_diameter = rim & (np.abs(X[:, 1]) < 0.0015)
at_notch = torn & (X[:, 0] > -0.0155) & (X[:, 0] < -0.012) & (np.abs(X[:, 1]) < 0.0015)
print("plate_with_hole: %d nodes (%d counted), %d bonds broken, energy balance error %.2e, torn rim nodes %d "
      "(%d within 1.5 mm of the horizontal diameter), torn at the notch tip %d"
      % (s["nodes"], count, s["broken_bonds"], s["energy_balance_error"], rim.sum(), at_diameter.sum(), at_notch.sum()))
ok = (s["nodes"] == count and s["broken_bonds"] > 100 and s["energy_balance_error"] < 0.01
      and at_diameter.sum() >= 2 and at_diameter.sum() == rim.sum() and at_notch.sum() >= 1)
sys.exit(0 if ok else 1)
PY

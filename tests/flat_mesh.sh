#!/usr/bin/env bash
# A flat triangle mesh whose z carries round-off (a CAD export, an STL's float32 coordinates) is
# a flat sheet: its nodes' z are set to one value, with one warning naming the spread, and it
# runs as the exact mesh does. A 10 mm square (Gmsh, edges about 0.5 mm) with a slit, pulled
# apart for 60 us on 2 ranks:
#  - exact z = 0: crack tips tracked (tips.csv has rows), no warning;
#  - z = +1e-18 m on odd node tags, -1e-18 m on even ones: one warning ("lie within 2e-18 m
#    in z"), the same tips.csv and the same final positions, bit for bit, as the exact mesh;
#  - a bump of 1e-4 m (1e-2 of the size, beyond the 1e-6 tolerance): a curved sheet, no warning,
#    no crack tips tracked (curved sheets have none);
#  - the square turned 30 degrees about x: a plane whose normal is off z, run as a curved sheet,
#    with one warning naming the normal.
# usage: flat_mesh.sh PERIDRIVE GMSH MPIEXEC [MPI flags...]
set -u
peridrive=$1 gmsh=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp" || exit 1
cat > square.geo <<'EOF'
L = 0.005; lc = 0.0005;
Point(1) = {-L, -L, 0, lc}; Point(2) = {L, -L, 0, lc}; Point(3) = {L, L, 0, lc}; Point(4) = {-L, L, 0, lc};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Physical Surface("sheet") = {1};
Mesh.Algorithm = 6;
EOF
"$gmsh" -2 -format msh22 square.geo -o exact.msh > gmsh.log 2>&1 || { cat gmsh.log; exit 1; }
# z of the $Nodes section's lines (tag x y z): +-1e-18 on every other node, or a bump near (2, 2) mm.
/usr/bin/python3 - <<'PY'
import math
lines = open("exact.msh").read().split("\n")
at = lines.index("$Nodes")
n = int(lines[at + 1])
def write(name, dz):
    out = list(lines)
    for k in range(at + 2, at + 2 + n):
        tag, x, y, z = out[k].split()
        out[k] = " ".join([tag, x, y, repr(float(z) + dz(int(tag), float(x), float(y)))])
    open(name, "w").write("\n".join(out))
write("noisy.msh", lambda t, x, y: (1e-18 if t % 2 else -1e-18))
write("bumpy.msh", lambda t, x, y: 1e-4 * math.exp(-((x - 0.002) ** 2 + (y - 0.002) ** 2) / 1e-6))
# The exact square turned by 30 degrees about x: a plane sheet whose normal is (0, -1/2, sqrt(3)/2).
out = list(lines)
for k in range(at + 2, at + 2 + n):
    tag, x, y, z = out[k].split()
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    out[k] = " ".join([tag, x, repr(c * float(y)), repr(s * float(y))])
open("tilted.msh", "w").write("\n".join(out))
PY
for m in exact noisy bumpy tilted; do
  cat > "$m.yaml" <<EOF
name: flat-mesh-$m
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 2.0}
bodies:
  sheet: {kind: membrane, material: rubber, mesh: $m.msh, thickness: 0.0005, spacing: 0.0005}
cracks:
  - {name: slit, from: [-0.0015, 0.00001, 0], to: [0.0015, 0.00001, 0]}
boundaries:
  - {name: top, region: {min: [-1, 0.0042, -1], max: [1, 1, 1]}, velocity: [0, 40, 0]}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, -0.0042, 1]}, velocity: [0, -40, 0]}
stages:
  - {name: pull, duration: 6.0e-5}
output: {frames: 2, series_every: 10}
EOF
  "${mpi[@]}" "$peridrive" "$m.yaml" --out "out-$m" --quiet > "$m.stdout" 2> "$m.stderr"
  echo "$?" > "$m.rc"
done
/usr/bin/python3 - <<'PY'
import os, sys
import h5py
import numpy as np
checks = []
def check(name, ok, detail):
    checks.append(bool(ok))
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
def run(m):
    rc = int(open(f"{m}.rc").read())
    err = open(f"{m}.stderr").read()
    warnings = [l for l in err.splitlines() if l.startswith("peridrive: warning:")]
    tips = open(f"out-{m}/tips.csv").read().splitlines() if os.path.exists(f"out-{m}/tips.csv") else None
    pos = None
    if rc == 0:
        with h5py.File(f"out-{m}/frames.h5", "r") as f:
            last = sorted(f["frames"])[-1]
            pos = f["frames"][last]["position"][...]
    return rc, err, warnings, tips, pos
rc, err, w, tips_exact, pos_exact = run("exact")
check("exact mesh", rc == 0 and not w and tips_exact and len(tips_exact) > 1,
      f"exit {rc}, {len(w)} warnings, {len(tips_exact or []) - 1} crack-tip rows")
rc, err, w, tips, pos = run("noisy")
want = (f"bodies.sheet.mesh: the nodes of '{os.path.realpath('noisy.msh')}' lie within 2e-18 m in z (at most 1e-06 "
        "of its size): taken as a flat sheet, every z set to 0 m")
check("z round-off warned once", rc == 0 and len(w) == 1 and want in w[0], w[0][:160] if w else err[:300])
check("z round-off runs as the exact mesh", tips == tips_exact and pos is not None and np.array_equal(pos, pos_exact),
      f"tips.csv {'same' if tips == tips_exact else 'differs'}, final positions "
      f"{'same bits' if pos is not None and np.array_equal(pos, pos_exact) else 'differ'}")
rc, err, w, tips, pos = run("bumpy")
check("a bump is a curved sheet", rc == 0 and not w and tips is None,
      f"exit {rc}, {len(w)} warnings, tips.csv {'absent' if tips is None else 'written'}")
rc, err, w, tips, pos = run("tilted")
want = (f"bodies.sheet.mesh: '{os.path.realpath('tilted.msh')}' is a plane sheet with normal (0, -0.5, 0.866025), "
        "not along z: it runs as a curved sheet")
check("a tilted plane is warned of", rc == 0 and len(w) == 1 and want in w[0] and tips is None,
      (w[0][:160] if w else err[:300]) + f"; tips.csv {'absent' if tips is None else 'written'}")
sys.exit(0 if all(checks) else 1)
PY

#!/usr/bin/env bash
# Resolved scenes far above the 64 KB an HDF5 attribute can hold, on 2 ranks: a fiber whose path
# has 3000 points, a sheet with 1000 cracks, a 100 KB description full of quotes, backslashes,
# newlines and non-ASCII text. Each runs to the end, frames.h5 and checkpoint.h5 hold the scene
# text exactly as scene.resolved.yaml (frames) and as emitted without comments (checkpoint), and
# --resume from the run's checkpoint ends bit for bit where the run ended. Then a checkpoint and a
# frames.h5 written before the scene moved into a dataset (tests/restart/old_layout/, peridrive
# 0.1.0 at revision 5d1f4dfc4753, tests/restart/tiny_sheet.yaml, 2 ranks, step 30 of 40) are
# continued: same final positions as a run from the start (relative 1e-12).
# usage: large_scene.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
py=/usr/bin/python3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pass=0 fail=0
ok() { echo "ok   $1"; pass=$((pass + 1)); }
bad() { echo "FAIL $1"; fail=$((fail + 1)); }

"$py" - "$work" <<'PY'
import sys
work = sys.argv[1]
sheet = """materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, critical_stretch: 1.6}
bodies:
  sheet: {material: rubber, origin: [0, 0, 0], size: [0.005, 0.005], thickness: 0.0005, spacing: 0.0005}
boundaries:
  - {name: top, region: {min: [-1, 0.0045, -1], max: [1, 1, 1]}, velocity: [0, 5, 0]}
stages:
  - {name: pull, steps: 40}
output: {frames: 4, series_every: 10, checkpoint_every_steps: 15}
"""
# A millimetre fiber along a zigzag of 3000 points (30 nodes), stretched by its initial velocity.
points = ", ".join(f"[{k * 1.00001e-6!r}, {(k % 2) * 1.0e-7}, 0]" for k in range(3000))
open(f"{work}/fiber3000.yaml", "w").write(f"""name: fiber3000
materials:
  gum: {{model: membrane, density: 1000, bulk_modulus: 1.0e9}}
bodies:
  fiber: {{kind: fiber, material: gum, diameter: 1.0e-4, spacing: 1.0e-4, path: [{points}]}}
initial: {{velocity_gradient: [[100, 0, 0], [0, 0, 0], [0, 0, 0]]}}
stages:
  - {{name: stretch, steps: 40}}
output: {{frames: 4, series_every: 10, checkpoint_every_steps: 15}}
""")
# 1000 short cracks scattered over the sheet (some cut bonds, most fall between nodes).
cracks = "\n".join(f"  - {{from: [{(k % 40) * 1.2e-4 + 1e-5:.6e}, {(k // 40) * 1.9e-4 + 2e-5:.6e}, 0], "
                   f"to: [{(k % 40) * 1.2e-4 + 4e-5:.6e}, {(k // 40) * 1.9e-4 + 9e-5:.6e}, 0]}}"
                   for k in range(1000))
open(f"{work}/cracks1000.yaml", "w").write("name: cracks1000\n" + sheet + "cracks:\n" + cracks + "\n")
# 100 KB of description that needs quoting: quotes, backslashes, newlines, tabs, '#', non-ASCII.
text = r'line \"quoted\" \\ back\tslash # not a comment: ünïcode ✓ 漢字\n' * 1700
open(f"{work}/description.yaml", "w").write(f'name: description\ndescription: "{text}"\n' + sheet)
PY

# check.py DIR: the scene text in frames.h5 (as scene.resolved.yaml) and in checkpoint.h5 (the
# same without its comment lines), above 64 KB; frames and checkpoint complete.
cat > "$work/check.py" <<'PY'
import json, os, sys, h5py
d = sys.argv[1]
resolved = open(f"{d}/scene.resolved.yaml", encoding="utf-8").read()
problems = []
if len(resolved.encode()) <= 65536:
    problems.append(f"resolved scene only {len(resolved.encode())} bytes: not above 64 KB")
with h5py.File(f"{d}/frames.h5", "r") as f:
    if f["scene"].asstr()[()] != resolved:
        problems.append("frames.h5 /scene differs from scene.resolved.yaml")
    if len(f["frames"]) != 4:
        problems.append(f"frames.h5 holds {len(f['frames'])} frames, expected 4")
with h5py.File(f"{d}/checkpoint.h5", "r") as f:
    stored = f["scene"].asstr()[()]
    uncommented = "".join(l for l in resolved.splitlines(True) if not l.startswith("#"))
    if stored != uncommented:
        problems.append("checkpoint.h5 /scene differs from the resolved scene without its comments")
    if int(f.attrs["step"]) != 30:
        problems.append(f"checkpoint at step {int(f.attrs['step'])}, expected 30")
if json.load(open(f"{d}/summary.json"))["steps"] != 40:
    problems.append("summary.json: steps != 40")
print("; ".join(problems) or f"scene {len(resolved.encode())} bytes in frames.h5 and checkpoint.h5")
sys.exit(1 if problems else 0)
PY

# same.py A B TOLERANCE: final positions of A and B within TOLERANCE (relative; 0: the same bits).
cat > "$work/same.py" <<'PY'
import sys, h5py, numpy as np
a, b, tol = sys.argv[1], sys.argv[2], float(sys.argv[3])
with h5py.File(f"{a}/frames.h5", "r") as fa, h5py.File(f"{b}/frames.h5", "r") as fb:
    ka, kb = sorted(fa["frames"]), sorted(fb["frames"])
    x, y = fa["frames"][ka[-1]]["position"][...], fb["frames"][kb[-1]]["position"][...]
    steps = [int(fa["frames"][k].attrs["step"]) for k in ka], [int(fb["frames"][k].attrs["step"]) for k in kb]
rel = float(np.abs(x - y).max() / np.abs(x).max())
print(f"frames at steps {steps[1]}; final positions: max relative difference {rel:.3e}")
sys.exit(0 if steps[0] == steps[1] and (rel == 0 if tol == 0 else rel <= tol) else 1)
PY

for case in fiber3000 cracks1000 description; do
  out="$work/$case"
  "${mpi[@]}" "$peridrive" "$work/$case.yaml" --out "$out" --quiet > "$work/stdout" 2> "$work/stderr"
  rc=$?
  if [ "$rc" -ne 0 ]; then
    bad "$case: exit status $rc, expected 0: $(head -c 300 "$work/stderr")"; continue
  fi
  if msg=$("$py" "$work/check.py" "$out" 2>&1); then ok "$case: $msg"; else bad "$case: $msg"; fi
  # Continue a copy from its checkpoint (step 30): the same end, bit for bit.
  cp -r "$out" "$out-resumed"
  "${mpi[@]}" "$peridrive" --resume "$out-resumed" --quiet > "$work/stdout" 2> "$work/stderr"
  rc=$?
  if [ "$rc" -ne 0 ]; then
    bad "$case resumed: exit status $rc, expected 0: $(head -c 300 "$work/stderr")"
  elif msg=$("$py" "$work/same.py" "$out" "$out-resumed" 0 2>&1); then
    ok "$case resumed: $msg"
  else
    bad "$case resumed: $msg"
  fi
done

# A checkpoint and frames.h5 of the old layout (scene as an attribute, no mesh connectivity).
cp -r "$src/tests/restart/old_layout" "$work/old"
"${mpi[@]}" "$peridrive" "$src/tests/restart/tiny_sheet.yaml" --out "$work/fresh" --quiet > /dev/null 2> "$work/stderr" ||
  bad "tiny_sheet run: $(head -c 300 "$work/stderr")"
"${mpi[@]}" "$peridrive" --resume "$work/old" --quiet > "$work/stdout" 2> "$work/stderr"
rc=$?
if [ "$rc" -ne 0 ]; then
  bad "old layout resumed: exit status $rc, expected 0: $(head -c 300 "$work/stderr")"
elif msg=$("$py" "$work/same.py" "$work/fresh" "$work/old" 1e-12 2>&1); then
  ok "old layout resumed: $msg"
else
  bad "old layout resumed: $msg"
fi
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

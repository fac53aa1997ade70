#!/usr/bin/env bash
# Time to a preloaded state: quasi-static SNES preload vs a damped dynamic ramp to the same band
# displacement (6 mm square membrane, bands moved 1.5 mm apart each, stretch 1.5), at two
# resolutions. Each configuration runs REPS times (default 3) alternately; medians of the wall
# time to the end of loading are printed with their ratio, and the two final displacement
# fields are compared (relative L2 difference).
# Usage: benchmarks/bench_preload.sh [PERIDRIVE] [RANKS] [REPS]
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
exe=${1:-build/peridrive}
ranks=${2:-2}
reps=${3:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene() {  # $1 spacing, $2 stages
  cat <<YAML
name: preload-bench
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000}
bodies:
  sheet: {material: rubber, origin: [0, 0, 0], size: [0.006, 0.006], thickness: 0.0005, spacing: $1}
boundaries:
  - {name: top, region: {min: [-1, 0.0054, -1], max: [1, 1, 1]}}
  - {name: bottom, region: {min: [-1, -1, -1], max: [1, 0.0006, 1]}}
stages:
$2
output: {frames: 1, series_every: 1000}
YAML
}
snes="  - {name: preload, kind: quasistatic, displacements: {top: [0, 0.0015, 0], bottom: [0, -0.0015, 0]}, load_steps: 3}
  - {name: hold, steps: 1}"
dyn="  - {name: ramp, duration: 3.0e-4, damping: 3.0e5, boundary_velocity: {top: [0, 5, 0], bottom: [0, -5, 0]}}
  - {name: settle, duration: 1.2e-3, damping: 3.0e5, boundary_velocity: {top: [0, 0, 0], bottom: [0, 0, 0]}}"
printf "%-10s %-8s %-12s %-12s %-8s %-12s\n" spacing nodes snes_s damped_s ratio rel_diff
for dx in 0.0003 0.00015; do
  scene $dx "$snes" > "$work/snes.yaml"
  scene $dx "$dyn" > "$work/dyn.yaml"
  ts=() td=()
  for ((r = 0; r < reps; ++r)); do
    mpirun -n "$ranks" "$exe" "$work/snes.yaml" --out "$work/s" --quiet
    ts+=("$($PERI_PYTHON -c "import json;print(json.load(open('$work/s/summary.json'))['wall_seconds'])")")
    mpirun -n "$ranks" "$exe" "$work/dyn.yaml" --out "$work/d" --quiet
    td+=("$($PERI_PYTHON -c "import json;print(json.load(open('$work/d/summary.json'))['wall_seconds'])")")
  done
  $PERI_PYTHON - "$work" "$dx" "${ts[*]}" "${td[*]}" <<'PY'
import sys, statistics, h5py, numpy as np
work, dx, ts, td = sys.argv[1], sys.argv[2], [float(x) for x in sys.argv[3].split()], [float(x) for x in sys.argv[4].split()]
def last(path):
    with h5py.File(path, "r") as f:
        g = f["frames"]; k = sorted(g.keys())[-1]
        return np.asarray(g[k]["displacement"])
a, b = last(f"{work}/s/frames.h5"), last(f"{work}/d/frames.h5")
ms, md = statistics.median(ts), statistics.median(td)
print(f"{dx:<10} {a.shape[0]:<8} {ms:<12.3f} {md:<12.3f} {md/ms:<8.1f} {np.linalg.norm(a-b)/np.linalg.norm(a):<12.2e}")
PY
done

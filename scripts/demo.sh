#!/usr/bin/env bash
# Quick start (a): install what is missing, build, run the default scene (Silling & Bobaru
# example 7.1) on two ranks, and draw the damage field: results in out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/install-deps.sh
scripts/build.sh
rm -rf out/demo
mpirun -n 2 build/peridrive --out out/demo "$@"
"$PERI_PYTHON" tools/plot_results.py out/demo
echo "demo: results and pictures in out/demo/ (open out/demo/frames.xdmf in ParaView)"

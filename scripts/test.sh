#!/usr/bin/env bash
# Quick start (b): install what is missing, build, and run the whole test suite through ctest
# (unit tests and tests on two MPI ranks).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/install-deps.sh
scripts/build.sh
cd build
ctest --output-on-failure --timeout 900 "$@"

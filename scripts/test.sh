#!/usr/bin/env bash
# Quick start (b): install what is missing, build, and run the whole test suite through ctest
# (unit tests and tests on two MPI ranks); then the unit tests again, built for the bond loop's
# other instruction sets (AVX2 alone, and the portable walk), in build-avx2/ and build-portable/.
# Arguments go to the first ctest (e.g. -R laws); PERI_ISAS="" skips the other instruction sets.
# ctest runs as many tests at once as there are cores; a test on n ranks declares PROCESSORS n.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/install-deps.sh
scripts/build.sh
(cd build && ctest -j "$(nproc)" --output-on-failure --timeout 900 "$@")
for isa in ${PERI_ISAS-avx2 portable}; do
  echo "test: unit tests built with PERI_ISA=$isa (build-$isa/)"
  cmake -S . -B "build-$isa" -DCMAKE_BUILD_TYPE=Release -DPERI_ISA="$isa" -DPERI_BUILD_BENCHMARKS=OFF \
    > "build-$isa.log" 2>&1 || { cat "build-$isa.log"; exit 1; }
  cmake --build "build-$isa" -j "$(nproc)" --target unit_tests >> "build-$isa.log" 2>&1 || { tail -n 30 "build-$isa.log"; exit 1; }
  (cd "build-$isa" && ctest -j "$(nproc)" -L unit --output-on-failure --timeout 900)
done

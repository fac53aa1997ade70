#!/usr/bin/env bash
# Quick start (b): install what is missing, build, and run the whole test suite through ctest
# (unit tests and tests on two MPI ranks); then the unit tests again, built for the bond loop's
# other instruction sets (AVX2 alone, and the portable walk), in build-avx2/ and build-portable/.
# Arguments go to the first ctest (e.g. -R laws); PERI_ISAS="" skips the other instruction sets.
# ctest runs as many tests at once as there are cores; a test on n ranks declares PROCESSORS n.
# The other instruction sets are built while the suite runs, at the lowest priority: the suite
# leaves the cores idle for a good part of its time (MPI start-up, Python, files), and the
# builds take only that.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
scripts/install-deps.sh
scripts/build.sh

isas=${PERI_ISAS-avx2 portable}
builder=""
if [ -n "$isas" ]; then
  set -m  # the builds in a process group of their own, so that an early exit stops them all
  (
    renice -n 19 "$BASHPID" > /dev/null
    for isa in $isas; do
      rm -f "build-$isa.ok"
      { cmake -S . -B "build-$isa" -DCMAKE_BUILD_TYPE=Release -DPERI_ISA="$isa" -DPERI_BUILD_BENCHMARKS=OFF &&
        cmake --build "build-$isa" -j "$(nproc)" --target unit_tests; } > "build-$isa.log" 2>&1 &&
        touch "build-$isa.ok"
    done
  ) &
  builder=$!
  set +m
  trap 'kill -- -"$builder" 2> /dev/null || true' EXIT
fi

(cd build && ctest -j "$(nproc)" --output-on-failure --timeout 900 "$@")

if [ -n "$builder" ]; then
  wait "$builder" || true
  trap - EXIT
fi
for isa in $isas; do
  echo "test: unit tests built with PERI_ISA=$isa (build-$isa/)"
  [ -f "build-$isa.ok" ] || { tail -n 30 "build-$isa.log"; echo "test: the PERI_ISA=$isa build failed (build-$isa.log)"; exit 1; }
  (cd "build-$isa" && ctest -j "$(nproc)" -L unit --output-on-failure --timeout 900)
done

#!/usr/bin/env bash
# Runs each libFuzzer target for a bounded time (default 60 s each) from the corpus in
# tests/fuzz/corpus/<target>. A crash, leak, timeout or out-of-memory is written to
# tests/fuzz/crashes/<target>/ -- commit it: ctest replays every file there (fuzz_replay_*) so a
# finding stays a regression test after it is fixed. New corpus entries go to a scratch copy.
# usage: tests/fuzz/run.sh [SECONDS] [BUILD_DIR] [TARGET...]   (default: every target)
set -u
seconds=${1:-60}
src=$(cd "$(dirname "$0")/../.." && pwd)
out=${2:-$src/build-fuzz}
"$src/tests/fuzz/build.sh" "$out" || exit 1
targets=("${@:3}")
[ ${#targets[@]} -gt 0 ] || targets=(scene checkpoint crossing polygon override)
status=0
for target in "${targets[@]}"; do
  work=$(mktemp -d)
  cp -r "$src/tests/fuzz/corpus/$target/." "$work/"
  crashes=$src/tests/fuzz/crashes/$target
  mkdir -p "$crashes"
  case $target in scene) max_len=8192 ;; checkpoint) max_len=16384 ;; crossing) max_len=65 ;; polygon) max_len=121 ;; *) max_len=4096 ;; esac
  echo "== fuzz_$target for $seconds s"
  "$out/fuzz_$target" "$work" -max_total_time="$seconds" -max_len="$max_len" -timeout=10 -rss_limit_mb=2048 \
    -artifact_prefix="$crashes/" -print_final_stats=1 > "$out/fuzz_$target.log" 2>&1
  rc=$?
  grep -E "^#[0-9]+.*(DONE|pulse)|stat::number_of_executed_units|stat::average_exec_per_sec|stat::new_units_added|stat::peak_rss_mb" \
    "$out/fuzz_$target.log" | tail -5
  grep -E "^#[0-9]+" "$out/fuzz_$target.log" | tail -1
  if [ "$rc" -ne 0 ]; then
    echo "fuzz_$target: FINDING (exit status $rc); see $out/fuzz_$target.log and $crashes/"
    grep -E "ERROR|SUMMARY|finding|Test unit written" "$out/fuzz_$target.log" | head -5
    status=1
  else
    echo "fuzz_$target: no finding in $seconds s; corpus grew from $(ls "$src/tests/fuzz/corpus/$target" | wc -l) to $(ls "$work" | wc -l) inputs"
  fi
  rm -rf "$work"
done
exit $status

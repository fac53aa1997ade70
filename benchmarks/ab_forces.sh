#!/bin/bash
# Two versions of the bond loop side by side in one process (benchmarks/ab_forces.cpp): finer than
# ab_kernels.py, which alternates whole processes, for changes confined to src/kernels/forces.cpp.
#   benchmarks/ab_forces.sh REV_A REV_B [MODEL N PAIRS NOISE]
# REV is a git revision, "work" for the working tree's src/kernels/forces.cpp, or a file holding a version. MODEL:
# membrane, pmb (N x N sheets; AB_QUADRATURE=full for whole cells) or solid (an N^3 PMB block).
# Defaults: membrane 400
# 200 1e-5. Needs a configured build in build/ (libperi.a and the flags it was compiled with);
# both versions must compile against the current headers. Prints figures; asserts nothing.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${PERI_BUILD_DIR:-$root/build}
if [ $# -lt 2 ]; then sed -n '2,10p' "$0"; exit 2; fi
flags_file=$build/benchmarks/CMakeFiles/bench_kernels.dir/flags.make
link_file=$build/benchmarks/CMakeFiles/bench_kernels.dir/link.txt
if [ ! -f "$flags_file" ] || [ ! -f "$build/libperi.a" ]; then
  echo "ab_forces.sh: no configured build with benchmarks in $build (cmake -B build, make bench_kernels)" >&2
  exit 1
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
source_of() {  # revision -> file with that revision's src/kernels/forces.cpp
  if [ "$1" = work ]; then cp "$root/src/kernels/forces.cpp" "$work/$2.cpp"
  elif [ -f "$1" ]; then cp "$1" "$work/$2.cpp"
  else git -C "$root" show "$1:src/kernels/forces.cpp" > "$work/$2.cpp" 2> /dev/null ||
    git -C "$root" show "$1:src/forces.cpp" > "$work/$2.cpp"; fi  # before the stage folders
}
source_of "$1" a
source_of "$2" b
get() { sed -n "s/^$1 = //p" "$flags_file"; }
flags="$(get CXX_DEFINES) $(get CXX_INCLUDES) $(get CXX_FLAGS)"
cxx=$(awk '{print $1}' "$link_file")
# As CMakeLists.txt compiles src/kernels/forces.cpp.
$cxx $flags -ffp-contract=off -Dperi=periA -c "$work/a.cpp" -o "$work/a.o" &
$cxx $flags -ffp-contract=off -Dperi=periB -c "$work/b.cpp" -o "$work/b.o" &
$cxx $flags -c "$root/benchmarks/ab_forces.cpp" -o "$work/main.o"
wait
# The bench_kernels link line with these objects in place of its own (and without Google Benchmark).
libs=$(sed -e 's/^.* -o bench_kernels //' -e 's#[^ ]*libbenchmark[^ ]*##g' -e "s#\.\./libperi\.a#$build/libperi.a#" "$link_file")
(cd "$build/benchmarks" && $cxx -O2 "$work/main.o" "$work/a.o" "$work/b.o" -o "$work/ab_forces" $libs)
"$work/ab_forces" "${3:-membrane}" "${4:-400}" "${5:-200}" "${6:-1e-5}"

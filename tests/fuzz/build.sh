#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (Debian clang-14 + libclang-rt-14-dev) and
# AddressSanitizer: BUILD_DIR/fuzz_scene and BUILD_DIR/fuzz_checkpoint.
# usage: tests/fuzz/build.sh [BUILD_DIR]   (default: build-fuzz)
set -eu
src=$(cd "$(dirname "$0")/../.." && pwd)
out=${1:-$src/build-fuzz}
mkdir -p "$out"
cxx=${CXX_FUZZ:-$(command -v clang++-14 || command -v clang++)}
hdf5_inc=$(pkg-config --cflags hdf5-openmpi 2> /dev/null || echo -I/usr/include/hdf5/openmpi)
hdf5_lib=$(pkg-config --libs hdf5-openmpi 2> /dev/null || echo "-L/usr/lib/x86_64-linux-gnu/hdf5/openmpi -lhdf5")
mpi_inc=$(mpicxx --showme:compile 2> /dev/null || true)
flags=(-std=c++20 -O1 -g -fno-omit-frame-pointer -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -I"$src/include" $hdf5_inc $mpi_inc)
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_scene.cpp" "$src/src/scene/scene.cpp" "$src/src/core/error.cpp" \
  "$src/src/geometry/discretization.cpp" "$src/src/models/model.cpp" -lyaml-cpp -o "$out/fuzz_scene"
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_checkpoint.cpp" "$src/src/io/checkpoint.cpp" "$src/src/core/error.cpp" \
  $hdf5_lib -o "$out/fuzz_checkpoint"
echo "built $out/fuzz_scene $out/fuzz_checkpoint"

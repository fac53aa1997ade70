#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (Debian clang-14 + libclang-rt-14-dev) and
# AddressSanitizer: BUILD_DIR/fuzz_scene, fuzz_checkpoint, fuzz_crossing and fuzz_override.
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
       -I"$src/include" -I/usr/include/eigen3 $hdf5_inc $mpi_inc)
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_scene.cpp" "$src"/src/scene/*.cpp "$src/src/core/error.cpp" \
  "$src/src/geometry/discretization.cpp" "$src/src/geometry/body_kinds.cpp" "$src"/src/geometry/kinds/*.cpp \
  "$src/src/models/model.cpp" "$src/src/models/marder.cpp" \
  "$src/src/kernels/laws.cpp" -lyaml-cpp \
  -o "$out/fuzz_scene"
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_checkpoint.cpp" "$src/src/io/checkpoint.cpp" "$src/src/core/error.cpp" \
  $hdf5_lib -o "$out/fuzz_checkpoint"
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_crossing.cpp" "$src/src/bonds/crossing.cpp" -o "$out/fuzz_crossing"
# The default scene embedded as CMakeLists.txt embeds it (PERI_DEFAULT_SCENE).
python3 - "$src" "$out/build_info.cpp" << 'EOF_PY'
import sys
src, out = sys.argv[1:]
text = open(src + "/src/core/build_info.cpp.in").read()
scene = open(src + "/drivers/scenes/slit_membrane.yaml").read()
text = text.replace("@PERI_GIT_REVISION@", "fuzz").replace("@PROJECT_VERSION@", "fuzz")
open(out, "w").write(text.replace("@PERI_DEFAULT_SCENE_TEXT@", scene))
EOF_PY
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_override.cpp" "$src"/src/scene/*.cpp "$src/src/core/error.cpp" \
  "$src/src/models/marder.cpp" "$src/src/models/model.cpp" \
  "$src/src/geometry/discretization.cpp" "$src/src/geometry/body_kinds.cpp" "$src"/src/geometry/kinds/*.cpp \
  "$src/src/kernels/laws.cpp" "$out/build_info.cpp" -lyaml-cpp -o "$out/fuzz_override"
echo "built $out/fuzz_scene $out/fuzz_checkpoint $out/fuzz_crossing $out/fuzz_override"

#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (Debian clang-14 + libclang-rt-14-dev) and
# AddressSanitizer: BUILD_DIR/fuzz_scene, fuzz_checkpoint, fuzz_crossing, fuzz_polygon and fuzz_override.
# usage: tests/fuzz/build.sh [BUILD_DIR]   (default: build-fuzz)
set -eu
src=$(cd "$(dirname "$0")/../.." && pwd)
out=${1:-$src/build-fuzz}
mkdir -p "$out"
cxx=${CXX_FUZZ:-$(command -v clang++-14 || command -v clang++)}
hdf5_inc=$(pkg-config --cflags hdf5-openmpi 2> /dev/null || echo -I/usr/include/hdf5/openmpi)
hdf5_lib=$(pkg-config --libs hdf5-openmpi 2> /dev/null || echo "-L/usr/lib/x86_64-linux-gnu/hdf5/openmpi -lhdf5")
mpi_inc=$(mpicxx --showme:compile 2> /dev/null || true)
petsc_inc=$(pkg-config --cflags petsc 2> /dev/null || echo -I/usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real/include)
petsc_lib=$(pkg-config --libs petsc 2> /dev/null || echo "-L/usr/lib/petscdir/petsc3.18/x86_64-linux-gnu-real/lib -lpetsc_real")
mpi_lib=$(mpicxx --showme:link 2> /dev/null || true)
# Gmsh is opened at run time (src/geometry/kinds/gmsh_library.cpp), by path and soname as CMake
# finds them.
gmsh_so=$(ls /usr/lib/*/libgmsh.so /usr/lib/libgmsh.so 2> /dev/null | head -1)
gmsh_path=$(realpath "${gmsh_so:-/usr/lib/libgmsh.so}" 2> /dev/null || echo "${gmsh_so:-}")
gmsh_soname=$(objdump -p "$gmsh_path" 2> /dev/null | awk '$1 == "SONAME" {print $2}')
flags=(-std=c++20 -O1 -g -fno-omit-frame-pointer -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -DPERI_GMSH_LIBRARY="\"$gmsh_path\"" -DPERI_GMSH_SONAME="\"$gmsh_soname\"" -I"$src/include" -I/usr/include/eigen3 $hdf5_inc $mpi_inc $petsc_inc)
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_scene.cpp" "$src"/src/scene/*.cpp "$src/src/core/error.cpp" \
  "$src/src/geometry/discretization.cpp" "$src/src/geometry/body_kinds.cpp" "$src"/src/geometry/kinds/*.cpp \
  "$src/src/models/model.cpp" "$src/src/models/marder.cpp" \
  "$src/src/kernels/laws.cpp" -lyaml-cpp $hdf5_lib -ldl \
  -o "$out/fuzz_scene"
# The default scene embedded as CMakeLists.txt embeds it (PERI_DEFAULT_SCENE), and the revision
# (cmake/git_revision.cmake writes it in the normal build).
python3 - "$src" "$out/build_info.cpp" << 'EOF_PY'
import sys
src, out = sys.argv[1:]
text = open(src + "/src/core/build_info.cpp.in").read()
scene = open(src + "/drivers/scenes/slit_membrane.yaml").read()
text = text.replace("@PERI_GIT_REVISION@", "fuzz").replace("@PROJECT_VERSION@", "fuzz")
text = text.replace("@PERI_DEFAULT_SCENE_TEXT@", scene)
text += '\nnamespace peri {\nconst char* git_revision() { return "fuzz"; }\n}  // namespace peri\n'
open(out, "w").write(text)
EOF_PY
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_checkpoint.cpp" "$src/src/io/checkpoint.cpp" "$src/src/io/output.cpp" \
  "$src/src/core/error.cpp" "$src/src/core/collective.cpp" "$src"/src/state/*.cpp "$out/build_info.cpp" \
  $hdf5_lib $petsc_lib $mpi_lib -o "$out/fuzz_checkpoint"
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_crossing.cpp" "$src/src/bonds/crossing.cpp" -o "$out/fuzz_crossing"
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_polygon.cpp" "$src/src/bonds/crossing.cpp" -o "$out/fuzz_polygon"
"$cxx" "${flags[@]}" "$src/tests/fuzz/fuzz_override.cpp" "$src"/src/scene/*.cpp "$src/src/core/error.cpp" \
  "$src/src/models/marder.cpp" "$src/src/models/model.cpp" \
  "$src/src/geometry/discretization.cpp" "$src/src/geometry/body_kinds.cpp" "$src"/src/geometry/kinds/*.cpp \
  "$src/src/kernels/laws.cpp" "$out/build_info.cpp" -lyaml-cpp $hdf5_lib -ldl -o "$out/fuzz_override"
echo "built $out/fuzz_scene $out/fuzz_checkpoint $out/fuzz_crossing $out/fuzz_polygon $out/fuzz_override"

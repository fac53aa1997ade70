#!/usr/bin/env bash
# The revision peridrive names (--version, summary.json's git_revision) is the source tree's
# commit when the binary was built, not when CMake last configured: the test builds a scratch git
# tree with CMakeLists.txt's revision block and cmake/git_revision.cmake, then edits and commits
# there, builds again each time without configuring, and expects the revision printed to follow
# (-dirty after the edit, the new commit after the commit). Skipped (exit status 77) when the
# source is not a git checkout.
# usage: revision.sh SOURCE_DIR
set -u
src=$1
command -v git > /dev/null && git -C "$src" rev-parse --git-dir > /dev/null 2>&1 || exit 77
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
# A tiny project that uses peridrive's own revision script the way CMakeLists.txt does.
git init -q "$work/tree" && cd "$work/tree" || fail "git init"
git config user.email test@example.invalid && git config user.name test
mkdir -p include/peri/core cmake
cp "$src/include/peri/core/build_info.hpp" include/peri/core/ && cp "$src/cmake/git_revision.cmake" cmake/
cat > main.cpp <<'CPP'
#include <cstdio>
#include "peri/core/build_info.hpp"
const char* peri::version() { return "test"; }
int main() { std::puts(peri::git_revision()); }
CPP
grep -A8 '^set(PERI_REVISION_FILE' "$src/CMakeLists.txt" | sed -n '/^set(PERI_REVISION_FILE/,/^add_custom_target/p' > revision.cmake
[ -s revision.cmake ] || fail "CMakeLists.txt has no PERI_REVISION_FILE block"
cat > CMakeLists.txt <<'CM'
cmake_minimum_required(VERSION 3.18)
project(revision CXX)
include(revision.cmake)
add_executable(show main.cpp ${PERI_REVISION_FILE})
target_include_directories(show PRIVATE include)
add_dependencies(show peri_git_revision)
CM
git add -A && git commit -q -m first || fail "commit"
first=$(git rev-parse --short=12 HEAD)
cmake -S . -B build > build.log 2>&1 && cmake --build build >> build.log 2>&1 || { cat build.log; fail "first build"; }
got=$(build/show)
[ "$got" = "$first" ] || fail "after the first build: '$got', expected '$first'"
echo "// edit" >> main.cpp
cmake --build build >> build.log 2>&1 || { cat build.log; fail "build of the edited tree"; }
got=$(build/show)
[ "$got" = "$first-dirty" ] || fail "after an edit: '$got', expected '$first-dirty'"
git commit -q -am second
second=$(git rev-parse --short=12 HEAD)
cmake --build build >> build.log 2>&1 || { cat build.log; fail "build after the commit"; }
got=$(build/show)
[ "$got" = "$second" ] || fail "after a commit and a build without configuring: '$got', expected '$second'"
echo "ok: $first, $first-dirty after an edit, $second after a commit, each built without configuring"

#!/usr/bin/env bash
# `peridrive --print-scene` prints the resolved scene as YAML that peridrive accepts back
# unchanged, for the default scene and for every scene in drivers/scenes/.
# usage: print_scene_roundtrip.sh PERIDRIVE SOURCE_DIR
set -eu
peridrive=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pass=0 fail=0
check() {
  local name=$1
  shift
  "$peridrive" "$@" --print-scene > "$work/$name.1.yaml"
  "$peridrive" "$work/$name.1.yaml" --print-scene > "$work/$name.2.yaml"
  if cmp -s "$work/$name.1.yaml" "$work/$name.2.yaml" && [ -s "$work/$name.1.yaml" ]; then
    echo "ok   $name"; pass=$((pass + 1))
  else
    echo "FAIL $name"; diff "$work/$name.1.yaml" "$work/$name.2.yaml" || true; fail=$((fail + 1))
  fi
}
check default
check overridden --set bodies.sheet.spacing=5e-4 --set "boundaries.top.velocity=[0, 20, 0]" --set initial.seed.amplitude=1e-6
for f in "$src"/drivers/scenes/*.yaml; do check "$(basename "$f" .yaml)" "$f"; done
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

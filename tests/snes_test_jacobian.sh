#!/usr/bin/env bash
# PETSc's own Jacobian check on the quasi-static stage (-qs_snes_test_jacobian): the assembled
# bond tangent agrees with PETSc's finite-difference Jacobian, ||J - Jfd||_F / ||J||_F < 1e-4 (PETSc differences one-sided with
# h ~ 1e-8 |u|, so its own error is about 1e-5; tests/test_quasistatic.cpp checks central
# differences to 1e-6),
# in every Newton iteration of a small preload (2 ranks, `jacobian: assembled`: the default
# mf_operator keeps a tangent over several iterations, as a preconditioner only); then the same for a sphere inflated by
# its follower pressure to a stretch of about 1.2, where the pressure's own stiffness (not
# symmetric) is some percent of the tangent: leaving it out or flipping its sign fails the check.
set -euo pipefail
exe=$1 mpiexec=$3
shift 3
mpi_flags=("$@")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cat > "$work/scene.yaml" <<'YAML'
name: jacobian-check
materials:
  rubber: {model: membrane, density: 1200, wave_speed: 1000, hardening: {coefficient: 1.0e5, exponent: 3}}
bodies:
  sheet: {material: rubber, origin: [0, 0, 0], size: [0.004, 0.003], thickness: 0.0005, spacing: 0.0005}
boundaries:
  - {name: left, region: {min: [-1, -1, -1], max: [0.0006, 1, 1]}}
  - {name: right, region: {min: [0.0034, -1, -1], max: [1, 1, 1]}}
stages:
  - {name: preload, kind: quasistatic, displacements: {right: [0.002, 0.0005, 0]}, load_steps: 2, jacobian: assembled}
  - {name: hold, steps: 1}
YAML
check() {
  local out ratios
  out=$("$mpiexec" -n 2 "${mpi_flags[@]}" "$exe" "$1" --quiet -qs_snes_test_jacobian 2>&1 || true)
  ratios=$(grep -o '||J - Jfd||_F/||J||_F = [0-9.eE+-]*' <<<"$out" | awk '{print $NF}')
  if [ -z "$ratios" ]; then echo "no Jacobian test output:"; echo "$out"; exit 1; fi
  echo "$(basename "$1"): ||J - Jfd||_F/||J||_F per Newton iteration:" $ratios
  for r in $ratios; do
    awk -v r="$r" 'BEGIN { exit !(r < 1e-4) }' || { echo "FAIL: $r >= 1e-4"; exit 1; }
  done
}
check "$work/scene.yaml"
cat > "$work/sphere.yaml" <<'YAML'
name: pressure-jacobian-check
materials:
  rubber: {model: membrane, density: 1200, bulk_modulus: 8.0e8}
bodies:
  balloon: {kind: sphere, material: rubber, center: [0, 0, 0], radius: 0.1, thickness: 0.0015, spacing: 0.02,
            pressure: 5.0e6}
stages:
  - {name: inflate, kind: quasistatic, load_steps: 2, jacobian: assembled}
  - {name: hold, steps: 1}
YAML
check "$work/sphere.yaml"
echo "OK"

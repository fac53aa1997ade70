#!/usr/bin/env bash
# Hostile lattice (Marder model) input at the driver level, on 2 ranks: each case must exit with
# status 2, print one message naming file:line, key and why, and leave no output behind.
# usage: bad_input_lattice.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
scene=$src/drivers/scenes/supersonic_rubber_broad_switch.yaml
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pass=0 fail=0

source "$(dirname "$0")/expect.sh"

# variant NAME SED_EXPRESSION: a copy of the scene with one edit; prints its path.
variant() {
  sed "$2" "$scene" > "$work/$1.yaml"
  echo "$work/$1.yaml"
}
line_of() { grep -n -m1 -- "$2" "$1" | cut -d: -f1; }

f=$(variant uc_too_small 's/fracture_separation: .*/fracture_separation: 0.00051/')
expect uc_too_small "$f:$(line_of "$f" 'spacing:'): bodies.strip.spacing: lattice spacing 0.0005 m with material 'rubber'" -- "$f"
expect uc_too_small_why "must exceed Delta + u_s" -- "$f"
f=$(variant b_no_shear 's/mooney_rivlin_b: .*/mooney_rivlin_b: 2.5/')
expect b_no_shear "$f:$(line_of "$f" 'spacing:'): bodies.strip.spacing:" -- "$f"
expect b_no_shear_why "makes the stretched sheet lose its shear stiffness" -- "$f"
expect b_unstable_reference "makes the unstretched lattice unstable" -- "$scene" --set materials.rubber.mooney_rivlin_b=-3 --set materials.rubber.cutoff=0.0004 --set materials.rubber.fracture_separation=0.002
f=$(variant a_negative 's/mooney_rivlin_a: .*/mooney_rivlin_a: -1000/')
expect a_negative "$f:$(line_of "$f" 'mooney_rivlin_a'): materials.rubber.mooney_rivlin_a: expected a positive number [J/kg], got -1000" -- "$f"
f=$(variant no_cutoff '/cutoff:/d')
expect no_cutoff "materials.rubber: missing required key 'cutoff'" -- "$f"
f=$(variant stiffness_key 's/density: 1000/density: 1000\n    wave_speed: 30/')
expect stiffness_key "$f:$(line_of "$f" 'wave_speed'): materials.rubber.wave_speed: not used by the marder model" -- "$f"
f=$(variant kelvin_negative 's/kelvin_viscosity: .*/kelvin_viscosity: -0.01/')
expect kelvin_negative "$f:$(line_of "$f" 'kelvin_viscosity'): materials.rubber.kelvin_viscosity: expected a non-negative number [m^2/s], got -0.01" -- "$f"
f=$(variant onset_alone 's/kelvin_viscosity: .*/kelvin_viscosity: 0.005\n    stiffening_onset: 0.0013/')
expect onset_alone "materials.rubber: missing required key 'stiffening_width' (given with stiffening_onset)" -- "$f"
f=$(variant onset_beyond_uc 's/kelvin_viscosity: .*/kelvin_viscosity: 0.005\n    stiffening_onset: 0.0016\n    stiffening_width: 0.0001/')
expect onset_beyond_uc "$f:$(line_of "$f" 'spacing:'): bodies.strip.spacing: lattice spacing 0.0005 m" -- "$f"
expect onset_beyond_uc_why "the stiffening onset u_g = 0.0016 m must lie on the Mooney-Rivlin branch" -- "$f"
f=$(variant width_zero 's/kelvin_viscosity: .*/kelvin_viscosity: 0.005\n    stiffening_onset: 0.0013\n    stiffening_width: 0/')
expect width_zero "$f:$(line_of "$f" 'stiffening_width'): materials.rubber.stiffening_width: expected a positive number [m], got 0" -- "$f"
f=$(variant break_beyond_uc 's/kelvin_viscosity: .*/kelvin_viscosity: 0.005\n    break_separation: 0.002/')
expect break_beyond_uc "$f:$(line_of "$f" 'spacing:'): bodies.strip.spacing: lattice spacing 0.0005 m" -- "$f"
expect break_beyond_uc_why "the break separation u_b = 0.002 m must lie in (Delta + u_s, u_c]" -- "$f"
f=$(variant bad_breaking 's/breaking: irreversible/breaking: sometimes/')
expect bad_breaking "materials.rubber.breaking: expected one of: irreversible, reversible; got sometimes" -- "$f"
f=$(variant lattice_grid 's/spacing: 0.0005/spacing: 0.0005\n    grid: square/')
expect lattice_grid "$f:$(line_of "$f" 'grid:'): bodies.strip.grid: not used by a lattice body" -- "$f"
f=$(variant membrane_marder 's/kind: lattice/kind: membrane/')
expect membrane_marder "bodies.strip.material: material 'rubber' has model: marder, which needs a body with kind: lattice" -- "$f"
f=$(variant lattice_pmb 's/model: marder/model: pmb\n    bulk_modulus: 1.0e6/; /mooney_rivlin\|cutoff\|fracture_separation\|breaking\|kelvin_viscosity/d')
expect lattice_pmb "bodies.strip.material: a lattice body needs a material with model: marder" -- "$f"
f=$(variant quasistatic 's/^stages:$/stages:\n  - {name: load, kind: quasistatic}/')
expect quasistatic "$f:$(line_of "$f" 'name: load'): stages.load.kind: a scene with a lattice body runs dynamic stages only" -- "$f"

# A breakable box that holds no two neighbours: nothing could break.
f=$(variant breakable_empty 's/breakable: .*/breakable: {min: [-1, 0.9, -1], max: [1, 1, 1]}/')
expect breakable_empty "bodies.strip.breakable: the box holds no bond of the body (no two lattice neighbours inside it)" -- "$f"

# An initial stretch at which the lattice has lost its stiffness (the homogeneous state unstable;
# it ran before, with NaN wave speeds where the Mooney-Rivlin c_l^2 < 0). The scene stretches to
# (1.3, 2.8): the Mooney-Rivlin sheet loses c_l along x below b = -2 / (2.8^2 - 1) = -0.292; the
# lattice, whose bonds reach into the switch before u_c, already at b = -0.1.
g="$(line_of "$scene" 'displacement_gradient')"
expect stretch_mooney_rivlin "$scene:$g: initial.displacement_gradient: stretches lattice body 'strip' to (1.3, 2.8) along (x, y), where its material (a = 1000, b = -0.5) has no longitudinal stiffness along x (waves along x): the stretched lattice is unstable (the Mooney-Rivlin sheet's c_l^2 = a [1 + (b/2)(lambda_across^2 - 1)] <= 0: at lambda_across = 2.8, b must exceed -0.292398)" -- "$scene" --set materials.rubber.mooney_rivlin_b=-0.5
expect stretch_switch "b = -0.1) has no longitudinal stiffness along y (waves along y): the stretched lattice is unstable (its bonds, up to 0.00125524 m long, near the fracture separation u_c = 0.0015 m" -- "$scene" --set materials.rubber.mooney_rivlin_b=-0.1
expect stretch_compressed "initial.displacement_gradient: stretches lattice body 'strip' to (0.5, 0.5) along (x, y), where its material (a = 1000, b = 0.4) has no shear stiffness: the stretched lattice is unstable (its bonds, as short as 0.00025 m, are on the cutoff branch below Delta + u_s = 0.000625 m (eq. 31)" -- "$scene" --set 'initial.displacement_gradient=[[-0.5,0,0],[0,-0.5,0],[0,0,0]]'
expect stretch_beyond_uc "its bonds are stretched up to 0.002 m, beyond the fracture separation u_c = 0.0015 m, where they carry no force" -- "$scene" --set 'initial.displacement_gradient=[[3,0,0],[0,3,0],[0,0,0]]'
# Just inside: b = 0 at the scene's stretch keeps the lattice stiff (the derived speed is printed).
if "${mpi[@]}" "$peridrive" "$scene" --dry-run --set materials.rubber.mooney_rivlin_b=0 > "$work/stdout" 2> "$work/stderr" &&
   grep -q "^strip.lattice_longitudinal_speed_x = 31.62" "$work/stdout"; then
  echo "ok   stretch_b_zero: $(grep '^strip.lattice_longitudinal_speed_x' "$work/stdout") (sqrt(a) = 31.623)"; pass=$((pass + 1))
else
  echo "FAIL stretch_b_zero: expected a run with c_l = sqrt(a)"; cat "$work/stderr"; fail=$((fail + 1))
fi

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

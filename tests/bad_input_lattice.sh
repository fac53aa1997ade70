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

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

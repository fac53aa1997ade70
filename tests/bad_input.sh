#!/usr/bin/env bash
# Hostile input at the driver level, on 2 ranks: each case must exit with status 2, print one
# message naming file:line, key and what was expected, and leave no output directory behind; a run
# that fails on the way (the last case) exits with status 3 and leaves a FAILED marker.
# usage: bad_input.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
scene=$src/drivers/scenes/slit_membrane.yaml
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
pass=0 fail=0

source "$(dirname "$0")/expect.sh"

# variant NAME SED_EXPRESSION: a copy of the default scene with one edit; prints its path.
variant() {
  sed "$2" "$scene" > "$work/$1.yaml"
  echo "$work/$1.yaml"
}
line_of() { grep -n -m1 -- "$2" "$1" | cut -d: -f1; }

f=$(variant unknown_key 's/density: 1200/densty: 1200/')
expect unknown_key "$f:$(line_of "$f" densty): materials.rubber.densty: unknown key; expected one of: model, density" -- "$f"
f=$(variant negative_density 's/density: 1200/density: -1200/')
expect negative_density "$f:$(line_of "$f" 'density: -'): materials.rubber.density: expected a positive number [kg/m^3], got -1200" -- "$f"
f=$(variant zero_thickness 's/thickness: 0.0005/thickness: 0/')
expect zero_thickness "$f:$(line_of "$f" 'thickness: 0$'): bodies.sheet.thickness: expected a positive number [m], got 0" -- "$f"
f=$(variant negative_spacing 's/spacing: [0-9.e-]*$/spacing: -0.00025/')
expect negative_spacing "$f:$(line_of "$f" 'spacing: -'): bodies.sheet.spacing: expected a positive number [m], got -0.00025" -- "$f"
f=$(variant wrong_type 's/spacing: [0-9.e-]*$/spacing: fine/')
expect wrong_type "$f:$(line_of "$f" 'spacing: fine'): bodies.sheet.spacing: expected a positive number [m], got fine" -- "$f"
f=$(variant small_horizon 's/horizon_factor: 3/horizon_factor: 0.5/')
expect small_horizon "$f:$(line_of "$f" 'horizon_factor'): bodies.sheet.horizon_factor: horizon must be at least one spacing (expected >= 1), got 0.5" -- "$f"
f=$(variant low_critical_stretch 's/critical_stretch: 2.0/critical_stretch: 0.9/')
expect low_critical_stretch "$f:$(line_of "$f" 'critical_stretch'): materials.rubber.critical_stretch: the membrane model needs a critical stretch lambda_0 > 1, got 0.9" -- "$f"
f=$(variant missing_key '/    material: rubber/d')
expect missing_key "$f:$(line_of "$f" 'kind: membrane'): bodies.sheet: missing required key 'material'" -- "$f"
f=$(variant empty_region 's/min: \[-1, 0.0242, -1\]/min: [-1, 0.9, -1]/')
expect empty_region "$f:$(line_of "$f" 'min: \[-1, 0.9'): boundaries.top.region: the region [-1, 0.9, -1] .. [1, 1, 1] selects no node" -- "$f"
f=$(variant nan_value 's/wave_speed: 1000/wave_speed: .nan/')
expect nan_value "materials.rubber.wave_speed" -- "$f"
printf 'name: broken\nmaterials: [unclosed\n' > "$work/syntax.yaml"
expect yaml_syntax "$work/syntax.yaml:3: YAML syntax error" -- "$work/syntax.yaml"
expect missing_file "cannot read scene file '$work/none.yaml': No such file or directory" -- "$work/none.yaml"
expect bad_override "--set: bodies.sheet.spacing: expected a positive number [m], got -1" -- --set bodies.sheet.spacing=-1
expect unknown_option "unknown option --bogus; see --help" -- --bogus
expect halo_chunk "-halo_chunk_nodes: expected a positive number of nodes, got 0" -- "$scene" -halo_chunk_nodes 0
expect unstable_dt "stages.0.dt: time step 1e-05 s exceeds the stable bound" -- --set stages.0.dt=1e-5
expect absurd_resolution "the scene cannot fit in memory: about 6.25e+08 nodes" -- --set bodies.sheet.spacing=2e-6
expect huge_number "the scene cannot fit in memory: about >1e308 nodes" -- --set bodies.sheet.size=[1e300,1e300]
# --dry-run prints its size estimate before setup: an overflowed one reads as the error does
# (it printed "estimate: inf nodes, inf bonds, inf GB").
"${mpi[@]}" "$peridrive" --set bodies.sheet.spacing=1e-300 --dry-run > "$work/stdout" 2> "$work/stderr"
rc=$?
if [ $rc -eq 2 ] && grep -qx "estimate: >1e308 nodes, >1e308 bonds, >1e308 GB" "$work/stdout" &&
  ! grep -qi "inf" "$work/stdout" && grep -q "cannot fit in memory: about >1e308 nodes" "$work/stderr"; then
  echo "ok   dry_run_overflowed_estimate: $(head -1 "$work/stdout")"; pass=$((pass + 1))
else
  echo "FAIL dry_run_overflowed_estimate: exit $rc, stdout '$(head -1 "$work/stdout")'"; cat "$work/stderr"
  fail=$((fail + 1))
fi
expect bad_checkpoint_cadence "--set: output.checkpoint_every_steps: expected an integer >= 0, got -1" -- --set output.checkpoint_every_steps=-1
printf 'not a checkpoint\n' > "$work/fake.h5"
expect foreign_checkpoint "checkpoint '$work/fake.h5': not a peridrive checkpoint" -- --resume "$work/fake.h5"
expect missing_checkpoint "checkpoint '$work/none': no such file" -- --resume "$work/none"

tool=$src/drivers/scenes/blunt_tool.yaml
expect tool_radius "tools.0.radius: expected a positive number [m], got -0.001" -- "$tool" --set tools.rod.radius=-0.001
expect tool_mass "tools.0.mass: expected a mass in (0, 1e30] kg, got 0" -- "$tool" --set tools.rod.mass=0
expect tool_mass_huge "tools.0.mass: expected a mass in (0, 1e30] kg, got 1e300" -- "$tool" --set tools.rod.mass=1e300
expect tool_kind "tools.0.kind: expected one of: cylinder, sphere; got cube" -- "$tool" --set tools.rod.kind=cube
expect tool_center "tools.0.center: expected a list of 2 numbers [x, y] [m]" -- "$tool" --set tools.rod.center=[0,0,0]

fiber=$src/drivers/scenes/fiber_long_range.yaml
expect fiber_one_point "bodies.fiber.path: expected a list of at least 2 points [x, y, z], m" -- "$fiber" --set 'bodies.fiber.path=[[0,0,0]]'
expect fiber_repeated_point "bodies.fiber.path.1: expected a point different from the one before it" -- "$fiber" --set 'bodies.fiber.path=[[0,0,0],[0,0,0]]'
expect fiber_diameter "bodies.fiber.diameter: expected a positive number [m], got -1e-9" -- "$fiber" --set bodies.fiber.diameter=-1e-9
expect fiber_origin "bodies.fiber.origin: not used by a fiber body" -- "$fiber" --set 'bodies.fiber.origin=[0,0,0]'
expect fiber_spacing "bodies.fiber.spacing: spacing must not exceed the fiber's length along its path" -- "$fiber" --set bodies.fiber.spacing=1e-6
expect fiber_kelvin "materials.protein.kelvin_viscosity: bodies.fiber is a fiber, which has no shear modulus to define the dashpots by (tau = rho nu / mu)" -- "$fiber" --set materials.protein.kelvin_viscosity=0.01
expect kelvin_negative_membrane "materials.protein.kelvin_viscosity: expected a non-negative number [m^2/s], got -0.01" -- "$fiber" --set materials.protein.kelvin_viscosity=-0.01
expect pair_kind "long_range.pairs.0.between: expected one of: adjacent_segments, distant_segments, other_fibers" -- "$fiber" --set long_range.pairs.0.between=neighbours
expect pair_alpha "long_range.pairs.1.alpha: expected a non-negative number [J/m^6], got -1" -- "$fiber" --set long_range.pairs.1.alpha=-1
# A rule for two particular segments: indices within the fiber's 20 segments (checked at setup),
# two different ones, only with between: segments; a rule's own cutoff is positive.
expect segments_range "long_range.pairs.0.segments: expected segment indices 0 to 19 (the fiber has 20 segments), got [0, 20]" -- "$fiber" --set 'long_range.pairs=[{between: segments, segments: [0, 20], alpha: 1, beta: 1}]'
expect segments_same "long_range.pairs.1.segments: expected two different segments (nodes of one segment never interact), got [3, 3]" -- "$fiber" --set 'long_range.pairs.1={between: segments, segments: [3, 3], alpha: 1, beta: 1}'
expect segments_missing "long_range.pairs.0: missing required key 'segments'" -- "$fiber" --set 'long_range.pairs.0={between: segments, alpha: 1, beta: 1}'
expect segments_on_kind "long_range.pairs.1.segments: only a rule with between: segments names segments" -- "$fiber" --set 'long_range.pairs.1.segments=[0, 3]'
expect segments_negative "long_range.pairs.0.segments.1: expected an integer >= 0, got -1" -- "$fiber" --set 'long_range.pairs=[{between: segments, segments: [1, -1], alpha: 1, beta: 1}]'
expect pair_cutoff "long_range.pairs.1.cutoff: expected a positive number [m], got 0" -- "$fiber" --set long_range.pairs.1.cutoff=0
expect segments_one_segment "long_range.pairs.0.segments: expected segment indices 0 to 0 (each of the scene's fibers is one segment" -- "$src/drivers/scenes/fiber_network.yaml" --set 'long_range.pairs=[{between: segments, segments: [0, 1], alpha: 1, beta: 1}]'
# A section that reaches no pair of nodes: other_fibers with one fiber; the segment kinds on a
# fiber of one segment (a segment_length longer than the fiber).
expect long_range_no_pair_one_fiber "long_range: no rule applies to any pair of nodes, so the section never acts: long_range.pairs.0 (between: other_fibers, --set) applies to no pair of the scene's fiber nodes: the scene has one fiber" -- "$fiber" --set 'long_range.pairs=[{between: other_fibers, alpha: 1, beta: 1}]'
expect long_range_no_pair_one_segment "applies to no pair of the scene's fiber nodes: each fiber is one segment (a fiber body's segment_length is 0, the default, or not shorter than its fiber); expected a rule" -- "$fiber" --set bodies.fiber.segment_length=1e-6
expect long_range_no_fiber "long_range: long-range forces act between fiber nodes" -- "$scene" --set 'long_range={length: 1e-9, cutoff: 3e-9, pairs: [{between: other_fibers, alpha: 1, beta: 1}]}'
sed 's/- {name: coil, duration: 4.0e-9/- {name: settle, kind: quasistatic}\n  - {name: coil, duration: 4.0e-9/' "$fiber" > "$work/fiber_qs.yaml"
expect long_range_quasistatic "a quasistatic stage in a scene with long_range" -- "$work/fiber_qs.yaml"
release=$src/drivers/scenes/slit_release.yaml
expect qs_option "$release:$(line_of "$release" 'name: preload'): quasi-static stage 'preload': PETSc refused the solver's -qs_* options: Unable to find requested PC type nosuchpc" -- "$release" -qs_pc_type nosuchpc
expect qs_option_value "quasi-static stage 'preload': PETSc refused the solver's -qs_* options: Unsupported viewer" -- "$release" -qs_ksp_view_final_residual 0
balloon=$src/drivers/scenes/balloon.yaml
expect sphere_size "bodies.balloon.size: not used by a sphere body" -- "$balloon" --set 'bodies.balloon.size=[1, 1]'
expect sphere_pressure "bodies.balloon.pressure: expected a non-negative number [Pa], got -1" -- "$balloon" --set bodies.balloon.pressure=-1
expect sphere_spacing "bodies.balloon.spacing: spacing must not exceed the radius (0.1 m), got 0.5" -- "$balloon" --set bodies.balloon.spacing=0.5
expect sphere_tool_center "tools.0.center: expected a list of 3 numbers [x, y, z] [m]" -- "$balloon" --set 'tools.fragment.center=[1, 0]'
expect membrane_pressure "bodies.sheet.pressure: only with mesh: pressure belongs to a membrane read from a mesh file" -- "$scene" --set bodies.sheet.pressure=1e5
expect long_range_cutoff "long_range.cutoff: 1 m takes in" -- "$src/drivers/scenes/fiber_network.yaml" --set long_range.cutoff=1
expect fiber_pressure "bodies.fiber.pressure: not used by a fiber body (nodes along a path, full weights within the horizon); expected one of: kind, material, path, polyline, network" -- "$fiber" --set bodies.fiber.pressure=1e5
network=$src/drivers/scenes/fiber_network.yaml
expect network_direction "bodies.net.network.families.0.direction: expected one of: x, y; got z" -- "$network" --set 'bodies.net.network.families=[{direction: z, count: 3}]'
expect network_box "bodies.net.network.box.max: expected min < max in every component, got z: min 0, max 0" -- "$network" --set 'bodies.net.network.box={min: [0, 0, 0], max: [2e-7, 2e-7, 0]}'
expect network_step "bodies.net.network.step: a fiber would take more than 1e6 steps" -- "$network" --set bodies.net.network.step=1e-16
expect sphere_absurd "the scene cannot fit in memory" -- "$balloon" --set bodies.balloon.spacing=1e-9
# A straight pre-crack cuts sheets and fibers; a scene of solids alone refuses it (it cut nothing).
cat > "$work/solid_crack.yaml" <<'YAML'
name: solid-crack
materials:
  m: {model: pmb, density: 1000, bulk_modulus: 1.0e9, critical_stretch: 0.01}
bodies:
  block: {kind: solid, material: m, origin: [0, 0, 0], size: [0.01, 0.01, 0.01], spacing: 0.001}
cracks:
  - {from: [0.002, 0.005, 0.005], to: [0.008, 0.005, 0.005]}
stages:
  - {name: run, steps: 5}
YAML
expect solid_crack "$work/solid_crack.yaml:7: cracks.0: a slit (from, to) is a straight segment, which cuts the bonds of sheets and fibers; every body of this scene is a volume (kind: solid), where a segment cuts no bond; a volume is cut by a polygon" -- "$work/solid_crack.yaml"
# Polygon cracks (they cut volumes): at least 3 corners, each unlike the one before, in one plane,
# convex, enclosing an area, and not with from and to.
expect polygon_two_corners "cracks.0.polygon: expected a list of at least 3 corners [[x, y, z], ...] [m] of a convex plane polygon, got a list of 2" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[0.005, 0, 0], [0.005, 1, 0]]}'
expect polygon_repeated_corner "cracks.0.polygon.2: expected a corner different from the one before it" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 1, 0]]}'
expect polygon_not_plane "cracks.0.polygon.0: expected the corners in one plane (to 1e-9 of the polygon's size), got this corner 0.00024999993750" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[0.005, 0, 0], [0.005, 1, 0], [0.005, 1, 1], [0.006, 0, 1]]}'
expect polygon_not_convex "cracks.0.polygon.2: expected a convex polygon with its corners in order, got a turn the other way at this corner; give a non-convex cut as several convex polygons" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[0, 0, 0], [1, 0, 0], [0.2, 0.2, 0], [0, 1, 0]]}'
expect polygon_closed "cracks.0.polygon.3: the same corner as the first; expected each corner once" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0]]}'
expect polygon_bow_tie "cracks.0.polygon: expected a polygon that encloses an area, its corners in order, got corners on one line or edges that cross" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]}'
expect polygon_with_from "cracks.0.from: not with polygon: a crack is a slit (from, to) or a polygon" -- "$work/solid_crack.yaml" --set 'cracks.0.polygon=[[0, 0, 0], [1, 0, 0], [0, 1, 0]]'
expect polygon_in_sheet_plane "cracks.hole.polygon: lies in the plane of the flat sheet 'sheet' (z = 0 m), where it would break every bond within its area" -- "$scene" --set 'cracks.0={name: hole, polygon: [[-0.005, -0.005, 0], [0.005, -0.005, 0], [0.005, 0.005, 0], [-0.005, 0.005, 0]]}'
expect polygon_far "cracks.0.polygon.1: expected a corner within 1e100 m of the origin" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[0, 0, 0], [1e200, 0, 0], [0, 1, 0]]}'
expect polygon_star "cracks.0.polygon: expected a polygon that encloses an area, its corners in order, got corners on one line or edges that cross" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[1, 0, 0], [-0.809, 0.588, 0], [0.309, -0.951, 0], [0.309, 0.951, 0], [-0.809, -0.588, 0]]}'
expect polygon_nan "cracks.0.polygon.1.2: expected a finite number" -- "$work/solid_crack.yaml" --set 'cracks.0={polygon: [[0, 0, 0], [1, 0, .nan], [0, 1, 0]]}'
expect solid_thickness "bodies.block.thickness: not used by a solid body (a box of simple-cubic points, a point cloud or a tetrahedral mesh from a file); expected one of: kind, material, origin, size, points, mesh, scale, spacing, grid, horizon_factor, horizon, quadrature, cutouts" -- "$work/solid_crack.yaml" --set bodies.block.thickness=0.001
expect network_and_path "bodies.net.network: give either path (one fiber) or network (many), not both" -- "$network" --set 'bodies.net.path=[[0,0,0],[1e-8,0,0]]'

# A run that fails on the way (the motion detector at a tiny motion limit, 1e-4 of the spacing,
# which the grips' nodes exceed at once): status 3, one message, and the same message in a FAILED
# marker beside the partial output.
out="$work/out-unstable"
"${mpi[@]}" "$peridrive" "$scene" --set stability.motion_per_step=1e-4 --out "$out" --quiet > "$work/stdout" 2> "$work/stderr"
rc=$?
want="unstable explicit integration detected by step 10 (t = 5.80098e-07 s): node"
if [ "$rc" -eq 3 ] && [ "$(grep -c "peridrive: error:" "$work/stderr")" -eq 1 ] && grep -qF -- "$want" "$work/stderr" &&
   grep -qF -- "more than stability.motion_per_step = 0.0001 of the grid spacing" "$out/FAILED"; then
  echo "ok   unstable_motion: $(grep "peridrive: error:" "$work/stderr" | cut -c1-160)"; pass=$((pass + 1))
else
  echo "FAIL unstable_motion: exit status $rc"; cat "$work/stderr"; ls "$out"; fail=$((fail + 1))
fi
echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

#!/usr/bin/env bash
# Mesh bodies (`mesh: file`) read through Gmsh, on meshes the gmsh program makes here from tiny
# .geo files: an open tube (R 50 mm, L 200 mm, edges about 10 mm) as a triangle membrane, in .msh
# and as STL; a box and a cylinder of tetrahedra as solids.
#  - total area of the tube against 2 pi R L within 0.3% (the faceting error, (pi/32)^2/6 = 0.16%);
#    the STL gives the same nodes and area (to its float32 coordinates);
#  - total volume of the box exact (1e-12), of the cylinder (R 5 mm, edges about 1.5 mm: about 21
#    around, faceting (2 pi/21)^2/6 = 1.5%) against pi R^2 L within 2% (1.06% measured); scale 2
#    gives 8 times the volume; the nodes' measures sum to the elements';
#  - eq. (19) on a curved membrane: the tube expanded radially by 0.1% (initial displacement_gradient
#    diag(e, e, 0)) stores at its nodes more than a horizon from its ends the energy density
#    (mu/2)(l1^2 + l2^2 + 2/(l1 l2) - 4), l1 = 1.001, l2 = 1, within 2% on average (0.7% measured);
#  - a physical group as a boundary region: the tube's "bottom" ring clamped (its 32 nodes, those at
#    z = 0, never move) while a follower pressure on the file's triangles inflates it (the radius
#    grows), on 1 and 2 ranks with the same positions bit for bit; a tet solid likewise;
#  - polygon pre-cracks: a rectangle in the plane y = 0 cuts the tube's +x wall only, and half of the
#    tet box, with the same damage on 1 and 2 ranks and when a release stage breaks it;
#  - a fiber's path read from a file (`polyline`, with a comment, a blank line, commas and blanks)
#    gives the nodes and the motion of the same path given inline, bit for bit;
#  - frames_surface.xdmf holds the tube's frames over its triangles (meshio reads them), and a tet
#    solid writes none; --dry-run's output size counts the triangles;
#  - --print-scene of a mesh scene reads back to the same text; --dry-run names the mesh's mean
#    edge length and the spacing the horizon is measured in.
# usage: mesh_bodies.sh PERIDRIVE GMSH MPIEXEC [MPI flags...]
set -eu
peridrive=$1 gmsh=$2 mpiexec=$3
shift 3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp"
cat > tube.geo <<'EOF'
R = 0.05; L = 0.2; lc = 0.01;
Point(1) = {0, 0, 0, lc};
Point(2) = {R, 0, 0, lc}; Point(3) = {0, R, 0, lc}; Point(4) = {-R, 0, 0, lc}; Point(5) = {0, -R, 0, lc};
Circle(1) = {2, 1, 3}; Circle(2) = {3, 1, 4}; Circle(3) = {4, 1, 5}; Circle(4) = {5, 1, 2};
out[] = Extrude {0, 0, L} { Curve{1, 2, 3, 4}; };
Physical Surface("wall") = {out[1], out[5], out[9], out[13]};
Physical Curve("bottom") = {1, 2, 3, 4};
EOF
cat > box.geo <<'EOF'
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.02, 0.01, 0.005};
Mesh.MeshSizeMax = 0.002;
EOF
cat > rod.geo <<'EOF'
SetFactory("OpenCASCADE");
Cylinder(1) = {0, 0, 0, 0, 0, 0.02, 0.005, 2*Pi};
Mesh.MeshSizeMax = 0.0015;
Physical Volume("rod") = {1};
Physical Surface("base") = {3};
EOF
"$gmsh" -2 -format msh41 tube.geo -o tube.msh -v 0 > /dev/null
"$gmsh" -2 tube.geo -o tube.stl -v 0 > /dev/null
"$gmsh" -3 -format msh41 box.geo -o box.msh -v 0 > /dev/null
"$gmsh" -3 -format msh41 rod.geo -o rod.msh -v 0 > /dev/null
membrane() {  # NAME MESH [BODY_KEYS [SECTIONS]]
  printf 'name: %s\nmaterials:\n  rubber: {model: membrane, density: 1000, bulk_modulus: 1.0e6}\nbodies:\n  shell: {kind: membrane, material: rubber, mesh: %s, thickness: 0.001%s}\n%b\nstages:\n  - {name: run, kind: dynamic, steps: 1}\noutput: {frames: 2}\n' \
    "$1" "$2" "${3:-}" "${4:-}" > "$1.yaml"
}
solid() {  # NAME MESH [BODY_KEYS [SECTIONS]]
  printf 'name: %s\nmaterials:\n  steel: {model: pmb, density: 8000, youngs_modulus: 2.0e11}\nbodies:\n  block: {kind: solid, material: steel, mesh: %s%s}\n%b\nstages:\n  - {name: run, kind: dynamic, steps: 1}\noutput: {frames: 2}\n' \
    "$1" "$2" "${3:-}" "${4:-}" > "$1.yaml"
}
membrane area tube.msh
membrane stl tube.stl
membrane strain tube.msh '' 'initial: {displacement_gradient: [[0.001, 0, 0], [0, 0.001, 0], [0, 0, 0]]}'
membrane inflate tube.msh ', pressure: 1000' 'boundaries:\n  - {name: clamp, region: {body: shell, group: bottom}}'
sed -i 's/steps: 1}/steps: 40}/' inflate.yaml
solid box box.msh
solid box2 box.msh ', scale: 2'
solid rod rod.msh '' 'boundaries:\n  - {name: base, region: {body: block, group: base}, velocity: [0, 0, 1]}'
# Polygon pre-cracks: a 40 mm axial cut in the tube's +x wall (a rectangle in the plane y = 0
# that the -x wall never meets), and half of the tet box cut at x = 10.1 mm.
membrane tubecut tube.msh '' 'cracks:\n  - {name: side, polygon: [[0.04, 0, 0.08], [0.06, 0, 0.08], [0.06, 0, 0.12], [0.04, 0, 0.12]]}'
solid boxcut box.msh '' 'cracks:\n  - {name: half, polygon: [[0.0101, -1, -1], [0.0101, 0.005, -1], [0.0101, 0.005, 1], [0.0101, -1, 1]]}'
# The same polygon broken by a release stage instead (on 2 ranks).
sed 's/^stages:$/stages:\n  - {name: cut, kind: release, cracks: [half]}/' boxcut.yaml > boxrelease.yaml
sed -i 's/steps: 1}/steps: 20}/' rod.yaml
# A fiber's path from a file (`polyline`) and inline: the same nodes.
printf '# a bent fiber\n0, 0, 0\n\n0.01 0 0\n0.01,0.01,0.002\n' > bent.xyz
fiber() {  # NAME PATH_KEY
  printf 'name: %s\nmaterials:\n  nylon: {model: membrane, density: 1100, youngs_modulus: 2.0e9}\nbodies:\n  f: {kind: fiber, material: nylon, %s, diameter: 0.0002, spacing: 0.0005}\nboundaries:\n  - {name: pull, region: {min: [-1, -1, -1], max: [0.0003, 1, 1]}, velocity: [-1, 0, 0]}\nstages:\n  - {name: run, kind: dynamic, steps: 20}\noutput: {frames: 2}\n' "$1" "$2" > "$1.yaml"
}
fiber inline 'path: [[0, 0, 0], [0.01, 0, 0], [0.01, 0.01, 0.002]]'
fiber polyline 'polyline: bent.xyz'
for s in area stl strain box box2 inline polyline tubecut; do "$peridrive" $s.yaml --out out-$s --quiet; done
for s in inflate rod boxcut; do
  "$peridrive" $s.yaml --out out-$s --quiet
  "$mpiexec" -n 2 "$@" "$peridrive" $s.yaml --out out-$s-np2 --quiet
done
"$peridrive" inflate.yaml --print-scene > printed.yaml
"$peridrive" printed.yaml --print-scene > printed2.yaml
"$peridrive" inflate.yaml --dry-run > dry.txt
"$peridrive" boxcut.yaml --dry-run > dry-box.txt
"$mpiexec" -n 2 "$@" "$peridrive" boxrelease.yaml --out out-boxrelease > boxrelease.txt
/usr/bin/python3 - "$tmp" <<'PY'
import sys, h5py, numpy as np
tmp = sys.argv[1]
checks = []
def check(name, ok, detail):
    checks.append(bool(ok))
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")
def frames(run):
    with h5py.File(f"{tmp}/out-{run}/frames.h5", "r") as f:
        keys = sorted(f["frames"].keys())
        return ({k: {d: f["frames"][k][d][()] for d in f["frames"][k].keys()} for k in keys},
                f["mesh/reference_position"][()], f["mesh/volume"][()])
R, L, h = 0.05, 0.2, 0.001
_, X, V = frames("area")
A = V.sum() / h
check("tube area", abs(A / (2 * np.pi * R * L) - 1) < 3e-3, f"{A:.6g} m^2 against 2 pi R L = {2 * np.pi * R * L:.6g} (error {A / (2 * np.pi * R * L) - 1:.2e}, tolerance 3e-3); {len(V)} nodes")
_, Xs, Vs = frames("stl")
check("STL tube", len(Vs) == len(V) and abs(Vs.sum() / V.sum() - 1) < 1e-6,
      f"{len(Vs)} nodes, area {Vs.sum() / h:.6g} m^2 (relative difference {Vs.sum() / V.sum() - 1:.1e})")
_, Xb, Vb = frames("box")
check("box volume", abs(Vb.sum() / 1e-6 - 1) < 1e-12, f"{Vb.sum():.15g} m^3 against 1e-6 ({len(Vb)} nodes)")
_, _, Vb2 = frames("box2")
check("scale 2", abs(Vb2.sum() / (8 * Vb.sum()) - 1) < 1e-12, f"{Vb2.sum():.15g} m^3 = 8 x {Vb.sum():.15g}")
_, Xr, Vr = frames("rod")
exact = np.pi * 0.005 ** 2 * 0.02
check("rod volume", abs(Vr.sum() / exact - 1) < 2e-2, f"{Vr.sum():.6g} m^3 against pi R^2 L = {exact:.6g} (error {Vr.sum() / exact - 1:.2e}, tolerance 2e-2)")
# Eq. (19) on the expanded tube: mu = K/2 = 0.5 MPa; W per unit volume (the frames' density).
fr, X, _ = frames("strain")
W = fr[sorted(fr)[0]]["strain_energy_density"]
delta = float([l.split("=")[1] for l in open(f"{tmp}/dry.txt") if l.startswith("shell.horizon")][0])
inner = (X[:, 2] > delta) & (X[:, 2] < L - delta)
l1, l2, mu = 1.001, 1.0, 0.5e6
W19 = mu / 2 * (l1 ** 2 + l2 ** 2 + 2 / (l1 * l2) - 4)
err = W[inner].mean() / W19 - 1
check("eq. (19) on the curved membrane", abs(err) < 2e-2,
      f"mean W {W[inner].mean():.5g} J/m^3 at {inner.sum()} nodes against {W19:.5g} (error {err:.2e}, tolerance 2e-2; node scatter {W[inner].std() / W19:.1e}); horizon {delta:.4g} m")
# The clamped group and the follower pressure, 1 and 2 ranks.
fr, X, _ = frames("inflate")
x = fr[sorted(fr)[-1]]["position"]
bottom = X[:, 2] == 0
dr = np.hypot(x[:, 0], x[:, 1]) - np.hypot(X[:, 0], X[:, 1])
check("group 'bottom' clamped", bottom.sum() == 32 and np.abs(x[bottom] - X[bottom]).max() == 0,
      f"{bottom.sum()} nodes at z = 0 unmoved; the others moved up to {np.abs(x - X).max():.2e} m")
check("pressure inflates", dr[~bottom].mean() > 0 and (dr[~bottom] > 0).mean() > 0.95, f"mean radial displacement {dr[~bottom].mean():.3e} m")
fr2, _, _ = frames("inflate-np2")
check("1 and 2 ranks, membrane", np.array_equal(x, fr2[sorted(fr2)[-1]]["position"]), "positions bit for bit")
fr, X, _ = frames("rod")
fr2, _, _ = frames("rod-np2")
x = fr[sorted(fr)[-1]]["position"]
check("1 and 2 ranks, solid", np.array_equal(x, fr2[sorted(fr2)[-1]]["position"]) and np.abs(x - X).max() > 0,
      f"positions bit for bit (moved up to {np.abs(x - X).max():.2e} m)")
fa, Xa, Va = frames("inline")
fb, Xb, Vb = frames("polyline")
xa, xb = fa[sorted(fa)[-1]]["position"], fb[sorted(fb)[-1]]["position"]
check("polyline file", np.array_equal(Xa, Xb) and np.array_equal(Va, Vb) and np.array_equal(xa, xb) and len(Va) == 40 and np.abs(xb - Xb).max() > 0,
      f"{len(Vb)} nodes, reference and final positions as the inline path's bit for bit")
# Polygon pre-cracks: on the tube the damage lies in the +x wall along the cut alone; in the box on
# the cut's side of y = 5 mm, the same bits on 1 and 2 ranks.
import json
fr, X, _ = frames("tubecut")
D = fr[sorted(fr)[0]]["damage"]
hit = D > 0
pre = json.load(open(f"{tmp}/out-tubecut/summary.json"))["precrack_bonds"]
# (A bond meets the plane y = 0 at 0.04 < x < 0.06 only if both its ends lie within a horizon of
# that strip: x > sqrt(R^2 - delta^2) on the circle.)
near = (X[:, 0] >= np.sqrt(R ** 2 - delta ** 2) - 1e-3) & (X[:, 2] > 0.08 - delta) & (X[:, 2] < 0.12 + delta)
check("polygon cut on a curved membrane", hit.sum() > 10 and near[hit].all() and pre > 20,
      f"{pre} bonds cut, {hit.sum()} nodes damaged, all in the +x wall within a horizon of the cut (x >= {np.sqrt(R ** 2 - delta ** 2):.4f} m)")
fr, X, _ = frames("boxcut")
fr2, _, _ = frames("boxcut-np2")
D, D2 = fr[sorted(fr)[0]]["damage"], fr2[sorted(fr2)[0]]["damage"]
pre = [json.load(open(f"{tmp}/out-{r}/summary.json"))["precrack_bonds"] for r in ("boxcut", "boxcut-np2")]
hit = D > 0
dbox = float([l.split("=")[1] for l in open(f"{tmp}/dry-box.txt") if l.startswith("block.horizon")][0])
near = (np.abs(X[:, 0] - 0.0101) <= dbox) & (X[:, 1] <= 0.005 + dbox)
check("polygon cut in a tet solid", hit.sum() > 10 and near[hit].all() and np.array_equal(D, D2) and pre[0] == pre[1] and pre[0] > 50,
      f"{pre[0]} bonds cut, {hit.sum()} nodes damaged, all within a horizon ({dbox:.4g} m) of the cut; damage on 2 ranks the same bits ({pre[1]} bonds)")
released = [int(l.split(":")[1].split()[0]) for l in open(f"{tmp}/boxrelease.txt") if "release 'cut'" in l]
fr3, _, _ = frames("boxrelease")
check("polygon released by a stage", released == [pre[0]] and np.array_equal(fr3[sorted(fr3)[-1]]["damage"], fr[sorted(fr)[-1]]["damage"]),
      f"release stage 'cut': {released} bonds broken against {pre[0]} at the start; the same damage")
# frames_surface.xdmf: the same frames over the file's triangles, as meshio reads it (a rod of
# tetrahedra has no surface file).
import os, meshio
with h5py.File(f"{tmp}/out-inflate/frames.h5", "r") as f:
    tri = f["mesh/triangles"][()]
    X = f["mesh/reference_position"][()]
    last = f["frames"][sorted(f["frames"].keys())[-1]]["position"][()]
with meshio.xdmf.TimeSeriesReader(f"{tmp}/out-inflate/frames_surface.xdmf") as r:
    points, cells = r.read_points_cells()
    t, point_data, _ = r.read_data(r.num_steps - 1)
cells = {c.type: c.data for c in cells}
check("surface XDMF", list(cells) == ["triangle"] and np.array_equal(cells["triangle"], tri) and len(points) == len(X)
      and np.array_equal(point_data["displacement"] + X, last) and not os.path.exists(f"{tmp}/out-rod/frames_surface.xdmf"),
      f"{len(tri)} triangles over {len(points)} nodes, {r.num_steps} steps; none for the tet rod")
a, b = open(f"{tmp}/printed.yaml").read(), open(f"{tmp}/printed2.yaml").read()
check("--print-scene round trip", a == b and "# spacing: not given; the mesh's mean edge length" in a and "group: bottom" in a, "same text")
dry = open(f"{tmp}/dry.txt").read()
edge = [float(l.split("=")[1]) for l in dry.splitlines() if l.startswith("shell.mesh_mean_edge_length")]
spacing = [float(l.split("=")[1]) for l in dry.splitlines() if l.startswith("shell.spacing")]
# The output's size counts the triangles /mesh/triangles holds (24 bytes each) beside the frames
# and the mesh's 48 bytes per node (and 64 KiB of headroom); the figures printed to 4 digits.
out = {l.split("=")[0].strip(): float(l.split("=")[1]) for l in dry.splitlines() if l.startswith("output.")}
rest = out["output.bytes"] - out["output.frames"] * out["output.frame_bytes"] - 48 * out["output.frame_nodes"] - 65536
check("output size counts the triangles", abs(rest - 24 * len(tri)) < 1e-3 * out["output.bytes"],
      f"{out['output.bytes']:.4g} bytes: {rest:.0f} beyond the frames and nodes, 24 x {len(tri)} triangles = {24 * len(tri)}")
check("--dry-run names the mean edge", edge and spacing and edge == spacing and abs(delta / (3 * edge[0]) - 1) < 1e-9,
      f"mean edge {edge}, spacing {spacing}, horizon {delta} = 3 spacings")
sys.exit(0 if all(checks) else 1)
PY

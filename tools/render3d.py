#!/usr/bin/env python3
"""Shaded 3D picture of one frame of a peridrive run, coloured by a node field.

usage: /usr/bin/python3 tools/render3d.py OUTDIR [--frame N|last] [--time T]
           [--field damage|strain_energy_density|displacement|displacement_x|_y|_z|velocity|body]
           [--view ELEV,AZIM] [--out FILE.png] [--deformed | --reference] [--clip 'x>0.01' ...]
           [--range LO,HI] [--gap-damage D] [--gap-stretch S] [--no-gaps] [--no-tools]
           [--size W,H] [--dpi DPI] [--title TEXT] [--stats FILE.json] [--mesh FILE.npz]

What is drawn, by body kind:
  membrane, lattice  a surface of triangles: a Delaunay triangulation of the reference (x, y)
                     positions (matplotlib.tri), drawn at the current positions (--deformed, the
                     default) or the reference ones (--reference); a mesh membrane (`mesh:`), the
                     mesh's own triangles (frames.h5 /mesh/triangles), curved or not
  sphere             a closed surface: the convex hull of the reference positions (scipy's
                     ConvexHull; without scipy, a Delaunay triangulation of their stereographic
                     projection, which gives the same hull)
  fiber              thick lines between consecutive nodes of a fiber, shaded as tubes
  solid              the nodes as points
Faces are shaded by their normals (Lambert, two-sided, a light above and to the left of the eye)
and coloured by the mean of their corners' field. Triangles that span broken material are left
out, so that holes and cracks show as gaps; a triangle is dropped when
  - a reference edge is longer than 2 median edges (cutouts, the hull of a non-convex sheet),
  - a corner's damage is at least --gap-damage (0.99: a node that has lost its bonds),
  - an edge is stretched, in the current configuration, beyond the critical stretch of the body's
    material (pmb: 1 + s_0, membrane: lambda_0; --gap-stretch S overrides it: current / reference
    length > S): that edge's bond is broken,
  - an edge meets a scene crack, a slit in the xy plane or a polygon in space (the pre-crack rule
    of docs/user/precracks.md; a crack a release stage breaks only where both ends of the edge
    are damaged).
--no-gaps draws every triangle. Fiber segments follow the same rules (a segment is one edge).
Tools (a cylinder's axis along z, a sphere) are drawn in grey at their position at the frame's
time (series.csv, else centre + velocity x time); --no-tools leaves them out.

Defaults: the last frame, damage on [0, 1] (grey undamaged to dark red broken), other fields on
their 1st to 99th percentile (signed components symmetric about 0); view 30,-60 for sheets,
20,-60 for fibers and solids, and for a sphere from the side of its damage (its damage-weighted
mean direction from the centre), 20,-60 while it is undamaged. --clip AXIS<VALUE or AXIS>VALUE
(x, y, z in m, current configuration; repeatable) keeps the triangles, segments and points whose
corners all satisfy it: --clip 'y<0' cuts a sphere open. Equal scales on the three axes, lengths
in nm, um, mm or m. The title names the run (the scene's name), the frame and its time.
--out defaults to OUTDIR/render3d_<field>.png; --stats writes the counts (triangles, dropped by
each rule, segments, points, field range) as JSON, --mesh the triangles (frame node indices), the
rule that dropped each (0 kept, 1 reference edge, 2 damage, 3 stretch, 4 crack, 5 clip) and the
fiber segments as .npz. The figure is noted in OUTDIR/figures.json (peri_view.note). A field the
frames do not hold (output.fields) or a bad option is refused with exit status 2.
Needs Debian's python3-h5py, python3-numpy, python3-matplotlib and python3-yaml (python3-scipy
optional).
"""
import argparse
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.tri as mtri  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import LinearSegmentedColormap, Normalize  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peri_view  # noqa: E402

TOOL = "render3d.py"
# Damage on a lit surface: a dark undamaged colour would hide the shading, so undamaged is a light
# grey and broken a dark red (through yellow and orange).
DAMAGE_SURFACE_CMAP = LinearSegmentedColormap.from_list(
    "damage_surface", ["#d4d9e0", "#f2d24b", "#e8731c", "#b5190f", "#5c0a06"])
KEPT, REF_EDGE, DAMAGED, STRETCHED, CRACK, CLIPPED = range(6)
RULES = {REF_EDGE: "reference_edge", DAMAGED: "damage", STRETCHED: "stretch", CRACK: "crack",
         CLIPPED: "clip"}
FIELDS = ("damage", "strain_energy_density", "displacement", "displacement_x", "displacement_y",
          "displacement_z", "velocity", "velocity_x", "velocity_y", "velocity_z", "body")
ALIASES = {"strain_energy": "strain_energy_density", "energy": "strain_energy_density", "u": "displacement",
           "u_x": "displacement_x", "u_y": "displacement_y", "u_z": "displacement_z", "v": "velocity"}


def refuse(message):
    """Print the message and exit with status 2 (what the run or the options cannot give)."""
    print(message, file=sys.stderr)
    sys.exit(2)


# ---------------------------------------------------------------- triangulations

def sphere_triangles(ref, use_scipy=True):
    """The convex hull of points on a sphere, as index triples: scipy's ConvexHull where it is
    installed, else the Delaunay triangulation of the stereographic projection from one node (the
    Delaunay triangles of the projection are the hull's faces not touching that node) closed by
    the fan from that node to the projection's convex boundary."""
    if len(ref) < 4:
        return np.zeros((0, 3), dtype=int)
    if use_scipy:
        try:
            from scipy.spatial import ConvexHull
            return ConvexHull(ref).simplices.astype(int)
        except ImportError:
            pass
    c = ref.mean(axis=0)
    r = ref - c
    radius = np.linalg.norm(r, axis=1).mean()
    pole = int(np.argmax(r[:, 2]))
    # Rotate so that the pole is at +z exactly, then project from it onto the plane z = -R.
    a = r[pole] / np.linalg.norm(r[pole])
    z = np.array([0.0, 0.0, 1.0])
    v, cth = np.cross(a, z), float(a @ z)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    rot = np.eye(3) + vx + vx @ vx / (1.0 + cth) if cth > -1 + 1e-12 else np.diag([1.0, -1.0, -1.0])
    q = r @ rot.T / radius
    others = np.array([k for k in range(len(ref)) if k != pole])
    w = 1.0 - q[others, 2]
    px, py = q[others, 0] / w, q[others, 1] / w
    tri = mtri.Triangulation(px, py)
    faces = [others[t] for t in tri.triangles]
    # The boundary of the projection (edges with one triangle) closes with the pole.
    edges = {}
    for t in tri.triangles:
        for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
            edges[tuple(sorted(e))] = edges.get(tuple(sorted(e)), 0) + 1
    for (i, j), n in edges.items():
        if n == 1:
            faces.append(np.array([pole, others[i], others[j]]))
    return np.array(faces, dtype=int)


def triangle_edges(tris):
    """The three edges (i, j) of each triangle: arrays [T, 3] of first and second corners."""
    return tris, np.roll(tris, -1, axis=1)


def fiber_segments(ref):
    """Consecutive nodes (natural order) of a fiber body closer than 1.5 median neighbour distances
    in the reference configuration: the segments of its fibers (a network's fibers follow one
    another)."""
    if len(ref) < 2:
        return np.zeros((0, 2), dtype=int)
    d = np.linalg.norm(np.diff(ref, axis=0), axis=1)
    h = np.median(d[d > 0]) if (d > 0).any() else 1.0
    k = np.nonzero((d > 0) & (d < 1.5 * h))[0]
    return np.stack([k, k + 1], axis=1)


# ---------------------------------------------------------------- what is broken

def critical_ratio(scene, body):
    """The stretch (current / reference length) beyond which a bond of `body` is broken, from its
    material in the resolved scene: pmb 1 + s_0, membrane lambda_0 (the larger of the values at
    xi = 0 and at the horizon); None when its bonds do not break or the law has no such stretch."""
    b = (scene.get("bodies") or {}).get(body) or {}
    m = (scene.get("materials") or {}).get(b.get("material")) or {}
    values = [m.get(k) for k in ("critical_stretch", "critical_stretch_at_horizon")]
    values = [float(v) for v in values if isinstance(v, (int, float))]
    if not values:
        return None
    model = m.get("model", "membrane")
    if model == "pmb":
        return 1.0 + max(values)
    if model == "membrane":
        return max(values)
    return None


def segments_meet(p, q, a, b):
    """Whether the 2D segments p-q (arrays [E, 2]) and a-b (one segment) have a point in common,
    end points included (orientation signs; collinear overlaps by their projections)."""
    def orient(u, v, w):
        return np.sign((v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1])
                       - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0]))
    a = np.broadcast_to(a, p.shape)
    b = np.broadcast_to(b, p.shape)
    o1, o2, o3, o4 = orient(p, q, a), orient(p, q, b), orient(a, b, p), orient(a, b, q)
    meet = (o1 * o2 <= 0) & (o3 * o4 <= 0)
    collinear = (o1 == 0) & (o2 == 0)
    if collinear.any():
        # On one line: the projections on the line's longer axis must overlap.
        ax = np.where(np.abs(q[:, 0] - p[:, 0]) >= np.abs(q[:, 1] - p[:, 1]), 0, 1)
        rows = np.arange(len(p))
        lo1, hi1 = np.minimum(p[rows, ax], q[rows, ax]), np.maximum(p[rows, ax], q[rows, ax])
        lo2, hi2 = np.minimum(a[rows, ax], b[rows, ax]), np.maximum(a[rows, ax], b[rows, ax])
        meet = np.where(collinear, (lo1 <= hi2) & (lo2 <= hi1), meet)
    return meet


def segments_meet_polygon(p, q, corners):
    """Whether the 3D segments p-q (arrays [E, 3]) meet a convex plane polygon (corners [K, 3]),
    end points and edges included to round-off: the fan of triangles from its first corner, each
    by the side of its plane the ends lie on and the crossing point's barycentric coordinates."""
    meet = np.zeros(len(p), dtype=bool)
    for k in range(1, len(corners) - 1):
        a, b, c = corners[0], corners[k], corners[k + 1]
        n = np.cross(b - a, c - a)
        if not np.any(n):
            continue
        sp, sq = (p - a) @ n, (q - a) @ n
        cross = (sp * sq <= 0) & (sp != sq)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(cross, sp / (sp - sq), 0.0)
        x = p + t[:, None] * (q - p)
        # Barycentric coordinates of x in a b c (with a relative tolerance for its edges).
        e1, e2, w = b - a, c - a, x - a
        d11, d12, d22 = e1 @ e1, e1 @ e2, e2 @ e2
        den = d11 * d22 - d12 * d12
        u = ((w @ e1) * d22 - (w @ e2) * d12) / den
        v = ((w @ e2) * d11 - (w @ e1) * d12) / den
        tol = 1e-12
        meet |= cross & (u >= -tol) & (v >= -tol) & (u + v <= 1 + tol)
    return meet


def released_cracks(scene):
    """Names of the cracks a release stage breaks (not broken at the start)."""
    names = set()
    for s in scene.get("stages") or []:
        if isinstance(s, dict) and s.get("kind") == "release":
            c = s.get("crack") or s.get("cracks")
            names.update(c if isinstance(c, list) else [c])
    return names


def drop_rules(edges_ref, edges_cur, ends, damage, scene, body, gap_damage, gap_stretch, long_edge):
    """Per element (triangle or segment) the first rule that drops it (0: kept). edges_ref and
    edges_cur: [T, E] reference and current lengths of its edges; ends: ([T, E], [T, E]) node
    indices of the edges' ends; damage: the frame's damage (None without it)."""
    t = edges_ref.shape[0]
    rule = np.zeros(t, dtype=int)
    if long_edge is not None:
        rule[(edges_ref > long_edge).any(axis=1)] = REF_EDGE
    i, j = ends
    if damage is not None and gap_damage is not None:
        hit = (damage[i] >= gap_damage).any(axis=1) | (damage[j] >= gap_damage).any(axis=1)
        rule[(rule == KEPT) & hit] = DAMAGED
    ratio = gap_stretch if gap_stretch is not None else critical_ratio(scene, body)
    if ratio is not None:
        with np.errstate(divide="ignore", invalid="ignore"):
            hit = (edges_cur > ratio * edges_ref).any(axis=1)
        rule[(rule == KEPT) & hit] = STRETCHED
    return rule


def crack_rule(rule, ref, ends, scene, damage):
    """Marks CRACK the kept elements with an edge meeting a scene crack: a slit in the xy plane,
    a polygon in space."""
    cracks = scene.get("cracks") or []
    if not cracks:
        return rule
    released = released_cracks(scene)
    i, j = ends
    p, q = ref[i.ravel(), :2], ref[j.ravel(), :2]
    for k, c in enumerate(cracks):
        if "polygon" in c:
            hit = segments_meet_polygon(ref[i.ravel()], ref[j.ravel()], np.asarray(c["polygon"], float))
        else:
            a, b = np.asarray(c["from"], float)[:2], np.asarray(c["to"], float)[:2]
            if np.allclose(a, b):
                continue
            hit = segments_meet(p, q, a, b)
        if c.get("name", f"crack{k}") in released:
            hit &= (damage[i.ravel()] > 0) & (damage[j.ravel()] > 0) if damage is not None else False
        hit = hit.reshape(i.shape).any(axis=1)
        rule[(rule == KEPT) & hit] = CRACK
    return rule


# ---------------------------------------------------------------- frame data

def read_frame(run, which):
    """(index, frame group data) for --frame/--time: time, step, position, and every field."""
    names = run.frame_names
    with run.open() as f:
        if isinstance(which, float):
            times = np.array([float(f["frames"][k].attrs["time"]) for k in names])
            k = int(np.argmin(np.abs(times - which)))
        else:
            k = which if which >= 0 else len(names) + which
            if not 0 <= k < len(names):
                refuse(f"{TOOL}: frame {which} out of range (the run holds {len(names)} frames)")
        g = f["frames"][names[k]]
        data = {name: g[name][...].astype(float) for name in g}
        data["time"], data["step"] = float(g.attrs["time"]), int(g.attrs["step"])
    if "position" not in data:
        # Frames without position or displacement (output.fields) show the reference configuration.
        data["reference_only"] = "displacement" not in data
        data["position"] = run.reference + data["displacement"] if "displacement" in data else run.reference
    if "displacement" not in data and "position" in data:
        data["displacement"] = data["position"] - run.reference
    return k, data


def field_values(name, data, run):
    """(values per node, label, signed) of field `name`."""
    comp = {"x": 0, "y": 1, "z": 2}
    if name == "body":
        return run.body.astype(float), "body (scene index)", False
    if name == "damage":
        if "damage" not in data:
            refuse(f"{TOOL}: the frames hold no damage (output.fields)")
        return data["damage"], "damage (broken fraction)", False
    if name == "strain_energy_density":
        if name not in data:
            refuse(f"{TOOL}: the frames hold no strain_energy_density (output.fields)")
        return data[name], "strain energy density [J/m^3]", False
    base, _, c = name.partition("_")
    vec = data.get(base)
    if vec is None:
        refuse(f"{TOOL}: the frames hold no {base} (output.fields)")
    unit = "m" if base == "displacement" else "m/s"
    if c:
        return vec[:, comp[c]], f"{base} {c} [{unit}]", True
    return np.linalg.norm(vec, axis=1), f"|{base}| [{unit}]", False


def tool_positions(outdir, scene, time):
    """[(kind, radius, centre)] of the scene's tools at `time`: series.csv's columns interpolated,
    else centre + velocity x time."""
    tools = scene.get("tools") or []
    rows = []
    path = os.path.join(outdir, "series.csv")
    if tools and os.path.exists(path):
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    out = []
    for t in tools:
        n, kind = t["name"], t["kind"]
        dim = 3 if kind == "sphere" else 2
        c = np.array(t["center"], float)[:dim] + np.array(t.get("velocity") or [0.0] * dim, float)[:dim] * time
        cols = [f"{n}_{a}" for a in "xyz"[:dim]]
        if rows and all(col in rows[0] for col in cols):
            ts = np.array([float(r["time"]) for r in rows])
            c = np.array([np.interp(time, ts, [float(r[col]) for r in rows]) for col in cols])
        out.append((kind, float(t["radius"]), c))
    return out


# ---------------------------------------------------------------- drawing

def light_direction(elev, azim):
    """A light above and to the left of the eye, in data coordinates (unit vector)."""
    e, a = np.radians(elev), np.radians(azim)
    eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    right = np.array([-np.sin(a), np.cos(a), 0.0])
    up = np.cross(eye, right)
    up = up / np.linalg.norm(up) if np.linalg.norm(up) > 0 else np.array([0.0, 0.0, 1.0])
    if up[2] < 0:
        up = -up
    l_ = eye + 0.7 * up - 0.5 * right
    return l_ / np.linalg.norm(l_)


def shade(rgba, cosines, ambient=0.35):
    """Lambert shading of colours: ambient + (1 - ambient) |cos|, alpha kept."""
    s = ambient + (1.0 - ambient) * np.clip(np.abs(cosines), 0.0, 1.0)
    out = rgba.copy()
    out[:, :3] *= s[:, None]
    return out


def face_normals(v):
    """Unit normals of triangles or planar quads v [F, K, 3] (from their first three corners)."""
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    nn = np.linalg.norm(n, axis=1)
    return n / np.where(nn > 0, nn, 1.0)[:, None]


def tool_faces(kind, r, c, zlo, zhi):
    """Triangles [F, 3, 3] of a tool's surface: a sphere of radius r about c, or a cylinder about
    the axis through c = (x, y) along z, from zlo - r to zhi + r (the bodies' z range)."""
    nu, nv = 36, 18
    u = np.linspace(0, 2 * np.pi, nu + 1)
    if kind == "sphere":
        v = np.linspace(0, np.pi, nv + 1)
        uu, vv = np.meshgrid(u, v)
        grid = np.stack([c[0] + r * np.cos(uu) * np.sin(vv), c[1] + r * np.sin(uu) * np.sin(vv),
                         c[2] + r * np.cos(vv)], axis=-1)
    elif kind == "cylinder":
        uu, zz = np.meshgrid(u, np.linspace(zlo - r, zhi + r, 2))
        grid = np.stack([c[0] + r * np.cos(uu), c[1] + r * np.sin(uu), zz], axis=-1)
    else:
        return None
    a, b, d, e = grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]
    tris = np.concatenate([np.stack([a, b, d], axis=-2).reshape(-1, 3, 3),
                           np.stack([a, d, e], axis=-2).reshape(-1, 3, 3)])
    area = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    return tris[area > 1e-12 * r * r]


def clip_mask(points, clips):
    """Nodes satisfying every --clip condition (AXIS<VALUE or AXIS>VALUE, current positions)."""
    keep = np.ones(len(points), dtype=bool)
    for c in clips:
        for op in "<>":
            if op in c:
                axis, value = c.split(op, 1)
                axis = axis.strip().lower()
                if axis not in ("x", "y", "z"):
                    refuse(f"{TOOL}: --clip {c!r}: expected x, y or z before {op}")
                v = points[:, "xyz".index(axis)]
                keep &= (v < float(value)) if op == "<" else (v > float(value))
                break
        else:
            refuse(f"{TOOL}: --clip {c!r}: expected AXIS<VALUE or AXIS>VALUE")
    return keep


def default_view(view, run, data, mask):
    """(elev, azim): sheets 30,-60; a sphere from the side of its damage; others 20,-60."""
    if view == "sheet":
        return 30.0, -60.0
    if view == "sphere" and "damage" in data:
        d = data["damage"][mask]
        if d.sum() > 0:
            p = data["position"][mask]
            r = p - p.mean(axis=0)
            r = r / np.linalg.norm(r, axis=1)[:, None]
            m = (d[:, None] * r).sum(axis=0)
            if np.linalg.norm(m) > 1e-9 * d.sum():
                m /= np.linalg.norm(m)
                # Look from the damaged side, raised by 20 degrees so that the sphere reads as one.
                azim = np.degrees(np.arctan2(m[1], m[0]))
                elev = float(np.clip(np.degrees(np.arcsin(np.clip(m[2], -1, 1))) + 20.0, -70, 70))
                return elev, float(azim)
    return 20.0, -60.0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--frame", default="last", help="frame index (negative: from the end) or 'last'")
    ap.add_argument("--time", type=float, default=None, help="the frame nearest this time [s]")
    ap.add_argument("--field", default="damage", help=", ".join(FIELDS))
    ap.add_argument("--view", default=None, help="ELEV,AZIM in degrees")
    ap.add_argument("--out", default=None)
    cfg = ap.add_mutually_exclusive_group()
    cfg.add_argument("--deformed", dest="reference", action="store_false", default=False)
    cfg.add_argument("--reference", dest="reference", action="store_true")
    ap.add_argument("--clip", action="append", default=[])
    ap.add_argument("--range", default=None, help="LO,HI colour limits")
    ap.add_argument("--gap-damage", type=float, default=0.99)
    ap.add_argument("--gap-stretch", type=float, default=None)
    ap.add_argument("--no-gaps", action="store_true")
    ap.add_argument("--no-tools", action="store_true")
    ap.add_argument("--no-scipy", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--size", default="8,6", help="W,H in inches")
    ap.add_argument("--dpi", type=float, default=100)
    ap.add_argument("--title", default=None)
    ap.add_argument("--bare", action="store_true", help="no axes, colour bar or title")
    ap.add_argument("--stats", default=None)
    ap.add_argument("--mesh", default=None)
    args = ap.parse_args(argv)

    field = ALIASES.get(args.field, args.field)
    if field not in FIELDS:
        ap.error(f"--field {args.field}: expected one of {', '.join(FIELDS)}")

    def pair(option, text, check, what):
        # "A,B" as two finite numbers that pass `check` (status 2 otherwise, as argparse's errors).
        try:
            a, b = (float(v) for v in text.split(","))
        except ValueError:
            ap.error(f"{option} {text}: expected two numbers {what}")
        if not (np.isfinite(a) and np.isfinite(b) and check(a, b)):
            ap.error(f"{option} {text}: expected {what}")
        return a, b

    if args.range:
        pair("--range", args.range, lambda a, b: a < b, "LO,HI with LO < HI")
    if args.view:
        pair("--view", args.view, lambda a, b: True, "ELEV,AZIM in degrees")
    pair("--size", args.size, lambda a, b: 0 < a <= 100 and 0 < b <= 100, "W,H in inches, each in (0, 100]")
    if not (np.isfinite(args.dpi) and 1 <= args.dpi <= 2000):
        ap.error(f"--dpi {args.dpi}: expected a number in [1, 2000]")
    for c in args.clip:
        value = c.split("<", 1)[-1] if "<" in c else c.split(">", 1)[-1]
        try:
            float(value)
        except ValueError:
            ap.error(f"--clip {c}: expected AXIS<VALUE or AXIS>VALUE with a number")
    for option, path, formats in (("--out", args.out, True), ("--stats", args.stats, False)):
        if path:
            existed = os.path.exists(path)
            try:
                with open(path, "ab"):
                    pass
            except OSError as e:
                ap.error(f"{option} {path}: cannot be written ({e.strerror})")
            if not existed:
                os.remove(path)
            if formats:
                import matplotlib.pyplot as plt_check
                ext = os.path.splitext(path)[1].lstrip(".").lower()
                if ext not in plt_check.gcf().canvas.get_supported_filetypes():
                    ap.error(f"{option} {path}: .{ext} is not a picture format matplotlib writes (png, pdf, svg, ...)")
                plt_check.close("all")
    run = peri_view.Run(args.outdir)
    if args.time is not None:
        which = float(args.time)
    elif args.frame == "last":
        which = -1
    else:
        try:
            which = int(args.frame)
        except ValueError:
            ap.error(f"--frame {args.frame}: expected an integer or 'last'")
    k, data = read_frame(run, which)
    values, label, signed = field_values(field, data, run)
    damage = data.get("damage")
    cur = data["position"]
    if data.get("reference_only") and not args.reference:
        print(f"{TOOL}: the frames hold no position or displacement (output.fields): drawing the reference "
              "configuration", file=sys.stderr)
        args.reference = True
    shown = run.reference if args.reference else cur
    keep_node = clip_mask(cur, args.clip)

    gap_damage = None if args.no_gaps else args.gap_damage
    tris_all, rules_all, segs_all, seg_rules_all, points = [], [], [], [], []
    for b, (name, kind) in enumerate(zip(run.body_names, run.kinds)):
        idx = np.nonzero(run.body == b)[0]
        if len(idx) == 0:
            continue
        ref = run.reference[idx]
        mesh_tris = None
        if kind == "membrane" and run.triangles is not None:  # a mesh membrane: the file's triangles
            mesh_tris = run.triangles[run.body[run.triangles[:, 0]] == b]
        if kind in ("membrane", "lattice", "sphere"):
            if mesh_tris is not None and len(mesh_tris):
                tris = mesh_tris
            else:
                local = peri_view.sheet_triangles(ref) if kind != "sphere" else sphere_triangles(ref, not args.no_scipy)
                tris = idx[local]
            i, j = triangle_edges(tris)
        elif kind == "fiber":
            tris = idx[fiber_segments(ref)]
            i, j = tris[:, :1], tris[:, 1:]
        else:
            points.append(idx)
            continue
        lref = np.linalg.norm(run.reference[i] - run.reference[j], axis=2)
        lcur = np.linalg.norm(cur[i] - cur[j], axis=2)
        long_edge = 2.0 * float(np.median(lref)) if kind != "fiber" and lref.size else None
        if args.no_gaps:
            rule = np.where((lref > long_edge).any(axis=1), REF_EDGE, KEPT) if long_edge else np.zeros(len(tris), int)
        else:
            rule = drop_rules(lref, lcur, (i, j), damage, run.scene, name, gap_damage, args.gap_stretch, long_edge)
            rule = crack_rule(rule, run.reference, (i, j), run.scene, damage)
        rule[(rule == KEPT) & ~keep_node[tris].all(axis=1)] = CLIPPED
        (tris_all if kind != "fiber" else segs_all).append(tris)
        (rules_all if kind != "fiber" else seg_rules_all).append(rule)
    tris = np.concatenate(tris_all) if tris_all else np.zeros((0, 3), int)
    rules = np.concatenate(rules_all) if rules_all else np.zeros(0, int)
    segs = np.concatenate(segs_all) if segs_all else np.zeros((0, 2), int)
    seg_rules = np.concatenate(seg_rules_all) if seg_rules_all else np.zeros(0, int)
    pts = np.concatenate(points) if points else np.zeros(0, int)
    pts = pts[keep_node[pts]]

    # Colours.
    if args.range:
        lo, hi = (float(v) for v in args.range.split(","))
    elif field == "damage":
        lo, hi = peri_view.DAMAGE_LIMITS
    elif field == "body":
        lo, hi = 0.0, max(1.0, len(run.body_names) - 1.0)
    elif signed:
        hi = float(np.percentile(np.abs(values), 99)) or 1.0
        lo = -hi
    else:
        lo, hi = (float(v) for v in np.percentile(values, [1, 99]))
        if hi <= lo:
            hi = lo + (abs(lo) or 1.0)
    cmap = DAMAGE_SURFACE_CMAP if field == "damage" else plt.get_cmap(
        "coolwarm" if signed else ("tab10" if field == "body" else "viridis"))
    norm = Normalize(lo, hi)

    unit, scale = run.unit, run.scale
    p = shown / scale
    visible = np.zeros(len(p), dtype=bool)
    kept_tris = tris[rules == KEPT]
    kept_segs = segs[seg_rules == KEPT]
    visible[kept_tris.ravel()] = True
    visible[kept_segs.ravel()] = True
    visible[pts] = True
    if not visible.any():
        visible[:] = True

    view = run.view
    if args.view:
        elev, azim = (float(v) for v in args.view.split(","))
    else:
        elev, azim = default_view(view, run, data, visible)
    light = light_direction(elev, azim)

    w, h = (float(v) for v in args.size.split(","))
    fig = plt.figure(figsize=(w, h))
    ax = fig.add_axes([0.0, 0.0, 0.84, 0.94], projection="3d")
    mappable = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    if len(kept_segs):
        v = p[kept_segs]
        t = v[:, 1] - v[:, 0]
        t = t / np.maximum(np.linalg.norm(t, axis=1), 1e-300)[:, None]
        rgba = cmap(norm(values[kept_segs].mean(axis=1)))
        # A tube's brightest line faces the light: its Lambert factor is sin(angle(axis, light)).
        colors = shade(rgba, np.sqrt(np.clip(1.0 - (t @ light) ** 2, 0.0, 1.0)))
        lw = 4.0 if len(kept_segs) < 2000 else 2.5 if len(kept_segs) < 20000 else 1.2
        ax.add_collection3d(Line3DCollection(v, colors=colors, linewidths=lw))
    if len(pts):
        ax.scatter(p[pts, 0], p[pts, 1], p[pts, 2], c=values[pts], cmap=cmap, norm=norm, s=4, depthshade=True)

    # Limits: the visible nodes, equal scales.
    q = p[visible]
    lo3, hi3 = q.min(axis=0), q.max(axis=0)
    span = hi3 - lo3
    big = float(span.max()) or 1.0
    pad = 0.02 * big
    lo3, hi3 = lo3 - pad, hi3 + pad
    span = np.maximum(hi3 - lo3, 0.04 * big)
    mid = 0.5 * (lo3 + hi3)
    lo3, hi3 = mid - span / 2, mid + span / 2

    # Faces of the bodies and of the tools in one collection, so that they are sorted by depth
    # together (matplotlib sorts the faces of a collection, but whole collections one behind the
    # other).
    faces, colors = [], []
    if len(kept_tris):
        v = p[kept_tris]
        rgba = cmap(norm(values[kept_tris].mean(axis=1)))
        faces.append(v)
        colors.append(shade(rgba, face_normals(v) @ light))
    tools_drawn = 0
    if not args.no_tools:
        for kind, radius, c in tool_positions(args.outdir, run.scene, data["time"]):
            v = tool_faces(kind, radius / scale, c / scale, lo3[2], hi3[2])
            if v is None or not ((v.max(axis=(0, 1)) > lo3 - 0.25 * big).all()
                                 and (v.min(axis=(0, 1)) < hi3 + 0.25 * big).all()):
                continue
            rgba = np.tile(np.array([0.62, 0.64, 0.68, 1.0]), (len(v), 1))
            faces.append(v)
            colors.append(shade(rgba, face_normals(v) @ light))
            tools_drawn += 1
    if faces:
        v, col = np.concatenate(faces), np.concatenate(colors)
        ax.add_collection3d(Poly3DCollection(v, facecolors=col, edgecolors=col, linewidths=0.4, antialiased=False))

    ax.set_xlim(lo3[0], hi3[0])
    ax.set_ylim(lo3[1], hi3[1])
    ax.set_zlim(lo3[2], hi3[2])
    ax.set_box_aspect(tuple(span / span.max()), zoom=1.0)
    ax.view_init(elev, azim)
    ax.set_xlabel(f"x [{unit}]")
    ax.set_ylabel(f"y [{unit}]")
    ax.set_zlabel(f"z [{unit}]", labelpad=6)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.pane.set_facecolor((1, 1, 1, 0))
        axis.pane.set_edgecolor("0.85")
    ax.grid(False)
    ax.tick_params(labelsize=7, pad=1)
    for axis, extent in zip((ax.xaxis, ax.yaxis, ax.zaxis), span):
        axis.set_major_locator(MaxNLocator(max(2, int(round(8 * extent / span.max())))))
    name = run.scene.get("name", os.path.basename(os.path.normpath(args.outdir)))
    with run.open() as f:
        duration = float(f["frames"][run.frame_names[-1]].attrs["time"])
    tu, ts = peri_view.time_unit(max(duration, data["time"], 1e-300))
    title = args.title or (f"{name}: frame {k} of {len(run.frame_names) - 1}, t = {data['time'] / ts:.4g} {tu}"
                           f" ({'reference' if args.reference else 'deformed'}, view {elev:.0f},{azim:.0f})")
    if args.bare:
        ax.set_axis_off()
    else:
        ax.set_title(title, fontsize=10)
        fig.colorbar(mappable, cax=fig.add_axes([0.9, 0.25, 0.02, 0.5]), label=label)
    out = args.out or os.path.join(args.outdir, f"render3d_{field}.png")
    fig.savefig(out, dpi=args.dpi, bbox_inches="tight", pad_inches=0.15)
    peri_view.note(args.outdir, os.path.basename(out), TOOL, "render3d", fig, mappable, unit)
    plt.close(fig)

    counts = {RULES[r]: int((rules == r).sum()) for r in RULES}
    seg_counts = {RULES[r]: int((seg_rules == r).sum()) for r in RULES}
    stats = dict(run=name, frame=k, time=data["time"], step=data["step"], field=field, range=[lo, hi],
                 view=[elev, azim], configuration="reference" if args.reference else "deformed",
                 triangles=int(len(tris)), triangles_drawn=int((rules == KEPT).sum()), triangles_dropped=counts,
                 segments=int(len(segs)), segments_drawn=int((seg_rules == KEPT).sum()), segments_dropped=seg_counts,
                 points=int(len(pts)), tools=tools_drawn, out=out)
    if args.stats:
        with open(args.stats, "w") as f:
            json.dump(stats, f, indent=1)
    if args.mesh:
        np.savez(args.mesh, triangles=tris, triangle_rule=rules, segments=segs, segment_rule=seg_rules)
    dropped = ", ".join(f"{v} {k_}" for k_, v in counts.items() if v)
    print(f"wrote {out}: frame {k}, t = {data['time']:.4g} s, {stats['triangles_drawn']} of {len(tris)} triangles"
          + (f" (dropped: {dropped})" if dropped else "")
          + (f", {stats['segments_drawn']} of {len(segs)} segments" if len(segs) else "")
          + (f", {len(pts)} points" if len(pts) else ""))
    return stats


if __name__ == "__main__":
    peri_view.run_tool(main)

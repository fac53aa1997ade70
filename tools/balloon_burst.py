#!/usr/bin/env python3
"""How far and how fast a struck balloon tears: the crack front's arc from the impact point against
time, its speed against the Rayleigh wave speed, and the pieces the balloon breaks into.

usage: /usr/bin/python3 tools/balloon_burst.py OUTDIR [--damage D] [--min-piece N] [--json-only]

Reads OUTDIR/frames.h5 and OUTDIR/scene.resolved.yaml of a run with one `sphere` body and a
`sphere` tool (the fragment). The impact point is where the fragment's initial velocity points
into the sphere, from its centre (-v/|v| from the sphere's centre). For each frame:
  - front_angle: the polar angle from the impact point (reference configuration, degrees) that 98%
    of the damaged nodes (damage >= D, default 0.3) lie within, counting only those within 135
    degrees (the fragment's exit hole at 180 degrees is not a crack from the impact);
  - front_arc: that angle as reference arc length R theta [m], and in fragment radii.
The crack speed is the least-squares slope of front_arc against time over the frames where the
front is between 15 and 120 degrees: a reference-frame speed, against the body's Rayleigh wave
speed (the derived constant rayleigh_wave_speed). Pieces in the last frame: the geodesic sphere's
triangles (convex hull of the reference positions) left whole -- no corner with damage >= 0.5, no
edge stretched beyond the material's critical stretch, the rule tools/render3d.py draws by --
joined across shared edges; `fragments` counts the pieces other than the largest with at least N
triangles (default 20).
Writes OUTDIR/burst.csv, OUTDIR/burst.json and OUTDIR/burst.png (front arc against time).
Needs Debian's python3-h5py, python3-numpy, python3-scipy and python3-matplotlib.
"""
import argparse
import json
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peri_view  # noqa: E402


def resolved(out):
    with open(os.path.join(out, "scene.resolved.yaml")) as f:
        text = f.read()
    values = {k: float(v) for k, v in re.findall(r"^# \S*?(\w+) = (\S+)$", text, re.M)
              if re.fullmatch(r"[-+0-9.eE]+", v)}
    sphere = re.search(r"kind: sphere\n(?:    .*\n)*?    center: \[([^\]]*)\]\n(?:    .*\n)*?    radius: (\S+)", text)
    tool = re.search(r"tools:\n  - name: (\S+)\n    kind: sphere\n    radius: (\S+)\n    center: \[([^\]]*)\]\n"
                     r"    velocity: \[([^\]]*)\]", text)
    stretch = re.search(r"critical_stretch: (\S+)", text)
    if not sphere or not tool:
        sys.exit(f"balloon_burst.py: {out}: expected a sphere body and a sphere tool in scene.resolved.yaml")
    vec = lambda s: np.array([float(x) for x in s.split(",")])
    return dict(center=vec(sphere.group(1)), radius=float(sphere.group(2)), tool=tool.group(1),
                tool_radius=float(tool.group(2)), tool_velocity=vec(tool.group(4)),
                critical_stretch=float(stretch.group(1)) if stretch else None,
                rayleigh=values.get("rayleigh_wave_speed"))


def pieces(ref, cur, damage, critical_stretch):
    """Sizes (triangles) of the pieces of whole triangles of the geodesic sphere, largest first."""
    from scipy.spatial import ConvexHull
    labels = peri_view.whole_pieces(ConvexHull(ref).simplices, ref, cur, damage, critical_stretch)
    return np.bincount(labels[labels >= 0]) if (labels >= 0).any() else np.zeros(0, int)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--damage", type=float, default=0.3)
    ap.add_argument("--min-piece", type=int, default=20)
    ap.add_argument("--json-only", action="store_true")
    args = ap.parse_args()
    if not 0 < args.damage <= 1:
        ap.error(f"--damage: expected a broken fraction in (0, 1], got {args.damage}")
    if args.min_piece < 1:
        ap.error(f"--min-piece: expected at least 1 triangle, got {args.min_piece}")
    peri_view.require_run(args.out)
    s = resolved(args.out)
    v = s["tool_velocity"]
    if not np.linalg.norm(v) > 0:
        sys.exit("balloon_burst.py: the fragment does not move; no impact point")
    impact = -v / np.linalg.norm(v)
    rows = []
    with peri_view.open_frames(args.out) as f:
        ref = f["mesh/reference_position"][...].reshape(-1, 3)
        rel = ref - s["center"]
        theta = np.degrees(np.arccos(np.clip(rel @ impact / np.linalg.norm(rel, axis=1), -1, 1)))
        names = peri_view.frame_names(f, args.out)
        if not names:
            sys.exit(f"balloon_burst.py: {args.out}: no complete frame")
        if "damage" not in f["frames"][names[0]]:
            sys.exit(f"balloon_burst.py: the frames of {args.out} hold no damage (output.fields); run the scene with it")
        for name in names:
            g = f["frames"][name]
            d = g["damage"][...]
            near = (d >= args.damage) & (theta < 135)
            angle = float(np.percentile(theta[near], 98)) if near.sum() >= 3 else 0.0
            rows.append((float(g.attrs["time"]), angle, int((d >= args.damage).sum())))
        last = f["frames"][names[-1]]
        cur = last["position"][...].reshape(-1, 3) if "position" in last else None
        dlast = last["damage"][...]
    t = np.array([r[0] for r in rows])
    angle = np.array([r[1] for r in rows])
    arc = np.radians(angle) * s["radius"]
    use = (angle >= 15) & (angle <= 120)
    speed = float(np.polyfit(t[use], arc[use], 1)[0]) if use.sum() >= 3 else None
    sizes = pieces(ref, cur, dlast, s["critical_stretch"]) if cur is not None else np.zeros(0, int)
    fragments = int((sizes[1:] >= args.min_piece).sum()) if sizes.size else 0
    result = {"impact_direction": impact.tolist(), "front_angle_deg": float(angle[-1]),
              "front_arc": float(arc[-1]), "front_arc_over_fragment_radius": float(arc[-1] / s["tool_radius"]),
              "largest_front_angle_deg": float(angle.max()),
              "crack_speed": speed, "rayleigh_wave_speed": s["rayleigh"],
              "crack_speed_over_rayleigh": speed / s["rayleigh"] if speed and s["rayleigh"] else None,
              "frames_used": int(use.sum()), "damaged_nodes": rows[-1][2],
              "pieces_triangles": sizes[:10].tolist(), "fragments": fragments}
    with open(os.path.join(args.out, "burst.csv"), "w") as o:
        o.write("time,front_angle_deg,front_arc,damaged_nodes\n")
        for (tt, a, n), ar in zip(rows, arc):
            o.write(f"{tt:.9g},{a:.6g},{ar:.6g},{n}\n")
    with open(os.path.join(args.out, "burst.json"), "w") as o:
        json.dump(result, o, indent=2)
    print(json.dumps(result, indent=2))
    if args.json_only:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.5, 4))
    ax.plot(t * 1e3, arc * 1e3, "o-", ms=3, label="crack front (98% of damaged nodes within)")
    if speed:
        t0 = t[use][0]
        a0 = arc[use][0]
        ax.plot(t[use] * 1e3, (a0 + speed * (t[use] - t0)) * 1e3, "k-",
                label=f"fit: {speed:.0f} m/s = {speed / s['rayleigh']:.2f} c_R" if s["rayleigh"] else f"fit: {speed:.0f} m/s")
    ax.set_xlabel("t [ms]")
    ax.set_ylabel("arc from the impact point [mm] (reference)")
    ax.set_title(f"crack front on the balloon; {fragments} fragments at the end")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "burst.png"), dpi=110)


if __name__ == "__main__":
    peri_view.run_tool(main)

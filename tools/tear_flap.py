#!/usr/bin/env python3
"""The two tears of a pulled flap (example 7.3): their paths, whether and where they meet, and
whether the flap between them comes off the sheet.

usage: /usr/bin/python3 tools/tear_flap.py OUTDIR [--grip NAME] [--frame K] [--damage D] [--json-only]

Reads OUTDIR/frames.h5 and OUTDIR/scene.resolved.yaml of a sheet run whose boundary `--grip`
(default: grip) pulls a segment of the sheet's free edge. In the reference configuration, in bands
of two spacings from the grip's inner edge toward the opposite edge, the damaged nodes (damage >=
D, default 0.3; none within 3 spacings of the sheet's other edges) fall into clusters (a gap wider
than two horizons splits them): where there are two or more, the leftmost and rightmost are the two
tears; the tears meet at the first band with a single cluster, between the two tears of the band
above, which had come within six horizons and half their first distance of each other (merge_y); the
convergence angle is the angle between the least-squares lines of the two paths above it. The flap separates when the grip's nodes and the clamped edges' nodes lie
on different pieces of whole triangles (no corner with damage >= 0.5, no edge stretched beyond the
material's critical stretch: peri_view.whole_pieces, the rule tools/render3d.py draws by) in the
frame (default: the last); the flap's area is that piece's (reference configuration, m^2).
tears_at_top: the two tears' x in the band next to the grip.
Outcome: "flap cut out" (the tears met and the flap came off), "grip torn off" (off without a
meeting, the piece at most twice the grip's own area), "flap torn off" (a larger piece off without
a clean meeting), "two tears",
"one tear or none".
Writes OUTDIR/tear_flap.json and OUTDIR/tear_flap.png (damage with the two paths and the merge).
Needs Debian's python3-h5py, python3-numpy, python3-matplotlib and python3-yaml.
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peri_view  # noqa: E402


def in_region(X, region):
    lo, hi = np.asarray(region["min"], float), np.asarray(region["max"], float)
    return np.all((X >= lo) & (X <= hi), axis=1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--grip", default="grip")
    ap.add_argument("--frame", type=int, default=-1)
    ap.add_argument("--damage", type=float, default=0.3)
    ap.add_argument("--json-only", action="store_true")
    args = ap.parse_args()
    scene = peri_view.yaml.safe_load(peri_view.scene_text(args.out))
    bounds = {b["name"]: b for b in scene.get("boundaries") or []}
    if args.grip not in bounds:
        sys.exit(f"tear_flap.py: {args.out}: no boundary named '{args.grip}'")
    body = next(iter(scene["bodies"].values()))
    spacing = float(body["spacing"])
    material = scene["materials"][body["material"]]
    s0 = material.get("critical_stretch")
    critical = (1 + float(s0) if material.get("model") == "pmb" else float(s0)) if s0 is not None else None
    with peri_view.open_frames(args.out) as f:
        X = f["mesh/reference_position"][...].reshape(-1, 3)
        names = peri_view.frame_names(f, args.out)
        if not names:
            sys.exit(f"tear_flap.py: {args.out}: no complete frame")
        if not -len(names) <= args.frame < len(names):
            sys.exit(f"tear_flap.py: --frame {args.frame}: the run holds frames 0 .. {len(names) - 1}")
        g = f["frames"][names[args.frame]]
        missing = [k for k in ("damage", "position") if k not in g]
        if missing:
            sys.exit(f"tear_flap.py: the frames of {args.out} hold no {', '.join(missing)} (output.fields); run the "
                     "scene with them")
        damage = g["damage"][...]
        cur = g["position"][...].reshape(-1, 3)
        time = float(g.attrs["time"])
    grip = in_region(X, bounds[args.grip]["region"])
    if not grip.any():
        sys.exit(f"tear_flap.py: boundary '{args.grip}' holds no node")
    clamped = np.zeros(len(X), bool)
    for name, b in bounds.items():
        if name != args.grip:
            clamped |= in_region(X, b["region"])
    lo, hi = X[:, :2].min(axis=0), X[:, :2].max(axis=0)
    gx = X[grip, 0]
    top = X[grip, 1].min()                    # the grip's inner edge; the tears run toward -y
    margin = 3 * spacing
    damaged = ((damage >= args.damage) & (X[:, 0] > lo[0] + margin) & (X[:, 0] < hi[0] - margin)
               & (X[:, 1] > lo[1] + margin))
    # Per band, the damaged x's in clusters (gaps wider than two horizons split them): two or more
    # clusters are the two tears (leftmost and rightmost), one cluster below two is where they met.
    horizon = spacing * float(body.get("horizon_factor", 3))
    band = 2 * spacing
    ys, left, right, count = [], [], [], []
    y = top - 0.5 * band
    while y > lo[1] + margin:
        xs = np.sort(X[damaged & (np.abs(X[:, 1] - y) <= 0.5 * band), 0])
        groups = np.split(xs, np.nonzero(np.diff(xs) > 2 * horizon)[0] + 1) if xs.size else []
        ys.append(y)
        count.append(len(groups))
        left.append(groups[0].mean() if len(groups) >= 2 else np.nan)
        right.append(groups[-1].mean() if len(groups) >= 2 else np.nan)
        y -= band
    ys, left, right, count = np.array(ys), np.array(left), np.array(right), np.array(count)
    both = count >= 2
    # A single cluster right below two that were within six horizons of each other and half their
    # first distance apart, and between them: the tears met (one tear ending, or leaving for a
    # clamp, is not a meeting).
    meet = []
    for k in range(1, len(ys)):
        gap0 = (right - left)[both][0] if both.any() else np.inf
        if count[k] == 1 and both[k - 1] and right[k - 1] - left[k - 1] <= min(6 * horizon, 0.5 * gap0):
            xs = X[damaged & (np.abs(X[:, 1] - ys[k]) <= 0.5 * band), 0]
            if left[k - 1] - 2 * horizon <= xs.mean() <= right[k - 1] + 2 * horizon:
                meet.append(k)
                break
    meet = np.array(meet, dtype=int)
    merge_y = float(ys[meet[0]]) if meet.size else None
    angle = None
    if meet.size:
        above = both & (ys > merge_y)
        if above.sum() >= 3:
            kl = np.polyfit(ys[above], left[above], 1)[0]   # dx/dy of each path
            kr = np.polyfit(ys[above], right[above], 1)[0]
            angle = float(np.degrees(abs(np.arctan(kl) - np.arctan(kr))))
    tris = peri_view.sheet_triangles(X)
    labels = peri_view.whole_pieces(tris, X, cur, damage, critical)
    node_piece = np.full(len(X), -1)
    for c in range(3):
        ok = labels >= 0
        node_piece[tris[ok, c]] = labels[ok]
    grip_pieces = set(node_piece[grip & (node_piece >= 0)].tolist())
    clamp_pieces = set(node_piece[clamped & (node_piece >= 0)].tolist())
    separated = bool(grip_pieces) and not (grip_pieces & clamp_pieces)
    flap_area = None
    if separated:
        flap = np.isin(labels, list(grip_pieces))
        p = X[tris[flap]]
        flap_area = float(0.5 * np.abs(np.cross(p[:, 1, :2] - p[:, 0, :2], p[:, 2, :2] - p[:, 0, :2])).sum())
    grip_width = float(gx.max() - gx.min())
    grip_area = grip_width * float(X[grip, 1].max() - X[grip, 1].min() + spacing)
    if separated and merge_y is not None:
        outcome = "flap cut out"         # the tears met and the flap between them came off
    elif separated and flap_area is not None and flap_area <= 2 * grip_area:
        outcome = "grip torn off"        # the piece is little more than the grip itself
    elif separated:
        outcome = "flap torn off"        # came off without a clean meeting of two tears
    elif both.sum() >= 3:
        outcome = "two tears"
    else:
        outcome = "one tear or none"
    result = {"time": time, "outcome": outcome, "grip_width": grip_width, "merge_y": merge_y,
              "merge_depth": (float(top - merge_y) if merge_y is not None else None),
              "convergence_angle_deg": angle, "flap_separated": separated, "flap_area": flap_area,
              "tears_at_top": [float(left[0]) if left.size else None, float(right[0]) if right.size else None]}
    # (JSON has no NaN: a value not measured is null.)
    result = {k: ([None if isinstance(x, float) and not np.isfinite(x) else x for x in v] if isinstance(v, list)
                  else (None if isinstance(v, float) and not np.isfinite(v) else v)) for k, v in result.items()}
    with open(os.path.join(args.out, "tear_flap.json"), "w") as o:
        json.dump(result, o, indent=2, allow_nan=False)
    print(json.dumps(result, indent=2, allow_nan=False))
    if args.json_only:
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    sc = ax.scatter(X[:, 0] * 1e3, X[:, 1] * 1e3, c=damage, s=1, cmap=peri_view.DAMAGE_CMAP,
                    vmin=peri_view.DAMAGE_LIMITS[0], vmax=peri_view.DAMAGE_LIMITS[1], rasterized=True)
    ax.plot(left * 1e3, ys * 1e3, "c-", lw=1.2, label="left tear")
    ax.plot(right * 1e3, ys * 1e3, "g-", lw=1.2, label="right tear")
    if merge_y is not None:
        xm = X[damaged & (np.abs(X[:, 1] - merge_y) <= 0.5 * band), 0].mean()
        ax.plot([xm * 1e3], [merge_y * 1e3], "w*", ms=12,
                mec="k", label=f"tears meet ({(top - merge_y) * 1e3:.1f} mm from the grip)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm] (reference)")
    ax.set_ylabel("y [mm] (reference)")
    ax.set_title(f"t = {time * 1e3:.2f} ms: flap {'separated' if separated else 'attached'}")
    ax.legend(fontsize=7, loc="lower right")
    fig.colorbar(sc, ax=ax, label="damage")
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "tear_flap.png"), dpi=110)


if __name__ == "__main__":
    peri_view.run_tool(main)

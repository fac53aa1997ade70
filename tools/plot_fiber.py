#!/usr/bin/env python3
"""Pictures of a fiber run (examples 7.5, 7.6): the fiber in 3D, coloured by segment.

usage: /usr/bin/python3 tools/plot_fiber.py OUTDIR [--segment-length L] [--pair I J]

Writes into OUTDIR:
  fiber.png       one fiber (a path): the first, a middle and the last frame, each from the side
                  and from above, every segment of the fiber in its own colour (equal scales)
  network.png     a network (scene body with network:): the first, a middle and the last frame
                  seen from above, coloured by strain energy density (bonds and long-range
                  pairs; the paper's Fig. 11 colours by elastic energy), damaged nodes marked red
  fiber_shape.csv per frame: time, end-to-end distance (first to last node) and the extent
                  along x, y, z [m]
  with --pair I J (two segments of a fiber given by path, e.g. the attracting ones of Fig. 10's
  lower plot):
  fiber_pair.csv  per frame: time; the distance from each node of one segment to the other's
                  centreline (the polyline through its nodes), mean and largest over both segments
                  [m]; the length of each segment within 1.5 diameters of the other's centreline,
                  their mean [m]; the distance of their centroids [m]; and their winding, the Gauss
                  linking integral (1/4pi) int int (r1 - r2).(dr1 x dr2)/|r1 - r2|^3 over the two
                  centrelines (0 for parallel straight segments, about n for a pair twisted n turns
                  about each other), exact per pair of straight pieces (the solid angle they subtend)
  fiber_pair.png  the fiber at the start and the end with the two segments in red and blue, the
                  pair close up, and the distance and winding over time
Segment k holds the nodes k' with floor((k' + 1/2) ds / segment_length) = k, ds = L / n (as the
solver numbers them: the nodes sit at the centres of n equal arc steps along the path).
  figures.json    per figure: view, projection, units and damage colour limits (peri_view.note)
Lengths in nm, um, mm or m, whichever puts the fibers' extent between 1 and 1000 units. The
segment length defaults to the one in the run's resolved scene (the first fiber body). A run
without fiber bodies is refused (exit status 2).
Needs Debian's python3-h5py, python3-numpy, python3-matplotlib and python3-yaml.
"""
import argparse
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peri_view  # noqa: E402

TOOL = "plot_fiber.py"


def fiber_bodies(run):
    """The scene entries of the run's fiber bodies, in scene order."""
    return [run.scene["bodies"][b] for b, k in zip(run.body_names, run.kinds) if k == "fiber"]


def plot_network(outdir, times, positions, damages, energies, unit, scale):
    picks = [0, len(positions) // 2, len(positions) - 1]
    fig, axs = plt.subplots(1, 3, figsize=(16, 5.6))
    e = np.concatenate([energies[k] for k in picks])
    lo, hi = np.percentile(e, 1), np.percentile(e, 99)
    for ax, k in zip(axs, picks):
        p = positions[k] / scale
        sc = ax.scatter(p[:, 0], p[:, 1], s=0.6, c=energies[k], cmap="viridis", vmin=lo, vmax=hi)
        hit = damages[k] > 0
        if hit.any():
            ax.scatter(p[hit, 0], p[hit, 1], s=4, c="red", label="damaged")
            ax.legend(loc="upper right", fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlabel(f"x [{unit}]")
        ax.set_ylabel(f"y [{unit}]")
        ax.set_title(f"frame {k}, t = {times[k]:.3g} s", fontsize=10)
    fig.colorbar(sc, ax=axs, label="strain energy density [J/m^3]", shrink=0.8)
    plt.savefig(os.path.join(outdir, "network.png"), dpi=90)
    peri_view.note(outdir, "network.png", TOOL, "network", fig, None, unit)
    print(f"wrote {outdir}/network.png and fiber_shape.csv")


def path_length(path):
    p = np.asarray(path, float)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def distances_to_polyline(points, poly):
    """Distance of each point to the polyline through `poly`'s rows."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    rel = points[:, None, :] - a[None, :, :]
    t = np.clip((rel * ab[None]).sum(2) / (ab * ab).sum(1)[None], 0.0, 1.0)
    nearest = a[None] + t[:, :, None] * ab[None]
    return np.linalg.norm(points[:, None, :] - nearest, axis=2).min(1)


def gauss_linking(A, B):
    """(1/4pi) int int (rA - rB).(drA x drB)/|rA - rB|^3 over two polylines: per pair of straight
    pieces the signed solid angle /(4 pi) (Klenin & Langowski 2000, eq. 13)."""
    p1, p2 = A[:-1, None, :], A[1:, None, :]
    p3, p4 = B[None, :-1, :], B[None, 1:, :]
    r13, r14, r23, r24 = p3 - p1, p4 - p1, p3 - p2, p4 - p2

    def unit(v):
        n = np.linalg.norm(v, axis=-1, keepdims=True)
        return np.divide(v, n, out=np.zeros_like(v), where=n > 0)

    n = [unit(np.cross(r13, r14)), unit(np.cross(r14, r24)), unit(np.cross(r24, r23)), unit(np.cross(r23, r13))]
    omega = sum(np.arcsin(np.clip((n[k] * n[(k + 1) % 4]).sum(-1), -1.0, 1.0)) for k in range(4))
    sign = np.sign((np.cross(p4 - p3, p2 - p1) * r13).sum(-1))
    return float((omega * sign).sum() / (4 * np.pi))


def pair_measures(p, si, sj, diameter, ds):
    """Distances, contact length, centroid distance and winding of segments si, sj (masks)."""
    A, B = p[si], p[sj]
    da, db = distances_to_polyline(A, B), distances_to_polyline(B, A)
    d = np.concatenate([da, db])
    within = 0.5 * ((da < 1.5 * diameter).sum() + (db < 1.5 * diameter).sum()) * ds
    return dict(mean=float(d.mean()), largest=float(d.max()), within=float(within),
                centroids=float(np.linalg.norm(A.mean(0) - B.mean(0))), linking=gauss_linking(A, B))


def plot_pair(args, run, fiber, times, positions, unit, scale):
    i, j = args.pair
    name = [b for b, k in zip(run.body_names, run.kinds) if k == "fiber"][0]
    out = run.scene.get("output", {})
    if "path" not in fiber or int(out.get("node_stride", 1)) > 1 or out.get("region"):
        print(f"plot_fiber.py: --pair needs a fiber given by path whose every node the frames hold (body {name})",
              file=sys.stderr)
        sys.exit(2)
    seg_len = args.segment_length if args.segment_length is not None else float(fiber.get("segment_length", 0))
    n = len(positions[0])
    ds = path_length(fiber["path"]) / n
    seg = np.floor((np.arange(n) + 0.5) * ds / seg_len).astype(int) if seg_len > 0 else np.zeros(n, int)
    count = int(seg.max()) + 1
    if not (0 <= i < count and 0 <= j < count and i != j):
        print(f"plot_fiber.py: --pair {i} {j}: expected two different segments of 0..{count - 1} "
              f"(body {name} has {count})", file=sys.stderr)
        sys.exit(2)
    si, sj = seg == i, seg == j
    diameter = float(fiber["diameter"])
    rows = [pair_measures(p, si, sj, diameter, ds) for p in positions]
    with open(os.path.join(args.outdir, "fiber_pair.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["frame", "time", "mean_distance", "largest_distance", "length_within_1.5d", "centroid_distance",
                    "linking"])
        for k, (t, r) in enumerate(zip(times, rows)):
            w.writerow([k, t, r["mean"], r["largest"], r["within"], r["centroids"], r["linking"]])
    tu, ts = peri_view.time_unit(max(times[-1], 1e-300))
    fig = plt.figure(figsize=(14, 8.5))
    grid = fig.add_gridspec(2, 6)
    for col, k in enumerate([0, len(positions) - 1]):
        p = positions[k] / scale
        ax = fig.add_subplot(grid[0, 2 * col:2 * col + 2], projection="3d")
        ax.plot(p[:, 0], p[:, 1], p[:, 2], color="0.6", lw=1.2)
        for m, c in ((si, "tab:red"), (sj, "tab:blue")):
            ax.plot(p[m, 0], p[m, 1], p[m, 2], color=c, lw=3)
        mid, half = p.mean(0), np.ptp(p, 0).max() / 2
        for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid):
            set_lim(c - half, c + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(35, -60)
        ax.set_xlabel(f"x [{unit}]")
        ax.set_ylabel(f"y [{unit}]")
        ax.set_title(f"t = {times[k] / ts:.3g} {tu}: segments {i} (red) and {j} (blue)", fontsize=9)
    p = positions[-1]
    c = np.vstack([p[si], p[sj]]).mean(0)
    ax = fig.add_subplot(grid[0, 4:], projection="3d")
    for m, col in ((si, "tab:red"), (sj, "tab:blue")):
        q = (p[m] - c) / scale
        ax.plot(q[:, 0], q[:, 1], q[:, 2], "o-", color=col, ms=3, lw=2)
    half = max(np.abs(np.vstack([p[si], p[sj]]) - c).max() / scale, 1e-3)
    for set_lim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        set_lim(-half, half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_title(f"the pair at the end (nodes), about its centroid [{unit}]", fontsize=9)
    t = np.array(times) / ts
    ax = fig.add_subplot(grid[1, :3])
    ax.plot(t, [r["mean"] / scale for r in rows], label="mean distance to the other's centreline")
    ax.plot(t, [r["largest"] / scale for r in rows], label="largest distance")
    ax.plot(t, [r["centroids"] / scale for r in rows], ":", label="distance of the centroids")
    ax.axhline(diameter / scale, color="0.5", lw=0.8, ls="--", label="one diameter")
    ax.set_xlabel(f"time [{tu}]")
    ax.set_ylabel(f"[{unit}]")
    ax.legend(fontsize=8)
    ax.set_title(f"segments {i} and {j}: distance", fontsize=10)
    ax = fig.add_subplot(grid[1, 3:])
    ax.plot(t, [r["linking"] for r in rows], color="tab:purple", label="winding (Gauss linking integral)")
    ax.set_xlabel(f"time [{tu}]")
    ax.set_ylabel("turns")
    ax2 = ax.twinx()
    ax2.plot(t, [r["within"] / scale for r in rows], color="tab:green", label="length within 1.5 diameters")
    ax2.set_ylabel(f"length within 1.5 d [{unit}]", color="tab:green")
    ax2.set_ylim(0, seg_len / scale * 1.1)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"segments {i} and {j}: winding and contact length", fontsize=10)
    plt.tight_layout()
    plt.savefig(os.path.join(args.outdir, "fiber_pair.png"), dpi=90)
    peri_view.note(args.outdir, "fiber_pair.png", TOOL, "curves", fig, None, unit)
    last = rows[-1]
    print(f"segments {i} and {j} at t = {times[-1]:.3g} s: mean distance {last['mean']:.3g} m (largest "
          f"{last['largest']:.3g}), {last['within']:.3g} m within 1.5 diameters, winding {last['linking']:+.2f} turns")
    print(f"wrote {args.outdir}/fiber_pair.png and fiber_pair.csv")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--segment-length", type=float, default=None, help="m (default: from the scene)")
    ap.add_argument("--pair", type=int, nargs=2, metavar=("I", "J"), default=None,
                    help="two segments of the first fiber: their distance and winding over time")
    args = ap.parse_args()
    if args.segment_length is not None and not args.segment_length > 0:
        ap.error(f"--segment-length {args.segment_length}: expected a positive length [m]")
    run = peri_view.Run(args.outdir)
    fibers = fiber_bodies(run)
    if not fibers:
        print(f"plot_fiber.py: {args.outdir} holds no fiber body (bodies: "
              f"{', '.join(f'{b} ({k})' for b, k in zip(run.body_names, run.kinds))})", file=sys.stderr)
        sys.exit(2)
    seg_len = args.segment_length if args.segment_length is not None else float(fibers[0].get("segment_length", 0))
    mine = run.nodes_of("fiber")
    if args.segment_length is not None:
        spacing = float(fibers[0].get("spacing", 0) or 0)
        if spacing and seg_len < spacing:
            ap.error(f"--segment-length {seg_len}: below the fiber's node spacing {spacing} m (segments hold nodes)")
    unit, scale = peri_view.length_unit(float(np.ptp(run.reference[mine], axis=0).max()))
    run.require("plot_fiber.py", "position", "damage")
    with run.open() as f:
        frames = f["frames"]
        keys = run.frame_names
        times = [float(frames[k].attrs.get("time", np.nan)) for k in keys]
        positions = [frames[k]["position"][()][mine] for k in keys]
        damages = [frames[k]["damage"][()][mine] for k in keys]
        energies = [frames[k]["strain_energy_density"][()][mine] if "strain_energy_density" in frames[k]
                    else np.zeros(len(positions[0])) for k in keys]
    with open(os.path.join(args.outdir, "fiber_shape.csv"), "w", newline="") as out:
        w = csv.writer(out)
        w.writerow(["frame", "time", "end_to_end", "extent_x", "extent_y", "extent_z"])
        for k, (t, p) in enumerate(zip(times, positions)):
            ext = p.max(0) - p.min(0)
            w.writerow([k, t, np.linalg.norm(p[-1] - p[0]), *ext])
    if any("network" in b for b in fibers):
        plot_network(args.outdir, times, positions, damages, energies, unit, scale)
        return
    if args.pair is not None:
        plot_pair(args, run, fibers[0], times, positions, unit, scale)
    p0 = positions[0]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p0, axis=0), axis=1))])
    seg = (arc // seg_len).astype(int) if seg_len > 0 else np.zeros(len(p0), int)
    picks = [0, len(positions) // 2, len(positions) - 1]
    fig = plt.figure(figsize=(13, 8))
    for row, k in enumerate(picks):
        p = positions[k] / scale
        mid, half = p.mean(0), max(np.ptp(p, 0).max() / 2, 1e-3)
        for col, (elev, azim, view) in enumerate([(10, -90, "side"), (85, -90, "from above")]):
            ax = fig.add_subplot(3, 2, 2 * row + col + 1, projection="3d")
            for s in range(seg.max() + 1):
                m = seg == s
                ax.plot(p[m, 0], p[m, 1], p[m, 2], lw=1.8, color=plt.cm.viridis(s / max(seg.max(), 1)))
            ax.set_xlim(mid[0] - half, mid[0] + half)
            ax.set_ylim(mid[1] - half / 4, mid[1] + half / 4)
            ax.set_zlim(mid[2] - half / 4, mid[2] + half / 4)
            ax.set_box_aspect((4, 1, 1))
            ax.view_init(elev, azim)
            ax.set_xlabel(f"x [{unit}]")
            ax.set_title(f"frame {k}, t = {times[k]:.3g} s, {view}", fontsize=9)
    plt.tight_layout()
    plt.savefig(os.path.join(args.outdir, "fiber.png"), dpi=90)
    peri_view.note(args.outdir, "fiber.png", TOOL, "curves", fig, None, unit)
    print(f"wrote {args.outdir}/fiber.png and fiber_shape.csv")


if __name__ == "__main__":
    peri_view.run_tool(main)

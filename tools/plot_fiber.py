#!/usr/bin/env python3
"""Pictures of a fiber run (examples 7.5, 7.6): the fiber in 3D, coloured by segment.

usage: /usr/bin/python3 tools/plot_fiber.py OUTDIR [--segment-length L]

Writes into OUTDIR:
  fiber.png       one fiber (a path): the first, a middle and the last frame, each from the side
                  and from above, every segment of the fiber in its own colour (equal scales)
  network.png     a network (scene body with network:): the first, a middle and the last frame
                  seen from above, coloured by strain energy density (bonds and long-range
                  pairs; the paper's Fig. 11 colours by elastic energy), damaged nodes marked red
  fiber_shape.csv per frame: time, end-to-end distance (first to last node) and the extent
                  along x, y, z [m]
The segment length defaults to the one in OUTDIR/scene.resolved.yaml (the first fiber body).
Needs Debian's python3-h5py, python3-numpy and python3-matplotlib.
"""
import argparse
import csv
import os
import re
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def segment_length_of(outdir):
    try:
        with open(os.path.join(outdir, "scene.resolved.yaml")) as f:
            m = re.search(r"segment_length:\s*([0-9.eE+-]+)", f.read())
        return float(m.group(1)) if m else 0.0
    except OSError:
        return 0.0


def is_network(outdir):
    try:
        with open(os.path.join(outdir, "scene.resolved.yaml")) as f:
            return re.search(r"^\s+network:", f.read(), re.M) is not None
    except OSError:
        return False


def plot_network(outdir, times, positions, damages, energies):
    picks = [0, len(positions) // 2, len(positions) - 1]
    fig, axs = plt.subplots(1, 3, figsize=(16, 5.6))
    e = np.concatenate([energies[k] for k in picks])
    lo, hi = np.percentile(e, 1), np.percentile(e, 99)
    for ax, k in zip(axs, picks):
        p = positions[k] * 1e9
        sc = ax.scatter(p[:, 0], p[:, 1], s=0.6, c=energies[k], cmap="viridis", vmin=lo, vmax=hi)
        hit = damages[k] > 0
        if hit.any():
            ax.scatter(p[hit, 0], p[hit, 1], s=4, c="red", label="damaged")
            ax.legend(loc="upper right", fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlabel("x [nm]")
        ax.set_ylabel("y [nm]")
        ax.set_title(f"frame {k}, t = {times[k]:.3g} s", fontsize=10)
    fig.colorbar(sc, ax=axs, label="strain energy density [J/m^3]", shrink=0.8)
    plt.savefig(os.path.join(outdir, "network.png"), dpi=90)
    print(f"wrote {outdir}/network.png and fiber_shape.csv")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--segment-length", type=float, default=None, help="m (default: from the scene)")
    args = ap.parse_args()
    path = os.path.join(args.outdir, "frames.h5")
    if not os.path.exists(path):
        sys.exit(f"plot_fiber.py: {path} does not exist; expected a peridrive output directory")
    seg_len = args.segment_length if args.segment_length is not None else segment_length_of(args.outdir)
    with h5py.File(path, "r") as f:
        frames = f["frames"]
        keys = sorted(frames.keys())
        times = [float(frames[k].attrs.get("time", np.nan)) for k in keys]
        positions = [frames[k]["position"][()] for k in keys]
        damages = [frames[k]["damage"][()] for k in keys]
        energies = [frames[k]["strain_energy_density"][()] if "strain_energy_density" in frames[k]
                    else np.zeros(len(positions[0])) for k in keys]
    with open(os.path.join(args.outdir, "fiber_shape.csv"), "w", newline="") as out:
        w = csv.writer(out)
        w.writerow(["frame", "time", "end_to_end", "extent_x", "extent_y", "extent_z"])
        for k, (t, p) in enumerate(zip(times, positions)):
            ext = p.max(0) - p.min(0)
            w.writerow([k, t, np.linalg.norm(p[-1] - p[0]), *ext])
    if is_network(args.outdir):
        plot_network(args.outdir, times, positions, damages, energies)
        return
    p0 = positions[0]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p0, axis=0), axis=1))])
    seg = (arc // seg_len).astype(int) if seg_len > 0 else np.zeros(len(p0), int)
    picks = [0, len(positions) // 2, len(positions) - 1]
    fig = plt.figure(figsize=(13, 8))
    for row, k in enumerate(picks):
        p = positions[k] * 1e9
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
            ax.set_xlabel("x [nm]")
            ax.set_title(f"frame {k}, t = {times[k]:.3g} s, {view}", fontsize=9)
    plt.tight_layout()
    plt.savefig(os.path.join(args.outdir, "fiber.png"), dpi=90)
    print(f"wrote {args.outdir}/fiber.png and fiber_shape.csv")


if __name__ == "__main__":
    main()

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

import h5py
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--segment-length", type=float, default=None, help="m (default: from the scene)")
    args = ap.parse_args()
    run = peri_view.Run(args.outdir)
    fibers = fiber_bodies(run)
    if not fibers:
        print(f"plot_fiber.py: {args.outdir} holds no fiber body (bodies: "
              f"{', '.join(f'{b} ({k})' for b, k in zip(run.body_names, run.kinds))})", file=sys.stderr)
        sys.exit(2)
    seg_len = args.segment_length if args.segment_length is not None else float(fibers[0].get("segment_length", 0))
    mine = run.nodes_of("fiber")
    unit, scale = peri_view.length_unit(float(np.ptp(run.reference[mine], axis=0).max()))
    run.require("plot_fiber.py", "position", "damage")
    with h5py.File(run.h5, "r") as f:
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
    main()

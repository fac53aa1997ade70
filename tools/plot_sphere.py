#!/usr/bin/env python3
"""Pictures of a sphere run (example 7.2, the balloon).

usage: /usr/bin/python3 tools/plot_sphere.py OUTDIR [--frames I J K]

Writes into OUTDIR:
  sphere.png        three frames (default: the first, the middle and the last), each seen from +x
                    and from +y, nodes coloured by damage (broken-bond fraction), equal scales
  sphere_radius.csv per frame: time, mean and standard deviation of the nodes' distance from the
                    sphere's centre (the scene's center; the inflation), nodes over 30% damaged
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


def center_of(outdir):
    try:
        with open(os.path.join(outdir, "scene.resolved.yaml")) as f:
            m = re.search(r"^\s+center:\s*\[([^\]]*)\]", f.read(), re.M)
        return np.array([float(v) for v in m.group(1).split(",")]) if m else np.zeros(3)
    except OSError:
        return np.zeros(3)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--frames", type=int, nargs="+", default=None)
    args = ap.parse_args()
    path = os.path.join(args.outdir, "frames.h5")
    if not os.path.exists(path):
        sys.exit(f"plot_sphere.py: {path} does not exist; expected a peridrive output directory")
    c = center_of(args.outdir)
    with h5py.File(path, "r") as f:
        keys = sorted(f["frames"].keys())
        times = [float(f["frames"][k].attrs.get("time", np.nan)) for k in keys]
        pos = [f["frames"][k]["position"][()] for k in keys]
        dmg = [f["frames"][k]["damage"][()] for k in keys]
    with open(os.path.join(args.outdir, "sphere_radius.csv"), "w", newline="") as out:
        w = csv.writer(out)
        w.writerow(["frame", "time", "mean_radius", "radius_std", "damaged_nodes"])
        for k, (t, p, d) in enumerate(zip(times, pos, dmg)):
            r = np.linalg.norm(p - c, axis=1)
            w.writerow([k, t, r.mean(), r.std(), int((d > 0.3).sum())])
    picks = args.frames if args.frames else [0, len(keys) // 2, len(keys) - 1]
    fig = plt.figure(figsize=(4.2 * len(picks), 8))
    half = max(np.abs(p - c).max() for p in pos)
    for col, k in enumerate(picks):
        p = pos[k] - c
        for row, (elev, azim, view) in enumerate([(0, 0, "from +x"), (0, 90, "from +y")]):
            ax = fig.add_subplot(2, len(picks), row * len(picks) + col + 1, projection="3d")
            order = np.argsort(dmg[k])
            ax.scatter(p[order, 0], p[order, 1], p[order, 2], s=0.5, c=dmg[k][order], cmap="inferno_r", vmin=0, vmax=0.5)
            for setlim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
                setlim(-half, half)
            ax.set_box_aspect((1, 1, 1))
            ax.view_init(elev, azim)
            ax.set_title(f"frame {k}, t = {times[k]:.3g} s, {view}", fontsize=9)
    plt.tight_layout()
    plt.savefig(os.path.join(args.outdir, "sphere.png"), dpi=80)
    print(f"wrote {args.outdir}/sphere.png and sphere_radius.csv")


if __name__ == "__main__":
    main()

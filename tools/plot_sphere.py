#!/usr/bin/env python3
"""Pictures of a sphere run (example 7.2, the balloon).

usage: /usr/bin/python3 tools/plot_sphere.py OUTDIR [--frames I J K]

Writes into OUTDIR:
  sphere.png        three frames (default: the first, the middle and the last), each seen from +x
                    and from +y, nodes coloured by damage (broken-bond fraction, on [0, 1]),
                    equal scales, lengths in nm, um, mm or m (the sphere's diameter as 1 to 1000)
  sphere_radius.csv per frame: time, mean and standard deviation of the nodes' distance from the
                    sphere's centre (the scene's center; the inflation), nodes over 30% damaged
  figures.json      per figure: view, projection, units and damage colour limits (peri_view.note)
The first sphere body is drawn; a run without one is refused (exit status 2).
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
from peri_view import DAMAGE_CMAP, DAMAGE_LIMITS  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--frames", type=int, nargs="+", default=None)
    args = ap.parse_args()
    run = peri_view.Run(args.outdir)
    spheres = [b for b, k in zip(run.body_names, run.kinds) if k == "sphere"]
    if not spheres:
        print(f"plot_sphere.py: {args.outdir} holds no sphere body (bodies: "
              f"{', '.join(f'{b} ({k})' for b, k in zip(run.body_names, run.kinds))})", file=sys.stderr)
        sys.exit(2)
    c = np.array(run.scene["bodies"][spheres[0]]["center"], dtype=float)
    mine = run.body == run.body_names.index(spheres[0])
    run.require("plot_sphere.py", "position", "damage")
    with run.open() as f:
        keys = run.frame_names
        times = [float(f["frames"][k].attrs.get("time", np.nan)) for k in keys]
        pos = [f["frames"][k]["position"][()][mine] for k in keys]
        dmg = [f["frames"][k]["damage"][()][mine] for k in keys]
    bad = [k for k in (args.frames or []) if not -len(keys) <= k < len(keys)]
    if bad:
        print(f"plot_sphere.py: --frames {' '.join(map(str, bad))}: the run holds frames 0 .. {len(keys) - 1}",
              file=sys.stderr)
        sys.exit(2)
    with open(os.path.join(args.outdir, "sphere_radius.csv"), "w", newline="") as out:
        w = csv.writer(out)
        w.writerow(["frame", "time", "mean_radius", "radius_std", "damaged_nodes"])
        for k, (t, p, d) in enumerate(zip(times, pos, dmg)):
            r = np.linalg.norm(p - c, axis=1)
            w.writerow([k, t, r.mean(), r.std(), int((d > 0.3).sum())])
    picks = args.frames if args.frames else [0, len(keys) // 2, len(keys) - 1]
    fig = plt.figure(figsize=(4.2 * len(picks), 8))
    unit, scale = peri_view.length_unit(float(np.ptp(run.reference[mine], axis=0).max()))
    half = max(np.abs(p - c).max() for p in pos) / scale
    for col, k in enumerate(picks):
        p = (pos[k] - c) / scale
        for row, (elev, azim, view) in enumerate([(0, 0, "from +x"), (0, 90, "from +y")]):
            ax = fig.add_subplot(2, len(picks), row * len(picks) + col + 1, projection="3d")
            order = np.argsort(dmg[k])
            sc = ax.scatter(p[order, 0], p[order, 1], p[order, 2], s=0.5, c=dmg[k][order], cmap=DAMAGE_CMAP,
                            vmin=DAMAGE_LIMITS[0], vmax=DAMAGE_LIMITS[1])
            for setlim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
                setlim(-half, half)
            ax.set_box_aspect((1, 1, 1))
            ax.view_init(elev, azim)
            ax.set_xlabel(f"x - x_c [{unit}]")
            ax.set_ylabel(f"y - y_c [{unit}]")
            ax.set_zlabel(f"z - z_c [{unit}]")
            ax.set_title(f"frame {k}, t = {times[k]:.3g} s, {view}", fontsize=9)
    plt.tight_layout()
    fig.colorbar(sc, ax=fig.axes, label="damage (broken fraction)", shrink=0.5)
    plt.savefig(os.path.join(args.outdir, "sphere.png"), dpi=80)
    peri_view.note(args.outdir, "sphere.png", "plot_sphere.py", "sphere", fig, sc, unit)
    print(f"wrote {args.outdir}/sphere.png and sphere_radius.csv")


if __name__ == "__main__":
    peri_view.run_tool(main)

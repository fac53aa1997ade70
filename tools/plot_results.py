#!/usr/bin/env python3
"""Turn a peridrive output directory into pictures.

usage: /usr/bin/python3 tools/plot_results.py OUTDIR [--frame K]

Writes into OUTDIR:
  damage.png    damage (broken-bond fraction) of the last frame, drawn on the deformed membrane
  deformed.png  deformed positions coloured by out-of-plane displacement (wrinkles)
  energies.png  kinetic, strain, dissipated energy and external work versus time
Needs Debian's python3-h5py, python3-numpy and python3-matplotlib.
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


def load_frame(path, k):
    with h5py.File(path, "r") as f:
        names = sorted(f["frames"].keys())
        if not names:
            sys.exit(f"{path}: no complete frame")
        name = names[k]
        g = f["frames"][name]
        return (dict(time=float(g.attrs["time"]), step=int(g.attrs["step"]),
                     position=g["position"][...], displacement=g["displacement"][...],
                     damage=g["damage"][...]), f["mesh/reference_position"][...])


def scatter(ax, xy, values, spacing, cmap, label, vmin=None, vmax=None):
    # Marker size from the node spacing so the sheet looks continuous at any resolution.
    fig = ax.figure
    width_in = fig.get_size_inches()[0] * ax.get_position().width
    span = max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1]), spacing)
    points = max(0.05, (spacing / span * width_in * 72.0) ** 2)
    sc = ax.scatter(xy[:, 0] * 1e3, xy[:, 1] * 1e3, c=values, s=points, marker="s", cmap=cmap,
                    vmin=vmin, vmax=vmax, linewidths=0)
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    fig.colorbar(sc, ax=ax, label=label, shrink=0.85)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("outdir")
    ap.add_argument("--frame", type=int, default=-1, help="frame index (default: last)")
    a = ap.parse_args()
    h5 = os.path.join(a.outdir, "frames.h5")
    if not os.path.exists(h5):
        sys.exit(f"{h5}: not found")
    fr, ref = load_frame(h5, a.frame)
    d = np.sqrt(np.sum((ref[1:] - ref[:-1]) ** 2, axis=1))
    spacing = float(np.median(d[d > 0])) if len(d) else 1.0

    # Damage on the reference configuration (as peridynamic damage maps are usually shown).
    fig, ax = plt.subplots(figsize=(7, 6))
    scatter(ax, ref, fr["damage"], spacing, "inferno", "damage (broken fraction)", 0.0, 1.0)
    ax.set_title(f"damage at t = {fr['time'] * 1e6:.1f} us (step {fr['step']}), reference configuration")
    fig.savefig(os.path.join(a.outdir, "damage.png"), dpi=130, bbox_inches="tight")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 6))
    uz = fr["displacement"][:, 2] * 1e6
    # Colour range from the sheet's 99th percentile, not from a fragment flying off.
    lim = max(float(np.percentile(np.abs(uz), 99.0)), 1e-12)
    scatter(ax, fr["position"], uz, spacing, "coolwarm", "out-of-plane displacement [um]", -lim, lim)
    # Frame the sheet, not the odd fragment that flies away after separation.
    lo = np.percentile(fr["position"][:, :2], 0.5, axis=0) * 1e3
    hi = np.percentile(fr["position"][:, :2], 99.5, axis=0) * 1e3
    pad = 0.05 * (hi - lo)
    ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
    ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
    ax.set_title(f"deformed membrane at t = {fr['time'] * 1e6:.1f} us")
    fig.savefig(os.path.join(a.outdir, "deformed.png"), dpi=130, bbox_inches="tight")
    plt.close(fig)

    series = os.path.join(a.outdir, "series.csv")
    if os.path.exists(series):
        with open(series) as f:
            rows = list(csv.DictReader(f))
        t = np.array([float(r["time"]) for r in rows]) * 1e6
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for key, label in [("kinetic_energy", "kinetic"), ("strain_energy", "strain"),
                           ("dissipated_energy", "dissipated (broken bonds)"), ("external_work", "external work"),
                           ("total_energy", "kinetic + strain + dissipated - work")]:
            ax.plot(t, [float(r[key]) for r in rows], label=label)
        ax.set_xlabel("time [us]")
        ax.set_ylabel("energy [J]")
        ax.legend()
        ax.grid(alpha=0.3)
        fig.savefig(os.path.join(a.outdir, "energies.png"), dpi=130, bbox_inches="tight")
        plt.close(fig)
    print(f"plot_results: wrote damage.png, deformed.png, energies.png in {a.outdir}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Turn a peridrive output directory into pictures.

usage: /usr/bin/python3 tools/plot_results.py OUTDIR [--frame K]

Writes into OUTDIR:
  damage.png    damage (broken-bond fraction) of the last frame, drawn on the deformed membrane
  deformed.png  deformed positions coloured by out-of-plane displacement (wrinkles)
  energies.png  kinetic, strain, dissipated energy and external work versus time
  wrinkles.png  four frames of the deformed membrane coloured by out-of-plane displacement
                (the paper's Fig. 5 views: slit, crack running, crack through, halves rebounding)
  crack_speed.png, crack_speed.csv  (runs with crack tips, from tips.csv) smoothed crack tip speed
                against tip position, one curve per tip (the paper's Fig. 6), with c_R and the
                mean speed of summary.json
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
    wrote = ["damage.png", "deformed.png", "energies.png"]
    wrote += plot_wrinkles(h5, ref, spacing, a.outdir)
    wrote += plot_crack_speed(a.outdir)
    print(f"plot_results: wrote {', '.join(wrote)} in {a.outdir}")


def plot_wrinkles(h5, ref, spacing, outdir):
    with h5py.File(h5, "r") as f:
        names = sorted(f["frames"].keys())
        if len(names) < 4:
            return []
        times = np.array([float(f["frames"][n].attrs["time"]) for n in names])
        picks = [names[round(k * (len(names) - 1) / 3)] for k in range(4)]
        growth = crack_growth_times(outdir)
        if growth:
            # Slit before it grows, crack half way, crack through, halves rebounding (last frame).
            t0, t1 = growth
            picks = [names[int(np.argmin(np.abs(times - t)))] for t in (t0, 0.5 * (t0 + t1), t1)] + [names[-1]]
        frames = [(float(f["frames"][n].attrs["time"]), f["frames"][n]["position"][...],
                   f["frames"][n]["displacement"][:, 2]) for n in picks]
    fig, axes = plt.subplots(2, 2, figsize=(12.5, 10))
    fig.subplots_adjust(wspace=0.35)
    for ax, (t, x, uz) in zip(axes.flat, frames):
        lim = max(float(np.percentile(np.abs(uz), 99.0)) * 1e6, 1e-9)  # each view its own range
        scatter(ax, x, uz * 1e6, spacing, "coolwarm", "u_z [um]", -lim, lim)
        lo = np.percentile(x[:, :2], 0.5, axis=0) * 1e3
        hi = np.percentile(x[:, :2], 99.5, axis=0) * 1e3
        ax.set_xlim(lo[0] - 1, hi[0] + 1)
        ax.set_ylim(lo[1] - 1, hi[1] + 1)
        ax.set_title(f"t = {t * 1e6:.1f} us")
    fig.suptitle("out-of-plane displacement (wrinkles along the slit and in the wake), deformed configuration")
    fig.savefig(os.path.join(outdir, "wrinkles.png"), dpi=110, bbox_inches="tight")
    plt.close(fig)
    return ["wrinkles.png"]


def crack_growth_times(outdir):
    """(time the first tip has moved 1 mm, time it has covered 95% of its travel), or None."""
    path = os.path.join(outdir, "tips.csv")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        rs = [r for r in csv.DictReader(f) if r["track"] == "0"]
    if len(rs) < 3:
        return None
    p = np.array([[float(r["x"]), float(r["y"])] for r in rs])
    t = np.array([float(r["time"]) for r in rs])
    travel = np.hypot(*(p - p[0]).T)
    if travel[-1] < 2e-3:
        return None
    return float(t[np.argmax(travel >= 1e-3)]), float(t[np.argmax(travel >= 0.95 * travel[-1])])


def plot_crack_speed(outdir):
    path = os.path.join(outdir, "tips.csv")
    if not os.path.exists(path):
        return []
    with open(path) as f:
        rows = [r for r in csv.DictReader(f)]
    summary = {}
    if os.path.exists(os.path.join(outdir, "summary.json")):
        import json
        with open(os.path.join(outdir, "summary.json")) as f:
            summary = json.load(f)
    tracks = {}
    for r in rows:
        tracks.setdefault(int(r["track"]), []).append(r)
    # Tip position as the paper plots it: distance of the tip from the slit centre along x
    # (the first sample of the first tracks is the slit end).
    with open(os.path.join(outdir, "crack_speed.csv"), "w") as out:
        out.write("track,time,tip_x,tip_y,tip_distance_from_centre,speed\n")
        for k, rs in sorted(tracks.items()):
            for r in rs:
                if r["speed"]:
                    out.write(f'{k},{r["time"]},{r["x"]},{r["y"]},{abs(float(r["x"]))},{r["speed"]}\n')
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, rs in sorted(tracks.items()):
        pts = [(abs(float(r["x"])) * 1e3, float(r["speed"])) for r in rs if r["speed"]]
        if len(pts) < 5:
            continue
        x, v = np.array(pts).T
        ax.plot(x, v, label=f"tip {k} ({'x < 0' if float(rs[-1]['x']) < 0 else 'x > 0'})")
    c_r = summary.get("rayleigh_wave_speed")
    if c_r:
        ax.axhline(c_r, color="k", ls="--", lw=1, label=f"Rayleigh speed c_R = {c_r:.0f} m/s")
    mean = summary.get("mean_crack_speed")
    if mean:
        ax.axhline(mean, color="gray", ls=":", lw=1, label=f"mean over the steady part {mean:.0f} m/s")
    win = summary.get("crack_speed_window")
    ax.set_xlabel("crack tip position |x| [mm]")
    ax.set_ylabel("crack tip speed [m/s]" + (f" ({win * 1e6:.1f} us window)" if win else ""))
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(os.path.join(outdir, "crack_speed.png"), dpi=130, bbox_inches="tight")
    plt.close(fig)
    dynamic_release_rate(outdir)
    return ["crack_speed.png", "crack_speed.csv"]


def dynamic_release_rate(outdir):
    """Dissipated energy per unit new crack area while two tips (tracks 0 and 1) run, against
    eq. (30) G = 2 h w_0 delta^3 / 3 (one membrane body, g = 1, constant lambda_0): printed."""
    import re
    try:
        scene = open(os.path.join(outdir, "scene.resolved.yaml")).read()
        h = [float(v) for v in re.findall(r"^\s+thickness: (\S+)", scene, re.M)]
        l0 = [float(v) for v in re.findall(r"^\s+critical_stretch: (\S+)", scene, re.M)]
        c = [float(v) for v in re.findall(r"micromodulus = (\S+)", scene)]
        delta = [float(v) for v in re.findall(r"\.horizon = (\S+)", scene)]
        with open(os.path.join(outdir, "series.csv")) as f:
            rows = [r for r in csv.DictReader(f) if r.get("tip0_x") and r.get("tip1_x")]
    except (OSError, ValueError):
        return
    if not (len(h) == len(l0) == len(c) == len(delta) == 1) or "influence: constant" not in scene or len(rows) < 10:
        return
    length = np.array([abs(float(r["tip1_x"]) - float(r["tip0_x"])) for r in rows])
    dissipated = np.array([float(r["dissipated_energy"]) for r in rows])
    # Middle half of the growth (the steady part), as for the mean speed.
    lo, hi = length[0] + 0.25 * (length.max() - length[0]), length[0] + 0.75 * (length.max() - length[0])
    sel = (length >= lo) & (length <= hi)
    if sel.sum() < 3:
        return
    slope = np.polyfit(length[sel], dissipated[sel], 1)[0]
    w0 = c[0] * (l0[0] ** 2 + l0[0] ** -2 - 2)
    g30 = 2 * h[0] * w0 * delta[0] ** 3 / 3
    print(f"dissipated energy per new crack area over the middle half of the growth: {slope / h[0]:.4g} J/m^2 "
          f"= {slope / h[0] / g30:.3f} x eq. (30) G = {g30:.4g} J/m^2")


if __name__ == "__main__":
    main()

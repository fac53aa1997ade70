#!/usr/bin/env python3
"""Turn a peridrive output directory into pictures that fit its bodies.

usage: /usr/bin/python3 tools/plot_results.py OUTDIR [--frame K]

The view follows the run's body kinds (frames.h5 /mesh and the resolved scene): flat membranes
and lattices as a sheet seen from above, solids as a mid-plane slice beside their damaged region
in 3D, fibers as 3D curves, spheres and mixed scenes in 3D. Lengths are shown in nm, um, mm or m
(whichever puts the run's extent between 1 and 1000), times likewise in ns, us, ms or s, damage
always on [0, 1]. Writes into OUTDIR:
  damage.png    damage (broken-bond fraction) of the frame (default: the last): sheets on the
                reference configuration; solids in the slice and the damaged region; otherwise in 3D
  deformed.png  deformed positions, sheets coloured by out-of-plane displacement, others by |u|
  energies.png  kinetic, strain, dissipated energy and external work versus time
  wrinkles.png  (sheets) four frames of the deformed membrane coloured by out-of-plane
                displacement (the paper's Fig. 5 views: slit, crack running, crack through,
                halves rebounding)
  crack_speed.png, crack_speed.csv  (runs with crack tips, from tips.csv) smoothed crack tip speed
                against tip position, one curve per tip (the paper's Fig. 6), with c_R and the
                mean speed of summary.json
  figures.json  per figure: view, projection, units and damage colour limits (peri_view.note)
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

TOOL = "plot_results.py"
MAX_3D_POINTS = 100000  # 3D scatters draw every k-th node beyond this


def scatter(ax, xy, values, spacing, cmap, label, vmin, vmax, unit, scale):
    # Marker size from the node spacing so the sheet looks continuous at any resolution.
    fig = ax.figure
    width_in = fig.get_size_inches()[0] * ax.get_position().width
    span = max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1]), spacing)
    points = max(0.05, (spacing / span * width_in * 72.0) ** 2)
    sc = ax.scatter(xy[:, 0] / scale, xy[:, 1] / scale, c=values, s=points, marker="s", cmap=cmap,
                    vmin=vmin, vmax=vmax, linewidths=0)
    ax.set_aspect("equal")
    ax.set_xlabel(f"x [{unit}]")
    ax.set_ylabel(f"y [{unit}]")
    fig.colorbar(sc, ax=ax, label=label, shrink=0.85)
    return sc


def scatter3d(ax, p, values, cmap, label, vmin, vmax, unit, scale, run=None):
    """Nodes in 3D at equal scales on every axis; fibers (run given) also as lines."""
    step = max(1, len(p) // MAX_3D_POINTS)
    q = p[::step] / scale
    if run is not None:
        # Consecutive nodes of one fiber lie about a spacing apart; a longer jump starts another.
        ref = run.reference[::step]
        cut = np.linalg.norm(np.diff(ref, axis=0), axis=1) > 2.5 * run.spacing() * step
        starts = np.concatenate([[0], np.nonzero(cut)[0] + 1, [len(q)]])
        for a, b in zip(starts[:-1], starts[1:]):
            ax.plot(q[a:b, 0], q[a:b, 1], q[a:b, 2], color="0.6", lw=0.8)
    sc = ax.scatter(q[:, 0], q[:, 1], q[:, 2], c=values[::step], s=4, cmap=cmap, vmin=vmin, vmax=vmax,
                    linewidths=0)
    mid, half = q.mean(axis=0), max(float(np.ptp(q, axis=0).max()) / 2, 1e-12)
    for setlim, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid):
        setlim(m - half, m + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel(f"x [{unit}]")
    ax.set_ylabel(f"y [{unit}]")
    ax.set_zlabel(f"z [{unit}]")
    ax.figure.colorbar(sc, ax=ax, label=label, shrink=0.7)
    return sc


def mid_plane(run):
    """Nodes of the solid bodies on the node layer nearest their mid-height (a z slice)."""
    solid = run.nodes_of("solid")
    z = run.reference[solid, 2]
    layer = z[np.argmin(np.abs(z - 0.5 * (z.min() + z.max())))]
    return solid & (np.abs(run.reference[:, 2] - layer) < 0.5 * run.spacing()), layer


def plot_damage(run, fr, t_unit, t_scale):
    when = f"t = {fr['time'] / t_scale:.3g} {t_unit} (step {fr['step']})"
    u, s = run.unit, run.scale
    if run.view == "sheet":
        fig, ax = plt.subplots(figsize=(7, 6))
        sc = scatter(ax, run.reference, fr["damage"], run.spacing(), DAMAGE_CMAP, "damage (broken fraction)",
                     *DAMAGE_LIMITS, u, s)
        ax.set_title(f"damage at {when}, reference configuration")
    elif run.view == "solid":
        fig = plt.figure(figsize=(13, 5.5))
        ax = fig.add_subplot(1, 2, 1)
        sel, z = mid_plane(run)
        sc = scatter(ax, run.reference[sel], fr["damage"][sel], run.spacing(), DAMAGE_CMAP,
                     "damage (broken fraction)", *DAMAGE_LIMITS, u, s)
        ax.set_title(f"mid-plane slice z = {z / s:.4g} {u}, reference configuration", fontsize=10)
        ax3 = fig.add_subplot(1, 2, 2, projection="3d")
        hit = fr["damage"] > 0
        if hit.any():
            scatter3d(ax3, run.reference[hit], fr["damage"][hit], DAMAGE_CMAP, "damage (broken fraction)",
                      *DAMAGE_LIMITS, u, s)
            ax3.set_title(f"damaged nodes ({int(hit.sum())} of {len(hit)}), reference configuration", fontsize=10)
        else:
            lo, hi = run.reference.min(axis=0) / s, run.reference.max(axis=0) / s
            for setlim, a, b in zip((ax3.set_xlim, ax3.set_ylim, ax3.set_zlim), lo, hi):
                setlim(a, b)
            ax3.set_xlabel(f"x [{u}]")
            ax3.set_title("no damaged node", fontsize=10)
        fig.suptitle(f"damage at {when}")
    else:
        fig = plt.figure(figsize=(7.5, 6.5))
        ax = fig.add_subplot(projection="3d")
        # (Frames without positions, by output.fields: the reference configuration, said so.)
        deformed = fr["position"] is not None
        sc = scatter3d(ax, fr["position"] if deformed else run.reference, fr["damage"], DAMAGE_CMAP,
                       "damage (broken fraction)", *DAMAGE_LIMITS, u, s, run if run.view == "curves" else None)
        ax.set_title(f"damage at {when}, {'deformed' if deformed else 'reference'} configuration", fontsize=10)
    fig.savefig(os.path.join(run.outdir, "damage.png"), dpi=130, bbox_inches="tight")
    peri_view.note(run.outdir, "damage.png", TOOL, run.view, fig, sc, run.unit)
    plt.close(fig)
    return ["damage.png"]


def plot_deformed(run, fr, t_unit, t_scale):
    u, s = run.unit, run.scale
    when = f"t = {fr['time'] / t_scale:.3g} {t_unit}"
    # Colour ranges from the 99th percentile, not from a fragment flying off; |u| in its own unit.
    magnitude = np.linalg.norm(fr["displacement"], axis=1)
    u_unit, u_scale = peri_view.length_unit(max(float(np.percentile(magnitude, 99.0)), 1e-15))
    magnitude /= u_scale
    top = max(float(np.percentile(magnitude, 99.0)), 1e-12)
    if run.view == "sheet":
        fig, ax = plt.subplots(figsize=(7, 6))
        uz = fr["displacement"][:, 2] / s
        lim = max(float(np.percentile(np.abs(uz), 99.0)), 1e-12)
        scatter(ax, fr["position"], uz, run.spacing(), "coolwarm", f"out-of-plane displacement [{u}]",
                     -lim, lim, u, s)
        # Frame the sheet, not the odd fragment that flies away after separation.
        lo = np.percentile(fr["position"][:, :2], 0.5, axis=0) / s
        hi = np.percentile(fr["position"][:, :2], 99.5, axis=0) / s
        pad = 0.05 * (hi - lo)
        ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
        ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
        ax.set_title(f"deformed membrane at {when}")
    elif run.view == "solid":
        fig, ax = plt.subplots(figsize=(7, 6))
        sel, z = mid_plane(run)
        scatter(ax, fr["position"][sel], magnitude[sel], run.spacing(), "viridis", f"|u| [{u_unit}]", 0, top, u, s)
        ax.set_title(f"mid-plane slice (z = {z / s:.4g} {u} at rest), deformed, at {when}", fontsize=10)
    else:
        fig = plt.figure(figsize=(7.5, 6.5))
        ax = fig.add_subplot(projection="3d")
        scatter3d(ax, fr["position"], magnitude, "viridis", f"|u| [{u_unit}]", 0, top, u, s,
                       run if run.view == "curves" else None)
        ax.set_title(f"deformed configuration at {when}", fontsize=10)
    fig.savefig(os.path.join(run.outdir, "deformed.png"), dpi=130, bbox_inches="tight")
    peri_view.note(run.outdir, "deformed.png", TOOL, run.view, fig, None, run.unit)
    plt.close(fig)
    return ["deformed.png"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("outdir")
    ap.add_argument("--frame", type=int, default=-1, help="frame index (default: last)")
    a = ap.parse_args()
    run = peri_view.Run(a.outdir)
    fr = run.frame(a.frame)
    t_unit, t_scale = peri_view.time_unit(run.frame(-1)["time"])
    wrote = []
    if fr["damage"] is not None:
        wrote += plot_damage(run, fr, t_unit, t_scale)
    if fr["displacement"] is not None:
        wrote += plot_deformed(run, fr, t_unit, t_scale)
    missing = [k for k in ("damage", "displacement") if fr[k] is None]
    if missing:
        print(f"plot_results: the frames hold no {' or '.join(missing)} (output.fields): not drawn")

    series = os.path.join(a.outdir, "series.csv")
    if os.path.exists(series):
        with open(series) as f:
            rows = list(csv.DictReader(f))
        t = np.array([float(r["time"]) for r in rows]) / t_scale
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for key, label in [("kinetic_energy", "kinetic"), ("strain_energy", "strain"),
                           ("dissipated_energy", "dissipated (broken bonds)"), ("external_work", "external work"),
                           ("total_energy", "kinetic + strain + dissipated - work")]:
            ax.plot(t, [float(r[key]) for r in rows], label=label)
        ax.set_xlabel(f"time [{t_unit}]")
        ax.set_ylabel("energy [J]")
        ax.legend()
        ax.grid(alpha=0.3)
        fig.savefig(os.path.join(a.outdir, "energies.png"), dpi=130, bbox_inches="tight")
        peri_view.note(a.outdir, "energies.png", TOOL, "series", fig)
        plt.close(fig)
        wrote.append("energies.png")
    if run.view == "sheet" and fr["displacement"] is not None:
        wrote += plot_wrinkles(run, t_unit, t_scale)
    wrote += plot_crack_speed(run)
    print(f"plot_results: {run.view} view of {', '.join(sorted(set(run.kinds)))} bodies in {run.unit}; "
          f"wrote {', '.join(wrote)} in {a.outdir}")


def plot_wrinkles(run, t_unit, t_scale):
    names = run.frame_names
    if len(names) < 4:
        return []
    picks = [round(k * (len(names) - 1) / 3) for k in range(4)]
    growth = crack_growth_times(run)
    if growth:
        # Slit before it grows, crack half way, crack through, halves rebounding (last frame).
        times = np.array([run.frame(k)["time"] for k in range(len(names))])
        t0, t1 = growth
        picks = [int(np.argmin(np.abs(times - t))) for t in (t0, 0.5 * (t0 + t1), t1)] + [len(names) - 1]
    frames = [run.frame(k) for k in picks]
    # One unit for the out-of-plane displacement of the four views, from the largest of them.
    lims = [max(float(np.percentile(np.abs(fr["displacement"][:, 2]), 99.0)), 1e-15) for fr in frames]
    uz_unit, uz_scale = peri_view.length_unit(max(lims))
    u, s = run.unit, run.scale
    fig, axes = plt.subplots(2, 2, figsize=(12.5, 10))
    fig.subplots_adjust(wspace=0.35)
    for ax, fr, lim in zip(axes.flat, frames, lims):
        x = fr["position"]
        scatter(ax, x, fr["displacement"][:, 2] / uz_scale, run.spacing(), "coolwarm", f"u_z [{uz_unit}]",
                -lim / uz_scale, lim / uz_scale, u, s)  # each view its own range
        lo = np.percentile(x[:, :2], 0.5, axis=0) / s
        hi = np.percentile(x[:, :2], 99.5, axis=0) / s
        pad = 0.02 * run.extent / s
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_title(f"t = {fr['time'] / t_scale:.3g} {t_unit}")
    fig.suptitle("out-of-plane displacement (wrinkles along the slit and in the wake), deformed configuration")
    fig.savefig(os.path.join(run.outdir, "wrinkles.png"), dpi=110, bbox_inches="tight")
    peri_view.note(run.outdir, "wrinkles.png", TOOL, run.view, fig, None, run.unit)
    plt.close(fig)
    return ["wrinkles.png"]


def crack_growth_times(run):
    """(time the first tip has moved 2% of the run's extent, time it has covered 95% of its
    travel), or None (no tips, or less than 4% of the extent travelled)."""
    path = os.path.join(run.outdir, "tips.csv")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        rs = [r for r in csv.DictReader(f) if r["track"] == "0"]
    if len(rs) < 3:
        return None
    p = np.array([[float(r["x"]), float(r["y"])] for r in rs])
    t = np.array([float(r["time"]) for r in rs])
    travel = np.hypot(*(p - p[0]).T)
    if travel[-1] < 0.04 * run.extent:
        return None
    return float(t[np.argmax(travel >= 0.02 * run.extent)]), float(t[np.argmax(travel >= 0.95 * travel[-1])])


def plot_crack_speed(run):
    outdir = run.outdir
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
        pts = [(abs(float(r["x"])) / run.scale, float(r["speed"])) for r in rs if r["speed"]]
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
    ax.set_xlabel(f"crack tip position |x| [{run.unit}]")
    w_unit, w_scale = peri_view.time_unit(win or 1.0)
    ax.set_ylabel("crack tip speed [m/s]" + (f" ({win / w_scale:.3g} {w_unit} window)" if win else ""))
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(os.path.join(outdir, "crack_speed.png"), dpi=130, bbox_inches="tight")
    peri_view.note(outdir, "crack_speed.png", TOOL, "series", fig, None, run.unit)
    plt.close(fig)
    dynamic_release_rate(outdir)
    return ["crack_speed.png", "crack_speed.csv"]


def dynamic_release_rate(outdir):
    """Dissipated energy per unit new crack area while two tips (tracks 0 and 1) run, against the
    energy of the bonds a unit of crack cuts, G = 2 h int_0^delta w_0(xi) xi^2 dxi (one sheet, g = 1,
    constant critical value): eq. (30) G = 2 h w_0 delta^3 / 3 for the membrane law, whose w_0 is
    the same for every bond, and G = h c s_0^2 delta^4 / 4 for PMB bonds (w_0 = c s_0^2 xi / 2).
    Printed."""
    import re
    try:
        scene = open(os.path.join(outdir, "scene.resolved.yaml")).read()
        h = [float(v) for v in re.findall(r"^\s+thickness: (\S+)", scene, re.M)]
        l0 = [float(v) for v in re.findall(r"^\s+critical_stretch: (\S+)", scene, re.M)]
        c = [float(v) for v in re.findall(r"micromodulus = (\S+)", scene)]
        delta = [float(v) for v in re.findall(r"\.horizon = (\S+)", scene)]
        models = re.findall(r"^\s+model: (\S+)", scene, re.M)
        with open(os.path.join(outdir, "series.csv")) as f:
            rows = [r for r in csv.DictReader(f) if r.get("tip0_x") and r.get("tip1_x")]
    except (OSError, ValueError):
        return
    if not (len(h) == len(l0) == len(c) == len(delta) == len(models) == 1) or models[0] not in ("membrane", "pmb") \
            or "influence: constant" not in scene or "critical_stretch_at_horizon" in scene or len(rows) < 10:
        return
    length = np.array([abs(float(r["tip1_x"]) - float(r["tip0_x"])) for r in rows])
    dissipated = np.array([float(r["dissipated_energy"]) for r in rows])
    if not length.max() > length[0] + 0.5 * delta[0]:
        # No growth to fit (a crack that did not run): no rate, rather than a slope of zero.
        print(f"dissipated energy per new crack area: not measured, the crack grew {length.max() - length[0]:.3g} m "
              f"(less than half a horizon, {0.5 * delta[0]:.3g} m)")
        return
    # Middle half of the growth (the steady part), as for the mean speed.
    lo, hi = length[0] + 0.25 * (length.max() - length[0]), length[0] + 0.75 * (length.max() - length[0])
    sel = (length >= lo) & (length <= hi)
    if sel.sum() < 3:
        return
    slope = np.polyfit(length[sel], dissipated[sel], 1)[0]
    if models[0] == "membrane":
        w0 = c[0] * (l0[0] ** 2 + l0[0] ** -2 - 2)
        g, name = 2 * h[0] * w0 * delta[0] ** 3 / 3, "eq. (30) G"
    else:
        g, name = h[0] * c[0] * l0[0] ** 2 * delta[0] ** 4 / 4, "PMB's G = h c s_0^2 delta^4 / 4"
    print(f"dissipated energy per new crack area over the middle half of the growth: {slope / h[0]:.4g} J/m^2 "
          f"= {slope / h[0] / g:.3f} x {name} = {g:.4g} J/m^2")


if __name__ == "__main__":
    peri_view.run_tool(main)

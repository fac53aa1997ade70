#!/usr/bin/env python3
"""Crack tip of a lattice run: position and speed against the Mooney-Rivlin wave speeds.

usage: /usr/bin/python3 tools/crack_tip_lattice.py OUTDIR [--band B] [--frame K]

Reads OUTDIR/frames.h5 and OUTDIR/scene.resolved.yaml (derived constants as comments). The tip
of each frame is the largest reference x of the run of damaged nodes within B (default 3)
lattice spacings of the seed crack's line that is contiguous (gaps <= 2.5 spacings) with the seed;
damage nucleated further ahead is counted (damaged_ahead_of_tip, the most over the measured
frames) but is not the tip. The crack speed is the least-squares slope of tip
position against time over the frames where the tip has left the seed and is still more than
10 spacings from the far edge, and before the tip first jumps faster than 3 c_l between frames
(it met damage formed ahead: tip_jumps_at, the time); it is a reference-frame speed, compared with
the reference-frame long-wave speeds of the lattice in the stretched state ahead of the tip
(lattice_longitudinal_speed_x, lattice_shear_speed_x of the derived constants; the Mooney-Rivlin
formulas longitudinal_wave_speed_x, shear_wave_speed are reported beside them).
Writes OUTDIR/crack_tip.csv, OUTDIR/crack_tip.json and OUTDIR/tip_region.png (frame K, default:
the frame where the tip is nearest the middle of the measured run).
Needs Debian's python3-h5py, python3-numpy and python3-matplotlib.
"""
import argparse
import json
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peri_view  # noqa: E402


def derived(out):
    values = {}
    with open(os.path.join(out, "scene.resolved.yaml")) as f:
        text = f.read()
    for m in re.finditer(r"^# (\S+) = (\S+)$", text, re.M):
        try:
            values[m.group(1)] = float(m.group(2))
        except ValueError:
            pass
    seed = re.search(r"cracks:\n  - name: \S+\n    from: \[([^\]]*)\]\n    to: \[([^\]]*)\]", text)
    spacing = re.search(r"kind: lattice\n(?:    .*\n)*?    spacing: (\S+)", text)
    if not seed or not spacing:
        sys.exit("scene.resolved.yaml: expected a lattice body and a seed crack")
    a = [float(v) for v in seed.group(1).split(",")]
    b = [float(v) for v in seed.group(2).split(",")]
    return values, a, b, float(spacing.group(1))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--band", type=float, default=3.0)
    ap.add_argument("--frame", type=int, default=None)
    args = ap.parse_args()
    peri_view.require_run(args.out)
    values, c0, c1, delta = derived(args.out)
    y_line = 0.5 * (c0[1] + c1[1])
    seed_end = max(c0[0], c1[0])
    with peri_view.open_frames(args.out) as f:
        X = f["mesh/reference_position"][...]
        names = peri_view.frame_names(f, args.out)
        if args.frame is not None and not -len(names) <= args.frame < len(names):
            sys.exit(f"crack_tip_lattice.py: --frame {args.frame}: the run holds frames 0 .. {len(names) - 1}")
        missing = [k for k in ("position", "damage") if names and k not in f["frames"][names[0]]]
        if missing:
            sys.exit(f"crack_tip_lattice.py: the frames hold no {', '.join(missing)} (output.fields); run the scene with them")
        times, tips, frames, ahead = [], [], [], []
        for name in names:
            g = f["frames"][name]
            d = g["damage"][...]
            near = (np.abs(X[:, 1] - y_line) < args.band * delta) & (d > 0)
            xs = np.sort(X[near, 0])
            # The crack grown from the seed: damaged nodes on the line contiguous (gaps of at most
            # 2.5 spacings) with the seed's end; damage nucleated further ahead is not its tip.
            tip = np.nan
            if xs.size and xs[0] <= seed_end + 2.5 * delta:
                gaps = np.where(np.diff(xs) > 2.5 * delta)[0]
                tip = xs[gaps[0]] if gaps.size else xs[-1]
            tips.append(tip)
            ahead.append(int((xs > tip + 2.5 * delta).sum()) if xs.size and tip == tip else 0)
            times.append(float(g.attrs["time"]))
            frames.append(name)
        times, tips = np.array(times), np.array(tips)
        def first(suffix):
            return next((values[k] for k in values if k.endswith(suffix)), None)
        cl_mr, cs_mr = first(".longitudinal_wave_speed_x"), first(".shear_wave_speed")
        # Compare with the lattice's own long-wave speeds at the far-field stretch where the run
        # reports them (they differ from Mooney-Rivlin when bonds are near u_c or below Delta + u_s).
        cl, cs = first(".lattice_longitudinal_speed_x") or cl_mr, first(".lattice_shear_speed_x") or cs_mr
        x_end = X[:, 0].max()
        use = (tips > seed_end + 5 * delta) & (tips < x_end - 10 * delta)
        # A tip that jumps faster than 3 c_l between frames has met damage that formed ahead of it
        # (the line failed there, or a rupture from the far end arrived): the crack from the seed
        # is measured up to the frame before.
        jumps = np.where(np.diff(tips) > 3 * cl * np.diff(times))[0]
        ruptured = float(times[jumps[0] + 1]) if jumps.size else None
        if jumps.size:
            use &= np.arange(tips.size) <= jumps[0]
        if use.sum() < 3:
            sys.exit(f"{args.out}: the tip moved through fewer than 3 frames; no speed")
        v, x0 = np.polyfit(times[use], tips[use], 1)
        result = {"crack_speed": v, "longitudinal_wave_speed_x": cl, "shear_wave_speed": cs,
                  "mooney_rivlin_longitudinal_x": cl_mr, "mooney_rivlin_shear": cs_mr,
                  "v_over_cl": v / cl, "v_over_cs": v / cs, "frames_used": int(use.sum()),
                  "tip_start": float(tips[use][0]), "tip_end": float(tips[use][-1]),
                  "damaged_ahead_of_tip": int(max(np.array(ahead)[use])), "tip_jumps_at": ruptured}
        with open(os.path.join(args.out, "crack_tip.csv"), "w") as o:
            o.write("time,tip_x\n")
            for t, x in zip(times, tips):
                o.write(f"{t:.9g},{x:.9g}\n")
        with open(os.path.join(args.out, "crack_tip.json"), "w") as o:
            json.dump(result, o, indent=2)
        print(json.dumps(result, indent=2))
        k = args.frame
        if k is None:
            idx = np.where(use)[0]
            k = int(idx[len(idx) // 2])
        g = f["frames"][frames[k]]
        x = g["position"][...]
        d = g["damage"][...]
        tip = tips[k]
    # Left: tip region, deformed configuration, damaged nodes drawn on top. Right: tip position
    # against time with lines of slope c_l and c_s through the first measured point.
    sel = np.abs(X[:, 0] - tip) < 40 * delta
    intact = sel & (d == 0)
    hit = sel & (d > 0)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw={"width_ratios": [1.3, 1]})
    ax.scatter(x[intact, 0] * 1e3, x[intact, 1] * 1e3, c="0.75", s=1)
    sc = ax.scatter(x[hit, 0] * 1e3, x[hit, 1] * 1e3, c=d[hit], s=4, cmap="plasma", vmin=0, vmax=0.7)
    fig.colorbar(sc, ax=ax, label="damage (broken fraction of bonds)")
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm] (deformed)")
    ax.set_ylabel("y [mm] (deformed)")
    ax.set_title(f"tip region at t = {times[k] * 1e3:.3f} ms")
    t0, x0m = times[use][0], tips[use][0]
    bx.plot(times * 1e3, tips * 1e3, "k.", label="tip (reference x)")
    tt = np.array([t0, times[use][-1]])
    bx.plot(tt * 1e3, (x0m + v * (tt - t0)) * 1e3, "k-", label=f"fit: {v:.1f} m/s")
    bx.plot(tt * 1e3, (x0m + cl * (tt - t0)) * 1e3, "b--", label=f"c_l = {cl:.1f} m/s")
    bx.plot(tt * 1e3, (x0m + cs * (tt - t0)) * 1e3, "r--", label=f"c_s = {cs:.1f} m/s")
    bx.set_xlabel("t [ms]")
    bx.set_ylabel("tip position [mm] (reference)")
    bx.set_title(f"v/c_l = {v / cl:.2f}, v/c_s = {v / cs:.2f}")
    bx.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "tip_region.png"), dpi=110)

if __name__ == "__main__":
    peri_view.run_tool(main)

#!/usr/bin/env python3
"""Crack path of a sheet run: y(x) of the damaged nodes in a frame, its oscillation about its mean
line (sign changes, wavelength, amplitude), for the blunt-tool scenes (examples/blunt-tool.md).

The path: in each column of nodes (reference x, binned by the sheet's spacing: a grid's columns,
or bins one spacing wide on a mesh) the mean reference y of the nodes with damage >= --threshold
(0.3: the nodes along a crack's faces, not those a row away); a column whose damaged nodes spread
over more than --fork (default 2 mm) holds a fork and is reported. The mean line is the
least-squares straight line through y(x) from --from (default: the first damaged column, a notch
included) to --to (default: the path's end), and d(x) = y(x) - line;
forks are counted in the same window. Sign changes of d count with hysteresis: d must pass beyond
+-h (--band, default one spacing) on the other side. Wavelength: twice the mean distance between consecutive crossings (taken where d changes
sign); amplitude: the mean of |d| at its extreme between consecutive crossings.

usage: crack_path.py RUN_DIR [--frame N] [--threshold 0.3] [--from X] [--to X] [--band H] [--fork F]
                     [--plot FILE] [--json]
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import peri_view  # noqa: E402


def load(run, frame):
    """Reference positions, damage and time of frame `frame` (negative: from the end)."""
    r = peri_view.Run(run)
    if "membrane" not in r.kinds:
        print(f"crack_path: {run} holds no membrane sheet (bodies: {', '.join(r.kinds) or 'none'}); expected a "
              "sheet run such as the blunt tool's", file=sys.stderr)
        sys.exit(2)
    r.require("crack_path", "damage")
    n = len(r.frame_names)
    if not -n <= frame < n:
        print(f"crack_path: --frame {frame}: the run holds frames 0 .. {n - 1} (or -{n} .. -1)", file=sys.stderr)
        sys.exit(2)
    f = r.frame(frame)
    spacings = [float(b["spacing"]) for b in (r.scene.get("bodies") or {}).values()
                if (b or {}).get("kind", "membrane") == "membrane" and (b or {}).get("spacing")]
    return r.reference, f["damage"], f["time"], (min(spacings) if spacings else None)


def path(X, damage, threshold, fork, spacing=None):
    """Columns of the path: a grid's columns of nodes (the distinct x, at least half the sheet's
    spacing apart), else (a mesh, whose nodes' x all differ) bins one spacing wide."""
    x, y = X[:, 0], X[:, 1]
    xs = np.unique(np.round(x, 9))
    h = np.min(np.diff(xs)) if len(xs) > 1 else 1.0
    near = 0.25
    if spacing and h < 0.5 * spacing:
        h, near = spacing, 0.5
        xs = np.arange(x.min(), x.max() + 0.5 * h, h)
    cols, ys, spread = [], [], []
    for xc in xs:
        sel = (np.abs(x - xc) < near * h) & (damage >= threshold)
        if not sel.any():
            continue
        cols.append(xc)
        ys.append(float(np.mean(y[sel])))
        spread.append(float(np.ptp(y[sel])))
    cols, ys, spread = np.array(cols), np.array(ys), np.array(spread)
    forks = cols[spread > fork]
    return cols, ys, spread, forks, h


def window(xc, yc, forks, start=None, end=None):
    """The path's columns and fork columns with start <= x <= end (None: unbounded)."""
    lo = -np.inf if start is None else start
    hi = np.inf if end is None else end
    keep = (xc >= lo) & (xc <= hi)
    return xc[keep], yc[keep], forks[(forks >= lo) & (forks <= hi)]


def oscillation(xc, yc, band):
    """Line fit, deviation, crossings with hysteresis, wavelength and amplitude."""
    if len(xc) < 3:
        return None
    a, b = np.polyfit(xc, yc, 1)
    d = yc - (a * xc + b)
    crossings, extremes = [], []
    side, best_abs = 0, 0.0
    for k in range(len(d)):
        s = 1 if d[k] > band else (-1 if d[k] < -band else 0)
        if s != 0 and side == 0:
            side = s
        if s != 0 and s != side:
            # where d changes sign last before k
            j = k
            while j > 0 and np.sign(d[j - 1]) == np.sign(d[k]):
                j -= 1
            x0 = xc[j - 1] + (xc[j] - xc[j - 1]) * d[j - 1] / (d[j - 1] - d[j]) if j > 0 else xc[j]
            crossings.append(float(x0))
            extremes.append(best_abs)
            side, best_abs = s, 0.0
        if side != 0 and np.sign(d[k]) == side:
            best_abs = max(best_abs, abs(float(d[k])))
    extremes.append(best_abs)
    out = {"slope": float(a), "intercept": float(b), "sign_changes": len(crossings), "crossings": crossings,
           "extremes": extremes, "rms_deviation": float(np.sqrt(np.mean(d * d))), "x": xc.tolist(), "d": d.tolist()}
    if len(crossings) >= 2:
        out["wavelength"] = float(2 * np.mean(np.diff(crossings)))
    inner = extremes[1:-1] if len(extremes) > 2 else extremes
    out["amplitude"] = float(np.mean(inner)) if inner else 0.0
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run")
    ap.add_argument("--frame", type=int, default=-1)
    ap.add_argument("--threshold", type=float, default=0.3)
    ap.add_argument("--from", dest="start", type=float, default=None, help="first x of the fit [m]")
    ap.add_argument("--to", dest="end", type=float, default=None, help="last x of the fit [m]")
    ap.add_argument("--band", type=float, default=None, help="hysteresis band [m] (default: the spacing)")
    ap.add_argument("--fork", type=float, default=0.002)
    ap.add_argument("--plot", default=None)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    if a.start is not None and a.end is not None and not a.start < a.end:
        ap.error(f"--from {a.start} is not below --to {a.end}")
    if a.band is not None and not a.band > 0:
        ap.error(f"--band {a.band}: expected a positive distance [m]")
    if not a.fork > 0:
        ap.error(f"--fork {a.fork}: expected a positive distance [m]")
    X, damage, time, spacing = load(a.run, a.frame)
    xc, yc, _, forks, h = path(X, damage, a.threshold, a.fork, spacing)
    xc, yc, forks = window(xc, yc, forks, a.start, a.end)
    res = oscillation(xc, yc, a.band if a.band is not None else h) or {"sign_changes": 0}
    res.update({"time": time, "spacing": float(h), "path_start": float(xc[0]) if len(xc) else None,
                "path_end": float(xc[-1]) if len(xc) else None, "fork_columns": len(forks),
                "first_fork": float(forks[0]) if len(forks) else None})
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(9, 3))
        hit = damage > 0.05
        ax.scatter(1e3 * X[hit, 0], 1e3 * X[hit, 1], c=damage[hit], s=2, cmap="viridis", vmin=0, vmax=0.6)
        ax.plot(1e3 * xc, 1e3 * yc, "r-", lw=1, label="path y(x)")
        if "slope" in res:
            ax.plot(1e3 * xc, 1e3 * (res["slope"] * xc + res["intercept"]), "k--", lw=0.8, label="mean line")
            for c in res["crossings"]:
                ax.axvline(1e3 * c, color="0.7", lw=0.5)
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_aspect("equal")
        ax.legend(loc="upper right", fontsize=7)
        fig.savefig(a.plot, dpi=130, bbox_inches="tight")
    if a.json:
        print(json.dumps({k: v for k, v in res.items() if k not in ("x", "d")}))
    else:
        print(f"t = {1e3 * time:.2f} ms, path x = {1e3 * res['path_start']:.2f} .. {1e3 * res['path_end']:.2f} mm, "
              f"{res['sign_changes']} sign changes, wavelength "
              f"{1e3 * res['wavelength']:.2f} mm" if "wavelength" in res else f"t = {1e3 * time:.2f} ms, "
              f"{res['sign_changes']} sign changes")
        print(f"amplitude {1e3 * res.get('amplitude', 0):.2f} mm, rms deviation {1e3 * res.get('rms_deviation', 0):.2f} mm, "
              f"fork columns {res['fork_columns']}" + (f" (first at x = {1e3 * res['first_fork']:.2f} mm)" if res['first_fork'] else ""))
    return 0


if __name__ == "__main__":
    sys.exit(peri_view.run_tool(main))

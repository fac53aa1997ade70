#!/usr/bin/env python3
"""Plot the work-precision CSV written by build/benchmarks/work_precision.

usage: /usr/bin/python3 tools/plot_work_precision.py work_precision.csv [--out work_precision.png]

One row of panels per problem: relative error against wall time and against bonds, one line per
ladder (fixed delta: m grows; fixed m = 3: delta and dx shrink together), log-log. Prints a
Markdown table (resolution, bonds, wall time, error) and the observed orders: the least-squares
slope of log(error) against log(dx) over each ladder.
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

TITLES = {
    "stretch_energy": "(a) homogeneous stretch energy vs eq. (19)",
    "wave_speed": "(b) longitudinal wave speed vs c_l",
    "release_rate": "(c) work to advance a crack vs eq. (30)",
}
BONDS = {
    "stretch_energy": "ordered bonds of the measured nodes",
    "wave_speed": "bond updates (bonds x steps)",
    "release_rate": "bonds crossing the advance",
}


def order(rows):
    dx = np.array([float(r["dx"]) for r in rows])
    err = np.array([float(r["relative_error"]) for r in rows])
    ok = err > 0
    if ok.sum() < 2 or np.ptp(np.log(dx[ok])) == 0:
        return float("nan")
    return float(np.polyfit(np.log(dx[ok]), np.log(err[ok]), 1)[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("csv")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    with open(a.csv) as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{a.csv}: no rows")
    problems = [p for p in TITLES if any(r["problem"] == p for r in rows)]
    fig, axes = plt.subplots(len(problems), 2, figsize=(11, 3.6 * len(problems)), squeeze=False)
    print("| problem | ladder | m | dx [mm] | delta [mm] | bonds | wall [s] | relative error |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    orders = []
    for row, p in zip(axes, problems):
        for ladder, marker in (("fixed_delta", "o-"), ("fixed_m", "s--")):
            rs = [r for r in rows if r["problem"] == p and r["ladder"] == ladder]
            if not rs:
                continue
            err = [max(float(r["relative_error"]), 1e-16) for r in rs]
            label = "fixed delta, m = " + ",".join(f'{float(r["m"]):g}' for r in rs) if ladder == "fixed_delta" \
                else "m = 3, delta = " + ",".join(f'{float(r["delta"]) * 1e3:g}' for r in rs) + " mm"
            row[0].loglog([float(r["wall_seconds"]) for r in rs], err, marker, label=label)
            row[1].loglog([float(r["bonds"]) for r in rs], err, marker, label=label)
            for r in rs:
                print(f'| {p} | {ladder} | {float(r["m"]):g} | {float(r["dx"]) * 1e3:.4g} | {float(r["delta"]) * 1e3:.4g} | '
                      f'{float(r["bonds"]):.3g} | {float(r["wall_seconds"]):.3g} | {float(r["relative_error"]):.2e} |')
            orders.append((p, ladder, order(rs)))
        row[0].set_xlabel("wall time [s]")
        row[1].set_xlabel(BONDS[p])
        for ax in row:
            ax.set_ylabel("relative error")
            ax.set_title(TITLES[p], fontsize=10)
            ax.grid(alpha=0.3, which="both")
            ax.legend(fontsize=7)
    print()
    for p, ladder, o in orders:
        print(f"observed order {p} {ladder}: {o:.2f}" + ("" if math.isfinite(o) else " (undefined)"))
    out = a.out or os.path.splitext(a.csv)[0] + ".png"
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Two runs of one sheet problem side by side, by their crack tips: a run on a triangle mesh
against the grid run (docs/examples/slit-membrane.md, "On a triangle mesh"), or any two runs
whose tips peridrive tracked (tips.csv, summary.json).

For each run: when the crack starts (the first time a tip has moved --start metres from where
it began), when it arrives (the first time a tip of tracks 0 and 1 is within --edge metres of
the farthest |x| any tip of either run reached), the mean speed over the steady part and the
largest speed (summary.json: mean_crack_speed, max_crack_speed), and the path's largest and
root-mean-square distance from the slit's line y = y0 (tips of tracks 0 and 1, every sample).
Prints a table; --plot draws tip |x| against time and the paths y(x) of both runs; --check
exits 1 when the second run is outside the bands: mean and largest speed within --speed-band
(relative), arrival within --arrival-band (relative), largest path distance within --path-band
metres.

usage: compare_cracks.py REFERENCE_RUN RUN [--labels A B] [--plot FILE] [--check]
                         [--speed-band 0.1] [--arrival-band 0.15] [--path-band 1e-3]
                         [--start 5e-4] [--edge 1e-3] [--y0 0]
"""
import argparse
import csv
import json
import os
import sys

import numpy as np


def load(run):
    for name in ("tips.csv", "summary.json"):
        if not os.path.isfile(os.path.join(run, name)):
            why = ("no such directory" if not os.path.isdir(run) else
                   "the run failed (FAILED)" if os.path.exists(os.path.join(run, "FAILED")) else
                   f"no {name} (a run that has not finished, or no sheet whose tips are tracked)")
            print(f"compare_cracks.py: {run}: {why}; expected a finished run with tracked crack tips", file=sys.stderr)
            sys.exit(2)
    with open(os.path.join(run, "tips.csv")) as f:
        rows = [r for r in csv.DictReader(f) if r["track"] in ("0", "1")]
    if not rows:
        sys.exit(f"compare_cracks.py: {run}/tips.csv: no tip of tracks 0 and 1")
    with open(os.path.join(run, "summary.json")) as f:
        summary = json.load(f)
    tips = {}
    for r in rows:
        tips.setdefault(r["track"], []).append((float(r["time"]), float(r["x"]), float(r["y"])))
    return {k: np.array(v) for k, v in tips.items()}, summary


def figures(tips, summary, reach, args):
    """The figures of one run; reach: the farthest |x| a tip reached in either run."""
    start = arrive = None
    for track in tips.values():
        moved = np.hypot(track[:, 1] - track[0, 1], track[:, 2] - track[0, 2])
        hit = np.nonzero(moved >= args.start)[0]
        if len(hit):
            start = min(start, track[hit[0], 0]) if start is not None else track[hit[0], 0]
        there = np.nonzero(np.abs(track[:, 1]) >= reach - args.edge)[0]
        if len(there):
            arrive = min(arrive, track[there[0], 0]) if arrive is not None else track[there[0], 0]
    # The path up to the arrival (afterwards the halves part and the tips stop meaning a crack).
    d = np.concatenate([track[track[:, 0] <= (arrive if arrive is not None else np.inf), 2]
                        for track in tips.values()]) - args.y0
    return {
        "start": start,
        "arrive": arrive,
        "mean_speed": summary.get("mean_crack_speed"),
        "max_speed": summary.get("max_crack_speed"),
        "path_max": float(np.max(np.abs(d))),
        "path_rms": float(np.sqrt(np.mean(d * d))),
        "broken_bonds": summary.get("broken_bonds"),
        "nodes": summary.get("nodes"),
    }


def text(v, scale=1.0, fmt="{:.1f}"):
    return "-" if v is None else fmt.format(v * scale)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("reference")
    ap.add_argument("run")
    ap.add_argument("--labels", nargs=2, default=None)
    ap.add_argument("--plot")
    ap.add_argument("--check", action="store_true")
    ap.add_argument("--speed-band", type=float, default=0.1)
    ap.add_argument("--arrival-band", type=float, default=0.15)
    ap.add_argument("--path-band", type=float, default=1e-3)
    ap.add_argument("--start", type=float, default=5e-4)
    ap.add_argument("--edge", type=float, default=1e-3)
    ap.add_argument("--y0", type=float, default=0.0)
    args = ap.parse_args()
    labels = args.labels or [os.path.basename(os.path.normpath(r)) for r in (args.reference, args.run)]
    runs = [load(r) for r in (args.reference, args.run)]
    reach = max(float(np.max(np.abs(track[:, 1]))) for tips, _ in runs for track in tips.values())
    ref, new = (figures(tips, summary, reach, args) for tips, summary in runs)

    def rel(key):
        a, b = ref[key], new[key]
        return None if a is None or b is None or a == 0 else b / a - 1

    rows = [
        ("crack starts [us]", "start", 1e6, "{:.1f}", True),
        (f"arrives within {args.edge * 1e3:g} mm of |x| = {reach * 1e3:.2f} mm [us]", "arrive", 1e6, "{:.1f}", True),
        ("mean speed, steady part [m/s]", "mean_speed", 1, "{:.1f}", True),
        ("largest speed [m/s]", "max_speed", 1, "{:.1f}", True),
        ("path: largest |y - y0| [mm]", "path_max", 1e3, "{:.3f}", False),
        ("path: rms |y - y0| [mm]", "path_rms", 1e3, "{:.3f}", False),
        ("bonds broken", "broken_bonds", 1, "{:.0f}", True),
    ]
    print(f"| | {labels[0]} | {labels[1]} | difference |")
    print("| --- | --- | --- | --- |")
    for name, key, scale, fmt, relative in rows:
        r = rel(key) if relative else None
        diff = f"{100 * r:+.1f}%" if r is not None else ("" if relative else
               text(None if ref[key] is None else new[key] - ref[key], scale, "{:+.3f}"))
        print(f"| {name} | {text(ref[key], scale, fmt)} | {text(new[key], scale, fmt)} | {diff} |")

    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
        for (tips, _), label, color in zip(runs, labels, ("C0", "C3")):
            for k, track in sorted(tips.items()):
                a.plot(track[:, 0] * 1e6, np.abs(track[:, 1]) * 1e3, color=color, lw=1.2 if k == "0" else 0.8,
                       ls="-" if k == "0" else "--", label=f"{label}, tip {k}")
                b.plot(track[:, 1] * 1e3, track[:, 2] * 1e3, color=color, lw=1, label=label if k == "0" else None)
        a.set_xlabel("time [us]")
        a.set_ylabel("crack tip |x| [mm]")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
        b.set_xlabel("x [mm]")
        b.set_ylabel("y of the tip [mm]")
        b.set_aspect("auto")
        b.grid(alpha=0.3)
        b.legend(fontsize=8)
        b.set_title("crack paths (tips' positions)", fontsize=10)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=130)
        print(f"wrote {args.plot}")

    if args.check:
        problems = []
        for key in ("mean_speed", "max_speed"):
            r = rel(key)
            if r is None or abs(r) > args.speed_band:
                problems.append(f"{key} {text(new[key])} against {text(ref[key])} (band {args.speed_band:g})")
        r = rel("arrive")
        if r is None or abs(r) > args.arrival_band:
            problems.append(f"arrival {text(new['arrive'], 1e6)} us against {text(ref['arrive'], 1e6)} us "
                            f"(band {args.arrival_band:g})")
        if not new["path_max"] <= args.path_band:
            problems.append(f"path strays {new['path_max'] * 1e3:.3f} mm from y0 (band {args.path_band * 1e3:g} mm)")
        if problems:
            print("outside the bands: " + "; ".join(problems))
            sys.exit(1)
        print(f"within the bands: speeds {args.speed_band:g}, arrival {args.arrival_band:g}, "
              f"path {args.path_band * 1e3:g} mm")


if __name__ == "__main__":
    main()

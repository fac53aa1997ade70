#!/usr/bin/env python3
"""Terminal crack speed of example 7.1 against the pre-stretch, at a fixed horizon and several m:
the slit sheet is preloaded quasi-statically (PETSc SNES) to an overall stretch lambda with the
slit intact, the slit is released and the crack runs with the grips held
(drivers/scenes/slit_release.yaml); docs/examples/slit-membrane.md, "Crack speed against the
pre-stretch".

For each m and lambda: spacing = horizon / m, the grips' bands moved (lambda - 1) H / 2 apart each
(H: the sheet's height), load_steps = max(4, ceil((lambda - 1) / 0.05)). A run whose directory
already holds a summary.json is not run again. Writes speed_vs_stretch.csv in --out (mean speed
over the steady part and the largest speed of each run, in m/s and over the Rayleigh speed of the
reference state, with the preload's Newton iterations and the wall time) and, with --plot, the
figure.

usage: speed_vs_stretch.py --peridrive BUILD/peridrive [--mpiexec mpirun] [--mpiexec-flags=...]
                           [--np 2] [--scene drivers/scenes/slit_release.yaml] [--m 3 4 6]
                           [--stretch 1.2 1.3 1.4] [--horizon 0.0009375] [--duration 1e-4]
                           [--safety-factor S] [--out DIR] [--plot FILE]
"""
import argparse
import csv
import json
import math
import os
import shlex
import subprocess
import sys
import time

import yaml


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--peridrive", required=True)
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--mpiexec-flags", default="")
    ap.add_argument("--np", type=int, default=2)
    ap.add_argument("--scene", default=os.path.join(here, "..", "drivers", "scenes", "slit_release.yaml"))
    ap.add_argument("--m", type=int, nargs="+", default=[3, 4, 6])
    ap.add_argument("--stretch", type=float, nargs="+", default=[1.15, 1.2, 1.25, 1.3, 1.4, 1.5])
    ap.add_argument("--horizon", type=float, default=0.0009375)
    ap.add_argument("--duration", type=float, default=1.0e-4)
    ap.add_argument("--safety-factor", type=float, help="the dynamic stage's (default: the scene's)")
    ap.add_argument("--out", default="out/speed_vs_stretch")
    ap.add_argument("--plot")
    args = ap.parse_args()

    try:
        scene = yaml.safe_load(open(args.scene))
    except OSError as e:
        sys.exit(f"speed_vs_stretch.py: {args.scene}: cannot read the scene ({e.strerror})")
    body = next(iter(scene["bodies"]))
    height = float(scene["bodies"][body]["size"][1])
    stages = scene["stages"]
    preload = next((i for i, s in enumerate(stages) if s.get("kind") == "quasistatic"), None)
    dynamic = next((i for i, s in enumerate(stages) if s.get("kind", "dynamic") == "dynamic"), None)
    if preload is None or dynamic is None or not (stages[preload].get("displacements") or {}):
        sys.exit(f"speed_vs_stretch.py: {args.scene}: expected a quasi-static stage that moves the grips "
                 "(displacements) and a dynamic stage after it, as drivers/scenes/slit_release.yaml")
    grips = list(stages[preload]["displacements"])
    os.makedirs(args.out, exist_ok=True)
    rows, failed = [], []
    for m in args.m:
        for lam in args.stretch:
            run = os.path.join(args.out, f"m{m}_stretch{lam!r}")
            d = (lam - 1) * height / 2
            sets = {
                f"bodies.{body}.spacing": repr(args.horizon / m),
                f"bodies.{body}.horizon_factor": "~",
                f"bodies.{body}.horizon": repr(args.horizon),
                f"stages.{preload}.displacements": "{" + ", ".join(
                    f"{g}: [0, {d if k == 0 else -d!r}, 0]" for k, g in enumerate(grips)) + "}",
                f"stages.{preload}.load_steps": str(max(4, math.ceil((lam - 1) / 0.05 - 1e-9))),
                f"stages.{dynamic}.duration": repr(args.duration),
                "output.frames": "4",
            }
            if args.safety_factor:
                sets[f"stages.{dynamic}.safety_factor"] = repr(args.safety_factor)
            # A run is reused only for the same request (scene file, overrides, ranks), kept
            # beside its directory.
            request = {"scene": os.path.abspath(args.scene), "scene_text": open(args.scene).read(), "sets": sets,
                       "np": args.np}
            request_path = run + ".request.json"
            try:
                reuse = os.path.exists(os.path.join(run, "summary.json")) and json.load(open(request_path)) == request
            except (OSError, ValueError):
                reuse = False
            if not reuse:
                cmd = [args.mpiexec, "-n", str(args.np), *shlex.split(args.mpiexec_flags), args.peridrive, args.scene]
                for k, v in sets.items():
                    cmd += ["--set", f"{k}={v}"]
                cmd += ["--out", run, "--quiet"]
                t0 = time.time()
                with open(run + ".log", "w") as log:
                    rc = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT)
                print(f"m = {m}, stretch {lam:g}: exit {rc} in {time.time() - t0:.0f} s", flush=True)
                if rc != 0:
                    failed.append(f"m = {m}, stretch {lam:g} (exit {rc}, log {run}.log)")
                    continue
                with open(request_path, "w") as r:
                    json.dump(request, r)
            s = json.load(open(os.path.join(run, "summary.json")))
            c_r = float(s["derived"][f"{body}.rayleigh_wave_speed"])
            qs = (s.get("quasistatic") or [{}])[0]
            mean, top = s.get("mean_crack_speed"), s.get("max_crack_speed")
            rows.append(dict(m=m, stretch=lam, spacing=args.horizon / m, mean_speed=mean, max_speed=top,
                             mean_over_cR=mean / c_r if mean else None, max_over_cR=top / c_r if top else None,
                             rayleigh_speed=c_r, broken_bonds=s["broken_bonds"],
                             preload_newton=qs.get("newton_iterations"), preload_seconds=qs.get("seconds"),
                             wall_seconds=s.get("wall_seconds"), nodes=s["derived"].get(f"{body}.nodes")))
    path = os.path.join(args.out, "speed_vs_stretch.csv")
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["m"])
        w.writeheader()
        w.writerows(rows)
    print(f"{'m':>2} {'stretch':>7} {'mean m/s':>9} {'max m/s':>8} {'mean/cR':>8} {'max/cR':>7} {'broken':>7} {'Newton':>6} {'wall s':>7}")
    for r in rows:
        f = lambda v, p: "-" if v is None else f"{v:.{p}f}"
        print(f"{r['m']:>2} {r['stretch']:>7.3g} {f(r['mean_speed'], 1):>9} {f(r['max_speed'], 1):>8} "
              f"{f(r['mean_over_cR'], 3):>8} {f(r['max_over_cR'], 3):>7} {r['broken_bonds']:>7} "
              f"{r['preload_newton'] if r['preload_newton'] is not None else '-':>6} {f(r['wall_seconds'], 1):>7}")
    print(f"wrote {path}")
    if args.plot and rows:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for k, m in enumerate(sorted({r["m"] for r in rows})):
            rs = sorted((r for r in rows if r["m"] == m and r["mean_over_cR"]), key=lambda r: r["stretch"])
            if not rs:
                continue
            x = [r["stretch"] for r in rs]
            ax.plot(x, [r["mean_over_cR"] for r in rs], "o-", color=f"C{k}",
                    label=f"m = {m} (dx = {args.horizon / m * 1e3:.3g} mm): steady mean")
            ax.plot(x, [r["max_over_cR"] for r in rs], "^:", color=f"C{k}", ms=4, label=f"m = {m}: largest")
        c_r = rows[0]["rayleigh_speed"]
        ax.axhline(1.0, color="k", ls="--", lw=1, label=f"c_R of the unstretched sheet, {c_r:.0f} m/s")
        ax.axhline(400 / c_r, color="gray", ls="-.", lw=1, label="the paper's 400 m/s")
        ax.set_xlabel("pre-stretch lambda (grips' separation over the sheet's height)")
        ax.set_ylabel("crack speed / c_R")
        ax.set_title(f"example 7.1, SNES preload then release; horizon {args.horizon * 1e3:g} mm", fontsize=10)
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=130)
        print(f"wrote {args.plot}")
    if failed:
        sys.exit("speed_vs_stretch.py: " + str(len(failed)) + " run(s) failed, left out of the table: " + "; ".join(failed))


if __name__ == "__main__":
    main()

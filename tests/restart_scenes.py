#!/usr/bin/env python3
"""Every scene resumes bit for bit: each scene of drivers/scenes/, its dynamic stages cut to
--steps steps, runs with a checkpoint every 3/4 of that, and is resumed from its last checkpoint
on the same number of ranks; every frame and series row the resumed run writes must be the same
bits as the uninterrupted run's at the same step, and summary.json's energy balance error and
broken bonds the same.

What it guards: state a scene needs beyond displacement, velocity and the broken bonds (tools,
the crack-tip rule, bond history, dashpots, a lattice's flag bits, quasi-static loads, stages)
must be in the checkpoint or rebuilt from the scene exactly. A lattice's unbreakable bonds were
once recorded as broken there, and the resumed supersonic scene lost its bonds; no scene-by-scene
test saw it.

usage: restart_scenes.py PERIDRIVE SCENES_DIR MPIRUN [--mpi-flag=FLAG ...] [--ranks 2] [--steps 80]
                         [--scenes STEM ...] [--keep DIR]
"""
import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np
import yaml


def run(args, cmd):
    full = [args.mpirun, "-n", str(args.ranks), "--oversubscribe", *args.mpi_flags, args.peridrive, *cmd]
    r = subprocess.run(full, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"restart_scenes: {' '.join(full)} exited {r.returncode}:\n{r.stderr[-2000:]}")
    return r


def series(out):
    with open(os.path.join(out, "series.csv")) as f:
        rows = list(csv.reader(f))
    return rows[0], {row[0]: row for row in rows[1:]}


def frames(out):
    """{step: {dataset: array}} of a run's frames.h5."""
    with h5py.File(os.path.join(out, "frames.h5"), "r") as f:
        return {int(g.attrs["step"]): {name: g[name][()] for name in g if isinstance(g[name], h5py.Dataset)}
                for g in (f["frames"][k] for k in f["frames"])}


def check(stem, whole, resumed, step):
    """Problems of a resumed run (from the checkpoint at `step`) against the uninterrupted one,
    and what was compared."""
    problems = []
    head_a, rows_a = series(whole)
    head_b, rows_b = series(resumed)
    if head_a != head_b:
        problems.append(f"{stem}: series.csv columns differ")
    later = [k for k in rows_b if int(k) > step]
    for k in rows_b:
        if rows_a.get(k) != rows_b[k]:
            problems.append(f"{stem}: series.csv row of step {k} differs")
            break
    fa, fb = frames(whole), frames(resumed)
    compared = [s for s in fb if s > step]
    for s in sorted(fb):
        if s not in fa:
            problems.append(f"{stem}: the resumed run wrote a frame at step {s}, the uninterrupted one did not")
            continue
        for name, y in fb[s].items():
            x = fa[s].get(name)
            if x is None or x.shape != y.shape or x.tobytes() != y.tobytes():
                d = float(np.nanmax(np.abs(x.astype(float) - y.astype(float)))) if x is not None and x.shape == y.shape else float("nan")
                problems.append(f"{stem}: frame of step {s}, {name} differs (max |diff| {d:.3g})")
    missing = [s for s in fa if s > step and s not in fb]
    if missing:
        problems.append(f"{stem}: frames after the checkpoint missing from the resumed run: steps {missing}")
    if not compared or not later:
        problems.append(f"{stem}: nothing after the checkpoint (step {step}) to compare: {len(compared)} frames, "
                        f"{len(later)} series rows")
    with open(os.path.join(whole, "summary.json")) as f:
        sa = json.load(f)
    with open(os.path.join(resumed, "summary.json")) as f:
        sb = json.load(f)
    for key in ("steps", "broken_bonds", "precrack_bonds", "final", "energy_balance_error", "run_energy_balance_error",
                "quasistatic_work_error", "crack_tips", "max_crack_speed", "mean_crack_speed"):
        if sa.get(key) != sb.get(key):
            problems.append(f"{stem}: summary.json {key} {sa.get(key)} vs {sb.get(key)}")
    return problems, len(compared), len(later)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("peridrive")
    p.add_argument("scenes_dir")
    p.add_argument("mpirun")
    p.add_argument("--mpi-flag", dest="mpi_flags", action="append", default=[],
                   help="a flag for mpirun (e.g. --mpi-flag=--allow-run-as-root); repeatable")
    p.add_argument("--ranks", type=int, default=2)
    p.add_argument("--steps", type=int, default=80, help="steps of each dynamic stage")
    p.add_argument("--scenes", nargs="+", help="scene stems (default: every drivers/scenes/*.yaml)")
    p.add_argument("--keep", help="keep the runs in this directory")
    args = p.parse_args()
    stems = args.scenes or sorted(f[:-5] for f in os.listdir(args.scenes_dir) if f.endswith(".yaml"))
    work = args.keep or tempfile.mkdtemp(prefix="restart_scenes.")
    os.makedirs(work, exist_ok=True)
    every = max(1, (3 * args.steps) // 4)
    problems = []
    try:
        for stem in stems:
            scene = os.path.join(args.scenes_dir, stem + ".yaml")
            resolved = yaml.safe_load(subprocess.run([args.peridrive, scene, "--print-scene"], capture_output=True,
                                                     text=True, check=True).stdout)
            sets = ["--set", "output.checkpoint_every_seconds=0", "--set", f"output.checkpoint_every_steps={every}"]
            for k, stage in enumerate(resolved.get("stages", [])):
                if stage.get("kind", "dynamic") == "dynamic":
                    sets += ["--set", f"stages.{k}.steps={args.steps}"]
            whole = os.path.join(work, stem + ".whole")
            resumed = os.path.join(work, stem + ".resumed")
            for d in (whole, resumed):
                shutil.rmtree(d, ignore_errors=True)
            run(args, [scene, "--quiet", "--out", whole, *sets])
            checkpoint = os.path.join(whole, "checkpoint.h5")
            with h5py.File(checkpoint, "r") as f:
                step = int(f.attrs["step"])
            run(args, ["--resume", checkpoint, "--quiet", "--out", resumed])
            found, nframes, nrows = check(stem, whole, resumed, step)
            print(f"{stem}: resumed at step {step}: {nframes} frames and {nrows} series rows after it "
                  f"{'the same bits' if not found else 'DIFFER: ' + found[0]}", flush=True)
            problems += found
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    if problems:
        print("\n".join(["FAILED:"] + problems))
        return 1
    print(f"all {len(stems)} scenes resume bit for bit on {args.ranks} ranks")
    return 0


if __name__ == "__main__":
    sys.exit(main())

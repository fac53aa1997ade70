#!/usr/bin/python3
"""Checkpoint write and resume: time and each rank's peak memory, for one or two peridrive builds.

For each build and round (builds alternated, their order rotating each round), on R ranks:
  with    the slit membrane at the given spacing for S steps, one checkpoint at the last step;
  without the same run with no checkpoint; the write time is summary.json's checkpoint_seconds
          (builds that have it) and, for any two builds alike, the difference of the two runs'
          wall_seconds (noisier: it holds the whole run's noise);
  resume  --resume of the first run's directory (0 steps left: the time to read the checkpoint,
          set up and restore).
Each rank runs under /usr/bin/time, whose maximum resident set is that rank's peak over the run.

    /usr/bin/python3 benchmarks/checkpoint_io.py build/peridrive [BASE/peridrive] \\
        --spacing 5e-5 --steps 4 --rounds 3            # about 1e6 nodes
    /usr/bin/python3 benchmarks/checkpoint_io.py build/peridrive --spacing 1.58e-5 --steps 2 --rounds 1  # 1e7

Prints one line per run and, per build, the medians; with two builds the ratios (second / first).
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "drivers", "scenes", "slit_membrane.yaml")


def run(cmd, env):
    t0 = time.monotonic()
    p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wall = time.monotonic() - t0
    if p.returncode != 0:
        sys.exit("failed (%d): %s\n%s" % (p.returncode, " ".join(cmd), p.stderr[-4000:]))
    return wall


def peaks(prefix, ranks):
    out = []
    for r in range(ranks):
        with open("%s.%d" % (prefix, r)) as f:
            out.append(int(f.read().split()[-1]) * 1024)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("builds", nargs="+", help="peridrive executables (the first is the reference)")
    ap.add_argument("--spacing", default="5e-5", help="bodies.sheet.spacing [m] (5e-5: 1e6 nodes)")
    ap.add_argument("--steps", type=int, default=4)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--mpirun", default="mpirun")
    ap.add_argument("--work", default=None, help="directory for the runs (default: a temporary one)")
    a = ap.parse_args()
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")
    work = a.work or tempfile.mkdtemp(prefix="ckpt-io-")
    os.makedirs(work, exist_ok=True)
    common = ["--set", "bodies.sheet.spacing=" + a.spacing, "--set", "stages.0.steps=%d" % a.steps,
              "--set", "output.frames=1", "--set", "output.node_stride=1000", "--set", "output.series_every=1000000",
              "--quiet"]  # frames of a thousandth of the nodes: the output time is the checkpoint's
    # Each rank under /usr/bin/time: its peak resident set into PREFIX.<rank>.
    timed = ["sh", "-c", 'p="$1"; shift; exec /usr/bin/time -f "%M" -o "$p.$OMPI_COMM_WORLD_RANK" "$@"', "sh"]
    results = {b: [] for b in a.builds}
    for rnd in range(a.rounds):
        order = a.builds[rnd % len(a.builds):] + a.builds[:rnd % len(a.builds)]
        for k, exe in enumerate(order):
            tag = "%d-%d" % (rnd, a.builds.index(exe))
            mpi = [a.mpirun, "-n", str(a.ranks)]
            d_with, d_without = os.path.join(work, "with-" + tag), os.path.join(work, "without-" + tag)
            for d in (d_with, d_without):
                shutil.rmtree(d, ignore_errors=True)
            run(mpi + timed + [os.path.join(work, "rss-with-" + tag), exe, SCENE, "--out", d_with] + common +
                ["--set", "output.checkpoint_every_steps=%d" % a.steps], env)
            run(mpi + [exe, SCENE, "--out", d_without] + common + ["--set", "output.checkpoint_every_steps=0"], env)
            wall = run(mpi + timed + [os.path.join(work, "rss-resume-" + tag), exe, "--resume", d_with, "--quiet"], env)
            with open(os.path.join(d_with, "summary.json")) as f:
                s_with = json.load(f)
            with open(os.path.join(d_without, "summary.json")) as f:
                s_without = json.load(f)
            row = {
                "nodes": s_with.get("nodes"),
                "write_seconds": s_with.get("checkpoint_seconds", float("nan")),
                "write_wall_difference": s_with["wall_seconds"] - s_without["wall_seconds"],
                "resume_wall_seconds": wall,
                "write_run_peaks": peaks(os.path.join(work, "rss-with-" + tag), a.ranks),
                "resume_peaks": peaks(os.path.join(work, "rss-resume-" + tag), a.ranks),
                "checkpoint_bytes": os.path.getsize(os.path.join(d_with, "checkpoint.h5")),
            }
            results[exe].append(row)
            print("round %d %s: %s" % (rnd, exe, json.dumps(row)), flush=True)
            for d in (d_with, d_without):
                shutil.rmtree(d, ignore_errors=True)
    med = {}
    for exe, rows in results.items():
        m = {key: statistics.median(r[key] for r in rows) for key in ("write_seconds", "write_wall_difference", "resume_wall_seconds")}
        for key in ("write_run_peaks", "resume_peaks"):
            m[key + "_MB"] = [round(statistics.median(r[key][i] for r in rows) / 1e6, 1) for i in range(a.ranks)]
            m[key + "_rank0_over_rank1"] = round(statistics.median(r[key][0] / r[key][1] for r in rows), 3)
        med[exe] = m
        print("median %s: %s" % (exe, json.dumps(m)))
    if len(a.builds) == 2:
        b0, b1 = (med[e] for e in a.builds)
        print("ratios (%s / %s): write (wall difference) %.3f, resume %.3f" % (a.builds[1], a.builds[0],
              b1["write_wall_difference"] / b0["write_wall_difference"] if b0["write_wall_difference"] > 0 else float("nan"),
              b1["resume_wall_seconds"] / b0["resume_wall_seconds"]))
    if not a.work:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()

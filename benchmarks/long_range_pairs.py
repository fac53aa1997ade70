#!/usr/bin/python3
"""Long-range pairs at scale: the fiber network of drivers/scenes/fiber_network.yaml grown to
FIBERS fibers per family in a BOX x BOX x 5 nm box (the scene's density of fibers: 20 in 200 nm),
a short stretch, run by two builds alternately (A B A B ...); prints each run's time per step
(summary.json's step_seconds / steps_timed) and each rank's peak resident memory
(/usr/bin/time -v), then the medians.

  /usr/bin/python3 benchmarks/long_range_pairs.py REF_EXE                      # 8 129 nodes
  /usr/bin/python3 benchmarks/long_range_pairs.py REF_EXE --fibers 224 --box 2236e-9   # 1.02e6 nodes
  /usr/bin/python3 benchmarks/long_range_pairs.py REF_EXE --only this ...       # this build alone

The 8 129-node scene runs its full stretch (5 636 steps) unless --duration says otherwise; larger
ones default to 1e-10 s (491 steps). Frames: one, at the end (step time excludes output).
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SCENE = os.path.join(ROOT, "drivers", "scenes", "fiber_network.yaml")


def overrides(fibers, box, duration):
    sets = ["output.frames=1", "output.checkpoint_every_seconds=0"]
    if fibers != 20 or box != 200e-9:
        sets += [f"bodies.net.network.box={{min: [0, 0, 0], max: [{box!r}, {box!r}, 5.0e-9]}}",
                 f"bodies.net.network.families=[{{direction: x, count: {fibers}}}, {{direction: y, count: {fibers}}}]",
                 f"boundaries.1.region.min=[{box - 6e-9!r}, -1, -1]"]
    if duration:
        sets.append(f"stages.0.duration={duration!r}")
    return sets


def run(exe, ranks, sets, out):
    # Each rank's /usr/bin/time report to a file of its own (Open MPI names the rank).
    times = out + ".time"
    cmd = ["mpirun", "-n", str(ranks), "sh", "-c", f'exec /usr/bin/time -v -o {times}.$OMPI_COMM_WORLD_RANK "$@"',
           "sh", exe, SCENE, "--quiet", "--out", out]
    for s in sets:
        cmd += ["--set", s]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"long_range_pairs: {' '.join(cmd)} exited {r.returncode}:\n{r.stderr[-3000:]}")
    rss = []
    for rank in range(ranks):
        with open(f"{times}.{rank}") as f:
            rss.append(int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", f.read()).group(1)) * 1024)
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    return s["step_seconds"] / s["steps_timed"], rss, s["nodes"], s["steps_timed"]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("ref", help="the other build's peridrive")
    p.add_argument("--exe", default=os.path.join(ROOT, "build", "peridrive"))
    p.add_argument("--fibers", type=int, default=20, help="fibers per family")
    p.add_argument("--box", type=float, default=200e-9, help="box side in x and y [m]")
    p.add_argument("--duration", type=float, default=None, help="the stretch's duration [s]")
    p.add_argument("--ranks", type=int, default=2)
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--only", choices=["ref", "this"], help="run one build alone")
    a = p.parse_args()
    duration = a.duration if a.duration is not None else (None if a.fibers == 20 and a.box == 200e-9 else 1e-10)
    sets = overrides(a.fibers, a.box, duration)
    builds = [("ref", a.ref), ("this", a.exe)]
    if a.only:
        builds = [b for b in builds if b[0] == a.only]
    results = {name: [] for name, _ in builds}
    with tempfile.TemporaryDirectory() as work:
        for k in range(a.runs):
            for name, exe in builds:
                out = os.path.join(work, f"{name}{k}")
                step, rss, nodes, steps = run(exe, a.ranks, sets, out)
                results[name].append((step, rss))
                print(f"{name:4s} run {k + 1}: {nodes} nodes, {steps} steps, {step * 1e3:.3f} ms/step, "
                      f"peak RSS per rank {', '.join(f'{b / 2**20:.0f}' for b in rss)} MiB", flush=True)
    for name, rows in results.items():
        step = statistics.median(r[0] for r in rows)
        rss = [statistics.median(r[1][i] for r in rows) / 2**20 for i in range(len(rows[0][1]))]
        print(f"{name:4s} median: {step * 1e3:.3f} ms/step, peak RSS per rank {', '.join(f'{m:.0f}' for m in rss)} MiB")


if __name__ == "__main__":
    main()

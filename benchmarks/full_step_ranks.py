#!/usr/bin/python3
"""Full explicit step on 1 and 2 ranks, alternated, for a parallel-efficiency figure. Prints figures
only; asserts nothing.

Scene: the membrane of bench_kernels' full_step (N x N nodes, dx = 1 mm, m = 3, partial-area
weights, critical stretch 5 so nothing breaks), run by `peridrive` for --steps steps. Each round
runs every rank count once (1 2 1 2 ...); the figure per run is `step_seconds` of summary.json (the
time-stepping loop alone, setup and output excluded). The table gives medians over rounds;
efficiency = t_1 / (P t_P) from the medians, and its range over the rounds (each round's P-rank run
against the same round's 1-rank run).

  /usr/bin/python3 benchmarks/full_step_ranks.py                   # N = 500, 200 steps, 5 rounds
  /usr/bin/python3 benchmarks/full_step_ranks.py --n 400 --rounds 9
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def scene(n, steps):
    dx = 1e-3
    return f"""name: full-step
description: membrane of bench_kernels' full_step (benchmarks/full_step_ranks.py)
materials:
  m: {{model: membrane, density: 1200, bulk_modulus: 800.0e6, critical_stretch: 5.0}}
bodies:
  sheet: {{material: m, origin: [0, 0, 0], size: [{n * dx!r}, {n * dx!r}], thickness: 0.0005, spacing: {dx}, quadrature: partial_area}}
stages:
  - {{name: run, steps: {steps}}}
output: {{frames: 1, series_every: {steps}}}
"""


def run(exe, mpirun, ranks, scene_file, out):
    shutil.rmtree(out, ignore_errors=True)
    cmd = [mpirun, "--allow-run-as-root", "-n", str(ranks), exe, scene_file, "--out", out, "--quiet"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    return s["step_seconds"] / s["steps"], s["ordered_bonds"], s.get("partition_balance")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=500, help="nodes per edge (default 500: 250 000 nodes)")
    ap.add_argument("--steps", type=int, default=200, help="time steps per run (default 200)")
    ap.add_argument("--rounds", type=int, default=5, help="rounds of 1 2 ... (default 5)")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2], help="rank counts (default 1 2)")
    ap.add_argument("--peridrive", default=os.path.join(ROOT, "build", "peridrive"))
    ap.add_argument("--mpirun", default=shutil.which("mpirun") or "mpirun")
    args = ap.parse_args()
    if not os.path.exists(args.peridrive):
        raise SystemExit(f"full_step_ranks.py: {args.peridrive} not found (build first: bash scripts/build.sh)")
    times = {p: [] for p in args.ranks}
    bonds = balance = None
    with tempfile.TemporaryDirectory() as work:
        scene_file = os.path.join(work, "scene.yaml")
        with open(scene_file, "w") as f:
            f.write(scene(args.n, args.steps))
        for r in range(args.rounds):
            for p in args.ranks:
                t, bonds, bal = run(args.peridrive, args.mpirun, p, scene_file, os.path.join(work, f"out{p}"))
                times[p].append(t)
                if p > 1:
                    balance = bal
            print(f"round {r + 1}: " + ", ".join(f"{p} rank(s) {times[p][-1]:.4f} s/step" for p in args.ranks), flush=True)
    base = min(args.ranks)
    t_base = statistics.median(times[base])
    print(f"\n{args.n} x {args.n} nodes, {bonds} ordered bonds, {args.steps} steps per run, {args.rounds} rounds "
          f"(ranks alternated), medians of step_seconds / steps; largest part / mean bonds {balance}")
    print(f"{'ranks':>5s} {'s/step':>9s} {'bond updates/s':>15s} {'per core':>10s} {'efficiency':>11s} {'per round':>12s}")
    for p in args.ranks:
        t = statistics.median(times[p])
        rate = bonds / t
        if p == base:
            eff, spread = "", ""
        else:
            per_round = sorted(times[base][k] * base / (p * times[p][k]) for k in range(args.rounds))
            eff = f"{t_base * base / (p * t):.3f}"
            spread = f"{per_round[0]:.2f}-{per_round[-1]:.2f}"
        print(f"{p:5d} {t:9.4f} {rate:15.3e} {rate / p:10.3e} {eff:>11s} {spread:>12s}")


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Whole explicit steps of two peridrive builds side by side: runs A B B A A B ... on each case and
prints the median of step_seconds per step of each build and of their per-pair ratio A/B (> 1: B
faster), with its quartiles. Prints figures only; asserts nothing.

  /usr/bin/python3 benchmarks/ab_steps.py OLD/peridrive build/peridrive            # every case, 7 pairs
  /usr/bin/python3 benchmarks/ab_steps.py OLD/peridrive build/peridrive --cases block64 --pairs 11 --ranks 2

Cases (each a scene run for --steps steps, one frame, no checkpoints):
  membrane   400 x 400 membrane sheet, partial-area weights, critical stretch 5 (intact)
  pmb        400 x 400 PMB sheet, critical strain 0.5 (intact)
  block64    the 64^3 PMB block of compare_lammps.py, intact (s0 = 0.5)
  block64f   the same block fracturing (s0 = 0.0005: half its bonds break by step 50)
  lattice    drivers/scenes/supersonic_rubber_broad_switch.yaml (Marder's lattice)
  network    drivers/scenes/fiber_network.yaml (fibers with long-range pairs)
Alternating pairs spread a shared machine's noise over both builds alike; report the ratio, never
an absolute time.
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)


def sheet(model, critical, n=400):
    dx = 1e-3
    stiffness = "bulk_modulus: 800.0e6" if model == "membrane" else "bulk_modulus: 300.0e6"
    return f"""name: ab-{model}
materials:
  m: {{model: {model}, density: 1200, {stiffness}, critical_stretch: {critical}}}
bodies:
  sheet: {{material: m, origin: [0, 0, 0], size: [{n * dx!r}, {n * dx!r}], thickness: 0.0005, spacing: {dx}, quadrature: partial_area}}
initial:
  velocity_gradient: [[20, 0, 0], [0, -10, 0], [0, 0, 0]]
stages:
  - {{name: run, steps: STEPS}}
output: {{frames: 1, series_every: 10}}
"""


def block(s0):
    from compare_lammps import peridrive_scene
    text = peridrive_scene(64, 12345).replace("steps: 12345", "steps: STEPS")
    return text.replace("critical_stretch: 0.0005", f"critical_stretch: {s0}")


def scene_file(stem):
    with open(os.path.join(ROOT, "drivers", "scenes", stem + ".yaml")) as f:
        return f.read()


CASES = {
    "membrane": lambda: sheet("membrane", 5.0),
    "pmb": lambda: sheet("pmb", 0.5),
    "block64": lambda: block(0.5),
    "block64f": lambda: block(0.0005),
    "lattice": lambda: scene_file("supersonic_rubber_broad_switch"),
    "network": lambda: scene_file("fiber_network"),
}


def run(exe, ranks, scene, out, steps, env):
    shutil.rmtree(out, ignore_errors=True)
    cmd = ["mpirun", "-n", str(ranks), exe, scene, "--out", out, "--quiet",
           "--set", "output.checkpoint_every_seconds=0", "--set", "output.frames=1"]
    if "STEPS" not in open(scene).read():
        cmd += ["--set", f"stages.0.steps={steps}"]
    subprocess.run(cmd, check=True, capture_output=True, text=True, env=env)
    with open(os.path.join(out, "summary.json")) as f:
        s = json.load(f)
    return s["step_seconds"] / s["steps"]


def quartiles(v):
    v = sorted(v)
    return v[len(v) // 4], v[(3 * len(v)) // 4]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("a", help="peridrive build A (e.g. the reference)")
    p.add_argument("b", help="peridrive build B")
    p.add_argument("--cases", nargs="*", default=list(CASES))
    p.add_argument("--pairs", type=int, default=7)
    p.add_argument("--steps", type=int, default=50)
    p.add_argument("--ranks", type=int, default=1)
    args = p.parse_args()
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    print(f"A {args.a}\nB {args.b}\n{args.ranks} rank(s), {args.steps} steps, {args.pairs} pairs (A B B A ...)")
    print(f"{'case':10s} {'A s/step':>10s} {'B s/step':>10s} {'A/B median':>11s} {'quartiles':>12s}")
    with tempfile.TemporaryDirectory() as work:
        for case in args.cases:
            path = os.path.join(work, case + ".yaml")
            with open(path, "w") as f:
                f.write(CASES[case]().replace("STEPS", str(args.steps)))
            ta, tb, ratio = [], [], []
            for k in range(args.pairs):
                order = [("a", args.a), ("b", args.b)] if k % 2 == 0 else [("b", args.b), ("a", args.a)]
                t = {}
                for tag, exe in order:
                    t[tag] = run(exe, args.ranks, path, os.path.join(work, tag), args.steps, env)
                ta.append(t["a"])
                tb.append(t["b"])
                ratio.append(t["a"] / t["b"])
            q = quartiles(ratio)
            print(f"{case:10s} {statistics.median(ta):10.4g} {statistics.median(tb):10.4g} "
                  f"{statistics.median(ratio):11.3f} {q[0]:5.3f}-{q[1]:5.3f}", flush=True)


if __name__ == "__main__":
    main()

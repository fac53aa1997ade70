#!/usr/bin/python3
"""Quasi-static preload at growing sizes, beside the dynamic run it prepares.

Example 7.1's sheet (50 mm square, h = 0.5 mm, c_l = 1000 m/s, lambda_0 = 2, the 10 mm slit
released later) is pulled by its top and bottom bands to a stretch of 1.3 by SNES, at spacings
that give about 25k, 100k, 400k (and with --sizes, 1.6M) nodes, on --ranks ranks. Per size it
prints the Newton and linear iterations, linear iterations per Newton step, the seconds spent in
residuals, in tangents (assembly) and in the rest of the solve (preconditioner and Krylov), the
preload's wall time, and the wall time of the same sheet's dynamic crack run (the default scene,
example 7.1's 40 us pull: the run a preload prepares) at the same spacing. Prints figures only;
asserts nothing.

  /usr/bin/python3 benchmarks/preload_scaling.py build/peridrive                 # 25k, 100k, 400k nodes
  /usr/bin/python3 benchmarks/preload_scaling.py build/peridrive --sizes 25k 1.6M --no-dynamic
  /usr/bin/python3 benchmarks/preload_scaling.py build/peridrive -- -qs_pc_type bjacobi -qs_mat_type baij
  /usr/bin/python3 benchmarks/preload_scaling.py build/peridrive --work-precision 100k

--work-precision SIZE: instead, the preload at one size with SNES relative tolerances from 1e-2 to
1e-8 against the default (1e-9, and the absolute floor 1e-10 of a node's stiffness times its
spacing) as the reference: per tolerance the iterations, the preload's seconds, and the relative
errors of the displacement field (L2, the frame written one step after the release), of the top
band's final reaction and of the final strain energy (quasistatic.csv).

Arguments after -- go to peridrive (PETSc options: the preconditioner, -qs_snes_rtol, ...).
"""
import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SCENE = os.path.join(ROOT, "drivers", "scenes", "slit_release.yaml")
DEFAULT = os.path.join(ROOT, "drivers", "scenes", "slit_membrane.yaml")
SPACING = {"25k": 3.125e-4, "100k": 1.5625e-4, "400k": 7.8125e-5, "1.6M": 3.90625e-5}


def peridrive(exe, ranks, args, out):
    cmd = ([exe] if ranks == 1 else [shutil.which("mpirun") or "mpirun", "-n", str(ranks), exe]) + args
    cmd += ["--out", out, "--quiet"]
    env = dict(os.environ)
    if os.geteuid() == 0:  # mpirun refuses root without these (containers)
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    t0 = time.monotonic()
    run = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    wall = time.monotonic() - t0
    if run.returncode != 0:
        sys.exit(f"preload_scaling: {' '.join(cmd)} failed ({run.returncode}):\n{run.stderr[-2000:]}")
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f), wall


def final_row(out):
    """The last converged increment of quasistatic.csv: (top band's y reaction [N], strain energy [J])."""
    with open(os.path.join(out, "quasistatic.csv")) as f:
        rows = list(csv.DictReader(f))
    return float(rows[-1]["top_reaction_y"]), float(rows[-1]["strain_energy"])


def displacement(out):
    """The displacement of the run's last frame (natural node order)."""
    import h5py
    with h5py.File(os.path.join(out, "frames.h5"), "r") as f:
        frames = sorted(f["frames"].keys())
        return f["frames"][frames[-1]]["displacement"][:].ravel()


def work_precision(a, extra, work):
    import numpy as np
    dx = SPACING[a.work_precision]
    base = [SCENE, "--set", f"bodies.sheet.spacing={dx}", "--set", "stages.2.steps=1", "--set", "output.frames=1"]
    print(f"work-precision of the preload at {a.work_precision}, {a.ranks} rank(s); peridrive options: "
          f"{' '.join(extra) or '-'}")
    print(f"{'snes_rtol':>10} {'newton':>6} {'linear':>7} {'preload_s':>9} {'displacement_err':>16} "
          f"{'reaction_err':>12} {'energy_err':>10}")
    s, _ = peridrive(a.peridrive, a.ranks, base + extra, os.path.join(work, "reference"))
    ref = final_row(os.path.join(work, "reference"))
    u_ref = displacement(os.path.join(work, "reference"))
    rows = [(tol, ["-qs_snes_rtol", tol]) for tol in ["1e-2", "1e-3", "1e-4", "1e-5", "1e-6", "1e-7", "1e-8"]]
    for tol, opts in rows + [("1e-9 (ref)", [])]:
        out = os.path.join(work, f"wp-{tol.split()[0]}")
        s, _ = peridrive(a.peridrive, a.ranks, base + extra + opts, out)
        q = s["quasistatic"][0]
        reaction, energy = final_row(out)
        du = np.linalg.norm(displacement(out) - u_ref) / np.linalg.norm(u_ref)
        print(f"{tol:>10} {q['newton_iterations']:>6} {q['linear_iterations']:>7} {q['seconds']:>9.3g} {du:>16.2e} "
              f"{abs(reaction - ref[0]) / abs(ref[0]):>12.2e} {abs(energy - ref[1]) / abs(ref[1]):>10.2e}", flush=True)


def main():
    argv = sys.argv[1:]
    extra = []
    if "--" in argv:
        extra = argv[argv.index("--") + 1:]
        argv = argv[:argv.index("--")]
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("peridrive")
    ap.add_argument("--sizes", nargs="*", default=["25k", "100k", "400k"], choices=list(SPACING))
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--no-dynamic", action="store_true", help="skip the dynamic runs")
    ap.add_argument("--work-precision", choices=list(SPACING), metavar="SIZE",
                    help="instead: residual tolerance against time and error at one size")
    a = ap.parse_args(argv)
    if a.work_precision:
        with tempfile.TemporaryDirectory() as work:
            work_precision(a, extra, work)
        return
    print(f"preload to stretch 1.3 of example 7.1's sheet, {a.ranks} rank(s); peridrive options: {' '.join(extra) or '-'}")
    print(f"{'size':>5} {'nodes':>8} {'newton':>6} {'linear':>7} {'lin/newton':>10} {'residual_s':>10} "
          f"{'tangent_s':>9} {'solve_s':>8} {'preload_s':>9} {'dynamic_s':>9}")
    with tempfile.TemporaryDirectory() as work:
        for size in a.sizes:
            dx = SPACING[size]
            # The preload stage alone (release and dynamics cut to one step).
            args = [SCENE, "--set", f"bodies.sheet.spacing={dx}", "--set", "stages.2.steps=1",
                    "--set", "output.frames=1"] + extra
            s, _ = peridrive(a.peridrive, a.ranks, args, os.path.join(work, f"qs-{size}"))
            q = s["quasistatic"][0]
            newton, linear = q["newton_iterations"], q["linear_iterations"]
            dyn = "-"
            if not a.no_dynamic:
                d, _ = peridrive(a.peridrive, a.ranks, [DEFAULT, "--set", f"bodies.sheet.spacing={dx}",
                                                        "--set", "output.frames=2"], os.path.join(work, f"dyn-{size}"))
                dyn = f"{d['wall_seconds']:.3g}"
            print(f"{size:>5} {s['nodes']:>8} {newton:>6} {linear:>7} {linear / max(newton, 1):>10.1f} "
                  f"{q.get('residual_seconds', float('nan')):>10.3g} {q.get('tangent_seconds', float('nan')):>9.3g} "
                  f"{q['seconds'] - q.get('residual_seconds', 0) - q.get('tangent_seconds', 0):>8.3g} "
                  f"{q['seconds']:>9.3g} {dyn:>9}", flush=True)


if __name__ == "__main__":
    main()

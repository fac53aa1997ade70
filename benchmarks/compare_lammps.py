#!/usr/bin/python3
"""peridrive vs LAMMPS PERI (pair style peri/pmb) on the identical problem; prints figures only.

Problem: a free block of N^3 simple-cubic points, dx = 1 mm, delta = 3.015 dx, K = 14.9 GPa
(c = 18 K / (pi delta^4)), rho = 2200 kg/m^3, s0 = 0.0005 (no compressive enhancement, alpha = 0),
initial velocity v_x = 200 s^-1 (x - x_c), dt = 2e-7 s. Both codes weight the neighbours near the
horizon with LAMMPS' linear taper (peridrive: `quadrature: taper`), so the bond sets, micromodulus,
masses and integrator agree; the kinetic-energy histories match to round-off until bonds break.

Runs alternate A B A B (peridrive, LAMMPS) for every size and rank count; the table gives medians.
  /usr/bin/python3 benchmarks/compare_lammps.py                 # N = 32 64, ranks 1 2, 3 repetitions
  /usr/bin/python3 benchmarks/compare_lammps.py --sizes 32 64 100 --reps 5 --steps 50
  /usr/bin/python3 benchmarks/compare_lammps.py --quick         # N = 20, 1 repetition, ranks 1
Without `lmp` in PATH (Debian: apt-get install lammps) it runs peridrive alone.
"""
import argparse
import csv
import json
import math
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile

DX, DELTA_FACTOR, K, RHO, S0, RATE, DT = 1e-3, 3.015, 14.9e9, 2200.0, 0.0005, 200.0, 2.0e-7
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def micromodulus(delta):
    return 18.0 * K / (math.pi * delta ** 4)


def peridrive_scene(n, steps):
    L, delta, xc = n * DX, DELTA_FACTOR * DX, 0.5 * n * DX
    return f"""name: lammps-block
description: free PMB block, the problem of benchmarks/compare_lammps.py
materials:
  glass: {{model: pmb, density: {RHO}, micromodulus: {micromodulus(delta)!r}, critical_stretch: {S0}}}
bodies:
  block: {{kind: solid, material: glass, origin: [0, 0, 0], size: [{L!r}, {L!r}, {L!r}], spacing: {DX}, horizon: {delta!r}, quadrature: taper}}
initial:
  velocity_gradient: [[{RATE}, 0, 0], [0, 0, 0], [0, 0, 0]]
  center: [{xc!r}, {xc!r}, {xc!r}]
stages:
  - {{name: expand, steps: {steps}, dt: {DT}}}
output: {{frames: 1, series_every: 10, velocity: false}}
"""


def lammps_input(n, steps):
    delta, xc = DELTA_FACTOR * DX, 0.5 * n * DX
    return f"""# free PMB block, the problem of benchmarks/compare_lammps.py
units si
dimension 3
boundary s s s
atom_style peri
atom_modify map array
lattice sc {DX} origin 0.5 0.5 0.5
region box block 0 {n} 0 {n} 0 {n} units lattice
create_box 1 box
create_atoms 1 region box
pair_style peri/pmb
pair_coeff * * {micromodulus(delta)!r} {delta!r} {S0} 0.0
set group all density {RHO}
set group all volume {DX ** 3!r}
variable vx atom {RATE}*(x-{xc!r})
velocity all set v_vx 0.0 0.0 units box
neighbor {0.5 * DX} bin
fix 1 all nve
compute dmg all damage/atom
timestep {DT}
thermo 10
thermo_style custom step time ke pe
dump d all custom {steps} dump.final id x y z c_dmg
run {steps}
"""


def wrap(argv):
    """--wrap FILE -- cmd...: run cmd, write its peak RSS (kB) to FILE.<rank>."""
    out, cmd = argv[0], argv[2:]
    rc = subprocess.call(cmd)
    rank = os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK", "0"))
    with open(f"{out}.{rank}", "w") as f:
        f.write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
    return rc


def launch(ranks, cmd, cwd, rss_file, mpirun):
    full = [mpirun, "-n", str(ranks), "--allow-run-as-root", "--bind-to", "none", sys.executable,
            os.path.abspath(__file__), "--wrap", rss_file, "--"] + cmd
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    r = subprocess.run(full, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stdout[-3000:]}")
    rss = sum(int(open(os.path.join(cwd, f)).read()) for f in os.listdir(cwd) if f.startswith(rss_file + "."))
    for f in os.listdir(cwd):
        if f.startswith(rss_file + "."):
            os.remove(os.path.join(cwd, f))
    return r.stdout, rss * 1024.0


def run_peridrive(exe, n, steps, ranks, work, mpirun):
    scene = os.path.join(work, "block.yaml")
    with open(scene, "w") as f:
        f.write(peridrive_scene(n, steps))
    out = os.path.join(work, "pd")
    _, rss = launch(ranks, [exe, scene, "--out", out, "--quiet"], work, "rss", mpirun)
    s = json.load(open(os.path.join(out, "summary.json")))
    ke = {}
    with open(os.path.join(out, "series.csv")) as f:
        for row in csv.DictReader(f):
            ke[int(row["step"])] = float(row["kinetic_energy"])
    # Peak memory after each setup phase, summed over ranks (summary.json "memory"), bytes/bond.
    phases = " ".join(f"{m['phase']}:{m['peak_bytes'] / s['ordered_bonds']:.2f}" for m in s.get("memory", []))
    return dict(seconds=s["step_seconds"] / s["steps"], rss=rss, bonds=s["ordered_bonds"],
                broken=2 * s["broken_bonds"], ke=ke, nodes=s["nodes"], phases=phases,
                partition=f"{s.get('partition_method', '?')} cut {s.get('edge_cut', 0)} balance {s.get('partition_balance', 1):.4f} "
                          f"{s.get('partition_seconds', 0):.2f} s")


def neighbour_counts(n):
    """Ordered bonds of each lattice point (the same bond set in both codes), indexed like LAMMPS ids."""
    import numpy as np
    m = int(DELTA_FACTOR) + 1
    idx = np.arange(n)
    counts = np.zeros((n, n, n), dtype=np.int64)
    for a in range(-m, m + 1):
        for b in range(-m, m + 1):
            for c in range(-m, m + 1):
                if (a, b, c) == (0, 0, 0) or a * a + b * b + c * c > DELTA_FACTOR ** 2:
                    continue
                ok = [((idx + s) >= 0) & ((idx + s) < n) for s in (a, b, c)]
                counts += ok[2][:, None, None] & ok[1][None, :, None] & ok[0][None, None, :]
    return counts.reshape(-1)  # z slowest, x fastest: LAMMPS' id order for this lattice


def run_lammps(lmp, n, steps, ranks, work, mpirun):
    with open(os.path.join(work, "in.block"), "w") as f:
        f.write(lammps_input(n, steps))
    log, rss = launch(ranks, [lmp, "-in", "in.block", "-log", "log.lammps", "-screen", "none"], work, "rss", mpirun)
    text = open(os.path.join(work, "log.lammps")).read()
    loop = float(re.search(r"Loop time of ([0-9.eE+-]+) on", text).group(1))
    ke = {}
    for m in re.finditer(r"^\s+(\d+)\s+[0-9.eE+-]+\s+([0-9.eE+-]+)\s+[0-9.eE+-]+\s*$", text, re.M):
        ke[int(m.group(1))] = float(m.group(2)) * DX ** 3  # LAMMPS PERI: rmass = density
    # Broken ordered bonds from the final per-atom damage (uniform volumes: damage = broken/partners).
    lines = open(os.path.join(work, "dump.final")).read().split("ITEM: TIMESTEP")[-1].splitlines()
    start = next(k for k, l in enumerate(lines) if l.startswith("ITEM: ATOMS")) + 1
    dmg = {}
    for l in lines[start:]:
        p = l.split()
        dmg[int(p[0])] = float(p[4])
    counts = neighbour_counts(n)
    broken = sum(d * counts[i - 1] for i, d in dmg.items())
    return dict(seconds=loop / steps, rss=rss, ke=ke, broken=broken)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--wrap":
        return wrap(sys.argv[2:])
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 64], help="points per edge N (default 32 64)")
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2], help="MPI ranks (default 1 2)")
    ap.add_argument("--reps", type=int, default=3, help="repetitions of each A B pair (default 3)")
    ap.add_argument("--steps", type=int, default=50, help="time steps (default 50)")
    ap.add_argument("--quick", action="store_true", help="N = 20, 1 rank, 1 repetition")
    ap.add_argument("--peridrive", default=os.path.join(ROOT, "build", "peridrive"))
    ap.add_argument("--lmp", default=shutil.which("lmp") or shutil.which("lmp_serial"))
    ap.add_argument("--mpirun", default=shutil.which("mpirun") or "mpirun")
    ap.add_argument("--csv", help="also write the table as CSV")
    a = ap.parse_args()
    if a.quick:
        a.sizes, a.ranks, a.reps = [20], [1], 1
    if not os.path.exists(a.peridrive):
        sys.exit(f"{a.peridrive}: not found; build first (see README Quick start)")
    if not a.lmp:
        print("lmp (LAMMPS) not found: install it with `apt-get install -y lammps` (Debian) to compare;\n"
              "running peridrive alone.\n")
    rows = []
    for n in a.sizes:
        for ranks in a.ranks:
            pd, lm = [], []
            with tempfile.TemporaryDirectory() as work:
                for rep in range(a.reps):  # A B A B ...
                    pd.append(run_peridrive(a.peridrive, n, a.steps, ranks, work, a.mpirun))
                    if a.lmp:
                        lm.append(run_lammps(a.lmp, n, a.steps, ranks, work, a.mpirun))
                    print(f"  N={n} ranks={ranks} rep {rep + 1}/{a.reps}: peridrive {pd[-1]['seconds']:.4g} s/step"
                          + (f", LAMMPS {lm[-1]['seconds']:.4g} s/step" if lm else ""), flush=True)
            bonds = pd[0]["bonds"]
            med = lambda runs, k: statistics.median(r[k] for r in runs)
            row = dict(N=n, points=pd[0]["nodes"], ordered_bonds=bonds, ranks=ranks, steps=a.steps,
                       pd_s_per_step=med(pd, "seconds"), pd_rss_MB=med(pd, "rss") / 1e6)
            row["pd_updates_per_s_per_core"] = bonds / row["pd_s_per_step"] / ranks
            row["pd_bytes_per_bond"] = med(pd, "rss") / bonds
            row["pd_broken_ordered"] = pd[0]["broken"]
            row["pd_memory_phases"] = pd[0]["phases"]
            row["pd_partition"] = pd[0]["partition"]
            if lm:
                row["lmp_s_per_step"] = med(lm, "seconds")
                row["lmp_rss_MB"] = med(lm, "rss") / 1e6
                row["lmp_updates_per_s_per_core"] = bonds / row["lmp_s_per_step"] / ranks
                row["lmp_bytes_per_bond"] = med(lm, "rss") / bonds
                row["speedup"] = row["lmp_s_per_step"] / row["pd_s_per_step"]
                row["lmp_broken_ordered"] = lm[0]["broken"]
                kp, kl = pd[0]["ke"], lm[0]["ke"]
                common = sorted(set(kp) & set(kl))
                first_break = next((s for s in common if s > 0 and abs(kp[s] - kl[s]) > 1e-6 * kp[0]), None)
                before = [s for s in common if first_break is None or s < first_break]
                row["ke_rel_diff_before_breaking"] = max(abs(kp[s] - kl[s]) / kp[0] for s in before)
                row["ke_rel_diff_max"] = max(abs(kp[s] - kl[s]) / kp[0] for s in common)
                row["ke_history"] = " ".join(f"{s}:{kp[s]:.4g}/{kl[s]:.4g}" for s in common)
            rows.append(row)
    print("\n| N | points | ordered bonds | ranks | code | s/step (median) | bond updates/s/core | peak RSS [MB] | bytes/bond | LAMMPS/peridrive time |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['N']} | {r['points']} | {r['ordered_bonds']} | {r['ranks']} | peridrive | {r['pd_s_per_step']:.4g} | "
              f"{r['pd_updates_per_s_per_core']:.3g} | {r['pd_rss_MB']:.1f} | {r['pd_bytes_per_bond']:.1f} | |")
        if "lmp_s_per_step" in r:
            print(f"| | | | | LAMMPS | {r['lmp_s_per_step']:.4g} | {r['lmp_updates_per_s_per_core']:.3g} | "
                  f"{r['lmp_rss_MB']:.1f} | {r['lmp_bytes_per_bond']:.1f} | **{r['speedup']:.2f}** |")
    print("\nperidrive peak memory (summed over ranks) after each setup phase, bytes per ordered bond; partitioner:")
    for r in rows:
        print(f"  N={r['N']} ranks={r['ranks']}: {r['pd_memory_phases']}; {r['pd_partition']}")
    # Parallel efficiency t_1 / (P t_P) of the medians, for each size run on 1 rank and on more.
    lines = []
    for r in rows:
        one = next((o for o in rows if o["N"] == r["N"] and o["ranks"] == 1), None)
        if one is not None and r["ranks"] > 1:
            eff = [f"peridrive {one['pd_s_per_step'] / (r['ranks'] * r['pd_s_per_step']):.2f}"]
            if "lmp_s_per_step" in r and "lmp_s_per_step" in one:
                eff.append(f"LAMMPS {one['lmp_s_per_step'] / (r['ranks'] * r['lmp_s_per_step']):.2f}")
            lines.append(f"  N={r['N']} ({r['points']} points) on {r['ranks']} ranks: " + ", ".join(eff))
    if lines:
        print("\nParallel efficiency (1-rank median s/step over ranks x median s/step):")
        print("\n".join(lines))
    if any("lmp_s_per_step" in r for r in rows):
        print("\nPhysical cross-check (kinetic energy relative to its initial value; broken ordered bonds at the end):")
        for r in rows:
            if "lmp_s_per_step" not in r:
                continue
            print(f"  N={r['N']} ranks={r['ranks']}: KE difference before the first break {r['ke_rel_diff_before_breaking']:.1e} "
                  f"(tolerance 1e-6), largest over the run {r['ke_rel_diff_max']:.3f}; broken bonds peridrive "
                  f"{r['pd_broken_ordered']:.0f}, LAMMPS {r['lmp_broken_ordered']:.0f} "
                  f"(ratio {r['pd_broken_ordered'] / max(r['lmp_broken_ordered'], 1):.3f})")
            print(f"    KE history step:peridrive/LAMMPS [J]: {r['ke_history']}")
        print("  After bonds start to break the histories part: LAMMPS uses a bond's force in the step it\n"
              "  exceeds s0 and removes it from the next step on; peridrive removes it in that step (a one-step\n"
              "  lag in LAMMPS, first order in dt).")
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=sorted({k for r in rows for k in r}))
            w.writeheader()
            w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/python3
"""peridrive vs LAMMPS PERI (pair style peri/pmb) on the identical problem; prints figures only.

Problem: a free block of N^3 simple-cubic points, dx = 1 mm, delta = 3.015 dx, K = 14.9 GPa
(c = 18 K / (pi delta^4)), rho = 2200 kg/m^3, s0 = 0.0005 (no compressive enhancement, alpha = 0),
initial velocity v_x = 200 s^-1 (x - x_c), dt = 2e-7 s. Both codes weight the neighbours near the
horizon with LAMMPS' linear taper (peridrive: `quadrature: taper`), so the bond sets, micromodulus,
masses and integrator agree; the kinetic-energy histories match to round-off until bonds break.

What is timed: the time-step loop alone, thermodynamic rows every 10 steps included in both (LAMMPS
thermo, peridrive series.csv). LAMMPS: "Loop time" of a `run` with no dump in it; the per-atom
damage for the cross-check is written afterwards by a `run 0` with a dump, outside the timed run.
peridrive: summary.json step_seconds (the loop less its frame output; slowest rank) over
steps_timed. Setup is in neither.

Method (benchmarks/bench_common.py): every run is pinned, rank r to the r-th core of --cpus (the
wrapper sets the affinity before it starts the code, the same for both codes; the binding each rank
had is read back from /proc and printed); before each run the machine's cores (--load-scope run:
those the run will use) are watched for --load-window s and the run waits (up to --max-wait s)
while other processes use more than --load-threshold of a core, and is marked `loaded` if they
still do, or did during the run (their share = the cores' busy time less the run's own CPU time),
or the hypervisor stole as much. A round
runs each code on each rank count once; the order rotates from round to round (--order). The
LAMMPS/peridrive time ratio and the parallel efficiency t_1 / (P t_P) are formed within each round
(runs seconds apart) and reported as median [first quartile, third quartile] of the per-round
ratios; the s/step columns are the median [quartiles] of the runs. Figures over the rounds with no
loaded run follow when some were loaded.

  /usr/bin/python3 benchmarks/compare_lammps.py                 # N = 32 64, ranks 1 2, 5 rounds
  /usr/bin/python3 benchmarks/compare_lammps.py --sizes 32 64 100 --reps 7 --steps 50
  /usr/bin/python3 benchmarks/compare_lammps.py --quick         # N = 20, 1 round, ranks 1
Without `lmp` in PATH (Debian: apt-get install lammps) it runs peridrive alone.
"""
import argparse
import csv
import json
import math
import os
import re
import shutil
import sys
import tempfile

import bench_common as bc

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
run {steps}
# the cross-check's per-atom damage, outside the timed run above (its "Loop time" is the figure)
dump d all custom 1 dump.final id x y z c_dmg
run 0 post no
"""


def run_peridrive(exe, n, steps, ranks, work, mpirun, cpus):
    scene = os.path.join(work, "block.yaml")
    with open(scene, "w") as f:
        f.write(peridrive_scene(n, steps))
    out = os.path.join(work, "pd")
    _, rss, binding = bc.launch(ranks, [exe, scene, "--out", out, "--quiet"], work, mpirun, cpus)
    s = json.load(open(os.path.join(out, "summary.json")))
    ke = {}
    with open(os.path.join(out, "series.csv")) as f:
        for row in csv.DictReader(f):
            ke[int(row["step"])] = float(row["kinetic_energy"])
    # Peak memory after each setup phase, summed over ranks (summary.json "memory"), bytes/bond.
    phases = " ".join(f"{m['phase']}:{m['peak_bytes'] / s['ordered_bonds']:.2f}" for m in s.get("memory", []))
    return dict(seconds=s["step_seconds"] / s.get("steps_timed", s["steps"]), rss=rss, bonds=s["ordered_bonds"],
                broken=2 * s["broken_bonds"], ke=ke, nodes=s["nodes"], phases=phases, binding=binding,
                version=f"{s.get('git_revision', '?')} {s.get('bond_kernel', '')}".strip(),
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


def lammps_loop_time(text, steps):
    """Seconds of the `run` of `steps` steps in a LAMMPS log ("Loop time of T on P procs for S
    steps"), not those of the `run 0` after it."""
    for m in re.finditer(r"Loop time of ([0-9.eE+-]+) on \d+ procs for (\d+) steps", text):
        if int(m.group(2)) == steps:
            return float(m.group(1))
    raise ValueError(f"no 'Loop time' of a {steps}-step run in the log")


def run_lammps(lmp, n, steps, ranks, work, mpirun, cpus):
    with open(os.path.join(work, "in.block"), "w") as f:
        f.write(lammps_input(n, steps))
    _, rss, binding = bc.launch(ranks, [lmp, "-in", "in.block", "-log", "log.lammps", "-screen", "none"], work,
                                mpirun, cpus)
    text = open(os.path.join(work, "log.lammps")).read()
    loop = lammps_loop_time(text, steps)
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
    version = re.search(r"^LAMMPS \(([^)]*)\)", text, re.M)
    return dict(seconds=loop / steps, rss=rss, ke=ke, broken=broken, binding=binding,
                version=version.group(1) if version else "?")


PD, LMP = "peridrive", "LAMMPS"


def size_rows(n, steps, ranks_list, samples):
    """Rows of the table for one size from its samples (see bench_common.paired_ratios)."""
    rows = []
    quiet = [s for s in samples if not s["loaded"]]
    for ranks in ranks_list:
        pd = [s for s in samples if s["key"] == (PD, ranks)]
        lm = [s for s in samples if s["key"] == (LMP, ranks)]
        first = pd[0]["res"]
        bonds = first["bonds"]
        med = lambda runs, k: bc.quartiles([r["res"][k] for r in runs])[1]
        q1, m, q3 = bc.quartiles([s["seconds"] for s in pd])
        row = dict(N=n, points=first["nodes"], ordered_bonds=bonds, ranks=ranks, steps=steps,
                   pd_s_per_step=m, pd_s_q1=q1, pd_s_q3=q3, pd_rss_MB=med(pd, "rss") / 1e6,
                   runs=len(pd) + len(lm), loaded_runs=sum(s["loaded"] for s in pd + lm),
                   pd_binding=first["binding"], pd_version=first["version"])
        row["pd_updates_per_s_per_core"] = bonds / m / ranks
        row["pd_bytes_per_bond"] = med(pd, "rss") / bonds
        row["pd_broken_ordered"] = first["broken"]
        row["pd_memory_phases"] = first["phases"]
        row["pd_partition"] = first["partition"]
        if ranks > 1 and any(s["key"] == (PD, 1) for s in samples):
            for tag, code in (("pd", PD), ("lmp", LMP)):
                for sel, suffix in ((samples, ""), (quiet, "_quiet")):
                    eff = [v for _, v in bc.paired_ratios(sel, (code, 1), (code, ranks), scale=1.0 / ranks)]
                    if eff:
                        e1, em, e3 = bc.quartiles(eff)
                        row.update({f"{tag}_efficiency{suffix}": em, f"{tag}_efficiency{suffix}_q1": e1,
                                    f"{tag}_efficiency{suffix}_q3": e3, f"{tag}_efficiency{suffix}_pairs": len(eff)})
        if lm:
            l1, lmed, l3 = bc.quartiles([s["seconds"] for s in lm])
            lfirst = lm[0]["res"]
            row.update(lmp_s_per_step=lmed, lmp_s_q1=l1, lmp_s_q3=l3, lmp_rss_MB=med(lm, "rss") / 1e6,
                       lmp_binding=lfirst["binding"], lmp_version=lfirst["version"])
            row["lmp_updates_per_s_per_core"] = bonds / lmed / ranks
            row["lmp_bytes_per_bond"] = med(lm, "rss") / bonds
            for sel, suffix in ((samples, ""), (quiet, "_quiet")):
                ratio = [v for _, v in bc.paired_ratios(sel, (LMP, ranks), (PD, ranks))]
                if ratio:
                    r1, rm, r3 = bc.quartiles(ratio)
                    row.update({f"speedup{suffix}": rm, f"speedup{suffix}_q1": r1, f"speedup{suffix}_q3": r3,
                                f"speedup{suffix}_pairs": len(ratio)})
            row["lmp_broken_ordered"] = lfirst["broken"]
            kp, kl = first["ke"], lfirst["ke"]
            common = sorted(set(kp) & set(kl))
            first_break = next((s for s in common if s > 0 and abs(kp[s] - kl[s]) > 1e-6 * kp[0]), None)
            before = [s for s in common if first_break is None or s < first_break]
            row["ke_rel_diff_before_breaking"] = max(abs(kp[s] - kl[s]) / kp[0] for s in before)
            row["ke_rel_diff_max"] = max(abs(kp[s] - kl[s]) / kp[0] for s in common)
            row["ke_history"] = " ".join(f"{s}:{kp[s]:.4g}/{kl[s]:.4g}" for s in common)
        recs = [s["load"] for s in pd + lm]
        row["load"] = bc.load_summary(recs)
        rows.append(row)
    return rows


def stat_cell(r, key, spec=".3g"):
    """'median [q1, q3] (n)' of a row's paired statistic, '-' when absent."""
    if key not in r:
        return "-"
    return f"{r[key]:{spec}} [{r[key + '_q1']:{spec}}, {r[key + '_q3']:{spec}}] ({r[key + '_pairs']})"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 64], help="points per edge N (default 32 64)")
    ap.add_argument("--steps", type=int, default=50, help="time steps (default 50)")
    ap.add_argument("--quick", action="store_true", help="N = 20, 1 rank, 1 round")
    ap.add_argument("--peridrive", default=os.path.join(ROOT, "build", "peridrive"))
    ap.add_argument("--lmp", default=shutil.which("lmp") or shutil.which("lmp_serial"))
    ap.add_argument("--csv", help="also write the table as CSV")
    bc.add_common_options(ap, default_reps=5)
    a = ap.parse_args()
    if a.quick:
        a.sizes, a.ranks, a.reps = [20], [1], 1
    if not os.path.exists(a.peridrive):
        sys.exit(f"{a.peridrive}: not found; build first (see README Quick start)")
    if not a.lmp:
        print("lmp (LAMMPS) not found: install it with `apt-get install -y lammps` (Debian) to compare;\n"
              "running peridrive alone.\n")
    cpus = bc.run_cpus(a.cpus)
    if max(a.ranks) > len(cpus):
        sys.exit(f"{max(a.ranks)} ranks need as many cores to pin to; --cpus gives {cpus}")
    watch = bc.LoadWatch(a.load_threshold, a.load_window, a.max_wait, a.load_scope)
    rng = bc.new_rng(a.seed)
    codes = [PD, LMP] if a.lmp else [PD]
    print(f"machine: {bc.machine_description()}; cores {cpus} (rank r on the r-th); order {a.order}; "
          f"load threshold {a.load_threshold:.0%} of a core over {a.load_window:g} s ({a.load_scope} cores), "
          f"wait up to {a.max_wait:g} s")
    rows = []
    for n in a.sizes:
        samples = []
        with tempfile.TemporaryDirectory() as work:
            for k in range(a.reps):
                for code, ranks in bc.round_order(codes, a.ranks, k, a.order, rng):
                    if code == PD:
                        fn = lambda: run_peridrive(a.peridrive, n, a.steps, ranks, work, a.mpirun, cpus)
                    else:
                        fn = lambda: run_lammps(a.lmp, n, a.steps, ranks, work, a.mpirun, cpus)
                    res, rec = bc.measure_round(watch, cpus, ranks, fn)
                    samples.append(dict(round=k, key=(code, ranks), seconds=res["seconds"], res=res, load=rec,
                                        loaded=rec["loaded"]))
                    print(f"  N={n} round {k + 1}/{a.reps} {code:9s} {ranks} rank(s): {res['seconds']:.4g} s/step; "
                          f"pinned {res['binding']}; {bc.describe_load(rec)}", flush=True)
        rows += size_rows(n, a.steps, a.ranks, samples)
    versions = f"peridrive {rows[0]['pd_version']}" + (f", LAMMPS {rows[0]['lmp_version']}" if "lmp_version" in rows[0] else "")
    print(f"\n{versions}; {a.steps} steps; {a.reps} rounds; s/step: median [quartiles] of the runs; "
          "LAMMPS/peridrive: median [quartiles] (pairs) of the per-round ratios")
    print("\n| N | points | ordered bonds | ranks | code | s/step | bond updates/s/core | peak RSS [MB] | bytes/bond | LAMMPS/peridrive time |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['N']} | {r['points']} | {r['ordered_bonds']} | {r['ranks']} | peridrive | "
              f"{r['pd_s_per_step']:.4g} [{r['pd_s_q1']:.4g}, {r['pd_s_q3']:.4g}] | "
              f"{r['pd_updates_per_s_per_core']:.3g} | {r['pd_rss_MB']:.1f} | {r['pd_bytes_per_bond']:.1f} | |")
        if "lmp_s_per_step" in r:
            print(f"| | | | | LAMMPS | {r['lmp_s_per_step']:.4g} [{r['lmp_s_q1']:.4g}, {r['lmp_s_q3']:.4g}] | "
                  f"{r['lmp_updates_per_s_per_core']:.3g} | {r['lmp_rss_MB']:.1f} | {r['lmp_bytes_per_bond']:.1f} | "
                  f"**{stat_cell(r, 'speedup', '.2f')}** |")
    print("\nParallel efficiency t_1 / (P t_P), formed within each round: median [quartiles] (pairs)")
    for r in rows:
        if "pd_efficiency" in r:
            print(f"  N={r['N']} on {r['ranks']} ranks: peridrive {stat_cell(r, 'pd_efficiency', '.3f')}"
                  + (f", LAMMPS {stat_cell(r, 'lmp_efficiency', '.3f')}" if "lmp_efficiency" in r else ""))
    print("\nLoad and binding (per size and rank count, both codes' runs):")
    for r in rows:
        print(f"  N={r['N']} {r['ranks']} rank(s): pinned peridrive {r['pd_binding']}"
              + (f", LAMMPS {r['lmp_binding']}" if "lmp_binding" in r else "") + f"; {r['load']}")
    if any(r["loaded_runs"] for r in rows):
        print("\nWithout the rounds that had a loaded run (pairs whose two runs were both quiet):")
        for r in rows:
            line = [f"LAMMPS/peridrive {stat_cell(r, 'speedup_quiet', '.2f')}"] if "speedup" in r else []
            for tag, code in (("pd", "peridrive"), ("lmp", "LAMMPS")):
                if f"{tag}_efficiency" in r:
                    line.append(f"{code} efficiency {stat_cell(r, f'{tag}_efficiency_quiet', '.3f')}")
            if line:
                print(f"  N={r['N']} {r['ranks']} rank(s): " + "; ".join(line))
    print("\nperidrive peak memory (summed over ranks) after each setup phase, bytes per ordered bond; partitioner:")
    for r in rows:
        print(f"  N={r['N']} ranks={r['ranks']}: {r['pd_memory_phases']}; {r['pd_partition']}")
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
        bc.write_csv(a.csv, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/python3
"""peridrive vs CabanaPD (ORNL, Kokkos/Cabana) on CabanaPD's CrackBranching example; prints figures only.

Problem (CabanaPD examples/mechanics/inputs/crack_branching.json and crack_branching.cpp, read for
their parameters): a glass plate of 400 x 160 x 8 cells of 0.25 mm (0.1 x 0.04 x 0.002 m, centred
at the origin, one point at each cell centre), PMB, rho = 2440 kg/m^3, E = 72 GPa with nu = 1/4
(K = E / (3 (1 - 2 nu)) = 48 GPa), G0 = 3.8 J/m^2, horizon 1 mm (4 dx; CabanaPD adds 1e-10 m),
c = 18 K / (pi delta^4), s0 = sqrt(5 G0 / (9 K delta)), a pre-notch in the plane y = 0 from the
left face to x = 0 through the thickness, dt = 4.5e-8 s. Both codes take every neighbour cell whose
centre lies within the horizon at full weight (peridrive `quadrature: full`, `horizon_factor: 4`):
the same 256 neighbours in the bulk, the same ordered bonds in all (printed: CabanaPD's "Total
neighbors", peridrive's ordered_bonds and the count of the lattice).
Where the scenes differ (peridrive has no traction loads, no no-fail zones, and its pre-cracks cut
membrane bonds only): CabanaPD pulls the top and bottom rows apart with a traction of 2 MPa (a body
force sigma/dy on one row) and keeps three rows at each edge from breaking; peridrive's scene moves
the same rows apart at sigma / (rho c_l) (the particle velocity of the wave that traction
launches) and has no notch. CabanaPD keeps the notch's bonds (0.47% of all at 400 x 160 x 8,
printed) in its neighbour lists, flagged broken, and still visits them each step. The per-step
work is otherwise the same (every bond evaluated every step; at 2 MPa no bond near the edges nears
s0); the fields differ, and no physical cross-check is made.

Timed: the step loop only. CabanaPD: from its output file (cabanaPD.out) the cumulative time
between its two timing rows (steps/2 and steps) less the energy and particle-output time in
between, over steps/2 steps (its first half and setup excluded; the stress pass of an output step,
if its build outputs stress, stays in). peridrive: summary.json step_seconds over steps_timed
(its series rows, every steps/2 steps, included). Ranks pinned, machine load checked before and
during each run, runs alternated in rotating order, ratios and efficiencies formed within each
round and reported as median [quartiles]: see benchmarks/bench_common.py and compare_lammps.py.

CabanaPD is looked for in $CABANAPD_EXE, then `CrackBranching` on PATH (--cabanapd overrides); it
should be a CPU build (Kokkos Serial or OpenMP: OMP_NUM_THREADS=1 and KOKKOS_NUM_THREADS=1 are set,
one thread per rank). Without it the script says so in one line and runs peridrive alone (its
s/step and parallel efficiency), exit status 0.

  /usr/bin/python3 benchmarks/compare_cabanapd.py                  # 400 x 160 x 8, 100 steps, ranks 1 2, 5 rounds
  CABANAPD_EXE=~/CabanaPD/build/examples/mechanics/CrackBranching /usr/bin/python3 benchmarks/compare_cabanapd.py
  /usr/bin/python3 benchmarks/compare_cabanapd.py --cells 200 80 8 --steps 40 --reps 3
  /usr/bin/python3 benchmarks/compare_cabanapd.py --quick          # 100 x 40 x 8, 20 steps, 1 round
"""
import argparse
import json
import math
import os
import shutil
import sys
import tempfile

import bench_common as bc

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

DX = 0.00025                      # 0.1 m / 400 cells (the same in y and z)
RHO, E, NU, G0 = 2440.0, 72e9, 0.25, 3.8
K = E / (3 * (1 - 2 * NU))
M = 4                             # horizon / dx
HORIZON = M * DX + 1e-10          # CabanaPD's horizon (its example adds 1e-10 m)
SIGMA, DT = 2e6, 4.5e-8
PD, CPD = "peridrive", "CabanaPD"


def micromodulus():
    return 18.0 * K / (math.pi * HORIZON ** 4)


def critical_stretch():
    return math.sqrt(5.0 * G0 / (9.0 * K * HORIZON))


def edge_velocity():
    """sigma / (rho c_l): the particle velocity behind a longitudinal wave of stress sigma."""
    c_l = math.sqrt(E * (1 - NU) / ((1 + NU) * (1 - 2 * NU) * RHO))
    return SIGMA / (RHO * c_l)


def lattice_bonds(cells, m=M):
    """Ordered bonds of a cell-centred box of cells[0] x cells[1] x cells[2] points whose offsets
    (a, b, c) in spacings satisfy a^2 + b^2 + c^2 <= m^2 (full quadrature), and per bulk point."""
    total = per = 0
    for a in range(-m, m + 1):
        for b in range(-m, m + 1):
            for c in range(-m, m + 1):
                if (a, b, c) == (0, 0, 0) or a * a + b * b + c * c > m * m:
                    continue
                per += 1
                total += max(cells[0] - abs(a), 0) * max(cells[1] - abs(b), 0) * max(cells[2] - abs(c), 0)
    return total, per


def notch_bonds(cells, m=M):
    """Ordered bonds that cross CabanaPD's pre-notch (the plane y = 0 for x <= 0, through the
    thickness; a crossing at x = 0 counts). In half spacings a point sits at x = 2i + 1 - nx,
    y = 2j + 1 - ny; a bond from y < 0 up by b > 0 rows and over by a columns meets y = 0 at
    x - a y / b, which is <= 0 when b x - a y <= 0: exact integer arithmetic."""
    nx, ny, nz = cells
    count = 0
    for a in range(-m, m + 1):
        for b in range(1, m + 1):
            for c in range(-m, m + 1):
                if a * a + b * b + c * c > m * m or nz - abs(c) <= 0:
                    continue
                for j in range(max(0, ny // 2 - b), min(ny - b, ny)):
                    y = 2 * j + 1 - ny
                    if not (y < 0 < y + 2 * b):
                        continue
                    i0, i1 = max(0, -a), min(nx, nx - a)   # both ends inside: i and i + a
                    # b (2i + 1 - nx) - a y <= 0  <=>  i <= (a y / b + nx - 1) / 2
                    hi = math.floor((a * y / b + nx - 1) / 2 + 1e-12)
                    count += max(0, min(i1 - 1, hi) - i0 + 1) * (nz - abs(c))
    return 2 * count


def cabanapd_input(cells, steps):
    """CabanaPD's crack_branching.json with the plate's cells, the run's length (final_time gives
    floor(final_time / dt) steps: half a step over) and two timing rows (steps/2 and steps)."""
    size = [n * DX for n in cells]
    return json.dumps({
        "num_cells": {"value": list(cells)},
        "system_size": {"value": size, "unit": "m"},
        "density": {"value": RHO, "unit": "kg/m^3"},
        "elastic_modulus": {"value": E, "unit": "Pa"},
        "fracture_energy": {"value": G0, "unit": "J/m^2"},
        "horizon": {"value": M * DX, "unit": "m"},
        "traction": {"value": SIGMA, "unit": "Pa"},
        "final_time": {"value": (steps + 0.5) * DT, "unit": "s"},
        "timestep": {"value": DT, "unit": "s"},
        "timestep_safety_factor": {"value": 0.85},
        "output_frequency": {"value": steps // 2},
        "output_reference": {"value": True},
    }, indent=2) + "\n"


def peridrive_scene(cells, steps):
    lx, ly, lz = (n * DX for n in cells)
    v = edge_velocity()
    row = lambda y0, y1: f"{{min: [{-lx!r}, {y0!r}, {-lz!r}], max: [{lx!r}, {y1!r}, {lz!r}]}}"
    return f"""name: cabanapd-crack-branching
description: CabanaPD's CrackBranching plate (benchmarks/compare_cabanapd.py), rows moved at sigma/(rho c_l), no notch
materials:
  glass: {{model: pmb, density: {RHO}, micromodulus: {micromodulus()!r}, critical_stretch: {critical_stretch()!r}}}
bodies:
  plate: {{kind: solid, material: glass, origin: [{-lx / 2!r}, {-ly / 2!r}, {-lz / 2!r}], size: [{lx!r}, {ly!r}, {lz!r}], spacing: {DX}, horizon_factor: {M}, quadrature: full}}
boundaries:
  - {{name: bottom, region: {row(-ly / 2 - DX, -ly / 2 + DX)}, velocity: [0, {-v!r}, 0], components: [y]}}
  - {{name: top, region: {row(ly / 2 - DX, ly / 2 + DX)}, velocity: [0, {v!r}, 0], components: [y]}}
stages:
  - {{name: load, steps: {steps}, dt: {DT}}}
output: {{frames: 1, series_every: {steps // 2}, velocity: false}}
"""


def parse_cabanapd_out(text):
    """CabanaPD's output file: dict(particles, total_neighbors, init_seconds, columns, rows) where
    rows are dicts keyed by the header's column names (plus 'step')."""
    out = dict(particles=None, total_neighbors=None, init_seconds=None, columns=None, rows=[])
    lines = text.splitlines()
    for i, line in enumerate(lines):
        s = line.strip()
        if s.startswith("Local particles, Ghosted particles, Global particles") and i + 1 < len(lines):
            out["particles"] = int(lines[i + 1].split(",")[-1])
        elif "Total neighbors:" in s:
            out["total_neighbors"] = int(s.split("Total neighbors:")[1].split()[0].strip(","))
        elif s.startswith("Init-Time(s):"):
            out["init_seconds"] = float(s.split(":", 1)[1])
        elif s.startswith("#Timestep/Total-steps"):
            out["columns"] = s.split()
        elif out["columns"] and s and s[0].isdigit() and "/" in s.split()[0]:
            p = s.split()
            if len(p) != len(out["columns"]):
                continue
            row = {c: float(v) for c, v in zip(out["columns"][1:], p[1:])}
            row["step"] = int(p[0].split("/")[0])
            out["rows"].append(row)
    return out


def cabanapd_loop_seconds(parsed):
    """(seconds per step, steps) between the first and the last timing row: the difference of
    Cumulative-Time less those of Energy-Time and Output-Time (columns absent count as 0)."""
    rows = parsed["rows"]
    if len(rows) < 2:
        raise ValueError("CabanaPD's output holds fewer than two timing rows")
    a, b = rows[0], rows[-1]
    d = lambda key: b.get(key, 0.0) - a.get(key, 0.0)
    steps = b["step"] - a["step"]
    return (d("Cumulative-Time(s)") - d("Energy-Time(s)") - d("Output-Time(s)")) / steps, steps


def run_peridrive(exe, cells, steps, ranks, work, mpirun, cpus):
    scene = os.path.join(work, "plate.yaml")
    with open(scene, "w") as f:
        f.write(peridrive_scene(cells, steps))
    out = os.path.join(work, "pd")
    _, rss, binding = bc.launch(ranks, [exe, scene, "--out", out, "--quiet"], work, mpirun, cpus)
    s = json.load(open(os.path.join(out, "summary.json")))
    return dict(seconds=s["step_seconds"] / s.get("steps_timed", s["steps"]), rss=rss, bonds=s["ordered_bonds"],
                broken=s.get("broken_bonds", 0), nodes=s["nodes"],
                binding=binding, version=f"{s.get('git_revision', '?')} {s.get('bond_kernel', '')}".strip())


def run_cabanapd(exe, cells, steps, ranks, work, mpirun, cpus, extra):
    sub = os.path.join(work, "cpd")
    shutil.rmtree(sub, ignore_errors=True)
    os.makedirs(sub)
    with open(os.path.join(sub, "crack_branching.json"), "w") as f:
        f.write(cabanapd_input(cells, steps))
    _, rss, binding = bc.launch(ranks, [exe, "crack_branching.json"] + extra, sub, mpirun, cpus,
                                env_extra=dict(KOKKOS_NUM_THREADS="1"))
    parsed = parse_cabanapd_out(open(os.path.join(sub, "cabanaPD.out")).read())
    seconds, timed = cabanapd_loop_seconds(parsed)
    return dict(seconds=seconds, steps_timed=timed, rss=rss, bonds=parsed["total_neighbors"],
                nodes=parsed["particles"], binding=binding)


def find_cabanapd(arg):
    for c in (arg, os.environ.get("CABANAPD_EXE"), shutil.which("CrackBranching")):
        if c and os.path.isfile(c) and os.access(c, os.X_OK):
            return c
    return None


def stat(xs, spec):
    return bc.fmt_stat(xs, spec) + (f" ({len(xs)})" if len(xs) > 1 else "")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cells", type=int, nargs=3, default=[400, 160, 8], metavar=("NX", "NY", "NZ"),
                    help="cells of 0.25 mm along x, y, z (default CabanaPD's 400 160 8)")
    ap.add_argument("--steps", type=int, default=100, help="time steps, even (default 100)")
    ap.add_argument("--quick", action="store_true", help="100 x 40 x 8 cells, 20 steps, 1 round")
    ap.add_argument("--peridrive", default=os.path.join(ROOT, "build", "peridrive"))
    ap.add_argument("--cabanapd", help="CrackBranching executable (default $CABANAPD_EXE, then PATH)")
    ap.add_argument("--cabanapd-args", nargs="*", default=[], help="more arguments for CrackBranching")
    ap.add_argument("--csv", help="also write the table as CSV")
    bc.add_common_options(ap, default_reps=5)
    a = ap.parse_args()
    if a.quick:
        a.cells, a.steps, a.reps = [100, 40, 8], 20, 1
    if a.steps < 2 or a.steps % 2:
        sys.exit("--steps must be even and at least 2 (CabanaPD's timing rows at steps/2 and steps)")
    if not os.path.exists(a.peridrive):
        sys.exit(f"{a.peridrive}: not found; build first (see README Quick start)")
    exe = find_cabanapd(a.cabanapd)
    if not exe:
        print("CabanaPD not found (set CABANAPD_EXE or put CrackBranching on PATH): comparison skipped, peridrive alone.")
    cpus = bc.run_cpus(a.cpus)
    if max(a.ranks) > len(cpus):
        sys.exit(f"{max(a.ranks)} ranks need as many cores to pin to; --cpus gives {cpus}")
    watch = bc.LoadWatch(a.load_threshold, a.load_window, a.max_wait, a.load_scope)
    rng = bc.new_rng(a.seed)
    codes = [PD, CPD] if exe else [PD]
    cells = tuple(a.cells)
    expect, per = lattice_bonds(cells)
    print(f"machine: {bc.machine_description()}; cores {cpus} (rank r on the r-th); order {a.order}; "
          f"load threshold {a.load_threshold:.0%} of a core over {a.load_window:g} s ({a.load_scope} cores), "
          f"wait up to {a.max_wait:g} s")
    print(f"plate {cells[0]} x {cells[1]} x {cells[2]} cells ({cells[0] * cells[1] * cells[2]} points), "
          f"{per} neighbours in the bulk, {expect} ordered bonds on the lattice; c = {micromodulus():.6g}, "
          f"s0 = {critical_stretch():.6g}; {a.steps} steps of {DT:g} s")
    samples = []
    with tempfile.TemporaryDirectory() as work:
        for k in range(a.reps):
            for code, ranks in bc.round_order(codes, a.ranks, k, a.order, rng):
                if code == PD:
                    fn = lambda: run_peridrive(a.peridrive, cells, a.steps, ranks, work, a.mpirun, cpus)
                else:
                    fn = lambda: run_cabanapd(exe, cells, a.steps, ranks, work, a.mpirun, cpus, a.cabanapd_args)
                res, rec = bc.measure_round(watch, cpus, ranks, fn)
                samples.append(dict(round=k, key=(code, ranks), seconds=res["seconds"], res=res, load=rec,
                                    loaded=rec["loaded"]))
                print(f"  round {k + 1}/{a.reps} {code:9s} {ranks} rank(s): {res['seconds']:.4g} s/step; "
                      f"pinned {res['binding']}; {bc.describe_load(rec)}", flush=True)
    pd0 = next(s["res"] for s in samples if s["key"][0] == PD)
    line = f"\nordered bonds: lattice {expect}, peridrive {pd0['bonds']}"
    cp = [s for s in samples if s["key"][0] == CPD]
    if cp:
        line += f", CabanaPD {cp[0]['res']['bonds']} (its 'Total neighbors')"
        same = cp[0]["res"]["bonds"] == pd0["bonds"]
        line += ": the same" if same else ": DIFFERENT (the ratios below compare unequal work)"
    notch = notch_bonds(cells)
    line += (f"\n  CabanaPD's pre-notch marks {notch} of them broken ({notch / expect:.2%}; they stay in its neighbour"
             f" lists); peridrive's pre-cracks cut no solid's bonds, so its plate has no notch")
    print(line + f"; peridrive {pd0['version']}")
    rows = []
    quiet = [s for s in samples if not s["loaded"]]
    print("\n| ranks | code | s/step median [quartiles] | bond updates/s/core | peak RSS [MB] | CabanaPD/peridrive time (paired) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for ranks in a.ranks:
        row = dict(cells="x".join(map(str, cells)), points=pd0["nodes"], ordered_bonds=pd0["bonds"],
                   lattice_bonds=expect, ranks=ranks, steps=a.steps)
        for code, tag in ((PD, "pd"), (CPD, "cpd")):
            runs = [s for s in samples if s["key"] == (code, ranks)]
            if not runs:
                continue
            q1, m, q3 = bc.quartiles([s["seconds"] for s in runs])
            rss = bc.quartiles([s["res"]["rss"] for s in runs])[1]
            row.update({f"{tag}_s_per_step": m, f"{tag}_s_q1": q1, f"{tag}_s_q3": q3, f"{tag}_rss_MB": rss / 1e6,
                        f"{tag}_updates_per_s_per_core": pd0["bonds"] / m / ranks, f"{tag}_binding": runs[0]["res"]["binding"]})
            ratio = ""
            if code == CPD:
                r = [v for _, v in bc.paired_ratios(samples, (CPD, ranks), (PD, ranks))]
                rq = [v for _, v in bc.paired_ratios(quiet, (CPD, ranks), (PD, ranks))]
                if r:
                    q = bc.quartiles(r)
                    row.update(speedup=q[1], speedup_q1=q[0], speedup_q3=q[2], speedup_pairs=len(r))
                    ratio = f"**{stat(r, '.2f')}**" + (f"; quiet pairs {stat(rq, '.2f')}" if len(rq) != len(r) else "")
            print(f"| {ranks} | {code} | {m:.4g} [{q1:.4g}, {q3:.4g}] | {pd0['bonds'] / m / ranks:.3g} | {rss / 1e6:.1f} | {ratio} |")
        row["load"] = bc.load_summary([s["load"] for s in samples if s["key"][1] == ranks])
        rows.append(row)
    print("\nParallel efficiency t_1 / (P t_P), formed within each round: median [quartiles] (pairs)")
    for row in rows:
        ranks = row["ranks"]
        if ranks == 1 or 1 not in a.ranks:
            continue
        parts = []
        for code, tag in ((PD, "pd"), (CPD, "cpd")):
            eff = [v for _, v in bc.paired_ratios(samples, (code, 1), (code, ranks), scale=1.0 / ranks)]
            effq = [v for _, v in bc.paired_ratios(quiet, (code, 1), (code, ranks), scale=1.0 / ranks)]
            if eff:
                q = bc.quartiles(eff)
                row.update({f"{tag}_efficiency": q[1], f"{tag}_efficiency_q1": q[0], f"{tag}_efficiency_q3": q[2],
                            f"{tag}_efficiency_pairs": len(eff)})
                parts.append(f"{code} {stat(eff, '.3f')}" + (f" (quiet pairs {stat(effq, '.3f')})" if len(effq) != len(eff) else ""))
        print(f"  {ranks} ranks: " + ", ".join(parts))
    print("\nLoad and binding:")
    for row in rows:
        print(f"  {row['ranks']} rank(s): pinned peridrive {row.get('pd_binding', '-')}"
              + (f", CabanaPD {row['cpd_binding']}" if "cpd_binding" in row else "") + f"; {row['load']}")
    if a.csv:
        bc.write_csv(a.csv, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())

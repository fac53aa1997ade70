#!/usr/bin/env python3
"""Rank invariance: the same scene on 1 rank and on several (3, 4 and 8 by default) gives the same
positions, velocities and damage in every frame, bit for bit, and a run resumed from a
checkpoint on another number of ranks gives the same final frame as the run that was not
stopped.

The design promises this: each row sums its bonds in CSR order whatever the partition, every
rank evaluates a bond crossing a cut with the same operations, and frames are written in the
natural node order. Energies in series.csv are sums over ranks (MPI_Allreduce), so their last
bits may differ; they are not compared, and every other column of series.csv is (crack tips,
broken bonds, tools' positions, velocities and forces). Each case is a scene of drivers/scenes/ reduced with --set
(or a small inline scene), sized to run in a few seconds even on ranks that share two cores
(--oversubscribe).

usage: rank_invariance.py PERIDRIVE SCENES_DIR MPIRUN [--mpi-flag=FLAG ...] [--ranks 3 4 8]
                          [--cases NAME ...] [--keep DIR]
"""
import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np

# A free PMB block, expanding and fragmenting: 3D cuts, 8-way corners at 8 ranks.
BLOCK = """name: block
materials:
  glass: {model: pmb, density: 2200, micromodulus: 1.0e19, critical_stretch: 0.0005}
bodies:
  block: {kind: solid, material: glass, origin: [0, 0, 0], size: [0.014, 0.014, 0.014], spacing: 0.001,
          horizon: 0.003015, quadrature: taper}
initial:
  velocity_gradient: [[2000, 0, 0], [0, -500, 0], [0, 0, 0]]
  center: [0.007, 0.007, 0.007]
stages:
  - {name: expand, steps: 120, dt: 2.0e-8}
output: {frames: 3, series_every: 20}
"""

# Eight straight fibers along y, 15 nm apart in x, drawn together (v_x = -1.2e10/s (x - 52.5 nm)):
# farther apart at the start than the long-range reach + skin (6 + 1.5 nm), so on several ranks
# no fiber of one rank is in another's halo; by the end the gaps are 4.2 nm and the pairs act
# across ranks. Only halos rebuilt as the fibers move see them (32 rebuilds in 62 steps).
FIBERS = """name: fiber-halo
materials:
  polymer: {model: pmb, density: 1200, youngs_modulus: 1.5e9, critical_stretch: 0.3}
bodies:
""" + "".join(f"  f{k}: {{kind: fiber, material: polymer, path: [[{15 * k}.0e-9, 0, 0], [{15 * k}.0e-9, 40.0e-9, 0]], "
              "diameter: 2.0e-9, spacing: 1.0e-9, horizon_factor: 3}\n" for k in range(8)) + """long_range:
  length: 2.0e-9
  cutoff: 6.0e-9
  pairs:
    - {between: other_fibers, alpha: 1.0e31, beta: 2.0e31}
initial:
  velocity_gradient: [[-1.2e10, 0, 0], [0, 0, 0], [0, 0, 0]]
  center: [52.5e-9, 20.0e-9, 0]
stages:
  - {name: close, duration: 6.0e-11}
output: {frames: 3}
"""

# The block with a tilted 12-corner penny cut at the start (a polygon crack: its fan searched by
# angle, Crack::fan_low), pulled apart across it.
PENNY = BLOCK.replace("initial:\n  velocity_gradient: [[2000, 0, 0], [0, -500, 0], [0, 0, 0]]",
                      "cracks:\n  - {name: penny, polygon: [" + ", ".join(
                          f"[{0.007 + 0.0045 * np.cos(k * np.pi / 6):.12f}, {0.007 + 0.0045 * np.sin(k * np.pi / 6):.12f}, "
                          f"{0.0072 + 0.0008 * np.cos(k * np.pi / 6):.12f}]" for k in range(12)) + "]}\n"
                      "initial:\n  velocity_gradient: [[0, 0, 0], [0, 0, 0], [0, 0, 300]]")
assert PENNY != BLOCK

# Each case: scene (file in SCENES_DIR or inline text), --set overrides, what must happen in it.
CASES = {
    # A slit membrane pulled apart: the crack runs across rank boundaries.
    "membrane_slit": ("slit_membrane.yaml",
                      ["bodies.sheet.spacing=0.0003", "stages.pull.duration=8.0e-5", "output.frames=3"]),
    "pmb_block": (BLOCK, []),
    "penny_block": (PENNY, []),
    # A curved mesh membrane (Gmsh triangles, free rows) under the follower pressure, clamped by
    # physical groups, with a polygon flaw in one wall that runs as the pressure rises.
    "mesh_tube_flaw": ("tube_flaw.yaml", ["stages.open.duration=3.0e-4", "output.frames=3"]),
    # Marder's lattice (two- and three-body terms, Kelvin dashpots), the crack running.
    "lattice": ("supersonic_rubber_broad_switch.yaml",
                ["bodies.strip.size=[0.05, 0.04330127]", "stages.run.duration=2.0e-4", "output.frames=3",
                 "cracks.seed.to=[0.015, 0, 0]"]),
    # Fibers with long-range pairs between fibers (the pair sums over every rank's nodes).
    "fiber_network": ("fiber_network.yaml",  # (too short for bonds to break: the pairs are the point)
                      ["bodies.net.network.families=[{direction: x, count: 6}, {direction: y, count: 6}]",
                       "stages.stretch.duration=6.0e-10", "output.frames=3"]),
    # Fibers that come within the long-range cutoff of other ranks' fibers only after moving:
    # the long-range halo must follow them.
    "fiber_halo": (FIBERS, []),
    # A rigid tool with contact and friction cutting a clamped, notched sheet.
    "tool": ("blunt_tool.yaml",
             ["bodies.sheet.spacing=0.0005", "stages.push.duration=4.0e-3", "output.frames=3"]),
    # The tool as a free rigid body (2.5 times the sheet's mass, 3 m/s): its reaction is summed in
    # natural order, so its motion and the sheet's are the same bits on any number of ranks.
    "free_tool": ("blunt_tool.yaml",
                  ["bodies.sheet.spacing=0.0005", "stages.push.duration=4.0e-3", "output.frames=3",
                   "tools.rod.mass=0.0005", "tools.rod.velocity=[3, 0]"]),
    # The same with the incremental crack-tip advance (tip_advance: break times, tips and
    # permissions exchanged with the ghosts; break times in the checkpoint).
    "tool_tip_advance": ("blunt_tool.yaml",
                         ["bodies.sheet.spacing=0.0005", "stages.push.duration=4.0e-3", "output.frames=3",
                          "materials.film.tip_advance=0.0005"]),
    # One tip for the whole body (tip_advance_tips: body): its latest break time reduced over ranks.
    "tool_one_tip": ("blunt_tool.yaml",
                     ["bodies.sheet.spacing=0.0005", "stages.push.duration=4.0e-3", "output.frames=3",
                      "materials.film.tip_advance=0.0005", "materials.film.tip_advance_tips=body"]),
}
FIELDS = ("position", "velocity", "damage")
UNBROKEN = {"fiber_network", "fiber_halo"}  # cases about pairs, too short for bonds to break


def scene_file(case, scenes_dir, work):
    scene, _ = CASES[case]
    if scene.endswith(".yaml"):
        return os.path.join(scenes_dir, scene)
    path = os.path.join(work, case + ".yaml")
    with open(path, "w") as f:
        f.write(scene)
    return path


def run(args, ranks, scene, out, extra=()):
    cmd = [args.mpirun, "-n", str(ranks), "--oversubscribe", *args.mpi_flags, args.peridrive]
    cmd += ([scene] if scene else []) + ["--quiet", "--out", out, *extra]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"rank_invariance: {' '.join(cmd)} exited {r.returncode}:\n{r.stderr[-2000:]}")


def stop_after_checkpoint(args, ranks, scene, out, extra):
    """Starts the run, sends SIGTERM once its first checkpoint is written, waits for the final
    checkpoint (exit status 5); returns the checkpoint's step."""
    cmd = [args.mpirun, "-n", str(ranks), "--oversubscribe", *args.mpi_flags, args.peridrive, scene, "--quiet",
           "--out", out, *extra]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    ckpt = os.path.join(out, "checkpoint.h5")
    deadline = time.monotonic() + 120
    while not os.path.exists(ckpt) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    # SIGTERM to one rank (a child of mpirun): every rank writes a final checkpoint and stops.
    ranks_pids = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    if not ranks_pids:
        sys.exit(f"rank_invariance: no rank of {' '.join(cmd)} found to stop")
    os.kill(int(ranks_pids[0]), signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    if proc.returncode != 5:
        sys.exit(f"rank_invariance: {' '.join(cmd)}: expected exit status 5 after SIGTERM, got "
                 f"{proc.returncode} (the run may have ended first):\n{err[-2000:]}")
    with h5py.File(ckpt, "r") as f:
        return int(f.attrs["step"])


def frames(out):
    """{step: {field: array}} of a run's frames.h5."""
    with h5py.File(os.path.join(out, "frames.h5"), "r") as f:
        return {int(g.attrs["step"]): {field: g[field][()] for field in FIELDS if field in g}
                for g in (f["frames"][name] for name in f["frames"])}


# series.csv columns that are sums over ranks (the energies) and may differ in their last bits.
ENERGY_COLUMNS = {"kinetic_energy", "strain_energy", "external_work", "dissipated_energy", "total_energy"}


def compare_series(a, b, what):
    """Differences between two runs' series.csv in every column but the energies (crack tips,
    broken bonds, tools' positions, velocities and forces), as printed."""
    rows = []
    for d in (a, b):
        with open(os.path.join(d, "series.csv")) as f:
            rows.append([line.rstrip("\n").split(",") for line in f])
    head = rows[0][0]
    if rows[1][0] != head or len(rows[0]) != len(rows[1]):
        return [f"{what}: series.csv has other columns or another number of rows"]
    for r, (x, y) in enumerate(zip(rows[0][1:], rows[1][1:]), start=1):
        for name, u, v in zip(head, x, y):
            if name not in ENERGY_COLUMNS and u != v:
                return [f"{what}: series.csv row {r} (step {x[0]}) column {name}: {u} vs {v}"]
    return []


def compare(a, b, what):
    """Differences between two runs' frames (frames in both; the counts must agree too)."""
    problems = []
    if sorted(a) != sorted(b):
        problems.append(f"{what}: frames at steps {sorted(a)} vs {sorted(b)}")
    for name in sorted(set(a) & set(b)):
        for field in FIELDS:
            if field not in a[name] or field not in b[name]:
                continue
            x, y = a[name][field], b[name][field]
            if x.shape != y.shape or x.tobytes() != y.tobytes():
                d = float(np.max(np.abs(x - y))) if x.shape == y.shape else float("nan")
                problems.append(f"{what}: step {name} {field} differs (max |diff| {d:.3g})")
    return problems


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("peridrive")
    p.add_argument("scenes_dir")
    p.add_argument("mpirun")
    p.add_argument("--mpi-flag", dest="mpi_flags", action="append", default=[],
                   help="a flag for mpirun (e.g. --mpi-flag=--allow-run-as-root); repeatable")
    p.add_argument("--ranks", type=int, nargs="+", default=[3, 4, 8])
    p.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    p.add_argument("--resume", nargs=2, type=int, action="append", metavar=("FROM", "TO"),
                   help="also resume a checkpoint written on FROM ranks on TO ranks (default: 4 3 and 2 8)")
    p.add_argument("--keep", help="keep the runs in this directory")
    args = p.parse_args()
    resumes = args.resume or [(4, 3), (2, 8)]
    work = args.keep or tempfile.mkdtemp(prefix="rank_invariance.")
    os.makedirs(work, exist_ok=True)
    problems = []
    try:
        for case in args.cases:
            scene = scene_file(case, args.scenes_dir, work)
            sets = [x for s in CASES[case][1] for x in ("--set", s)] + ["--set", "output.checkpoint_every_seconds=0"]
            one = os.path.join(work, f"{case}.np1")
            run(args, 1, scene, one, sets)
            reference = frames(one)
            last = sorted(reference)[-1]
            damaged = int(np.count_nonzero(reference[last]["damage"] > 0))
            moved = float(np.max(np.abs(reference[last]["position"] - reference[sorted(reference)[0]]["position"])))
            print(f"{case}: {len(reference[last]['damage'])} nodes, {len(reference)} frames, "
                  f"{damaged} damaged nodes and largest motion {moved:.3g} m at the end")
            if damaged == 0 and case not in UNBROKEN:
                problems.append(f"{case}: no node is damaged at the end: the case does not test breaking bonds")
            if case == "fiber_halo":  # the fibers must have come within the cutoff (6 nm)
                x = np.sort(np.unique(reference[last]["position"][:, 0]))
                first = np.sort(np.unique(reference[sorted(reference)[0]]["position"][:, 0]))
                if not (np.min(np.diff(first)) > 7.5e-9 and np.max(np.diff(x)) < 6.0e-9):
                    problems.append(f"{case}: gaps between fibers {np.diff(first)} at the start, {np.diff(x)} at the "
                                    "end: expected beyond reach + skin (7.5 nm) at first and within the cutoff at the end")
            for n in args.ranks:
                out = os.path.join(work, f"{case}.np{n}")
                run(args, n, scene, out, sets)
                found = compare(reference, frames(out), f"{case} on {n} ranks")
                found += compare_series(one, out, f"{case} on {n} ranks")
                print(f"  {n} ranks: {'same bits' if not found else found[0]}")
                problems += found
        # Resume on another number of ranks: the block's run stopped by SIGTERM after its first
        # checkpoint (every rank writes a final one and exits 5), continued on other ranks.
        scene = scene_file("pmb_block", args.scenes_dir, work)
        longer = ["--set", "stages.expand.steps=600", "--set", "output.frames=2",
                  "--set", "output.checkpoint_every_seconds=0", "--set", "output.checkpoint_every_steps=100"]
        whole_dir = os.path.join(work, "block.whole")
        run(args, 1, scene, whole_dir, longer)
        whole = frames(whole_dir)
        last = sorted(whole)[-1]
        for src, dst in resumes:
            first = os.path.join(work, f"block.stopped.np{src}")
            step = stop_after_checkpoint(args, src, scene, first, longer)
            print(f"pmb_block stopped on {src} ranks at step {step}, resumed on {dst} ranks:")
            resumed = os.path.join(work, f"block.resumed.np{src}to{dst}")
            run(args, dst, None, resumed, ["--resume", first])
            got = frames(resumed)
            found = compare({last: whole[last]}, {last: got[last]} if last in got else {},
                            f"resume of a {src}-rank checkpoint (step {step}) on {dst} ranks")
            print(f"  {'same bits as the run not stopped, at step ' + str(last) if not found else found[0]}")
            problems += found
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    if problems:
        print("\n".join(["FAILED:"] + problems))
        return 1
    print("all same")
    return 0


if __name__ == "__main__":
    sys.exit(main())

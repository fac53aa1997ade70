#!/usr/bin/env python3
"""Crack speed of a lattice scene over a map of parameters, against the far field's wave speeds.

usage: /usr/bin/python3 tools/lattice_crack_map.py SCENE CASES.csv OUT.csv [--set KEY=VALUE ...]
           [--peridrive EXE] [--np N] [--mpiexec CMD] [--mpi-flag=FLAG ...] [--work DIR] [--plot PNG]
       /usr/bin/python3 tools/lattice_crack_map.py --plot PNG OUT.csv [OUT.csv ...]   (figure from finished maps)

SCENE is a scene with one lattice body, one material and a seed crack along y = 0 (as
drivers/scenes/supersonic_rubber_broad_switch.yaml). Each row of CASES.csv is one run; its columns:
  lx, ly        the initial stretches (initial.displacement_gradient = diag(lx - 1, ly - 1, 0))
  us, uc        cutoff u_s and fracture separation u_c in lattice spacings (materials' cutoff,
                fracture_separation); uc = "min" takes the smallest u_c (step 0.05 Delta) at which
                the lattice's four long-wave speeds at (lx, ly) are within --mr-tolerance of the
                Mooney-Rivlin ones (the derived constants of --dry-run)
  nu, b         kelvin_viscosity [m^2/s] and mooney_rivlin_b
  ug, w         optional: stiffening_onset and stiffening_width in lattice spacings (empty or
                absent: no stiffening)
  ub            optional: break_separation in lattice spacings (empty or absent: bonds break at u_c);
                "min" u_c is searched without ug, w and ub (they act beyond the far field)
  duration      the stage's duration [s]
  length        the strip's length [m] (its height, spacing and seed stay the scene's)
For each case the script reads --dry-run's derived constants, runs the scene on --np ranks,
measures the tip with tools/crack_tip_lattice.py and appends one line to OUT.csv: the case, the
largest relative deviation of the lattice's speeds from Mooney-Rivlin (mr_deviation), the
Mooney-Rivlin c_L along x and c_T, the mean crack speed (crack_tip_lattice's fit), the peak speed
(largest least-squares slope over 5 consecutive frames of the measured run, before any jump of
the tip) and both over c_L.
A case whose tip never leaves the seed is recorded with speed 0 (outcome "arrested"); one whose
tip stops early (mean speed below 1e-3 c_L) keeps its speeds and is "arrested" too; one whose tip
jumps (crack_tip_lattice's tip_jumps_at: the line failed ahead of it, or a rupture from the far
end arrived) is "runs, then meets damage ahead", its speeds those of the crack before the jump.
--plot draws v/c_L (mean and peak) against mr_deviation, runs with stiffening or an earlier
break in their own markers. Needs python3-h5py, numpy, matplotlib.
"""
import argparse
import csv
import json
import math
import os
import re
import shutil
import subprocess
import sys

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FIELDS = ["lx", "ly", "us", "uc", "nu", "b", "ug", "w", "ub", "duration", "length", "mr_deviation", "cl_mr", "ct_mr",
          "v_mean", "v_peak", "v_mean_over_cl", "v_peak_over_cl", "outcome"]


def stiffening(case):
    """(u_g, w) in lattice spacings, or None."""
    ug, w = (case.get("ug") or "").strip(), (case.get("w") or "").strip()
    return (float(ug), float(w)) if ug and w and float(w) > 0 else None


def overrides(case, spacing, uc, stiff=True):
    extra = []
    if stiff and stiffening(case):
        ug, w = stiffening(case)
        extra = ["--set", f"materials.{case['material']}.stiffening_onset={ug * spacing!r}",
                 "--set", f"materials.{case['material']}.stiffening_width={w * spacing!r}"]
    # Without ub (and during the u_c search) bonds break at u_c, whatever the scene says.
    ub = float(case["ub"]) if stiff and (case.get("ub") or "").strip() else uc
    extra += ["--set", f"materials.{case['material']}.break_separation={ub * spacing!r}"]
    return extra + ["--set", f"materials.{case['material']}.cutoff={float(case['us']) * spacing!r}",
            "--set", f"materials.{case['material']}.fracture_separation={uc * spacing!r}",
            "--set", f"materials.{case['material']}.kelvin_viscosity={case['nu']}",
            "--set", f"materials.{case['material']}.mooney_rivlin_b={case['b']}",
            "--set", f"initial.displacement_gradient=[[{float(case['lx']) - 1!r}, 0, 0], "
                     f"[0, {float(case['ly']) - 1!r}, 0], [0, 0, 0]]"]


def derived(text):
    return {k: float(v) for k, v in re.findall(r"^(?:# )?\S*?\.?(\w+) = (\S+)$", text, re.M)
            if re.fullmatch(r"[-+0-9.eE]+", v)}


def deviation(values):
    pairs = [("lattice_longitudinal_speed_x", "longitudinal_wave_speed_x"),
             ("lattice_shear_speed_x", "shear_wave_speed"),
             ("lattice_longitudinal_speed_y", "longitudinal_wave_speed_y"),
             ("lattice_shear_speed_y", "shear_wave_speed")]
    return max(abs(values[a] / values[b] - 1) for a, b in pairs)


def dry_run(args, case, spacing, uc, stiff=True):
    cmd = [args.peridrive, args.scene, "--dry-run"] + args.overrides + overrides(case, spacing, uc, stiff)
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"lattice_crack_map.py: --dry-run failed for {case}: {r.stderr.strip()}")
    return derived(r.stdout)


def peak_speed(csv_path, seed_end, x_end, delta, jump=None):
    t, x = np.loadtxt(csv_path, delimiter=",", skiprows=1, unpack=True, ndmin=2)
    use = (x > seed_end + 5 * delta) & (x < x_end - 10 * delta)
    if jump is not None:
        use &= t < jump  # the crack from the seed, before its tip jumps onto damage ahead
    t, x = t[use], x[use]
    if t.size < 5:
        return 0.0
    return max(np.polyfit(t[k:k + 5], x[k:k + 5], 1)[0] for k in range(t.size - 4))


def run_case(args, case, scene_text, spacing, material, body):
    case = dict(case, material=material)
    uc = case["uc"]
    if uc == "min":
        uc = 1.05 + float(case["us"])
        # The longest bond of the stretched lattice (along x or at 60 degrees), in spacings: a u_c at
        # or below it leaves those bonds without force, and peridrive refuses the stretch.
        lx, ly = float(case["lx"]), float(case["ly"])
        longest = max(lx, math.hypot(0.5 * lx, 0.5 * math.sqrt(3.0) * ly))
        while uc <= longest or deviation(dry_run(args, case, spacing, uc, stiff=False)) > args.mr_tolerance:
            uc = round(uc + 0.05, 6)
            if uc > 20:
                sys.exit(f"lattice_crack_map.py: no u_c below 20 Delta makes {case} Mooney-Rivlin")
    uc = float(uc)
    values = dry_run(args, case, spacing, uc)
    out = os.path.join(args.work, "run")
    shutil.rmtree(out, ignore_errors=True)
    cmd = [args.mpiexec, "-n", str(args.np)] + args.mpi_flag + [args.peridrive, args.scene, "--quiet", "--out", out,
           "--set", f"stages.0.duration={case['duration']}",
           "--set", f"bodies.{body}.size=[{case['length']}, {size_y(scene_text, body)}]"] + args.overrides \
        + overrides(case, spacing, uc)
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"lattice_crack_map.py: the run failed for {case}:\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
    tip = subprocess.run([sys.executable, os.path.join(HERE, "crack_tip_lattice.py"), out],
                         capture_output=True, text=True)
    row = {k: case[k] for k in ("lx", "ly", "us", "nu", "b", "duration", "length")}
    row.update(ug=case.get("ug") or "", w=case.get("w") or "", ub=case.get("ub") or "")
    row.update(uc=uc, mr_deviation=deviation(values), cl_mr=values["longitudinal_wave_speed_x"],
               ct_mr=values["shear_wave_speed"])
    if tip.returncode != 0:
        # Only a tip that never left the seed is an arrest; any other failure of the measurement
        # (frames without positions, a run cut short) is not a speed of 0.
        if "fewer than 3 frames" not in tip.stderr:
            sys.exit(f"lattice_crack_map.py: the crack tip of {case} could not be measured: "
                     f"{(tip.stderr.strip() or tip.stdout.strip())[-2000:]}")
        row.update(v_mean=0.0, v_peak=0.0, outcome="arrested")
    else:
        res = json.load(open(os.path.join(out, "crack_tip.json")))
        with h5py.File(os.path.join(out, "frames.h5"), "r") as f:
            x_end = float(f["mesh/reference_position"][...].reshape(-1, 3)[:, 0].max())
        row.update(v_mean=res["crack_speed"],
                   v_peak=peak_speed(os.path.join(out, "crack_tip.csv"), seed_end_of(scene_text), x_end, spacing,
                                     res.get("tip_jumps_at")),
                   outcome="runs" if res["crack_speed"] > 1e-3 * row["cl_mr"] else "arrested")
        if res.get("tip_jumps_at") is not None:
            row["outcome"] = "runs, then meets damage ahead"
    row.update(v_mean_over_cl=row["v_mean"] / row["cl_mr"], v_peak_over_cl=row["v_peak"] / row["cl_mr"])
    return row


def size_y(scene_text, body):
    m = re.search(rf"^  {re.escape(body)}:\n(?:    .*\n)*?    size: \[[^,\]]+, *([^\],]+)", scene_text, re.M)
    if not m:
        sys.exit(f"lattice_crack_map.py: no size of body {body} in the scene")
    return m.group(1).strip()


def seed_end_of(scene_text):
    m = re.search(r"cracks:\n  - name: \S+\n    from: \[([^\]]*)\]\n    to: \[([^\]]*)\]", scene_text)
    if not m:
        sys.exit("lattice_crack_map.py: the scene has no seed crack")
    return max(float(m.group(1).split(",")[0]), float(m.group(2).split(",")[0]))


def plot(rows, png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    dev = np.array([max(float(r["mr_deviation"]), 1e-4) for r in rows])
    mean = np.array([float(r["v_mean_over_cl"]) for r in rows])
    peak = np.array([float(r["v_peak_over_cl"]) for r in rows])
    stiff = np.array([bool((r.get("w") or "").strip()) for r in rows])
    early = np.array([bool((r.get("ub") or "").strip()) for r in rows])
    fig, ax = plt.subplots(figsize=(10, 4.5))
    ax.axvspan(1e-4, 0.03, color="0.92", label="far field Mooney-Rivlin (speeds within 3%)")
    ax.axhline(1.0, color="k", lw=0.8)
    for sel, tag, up, ring, colours in ((~stiff & ~early, "", "^", "o", ("C3", "C0")),
                                        (stiff & ~early, ", stiffening", "v", "s", ("C2", "C4")),
                                        (early, ", break below u_c", ">", "D", ("C1", "C5"))):
        if sel.any():
            ax.scatter(dev[sel], peak[sel], marker=up, color=colours[0], label="peak speed (5 frames)" + tag)
            ax.scatter(dev[sel], mean[sel], marker=ring, facecolor="none", edgecolor=colours[1], label="mean speed" + tag)
    ax.set_xscale("log")
    ax.set_xlabel("largest deviation of the stretched lattice's wave speeds from Mooney-Rivlin (below 1e-4 drawn at 1e-4)")
    ax.set_ylabel("crack speed / Mooney-Rivlin c_L (along the crack)")
    ax.set_title("crack speed against how far the far field is from Mooney-Rivlin")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1))
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("paths", nargs="+")
    ap.add_argument("--peridrive", default=os.path.join(HERE, "..", "build", "peridrive"))
    ap.add_argument("--np", type=int, default=2)
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--mpi-flag", action="append", default=[], help="an argument for mpiexec (repeatable)")
    ap.add_argument("--work", default=None)
    ap.add_argument("--mr-tolerance", type=float, default=0.03)
    ap.add_argument("--plot", default=None)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a scene override applied to every run (repeatable), e.g. bodies.strip.spacing=0.001")
    args = ap.parse_args()
    args.overrides = [a for kv in args.set for a in ("--set", kv)]
    if all(p.endswith(".csv") for p in args.paths):
        if not args.plot:
            sys.exit("usage: lattice_crack_map.py --plot PNG OUT.csv [OUT.csv ...] (or SCENE CASES.csv OUT.csv)")
        plot([r for p in args.paths for r in csv.DictReader(open(p))], args.plot)
        return
    if len(args.paths) != 3:
        sys.exit("usage: lattice_crack_map.py SCENE CASES.csv OUT.csv")
    args.scene, cases_path, out_path = args.paths
    # The cases first, before OUT is opened for writing (arguments given the other way round
    # would truncate the cases file).
    try:
        with open(cases_path, newline="") as f:
            cases = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"lattice_crack_map.py: {cases_path}: cannot read the cases ({e.strerror})")
    needed = {"lx", "ly", "us", "nu", "b", "duration", "length"}
    if not cases or not needed <= set(cases[0]):
        sys.exit(f"lattice_crack_map.py: {cases_path}: expected a cases CSV with the columns "
                 f"{', '.join(sorted(needed))} and at least one row (usage: SCENE CASES.csv OUT.csv)")
    if os.path.exists(out_path) and os.path.samefile(out_path, cases_path):
        sys.exit(f"lattice_crack_map.py: {out_path}: OUT.csv is the cases file")
    r = subprocess.run([args.peridrive, args.scene, "--print-scene"] + args.overrides, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"lattice_crack_map.py: {args.scene}: {r.stderr.strip()}")
    scene_text = r.stdout
    if not re.search(r"^  (\S+):\n    kind: lattice", scene_text, re.M):
        sys.exit(f"lattice_crack_map.py: {args.scene}: no lattice body (kind: lattice); expected a Marder scene")
    spacing = float(re.search(r"kind: lattice\n(?:    .*\n)*?    spacing: (\S+)", scene_text).group(1))
    material = re.search(r"kind: lattice\n(?:    .*\n)*?    material: (\S+)", scene_text).group(1)
    body = re.search(r"^  (\S+):\n    kind: lattice", scene_text, re.M).group(1)
    args.work = args.work or os.path.join(os.path.dirname(os.path.abspath(out_path)), "lattice_crack_map.work")
    os.makedirs(args.work, exist_ok=True)
    rows = []
    with open(out_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for case in cases:
            row = run_case(args, case, scene_text, spacing, material, body)
            w.writerow(row)
            f.flush()
            rows.append(row)
            stiff = (f" ug={row['ug']} w={row['w']}" if row["w"] else "") + (f" ub={row['ub']}" if row["ub"] else "")
            print(f"lx={row['lx']} ly={row['ly']} us={row['us']} uc={row['uc']:.2f} nu={row['nu']} b={row['b']}{stiff}: "
                  f"MR deviation {row['mr_deviation']:.3f}, v/c_L mean {row['v_mean_over_cl']:.3f} "
                  f"peak {row['v_peak_over_cl']:.3f} ({row['outcome']})", flush=True)
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Same results as a reference revision: every scene of drivers/scenes/ and the 32^3 PMB block of
compare_lammps.py, run by this build and by a build of REV, on 1 and 2 ranks; every dataset of
frames.h5, every row of series.csv and tips.csv, and the physics fields of summary.json must be
the same bits. For refactors ("refactors keep the bits"); prints a table and exits 1 on any
difference.

  /usr/bin/python3 benchmarks/same_results.py REV                  # all scenes, 1 and 2 ranks
  /usr/bin/python3 benchmarks/same_results.py REV --scenes slit_membrane block32 --ranks 2
  /usr/bin/python3 benchmarks/same_results.py REV --ref-exe path/to/peridrive   # a build you have

REV is built once into build-ref/<sha>/ (a git worktree, no tests or benchmarks) and reused.
Long scenes are cut to their first --max-steps steps (default: none) with --set stages.N.steps,
the same cut for both builds.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)

# summary.json fields that measure the machine, not the physics.
VOLATILE = {"wall_seconds", "setup_seconds", "step_seconds", "output_seconds", "bond_updates_per_second",
            "bond_updates_per_second_per_rank", "partition_seconds", "memory", "git_revision",
            "peridrive_version", "crack_tip_seconds", "quasistatic", "bytes_per_bond", "peak_bytes_per_bond"}


# Datasets that hold the resolved scene text (with the revision that wrote it), not results.
PROVENANCE = {"scene", "resolved_scene"}
# Datasets that revisions before the scene dataset and the mesh's vertex cells do not hold.
LAYOUT = {"scene", "mesh/connectivity"}


def block_scene(n=32, steps=50):
    from compare_lammps import peridrive_scene
    return peridrive_scene(n, steps)


def build_reference(rev):
    sha = subprocess.check_output(["git", "-C", ROOT, "rev-parse", rev], text=True).strip()
    exe = os.path.join(ROOT, "build-ref", sha[:12], "build", "peridrive")
    if os.path.exists(exe):
        return exe
    src = os.path.join(ROOT, "build-ref", sha[:12], "src")
    if not os.path.exists(src):
        subprocess.check_call(["git", "-C", ROOT, "worktree", "add", "--detach", src, sha])
    subprocess.check_call(["cmake", "-S", src, "-B", os.path.dirname(exe), "-DCMAKE_BUILD_TYPE=Release",
                           "-DPERI_BUILD_TESTS=OFF", "-DPERI_BUILD_BENCHMARKS=OFF"], stdout=subprocess.DEVNULL)
    subprocess.check_call(["cmake", "--build", os.path.dirname(exe), "-j", str(os.cpu_count()),
                           "--target", "peridrive"], stdout=subprocess.DEVNULL)
    return exe


def dynamic_stages(scene_file):
    """Indices of the scene's dynamic stages (from its resolved YAML)."""
    import yaml
    out = subprocess.run([EXE, scene_file, "--print-scene"], capture_output=True, text=True, env=ENV)
    stages = yaml.safe_load(out.stdout).get("stages", [])
    return [k for k, s in enumerate(stages) if s.get("kind", "dynamic") == "dynamic"]


def run(exe, scene_file, ranks, out, sets):
    cmd = ["mpirun", "-n", str(ranks), exe, scene_file, "--quiet", "--out", out,
           "--set", "output.checkpoint_every_seconds=0"]
    for s in sets:
        cmd += ["--set", s]
    r = subprocess.run(cmd, capture_output=True, text=True, env=ENV)
    return r.returncode, (r.stderr or r.stdout).strip().splitlines()[-1:] if r.returncode else []


def same_h5(a, b):
    diffs = []
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        names_a, names_b = [], []
        fa.visit(lambda n: names_a.append(n) if isinstance(fa[n], h5py.Dataset) else None)
        fb.visit(lambda n: names_b.append(n) if isinstance(fb[n], h5py.Dataset) else None)
        if sorted(set(names_a) - LAYOUT) != sorted(set(names_b) - LAYOUT):
            diffs.append(f"datasets differ: {sorted((set(names_a) ^ set(names_b)) - LAYOUT)[:4]}")
        worst = 0.0
        for n in names_a:
            if n not in fb or n.split("/")[-1] in PROVENANCE:
                continue
            x, y = fa[n][()], fb[n][()]
            if x.shape != y.shape:
                diffs.append(f"{n}: shape {x.shape} vs {y.shape}")
            elif x.tobytes() != y.tobytes():
                d = float(np.nanmax(np.abs(x.astype(float) - y.astype(float))))
                scale = float(np.nanmax(np.abs(x.astype(float)))) or 1.0
                worst = max(worst, d / scale)
                diffs.append(f"{n}: max |diff| {d:.3g} ({d / scale:.2g} of max)")
    return diffs


def same_text(a, b, name):
    if not os.path.exists(a) and not os.path.exists(b):
        return []
    if not (os.path.exists(a) and os.path.exists(b)):
        return [f"{name} only in one run"]
    la, lb = open(a).read().splitlines(), open(b).read().splitlines()
    for k, (x, y) in enumerate(zip(la, lb)):
        if x != y:
            return [f"{name} line {k + 1}: '{x[:60]}' vs '{y[:60]}'"]
    return [] if len(la) == len(lb) else [f"{name}: {len(la)} vs {len(lb)} lines"]


def same_summary(a, b):
    ja, jb = json.load(open(a)), json.load(open(b))
    out = []
    for k in sorted(set(ja) & set(jb)):  # fields only one build writes are new, not different
        if k in VOLATILE:
            continue
        if ja.get(k) != jb.get(k):
            out.append(f"summary {k}: {str(ja.get(k))[:40]} vs {str(jb.get(k))[:40]}")
    return out


def main():
    global EXE, ENV
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("rev", help="reference git revision")
    p.add_argument("--ref-exe", help="a reference peridrive binary instead of building REV")
    p.add_argument("--exe", default=os.path.join(ROOT, "build", "peridrive"))
    p.add_argument("--scenes", nargs="*", help="scene stems (drivers/scenes/STEM.yaml) or block32")
    p.add_argument("--ranks", nargs="*", type=int, default=[1, 2])
    p.add_argument("--max-steps", type=int, default=0, help="cut each dynamic stage to this many steps")
    p.add_argument("--keep", help="keep the runs in this directory")
    args = p.parse_args()
    EXE = args.exe
    ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    ref = args.ref_exe or build_reference(args.rev)
    work = args.keep or tempfile.mkdtemp(prefix="same_results_")
    os.makedirs(work, exist_ok=True)
    stems = args.scenes or sorted(f[:-5] for f in os.listdir(os.path.join(ROOT, "drivers", "scenes"))
                                  if f.endswith(".yaml")) + ["block32"]
    failed = 0
    print(f"reference {ref}\nthis      {EXE}")
    for stem in stems:
        if stem == "block32":
            scene = os.path.join(work, "block32.yaml")
            with open(scene, "w") as f:
                f.write(block_scene())
        else:
            scene = os.path.join(ROOT, "drivers", "scenes", stem + ".yaml")
        sets = []
        if args.max_steps:
            sets = [f"stages.{s}.steps={args.max_steps}" for s in dynamic_stages(scene)]
        for ranks in args.ranks:
            outs = []
            for tag, exe in (("ref", ref), ("new", EXE)):
                out = os.path.join(work, f"{stem}_np{ranks}_{tag}")
                shutil.rmtree(out, ignore_errors=True)
                rc, msg = run(exe, scene, ranks, out, sets)
                outs.append((out, rc, msg))
            (a, ra, ma), (b, rb, mb) = outs
            diffs = []
            if ra != rb or ra != 0:
                diffs.append(f"exit {ra} vs {rb}: {ma} {mb}")  # a run that fails compares nothing
            else:
                for name in ("series.csv", "tips.csv"):
                    diffs += same_text(os.path.join(a, name), os.path.join(b, name), name)
                if os.path.exists(os.path.join(a, "frames.h5")):
                    diffs += same_h5(os.path.join(a, "frames.h5"), os.path.join(b, "frames.h5"))
                if os.path.exists(os.path.join(a, "summary.json")):
                    diffs += same_summary(os.path.join(a, "summary.json"), os.path.join(b, "summary.json"))
            verdict = "same bits" if not diffs else "DIFFERENT"
            failed += bool(diffs)
            print(f"{stem:24s} np{ranks}  exit {ra}  {verdict}")
            for d in diffs[:6]:
                print("    " + d)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    print("all same" if not failed else f"{failed} differ")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/python3
"""Fig. 3 of Silling & Bobaru (2005): stress against stretch of a damaging membrane, from the closed
form (eqs. 27-29) and measured by peridrive.

  /usr/bin/python3 tools/fig3_damage_stress.py [--peridrive build/peridrive] [--np 2] [--m 8]
        [--out out/fig3] [--figure docs/figures/fig3_damage_stress.png] [--check] [--tolerance 0.06]

For each of the three cases (CASES below) it runs drivers/scenes/fig3_damage_stress.yaml with the
case's eq. (29) parameters, transverse stretch and (case 3) hardening set by --set, at delta / dx =
--m, reads quasistatic.csv, and compares the measured Piola stress P_11(lambda_1) with the closed
form. --check prints the comparison and exits 1 when a measured curve is farther than --tolerance
from the closed form or does not have its case's shape (the ctest `fig3_damage_stress`); without
--check it also draws the figure.

Measured stress: the scene holds two sheets (heights 5 and 7 mm) in frames of boundary bands that
follow the affine map diag(lambda_1, lambda_2); the x reaction of a sheet's right band is the force
of every bond that crosses the band's inner edge. The free edges y = 0 and y = H take the same share
from both sheets, so P_11 = (R_b - R_a) / (h (7 mm - 5 mm)) is the stress of the interior: the
reactions written per increment in quasistatic.csv (docs/user/outputs.md), not an energy derivative.

Closed form: with g = 1, the energy (27)-(28) per unit volume is

    W(lambda_1, lambda_2) = 2 h c int_0^delta F(lambda_1, lambda_2, lambda_0(xi)) xi dxi,

F the bracket of eq. (28) with theta_0 of eq. (25) for the ring's lambda_0(xi) of eq. (29)
(theta_0 = 0 while lambda_1 <= lambda_0(xi)). Differentiating, the terms in d theta_0 / d lambda_1
cancel (a bond breaks at the stretch where it holds w_0), so

    P_11 = dW/dlambda_1 = 2 h c int_0^delta dF/dlambda_1|_theta_0 xi dxi,
    dF/dlambda_1|_theta_0 = 2 l1 (pi/4 - t0/2) - (l1/2) sin 2 t0 - atan2(l1 cos t0, l2 sin t0) / (l1^2 l2)
                            + l2 sin t0 cos t0 / (l1 (l2^2 sin^2 t0 + l1^2 cos^2 t0)),

which at theta_0 = 0 is eq. (19)'s pi (l1 - 1/(l1^2 l2)) / 2. The xi integral is done by the
midpoint rule on 4000 rings (its kinks, where a ring starts to break, cost O(1e-6) relative). The
hardening of eq. (16) (case 3), c' (lambda^n - n lambda + n - 1) g, adds
2 h c' int xi dxi int_{theta_0}^{pi/2} n (lambda^(n-1) - 1) lambda_1 cos^2 theta / lambda dtheta,
whose theta integral is done by 48-point Gauss-Legendre on [theta_0, pi/2]. Stresses are given
over mu = pi h c delta^2 / 2, the small-strain shear modulus.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SCENE = os.path.join(ROOT, "drivers", "scenes", "fig3_damage_stress.yaml")
DELTA = 1e-3            # the scene's horizon [m]
HEIGHTS = (5e-3, 7e-3)  # the two sheets' heights [m]

# The three cases: eq. (29) parameters, transverse stretch, hardening (c'/c, n) and the range.
CASES = [
    dict(name="plateau", L0=6.0, Ld=1.5, l2=1.0, hard=None, l1max=4.0,
         label="(a) plateau: $\\Lambda_0 = 6$, $\\Lambda_\\delta = 1.5$, $\\lambda_2 = 1$"),
    dict(name="cusp", L0=2.0, Ld=2.0, l2=1.5, hard=None, l1max=3.0,
         label="(b) cusp: $\\Lambda_0 = \\Lambda_\\delta = 2$, $\\lambda_2 = 1.5$"),
    dict(name="rise", L0=4.0, Ld=1.5, l2=1.485, hard=(5e-8, 16.0), l1max=3.15,
         label="(c) local max, then rise: $\\Lambda_0 = 4$, $\\Lambda_\\delta = 1.5$, $\\lambda_2 = 1.485$,\n"
               "hardening (16) $c'/c = 5\\times10^{-8}$, $n = 16$"),
]


# ------------------------------------------------------------------------------------------------
# Closed form


def theta0(l1, l2, l0):
    """eq. (25) per ring (0 while lambda_1 <= lambda_0)."""
    l0 = np.asarray(l0, float)
    ratio = np.clip((l1 * l1 - l0 * l0) / max(l1 * l1 - l2 * l2, 1e-300), 0.0, 1.0)
    return np.where(l1 > l0, np.arcsin(np.sqrt(ratio)), 0.0)


def bracket(l1, l2, l0):
    """The bracket F of eq. (28) (energy per 2 h c R)."""
    t = theta0(l1, l2, l0)
    s, c = np.sin(t), np.cos(t)
    return ((l0 * l0 + 1 / (l0 * l0)) * t + (l1 * l1 + l2 * l2) * (math.pi / 4 - t / 2)
            + np.sin(2 * t) / 4 * (l2 * l2 - l1 * l1) + np.arctan2(l1 * c, l2 * s) / (l1 * l2) - math.pi)


def dbracket(l1, l2, l0):
    """dF/dlambda_1 at fixed theta_0."""
    t = theta0(l1, l2, l0)
    s, c = np.sin(t), np.cos(t)
    return (2 * l1 * (math.pi / 4 - t / 2) - l1 / 2 * np.sin(2 * t) - np.arctan2(l1 * c, l2 * s) / (l1 * l1 * l2)
            + l2 * s * c / (l1 * (l2 * l2 * s * s + l1 * l1 * c * c)))


RINGS = 4000
GAUSS = np.polynomial.legendre.leggauss(48)


def stress(l1, case):
    """P_11 / mu of eqs. (27)-(29) (+ eq. 16's hardening) at lambda_1, the case's lambda_2."""
    x = (np.arange(RINGS) + 0.5) / RINGS  # xi / delta
    l0 = case["L0"] + (case["Ld"] - case["L0"]) * x
    l2 = case["l2"]
    s = np.sum(dbracket(l1, l2, l0) * x) / RINGS
    if case["hard"]:
        ratio, n = case["hard"]
        t0 = theta0(l1, l2, l0)[:, None]
        g, w = GAUSS
        th = t0 + (math.pi / 2 - t0) * (g[None, :] + 1) / 2
        lam = np.sqrt((l1 * np.cos(th)) ** 2 + (l2 * np.sin(th)) ** 2)
        inner = np.sum(n * (lam ** (n - 1) - 1) * l1 * np.cos(th) ** 2 / lam * w[None, :], axis=1)
        s += ratio * np.sum(inner * (math.pi / 2 - t0[:, 0]) / 2 * x) / RINGS
    return 4 / math.pi * s  # 2 h c delta^2 s / (pi h c delta^2 / 2)


def energy(l1, case):
    """W / mu of eq. (28) (no hardening): for the derivative check."""
    x = (np.arange(RINGS) + 0.5) / RINGS
    l0 = case["L0"] + (case["Ld"] - case["L0"]) * x
    return 4 / math.pi * np.sum(bracket(l1, case["l2"], l0) * x) / RINGS


# ------------------------------------------------------------------------------------------------
# Runs


def run_case(case, args):
    out = os.path.join(args.out, f"{case['name']}_m{args.m}")
    dx = DELTA / args.m
    sets = {
        "bodies.a.spacing": repr(dx), "bodies.b.spacing": repr(dx),
        "materials.rubber.critical_stretch": repr(case["L0"]),
        "materials.rubber.critical_stretch_at_horizon": repr(case["Ld"]),
        "stages.transverse.displacement_gradient": f"[[0,0,0],[0,{case['l2'] - 1!r},0],[0,0,0]]",
        "stages.stretch.displacement_gradient": f"[[{case['l1max'] - 1!r},0,0],[0,0,0],[0,0,0]]",
        "stages.stretch.max_load_step": repr(args.dl / (case["l1max"] - 1)),
    }
    if case["hard"]:
        c = 1.2732395447351627e15
        sets["materials.rubber.hardening"] = f"{{coefficient: {case['hard'][0] * c!r}, exponent: {case['hard'][1]!r}}}"
    cmd = list(args.launcher) + [args.peridrive, SCENE, "--out", out, "--quiet"]
    for k, v in sets.items():
        cmd += ["--set", f"{k}={v}"]
    if not args.reuse or not os.path.exists(os.path.join(out, "summary.json")):
        r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if r.returncode != 0:
            sys.exit(f"fig3: {' '.join(cmd)} failed ({r.returncode}):\n{r.stdout[-3000:]}")
    summary = json.load(open(os.path.join(out, "summary.json")))
    c = summary["derived"]["a.micromodulus"]
    h = 5e-4
    mu = math.pi * h * c * DELTA * DELTA / 2
    l1, p = [], []
    for row in csv.DictReader(open(os.path.join(out, "quasistatic.csv"))):
        if row["stage"] != "stretch":
            continue
        l1.append(1 + float(row["load_factor"]) * (case["l1max"] - 1))
        p.append((float(row["b_right_reaction_x"]) - float(row["a_right_reaction_x"])) / (h * (HEIGHTS[1] - HEIGHTS[0])))
    return np.array(l1), np.array(p) / mu, summary


# ------------------------------------------------------------------------------------------------
# Shapes


def plateau_width(l1, s, level=0.98):
    """Width in lambda_1 of the contiguous stretch around the maximum where s >= level * max."""
    i = int(np.argmax(s))
    a = b = i
    while a > 0 and s[a - 1] >= level * s[i]:
        a -= 1
    while b < len(s) - 1 and s[b + 1] >= level * s[i]:
        b += 1
    return l1[b] - l1[a], i


def shape(case, l1, s):
    """(ok, words) for the case's shape on the curve (l1, s)."""
    if case["name"] == "plateau":
        width, i = plateau_width(l1, s)
        ok = width >= 0.5 and 0 < i < len(s) - 1
        return ok, f"within 2% of its maximum {s[i]:.3f} over a lambda_1 range of {width:.2f} (>= 0.5 wanted)"
    if case["name"] == "cusp":
        i = int(np.argmax(s))
        before = np.interp(l1[i] - 0.1, l1, s)
        after = np.interp(l1[i] + 0.1, l1, s)
        width, _ = plateau_width(l1, s)
        ratio = (s[i] - after) / max(s[i] - before, 1e-12)
        ok = ratio >= 3 and width <= 0.15 and 0 < i < len(s) - 1
        return ok, (f"maximum {s[i]:.3f} at lambda_1 = {l1[i]:.3f}: drop over the next 0.1 is {ratio:.1f} x the rise "
                    f"over the previous 0.1 (>= 3 wanted); 2% band {width:.2f} wide (<= 0.15 wanted)")
    # local maximum, a valley at least 3% deep, then above the local maximum
    lo, hi = case["window"]
    sel = (l1 >= lo) & (l1 <= hi)
    i = int(np.flatnonzero(sel)[np.argmax(s[sel])])
    j = i + int(np.argmin(s[i:]))
    peak, valley, final = s[i], s[j], s[j:].max()
    ok = valley <= 0.97 * peak and final >= 1.03 * peak and j < len(s) - 1
    return ok, (f"local maximum {peak:.3f} at lambda_1 = {l1[i]:.3f}, valley {valley:.3f} at {l1[j]:.3f} "
                f"({100 * (1 - valley / peak):.1f}% deep, >= 3% wanted), then up to {final:.3f} "
                f"({final / peak:.3f} x the maximum, >= 1.03 wanted)")


def smoothed(l1, s, width):
    """Running mean over a lambda_1 window of `width` (the shapes of a measured curve: each group of
    symmetric bonds breaks at once, so the discrete curve is a sawtooth about the continuum one)."""
    if width <= 0:
        return s
    return np.array([s[np.abs(l1 - x) <= width / 2].mean() for x in l1])


# ------------------------------------------------------------------------------------------------


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--peridrive", default=os.path.join(ROOT, "build", "peridrive"))
    ap.add_argument("--mpiexec", default="mpirun")
    ap.add_argument("--mpiexec-flags", default="--allow-run-as-root" if os.geteuid() == 0 else "",
                    help="flags for the launcher, one string")
    ap.add_argument("--np", type=int, default=2)
    ap.add_argument("--m", type=int, default=8, help="delta / dx")
    ap.add_argument("--dl", type=float, default=0.05, help="largest increment of lambda_1")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "fig3"))
    ap.add_argument("--figure", default=os.path.join(ROOT, "docs", "figures", "fig3_damage_stress.png"))
    ap.add_argument("--check", action="store_true", help="compare and test the shapes only; exit 1 on failure")
    ap.add_argument("--tolerance", type=float, default=0.06,
                    help="largest |P_measured - P_eq28| over the curve's maximum (default 0.06)")
    ap.add_argument("--smooth", type=float, default=0.3,
                    help="judge the measured plateau and rise on a running mean over this lambda_1 window "
                         "(default 0.3; 0: raw)")
    ap.add_argument("--mean-tolerance", type=float, default=0.03,
                    help="largest mean of |P_measured - P_eq28| over the curve's maximum (default 0.03)")
    ap.add_argument("--reuse", action="store_true", help="reuse runs already in --out")
    args = ap.parse_args(argv)
    if args.m < 1:
        ap.error(f"--m: expected a whole number of spacings per horizon >= 1, got {args.m}")
    if args.np < 0:
        ap.error(f"--np: expected a number of ranks >= 0 (0: no launcher), got {args.np}")
    for name in ("dl", "tolerance", "mean_tolerance"):
        if not getattr(args, name) > 0:
            ap.error(f"--{name.replace('_', '-')}: expected a number > 0, got {getattr(args, name)}")
    if not args.smooth >= 0:
        ap.error(f"--smooth: expected a window >= 0 (0: raw), got {args.smooth}")
    args.launcher = [args.mpiexec, "-n", str(args.np)] + args.mpiexec_flags.split() if args.np > 0 else []

    # The closed form's own check: the stress is the derivative of the energy (28).
    case = CASES[0]
    for l1 in (1.3, 2.2, 3.1):
        fd = (energy(l1 + 1e-5, case) - energy(l1 - 1e-5, case)) / 2e-5
        if abs(fd - stress(l1, case)) > 1e-4 * abs(fd):
            sys.exit(f"fig3: closed form: dW/dlambda_1 {fd} != P_11 {stress(l1, case)} at {l1}")
    # eq. (19) without damage
    l1, l2 = 1.4, 1.2
    undamaged = dict(L0=9.0, Ld=9.0, l2=l2, hard=None)
    if abs(stress(l1, undamaged) - (l1 - 1 / (l1 * l1 * l2))) > 1e-9:
        sys.exit("fig3: closed form does not reduce to eq. (19)")

    failed = False
    results = []
    for case in CASES:
        grid = np.linspace(1.0, case["l1max"], 601)
        exact = np.array([stress(x, case) for x in grid])
        if case["name"] == "rise":  # window of the first maximum: from the onset to the closed form's valley
            d = np.diff(exact)
            k = next(k for k in range(1, len(d)) if d[k - 1] > 0 >= d[k])
            case["window"] = (case["Ld"], grid[k] + 0.3)
        l1m, pm, summary = run_case(case, args)
        at = np.array([stress(x, case) for x in l1m])
        err = np.abs(pm - at) / np.max(exact)
        k = int(np.argmax(err))
        ok_cf, words_cf = shape(case, grid, exact)
        # (a cusp is judged raw: a running mean would round it off)
        ok_m, words_m = shape(case, l1m, pm if case["name"] == "cusp" else smoothed(l1m, pm, args.smooth))
        ok_err = err.max() <= args.tolerance and err.mean() <= args.mean_tolerance
        print(f"{case['name']}: m = {args.m}, {len(l1m)} increments, {summary['nodes']} nodes")
        print(f"  eq. (28):  {'ok  ' if ok_cf else 'FAIL'} {words_cf}")
        print(f"  measured{' (smoothed)' if args.smooth else ''}:  {'ok  ' if ok_m else 'FAIL'} {words_m}")
        print(f"  error:     {'ok  ' if ok_err else 'FAIL'} max |P - P_eq28| / max P_eq28 = {err.max():.4f} at lambda_1 = "
              f"{l1m[k]:.3f} (<= {args.tolerance}); mean {err.mean():.4f} (<= {args.mean_tolerance})")
        failed |= not (ok_cf and ok_m and ok_err)
        results.append((case, grid, exact, l1m, pm, err))
    if args.check:
        return 1 if failed else 0

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    for ax, (case, grid, exact, l1m, pm, err) in zip(axes, results):
        ax.plot(grid, exact, "k-", lw=1.6, label="eq. (28), closed form")
        ax.plot(l1m, pm, "o", ms=3.2, mfc="none", color="tab:red",
                label=f"peridrive, SNES, $\\delta/\\Delta x = {args.m}$ (max err {100 * err.max():.1f}%)")
        ax.axvline(case["Ld"], color="0.6", ls=":", lw=1)
        ax.set_title(case["label"], fontsize=9)
        ax.set_xlabel("$\\lambda_1$")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="lower right" if case["name"] != "rise" else "upper left")
    axes[0].set_ylabel("$P_{11} / \\mu$")
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(args.figure)), exist_ok=True)
    fig.savefig(args.figure, dpi=120)
    print(f"wrote {args.figure}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

#!/usr/bin/env python3
"""tools/crack_path.py on synthetic sheets whose answer is known: a grid of nodes (spacing h) with
damage along y(x) = y0 + A sin(2 pi x / lambda) + s x, the crack's faces one node either side.

Checked: the path follows y(x) within a spacing; a straight tilted crack has no sign changes; the
sine has one sign change per zero inside the sheet (at the half-wavelengths), a wavelength within
2% of lambda and an amplitude within a spacing of A; a window (--from/--to) counts only its own
crossings and forks; a fork (two damaged bands in a column, 4 mm apart) is reported at its column;
on an irregular node set (a mesh) the columns are a spacing wide and give the same answers.
usage: crack_path_test.py SOURCE_DIR
"""
import importlib.util
import math
import sys

import numpy as np

spec = importlib.util.spec_from_file_location("crack_path", f"{sys.argv[1]}/tools/crack_path.py")
cp = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cp)

h = 2.5e-4
checks = []


def check(name, ok, detail):
    checks.append(ok)
    print(("ok   " if ok else "FAIL ") + f"{name}: {detail}")


def sheet(fn, length=0.06, width=0.02, extra=None):
    xs = (np.arange(round(length / h)) + 0.5) * h
    ys = (np.arange(round(width / h)) + 0.5) * h
    X = np.array([(x, y, 0.0) for x in xs for y in ys])
    centre = fn(X[:, 0])
    damage = np.where(np.abs(X[:, 1] - centre) <= 1.01 * h, 0.5, 0.0)
    if extra is not None:
        damage = np.maximum(damage, np.where(extra(X[:, 0], X[:, 1]), 0.5, 0.0))
    return X, damage


def analyse(X, damage, start=None, end=None, band=h):
    xc, yc, _, forks, _ = cp.path(X, damage, 0.3, 0.002)
    xc, yc, forks = cp.window(xc, yc, forks, start, end)
    return cp.oscillation(xc, yc, band), xc, yc, forks


# A straight crack tilted by 0.05: the fit takes the tilt, no sign change.
res, xc, yc, forks = analyse(*sheet(lambda x: 0.008 + 0.05 * x))
check("tilted line", res["sign_changes"] == 0 and abs(res["slope"] - 0.05) < 1e-3 and len(forks) == 0,
      f"{res['sign_changes']} sign changes, slope {res['slope']:.4f} (0.05), {len(forks)} fork columns")

# A sine of wavelength 12 mm and amplitude 1.5 mm about a tilted line, 63 mm long (its last
# zero, at 60 mm, followed by a quarter wave).
lam, amp, length = 0.012, 0.0015, 0.063
curve = lambda x: 0.01 + amp * np.sin(2 * math.pi * x / lam) + 0.02 * x
res, xc, yc, forks = analyse(*sheet(curve, length))
err = np.max(np.abs(yc - curve(xc)))
check("path on the crack", err <= h, f"largest |y - y(x)| {err * 1e3:.3f} mm (spacing {h * 1e3} mm)")
expect = len([k for k in range(1, 100) if k * lam / 2 < length])
check("sine: sign changes", res["sign_changes"] == expect, f"{res['sign_changes']} (expected {expect})")
check("sine: wavelength", abs(res["wavelength"] / lam - 1) < 0.02, f"{res['wavelength'] * 1e3:.3f} mm ({lam * 1e3} mm)")
check("sine: amplitude", abs(res["amplitude"] - amp) <= h, f"{res['amplitude'] * 1e3:.3f} mm ({amp * 1e3} mm, within a spacing)")

# A window of two wavelengths (3 mm to 27 mm): its own crossings only.
res, xc, yc, forks = analyse(*sheet(curve), start=0.003, end=0.027)
inside = [k * lam / 2 for k in range(1, 20) if 0.003 < k * lam / 2 < 0.027]
check("window: sign changes", res["sign_changes"] == len(inside) and xc[0] >= 0.003 and xc[-1] <= 0.027,
      f"{res['sign_changes']} in [3, 27] mm (expected {len(inside)}: crossings at {[round(c * 1e3) for c in inside]} mm)")

# A side crack 4 mm above the path between x = 30 and 35 mm: forks in those columns, none in a
# window before them.
side = lambda x, y: (x > 0.030) & (x < 0.035) & (np.abs(y - (curve(x) + 0.004)) <= 1.01 * h)
X, damage = sheet(curve, extra=side)
res, xc, yc, forks = analyse(X, damage)
check("fork reported", len(forks) > 0 and abs(forks[0] - 0.030) < 2 * h and forks[-1] < 0.035,
      f"{len(forks)} fork columns from x = {forks[0] * 1e3:.2f} to {forks[-1] * 1e3:.2f} mm (side crack 30-35 mm)")
res, xc, yc, forks = analyse(X, damage, end=0.028)
check("no fork before it", len(forks) == 0, f"{len(forks)} fork columns in [0, 28] mm")

# The same sine on an irregular node set (a mesh's nodes: every x differs): columns one spacing
# wide (the scene's), not one node each (binned by the smallest x difference, a straight slit gave
# 28 sign changes).
rng = np.random.default_rng(7)
Xg, _ = sheet(curve, length)
Xm = Xg + np.column_stack([rng.uniform(-0.3 * h, 0.3 * h, (len(Xg), 2)), np.zeros(len(Xg))])
dm = np.where(np.abs(Xm[:, 1] - curve(Xm[:, 0])) <= 1.01 * h, 0.5, 0.0)
xc, yc, _, forks, width = cp.path(Xm, dm, 0.3, 0.002, h)
res = cp.oscillation(xc, yc, h)
check("irregular nodes: columns a spacing wide", abs(width - h) < 1e-12 and res["sign_changes"] == expect,
      f"column width {width * 1e3:.3f} mm, {res['sign_changes']} sign changes (expected {expect})")
Xs = Xm.copy()
ds = np.where(np.abs(Xs[:, 1] - 0.01) <= 1.01 * h, 0.5, 0.0)
xc, yc, _, forks, _ = cp.path(Xs, ds, 0.3, 0.002, h)
res = cp.oscillation(xc, yc, h)
check("irregular nodes, straight crack", res["sign_changes"] == 0, f"{res['sign_changes']} sign changes")

print(f"{sum(checks)} passed, {len(checks) - sum(checks)} failed")
sys.exit(0 if all(checks) else 1)

#!/usr/bin/env python3
"""Short-wavelength stability of Marder's lattice under a homogeneous stretch.

usage: /usr/bin/python3 tools/marder_phonons.py B L1 L2 [--us U] [--uc U] [--cells N]

Builds an N x N periodic triangular lattice (Delta = 1, a = 1, node mass 1) stretched by
diag(L1, L2), evaluates the energy of eqs. (28)-(33) (cutoff u_s and fracture separation u_c in
units of Delta), and prints the lowest eigenvalues of its Hessian (central differences). Two
zeros are the rigid translations; a clearly negative eigenvalue is an unstable mode with a wave
vector on the N x N grid of the Brillouin zone. Needs Debian's python3-numpy.
"""
import argparse

import numpy as np


def lattice(n):
    pts, nbrs = [], []
    for j in range(n):
        for i in range(n):
            pts.append((i + 0.5 * (j % 2), j * np.sqrt(3) / 2))
    for j in range(n):
        for i in range(n):
            o = j % 2
            row = []
            for a, b in [(i + 1, j), (i - 1, j), (i - 1 + o, j + 1), (i + o, j + 1), (i - 1 + o, j - 1), (i + o, j - 1)]:
                sx, sy = (a >= n) - (a < 0), (b >= n) - (b < 0)
                row.append(((b - sy * n) * n + (a - sx * n), sx, sy))
            nbrs.append(row)
    return np.array(pts), nbrs


def energy(x, nbrs, n, F, A, B, us, uc):
    period = np.array([n, n * np.sqrt(3) / 2])
    total = 0.0
    for i, row in enumerate(nbrs):
        d = np.array([x[o] + F @ (np.array([sx, sy]) * period) - x[i] for o, sx, sy in row])
        r = np.linalg.norm(d, axis=1)
        s = r * r - 1
        f = np.where(r < 1 + us, A / 6 * s * (r - 1) / us, A / 6 * s) + B / 9 * s * s  # eq. (31)
        h = 1 / (1 + np.exp((r - uc) / us))  # eq. (32)
        hh = np.outer(h, h)
        np.fill_diagonal(hh, 0)
        total += f.sum() + (hh * (-B / 27) * (d @ d.T + 2) ** 2).sum()  # eqs. (29), (33)
    return total


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("b", type=float)
    ap.add_argument("l1", type=float)
    ap.add_argument("l2", type=float)
    ap.add_argument("--us", type=float, default=0.05)
    ap.add_argument("--uc", type=float, default=3.0)
    ap.add_argument("--cells", type=int, default=4)
    args = ap.parse_args()
    if not (args.l1 > 0 and args.l2 > 0):
        ap.error(f"the stretches must be > 0, got {args.l1}, {args.l2}")
    if not args.us > 0:
        ap.error(f"--us: the switch width (eq. 32 divides by it) must be > 0, got {args.us}")
    if not np.isfinite(args.b) or not np.isfinite(args.uc):
        ap.error("b and --uc must be finite numbers")
    if args.cells < 2:
        ap.error(f"--cells: expected at least 2 cells per side, got {args.cells}")
    n = args.cells
    X, nbrs = lattice(n)
    F = np.diag([args.l1, args.l2])
    A, B = 1.0, 9 * args.b / 8  # eq. (27) with a = m = Delta = 1
    x0 = (F @ X.T).T.reshape(-1)
    dof, e = x0.size, 1e-4
    H = np.zeros((dof, dof))

    def E(v):
        return energy(v.reshape(-1, 2), nbrs, n, F, A, B, args.us, args.uc)

    for p in range(dof):
        for q in range(p, dof):
            val = 0.0
            for sp, sq, w in [(e, e, 1), (e, -e, -1), (-e, e, -1), (-e, -e, 1)]:
                v = x0.copy()
                v[p] += sp
                v[q] += sq
                val += w * E(v)
            H[p, q] = H[q, p] = val / (4 * e * e)
    ev = np.linalg.eigvalsh(H)
    print(f"b = {args.b}, stretch ({args.l1}, {args.l2}), u_s = {args.us}, u_c = {args.uc}: "
          f"lowest Hessian eigenvalues {np.array2string(ev[:4], precision=3)} -> "
          f"{'UNSTABLE' if ev[0] < -1e-4 else 'stable'} on the {n} x {n} wave-vector grid")


if __name__ == "__main__":
    main()

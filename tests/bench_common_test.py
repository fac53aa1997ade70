#!/usr/bin/python3
"""The pure parts of the comparison scripts (benchmarks/bench_common.py, compare_lammps.py,
compare_cabanapd.py): /proc parsing, load shares, quartiles, paired ratios, run order, the timed
loop read from LAMMPS' and CabanaPD's outputs, and the lattice's bond counts. Exit status 0 when
all hold."""
import math
import os
import random
import sys
import unittest
from fractions import Fraction

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))

import bench_common as bc  # noqa: E402
import compare_cabanapd as cpd  # noqa: E402
import compare_lammps as cl  # noqa: E402

STAT_BEFORE = """cpu  300 0 100 1000 10 0 0 0 0 0
cpu0 100 0 50 500 5 0 0 0 0 0
cpu1 200 0 50 500 5 0 0 0 0 0
intr 12345 0 0
ctxt 999
"""
STAT_AFTER = """cpu  480 0 120 1180 10 0 0 20 0 0
cpu0 110 0 50 585 5 0 0 0 0 0
cpu1 370 0 70 595 5 0 0 20 0 0
intr 12400 0 0
"""


class ProcParsing(unittest.TestCase):
    def test_proc_stat(self):
        s = bc.parse_proc_stat(STAT_BEFORE)
        self.assertEqual(sorted(s), [0, 1])  # the aggregate line is skipped
        self.assertEqual(s[0], dict(busy=150, idle=505, steal=0, total=655))

    def test_shares(self):
        sh = bc.cpu_shares(bc.parse_proc_stat(STAT_BEFORE), bc.parse_proc_stat(STAT_AFTER), [0, 1])
        # cpu0: 10 busy of 95 jiffies; cpu1: 190 busy, 20 steal, 95 idle of 305.
        self.assertAlmostEqual(sh["busy"][0], 10 / 95)
        self.assertAlmostEqual(sh["busy"][1], 190 / 305)
        self.assertAlmostEqual(sh["steal"][1], 20 / 305)
        self.assertEqual((sh["busy_jiffies"], sh["total_jiffies"]), (200, 400))
        only1 = bc.cpu_shares(bc.parse_proc_stat(STAT_BEFORE), bc.parse_proc_stat(STAT_AFTER), [1])
        self.assertEqual(only1["total_jiffies"], 305)

    def test_loadavg(self):
        self.assertEqual(bc.parse_loadavg("7.35 3.51 1.97 9/135 12872\n"), (7.35, 3.51, 1.97, 9, 135))


class Statistics(unittest.TestCase):
    def test_quartiles(self):
        self.assertEqual(bc.quartiles([5, 1, 4, 2, 3]), (2, 3, 4))
        q1, med, q3 = bc.quartiles([4, 1, 3, 2])
        self.assertAlmostEqual(q1, 1.75)
        self.assertAlmostEqual(med, 2.5)
        self.assertAlmostEqual(q3, 3.25)
        self.assertEqual(bc.quartiles([0.7]), (0.7, 0.7, 0.7))
        self.assertRaises(ValueError, bc.quartiles, [])
        self.assertEqual(bc.fmt_stat([1.0, 2.0, 3.0], ".2f"), "2.00 [1.50, 2.50]")

    def test_paired_ratios(self):
        # Round 0 slow (the machine drifted), round 1 fast, round 2 lacks the 2-rank run.
        s = [dict(round=0, key=("pd", 1), seconds=4.0), dict(round=0, key=("pd", 2), seconds=2.5),
             dict(round=1, key=("pd", 2), seconds=1.0), dict(round=1, key=("pd", 1), seconds=1.9),
             dict(round=2, key=("pd", 1), seconds=3.0)]
        eff = bc.paired_ratios(s, ("pd", 1), ("pd", 2), scale=0.5)
        self.assertEqual([r for r, _ in eff], [0, 1])
        self.assertAlmostEqual(eff[0][1], 0.8)
        self.assertAlmostEqual(eff[1][1], 0.95)
        # The blocked medians would say 3.0 / (2 x 1.75) = 0.857: neither pair's value.
        self.assertAlmostEqual(bc.quartiles([v for _, v in eff])[1], 0.875)

    def test_round_order(self):
        rounds = [bc.round_order(["A", "B"], [1, 2], k) for k in range(4)]
        self.assertEqual(rounds[0], [("A", 1), ("B", 1), ("B", 2), ("A", 2)])
        self.assertEqual(rounds[1], [("B", 1), ("A", 1), ("A", 2), ("B", 2)])
        self.assertEqual(rounds[2], [("A", 2), ("B", 2), ("B", 1), ("A", 1)])
        self.assertEqual(rounds[3], [("B", 2), ("A", 2), ("A", 1), ("B", 1)])
        # Over four rounds every run takes every position once.
        for pos in range(4):
            self.assertEqual(len({r[pos] for r in rounds}), 4)
        self.assertEqual(bc.round_order(["A"], [1, 2], 1), [("A", 1), ("A", 2)])
        self.assertEqual(bc.round_order(["A"], [1, 2], 2), [("A", 2), ("A", 1)])
        shuffled = bc.round_order(["A", "B"], [1, 2], 0, "random", random.Random(3))
        self.assertEqual(sorted(shuffled), [("A", 1), ("A", 2), ("B", 1), ("B", 2)])


LAMMPS_LOG = """LAMMPS (29 Sep 2021 - Update 2)
Loop time of 2.00447 on 1 procs for 50 steps with 8000 atoms
Performance: 0.000 ns/day
Loop time of 1.442e-06 on 1 procs for 0 steps with 8000 atoms
"""

# A CabanaPD output file in the layout its Solver writes (PMB with fracture): setup lines, the
# timing header, one row per output step, the final table.
CABANAPD_OUT = """CabanaPD Mon Jan  1 00:00:00 2024

Local particles, Ghosted particles, Global particles
32000, 0, 32000
Maximum neighbors: 256, Total neighbors: 6358416

Running PD only.

Init-Time(s): 1.5
#Timestep/Total-steps Simulation-time Total-strain-energy Total-Damage Cumulative-Time(s) Force-Time(s) Comm-Time(s) Integrate-Time(s) Energy-Time(s) Output-Time(s) Particle*steps/s
10/20 4.50e-07 1.00e-06 0.00e+00 3.700000 2.000000 0.010000 0.050000 0.100000 0.020000 1.45e+05
20/20 9.00e-07 4.00e-06 1.00e-03 6.000000 4.000000 0.020000 0.100000 0.250000 0.050000 1.39e+05

#Procs Particles | Total Force Neighbor Comm Integrate Energy Output Other |
1 32000 | \t6.00 4.00 0.10 0.02 0.10 0.25 0.05 0.00 | PERFORMANCE
"""


class Outputs(unittest.TestCase):
    def test_lammps_loop_time(self):
        self.assertEqual(cl.lammps_loop_time(LAMMPS_LOG, 50), 2.00447)  # not the `run 0` after it
        self.assertRaises(ValueError, cl.lammps_loop_time, LAMMPS_LOG, 100)

    def test_lammps_input_times_no_dump(self):
        text = cl.lammps_input(20, 50)
        timed = text.index("run 50")
        self.assertNotIn("dump", text[:timed])
        self.assertGreater(text.index("dump d all custom"), timed)
        self.assertIn("run 0", text[timed:])

    def test_cabanapd_out(self):
        p = cpd.parse_cabanapd_out(CABANAPD_OUT)
        self.assertEqual((p["particles"], p["total_neighbors"], p["init_seconds"]), (32000, 6358416, 1.5))
        self.assertEqual([r["step"] for r in p["rows"]], [10, 20])
        sec, steps = cpd.cabanapd_loop_seconds(p)
        # (6.0 - 3.7) - (0.25 - 0.1) - (0.05 - 0.02) = 2.12 s over 10 steps.
        self.assertEqual(steps, 10)
        self.assertAlmostEqual(sec, 0.212)
        self.assertRaises(ValueError, cpd.cabanapd_loop_seconds, dict(rows=p["rows"][:1]))

    def test_cabanapd_input(self):
        import json
        j = json.loads(cpd.cabanapd_input((400, 160, 8), 100))
        self.assertEqual(int(j["final_time"]["value"] / j["timestep"]["value"]), 100)  # CabanaPD's num_steps
        self.assertEqual(j["output_frequency"]["value"], 50)
        self.assertEqual([round(v / n, 12) for v, n in zip(j["system_size"]["value"], (400, 160, 8))], [0.00025] * 3)


def brute_bonds(cells, m):
    """Ordered bonds and notch-crossing ordered bonds of a small plate, point by point, exact."""
    nx, ny, nz = cells
    total = notch = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                for a in range(-m, m + 1):
                    for b in range(-m, m + 1):
                        for c in range(-m, m + 1):
                            if (a, b, c) == (0, 0, 0) or a * a + b * b + c * c > m * m:
                                continue
                            if not (0 <= i + a < nx and 0 <= j + b < ny and 0 <= k + c < nz):
                                continue
                            total += 1
                            y1, y2 = Fraction(2 * j + 1 - ny), Fraction(2 * (j + b) + 1 - ny)
                            if y1 * y2 < 0:
                                x1 = Fraction(2 * i + 1 - nx)
                                if x1 + (-y1 / (y2 - y1)) * 2 * a <= 0:
                                    notch += 1
    return total, notch


class Lattice(unittest.TestCase):
    def test_bond_counts(self):
        for cells in [(12, 10, 3), (9, 8, 2)]:
            total, notch = brute_bonds(cells, 4)
            self.assertEqual(cpd.lattice_bonds(cells)[0], total)
            self.assertEqual(cpd.notch_bonds(cells), notch)
        self.assertEqual(cpd.lattice_bonds((400, 160, 8)), (105871776, 256))
        self.assertEqual(cpd.notch_bonds((400, 160, 8)), 497112)

    def test_material(self):
        self.assertAlmostEqual(cpd.K, 48e9)
        self.assertAlmostEqual(cpd.critical_stretch(), math.sqrt(5 * 3.8 / (9 * 48e9 * (0.001 + 1e-10))))


if __name__ == "__main__":
    unittest.main()

#!/usr/bin/python3
"""Predicted strong-scaling efficiency of peridrive from a partition report and a network model.

Input: the CSV of `build/peridrive-partition scene.yaml --parts 2,4,...,4096 --csv FILE` (per P: the
largest part's owned bonds, ghosts and neighbour parts). Model of one explicit step on P ranks:

  T_comp(P) = t_bond * max_owned_bonds                       (the slowest rank sets the pace)
  T_halo(P) = max_neighbour_parts * latency + max_ghosts * 24 B / bandwidth   (3 doubles per ghost)
  T_coll(P) = 0.15 * ceil(log2 P) * latency    (energy row every 10 steps, health check every 20:
                                                 allreduces of a few doubles, tree depth log2 P)
  no overlap:   T(P) = T_comp + T_halo + T_coll
  overlap:      T(P) = max(t_bond * interior bonds, T_halo) + t_bond * max_boundary_bonds + T_coll
                (the rows with no ghost neighbour are computed while the halo flies, as the step
                does; the rows next to a ghost after it; interior = max_owned - max_boundary. A
                report without boundary columns falls back to max(T_comp, T_halo) + T_coll)
  efficiency    E(P) = t_bond * ordered_bonds / (P * T(P))

A run on P ranks writes the same halo figures in summary.json ("halo": max_ghosts,
max_neighbour_ranks, max_owned_bonds, max_boundary_bonds), so the report's terms can be checked
against a run (tests/halo_report.sh does, on 4 ranks). --target prints the largest P of the report
at which each model keeps E(P) >= target.

t_bond is the measured cost of one ordered bond update on one core (full step, docs/performance.md);
latency and bandwidth describe one rank's link (defaults: 2 us, 5 GB/s, an InfiniBand-class
network shared by the cores of a node). Memory bandwidth contention inside a node, OS noise and
the serial partitioner are not modelled; the partitioner is reported separately (metis_seconds).

  /usr/bin/python3 cluster/scaling_model.py cluster/partition_1M.csv --out cluster/scaling_1M
"""
import argparse
import csv
import math
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("report", help="CSV written by peridrive-partition --csv")
    ap.add_argument("--bond-seconds", type=float, default=1 / 1.3e9,
                    help="seconds per ordered bond update per core (default 1/1.3e9: the 1M-node membrane's measured full step on one core)")
    ap.add_argument("--latency", type=float, default=2e-6, help="message latency [s] (default 2e-6)")
    ap.add_argument("--bandwidth", type=float, default=5e9, help="bytes/s per rank (default 5e9)")
    ap.add_argument("--out", default=None, help="write OUT.csv and OUT.png")
    ap.add_argument("--target", type=float, default=0.7,
                    help="efficiency whose largest P is reported (default 0.7)")
    ap.add_argument("--method", default=None,
                    help="partitioner rows to model when the report has several (rcb, cells or bonds; default: "
                         "the first row's, which peridrive-partition lists first: the one peridrive takes)")
    a = ap.parse_args()
    rows = list(csv.DictReader(open(a.report)))
    method = a.method or (rows[0].get("method") if rows else None)
    rows = [r for r in rows if r.get("method", method) == method]
    if not rows:
        sys.exit(f"{a.report}: no rows")
    bonds = float(rows[0]["ordered_bonds"])
    t1 = a.bond_seconds * bonds
    out = []
    for r in rows:
        P = int(r["parts"])
        owned = float(r["max_owned_bonds"])
        comp = a.bond_seconds * owned
        halo = float(r["max_neighbour_parts"]) * a.latency + float(r["max_ghosts"]) * 24.0 / a.bandwidth
        coll = 0.15 * math.ceil(math.log2(P)) * a.latency
        t_no = comp + halo + coll
        if r.get("max_boundary_bonds"):
            boundary = float(r["max_boundary_bonds"])
            t_ov = max(a.bond_seconds * (owned - boundary), halo) + a.bond_seconds * boundary + coll
        else:
            boundary = float("nan")
            t_ov = max(comp, halo) + coll
        nodes_per_rank = float(r["nodes"]) / P
        out.append(dict(parts=P, nodes_per_rank=nodes_per_rank, step_seconds_no_overlap=t_no,
                        step_seconds_overlap=t_ov, efficiency_no_overlap=t1 / (P * t_no),
                        efficiency_overlap=t1 / (P * t_ov), load_balance=float(r["mean_owned_bonds"]) / owned,
                        halo_fraction=halo / t_no, boundary_fraction=boundary / owned,
                        max_ghosts=float(r["max_ghosts"]), max_neighbour_parts=float(r["max_neighbour_parts"]),
                        max_message_bytes=24.0 * float(r.get("max_message_ghosts") or "nan"),
                        metis_seconds=float(r["metis_seconds"])))
    print(f"# {int(bonds)} ordered bonds, t_bond = {a.bond_seconds:.3g} s, latency {a.latency:.3g} s, "
          f"bandwidth {a.bandwidth:.3g} B/s; single-core step {t1:.4g} s")
    print("| P | nodes/rank | ghosts (max) | neighbours (max) | largest message [B] | boundary bonds | "
          "step [s] (no overlap) | efficiency (no overlap) | efficiency (overlap) | load balance | partitioner [s] |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for o in out:
        print(f"| {o['parts']} | {o['nodes_per_rank']:.0f} | {o['max_ghosts']:.0f} | {o['max_neighbour_parts']:.0f} | "
              f"{o['max_message_bytes']:.0f} | {o['boundary_fraction']:.3f} | {o['step_seconds_no_overlap']:.3g} | "
              f"{o['efficiency_no_overlap']:.3f} | {o['efficiency_overlap']:.3f} | {o['load_balance']:.3f} | {o['metis_seconds']:.3g} |")
    for key, label in (("efficiency_no_overlap", "no overlap"), ("efficiency_overlap", "overlap")):
        kept = [o["parts"] for o in out if o[key] >= a.target]
        print(f"# largest P with E >= {a.target:g} ({label}): " + (str(max(kept)) if kept else "none in the report")
              + (" (the report's largest P: extend --parts)" if kept and max(kept) == out[-1]["parts"] else ""))
    if a.out:
        with open(a.out + ".csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(out[0]))
            w.writeheader()
            w.writerows(out)
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 4))
        P = [o["parts"] for o in out]
        ax.semilogx(P, [o["efficiency_no_overlap"] for o in out], "o-", base=2, label="no overlap")
        ax.semilogx(P, [o["efficiency_overlap"] for o in out], "s--", base=2, label="halo overlapped")
        ax.semilogx(P, [o["load_balance"] for o in out], ":", base=2, color="gray", label=f"load balance ({method})")
        ax.set_xlabel("ranks P")
        ax.set_ylabel("predicted strong-scaling efficiency")
        ax.set_ylim(0, 1.05)
        ax.set_title(f"{int(float(rows[0]['nodes']))} nodes, {bonds:.3g} ordered bonds, {method} partitions")
        ax.grid(True, alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(a.out + ".png", dpi=120)
        print(f"wrote {a.out}.csv and {a.out}.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())

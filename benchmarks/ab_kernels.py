#!/usr/bin/python3
"""Two builds of bench_kernels side by side: runs A B A B ... and prints median throughputs and
their ratio per benchmark. Prints figures only; asserts nothing.

  /usr/bin/python3 benchmarks/ab_kernels.py OLD/bench_kernels build/benchmarks/bench_kernels \
      [--rounds 5] [--filter 'kernel'] [--ranks 1] [--repetitions 1]

Each round runs every selected benchmark once in each binary (Google Benchmark, its own
iteration count; with --repetitions R, R repetitions of which the fastest counts); the table gives the median over rounds of `bond_updates/s` (per CPU
second of the process; MPI ranks poll while they wait, so for the full step that is wall time),
their ratio B/A, and the median and range of the ratios within each round ("paired"). Alternating spreads the noise of a
shared machine over both binaries alike, so the ratio is meaningful where absolute figures are
not. With --ranks 2 both run under `mpirun -n 2` (full-step benchmarks only).
"""
import argparse
import json
import os
import shutil
import statistics
import subprocess
import tempfile


def run(binary, bench_filter, ranks, mpirun, repetitions):
    cmd = [binary, f"--benchmark_filter={bench_filter}", "--benchmark_format=json",
           f"--benchmark_repetitions={repetitions}"]
    if ranks == 1:
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        report = json.loads(out)
    else:
        # Under mpirun every rank reports and the standard outputs interleave: each rank writes
        # its own file (Open MPI's rank variable), and rank 0's is read.
        with tempfile.TemporaryDirectory() as work:
            wrapped = ["sh", "-c", f'exec "$0" "$@" --benchmark_out={work}/rank$OMPI_COMM_WORLD_RANK.json '
                                   "--benchmark_out_format=json"] + cmd
            subprocess.run([mpirun, "--allow-run-as-root", "-n", str(ranks)] + wrapped, check=True,
                           capture_output=True, text=True)
            with open(os.path.join(work, "rank0.json")) as f:
                report = json.load(f)
    # With repetitions, the fastest of them: interference from other work on a shared machine
    # only slows a run down, so the best of a few is the steadier figure.
    best = {}
    for b in report["benchmarks"]:
        if b.get("run_type", "iteration") != "iteration":
            continue
        name = b.get("run_name", b["name"])
        if name not in best or b["bond_updates/s"] > best[name]["bond_updates/s"]:
            best[name] = b
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("a", help="bench_kernels binary A (e.g. a build of an older revision)")
    ap.add_argument("b", help="bench_kernels binary B")
    ap.add_argument("--rounds", type=int, default=5, help="A B rounds (default 5)")
    ap.add_argument("--filter", default="kernel", help="Google Benchmark filter (default 'kernel')")
    ap.add_argument("--ranks", type=int, default=1, help="MPI ranks (default 1)")
    ap.add_argument("--repetitions", type=int, default=1,
                    help="repetitions per run, the fastest kept (default 1)")
    ap.add_argument("--mpirun", default=shutil.which("mpirun") or "mpirun")
    args = ap.parse_args()
    rates = {"A": {}, "B": {}}
    meta = {}
    for _ in range(args.rounds):
        for label, binary in (("A", args.a), ("B", args.b)):
            for name, b in run(binary, args.filter, args.ranks, args.mpirun, args.repetitions).items():
                rates[label].setdefault(name, []).append(b["bond_updates/s"])
                meta.setdefault(name, {})[label] = b.get("bytes_per_bond")
    print(f"{args.rounds} rounds A B, {args.ranks} rank(s), best of {args.repetitions} per run; "
          "medians of bond_updates/s")
    print(f"{'benchmark':45s} {'A':>10s} {'B':>10s} {'B/A':>6s} {'paired':>6s} {'range':>11s} {'bytes/bond A':>13s} {'B':>6s}")
    for name in rates["A"]:
        if name not in rates["B"]:
            continue
        a, b = statistics.median(rates["A"][name]), statistics.median(rates["B"][name])
        ba, bb = meta[name].get("A"), meta[name].get("B")
        fmt = lambda x: f"{x:.2f}" if x else "-"
        # B/A within each round (the two runs minutes apart at most): median and range.
        paired = [y / x for x, y in zip(rates["A"][name], rates["B"][name])]
        spread = f"{min(paired):.2f}-{max(paired):.2f}"
        print(f"{name:45s} {a:10.3e} {b:10.3e} {b / a:6.2f} {statistics.median(paired):6.2f} {spread:>11s} "
              f"{fmt(ba):>13s} {fmt(bb):>6s}")


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""Helpers shared by the code-to-code comparisons (compare_lammps.py, compare_cabanapd.py).

What they guarantee, so that a figure can be trusted on a shared 2-core VM:
  * pinning: rank r of a run on R ranks is pinned to the r-th core of the run's core list (the
    first R of --cpus) by the launcher wrapper before it starts the code (sched_setaffinity, as
    `taskset -c` does; mpirun itself binds nothing), the same rule for every code; the core set
    each rank's process actually had is read back from /proc/PID/status and recorded;
  * machine load: before each measured run the machine's cores (--load-scope run: only those the
    run will use) are watched for a window (1 s by default) through /proc/stat; while other
    processes keep any of them busier than a threshold the run waits (up to a limit), and then
    runs anyway, marked `loaded`. During the run the same counters give the share of those cores'
    time taken by other processes (busy time minus the CPU time of the run's own processes) and
    the hypervisor's steal; a run above the threshold is marked too.
    Other people's `nice` does not shield a run: with the kernel's autogroup scheduling
    (/proc/sys/kernel/sched_autogroup_enabled = 1, as on these VMs) each session gets an equal
    share of a busy core whatever its processes' nice values;
  * order: a round runs every (code, ranks) combination once; successive rounds rotate the order
    (which code first, which rank count first) so that no combination always runs first or last;
  * statistics from pairs: a ratio (code against code at one rank count, or 1 rank against P ranks
    of one code) is formed within each round from runs a few seconds apart, and the median and
    quartiles of those per-round ratios are reported, never a ratio of medians of blocked runs.

Pure parts (parse_proc_stat, cpu_shares, parse_loadavg, quartiles, paired_ratios, round_order) are
checked by tests/bench_common_test.py.
"""
import csv
import json
import os
import random
import resource
import shutil
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))


# ---------------------------------------------------------------------------------------------
# /proc parsing (pure)

def parse_proc_stat(text):
    """Per-CPU jiffy counters of /proc/stat: {cpu: dict(busy, idle, steal, total)}.

    busy = user + nice + system + irq + softirq (guest time is already inside user and nice),
    idle = idle + iowait, total = busy + idle + steal."""
    cpus = {}
    for line in text.splitlines():
        if not line.startswith("cpu") or line.startswith("cpu "):
            continue
        parts = line.split()
        name, values = parts[0], [int(v) for v in parts[1:]]
        values += [0] * (8 - len(values))
        user, nice, system, idle, iowait, irq, softirq, steal = values[:8]
        busy = user + nice + system + irq + softirq
        cpus[int(name[3:])] = dict(busy=busy, idle=idle + iowait, steal=steal, total=busy + idle + iowait + steal)
    return cpus


def cpu_shares(before, after, cpus):
    """Shares of the time of the listed CPUs between two parse_proc_stat snapshots:
    dict(busy=[per cpu], steal=[per cpu], busy_jiffies=sum, total_jiffies=sum)."""
    busy, steal, bj, tj = [], [], 0, 0
    for c in cpus:
        d = {k: after[c][k] - before[c][k] for k in ("busy", "steal", "total")}
        t = max(d["total"], 1)
        busy.append(d["busy"] / t)
        steal.append(d["steal"] / t)
        bj += d["busy"]
        tj += d["total"]
    return dict(busy=busy, steal=steal, busy_jiffies=bj, total_jiffies=tj)


def parse_loadavg(text):
    """/proc/loadavg: (load1, load5, load15, runnable, scheduling entities)."""
    p = text.split()
    running, total = p[3].split("/")
    return float(p[0]), float(p[1]), float(p[2]), int(running), int(total)


def read(path):
    with open(path) as f:
        return f.read()


def clock_ticks():
    return os.sysconf("SC_CLK_TCK")


# ---------------------------------------------------------------------------------------------
# Statistics (pure)

def quartiles(xs):
    """(q1, median, q3) with linear interpolation between order statistics (numpy's default,
    Python's method='inclusive'); one value gives (x, x, x)."""
    xs = sorted(xs)
    if not xs:
        raise ValueError("no values")
    if len(xs) == 1:
        return xs[0], xs[0], xs[0]
    q1, med, q3 = statistics.quantiles(xs, n=4, method="inclusive")
    return q1, med, q3


def paired_ratios(samples, num, den, value="seconds", scale=1.0):
    """Ratios num/den formed within each round: samples is a list of dicts with keys `round`,
    `key` and `value`; num and den are keys (e.g. ("lammps", 2) and ("peridrive", 2)). A round
    lacking either gives no ratio. Returns [(round, scale * num_value / den_value)] in round order."""
    by = {}
    for s in samples:
        by.setdefault(s["round"], {})[s["key"]] = s[value]
    out = []
    for r in sorted(by):
        if num in by[r] and den in by[r] and by[r][den] > 0:
            out.append((r, scale * by[r][num] / by[r][den]))
    return out


def round_order(keys_codes, ranks, k, mode="rotate", rng=None):
    """The runs of round k as [(code, ranks)]. mode 'rotate': codes in order on even rounds and
    reversed on odd ones, rank counts reversed every other pair of rounds, and the runs snake
    (1: A B, 2: B A) so that the two codes at one rank count run back to back and the last code
    of one rank count is the first of the next: over four rounds every code and rank count
    takes every position. mode 'random': a shuffle by rng (random.Random)."""
    codes = list(keys_codes)
    rk = list(ranks)
    if mode == "random":
        runs = [(c, r) for r in rk for c in codes]
        rng.shuffle(runs)
        return runs
    if k % 2:
        codes.reverse()
    if (k // 2) % 2:
        rk.reverse()
    runs = []
    for i, r in enumerate(rk):
        cs = codes if i % 2 == 0 else codes[::-1]
        runs += [(c, r) for c in cs]
    return runs


def fmt_stat(xs, spec=".3g"):
    """'median [q1, q3]' of xs, or '-' when empty."""
    if not xs:
        return "-"
    q1, med, q3 = quartiles(xs)
    if len(xs) == 1:
        return f"{med:{spec}}"
    return f"{med:{spec}} [{q1:{spec}}, {q3:{spec}}]"


# ---------------------------------------------------------------------------------------------
# Machine load

class LoadWatch:
    """Load of a set of CPUs before and during a run (see the module docstring)."""

    def __init__(self, threshold=0.10, window=1.0, max_wait=60.0, scope="all"):
        """scope 'all': watch every CPU of the machine (a 1-rank run shares caches and memory
        bandwidth with the other cores); 'run': only the cores the run is pinned to."""
        self.threshold, self.window, self.max_wait, self.scope = threshold, window, max_wait, scope

    def watched(self, cpus):
        return sorted(parse_proc_stat(read("/proc/stat"))) if self.scope == "all" else list(cpus)

    def idle_check(self, cpus):
        """Waits until other processes use each listed CPU less than `threshold` over `window`
        seconds, for at most max_wait seconds. Returns dict(pre_busy: the largest share of a listed
        CPU that others took in the last window, pre_steal: likewise the hypervisor's steal,
        loadavg: 1-minute load average, waited: seconds waited, pre_quiet: both below threshold)."""
        t0 = time.monotonic()
        while True:
            before = parse_proc_stat(read("/proc/stat"))
            time.sleep(self.window)
            sh = cpu_shares(before, parse_proc_stat(read("/proc/stat")), cpus)
            busy, steal = max(sh["busy"]), max(sh["steal"])
            quiet = busy < self.threshold and steal < self.threshold
            elapsed = time.monotonic() - t0
            if quiet or elapsed >= self.max_wait:
                return dict(pre_busy=busy, pre_steal=steal, loadavg=parse_loadavg(read("/proc/loadavg"))[0],
                            waited=max(elapsed - self.window, 0.0), pre_quiet=quiet)
            time.sleep(1.0)

    def start(self, cpus):
        ru = resource.getrusage(resource.RUSAGE_CHILDREN)
        return dict(cpus=cpus, stat=parse_proc_stat(read("/proc/stat")), cpu=ru.ru_utime + ru.ru_stime,
                    wall=time.monotonic())

    def stop(self, mark):
        """Share of the run's CPUs taken by other processes during the run (the CPUs' busy time less
        the CPU time of this process' children, i.e. the run's own processes, over the CPUs' time;
        the whole run, MPI start and setup included) and the largest steal share."""
        ru = resource.getrusage(resource.RUSAGE_CHILDREN)
        ours = ru.ru_utime + ru.ru_stime - mark["cpu"]
        sh = cpu_shares(mark["stat"], parse_proc_stat(read("/proc/stat")), mark["cpus"])
        total_s = sh["total_jiffies"] / clock_ticks()
        others = max(sh["busy_jiffies"] / clock_ticks() - ours, 0.0) / max(total_s, 1e-9)
        return dict(run_others=others, run_steal=max(sh["steal"]), run_wall=time.monotonic() - mark["wall"])

    def loaded(self, rec):
        return (not rec["pre_quiet"]) or rec["run_others"] >= self.threshold or rec["run_steal"] >= self.threshold


def load_summary(recs):
    """One line on the load seen by a list of sample records (from LoadWatch)."""
    if not recs:
        return "no runs"
    la = [r["loadavg"] for r in recs]
    pre = [r["pre_busy"] for r in recs]
    run = [r["run_others"] for r in recs]
    st = [max(r["pre_steal"], r["run_steal"]) for r in recs]
    flagged = sum(1 for r in recs if r["loaded"])
    return (f"loadavg(1 min) {min(la):.2f}-{max(la):.2f}; others' share of the watched cores before a run "
            f"median {statistics.median(pre):.0%} (max {max(pre):.0%}), during it median "
            f"{statistics.median(run):.0%} (max {max(run):.0%}); steal max {max(st):.0%}; "
            f"waited {sum(r['waited'] for r in recs):.0f} s in all; {flagged} of {len(recs)} runs marked loaded")


def machine_description():
    model = "?"
    try:
        for line in read("/proc/cpuinfo").splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{os.cpu_count()} CPUs ({model}), kernel {os.uname().release}"


# ---------------------------------------------------------------------------------------------
# Launching pinned MPI runs

def wrap(argv):
    """--wrap FILE CPUS -- cmd...: pin this rank to CPUS[rank] (comma list; '-' for no pinning),
    run cmd, write FILE.<rank> as JSON: peak RSS (kB) of cmd and the CPU list its process had
    (at the last reading, within 50 ms of its end for runs under 2 s, 0.5 s for longer ones)."""
    out, cpus, cmd = argv[0], argv[1], argv[3:]
    rank = int(os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK", "0")))
    if cpus != "-":
        lst = [int(c) for c in cpus.split(",")]
        os.sched_setaffinity(0, {lst[rank % len(lst)]})
    p = subprocess.Popen(cmd)
    # The code's own CPU list, read while it runs: every 50 ms for its first 2 s, then every 0.5 s,
    # and the last reading recorded (its binding while it steps). MPI initialisation moves a
    # process for a while: hwloc's topology probe visits every core, and holds rank 1 of a 2-rank
    # run on core 0 for about 200 ms on these VMs, a third of a short run's life.
    allowed = None
    t = 0.0
    while True:
        dt = 0.05 if t < 2.0 else 0.5
        try:
            p.wait(timeout=dt)
            break
        except subprocess.TimeoutExpired:
            t += dt
            try:
                for line in read(f"/proc/{p.pid}/status").splitlines():
                    if line.startswith("Cpus_allowed_list:"):
                        allowed = line.split(":", 1)[1].strip()
            except OSError:
                pass
    if allowed is None:  # finished within 50 ms: it inherited this process' set
        allowed = ",".join(str(c) for c in sorted(os.sched_getaffinity(0)))
    with open(f"{out}.{rank}", "w") as f:
        json.dump(dict(rank=rank, rss_kb=resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss,
                       cpus=allowed), f)
    return p.returncode


def launch(ranks, cmd, cwd, mpirun, cpus, env_extra=None, tag="rss"):
    """Runs cmd on `ranks` MPI ranks, rank r pinned to cpus[r] (cpus None: unpinned). Returns
    (combined output, peak RSS summed over ranks [bytes], binding 'r0:cpu0 r1:cpu1')."""
    pin = ",".join(str(c) for c in cpus[:ranks]) if cpus else "-"
    full = [mpirun, "-n", str(ranks), "--allow-run-as-root", "--bind-to", "none", sys.executable,
            os.path.join(HERE, "bench_common.py"), "--wrap", tag, pin, "--"] + cmd
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMP_NUM_THREADS="1", **(env_extra or {}))
    r = subprocess.run(full, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stdout[-3000:]}")
    recs = []
    for f in sorted(os.listdir(cwd)):
        if f.startswith(tag + "."):
            recs.append(json.loads(read(os.path.join(cwd, f))))
            os.remove(os.path.join(cwd, f))
    recs.sort(key=lambda x: x["rank"])
    binding = " ".join(f"r{x['rank']}:{x['cpus']}" for x in recs)
    return r.stdout, sum(x["rss_kb"] for x in recs) * 1024.0, binding


def run_cpus(arg):
    """The --cpus option: a comma list, default this process' allowed CPUs in order."""
    if arg:
        return [int(c) for c in arg.split(",")]
    return sorted(os.sched_getaffinity(0))


def add_common_options(ap, default_reps):
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2], help="MPI ranks (default 1 2)")
    ap.add_argument("--reps", type=int, default=default_reps,
                    help=f"rounds; each runs every code on every rank count once (default {default_reps})")
    ap.add_argument("--cpus", help="cores to pin to, rank r on the r-th (default: all allowed, in order)")
    ap.add_argument("--order", choices=["rotate", "random"], default="rotate",
                    help="order of the runs within a round (default rotate)")
    ap.add_argument("--seed", type=int, default=1, help="seed of --order random (default 1)")
    ap.add_argument("--load-threshold", type=float, default=0.10,
                    help="others' share of a run's core above which it waits / is marked loaded (default 0.10)")
    ap.add_argument("--load-window", type=float, default=1.0, help="seconds of the idle check (default 1)")
    ap.add_argument("--max-wait", type=float, default=60.0,
                    help="seconds to wait for quiet cores before running anyway, marked (default 60)")
    ap.add_argument("--load-scope", choices=["all", "run"], default="all",
                    help="cores whose load is checked: all of the machine's (default; they share caches and "
                         "memory bandwidth) or only those the run is pinned to")
    ap.add_argument("--mpirun", default=shutil.which("mpirun") or "mpirun")


def measure_round(watch, cpus, ranks, fn):
    """Idle check, then fn() between the load counters; returns (fn's result, load record)."""
    use = watch.watched(cpus[:ranks])
    rec = watch.idle_check(use)
    mark = watch.start(use)
    res = fn()
    rec.update(watch.stop(mark))
    rec["loaded"] = watch.loaded(rec)
    return res, rec


def describe_load(rec):
    return (f"others {rec['pre_busy']:.0%} before (waited {rec['waited']:.0f} s), {rec['run_others']:.0%} during, "
            f"steal {max(rec['pre_steal'], rec['run_steal']):.0%}, loadavg {rec['loadavg']:.2f}"
            + (" LOADED" if rec["loaded"] else ""))


def write_csv(path, rows):
    """The rows (dicts) as CSV, the union of their keys as sorted columns."""
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=sorted({k for r in rows for k in r}))
        w.writeheader()
        w.writerows(rows)


def new_rng(seed):
    return random.Random(seed)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--wrap":
        sys.exit(wrap(sys.argv[2:]))
    sys.exit(__doc__)

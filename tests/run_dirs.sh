#!/usr/bin/env bash
# Runs and their output directories, on real processes (2 ranks):
#  command line  the first word that is no option is the scene, whatever its name (Upper.YAML is
#                read); a missing file, a directory, /dev/zero, a FIFO, an unreadable or a 65 MiB
#                file, a second scene, an option value that is an option or empty, --out twice:
#                exit status 2, one message naming it, nothing created (the working directory
#                stays empty)
#  output dir    under a regular file, a regular file, a directory that takes no file: exit
#                status 2 naming it, before setup (the scene's own setup error is not reached), no
#                MPI_ABORT; a run refused during setup removes the directories it made
#  lock          a second run and a resume into a directory in use are refused naming the holder
#                (pid and host); a lock held by another process is refused; a lock file left by a
#                dead process is taken over silently; the lock file is gone after a run
#  no flock      a file system without flock (a preloaded flock() failing with ENOLCK): one
#                warning, the run completes
#  resume        into another scene's directory (its scene.resolved.yaml, or only its frames.h5,
#                checkpoint or series): exit status 2, the directory unchanged (file hashes); into
#                a copy of the same run, a new or an empty directory: allowed, and the copy ends
#                bit for bit where the run resumed in its own directory ends; checkpoints later
#                than the one resumed from are removed
#  fresh         a fresh run into another run's directory leaves none of that run's files (its
#                checkpoints, tips, temporaries) to be mixed in
# usage: run_dirs.sh PERIDRIVE SOURCE_DIR FLOCK_SHIM MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 shim=$3 mpiexec=$4
shift 4
mpi=("$mpiexec" -n 2 "$@")
py=/usr/bin/python3
work=$(mktemp -d)
in=$work/in
mkdir "$in"
holder=""
cleanup() {
  [ -n "$holder" ] && kill "$holder" 2> /dev/null
  chattr -i "$in/imm" 2> /dev/null
  rm -rf "$work"
}
trap cleanup EXIT
scene=$src/tests/restart/small_slit.yaml
pass=0 fail=0
ok() { echo "ok   $1"; pass=$((pass + 1)); }
bad() { echo "FAIL $1"; fail=$((fail + 1)); }
line_of() { grep -n -m1 -- "$2" "$1" | cut -d: -f1; }

# refused NAME EXPECTED_SUBSTRING -- peridrive arguments...: exit status 2, exactly one error line
# holding the substring, no MPI_ABORT, and the (empty) working directory left empty.
refused() {
  local name=$1 want=$2
  shift 3
  local cwd="$work/cwd-$name"
  mkdir "$cwd"
  (cd "$cwd" && timeout -k 5 300 "${mpi[@]}" "$peridrive" "$@" --quiet > "$work/stdout" 2> "$work/stderr")
  local rc=$? n left
  n=$(grep -c "peridrive: error:" "$work/stderr")
  left=$(ls -A "$cwd")
  if [ "$rc" -eq 2 ] && [ "$n" -eq 1 ] && grep -qF -- "$want" "$work/stderr" && ! grep -q MPI_ABORT "$work/stderr" &&
     [ -z "$left" ]; then
    ok "$name: $(grep "peridrive: error:" "$work/stderr" | cut -c1-200)"
  else
    bad "$name: exit status $rc, $n error lines, working directory holds '$left'; expected '$want'"
    cat "$work/stderr"
  fi
}

# --- command line -----------------------------------------------------------------------------
sed 's/density: 1200/density: -1200/' "$scene" > "$in/Upper.YAML"
refused upper_yaml "$in/Upper.YAML:$(line_of "$in/Upper.YAML" 'density: -1200'): materials.rubber.density: expected a positive number" -- "$in/Upper.YAML"
refused typo "cannot read scene file 'typo': No such file or directory" -- typo
mkdir "$in/adir.yaml"
refused directory "cannot read scene file '$in/adir.yaml': is a directory" -- "$in/adir.yaml"
refused dev_zero "cannot read scene file '/dev/zero': not a regular file (a character device)" -- /dev/zero
mkfifo "$in/fifo.yaml"
refused fifo "cannot read scene file '$in/fifo.yaml': not a regular file (a FIFO)" -- "$in/fifo.yaml"
# A regular file whose read fails (reading address 0 of the reader's own memory), for root too.
refused unreadable "cannot read scene file '/proc/self/mem': Input/output error" -- /proc/self/mem
truncate -s 65M "$in/big.yaml"
refused too_large "cannot read scene file '$in/big.yaml': larger than 64 MiB (68157440 bytes)" -- "$in/big.yaml"
cp "$scene" "$in/Scene.yml"
refused second_scene "unexpected argument '$in/Scene.yml': the scene is '$scene'" -- "$scene" "$in/Scene.yml"
refused out_takes_option "option --out needs a value, got the option '--dry-run'" -- "$scene" --out --dry-run
refused resume_takes_option "option --resume needs a value, got the option '--quiet'" -- --resume --quiet
refused set_takes_option "option --set needs a value, got the option '--print-scene'" -- "$scene" --set --print-scene
refused out_empty "option --out: expected a value, got an empty string" -- "$scene" --out ""
refused out_eq_empty "option --out: expected a value, got an empty string" -- "$scene" --out=
refused out_twice "option --out given twice ('a' and 'b')" -- "$scene" --out a --out b
refused lone_dash "unexpected argument '-'" -- "$scene" -
# Names the old parser ignored are scenes now; PETSc options and their values still pass through.
cp "$scene" "$in/Valid.YAML"
if (cd "$work" && "${mpi[@]}" "$peridrive" "$in/Scene.yml" --print-scene > "$work/p.out" 2> "$work/p.err") &&
   grep -qx "name: small-slit" "$work/p.out"; then
  ok "scene_yml: Scene.yml is the scene (name: small-slit)"
else
  bad "scene_yml: $(head -3 "$work/p.out")"; cat "$work/p.err"
fi
if (cd "$work" && "${mpi[@]}" "$peridrive" -partition_method cells "$in/Valid.YAML" -partition_cells_per_part 8 --dry-run \
      > "$work/p.out" 2> "$work/p.err") && grep -q "^estimate: 1600 nodes" "$work/p.out"; then
  ok "petsc_options: -partition_method cells Valid.YAML: the scene's 1600 nodes"
else
  bad "petsc_options: $(head -3 "$work/p.out")"; cat "$work/p.err"
fi
# A misspelled partitioner option is read by nobody: warned of, the run goes on.
if (cd "$work" && "${mpi[@]}" "$peridrive" "$in/Valid.YAML" -partition_methd rcb --dry-run > "$work/p.out" 2> "$work/p.err") &&
   [ "$(grep -c "peridrive: warning: -partition_methd: a partitioner option this run did not read" "$work/p.err")" -eq 1 ]; then
  ok "partition_option_misspelled: one warning"
else
  bad "partition_option_misspelled"; cat "$work/p.err"
fi

# --- output directory ---------------------------------------------------------------------------
# The scene fails in setup (a region that selects no node): the directory's message must come first.
sed 's/min: \[-1, 0.0088, -1\]/min: [-1, 0.9, -1]/' "$scene" > "$in/empty_region.yaml"
touch "$in/afile"
refused out_under_file "cannot create output directory '$in/afile/out': Not a directory" -- "$in/empty_region.yaml" --out "$in/afile/out"
refused out_is_file "output directory '$in/afile' exists and is not a directory" -- "$in/empty_region.yaml" --out "$in/afile"
mkdir "$in/imm"
if chattr +i "$in/imm" 2> /dev/null; then  # immutable: no file can be made in it, not even by root
  refused out_immutable "cannot write in output directory '$in/imm': Operation not permitted" -- "$in/empty_region.yaml" --out "$in/imm"
  refused out_under_immutable "cannot create output directory '$in/imm/sub': Operation not permitted" -- "$in/empty_region.yaml" --out "$in/imm/sub"
  chattr -i "$in/imm"
fi
if [ -d /sys/kernel ]; then  # sysfs takes no file either
  refused out_sysfs "cannot write in output directory '/sys/kernel'" -- "$in/empty_region.yaml" --out /sys/kernel
fi
# Refused during setup: the directories the run made are removed again.
refused setup_error "boundaries.top.region: the region [-1, 0.9, -1] .. [1, 1, 1] selects no node" -- "$in/empty_region.yaml" --out new/a/b

# --- lock -----------------------------------------------------------------------------------------
# A: the scene, 195 steps with checkpoints every 50 (the last two kept: 100 and 150); B: another
# scene (denser rubber); K: the scene of A with another checkpoint cadence (every 25).
A=$work/A B=$work/B
"${mpi[@]}" "$peridrive" "$scene" --quiet --out "$A" > "$work/A.log" 2>&1 || { bad "run A"; cat "$work/A.log"; }
"${mpi[@]}" "$peridrive" "$scene" --quiet --set materials.rubber.density=1300 --out "$B" > "$work/B.log" 2>&1 ||
  { bad "run B"; cat "$work/B.log"; }
"${mpi[@]}" "$peridrive" "$scene" --quiet --set output.checkpoint_every_steps=25 --set output.progress_seconds=1 \
  --out "$work/K" > "$work/K.log" 2>&1 || { bad "run K"; cat "$work/K.log"; }
# run_refused NAME DIR EXPECTED -- peridrive arguments...: exit status 2, one error line with EXPECTED.
run_refused() {
  local name=$1 want=$2
  shift 3
  "${mpi[@]}" "$peridrive" "$@" --quiet > "$work/stdout" 2> "$work/stderr"
  local rc=$? n
  n=$(grep -c "peridrive: error:" "$work/stderr")
  if [ "$rc" -eq 2 ] && [ "$n" -eq 1 ] && grep -qF -- "$want" "$work/stderr"; then
    ok "$name: $(grep "peridrive: error:" "$work/stderr" | cut -c1-220)"
  else
    bad "$name: exit status $rc, $n error lines; expected '$want'"; cat "$work/stderr"
  fi
}
L=$work/L
# A long run without checkpoints (a resume into it is tried from A's checkpoint, made below).
"${mpi[@]}" "$peridrive" "$scene" --quiet --set stages.1.duration=0.05 --set output.checkpoint_every_steps=0 \
  --set output.checkpoint_every_seconds=0 --out "$L" > "$work/L.log" 2>&1 &
run=$!
for _ in $(seq 1 3000); do
  [ -e "$L/frames.xdmf" ] && grep -q "^pid: " "$L/.peridrive.lock" 2> /dev/null && break
  kill -0 "$run" 2> /dev/null || break
  sleep 0.02
done
pid=$(sed -n 's/^pid: //p' "$L/.peridrive.lock" 2> /dev/null)
if [ -n "$pid" ] && pgrep -P "$run" | grep -qx "$pid"; then
  ok "lock: held by rank 0 of the run (pid $pid)"
else
  bad "lock: no lock file naming a rank of the run ('$pid')"; cat "$work/L.log"
fi
run_refused lock_second_run "output directory '$L' is in use by another run (pid $pid on host $(hostname)" -- "$scene" --out "$L"
run_refused lock_resume "output directory '$L' is in use by another run (pid $pid on host $(hostname)" -- --resume "$A" --out "$L"
if kill -0 "$run" 2> /dev/null; then
  kill -TERM $(pgrep -P "$run" | head -1)  # a rank: the stop is collective
  wait "$run"
  rc=$?
  if [ "$rc" -eq 5 ] && [ ! -e "$L/.peridrive.lock" ]; then
    ok "lock: the first run went on (stopped by SIGTERM afterwards: exit status 5), its lock file removed"
  else
    bad "lock: first run's exit status $rc, lock file $(ls -a "$L" | grep -c peridrive.lock)"; cat "$work/L.log"
  fi
else
  wait "$run"
  bad "lock: the first run ended before the refusals were tried (exit status $?)"; cat "$work/L.log"
fi
# Another process holds the lock (one that writes no name into it): refused.
mkdir "$work/held"
$py -c "
import fcntl, sys, time
f = open(sys.argv[1], 'w')
fcntl.flock(f, fcntl.LOCK_EX)
open(sys.argv[2], 'w').close()
time.sleep(300)" "$work/held/.peridrive.lock" "$work/locked" > /dev/null 2>&1 &
holder=$!
for _ in $(seq 1 1000); do [ -e "$work/locked" ] && break; sleep 0.01; done
run_refused lock_other_process "output directory '$work/held' is in use by another run" -- "$scene" --out "$work/held"
kill "$holder"
wait "$holder" 2> /dev/null
holder=""
# A lock file left by a dead process (no flock on it): taken over silently.
mkdir "$work/stale"
printf 'peridrive output directory lock\nhost: %s\npid: 999999\nstarted: long ago\ncommand: killed\n' "$(hostname)" \
  > "$work/stale/.peridrive.lock"
if "${mpi[@]}" "$peridrive" "$scene" --quiet --out "$work/stale" > "$work/stdout" 2> "$work/stderr" &&
   [ ! -s "$work/stderr" ] && [ -e "$work/stale/summary.json" ] && [ ! -e "$work/stale/.peridrive.lock" ]; then
  ok "lock: a stale lock file taken over silently; run complete, lock file removed"
else
  bad "lock: stale lock file"; cat "$work/stderr"; ls -A "$work/stale"
fi

# --- no flock -------------------------------------------------------------------------------------
if LD_PRELOAD=$shim "${mpi[@]}" "$peridrive" "$scene" --quiet --out "$work/nolock" > "$work/stdout" 2> "$work/stderr" &&
   [ "$(grep -c . "$work/stderr")" -eq 1 ] &&
   grep -qF "peridrive: warning: output directory '$work/nolock' cannot be locked (flock: No locks available); running without the lock" "$work/stderr" &&
   [ -e "$work/nolock/summary.json" ] && [ ! -e "$work/nolock/.peridrive.lock" ]; then
  ok "no_flock: $(cat "$work/stderr" | cut -c1-200)"
else
  bad "no_flock"; cat "$work/stderr"; ls -A "$work/nolock"
fi

# --- resume -----------------------------------------------------------------------------------
mkdir "$work/Bf" "$work/Bc" "$work/Bs" "$work/Bg"
cp "$B/frames.h5" "$work/Bf/"
cp "$B/checkpoint.h5" "$work/Bc/"
cp "$B/series.csv" "$B/tips.csv" "$work/Bs/"
cp "$B/series.csv" "$work/Bg/"
printf 'name: [unclosed\n' > "$work/Bg/scene.resolved.yaml"
digest() { (cd "$1" && LC_ALL=C ls -A && find . -type f -exec md5sum {} + | sort) | md5sum; }
# resume_refused NAME DIR EXPECTED: --resume A --out DIR refused, DIR unchanged.
resume_refused() {
  local before after
  before=$(digest "$2")
  "${mpi[@]}" "$peridrive" --resume "$A" --out "$2" --quiet > "$work/stdout" 2> "$work/stderr"
  local rc=$? n
  n=$(grep -c "peridrive: error:" "$work/stderr")
  after=$(digest "$2")
  if [ "$rc" -eq 2 ] && [ "$n" -eq 1 ] && grep -qF -- "$3" "$work/stderr" && [ "$before" = "$after" ]; then
    ok "$1: $(grep "peridrive: error:" "$work/stderr" | cut -c1-220)"
  else
    bad "$1: exit status $rc, $n error lines, directory $([ "$before" = "$after" ] && echo unchanged || echo changed)"
    cat "$work/stderr"
  fi
}
held="cannot resume into output directory"
resume_refused resume_other_scene "$B" "$held '$B': it holds another run: $B/scene.resolved.yaml: resolved scene line"
resume_refused resume_other_frames "$work/Bf" "$held '$work/Bf': it holds another run: $work/Bf/frames.h5: resolved scene line"
resume_refused resume_other_checkpoint "$work/Bc" "$held '$work/Bc': it holds another run: $work/Bc/checkpoint.h5: resolved scene line"
resume_refused resume_no_record "$work/Bs" "$held '$work/Bs': it holds files of a run (series.csv, tips.csv) but no readable record"
resume_refused resume_foreign_record "$work/Bg" "$held '$work/Bg': its scene.resolved.yaml is not a scene of a run"
# Allowed: the run's own directory (R, the reference), a copy of it (C), a new (N) or an empty one
# (E, holding only a file no run writes), and a run of the same scene with another cadence (K).
cp -r "$A" "$work/R"
cp -r "$A" "$work/C"
mkdir "$work/E"
touch "$work/E/notes.txt"
allowed=1
for d in R C N E K; do
  if [ "$d" = R ]; then args=(--resume "$work/R")
  else args=(--resume "$A" --out "$work/$d"); fi
  "${mpi[@]}" "$peridrive" "${args[@]}" --quiet > "$work/$d.log" 2>&1 || { allowed=0; echo "  $d:"; cat "$work/$d.log"; }
done
[ "$allowed" -eq 1 ] && ok "resume_allowed: own directory, a copy, a new and an empty directory, another cadence's run" ||
  bad "resume_allowed"
$py - "$work" <<'PY'
import json, sys, h5py, numpy as np
w = sys.argv[1]
problems = []
def frames(d):
    with h5py.File(f"{w}/{d}/frames.h5", "r") as f:
        return {k: {n: f["frames"][k][n][...] for n in f["frames"][k]} | {"step": f["frames"][k].attrs["step"]}
                for k in f["frames"]}
ref = frames("R")
for d in ("C", "K"):
    got = frames(d)
    if sorted(got) != sorted(ref) or any(not np.array_equal(got[k][n], ref[k][n]) for k in ref for n in ref[k]):
        problems.append(f"{d}: frames differ from the run resumed in its own directory")
    for f in ("series.csv", "frames.xdmf", "tips.csv"):
        if open(f"{w}/{d}/{f}").read() != open(f"{w}/R/{f}").read():
            problems.append(f"{d}: {f} differs")
sr = json.load(open(f"{w}/R/summary.json"))
for d in ("C", "K", "N", "E"):
    s = json.load(open(f"{w}/{d}/summary.json"))
    for key in ("steps", "broken_bonds", "final", "energy_balance_error"):
        if s[key] != sr[key]:
            problems.append(f"{d}: summary {key} {s[key]} vs {sr[key]}")
# A new or empty directory holds the frames after the checkpoint's step (150).
for d in ("N", "E"):
    got, last = frames(d), max(ref)
    if not np.array_equal(got[max(got)]["position"], ref[last]["position"]) or min(v["step"] for v in got.values()) <= 150:
        problems.append(f"{d}: frames {[int(v['step']) for v in got.values()]}")
for p in problems:
    print("  " + p)
print(f"resumed copies compared with the run resumed in its own directory: {len(problems)} differences")
sys.exit(1 if problems else 0)
PY
[ $? -eq 0 ] && ok "resume_same_run: a copy ends bit for bit where the run's own directory ends" || bad "resume_same_run"

# A checkpoint later than the one resumed from describes steps whose frames the resume drops: it
# goes (here the resumed run writes no checkpoint of its own, so only the one resumed from is left).
cp -r "$A" "$work/P"
if "${mpi[@]}" "$peridrive" --resume "$work/P/checkpoint.prev.h5" --quiet --set output.checkpoint_every_steps=0 \
     --set output.checkpoint_every_seconds=0 > "$work/P.log" 2>&1 &&
   [ "$(cd "$work/P" && LC_ALL=C ls checkpoint*)" = "checkpoint.prev.h5" ] &&
   [ "$($py -c "import h5py; print(h5py.File('$work/P/checkpoint.prev.h5', 'r').attrs['step'])")" = 100 ]; then
  ok "resume_later_checkpoint: resumed from step 100, the checkpoint of step 150 removed"
else
  bad "resume_later_checkpoint: $(cd "$work/P" && ls checkpoint*)"; cat "$work/P.log"
fi

# --- fresh run into another run's directory -------------------------------------------------------
# A scene whose sheet does not break (no crack tips, so no tips.csv) and that writes no checkpoint,
# run into a copy of A: nothing of A may remain (its checkpoints, tips, a temporary).
sed 's/, critical_stretch: 1.6//' "$scene" > "$in/nobreak.yaml"
cp -r "$A" "$work/F"
touch "$work/F/checkpoint.h5.tmp" "$work/F/frames.h5.salvage" "$work/F/notes.txt"
if "${mpi[@]}" "$peridrive" "$in/nobreak.yaml" --quiet --set output.checkpoint_every_seconds=0 \
     --set output.checkpoint_every_steps=0 --out "$work/F" > "$work/F.log" 2>&1; then
  left=$(cd "$work/F" && LC_ALL=C ls -A | tr '\n' ' ')
  if [ "$left" = "frames.h5 frames.xdmf notes.txt scene.resolved.yaml series.csv summary.json " ]; then
    ok "fresh: only the new run's files (and notes.txt, which no run writes) remain: $left"
  else
    bad "fresh: the directory holds $left"
  fi
else
  bad "fresh: run failed"; cat "$work/F.log"
fi

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

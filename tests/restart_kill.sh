#!/usr/bin/env bash
# Nothing lost, end to end on real processes (2 ranks):
#  kill      SIGKILL both ranks mid-run; the XDMF must list only complete frames; --resume from the
#            last checkpoint must end with outputs identical (bit for bit) to an uninterrupted run
#  partial   a frame half written (its object header overwritten): the same after --resume
#  launcher  SIGKILL mpirun mid-run: its ranks end within 0.5 s and write nothing more; --resume
#            ends identical to the uninterrupted run
#  sigterm   SIGTERM to one rank: all ranks write a final checkpoint, exit status 5, no summary.json;
#            --resume ends identical to the uninterrupted run
#  one_rank  the 2-rank SIGTERM checkpoint resumed on 1 rank: final positions within 1e-12 relative
#  quasistatic  SIGTERM to one rank in a quasi-static stage: all stop before the next increment,
#            exit status 5, DIR/FAILED names the stage, no summary.json
#  refusals  truncated, bit-flipped and wrong-version checkpoints: exit status 2, one message, the
#            run's outputs untouched
# usage: restart_kill.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" "$@")
py=/usr/bin/python3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene=$src/tests/restart/small_slit.yaml
opts=(--quiet --set stages.1.duration=6e-4 --set output.checkpoint_every_steps=100 --set output.frames=36)
pass=0 fail=0
ok() { echo "ok   $1"; pass=$((pass + 1)); }
bad() { echo "FAIL $1"; fail=$((fail + 1)); }

# compare.py A B TOLERANCE: 0 = every output identical; else final positions within TOLERANCE.
cat > "$work/compare.py" <<'PY'
import json, sys, h5py, numpy as np
a, b, tol = sys.argv[1], sys.argv[2], float(sys.argv[3])
problems = []
with h5py.File(f"{a}/frames.h5", "r") as fa, h5py.File(f"{b}/frames.h5", "r") as fb:
    ka, kb = sorted(fa["frames"]), sorted(fb["frames"])
    if ka != kb:
        problems.append(f"frames {ka} vs {kb}")
    for k in ka if tol == 0 else ka[-1:]:
        for d in (fa["frames"][k] if tol == 0 else ["position"]):
            x, y = fa["frames"][k][d][...], fb["frames"][k][d][...]
            if tol == 0 and not np.array_equal(x, y):
                problems.append(f"frame {k} {d}: max difference {np.abs(x - y).max():.3e}")
            elif tol > 0:
                rel = np.abs(x - y).max() / np.abs(x).max()
                print(f"final positions: max relative difference {rel:.3e}")
                if not rel <= tol:
                    problems.append(f"final positions differ by {rel:.3e} relative")
        if tol == 0:
            for attr in ("step", "time"):
                if fa["frames"][k].attrs[attr] != fb["frames"][k].attrs[attr]:
                    problems.append(f"frame {k} {attr}")
if tol == 0:
    for f in ("series.csv", "frames.xdmf"):
        if open(f"{a}/{f}").read() != open(f"{b}/{f}").read():
            problems.append(f"{f} differs")
sa, sb = json.load(open(f"{a}/summary.json")), json.load(open(f"{b}/summary.json"))
for key in ("steps", "broken_bonds", "final", "energy_balance_error"):
    if tol == 0 and sa[key] != sb[key]:
        problems.append(f"summary {key}: {sa[key]} vs {sb[key]}")
for p in problems:
    print("  " + p)
sys.exit(1 if problems else 0)
PY

# xdmf_complete.py DIR: every dataset the XDMF names exists in frames.h5 with its full shape.
cat > "$work/xdmf_complete.py" <<'PY'
import re, sys, h5py
d = sys.argv[1]
x = open(f"{d}/frames.xdmf").read()
items = re.findall(r'Dimensions="([0-9 ]+)"[^>]*>frames.h5:([^<]+)<', x)
with h5py.File(f"{d}/frames.h5", "r") as f:
    for dims, path in items:
        shape = tuple(int(v) for v in dims.split())
        if path not in f or f[path].shape != shape:
            sys.exit(f"XDMF names {path} {shape}, not complete in frames.h5")
        f[path][...]
print(f"XDMF lists {x.count('<Time ')} frames, all complete ({len(items)} datasets read)")
PY

# The uninterrupted reference.
SECONDS=0
"${mpi[@]}" -n 2 "$peridrive" "$scene" "${opts[@]}" --out "$work/ref" > "$work/ref.log" 2>&1 || { cat "$work/ref.log"; exit 1; }
steps=$($py -c "import json; print(json.load(open('$work/ref/summary.json'))['steps'])")
echo "reference: $steps steps in about $SECONDS s"

# start_run DIR FRAMES: background 2-rank run; waits for its second checkpoint (step 200) and for
# the XDMF to list FRAMES frames (frame 3 is step 201: just after that checkpoint, so the kill
# leaves a frame and series rows for the resume to drop); sets $run_pid.
start_run() {
  "${mpi[@]}" -n 2 "$peridrive" "$scene" "${opts[@]}" --out "$1" > "$1.log" 2>&1 &
  run_pid=$!
  for _ in $(seq 1 3000); do
    if [ -e "$1/checkpoint.prev.h5" ] && [ "$(grep -c '<Time ' "$1/frames.xdmf" 2> /dev/null)" -ge "$2" ]; then
      return 0
    fi
    kill -0 "$run_pid" 2> /dev/null || return 1
    sleep 0.02
  done
  return 1
}
ranks_of() { pgrep -P "$1"; }

# --- kill -----------------------------------------------------------------------------------
if start_run "$work/kill" 4; then
  kill -KILL $(ranks_of "$run_pid")
  wait "$run_pid"
  at=$($py -c "import h5py; print(h5py.File('$work/kill/checkpoint.h5', 'r').attrs['step'])")
  $py - "$work/kill" "$at" <<'PY'
import sys, h5py
d, at = sys.argv[1], int(sys.argv[2])
rows = [l for l in open(f"{d}/series.csv").read().split("\n")[1:] if l]
after_rows = sum(1 for l in rows if int(l.split(",")[0]) > at)
try:
    with h5py.File(f"{d}/frames.h5", "r") as f:
        after_frames = sum(1 for k in f["frames"] if f["frames"][k].attrs["step"] > at)
except Exception as e:
    after_frames = f"unreadable ({e})"
print(f"killed after the checkpoint at step {at}: {after_rows} series rows and {after_frames} frames "
      f"written after it, to be dropped on resume")
PY
  [ -e "$work/kill/summary.json" ] && bad "kill: summary.json exists after a kill" || ok "kill: no summary.json after the kill"
  if $py "$work/xdmf_complete.py" "$work/kill"; then ok "kill: XDMF lists only complete frames"; else bad "kill: XDMF"; fi
  if "${mpi[@]}" -n 2 "$peridrive" --resume "$work/kill" --quiet > "$work/kill-resume.log" 2>&1 &&
     $py "$work/compare.py" "$work/ref" "$work/kill" 0; then
    ok "kill: resumed run identical to the uninterrupted one (frames, series, XDMF, summary)"
  else
    bad "kill: resumed run differs"; cat "$work/kill-resume.log"
  fi
else
  bad "kill: the run ended before its second checkpoint"; cat "$work/kill.log"
fi

# --- launcher -----------------------------------------------------------------------------------
# kill -9 of mpirun itself. Its ranks must end at once (orphans used to step and write on for 1 to
# 3 s, long enough to finish a short run and write summary.json), write nothing after it, and
# --resume (taking over the lock file that the killed rank 0 left) must end identical to the
# uninterrupted run.
if start_run "$work/launcher" 4; then
  ranks=$(ranks_of "$run_pid")
  killed_at=$(date +%s.%N)
  kill -KILL "$run_pid"
  gone=""
  for _ in $(seq 1 500); do  # a rank is alive until it is gone or a zombie
    alive=0
    for r in $ranks; do
      state=$(cut -d' ' -f3 "/proc/$r/stat" 2> /dev/null)
      [ -n "$state" ] && [ "$state" != Z ] && alive=1
    done
    [ "$alive" -eq 0 ] && { gone=$(date +%s.%N); break; }
    sleep 0.01
  done
  wait "$run_pid" 2> /dev/null
  sleep 1  # anything a surviving rank would still write
  if [ -n "$gone" ] && $py - "$work/launcher" "$killed_at" "$gone" <<'PY'
import os, sys
d, killed, gone = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
latest = max(os.stat(os.path.join(d, f)).st_mtime for f in os.listdir(d))
print(f"ranks gone {gone - killed:.3f} s after the kill of mpirun; last write {latest - killed:+.3f} s from it")
sys.exit(0 if gone - killed <= 0.5 and latest - killed <= 0.1 and not os.path.exists(f"{d}/summary.json") else 1)
PY
  then
    ok "launcher: ranks gone within 0.5 s of the kill of mpirun, nothing written after it, no summary.json"
  else
    bad "launcher: ranks $ranks outlived mpirun ($([ -n "$gone" ] && echo "gone at $gone, killed at $killed_at" || echo "still alive after 5 s")), or wrote after it"
    ls -la --time-style=+%s.%N "$work/launcher"
  fi
  [ -e "$work/launcher/.peridrive.lock" ] || bad "launcher: the killed rank 0 left no lock file behind"
  if "${mpi[@]}" -n 2 "$peridrive" --resume "$work/launcher" --quiet > "$work/launcher-resume.log" 2>&1 &&
     [ ! -e "$work/launcher/.peridrive.lock" ] && $py "$work/compare.py" "$work/ref" "$work/launcher" 0; then
    ok "launcher: resumed run (stale lock taken over) identical to the uninterrupted one"
  else
    bad "launcher: resumed run differs"; cat "$work/launcher-resume.log"
  fi
else
  bad "launcher: the run ended before its second checkpoint"; cat "$work/launcher.log"
fi

# --- partial frame ------------------------------------------------------------------------------
# A kill while a frame is being written leaves its HDF5 objects half written (the kill above lands
# there now and then): here, deterministically, the object header of the reference's last frame
# (step 2343, after its last checkpoint at step 2300) is overwritten. The resume must rebuild the
# file from the whole frames and end identical to the uninterrupted run.
cp -r "$work/ref" "$work/partial"
rm -f "$work/partial/summary.json"
$py - "$work/partial/frames.h5" <<'PY'
import sys, h5py
path = sys.argv[1]
with h5py.File(path, "r") as f:
    last = sorted(f["frames"])[-1]
    addr = h5py.h5o.get_info(f["frames"][last].id).addr
with open(path, "r+b") as f:
    f.seek(addr)
    f.write(bytes(8))
PY
if "${mpi[@]}" -n 2 "$peridrive" --resume "$work/partial" --quiet > "$work/partial-resume.log" 2>&1 &&
   grep -q "held a partly written frame" "$work/partial-resume.log" &&
   $py "$work/compare.py" "$work/ref" "$work/partial" 0; then
  ok "partial frame: file rebuilt from its whole frames, resumed run identical to the uninterrupted one"
else
  bad "partial frame: resumed run differs"; cat "$work/partial-resume.log"
fi

# --- sigterm ----------------------------------------------------------------------------------
if start_run "$work/term" 0; then
  kill -TERM $(ranks_of "$run_pid" | head -1)  # one rank only: the stop is collective
  wait "$run_pid"
  rc=$?
  at=$($py -c "import h5py; print(h5py.File('$work/term/checkpoint.h5', 'r').attrs['step'])")
  if [ "$rc" -eq 5 ] && [ "$at" -lt "$steps" ] && [ ! -e "$work/term/summary.json" ] &&
     grep -q "stopped by signal 15 at step $at/$steps" "$work/term.log"; then
    ok "sigterm: exit status 5, final checkpoint at step $at of $steps, no summary.json"
  else
    bad "sigterm: exit status $rc, checkpoint step $at"; cat "$work/term.log"
  fi
  cp -r "$work/term" "$work/one"
  cp -r "$work/term" "$work/refuse"
  if "${mpi[@]}" -n 2 "$peridrive" --resume "$work/term" --quiet > "$work/term-resume.log" 2>&1 &&
     $py "$work/compare.py" "$work/ref" "$work/term" 0; then
    ok "sigterm: resumed run identical to the uninterrupted one"
  else
    bad "sigterm: resumed run differs"; cat "$work/term-resume.log"
  fi
  # --- one rank -------------------------------------------------------------------------------
  if "${mpi[@]}" -n 1 "$peridrive" --resume "$work/one" --quiet > "$work/one.log" 2>&1 &&
     $py "$work/compare.py" "$work/ref" "$work/one" 1e-12; then
    ok "one_rank: 2-rank checkpoint continued on 1 rank within 1e-12"
  else
    bad "one_rank"; cat "$work/one.log"
  fi
  # --- refusals -------------------------------------------------------------------------------
  ck=$work/refuse/checkpoint.h5
  cp "$ck" "$work/good.h5"
  before=$(cat "$work/refuse/series.csv" "$work/refuse/frames.xdmf" "$work/refuse/frames.h5" | md5sum)
  refuse() {  # NAME EXPECTED_SUBSTRING PYTHON_EDIT
    cp "$work/good.h5" "$ck"
    $py -c "
import sys
b = bytearray(open('$ck', 'rb').read())
$3
open('$ck', 'wb').write(b)"
    "${mpi[@]}" -n 2 "$peridrive" --resume "$work/refuse" --quiet > "$work/r.out" 2> "$work/r.err"
    local rc=$? n
    n=$(grep -c "peridrive: error:" "$work/r.err")
    after=$(cat "$work/refuse/series.csv" "$work/refuse/frames.xdmf" "$work/refuse/frames.h5" | md5sum)
    if [ "$rc" -eq 2 ] && [ "$n" -eq 1 ] && grep -qF -- "$2" "$work/r.err" && [ "$before" = "$after" ]; then
      ok "refusal $1: $(cat "$work/r.err")"
    else
      bad "refusal $1: exit status $rc, $n messages, outputs $([ "$before" = "$after" ] && echo kept || echo changed)"
      cat "$work/r.err"
    fi
  }
  refuse truncated "checkpoint '$ck': truncated" "b = b[:len(b) // 2]"
  refuse header_bit "checkpoint '$ck': not a peridrive checkpoint" "b[3] ^= 0x04"
  refuse data_bit "checkpoint '$ck': damaged: checksum mismatch" "b[len(b) - 999] ^= 0x01"
  refuse version "checkpoint '$ck': format version 2; this peridrive reads version 1" \
         "i = b.find(b'format_version: 1'); b[i + 16] = ord('2')"
  refuse foreign "checkpoint '$ck': not a peridrive checkpoint" "b[:] = open('$work/ref/frames.h5', 'rb').read()"
else
  bad "sigterm: the run ended before its second checkpoint"; cat "$work/term.log"
fi

# --- quasistatic -------------------------------------------------------------------------------
# fig3_damage_stress: two quasi-static stages (3800 nodes), the second of 1000 increments.
qs=$work/qs
"${mpi[@]}" -n 2 "$peridrive" "$src/drivers/scenes/fig3_damage_stress.yaml" --quiet --out "$qs" > "$qs.log" 2>&1 &
run_pid=$!
for _ in $(seq 1 3000); do
  [ "$(grep -c ',stretch,' "$qs/quasistatic.csv" 2> /dev/null)" -ge 2 ] && break
  kill -0 "$run_pid" 2> /dev/null || break
  sleep 0.02
done
rows=$(grep -c ',stretch,' "$qs/quasistatic.csv" 2> /dev/null)
SECONDS=0
kill -TERM $(ranks_of "$run_pid" | head -1)
wait "$run_pid"
rc=$? took=$SECONDS
after=$(grep -c ',stretch,' "$qs/quasistatic.csv" 2> /dev/null)
if [ "$rc" -eq 5 ] && [ ! -e "$qs/summary.json" ] && [ "$took" -le 30 ] &&
   grep -q "stopped by signal 15 in quasi-static stage 'stretch'" "$qs/FAILED" &&
   [ "$(grep -c 'stopped by signal 15' "$qs.log")" -eq 1 ]; then
  ok "quasistatic: stopped $took s after SIGTERM at increment $after of the stage (signalled at $rows), status 5, FAILED"
else
  bad "quasistatic: exit status $rc after $took s, $rows..$after increments"; cat "$qs.log"; cat "$qs/FAILED" 2> /dev/null
fi

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

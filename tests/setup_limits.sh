#!/usr/bin/env bash
# Work that grows with the input stays bounded, and setup stops when asked:
#  crack_count   200,000 cracks (2.2 million YAML values): refused while the text is scanned, in
#                seconds and without holding the document (1 rank, peak resident memory measured)
#  many_cracks   40,000 cracks on the default sheet (102,400 nodes): --dry-run builds the pre-cracks
#                through the crack index in seconds, not the hours of 40,000 tests per bond
#  stop_reading  SIGTERM to both ranks while they read the 40,000-crack scene: exit status 5
#                within seconds, one message, nothing written
#  stop_setup    SIGTERM to both ranks while they build a million-node sheet in --dry-run: the same
# usage: setup_limits.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
py=/usr/bin/python3
work=$(mktemp -d)
trap 'kill -KILL $(jobs -p) 2> /dev/null; rm -rf "$work"' EXIT
pass=0 fail=0
ok() { echo "ok   $1"; pass=$((pass + 1)); }
bad() { echo "FAIL $1"; fail=$((fail + 1)); }

# cracks N FILE: the default scene with N short cracks scattered over the sheet.
cracks() {
  $py - "$src/drivers/scenes/slit_membrane.yaml" "$1" "$2" <<'PY'
import random, sys
text, n, out = open(sys.argv[1]).read(), int(sys.argv[2]), sys.argv[3]
head, tail = text.split("cracks:\n", 1)
rng = random.Random(1)
lines = []
for _ in range(n):
    x, y = rng.uniform(-0.024, 0.024), rng.uniform(-0.02, 0.02)
    lines.append(f"  - {{from: [{x:.6f}, {y:.6f}, 0], to: [{x + 0.0001:.6f}, {y:.6f}, 0]}}")
open(out, "w").write(head + "cracks:\n" + "\n".join(lines) + "\nboundaries:\n" + tail.split("boundaries:\n", 1)[1])
PY
}
cracks 200000 "$work/cracks200k.yaml"
cracks 40000 "$work/cracks40k.yaml"

# --- crack_count -------------------------------------------------------------------------------
/usr/bin/time -f "%e %M" -o "$work/time" timeout -s KILL 120 "$peridrive" "$work/cracks200k.yaml" --dry-run \
  > "$work/stdout" 2> "$work/stderr"
rc=$?
read -r seconds kb < <(tail -n 1 "$work/time")
# Refused at the line of the crack where the count passes the limit: 11 values a crack (its map, two
# keys, two lists of three), so some 1e6 / 11 cracks into the list, less the header's values.
want=": cracks: the scene holds more than 1000000 YAML values"
first=$(( $(grep -n -m1 '^cracks:' "$work/cracks200k.yaml" | cut -d: -f1) + 1 ))
at=$(grep -o "cracks200k.yaml:[0-9]*: cracks:" "$work/stderr" | cut -d: -f2)
echo "200,000 cracks: exit status $rc after $seconds s, peak resident memory $((kb / 1024)) MB; refused at line ${at:-?} (cracks from line $first)"
if [ "$rc" -eq 2 ] && grep -qF "$want" "$work/stderr" && [ "$(grep -c "peridrive: error:" "$work/stderr")" -eq 1 ] &&
   [ -n "$at" ] && [ "$at" -ge $((first + 1000000 / 11 - 300)) ] && [ "$at" -le $((first + 1000000 / 11)) ] &&
   $py -c "import sys; sys.exit(0 if $seconds < 30 and $kb < 512 * 1024 else 1)"; then
  ok "crack_count: refused in $seconds s, $((kb / 1024)) MB"
else bad "crack_count: expected exit status 2 within 30 s and 512 MB with '$want'"; cat "$work/stderr"; fi

# --- many_cracks ----------------------------------------------------------------------------------
SECONDS=0
timeout -s KILL 240 "${mpi[@]}" "$peridrive" "$work/cracks40k.yaml" --dry-run > "$work/stdout" 2> "$work/stderr"
rc=$?
if [ "$rc" -eq 0 ] && grep -q "ordered_bonds = " "$work/stdout" && [ "$SECONDS" -lt 120 ]; then
  ok "many_cracks: --dry-run of 40,000 cracks in $SECONDS s"
else bad "many_cracks: exit status $rc after $SECONDS s, expected 0 within 120 s"; cat "$work/stderr"; fi

# stop NAME WANT WAIT_FOR -- peridrive arguments: start a 2-rank run, wait until both ranks catch
# SIGTERM and WAIT_FOR (a pattern of its standard output, or empty) appears, signal both ranks,
# and expect exit status 5 within 10 s with the one message WANT and no output directory.
stop() {
  local name=$1 want=$2 wait_for=$3
  shift 4
  "${mpi[@]}" "$peridrive" "$@" --out "$work/out-$name" > "$work/stdout" 2> "$work/stderr" &
  local pid=$! ranks="" ready=0
  for _ in $(seq 1 1000); do
    ranks=$(pgrep -P "$pid")
    local caught=0
    for r in $ranks; do  # SigCgt bit 14: SIGTERM has a handler
      mask=$(awk '/^SigCgt:/ {print $2}' "/proc/$r/status" 2> /dev/null)
      [ -n "$mask" ] && [ $(( (0x$mask >> 14) & 1 )) -eq 1 ] && caught=$((caught + 1))
    done
    if [ "$caught" -eq 2 ] && { [ -z "$wait_for" ] || grep -q "$wait_for" "$work/stdout"; }; then ready=1; break; fi
    kill -0 "$pid" 2> /dev/null || break
    sleep 0.01
  done
  [ -z "$wait_for" ] && sleep 0.3  # well into the reading
  local t0=$SECONDS
  [ "$ready" -eq 1 ] && kill -TERM $ranks
  for _ in $(seq 1 1000); do kill -0 "$pid" 2> /dev/null || break; sleep 0.01; done
  kill -0 "$pid" 2> /dev/null && kill -KILL $ranks "$pid" 2> /dev/null
  wait "$pid"
  local rc=$? took=$((SECONDS - t0))
  if [ "$ready" -eq 1 ] && [ "$rc" -eq 5 ] && grep -qF "$want" "$work/stderr" &&
     [ "$(grep -c "^peridrive: " "$work/stderr")" -eq 1 ] && [ ! -e "$work/out-$name" ]; then
    ok "$name: exit status 5 about $took s after the signal: $(grep "^peridrive: " "$work/stderr")"
  else bad "$name: ready $ready, exit status $rc about $took s after the signal, expected 5 with '$want'"; cat "$work/stderr"; fi
}
stop stop_reading "peridrive: stopped by signal 15 while reading the scene; nothing was written" "" -- \
  "$work/cracks40k.yaml" --dry-run
stop stop_setup "peridrive: stopped by signal 15 while setting up the run; nothing was written" "^estimate:" -- \
  --set bodies.sheet.spacing=5e-5 --dry-run

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]

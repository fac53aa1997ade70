#!/usr/bin/env bash
# Output that cannot be written ends a 2-rank run on every rank together, with one message and
# exit status 3, and never hangs (a failure seen by one rank inside a collective HDF5 write used to
# leave the other waiting for ever):
#  file_size_limit  ulimit -f (16 MB) stops frames.h5 after 17 or 18 of its 40 frames: the run stops at
#                   the first frame that does not fit, naming frames.h5 and the dataset; FAILED
#                   says why, there is no summary.json, and frames.xdmf lists only whole frames,
#                   each readable
#  full_disk        a 4 MB tmpfs (when this machine lets root mount one): a run whose predicted
#                   output exceeds it is refused at the start (exit 2, nothing written); told not
#                   to check (output.check_free_space: false), the frame that does
#                   not fit is refused before it is begun, naming the free bytes; the file keeps
#                   its whole frames. Then a checkpoint that does not fit: refused with its partial
#                   file removed and the previous checkpoint kept, from which the run resumes
# usage: output_faults.sh PERIDRIVE SOURCE_DIR MPIEXEC [MPI flags...]
set -u
peridrive=$1 src=$2 mpiexec=$3
shift 3
mpi=("$mpiexec" -n 2 "$@")
py=/usr/bin/python3
work=$(mktemp -d)
mnt=$work/small
trap 'umount "$mnt" 2> /dev/null; rm -rf "$work"' EXIT
pass=0 fail=0
ok() { echo "ok   $1"; pass=$((pass + 1)); }
bad() { echo "FAIL $1"; fail=$((fail + 1)); }
coarse=(--set bodies.sheet.spacing=0.0005 --set output.frames=40)  # 10,000 nodes, frames of 880 kB

# whole_frames OUT: the frames frames.xdmf lists all read back from frames.h5, with finite positions.
whole_frames() {
  $py - "$1" << 'PY'
import re, sys
import h5py, numpy as np
out = sys.argv[1]
listed = re.findall(r"frames\.h5:/frames/(\d+)/position", open(out + "/frames.xdmf").read())
with h5py.File(out + "/frames.h5", "r") as f:
    for k in listed:
        x = f["/frames/%s/position" % k][...]
        assert x.shape == (10000, 3) and np.isfinite(x).all(), k
print(len(listed))
PY
}

# expect_failure NAME OUT WANT: exit status 3 within the timeout, one error line holding WANT, a
# FAILED marker saying the same, no summary.json, whole frames only.
expect_failure() {
  local name=$1 out=$2 want=$3 rc=$4
  local lines frames
  lines=$(grep -c "peridrive: error:" "$work/stderr")
  if [ "$rc" -eq 124 ]; then bad "$name: the run hung (killed after 120 s)"; return; fi
  if [ "$rc" -ne 3 ] || [ "$lines" -ne 1 ] || ! grep -qF -- "$want" "$work/stderr"; then
    bad "$name: exit status $rc, $lines error lines, expected 3 and one line with '$want'"; cat "$work/stderr"; return
  fi
  if [ -e "$out/summary.json" ]; then bad "$name: summary.json written"; return; fi
  if ! frames=$(whole_frames "$out"); then bad "$name: frames.xdmf lists a frame that cannot be read"; return; fi
  ok "$name: $frames whole frames; $(grep "peridrive: error:" "$work/stderr" | cut -c1-200)"
}

# --- file_size_limit ------------------------------------------------------------------------------
out=$work/limit
# (the limit on the ranks alone: mpiexec's own shared-memory files must not meet it)
timeout -s KILL 120 "${mpi[@]}" bash -c 'ulimit -f 16384 && exec "$@"' limited "$peridrive" "${coarse[@]}" --out "$out" \
  --quiet > "$work/stdout" 2> "$work/stderr"
rc=$?
[ "$rc" -eq 137 ] && rc=124
expect_failure file_size_limit "$out" "$out/frames.h5: writing dataset" "$rc"
grep -qF "the file reached this process's file size limit (ulimit -f) of 16777216 bytes" "$work/stderr" || bad "file_size_limit: the message does not name the limit"
grep -qF "frames.h5: writing dataset" "$out/FAILED" 2> /dev/null || bad "file_size_limit: FAILED lacks the message"

# --- full_disk --------------------------------------------------------------------------------------
mkdir -p "$mnt"
if mount -t tmpfs -o size=4m tmpfs "$mnt" 2> /dev/null; then
  # The predicted output (40 frames of 0.95 MB) does not fit: refused before anything is written.
  out=$mnt/run
  timeout -s KILL 120 "${mpi[@]}" "$peridrive" "${coarse[@]}" --out "$out" --quiet > "$work/stdout" 2> "$work/stderr"
  rc=$?
  want="output: the run would write about 38.4 MB to '$out' (40 frames of 0.946 MB, the mesh 0.546 MB) and its file system has"
  if [ "$rc" -eq 2 ] && [ "$(grep -c "peridrive: error:" "$work/stderr")" -eq 1 ] && grep -qF "$want" "$work/stderr" &&
     [ ! -e "$out/frames.h5" ] && [ ! -e "$out/scene.resolved.yaml" ]; then
    ok "predicted_too_large: $(grep "peridrive: error:" "$work/stderr" | cut -c1-160)"
  else bad "predicted_too_large: exit status $rc, expected 2 with '$want' and no files"; cat "$work/stderr"; ls "$out"; fi
  # Told not to check: the frame that does not fit is refused when it comes.
  rm -rf "${mnt:?}"/*
  timeout -s KILL 120 "${mpi[@]}" "$peridrive" "${coarse[@]}" --set output.check_free_space=false --out "$out" --quiet \
    > "$work/stdout" 2> "$work/stderr"
  rc=$?
  [ "$rc" -eq 137 ] && rc=124
  expect_failure full_disk "$out" "$out/frames.h5: no space left for the frame of step" "$rc"
  # A checkpoint that does not fit: exit 3 naming it, the partial file removed, the previous
  # checkpoint kept; resumed elsewhere, the run completes.
  rm -rf "${mnt:?}"/*
  out=$mnt/ck
  timeout -s KILL 120 "${mpi[@]}" "$peridrive" --set bodies.sheet.spacing=0.0003 --set output.frames=1 \
    --set output.checkpoint_every_steps=100 --set output.check_free_space=false --out "$out" --quiet \
    > "$work/stdout" 2> "$work/stderr"
  rc=$?
  want="cannot write checkpoint '$out/checkpoint.h5.tmp'"
  if [ "$rc" -eq 3 ] && [ "$(grep -c "peridrive: error:" "$work/stderr")" -eq 1 ] && grep -qF "$want" "$work/stderr" &&
     grep -qF "the previous checkpoint, if any, is kept" "$work/stderr" && [ -e "$out/checkpoint.h5" ] &&
     [ ! -e "$out/checkpoint.h5.tmp" ] && [ ! -e "$out/summary.json" ]; then
    cp -r "$out" "$work/ck"
    timeout -s KILL 300 "${mpi[@]}" "$peridrive" --resume "$work/ck" --quiet > "$work/stdout" 2> "$work/stderr"
    if [ $? -eq 0 ] && [ -e "$work/ck/summary.json" ]; then
      ok "checkpoint_full_disk: refused, previous checkpoint kept, resumed to the end"
    else bad "checkpoint_full_disk: the resume from the kept checkpoint failed"; cat "$work/stderr"; fi
  else
    bad "checkpoint_full_disk: exit status $rc, expected 3 with '$want', the previous checkpoint and no partial one"
    cat "$work/stderr"; ls "$out"
  fi
else
  echo "note full_disk, checkpoint_full_disk: this machine does not let the test mount a tmpfs; not run"
fi

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ] && [ "$pass" -ge 1 ]

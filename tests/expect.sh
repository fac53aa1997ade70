# Sourced by the refused-input tests (bad_input*.sh). The script sets peridrive, mpi (the mpirun
# command and its flags, an array), work (a scratch folder), pass and fail (counters), and
# optionally expect_dir (the working directory of the runs, default: the current one).
#
# expect NAME EXPECTED_SUBSTRING -- peridrive arguments...: the run is refused at setup: exit
# status 2, the substring in its message, exactly one error line, and no output directory.
expect() {
  local name=$1 want=$2
  shift 3
  local out="$work/out-$name"
  (cd "${expect_dir:-.}" && "${mpi[@]}" "$peridrive" "$@" --out "$out" --quiet > "$work/stdout" 2> "$work/stderr")
  local rc=$?
  local msg
  msg=$(grep -c "peridrive: error:" "$work/stderr")
  if [ "$rc" -ne 2 ]; then
    echo "FAIL $name: exit status $rc, expected 2"; cat "$work/stderr"; fail=$((fail + 1))
  elif ! grep -qF -- "$want" "$work/stderr"; then
    echo "FAIL $name: message lacks '$want':"; cat "$work/stderr"; fail=$((fail + 1))
  elif [ "$msg" -ne 1 ]; then
    echo "FAIL $name: expected exactly one error line, got $msg"; cat "$work/stderr"; fail=$((fail + 1))
  elif [ -e "$out" ]; then
    echo "FAIL $name: output directory $out was created"; fail=$((fail + 1))
  else
    echo "ok   $name: $(grep "peridrive: error:" "$work/stderr")"; pass=$((pass + 1))
  fi
}

#!/usr/bin/env bash
# The halo terms of cluster/scaling_model.py, as peridrive-partition predicts them for P parts,
# are those a P-rank run reports in summary.json ("halo"): largest and mean ghosts and neighbour
# ranks, largest owned and boundary-row bonds, equal. On 4 ranks (oversubscribed: correctness, not
# timing) for a sheet partitioned by rcb (the slit membrane, coarse) and a plate with a hole
# partitioned by METIS on the cell graph; one step each.
# usage: halo_report.sh PERIDRIVE PERIDRIVE_PARTITION SOURCE_DIR MPIEXEC [MPI flags...]
set -eu
peridrive=$1 partition=$2 src=$3 mpiexec=$4
shift 4
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
check() {  # name scene [--set ...]
  local name=$1 scene=$2
  shift 2
  "$mpiexec" -n 4 --oversubscribe "$@" "$peridrive" "$scene" "${sets[@]}" --set stages.0.duration=1e-9 --set output.frames=2 \
    --out "$work/$name" --quiet
  method=$(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['partition_method'])" \
    "$work/$name/summary.json")
  "$partition" "$scene" "${sets[@]}" --parts 4 --method "$method" --csv "$work/$name.csv" >/dev/null 2>&1
  /usr/bin/python3 - "$work/$name/summary.json" "$work/$name.csv" "$name" <<'PY'
import csv, json, sys
halo = json.load(open(sys.argv[1]))["halo"]
row = next(csv.DictReader(open(sys.argv[2])))
pairs = [("max_ghosts", "max_ghosts"), ("mean_ghosts", "mean_ghosts"),
         ("max_neighbour_ranks", "max_neighbour_parts"), ("mean_neighbour_ranks", "mean_neighbour_parts"),
         ("max_owned_bonds", "max_owned_bonds"), ("max_boundary_bonds", "max_boundary_bonds"),
         ("mean_boundary_bonds", "mean_boundary_bonds")]
bad = [(k, halo[k], row[c]) for k, c in pairs if abs(float(halo[k]) - float(row[c])) > 1e-6 * max(1.0, float(row[c]))]
print(f"{sys.argv[3]} ({row['method']}, 4 parts): " + ", ".join(f"{k} {halo[k]}" for k, _ in pairs))
if bad:
    sys.exit(f"{sys.argv[3]}: the run and peridrive-partition differ: " +
             "; ".join(f"{k}: run {a}, partition {b}" for k, a, b in bad))
if not halo["max_ghosts"] > 0 or not 0 < halo["max_boundary_bonds"] < halo["max_owned_bonds"]:
    sys.exit(f"{sys.argv[3]}: implausible halo {halo}")
PY
}
sets=(--set bodies.sheet.spacing=0.0005)
check sheet "$src/drivers/scenes/slit_membrane.yaml" "$@"
sets=(--set bodies.plate.spacing=0.0005)
check plate "$src/drivers/scenes/plate_with_hole.yaml" "$@"

# peridrive-partition's refusals: exit status 2 and one message, before any partition is made.
refused() {  # name expected-message args...
  local name=$1 want=$2
  shift 2
  set +e
  "$partition" "$@" > "$work/$name.out" 2> "$work/$name.err"
  local rc=$?
  set -e
  if [ "$rc" -ne 2 ] || ! grep -qF -- "$want" "$work/$name.err" || grep -q "^P = " "$work/$name.err"; then
    echo "FAIL $name: exit status $rc, stderr:"; cat "$work/$name.err"; exit 1
  fi
  echo "ok   $name: $(cat "$work/$name.err")"
}
plate=("$src/drivers/scenes/plate_with_hole.yaml" --set bodies.plate.spacing=0.001)
refused too_many_parts "--parts: every value (100000) exceeds the scene's 1516 nodes" "${plate[@]}" --parts 100000
refused csv_unwritable "--csv $work/none/x.csv: cannot write the file" "${plate[@]}" --parts 2 --csv "$work/none/x.csv"
# A P beyond the nodes among others is skipped with a note; the others are reported.
"$partition" "${plate[@]}" --parts 2,100000 --method rcb --csv "$work/some.csv" > /dev/null 2> "$work/some.err"
grep -qF "parts beyond the scene's 1516 nodes skipped: 100000" "$work/some.err" && [ "$(wc -l < "$work/some.csv")" -eq 2 ] \
  || { echo "FAIL skipped_parts:"; cat "$work/some.err"; exit 1; }
echo "ok   skipped_parts"

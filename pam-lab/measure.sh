#!/usr/bin/env bash
# Regenerates pam-lab/MEASURED.md, every measured table of pam-lab, from the
# commands it runs (release build):
#   pam-lab/measure.sh                      the repository's examples (examples/*.csv)
#   pam-lab/measure.sh --examples DIR       and an independent simulator's example_N.csv in DIR
#   pam-lab/measure.sh --festo DIR          and the Festo 10 mm set: DIR is the folder
#       BPA_Static_Characterization_Test/10mmData_Nov2022 of
#       github.com/Agile-and-Adaptive-Robotics/Muscle_Sensory (not shipped: no licence)
#   pam-lab/measure.sh --hidden             and the hidden plants' 54 records (generated)
#   pam-lab/measure.sh --long               and a 103 500-row record (host-sim's long_record
#       example): how long fit and diagnose take on a user-sized file
# Options combine. fit and diagnose run one record at a time, so the times are
# each command's own on this machine.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
examples="" festo="" hidden="" long=""
while [ $# -gt 0 ]; do
  case "$1" in
    --examples) examples=$(cd "$2" && pwd); shift 2 ;;
    --festo) festo=$(cd "$2" && pwd); shift 2 ;;
    --hidden) hidden=1; shift ;;
    --long) long=1; shift ;;
    *) echo "usage: $0 [--examples DIR] [--festo DIR] [--hidden] [--long]" >&2; exit 2 ;;
  esac
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$root"
cargo build -q --release -p pam-lab
bin=${CARGO_TARGET_DIR:-$root/target}/release/pam-lab

# run NAME COMMAND...: the command's outputs in $work/NAME, its wall time in
# $work/NAME.time.
run() {
  local name=$1; shift
  local t0 t1
  t0=$(date +%s.%N)
  "$@" >"$work/$name.log" 2>&1 || { echo "$name failed:" >&2; cat "$work/$name.log" >&2; exit 1; }
  t1=$(date +%s.%N)
  echo "$t0 $t1" | awk '{printf "%.1f\n", $2 - $1}' >"$work/$name.time"
}

# both SUB NAME FILE: fit and diagnose on FILE, into $work/SUB/{fit,diag}_NAME.
both() {
  echo "$3" >&2
  mkdir -p "$work/$1"
  run "$1/fit_$2" "$bin" fit "$3" --no-plot -o "$work/$1/fit_$2"
  run "$1/diag_$2" "$bin" diagnose "$3" --no-plot -o "$work/$1/diag_$2"
}

for f in reference rate_dependence load_dependent_width isometric; do
  both repo "$f" "examples/$f.csv"
done
if [ -n "$examples" ]; then
  for f in "$examples"/example_*.csv; do
    both ex "$(basename "$f" .csv)" "$f"
  done
fi

if [ -n "$long" ]; then
  mkdir -p "$work/long"
  cargo run -q --release -p host-sim --example long_record -- "$work/long/long_record.csv" 2>/dev/null
  both long long_record "$work/long/long_record.csv"
fi

if [ -n "$festo" ]; then
  mkdir -p "$work/festo"
  "$bin" import examples/festo-10mm-isometric.toml --data-dir "$festo" -o "$work/festo/rec" >"$work/festo/import.log" 2>&1
  for L in 10 15 20 25 30 40; do
    echo "festo ${L} cm" >&2
    train=$work/festo/rec/${L}cm_train.csv test=$work/festo/rec/${L}cm_test.csv
    run "festo/fit_$L" "$bin" fit "$train" --validate "$test" --holdout none --no-plot -o "$work/festo/fit_$L"
    run "festo/cubic_$L" "$bin" fit "$train" --validate "$test" --holdout none --no-static-shape --no-plot -o "$work/festo/cubic_$L"
    run "festo/diag_$L" "$bin" diagnose "$train" --validate "$test" --holdout none --no-plot -o "$work/festo/diag_$L"
  done
fi

if [ -n "$hidden" ]; then
  mkdir -p "$work/hidden/rec"
  PAM_HIDDEN_OUT="$work/hidden/rec" PAM_HIDDEN_SEEDS=3 cargo test -q --release -p pam-lab \
    --test diagnose_hidden -- --ignored write_hidden_plant_records >/dev/null
  for f in "$work"/hidden/rec/*.csv; do
    n=$(basename "$f" .csv)
    echo "$n" >&2
    run "hidden/diag_$n" "$bin" diagnose "$f" --no-plot -o "$work/hidden/diag_$n"
  done
fi

python3 "$here/measure.py" "$work" "$(git rev-parse --short HEAD)" >"$work/MEASURED.md"
mv "$work/MEASURED.md" "$here/MEASURED.md"
echo "wrote $here/MEASURED.md" >&2

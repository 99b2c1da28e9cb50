#!/usr/bin/env bash
# Run every fuzz target for a given time and print a Markdown table of
# executions, time and crashes per target.
#
#   fuzz/run-all.sh [seconds-per-target [target...]]   (default 120 s, all)
#
# Needs nightly and cargo-fuzz (`cargo +nightly install cargo-fuzz --locked`).
# Not part of CI: CI builds on stable, and libFuzzer needs nightly's
# `-Zsanitizer`. The checked-in seeds (fuzz/seeds/<target>) are copied into
# the working corpus (fuzz/corpus/<target>, git-ignored) first; a crash stops
# that target's run and leaves its input in fuzz/artifacts/<target>/.
set -u
secs="${1:-120}"
cd "$(dirname "$0")"
targets=(csv_reader model_file blob_decode core_eval tracker effects inverse preisach fit_record diagnose_record)
if [ $# -gt 1 ]; then targets=("${@:2}"); fi
logs="target/run-all-logs"
mkdir -p "$logs"

cargo +nightly fuzz build >"$logs/build.log" 2>&1 || {
    cat "$logs/build.log"
    exit 1
}

rows=()
trap 'rm -f /dev/shm/pam-fuzz-model-*.bin' EXIT  # model_file's scratch files
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t"
    if [ -d "seeds/$t" ]; then cp -n seeds/"$t"/* "corpus/$t/" 2>/dev/null; fi
    echo "== $t: ${secs} s" >&2
    start=$(date +%s)
    extra=()
    # The record targets: records up to 20 kB (the seeds are 15-19 kB), and
    # no leak check (the fit's worker threads register thread-local
    # destructors, which LeakSanitizer reports as a 32-byte leak).
    case "$t" in fit_record | diagnose_record) extra=(-max_len=20000 -detect_leaks=0 -timeout=60) ;; esac
    cargo +nightly fuzz run "$t" -- -max_total_time="$secs" -print_final_stats=1 "${extra[@]}" \
        >"$logs/$t.log" 2>&1
    rc=$?
    wall=$(( $(date +%s) - start ))
    execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$logs/$t.log" | tail -1 | grep -o '[0-9]*$')
    rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$logs/$t.log" | tail -1 | grep -o '[0-9]*$')
    # libFuzzer's own time ("Done N runs in T second(s)"); after a crash there
    # is none, and the wall time (which includes any rebuild) is shown.
    fuzzed=$(grep -o 'Done [0-9]* runs in [0-9]* second' "$logs/$t.log" | tail -1 | awk '{print $5}')
    corpus=$(ls "corpus/$t" | wc -l)
    if [ "$rc" -eq 0 ]; then
        crashes=0
    else
        art=$(grep -o 'Test unit written to [^ ]*' "$logs/$t.log" | head -1 | sed 's|.*/fuzz/||')
        crashes="1 (run stopped; ${art:-see $logs/$t.log})"
    fi
    rows+=("| \`$t\` | ${execs:-?} | ${rate:-?} | ${fuzzed:-wall ${wall}} | ${corpus} | ${crashes} |")
done

echo
echo "$(date -u +%Y-%m-%d), $(nproc) cores, \`cargo +nightly fuzz run <target> -- -max_total_time=$secs -print_final_stats=1\`"
echo
echo "| target | executions | exec/s | time (s) | corpus files | crashes |"
echo "|---|---:|---:|---:|---:|---|"
printf '%s\n' "${rows[@]}"

#!/usr/bin/env bash
# Everything in one command:
# 1. on the host, identify the baselines (and pam-core) on host-sim's
#    characterisation run: writes bench-m4/src/identified.rs, accuracy.md and
#    accuracy.tsv (bench-m4/src/bin/identify/);
# 2. build the bench image with those tables and count executed instructions
#    per call on Cortex-M4F (QEMU netduinoplus2 + the insn_count TCG plugin);
# 3. print the instruction table, the per-model summary (cost, code and RAM
#    bytes, held-out accuracy) and the accuracy table.
# With --check, fails when a count regresses by more than 10 % against
# bench-m4/baseline.tsv; with --update, rewrites that file. With
# --profile GROUP (e.g. ctl_run_effects), runs the image again and prints
# where GROUP's three slowest calls spend their instructions, by function
# (bench-m4/profile.py), instead of the tables.
#
# Needs: rustup target thumbv7em-none-eabihf and llvm-tools (rust-toolchain.toml),
# gcc, qemu-system-arm (apt-get install -y qemu-system-arm), python3.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/.." && pwd)
mode=${1:-}
target_dir=${CARGO_TARGET_DIR:-$root/target}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

gcc -shared -fPIC -O2 -Wall -Wextra -o "$work/libinsn_count.so" "$here/plugin/insn_count.c"
(cd "$root" && cargo run -q -p bench-m4 --features host --bin identify --release >/dev/null)
# The bench image is built with the firmware's release profile (LTO, one codegen
# unit: the `fw-*` aliases in .cargo/config.toml), which is what a user flashes.
(cd "$root" && cargo build -q -p bench-m4 --target thumbv7em-none-eabihf --release --features chip \
  --config "profile.release.lto = true" --config "profile.release.codegen-units = 1")
elf=$target_dir/thumbv7em-none-eabihf/release/bench-m4
nm=$(ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-nm | head -n1)
start=$("$nm" "$elf" | awk '/ bench_marker_start$/ {print "0x"$1}')
end=$("$nm" "$elf" | awk '/ bench_marker_end$/ {print "0x"$1}')

timeout 300 qemu-system-arm -machine netduinoplus2 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native -kernel "$elf" \
  -plugin "$work/libinsn_count.so,start=$start,end=$end" >"$work/out.txt" 2>"$work/regions.txt"

"$nm" --print-size --size-sort --radix=d "$elf" >"$work/symbols.txt"
objdump=$(ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-objdump | head -n1)
"$objdump" -d --no-show-raw-insn "$elf" >"$work/disasm.txt"
if [ "$mode" = "--profile" ]; then
  group=${2:?"--profile needs a group, e.g. ctl_run_effects"}
  threshold=$(python3 "$here/profile.py" threshold "$work/out.txt" "$work/regions.txt" "$group")
  timeout 300 qemu-system-arm -machine netduinoplus2 -nographic -monitor none -serial none \
    -semihosting-config enable=on,target=native -kernel "$elf" \
    -plugin "$work/libinsn_count.so,start=$start,end=$end,profile=$threshold" >/dev/null 2>"$work/profile.txt"
  "$nm" --print-size --radix=d --demangle "$elf" >"$work/functions.txt"
  python3 "$here/profile.py" show "$work/out.txt" "$work/profile.txt" "$work/functions.txt" "$group"
  exit 0
fi
python3 "$here/report.py" "$work/out.txt" "$work/regions.txt" "$work/symbols.txt" "$here/baseline.tsv" "$mode" \
  "$work/disasm.txt" "$here/accuracy.tsv"
echo
echo "Held-out accuracy (bench-m4/accuracy.md):"
echo
cat "$here/accuracy.md"

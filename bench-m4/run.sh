#!/usr/bin/env bash
# Executed-instruction counts per call on Cortex-M4F (QEMU netduinoplus2 + the
# insn_count TCG plugin). Prints a Markdown table; with --check, fails when a
# count regresses by more than 10 % against bench-m4/baseline.tsv; with
# --update, rewrites that file.
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
(cd "$root" && cargo build -q -p bench-m4 --target thumbv7em-none-eabihf --release --features chip)
elf=$target_dir/thumbv7em-none-eabihf/release/bench-m4
nm=$(ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-nm | head -n1)
size=$(ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-size | head -n1)
start=$("$nm" "$elf" | awk '/ bench_marker_start$/ {print "0x"$1}')
end=$("$nm" "$elf" | awk '/ bench_marker_end$/ {print "0x"$1}')

timeout 300 qemu-system-arm -machine netduinoplus2 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native -kernel "$elf" \
  -plugin "$work/libinsn_count.so,start=$start,end=$end" >"$work/out.txt" 2>"$work/regions.txt"

"$nm" --print-size --size-sort --radix=d "$elf" >"$work/symbols.txt"
python3 "$here/report.py" "$work/out.txt" "$work/regions.txt" "$work/symbols.txt" "$here/baseline.tsv" "$mode"

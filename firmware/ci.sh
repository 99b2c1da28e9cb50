#!/usr/bin/env bash
# Firmware CI, called by .ci/run: installs what it needs, lints the chip
# builds, builds the board image and checks it against the size budget and
# for panic paths from the control step (firmware/panic-check.sh), then
# runs the QEMU image (run-pass: exit 0 only when the tracking error stays
# within the stated bound and the injected fault is caught) and the QEMU
# image with a corrupt coefficient blob (must be refused at boot).
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== firmware: tools"
rustup target add thumbv7em-none-eabihf
rustup component add llvm-tools clippy
command -v qemu-system-arm >/dev/null || (apt-get update && apt-get install -y qemu-system-arm)
qemu-system-arm --version | head -n 1

target_dir=${CARGO_TARGET_DIR:-$PWD/target}
elf=$target_dir/thumbv7em-none-eabihf/release/firmware
llvm_size=$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/llvm-size

echo "== firmware: clippy for thumbv7em-none-eabihf (board and QEMU images)"
cargo fw-clippy-chip
cargo fw-clippy

echo "== firmware: board image and size budget"
cargo fw-build
"$llvm_size" -A "$elf"
read -r flash ram < <("$llvm_size" -A "$elf" | awk '
  /^\.(vector_table|text|rodata|data|pam_coeffs|gnu\.sgstubs) / { flash += $2 }
  /^\.(data|bss|uninit) / { ram += $2 }
  END { print flash + 0, ram + 0 }')
flash_budget=$(awk '$1 == "flash_bytes" { print $2 }' firmware/size-budget.txt)
ram_budget=$(awk '$1 == "ram_bytes" { print $2 }' firmware/size-budget.txt)
echo "flash $flash / $flash_budget bytes, static RAM $ram / $ram_budget bytes"
if [ "$flash" -gt "$flash_budget" ] || [ "$ram" -gt "$ram_budget" ]; then
  echo "firmware: over the size budget (firmware/size-budget.txt)" >&2
  exit 1
fi

echo "== firmware: no panic reachable from the control step (board image)"
bash firmware/panic-check.sh

echo "== firmware: QEMU run-pass (netduinoplus2)"
timeout 300 cargo fw-qemu

echo "== firmware: QEMU, corrupt coefficient blob must be refused at boot"
set +e
out=$(timeout 300 cargo fw-qemu-bad-blob 2>&1)
status=$?
set -e
echo "$out" | tail -n 3
if [ "$status" -eq 0 ] || ! grep -q "coefficient blob refused" <<<"$out"; then
  echo "firmware: the corrupt blob was not refused (exit $status)" >&2
  exit 1
fi
echo "firmware: OK"

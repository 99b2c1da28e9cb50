#!/usr/bin/env bash
# Every exception vector of an image reaches a handler of the image's own
# (firmware::crash: HardFault, NonMaskableInt, DefaultHandler, each putting
# the valves safe first) or one of the interrupt handlers named after ELF,
# and none reaches cortex-m-rt's defaults (`DefaultHandler_`, `HardFault_`:
# an endless loop that leaves the valves as they were).
#
# Reads the ELF's .vector_table (llvm-objdump) and maps each entry past the
# reset vector to the symbols at its address (llvm-nm). Reserved entries (0)
# are skipped. Fails on an entry that reaches a default, or reaches no
# allowed handler.
#
# usage: firmware/vector-check.sh ELF [HANDLER...]
#   e.g. firmware/vector-check.sh target/.../firmware TIM2
set -euo pipefail
elf=$1
shift
bin=$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin
echo "vector-check: $elf"
VECTOR_CHECK_EXTRA="$*" python3 -c '
import os, subprocess, sys

elf, bindir = sys.argv[1], sys.argv[2]
allowed = {"HardFault", "NonMaskableInt", "DefaultHandler"} | set(os.environ["VECTOR_CHECK_EXTRA"].split())
defaults = {"DefaultHandler_", "HardFault_"}

dump = subprocess.run([bindir + "/llvm-objdump", "-s", "-j", ".vector_table", elf],
                      check=True, capture_output=True, text=True).stdout
data = bytearray()
for line in dump.splitlines():
    parts = line.split()
    if len(parts) >= 2 and all(c in "0123456789abcdef" for c in parts[0]) and len(parts[1]) == 8:
        for word in parts[1:5]:
            if len(word) == 8 and all(c in "0123456789abcdef" for c in word):
                data += bytes.fromhex(word)
words = [int.from_bytes(data[i:i + 4], "little") for i in range(0, len(data) - 3, 4)]
if len(words) < 16:
    sys.exit("vector-check: no vector table in %s" % elf)

names = {}
nm = subprocess.run([bindir + "/llvm-nm", elf], check=True, capture_output=True, text=True).stdout
for line in nm.splitlines():
    parts = line.split()
    if len(parts) == 3:
        names.setdefault(int(parts[0], 16), set()).add(parts[2])

bad = []
checked = 0
for i, w in enumerate(words[2:], start=2):  # 0: initial SP, 1: reset
    if w == 0:
        continue
    at = names.get(w & ~1, set())
    checked += 1
    if at & defaults or not at & allowed:
        shown = sorted(at & defaults) or sorted(at)[:3] or ["no symbol"]
        bad.append("vector %d (%s) -> %#010x %s" % (i, "exception" if i < 16 else "IRQ %d" % (i - 16),
                                                  w & ~1, ", ".join(shown)))
for b in bad:
    print("vector-check: " + b, file=sys.stderr)
if bad:
    sys.exit("vector-check: %d of %d vectors do not reach the image'"'"'s own handlers" % (len(bad), checked))
print("vector-check: all %d vectors reach %s" % (checked, ", ".join(sorted(allowed))))
' "$elf" "$bin"

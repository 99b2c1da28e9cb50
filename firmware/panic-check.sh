#!/usr/bin/env bash
# Panic-freedom of the control step in an LTO image (release, one codegen
# unit): the board controller (`cargo fw-build`, root
# `firmware::board::pam_board_control_step`) or the self-test image
# (`cargo fw-selftest-build` / `cargo fw-qemu-build`, root
# `firmware::scenario::pam_control_step`).
#
# The root (exported unmangled, not inlined) is the image's whole control
# period: sensor reads, the controller's update and the valve write. This
# disassembles the ELF, builds the call graph from
# every direct branch whose target lies in another function (`bl`, `b.w`,
# conditional `b<cc>.w` tail calls), and takes the transitive closure from
# `pam_control_step`. It fails if that set contains a panic entry point
# (`core::panicking::*`, `panic_bounds_check`, `*unwrap_failed`,
# `*expect_failed`, `slice_*_fail`, `rust_begin_unwind`, `panic_probe`), or an
# indirect call (`blx rN`, `bx rN` other than `bx lr`) that the graph cannot
# follow, or a `udf` trap (an abort). To show the check can fail it also requires the image
# to contain `core::panicking::panic_fmt` and at least one function that
# reaches it.
#
# usage: firmware/panic-check.sh [ELF [ROOT]]
#   (default: the board controller, root pam_board_control_step)
set -euo pipefail
cd "$(dirname "$0")/.."
target_dir=${CARGO_TARGET_DIR:-$PWD/target}
elf=${1:-$target_dir/thumbv7em-none-eabihf/release/firmware}
root=${2:-pam_board_control_step}
echo "panic-check: $elf, root $root"
bin=$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin
"$bin/llvm-objdump" -d --no-show-raw-insn -C "$elf" | PANIC_CHECK_ROOT="$root" python3 -c '
import os, re, sys

ROOT = os.environ["PANIC_CHECK_ROOT"]
PANIC = re.compile(r"core::panicking::|panic_bounds_check|unwrap_failed|expect_failed|"
                   r"slice_\w*_fail|str_index_overflow_fail|rust_begin_unwind|panic_probe|"
                   r"\bpanic_fmt\b|panic_const|panic_nounwind")
head = re.compile(r"^([0-9a-f]+) <(.*)>:$")
insn = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$")
target = re.compile(r"\b0x([0-9a-f]+) <")

funcs = {}            # start address -> name
calls = {}            # start address -> set of target addresses
indirect = {}         # start address -> list of indirect branch instructions
traps = {}            # start address -> list of udf (permanently undefined) instructions
cur = None
for line in sys.stdin:
    line = line.rstrip()
    m = head.match(line)
    if m:
        cur = int(m.group(1), 16)
        funcs[cur] = m.group(2)
        calls[cur] = set()
        indirect[cur] = []
        traps[cur] = []
        continue
    m = insn.match(line)
    if not m or cur is None:
        continue
    op, args = m.group(2), m.group(3)
    if op.startswith("udf"):
        traps[cur].append(m.group(1) + ": " + op + " " + args)
        continue
    if not op.startswith("b") or op.startswith(("bic", "bfi", "bfc", "bkpt")):
        continue
    t = target.search(args)
    if t:
        calls[cur].add(int(t.group(1), 16))
    elif op in ("blx", "bx") and not args.startswith("lr"):
        indirect[cur].append(m.group(1) + ": " + op + " " + args)

starts = sorted(funcs)
def owner(addr):
    lo, hi = 0, len(starts) - 1
    best = None
    while lo <= hi:
        mid = (lo + hi) // 2
        if starts[mid] <= addr:
            best = starts[mid]
            lo = mid + 1
        else:
            hi = mid - 1
    return best

graph = {f: {owner(a) for a in ts if owner(a) not in (None, f)} for f, ts in calls.items()}

def closure(root):
    seen, todo, parent = {root}, [root], {root: None}
    while todo:
        f = todo.pop()
        for g in graph[f]:
            if g not in seen:
                seen.add(g)
                parent[g] = f
                todo.append(g)
    return seen, parent

def path(parent, f):
    out = []
    while f is not None:
        out.append(funcs[f])
        f = parent[f]
    return " <- ".join(out)

roots = [a for a, n in funcs.items() if n == ROOT]
if len(roots) != 1:
    sys.exit("panic-check: %d functions named %s in the image (want 1)" % (len(roots), ROOT))
panics = {a for a, n in funcs.items() if PANIC.search(n)}
if not any(funcs[a] == "core::panicking::panic_fmt" for a in panics):
    sys.exit("panic-check: no core::panicking::panic_fmt in the image: the symbol names changed, the check would be vacuous")
if not any(closure(f)[0] & panics for f in funcs if f not in panics):
    sys.exit("panic-check: no function reaches a panic symbol: the call graph is broken, the check would be vacuous")

reach, parent = closure(roots[0])
bad = sorted(reach & panics)
ind = [(f, i) for f in sorted(reach) for i in indirect[f]]
udf = [(f, i) for f in sorted(reach) for i in traps[f]]
print("panic-check: %s reaches %d functions:" % (ROOT, len(reach) - 1))
for f in sorted(reach - {roots[0]}):
    print("  " + funcs[f])
for f in bad:
    print("panic-check: PANIC PATH " + path(parent, f), file=sys.stderr)
for f, i in ind:
    print("panic-check: indirect branch in %s (%s) cannot be followed" % (funcs[f], i), file=sys.stderr)
for f, i in udf:
    print("panic-check: trap in %s (%s): an abort path" % (funcs[f], i), file=sys.stderr)
if bad or ind or udf:
    sys.exit(1)
print("panic-check: no panic symbol reachable from %s (%d panic entry points in the image)" % (ROOT, len(panics)))
'

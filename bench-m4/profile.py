#!/usr/bin/env python3
"""Where a bench group's slowest calls spend their instructions
(`bench-m4/run.sh --profile GROUP`).

    profile.py threshold OUT REGIONS GROUP [K]
        the instruction count of GROUP's K-th slowest region (default 3):
        the plugin's `profile=` argument for the second run
    profile.py show OUT PROFILE SYMBOLS GROUP [K]
        for each of GROUP's K slowest regions in PROFILE (the second run's
        stderr), the instructions executed in each function and how often
        it was entered (calls: its first instruction's count; a function
        inlined into its caller counts in the caller)

OUT is the bench image's stdout (`group NAME COUNT` lines, in region order),
REGIONS the first run's plugin lines, SYMBOLS `llvm-nm --print-size
--radix=d --demangle` of the image. Counts are raw: the empty region's overhead (the
markers and the call) is not subtracted.
"""
import bisect
import collections
import re
import sys


def owners(out_path):
    """(group, index within the group) of every region, in order."""
    owner = []
    for line in open(out_path):
        p = line.split()
        if len(p) == 3 and p[0] == "group":
            owner.extend((p[1], i) for i in range(int(p[2])))
    return owner


def slowest(owner, counts, group, k):
    mine = [(c, owner[r][1], r) for r, c in counts.items() if r < len(owner) and owner[r][0] == group]
    if not mine:
        sys.exit(f"profile.py: no region of group `{group}` (see the group lines of the bench's output)")
    return sorted(mine, reverse=True)[:k]


def region_counts(path):
    counts = {}
    for line in open(path):
        p = line.split()
        if len(p) >= 4 and p[0] == "region":
            counts[int(p[1])] = int(p[3])
    return counts


def functions(symbols_path):
    syms = []
    for line in open(symbols_path):
        p = line.split(None, 3)
        if len(p) == 4 and p[2] in "tTwW":
            name = re.sub(r"::h[0-9a-f]{16}$", "", p[3].strip())
            syms.append((int(p[0]) & ~1, int(p[1]), name))
    syms.sort()
    return syms


def main():
    what = sys.argv[1]
    if what == "threshold":
        out, regions, group = sys.argv[2:5]
        k = int(sys.argv[5]) if len(sys.argv) > 5 else 3
        worst = slowest(owners(out), region_counts(regions), group, k)
        print(worst[-1][0])
        return
    out, profile, symbols, group = sys.argv[2:6]
    k = int(sys.argv[6]) if len(sys.argv) > 6 else 3
    owner = owners(out)
    syms = functions(symbols)
    starts = [s[0] for s in syms]
    counts, pcs, current = {}, {}, None
    for line in open(profile):
        p = line.split()
        if not p:
            continue
        if p[0] == "region":
            current = int(p[1])
            counts[current] = int(p[3])
        elif p[0] == "pc" and current is not None:
            pcs.setdefault(current, []).append((int(p[1], 16), int(p[2])))
    for count, index, r in slowest(owner, counts, group, k):
        print(f"{group} call {index}: {count} instructions")
        spent, calls = collections.Counter(), collections.Counter()
        for pc, n in pcs.get(r, []):
            i = bisect.bisect_right(starts, pc) - 1
            name = syms[i][2] if i >= 0 and pc < syms[i][0] + syms[i][1] else f"0x{pc:x}"
            spent[name] += n
            if i >= 0 and pc == syms[i][0]:
                calls[name] += n
        for name, n in spent.most_common():
            print(f"  {n:6d} instructions {calls[name]:4d} calls  {name}")


if __name__ == "__main__":
    main()

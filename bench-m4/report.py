"""Merge the bench image's group names with the plugin's region counts.

Each measured region includes the marker call overhead and the call of the
group's `bench_<group>` function; the `empty` group measures both (with an
empty `bench_empty`), and it is subtracted. Per group: mean and max
instructions per call, VDIV / VSQRT executed per call (mean), and the code
bytes reachable from `bench_<group>`: the sizes (llvm-nm --print-size) of it
and of every function it reaches through direct branches and calls in the
disassembly (shared functions count for each group that reaches them;
calls through pointers are not followed).

With the accuracy TSV written by the `identify` binary, a per-model summary
follows: cost, bytes and held-out accuracy side by side, and the issue's goals.
"""
import re
import sys

out_path, regions_path, symbols_path, baseline_path, mode = sys.argv[1:6]
disasm_path = sys.argv[6] if len(sys.argv) > 6 else None
accuracy_path = sys.argv[7] if len(sys.argv) > 7 else None

groups = []  # (name, n)
ram = {}  # group -> bytes of state and coefficients in RAM
table_bytes = {}  # group -> bytes of constant per-load tables (flash)
done = False
for line in open(out_path):
    parts = line.split()
    if parts[:1] == ["group"]:
        groups.append((parts[1], int(parts[2])))
    if parts[:1] == ["ram"]:
        ram[parts[1]] = int(parts[2])
    if parts[:1] == ["table"]:
        table_bytes[parts[1]] = int(parts[2])
    if parts[:1] == ["done"]:
        done = True
if not done:
    sys.exit("bench image did not finish: " + open(out_path).read())

regions = []
for line in open(regions_path):
    p = line.split()
    if p[:1] == ["region"]:
        regions.append((int(p[3]), int(p[5]), int(p[7])))

rows = {}
i = 0
for name, n in groups:
    chunk = regions[i : i + n]
    i += n
    if len(chunk) != n:
        sys.exit(f"group {name}: expected {n} regions, got {len(chunk)}")
    rows[name] = chunk
if i != len(regions):
    sys.exit(f"{len(regions)} regions for {i} announced calls")

overhead = min(r[0] for r in rows.pop("empty"))
table = []
for name, chunk in rows.items():
    insns = [r[0] - overhead for r in chunk]
    table.append(
        (
            name,
            sum(insns) / len(insns),
            max(insns),
            sum(r[1] for r in chunk) / len(chunk),
            sum(r[2] for r in chunk) / len(chunk),
        )
    )

# Symbol sizes and the direct call/branch graph.
sizes, addr_of = {}, {}
for line in open(symbols_path):
    p = line.split()
    if len(p) == 4:
        sizes[p[3]] = int(p[1])
        addr_of[p[3]] = int(p[0]) & ~1
name_at = {}  # address -> the name the disassembly uses (merged functions share one)
graph = {}
if disasm_path:
    func = None
    head = re.compile(r"^[0-9a-f]+ <(.+)>:$")
    insn = re.compile(r"^\s*[0-9a-f]+:\s+(\S+)\s+(.*)$")
    target = re.compile(r"<([^>+]+)(\+0x[0-9a-f]+)?>")
    for line in open(disasm_path):
        m = head.match(line.strip())
        if m:
            func = m.group(1)
            func_start = int(line.split()[0], 16)
            name_at[func_start] = func
            graph.setdefault(func, set())
            continue
        m = insn.match(line)
        if not (m and func):
            continue
        # Only the function's own bytes (padding and literal pools after it
        # disassemble as junk branches).
        if int(line.split(":")[0], 16) >= func_start + sizes.get(func, 1 << 30):
            continue
        op = m.group(1)
        if not (op.startswith("b") or op.startswith("cb")) or op.startswith(("bic", "bfi", "bfc", "bkpt")):
            continue
        t = target.search(m.group(2))
        # A call or tail call enters a function at its start (no +offset).
        if t and t.group(1) != func and not t.group(2):
            graph[func].add(t.group(1))


def reachable(name):
    # The controller-run groups share one measured function.
    root = "bench_controller_run" if name.startswith("ctl_") else "bench_" + name
    root = {"bench_memory_inverse_new_loop": "bench_memory_inverse"}.get(root, root)
    if root not in sizes or not graph:
        return None
    root = name_at.get(addr_of.get(root), root)  # an alias of an identical function
    seen, todo = set(), [root]
    while todo:
        f = todo.pop()
        if f in seen or f.startswith("bench_marker"):
            continue
        seen.add(f)
        todo.extend(graph.get(f, ()))
    return seen


def code_bytes(name):
    seen = reachable(name)
    return None if seen is None else sum(sizes.get(f, 0) for f in seen)


stats = {name: (mean, mx, vdiv, vsqrt) for name, mean, mx, vdiv, vsqrt in table}

print("| call | instructions (mean) | instructions (max) | VDIV per call | VSQRT per call | code bytes |")
print("|---|---:|---:|---:|---:|---:|")
for name, mean, mx, vdiv, vsqrt in table:
    cb = code_bytes(name)
    print(f"| `{name}` | {mean:.0f} | {mx} | {vdiv:.1f} | {vsqrt:.1f} | {cb if cb is not None else '-'} |")

if accuracy_path:
    # accuracy.tsv: comparison, model, held-out RMS, held-out max, training RMS.
    acc_by = {}
    for line in open(accuracy_path):
        if line.startswith("#") or not line.strip():
            continue
        comparison, key, rms, mxe, _train = line.split("\t")
        acc_by.setdefault(comparison, {})[key] = (float(rms), float(mxe))
    acc = acc_by.get("cycles", {})
    models = [
        ("pam-core, paper model", "paper_model_step", "pam_core"),
        ("pam-core, paper model + non-local memory", "nonlocal_memory_step", "pam_core_memory"),
        ("pam-core, fit's model (paper + static shape)", "fit_model_step", "pam_core_fit"),
        ("pam-core, fit's model + non-local memory", "fit_memory_step", "pam_core_fit_memory"),
        ("Prandtl–Ishlinskii, 16 plays", "pi16_step", "pi16"),
        ("generalised Prandtl–Ishlinskii, 4 plays + cubic input", "gpi4_step", "gpi4"),
        ("Preisach, 16 × 16 (136 relays)", "preisach16_step", "preisach16"),
    ]
    # What pam flashes: pam-core's models, the Preisach model among them
    # (the firmware boots its blob); the plays are baselines only.
    flashed = lambda key: key.startswith("pam_core") or key == "preisach16"
    pam_models = [m for m in models if flashed(m[2])]
    baselines = [m for m in models if not flashed(m[2])]
    print()
    print("| model (per-sample call) | instructions (mean / max) | VDIV / VSQRT | code bytes | RAM bytes | table bytes (flash) | held-out RMS (%) | held-out max (%) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for label, g, key in models:
        if g not in stats:
            continue
        mean, mx, vdiv, vsqrt = stats[g]
        a = acc.get(key)
        print(
            f"| {label} (`{g}`) | {mean:.0f} / {mx} | {vdiv:.1f} / {vsqrt:.1f} | {code_bytes(g) or '-'} | "
            f"{ram.get(g, '-')} | {table_bytes.get(g, 0)} | "
            + (f"{100 * a[0]:.3f} | {100 * a[1]:.3f} |" if a else "- | - |")
        )

    def mean_of(g):
        return stats[g][0] if g in stats else float("nan")

    fwd = max(mean_of("forward_contraction"), mean_of("forward_expansion"))
    inv = max(mean_of("inverse_contraction"), mean_of("inverse_expansion"))
    mem = mean_of("nonlocal_memory_step") - mean_of("simulator_step")
    ctl = mean_of("controller_step")
    pam, pi = mean_of("paper_model_step"), mean_of("pi16_step")
    pam_acc, pi_acc = acc.get("pam_core", (float("nan"),) * 2), acc.get("pi16", (float("nan"),) * 2)
    ok = lambda c: "met" if c else "**not met**"

    # Dominance (issue 30): on each comparison, the most accurate model pam
    # can flash, and every baseline (a model pam cannot flash) that is
    # cheaper (mean instructions per sample) and more accurate (held-out
    # RMS) at once.
    titles = {
        "cycles": "held-out cycles",
        "held_out_loads": "held-out loads",
        "load_sweep": "a slow load sweep (the held-out-load models)",
        "other_protocol": "another protocol",
        "other_muscle": "another muscle",
    }
    print()
    print("| comparison | most accurate model pam flashes | dominated by (fewer instructions and lower held-out RMS) |")
    print("|---|---|---|")
    never = True
    for comparison, rows in acc_by.items():
        pams = [(rows[k][0], label, g) for label, g, k in pam_models if k in rows and g in stats]
        if not pams:
            continue
        best_rms, best_label, best_g = min(pams)
        by = [
            f"{bl} ({stats[bg][0]:.0f} vs {stats[best_g][0]:.0f} instructions, {100 * rows[bk][0]:.3f} % vs {100 * best_rms:.3f} %)"
            for bl, bg, bk in baselines
            if bg in stats and bk in rows and stats[bg][0] < stats[best_g][0] and rows[bk][0] < best_rms
        ]
        never = never and not by
        print(
            f"| {titles.get(comparison, comparison)} | {best_label} ({100 * best_rms:.3f} %, "
            f"{stats[best_g][0]:.0f} instructions) | {'; '.join(by) if by else 'none'} |"
        )

    print()
    print("| goal (issue 7) | measured (mean instructions) | |")
    print("|---|---:|---|")
    print(f"| forward evaluation ≤ 40 | {fwd:.0f} | {ok(fwd <= 40)} |")
    print(f"| inverse ≤ 150 | {inv:.0f} | {ok(inv <= 150)} |")
    print(f"| non-local memory adds ≤ 60 (`nonlocal_memory_step` − `simulator_step`) | {mem:.0f} | {ok(mem <= 60)} |")
    print(f"| controller step ≤ 400 | {ctl:.0f} | {ok(ctl <= 400)} |")
    better = pam < pi and pam_acc[0] <= pi_acc[0]
    print(
        f"| fewer instructions than PI-16 at equal or better held-out RMS | "
        f"{pam:.0f} vs {pi:.0f}; RMS {100 * pam_acc[0]:.3f} % vs {100 * pi_acc[0]:.3f} % | {ok(better)} |"
    )
    print(
        f"| never dominated (issue 30): no baseline cheaper and more accurate than the most accurate "
        f"model pam flashes, on every comparison | see the table above | {ok(never)} |"
    )

# The controller's worst case over the representative run, every feedforward.
WORST_BOUND = 2000
MEAN_BOUND = 400
# Feedforwards measured over the bound (issue 30's open item, bench-m4/
# README.md): the model with every effect at once (the shape's inverse, the
# rate law's powf, the creep, the lag and the memory in one period: up to
# about 2 230 instructions on a period that moves the memory's loop to the
# rate law's new factor). Reported as not met,
# checked against the baseline for regressions like every call, and not
# counted in the guarded worst case. (`memory_rate` is guarded since a
# reversal's new loop searches for its ends over periods.)
# (`shape_memory` is guarded again since a reversal's new loop searches for
# its ends over periods while a load switch's tables are built too.)
OVER_BUDGET = {"effects"}
runs = [(n, st) for n, st in stats.items() if n.startswith("ctl_run_")]
guarded = [(n, st) for n, st in runs if n[len("ctl_run_"):] not in OVER_BUDGET]
worst = max((st[1] for _, st in guarded), default=None)
if runs:
    print()
    print("| controller, representative run (2050 steps) | mean | max | reversal steps: max | load-switch steps: max | nested run: max |")
    print("|---|---:|---:|---:|---:|---:|")
    for n, st in runs:
        ff = n[len("ctl_run_"):]
        rev = stats.get("ctl_reversal_" + ff, (0, "-"))[1]
        ls = stats.get("ctl_load_switch_" + ff, (0, "-"))[1]
        nested = stats.get("ctl_nested_" + ff, (0, "-"))[1]
        print(f"| `{ff}` | {st[0]:.0f} | {st[1]} | {rev} | {ls} | {nested} |")
    print()
    print(f"| goal (issue 14) | measured | |")
    print("|---|---:|---|")
    print(f"| every path of one controller step ≤ {WORST_BOUND} instructions (worst case over the run, every feedforward but those below) | {worst} | {'met' if worst <= WORST_BOUND else '**not met**'} |")
    for n, st in runs:
        ff = n[len("ctl_run_"):]
        if ff in OVER_BUDGET:
            print(f"| the same, `{ff}` (not guarded: an open item) | {st[1]} | {'met' if st[1] <= WORST_BOUND else '**not met**'} |")
    # The nested run (a wipe-out that exposes a remembered loop): measured
    # and reported, not guarded (an open item of issue 30, bench-m4/README.md).
    nested = [(n, st) for n, st in stats.items()
              if n.startswith("ctl_nested_") and n[len("ctl_nested_"):] not in OVER_BUDGET]
    if nested:
        n_worst, st_worst = max(nested, key=lambda x: x[1][1])
        print(f"| the same over the nested run (not guarded: an open item; the slowest `{n_worst[len('ctl_nested_'):]}`) | {st_worst[1]} | {'met' if st_worst[1] <= WORST_BOUND else '**not met**'} |")
    for n, st in runs:
        print(f"| mean ≤ {MEAN_BOUND}, `{n[len('ctl_run_'):]}` | {st[0]:.0f} | {'met' if st[0] <= MEAN_BOUND else '**not met**'} |")

if mode == "--update":
    with open(baseline_path, "w") as f:
        f.write("# call\tmean_instructions\tmax_instructions (regenerate: bench-m4/run.sh --update)\n")
        for name, mean, mx, _, _ in table:
            f.write(f"{name}\t{mean:.1f}\t{mx}\n")
    print(f"\nwrote {baseline_path}")
elif mode == "--check":
    base = {}
    for line in open(baseline_path):
        if line.startswith("#") or not line.strip():
            continue
        name, mean, mx = line.split("\t")
        base[name] = (float(mean), int(mx))
    bad = []
    for name, mean, mx, _, _ in table:
        if name not in base:
            bad.append(f"{name}: not in the committed baseline (run bench-m4/run.sh --update)")
            continue
        bmean, bmax = base[name]
        if mean > 1.10 * bmean or mx > 1.10 * bmax:
            bad.append(f"{name}: mean {mean:.0f} / max {mx} vs baseline {bmean:.0f} / {bmax} (> +10 %)")
    if worst is not None and worst > WORST_BOUND:
        bad.append(f"controller worst case {worst} > {WORST_BOUND} instructions")
    if bad:
        print("\ninstruction-count regression:\n  " + "\n  ".join(bad))
        sys.exit(1)
    print("\nno call regressed more than 10 % against bench-m4/baseline.tsv")

"""Merge the bench image's group names with the plugin's region counts.

Each measured region includes the marker call overhead; the `empty` group
measures it, and it is subtracted. Per group: mean and max instructions per
call, and VDIV / VSQRT executed per call (mean).
"""
import sys

out_path, regions_path, symbols_path, baseline_path, mode = sys.argv[1:6]

groups = []  # (name, n)
done = False
for line in open(out_path):
    parts = line.split()
    if parts[:1] == ["group"]:
        groups.append((parts[1], int(parts[2])))
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

print("| call | instructions (mean) | instructions (max) | VDIV per call | VSQRT per call |")
print("|---|---:|---:|---:|---:|")
for name, mean, mx, vdiv, vsqrt in table:
    print(f"| `{name}` | {mean:.0f} | {mx} | {vdiv:.1f} | {vsqrt:.1f} |")

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
    if bad:
        print("\ninstruction-count regression:\n  " + "\n  ".join(bad))
        sys.exit(1)
    print("\nno call regressed more than 10 % against bench-m4/baseline.tsv")

#!/usr/bin/env python3
"""Format pam-lab/measure.sh's runs as pam-lab/MEASURED.md (stdout).

usage: measure.py WORK COMMIT

A section is regenerated from the runs in WORK when measure.sh made them,
and kept as the committed MEASURED.md has it otherwise (each says the
commit it was measured at and the command that measures it again).
"""
import json
import os
import re
import sys
from datetime import date

work, commit = sys.argv[1], sys.argv[2]
here = os.path.dirname(os.path.abspath(__file__))
stamp = f"measured at commit {commit}, {date.today().isoformat()}"


def load(path):
    with open(path) as f:
        return json.load(f)


def seconds(name):
    with open(os.path.join(work, name + ".time")) as f:
        return float(f.read())


def names(effects):
    return "+".join(effects) if effects else "none"


def fit_row(d):
    fit = load(os.path.join(d, "model.json"))["fit"]
    total = (fit.get("heldout_errors") or {}).get("total") or {}
    ref = fit.get("reference_heldout_rms_mpa")
    p = total.get("pressure_rms_mpa")
    ratio = f"{p / ref:.2f}" if p and ref else "-"
    return total, ratio


def closed_loop_cell(r):
    """The closed-loop check's verdict and the geometric mean of the diagnosed
    controller's RMS error over fit's, on a muscle that is the diagnosed model."""
    c = r.get("closed_loop")
    if not c:
        return "-"
    word = "accepted" if c["accepted"] else "fit's written"
    if not c["runs"]:
        return "not judged" if c["accepted"] else word
    fault = any(x["diagnosed"].get("first_fault") and not x["fit"].get("first_fault") for x in c["runs"])
    return f"{word} ({c['diagnosed_over_fit']:.2f}{', safe state' if fault else ''})"


def diag_cells(d):
    r = load(os.path.join(d, "report.json"))
    return r, (
        f"{names(r['effects_added'])} | {r['rms_before']:.5f} → {r['rms_after']:.5f} | "
        f"{r['residual_noise']:.5f} | {r['above_noise_before']:.5f} → "
        f"{r['above_noise_after']:.5f} ({100 * r['above_noise_removed']:.0f} %) | {closed_loop_cell(r)}"
    )


def records_table(sub, title, blurb, command):
    d = os.path.join(work, sub)
    if not os.path.isdir(d):
        return None
    stems = sorted(n[len("diag_"):] for n in os.listdir(d) if n.startswith("diag_") and not n.endswith((".log", ".time")))
    out = [f"## {title}", "", blurb, "", f"`{command}` ({stamp}).", ""]
    out.append("| record | fit: held-out contraction RMS | fit: held-out pressure RMS (MPa) | fit / reference surface (pressure) | fit (s) | diagnose named | diagnose: held-out RMS before → after | noise | above the noise before → after (removed) | closed loop (diagnosed / fit) | diagnose (s) |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for s in stems:
        total, ratio = fit_row(os.path.join(d, "fit_" + s))
        _, cells = diag_cells(os.path.join(d, "diag_" + s))
        out.append(
            f"| {s} | {total.get('contraction_rms', float('nan')):.5f} | {total.get('pressure_rms_mpa', float('nan')):.5f} | "
            f"{ratio} | {seconds(f'{sub}/fit_{s}'):.1f} | {cells} | {seconds(f'{sub}/diag_{s}'):.1f} |"
        )
    out.append("")
    out.append(
        "fit's columns are its own held-out cycles (`every:4`); diagnose's are its held-out "
        "segments (an isometric record's residual is in pressure, MPa, an isotonic one's in "
        "contraction), \"noise\" the record's own noise in the same quantity. \"closed loop\" is "
        "diagnose's closed-loop check (pam-lab/DIAGNOSE.md step 9): whether the diagnosed model is "
        "written, and its controller's RMS error over fit's on a muscle that is that model "
        "(geometric mean over three loads and four set-points)."
    )
    return "\n".join(out)


def festo_table():
    d = os.path.join(work, "festo")
    if not os.path.isdir(d):
        return None
    out = [
        "## Real muscles: the Festo 10 mm set",
        "",
        "Tests 8 and 9 train, test 10 validates (`--validate`); pressure RMS on test 10 in kPa, "
        "the reference surface (30 coefficients, least squares, no hysteresis) fitted to the same "
        "training samples. \"the cubic alone\" is fit with `--no-static-shape`. \"timing\" is the "
        "shift of the measured pressure that diagnose's model matches best (`timing` line), and "
        "what it cuts. \"delay\" is the pressure delay diagnose's model carries, where it names one, "
        "and \"reference, delayed\" the reference surface fitted and judged with the pressure taken "
        "that delay earlier: how much of the model's lead over the reference is the delay's.",
        "",
        f"`pam-lab/measure.sh --festo DIR` ({stamp}); the commands it runs for each length are "
        "in pam-lab/README.md.",
        "",
        "| muscle | training samples | test-10 samples | fit (kPa) | the cubic alone (kPa) | diagnose (kPa) | reference (kPa) | fit / reference | diagnose / reference | diagnose named | delay | reference, delayed (kPa) | timing | fit (s) | diagnose (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for L in (10, 15, 20, 25, 30, 40):
        fit = load(os.path.join(d, f"fit_{L}", "model.json"))["fit"]
        cubic = load(os.path.join(d, f"cubic_{L}", "model.json"))["fit"]
        r = load(os.path.join(d, f"diag_{L}", "report.json"))
        v = fit["validation"]
        ref = v["reference_rms_mpa"]
        p_fit = v["model"]["total"]["pressure_rms_mpa"]
        p_cubic = cubic["validation"]["model"]["total"]["pressure_rms_mpa"]
        dv = r["validation"]
        p_diag = dv["model"]["pressure_rms_mpa"]
        lag = r.get("pressure_lag")
        timing = (
            f"{1000 * lag['lag_s']:.0f} ms ({100 * (1 - lag['rms_at_lag_mpa'] / lag['rms_unshifted_mpa']):.1f} %)"
            if lag
            else "-"
        )
        delay = (r.get("effects") or {}).get("pressure_delay")
        delay_ms = f"{1000 * delay['delay_s']:.1f} ms" if delay else "-"
        ref_delayed = dv.get("reference_delayed_rms_mpa")
        ref_delayed = f"{1000 * ref_delayed:.1f}" if ref_delayed is not None else "-"
        out.append(
            f"| {L} cm | {fit['training_samples']} | {v['model']['total']['samples']} | {1000 * p_fit:.1f} | "
            f"{1000 * p_cubic:.1f} | {1000 * p_diag:.1f} | {1000 * ref:.1f} | {p_fit / ref:.2f} | "
            f"{p_diag / dv['reference_rms_mpa']:.2f} | {', '.join(r['effects_added']) or 'none'} | {delay_ms} | {ref_delayed} | {timing} | "
            f"{seconds(f'festo/fit_{L}'):.1f} | {seconds(f'festo/diag_{L}'):.1f} |"
        )
    return "\n".join(out)


def hidden_tables():
    d = os.path.join(work, "hidden")
    if not os.path.isdir(d):
        return None
    groups = {"a": [], "b": [], "top": []}
    for n in sorted(os.listdir(d)):
        m = re.fullmatch(r"diag_(a|b|top)_(.+)_(\d+)", n)
        if not m:
            continue
        proto, expected, seed = m.group(1), m.group(2), int(m.group(3))
        r, cells = diag_cells(os.path.join(d, n))
        want = set() if expected == "none" else set(expected.split("+"))
        right = "right" if set(r["effects_added"]) == want else "**wrong**"
        head, rest = cells.split(" | ", 1)
        groups[proto].append(
            (expected, seed, f"| {expected} | {seed} | {head} ({right}) | {rest} | {r['extrapolated_samples']} | {seconds('hidden/' + n):.1f} |")
        )
    titles = {
        "a": "Protocol A (the examples' protocol, short version, 50 Hz, 100–350 N)",
        "b": "Protocol B (100 Hz; full cycles, a decaying oscillation, random reversals, two steps with 5 s holds, six load blocks)",
        "top": "A rig run below its muscle's `Pmax` (protocol A, the loop closing at 0.56 MPa, the record's top at 0.5 MPa)",
    }
    out = [
        "## diagnose on the hidden plants",
        "",
        "Plants independent of pam-core's effect equations (`pam-lab/tests/support/hidden_plants.rs`), "
        "seeds 1–3, generated by `write_hidden_plant_records`.",
        "",
        f"`pam-lab/measure.sh --hidden` ({stamp}).",
    ]
    for proto in ("a", "b", "top"):
        out += ["", titles[proto] + ":", ""]
        out.append("| plant (expected) | seed | named | held-out RMS before → after | noise | above the noise before → after (removed) | closed loop (diagnosed / fit) | extrapolated | diagnose (s) |")
        out.append("|---|---|---|---|---|---|---|---|---|")
        out += [row for _, _, row in sorted(groups[proto])]
    return "\n".join(out)


def committed_sections():
    path = os.path.join(here, "MEASURED.md")
    if not os.path.exists(path):
        return {}
    text = open(path).read()
    parts = re.split(r"(?m)^(?=## )", text)
    return {p.splitlines()[0]: p.rstrip() for p in parts if p.startswith("## ")}


def readme_block(table):
    """The Festo table also stands in pam-lab/README.md, between its markers."""
    path = os.path.join(here, "README.md")
    text = open(path).read()
    begin, end = "<!-- festo table: pam-lab/measure.sh --festo DIR -->", "<!-- end of festo table -->"
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        sys.exit(f"{path}: the markers of the Festo table are missing")
    body = "\n".join(table.split("\n")[2:])  # without the heading
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(text[: i + len(begin)] + "\n" + body + "\n" + text[j:])
    os.replace(tmp, path)


old = committed_sections()
festo = festo_table()
sections = [
    (
        "## The repository's examples",
        records_table(
            "repo",
            "The repository's examples",
            "`examples/*.csv`: host-sim's rig (a static curve outside the paper's cubic, Maxwell-slip "
            "friction), isotonic, and one isometric record (examples/README.md says how each was made).",
            "pam-lab/measure.sh",
        ),
    ),
    (
        "## An independent simulator's examples",
        records_table(
            "ex",
            "An independent simulator's examples",
            "Five isotonic records of another rig simulator, each with one effect beyond the paper's "
            "model (`example_1` none, `_2` non-local memory, `_3` rate dependence, `_4` creep, `_5` "
            "load-dependent width); not shipped, read by no test.",
            "pam-lab/measure.sh --examples DIR",
        ),
    ),
    (
        "## A long record",
        records_table(
            "long",
            "A long record",
            "The time a user-sized record takes: host-sim's reference muscle through its end-to-end "
            "protocol logged at 250 Hz (`cargo run --release -p host-sim --example long_record -- "
            "long.csv`: 103 500 rows), each command timed as a whole process on two cores.",
            "pam-lab/measure.sh --long",
        ),
    ),
    ("## Real muscles: the Festo 10 mm set", festo),
    ("## diagnose on the hidden plants", hidden_tables()),
    # Printed by the tests that check them (each names its command): kept.
    ("## Measured by the tests", None),
]
# Every section is made before anything is written: a failure leaves the
# README and MEASURED.md as they were.
if festo is not None:
    readme_block(festo)
print("# pam-lab: measured")
print()
print(
    "Every table here is written by `pam-lab/measure.sh` (release build, one command at a time on "
    "a two-core machine); a section not measured by the last run is kept as it was, with the commit "
    "it was measured at. Do not edit by hand."
)
for heading, fresh in sections:
    text = fresh if fresh is not None else old.get(heading)
    if text:
        print()
        print(text)

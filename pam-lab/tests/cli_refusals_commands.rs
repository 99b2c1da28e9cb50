//! Every kind of bad input to `simulate` and `diagnose`, and the common
//! mistakes a record contradicts, one test each, checked as
//! `cli_refusals.rs` checks `fit`'s: exit code 1, one located `error:`
//! line, the directory exactly as it was.

#[path = "support/refusals.rs"]
mod refusals;

use std::process::Command;

use pam_core::Params;
use refusals::*;

// ---- simulate ----

#[test]
fn simulate_missing_model() {
    refused(
        &[("bad.csv", csv(good_csv()))],
        &["simulate", "nope.json", "bad.csv"],
        &["error: nope.json: cannot read"],
    );
}

#[test]
fn simulate_corrupt_blob() {
    let mut blob = pam_core::blob::encode(&Params::DEFAULT).to_vec();
    blob[30] ^= 4;
    refused(
        &[
            ("bad.csv", csv(good_csv())),
            ("m.blob", blob),
            ("sim.csv", csv("old")),
        ],
        &["simulate", "m.blob", "bad.csv", "-o", "sim.csv"],
        &["error: m.blob: ", "CRC"],
    );
}

#[test]
fn simulate_model_not_json() {
    refused(
        &[
            ("bad.csv", csv(good_csv())),
            ("m.json", csv("{\n  \"format\": 3,\n")),
        ],
        &["simulate", "m.json", "bad.csv"],
        &["error: m.json:2:", "not a model file"],
    );
}

#[test]
fn simulate_model_of_another_version() {
    let text = String::from_utf8(model_json())
        .unwrap()
        .replace("\"version\": 1", "\"version\": 7");
    refused(
        &[("bad.csv", csv(good_csv())), ("m.json", csv(text))],
        &["simulate", "m.json", "bad.csv"],
        &["error: m.json: format `pam-lab model` version 7"],
    );
}

#[test]
fn simulate_negative_deadband() {
    refused(
        &[("bad.csv", csv(good_csv())), ("model.json", model_json())],
        &["simulate", "model.json", "bad.csv", "--deadband", "-1"],
        &["error: invalid setting `--deadband`"],
    );
}

#[test]
fn simulate_zero_load_threshold() {
    refused(
        &[("bad.csv", csv(good_csv())), ("model.json", model_json())],
        &["simulate", "model.json", "bad.csv", "--load-threshold", "0"],
        &["error: invalid setting `--load-threshold`"],
    );
}

#[test]
fn simulate_zero_debounce() {
    refused(
        &[("bad.csv", csv(good_csv())), ("model.json", model_json())],
        &["simulate", "model.json", "bad.csv", "--debounce", "0"],
        &["error: invalid setting `--debounce`"],
    );
}

#[test]
fn simulate_output_is_a_directory() {
    refused(
        &[
            ("bad.csv", csv(good_csv())),
            ("model.json", model_json()),
            ("sim.csv/", vec![]),
        ],
        &["simulate", "model.json", "bad.csv", "-o", "sim.csv"],
        &["error: sim.csv: cannot write: is a directory"],
    );
}

#[test]
fn simulate_plot_into_a_missing_directory_writes_no_csv() {
    refused(
        &[("bad.csv", csv(good_csv())), ("model.json", model_json())],
        &[
            "simulate",
            "model.json",
            "bad.csv",
            "-o",
            "sim.csv",
            "--plot",
            "no/such/sim.png",
        ],
        &["error: no/such: cannot write into it: No such file"],
    );
}

#[test]
fn simulate_same_file_for_csv_and_plot() {
    refused(
        &[("bad.csv", csv(good_csv())), ("model.json", model_json())],
        &[
            "simulate",
            "model.json",
            "bad.csv",
            "-o",
            "x.png",
            "--plot",
            "x.png",
        ],
        &["error: x.png: cannot write: named twice in one command"],
    );
}

#[test]
fn simulate_time_never_advances() {
    simulate_refuses(
        csv(edited(|_, f| f[0] = "0".into())),
        &["error: bad.csv: column `t_s`: every time stamp is the same"],
    );
}

#[test]
fn simulate_constant_pressure() {
    simulate_refuses(
        csv(edited(|_, f| f[2] = "0".into())),
        &["error: bad.csv: column `pressure_mpa`: holds 0 on every sample"],
    );
}

#[test]
fn simulate_semicolon_separated() {
    simulate_refuses(
        csv(good_csv().replace(',', ";")),
        &["error: bad.csv:1: the header is separated by `;`"],
    );
}

// ---- diagnose ----

#[test]
fn diagnose_max_effects_out_of_range() {
    refused(
        &[("bad.csv", csv(good_csv()))],
        &["diagnose", "bad.csv", "-o", "diag", "--max-effects", "6"],
        &["invalid value '6' for '--max-effects <N>': 6 is not in 0..=5"],
    );
}

#[test]
fn diagnose_too_few_samples() {
    let rows: Vec<String> = good_rows().into_iter().take(60).collect();
    diagnose_refuses(
        csv(format!("{HEADER}\n{}\n", rows.join("\n"))),
        &["error: bad.csv: too few samples to identify the model: 60 samples, diagnose needs at least 100"],
    );
}

#[test]
fn diagnose_one_load_is_said_once() {
    diagnose_refuses(
        csv(edited(|_, f| f[1] = "100".into())),
        &[
            "error: base fit: bad.csv (training part): column `load_n`: too few samples",
            // The training part keeps the file's line numbers.
            "(first training line 2)",
        ],
    );
}

#[test]
fn diagnose_load_that_never_holds() {
    // A load cell's noise of a few newtons on every sample: no load blocks.
    diagnose_refuses(
        csv(edited(|i, f| {
            let load: f64 = f[1].parse().unwrap();
            f[1] = format!("{}", load + 3.0 * ((i * 7919 % 13) as f64 / 6.0 - 1.0));
        })),
        &["error: bad.csv: column `load_n`: too few samples to identify the model: diagnose holds out whole stretches of one load (within 1 N)"],
    );
}

#[test]
fn diagnose_output_is_a_file() {
    refused(
        &[("bad.csv", csv(good_csv())), ("diag", csv("a file"))],
        &["diagnose", "bad.csv", "-o", "diag"],
        &["error: diag: cannot write into it: not a directory"],
    );
}

#[test]
fn diagnose_residual_plot_blocked_writes_no_report() {
    let rec = format!("{HEADER}\n{}\n", rows_at(&[100.0, 200.0, 300.0]).join("\n"));
    refused(
        &[("bad.csv", csv(rec)), ("diag/residual.png/", vec![])],
        &["diagnose", "bad.csv", "--out", "diag"],
        &["error: diag/residual.png: cannot write: is a directory"],
    );
}

#[test]
fn diagnose_negative_deadband() {
    refused(
        &[("bad.csv", csv(good_csv()))],
        &["diagnose", "bad.csv", "--deadband", "-1"],
        &["error: invalid setting `--deadband`"],
    );
}

#[test]
fn diagnose_binary_file() {
    diagnose_refuses(
        b"PK\x03\x04\x14\x00\x00\x00\x08\x00".to_vec(),
        &["error: bad.csv: not a text file"],
    );
}

#[test]
fn diagnose_pressure_in_kpa() {
    diagnose_refuses(
        csv(good_csv().replacen("pressure_mpa", "pressure_kpa", 1)),
        &["error: bad.csv:1: column `pressure_mpa`: header names `pressure_kpa`"],
    );
}

#[test]
fn diagnose_contraction_stuck() {
    let n = good_rows().len();
    diagnose_refuses(
        csv(edited(|i, f| {
            if i >= n / 2 {
                f[3] = "0.1".into();
            }
        })),
        &[&format!(
            "error: bad.csv:{}: column `contraction`: stuck at 0.1",
            n / 2 + 2
        )],
    );
}

// ---- accepted: what used to be refused for the wrong reason ----

#[test]
fn a_byte_order_mark_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = b"\xEF\xBB\xBF".to_vec();
    bytes.extend(good_csv().into_bytes());
    std::fs::write(dir.path().join("bom.csv"), bytes).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_pam-lab"))
        .args(["fit", "bom.csv", "-o", "out", "--no-plot", "-q"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(dir.path().join("out/model.json").is_file());
    assert!(out.stdout.is_empty(), "quiet");
}

// ---- common mistakes the record contradicts ----

#[test]
fn fit_test_kind_the_record_contradicts() {
    refused(
        &[("bad.csv", csv(good_csv()))],
        &["fit", "bad.csv", "-o", "out", "--test", "isometric"],
        &[
            "error: invalid setting `--test`: `isometric`, but in bad.csv the load holds while \
             the contraction moves: it is isotonic",
        ],
    );
}

#[test]
fn diagnose_pmax_below_most_samples() {
    refused(
        &[("bad.csv", csv(good_csv()))],
        &["diagnose", "bad.csv", "-o", "diag", "--pmax", "0.05"],
        &[
            "invalid setting `--pmax`: 0.05 MPa, but",
            "lie above it (its top is",
        ],
    );
}

#[test]
fn fit_contraction_with_its_sign_flipped() {
    fit_refuses(
        csv(edited(|_, f| {
            f[3] = format!("{}", -f[3].parse::<f64>().unwrap())
        })),
        &[
            "error: bad.csv: column `contraction`: falls as the pressure rises",
            "is its sign flipped?",
        ],
    );
}

#[test]
fn simulate_plot_that_is_not_png() {
    refused(
        &[("rec.csv", csv(good_csv())), ("model.json", model_json())],
        &[
            "simulate",
            "model.json",
            "rec.csv",
            "-o",
            "sim.csv",
            "--plot",
            "x.svg",
        ],
        &["error: invalid setting `--plot`: x.svg: the plot is drawn as PNG only (name it .png)"],
    );
}

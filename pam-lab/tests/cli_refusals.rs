//! Every kind of bad input to `fit`, `simulate` and `diagnose`, one test
//! each: the command exits with code 1, prints one `error:` line that
//! locates the defect (file, line and column where there is one) and gives
//! its reason, and leaves the directory exactly as it was (no output file,
//! no output directory, no staging leftovers; a previous output untouched).
//!
//! Every command runs in a fresh temporary directory with relative paths,
//! so the messages are compared as a user sees them.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use pam_core::Params;
use pam_lab::export::model_file::ModelFile;
use pam_lab::synth::{generate, Protocol};

const HEADER: &str = "t_s,load_n,pressure_mpa,contraction";

/// A good two-load record as CSV rows (without the header).
fn good_rows() -> Vec<String> {
    rows_at(&[100.0, 300.0])
}

/// A good record at `loads` as CSV rows.
fn rows_at(loads: &[f64]) -> Vec<String> {
    let rec = generate(&Params::DEFAULT, &Protocol::quick(loads), 0.001, 0.0008, 5);
    rec.samples
        .iter()
        .map(|s| {
            format!(
                "{:.3},{},{:.5},{:.5}",
                s.t_s, s.load_n, s.pressure_mpa, s.contraction
            )
        })
        .collect()
}

fn good_csv() -> String {
    format!("{HEADER}\n{}\n", good_rows().join("\n"))
}

/// The rows of the good record with `f` applied to each `(index, fields)`.
fn edited(f: impl Fn(usize, &mut Vec<String>)) -> String {
    let mut out = format!("{HEADER}\n");
    for (i, row) in good_rows().iter().enumerate() {
        let mut fields: Vec<String> = row.split(',').map(str::to_string).collect();
        f(i, &mut fields);
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// Every file and directory below `dir`, with its contents.
fn snapshot(dir: &Path) -> BTreeMap<String, Option<Vec<u8>>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let key = p.strip_prefix(dir).unwrap().display().to_string();
            if p.is_dir() {
                out.insert(key, None);
                stack.push(p);
            } else if p.metadata().unwrap().len() < (1 << 20) {
                out.insert(key, Some(std::fs::read(&p).unwrap()));
            } else {
                let len = p.metadata().unwrap().len();
                out.insert(key, Some(len.to_le_bytes().to_vec()));
            }
        }
    }
    out
}

/// Set up the directory with `files`, run `pam-lab args`, and check the
/// refusal: exit code 1, one error line containing every `want`, nothing
/// written.
fn refused(files: &[(&str, Vec<u8>)], args: &[&str], want: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in files {
        let p = dir.path().join(name);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        if name.ends_with('/') {
            std::fs::create_dir_all(&p).unwrap();
        } else {
            std::fs::write(&p, bytes).unwrap();
        }
    }
    let before = snapshot(dir.path());
    let out = Command::new(env!("CARGO_BIN_EXE_pam-lab"))
        .args(args)
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert_eq!(
        out.status.code(),
        Some(1),
        "{args:?}: exit code\nstdout: {stdout}\nstderr: {stderr}"
    );
    for w in want {
        assert!(stderr.contains(w), "{args:?}: want `{w}` in:\n{stderr}");
        assert_eq!(
            stderr.matches(w).count(),
            1,
            "{args:?}: `{w}` said more than once:\n{stderr}"
        );
    }
    assert!(
        !stderr.contains("panicked"),
        "{args:?}: a panic, not a refusal:\n{stderr}"
    );
    // (Progress lines, on a redirected stderr, may come before it.)
    if stderr.lines().any(|l| l.starts_with("error: ")) {
        assert_eq!(
            stderr.matches("error:").count(),
            1,
            "{args:?}: the error is printed once:\n{stderr}"
        );
    }
    assert!(stdout.is_empty(), "{args:?}: nothing on stdout: {stdout}");
    assert_eq!(
        snapshot(dir.path()).keys().collect::<Vec<_>>(),
        before.keys().collect::<Vec<_>>(),
        "{args:?}: files written or removed"
    );
    assert!(
        snapshot(dir.path()) == before,
        "{args:?}: a file was changed"
    );
}

fn csv(text: impl Into<String>) -> Vec<u8> {
    text.into().into_bytes()
}

fn model_json() -> Vec<u8> {
    csv(ModelFile::new(Params::DEFAULT, None).to_json())
}

const FIT: [&str; 4] = ["fit", "bad.csv", "-o", "out"];

fn fit_refuses(data: Vec<u8>, want: &[&str]) {
    refused(&[("bad.csv", data)], &FIT, want);
}

fn simulate_refuses(data: Vec<u8>, want: &[&str]) {
    refused(
        &[("bad.csv", data), ("model.json", model_json())],
        &["simulate", "model.json", "bad.csv", "-o", "sim.csv"],
        want,
    );
}

fn diagnose_refuses(data: Vec<u8>, want: &[&str]) {
    refused(
        &[("bad.csv", data)],
        &["diagnose", "bad.csv", "-o", "diag"],
        want,
    );
}

// ---- reading: the file itself ----

#[test]
fn fit_missing_file() {
    refused(&[], &FIT, &["error: bad.csv: cannot read: No such file"]);
}

#[test]
fn fit_input_is_a_directory() {
    refused(
        &[("bad.csv/", vec![])],
        &FIT,
        &["error: bad.csv: cannot read: is a directory"],
    );
}

#[test]
fn fit_empty_file() {
    fit_refuses(vec![], &["error: bad.csv: no header line (expected `t_s,"]);
}

#[test]
fn fit_header_only() {
    fit_refuses(
        csv(format!("# rig 3\n{HEADER}\n# no data\n")),
        &["error: bad.csv: no samples after the header"],
    );
}

#[test]
fn fit_random_bytes() {
    // Bytes no text file has (a fixed pseudo-random sequence with a NUL).
    let mut x: u32 = 12345;
    let bytes: Vec<u8> = (0..3000)
        .map(|_| {
            x = x.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (x >> 16) as u8
        })
        .chain([0u8])
        .collect();
    fit_refuses(
        bytes,
        &["error: bad.csv: not a text file (a NUL byte or invalid UTF-8 at byte"],
    );
}

#[cfg(unix)]
#[test]
fn fit_dev_zero_is_refused_not_read_forever() {
    let start = std::time::Instant::now();
    refused(
        &[],
        &["fit", "/dev/zero", "-o", "out"],
        &["error: /dev/zero: not a text file (a NUL byte or invalid UTF-8 at byte 0)"],
    );
    assert!(start.elapsed().as_secs() < 20);
}

#[test]
fn fit_file_larger_than_64_mib() {
    let line = format!("# {}\n", "x".repeat(1021));
    let mut text = format!("{HEADER}\n");
    while text.len() <= (64 << 20) {
        text.push_str(&line);
    }
    fit_refuses(csv(text), &["error: bad.csv: larger than 64 MiB"]);
}

#[test]
fn fit_more_than_a_million_rows() {
    let mut text = String::with_capacity(17_000_000);
    text.push_str(HEADER);
    text.push('\n');
    for i in 0..1_000_001u64 {
        text.push_str(&format!("{i},100,0.1,0.05\n"));
    }
    fit_refuses(
        csv(text),
        &["error: bad.csv:1000002: more than 1000000 samples"],
    );
}

// ---- reading: the header ----

#[test]
fn fit_semicolon_separated() {
    fit_refuses(
        csv(good_csv().replace(',', ";")),
        &["error: bad.csv:1: the header is separated by `;`, not by commas"],
    );
}

#[test]
fn fit_tab_separated() {
    fit_refuses(
        csv(good_csv().replace(',', "\t")),
        &["error: bad.csv:1: the header is separated by `\\t`, not by commas"],
    );
}

#[test]
fn fit_missing_column() {
    fit_refuses(
        csv("# rig\nt_s,load_n,contraction\n0,100,0.02\n"),
        &["error: bad.csv:2: column `pressure_mpa`: missing from the header"],
    );
}

#[test]
fn fit_duplicate_column() {
    fit_refuses(
        csv("t_s,load_n,pressure_mpa,contraction,t_s\n0,100,0.1,0.02,0\n"),
        &["error: bad.csv:1: column `t_s`: named twice in the header"],
    );
}

#[test]
fn fit_no_header_line() {
    let rows = good_rows().join("\n");
    fit_refuses(
        csv(rows),
        &["error: bad.csv:1: the first line holds numbers, not column names"],
    );
}

#[test]
fn fit_pressure_in_kpa_by_header() {
    fit_refuses(
        csv(good_csv().replacen("pressure_mpa", "pressure_kpa", 1)),
        &["error: bad.csv:1: column `pressure_mpa`: header names `pressure_kpa`: pressure must be in MPa (`pressure_mpa`): divide by 1000"],
    );
}

#[test]
fn fit_contraction_in_percent_by_header() {
    fit_refuses(
        csv(good_csv().replacen("contraction", "contraction_pct", 1)),
        &["error: bad.csv:1: column `contraction`: header names `contraction_pct`: contraction must be a fraction of rest length: divide by 100"],
    );
}

#[test]
fn fit_time_in_milliseconds_by_header() {
    fit_refuses(
        csv(good_csv().replacen("t_s", "t_ms", 1)),
        &["error: bad.csv:1: column `t_s`: header names `t_ms`: time must be in seconds"],
    );
}

// ---- reading: values ----

#[test]
fn fit_pressure_in_kpa_by_value() {
    let text = edited(|_, f| {
        let p: f64 = f[2].parse().unwrap();
        f[2] = format!("{:.2}", p * 1000.0);
    });
    // The first row above 10 "MPa" is named; its line depends on the ramp.
    let dir_line = text
        .lines()
        .enumerate()
        .skip(1)
        .find(|(_, l)| l.split(',').nth(2).unwrap().parse::<f64>().unwrap() > 10.0)
        .map(|(i, _)| i + 1)
        .unwrap();
    fit_refuses(
        csv(text),
        &[
            &format!("error: bad.csv:{dir_line}: column `pressure_mpa`: value"),
            "this looks like kPa (divide by 1000)",
        ],
    );
}

#[test]
fn fit_contraction_in_percent_by_value() {
    let text = edited(|i, f| {
        if i == 6 {
            f[3] = "12.5".into();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:8: column `contraction`: value 12.5 is out of range: contraction is a fraction of rest length; this looks like per cent (divide by 100)"],
    );
}

#[test]
fn fit_not_a_number() {
    let text = edited(|i, f| {
        if i == 3 {
            f[2] = "0.1x".into();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:5: column `pressure_mpa`: `0.1x` is not a number"],
    );
}

#[test]
fn fit_nan_value() {
    let text = edited(|i, f| {
        if i == 9 {
            f[3] = "NaN".into();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:11: column `contraction`: value is NaN or infinite"],
    );
}

#[test]
fn fit_infinite_value() {
    let text = edited(|i, f| {
        if i == 2 {
            f[1] = "inf".into();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:4: column `load_n`: value is NaN or infinite"],
    );
}

#[test]
fn fit_empty_field() {
    let text = edited(|i, f| {
        if i == 4 {
            f[0] = String::new();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:6: column `t_s`: row has no value for this column"],
    );
}

#[test]
fn fit_short_row() {
    let text = edited(|i, f| {
        if i == 7 {
            f.truncate(3);
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:9: column `contraction`: row has no value for this column"],
    );
}

#[test]
fn fit_decimal_commas() {
    let text = edited(|i, f| {
        if i == 1 {
            f[2] = f[2].replace('.', ",");
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:3: row has 5 fields, the header 4 (a decimal comma"],
    );
}

#[test]
fn fit_time_backwards() {
    let text = format!("{HEADER}\n# c\n1,100,0.1,0.02\n0.9,100,0.1,0.02\n");
    fit_refuses(
        csv(text),
        &["error: bad.csv:4: column `t_s`: time goes backwards (0.9 s after 1 s on the previous sample)"],
    );
}

#[test]
fn fit_every_time_stamp_zero() {
    let text = edited(|_, f| f[0] = "0".into());
    fit_refuses(
        csv(text),
        &["error: bad.csv: column `t_s`: every time stamp is the same"],
    );
}

#[test]
fn fit_negative_load() {
    let text = edited(|i, f| {
        if i == 0 {
            f[1] = "-5".into();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:2: column `load_n`: physically impossible value -5 (a muscle only pulls"],
    );
}

#[test]
fn fit_huge_load_is_printed_short() {
    let text = edited(|i, f| {
        if i == 0 {
            f[1] = "1e30".into();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:2: column `load_n`: physically impossible value 1e30 ("],
    );
}

#[test]
fn fit_pressure_below_vacuum() {
    let text = edited(|i, f| {
        if i == 5 {
            f[2] = "-0.5".into();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:7: column `pressure_mpa`: physically impossible value -0.5 (gauge pressure between vacuum"],
    );
}

#[test]
fn fit_contraction_beyond_one() {
    let text = edited(|i, f| {
        if i == 0 {
            f[3] = "-1.5".into();
        }
    });
    fit_refuses(
        csv(text),
        &["error: bad.csv:2: column `contraction`: physically impossible value -1.5"],
    );
}

// ---- the record as a whole ----

#[test]
fn fit_constant_pressure() {
    let text = edited(|_, f| f[2] = "0.2".into());
    fit_refuses(
        csv(text),
        &["error: bad.csv: column `pressure_mpa`: holds 0.2 on every sample"],
    );
}

#[test]
fn fit_constant_contraction() {
    let text = edited(|_, f| f[3] = "0.05".into());
    fit_refuses(
        csv(text),
        &["error: bad.csv: column `contraction`: holds 0.05 on every sample"],
    );
}

#[test]
fn fit_contraction_stuck_for_half_the_record() {
    let n = good_rows().len();
    let text = edited(|i, f| {
        if i >= n / 2 {
            f[3] = "0.1".into();
        }
    });
    fit_refuses(
        csv(text),
        &[
            &format!(
                "error: bad.csv:{}: column `contraction`: stuck at 0.1 up to line {}",
                n / 2 + 2,
                n + 1
            ),
            "MPa of pressure moved: a sensor fault",
        ],
    );
}

#[test]
fn fit_pressure_sensor_stuck() {
    let n = good_rows().len();
    let text = edited(|i, f| {
        if (n / 4..n / 2).contains(&i) {
            f[2] = "0.3".into();
        }
    });
    fit_refuses(
        csv(text),
        &[
            &format!(
                "error: bad.csv:{}: column `pressure_mpa`: stuck at 0.3",
                n / 4 + 2
            ),
            "of contraction moved",
        ],
    );
}

#[test]
fn fit_one_load_only() {
    let text = edited(|_, f| f[1] = "100".into());
    fit_refuses(
        csv(text),
        &["error: bad.csv: column `load_n`: too few samples to identify the model: the load factors need two loads", "first training line 2"],
    );
}

// ---- fit's options ----

fn fit_option_refused(extra: &[&str], want: &str) {
    let mut args = FIT.to_vec();
    args.extend_from_slice(extra);
    refused(&[("bad.csv", csv(good_csv()))], &args, &[want]);
}

#[test]
fn fit_negative_deadband() {
    fit_option_refused(
        &["--deadband", "-1"],
        "error: invalid setting `--deadband`: must be a finite pressure >= 0 MPa",
    );
}

#[test]
fn fit_negative_load_bin() {
    fit_option_refused(
        &["--load-bin", "-5"],
        "error: invalid setting `--load-bin`: must be a finite number of newtons",
    );
}

#[test]
fn fit_pmax_out_of_range() {
    fit_option_refused(
        &["--pmax", "1e30"],
        "error: invalid setting `--pmax`: must be a number in (0, 10] MPa",
    );
}

#[test]
fn fit_zero_load_step() {
    fit_option_refused(
        &["--load-step", "0"],
        "error: invalid setting `--load-step`",
    );
}

#[test]
fn fit_holdout_every_one() {
    fit_option_refused(
        &["--holdout", "every:1"],
        "invalid value 'every:1' for '--holdout <HOLDOUT>': holdout `every:1`: expected `none`, `every:K` (K >= 2)",
    );
}

#[test]
fn fit_holdout_tail_beyond_one() {
    fit_option_refused(
        &["--holdout", "tail:1.5"],
        "invalid value 'tail:1.5' for '--holdout <HOLDOUT>'",
    );
}

#[test]
fn fit_zero_min_samples() {
    fit_option_refused(
        &["--min-samples", "0"],
        "error: invalid setting `--min-samples`: must be at least 1",
    );
}

#[test]
fn fit_unknown_test_kind() {
    fit_option_refused(
        &["--test", "sideways"],
        "invalid value 'sideways' for '--test",
    );
}

#[test]
fn fit_not_a_number_option() {
    fit_option_refused(&["--pmax", "abc"], "invalid value 'abc' for '--pmax");
}

#[test]
fn fit_unknown_option() {
    fit_option_refused(&["--out-dir", "x"], "unexpected argument '--out-dir'");
}

// ---- fit's outputs ----

#[test]
fn fit_output_directory_is_a_file() {
    refused(
        &[("bad.csv", csv(good_csv())), ("out", csv("a file"))],
        &FIT,
        &["error: out: cannot write into it: not a directory"],
    );
}

#[test]
fn fit_output_directory_below_a_file() {
    refused(
        &[("bad.csv", csv(good_csv())), ("f", csv("a file"))],
        &["fit", "bad.csv", "-o", "f/out"],
        &["error: f: cannot create the output directory below it: not a directory"],
    );
}

#[test]
fn fit_plot_blocked_by_a_directory_writes_no_model() {
    refused(
        &[
            ("bad.csv", csv(good_csv())),
            ("out/fit.png/", vec![]),
            ("out/model.json", csv("previous model")),
        ],
        &FIT,
        &["error: out/fit.png: cannot write: is a directory"],
    );
}

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

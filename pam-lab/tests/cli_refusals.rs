//! Every kind of bad input to `fit` and to the record reader every command
//! shares, one test each: the command exits with code 1, prints one
//! `error:` line that locates the defect (file, line and column where there
//! is one) and gives its reason, and leaves the directory exactly as it was
//! (no output file, no output directory, no staging leftovers; a previous
//! output untouched). `cli_refusals_commands.rs` has `simulate`'s and
//! `diagnose`'s.
//!
//! Every command runs in a fresh temporary directory with relative paths,
//! so the messages are compared as a user sees them.

#[path = "support/refusals.rs"]
mod refusals;

use refusals::*;

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

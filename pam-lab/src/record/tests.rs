//! Tests of the reader and the checks.

use std::path::Path;

use super::*;

fn parse(text: &str) -> Result<Record, DataError> {
    parse_csv("test.csv", text.as_bytes())
}

#[test]
fn reads_columns_in_any_order_with_extras_and_comments() {
    let r = parse(
        "# rig 7\nextra,contraction,t_s,pressure_mpa,load_n\n\
         a,0.02,0.0,0.001,100\n# pause\n\nb,0.03,0.02,0.01,100.5\n",
    )
    .unwrap();
    assert_eq!(r.len(), 2);
    assert_eq!(
        r.samples[1],
        Sample {
            t_s: 0.02,
            load_n: 100.5,
            pressure_mpa: 0.01,
            contraction: 0.03
        }
    );
    assert_eq!(r.lines, vec![3, 6]);
}

#[test]
fn segment_comments_mark_where_the_records_parts_begin() {
    let r = parse(
        "# segment: a.csv (new file)\nt_s,load_n,pressure_mpa,contraction\n\
         0,100,0.1,0.01\n0.1,100,0.2,0.02\n# segment: b.csv:9: the clock restarts, 0.1 s after 7 s\n\
         0.2,100,0.3,0.03\n# a note, not a seam\n0.3,100,0.4,0.04\n",
    )
    .unwrap();
    assert_eq!(
        r.segments,
        vec![
            Segment {
                start: 0,
                label: "a.csv (new file)".into()
            },
            Segment {
                start: 2,
                label: "b.csv:9: the clock restarts, 0.1 s after 7 s".into()
            },
        ]
    );
    let ranges: Vec<_> = r.segment_ranges();
    assert_eq!(
        ranges,
        vec![
            ("a.csv (new file)", 0..2),
            ("b.csv:9: the clock restarts, 0.1 s after 7 s", 2..4)
        ]
    );
    // A subset keeps each part that keeps a sample, from its first kept one.
    let odd = r.subset("odd".into(), |i| i % 2 == 1);
    assert_eq!(odd.lines, vec![4, 8]);
    assert_eq!(
        odd.segment_ranges()
            .iter()
            .map(|(_, range)| range.clone())
            .collect::<Vec<_>>(),
        vec![0..1, 1..2]
    );
    let tail = r.subset("tail".into(), |i| i == 3);
    assert_eq!(tail.segments.len(), 1);
    assert_eq!(
        tail.segments[0].label,
        "b.csv:9: the clock restarts, 0.1 s after 7 s"
    );
    // Samples before the first seam are a part of their own.
    let late = parse(
        "t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.01\n# segment: b\n0.1,100,0.2,0.02\n",
    )
    .unwrap();
    assert_eq!(late.segment_ranges(), vec![("(start)", 0..1), ("b", 1..2)]);
    assert!(
        parse("t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.01\n")
            .unwrap()
            .segment_ranges()
            .is_empty()
    );
}

#[test]
fn missing_column_names_the_column_and_the_header_line() {
    let e = parse("t_s,load_n,contraction\n0,100,0.02\n").unwrap_err();
    assert_eq!(e.kind, DataErrorKind::MissingColumn);
    assert_eq!(e.column.as_deref(), Some("pressure_mpa"));
    assert_eq!(e.line, 1);
    assert_eq!(
        e.to_string(),
        "test.csv:1: column `pressure_mpa`: missing from the header (need `t_s,load_n,pressure_mpa,contraction`)"
    );
}

#[test]
fn non_numeric_field_is_located() {
    let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.02\n0.02,100,0.1x,0.02\n")
        .unwrap_err();
    assert_eq!(e.line, 3);
    assert_eq!(e.column.as_deref(), Some("pressure_mpa"));
    assert_eq!(e.kind, DataErrorKind::NotANumber("0.1x".into()));
}

#[test]
fn nan_and_infinity_are_refused() {
    for bad in ["NaN", "inf", "-inf"] {
        let e = parse(&format!(
            "t_s,load_n,pressure_mpa,contraction\n0,100,0.1,{bad}\n"
        ))
        .unwrap_err();
        assert_eq!(e.kind, DataErrorKind::NonFinite, "{bad}");
        assert_eq!((e.line, e.column.as_deref()), (2, Some("contraction")));
    }
}

#[test]
fn short_row_is_a_missing_field() {
    let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,0.1\n").unwrap_err();
    assert_eq!(e.kind, DataErrorKind::MissingField);
    assert_eq!(e.column.as_deref(), Some("contraction"));
}

#[test]
fn time_going_backwards_is_refused_but_repeats_are_not() {
    let ok = "t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.02\n0,100,0.1,0.02\n";
    assert!(parse(ok).is_ok());
    let e = parse("t_s,load_n,pressure_mpa,contraction\n1,100,0.1,0.02\n0.5,100,0.1,0.02\n")
        .unwrap_err();
    assert_eq!((e.line, e.column.as_deref()), (3, Some("t_s")));
    assert!(matches!(e.kind, DataErrorKind::TimeBackwards { .. }));
}

#[test]
fn impossible_values_are_refused() {
    for (row, col) in [
        ("0,-5,0.1,0.02", "load_n"),
        ("0,100,-0.5,0.02", "pressure_mpa"),
        ("0,100,20000,0.02", "pressure_mpa"),
        ("0,100,0.1,120", "contraction"),
    ] {
        let e = parse(&format!("t_s,load_n,pressure_mpa,contraction\n{row}\n")).unwrap_err();
        assert_eq!(e.column.as_deref(), Some(col), "{row}");
        assert!(matches!(e.kind, DataErrorKind::Impossible { .. }));
    }
}

#[test]
fn empty_inputs_are_refused() {
    assert_eq!(parse("").unwrap_err().kind, DataErrorKind::NoHeader);
    assert_eq!(
        parse("t_s,load_n,pressure_mpa,contraction\n# nothing\n")
            .unwrap_err()
            .kind,
        DataErrorKind::NoSamples
    );
}

#[test]
fn unreadable_file_is_named() {
    let e = read_csv(Path::new("/nonexistent/x.csv")).unwrap_err();
    assert!(e.to_string().starts_with("/nonexistent/x.csv: cannot read"));
}

#[test]
fn lines_are_counted_as_an_editor_counts_them() {
    let text = "# a\r\n\r\nt_s,load_n,pressure_mpa,contraction\r\n\r\n\n# b\n1,100,0.1,0.02\n\n\n2,100,0.1,0.02\r\n";
    assert_eq!(parse(text).unwrap().lines, vec![7, 10]);
    let e = parse("\n\n# x\n\nt_s,load_n,pressure_mpa\n").unwrap_err();
    assert_eq!(e.line, 5);
}

#[test]
fn a_byte_order_mark_is_skipped() {
    let r = parse("\u{feff}t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.02\n").unwrap();
    assert_eq!(r.len(), 1);
    assert_eq!(r.lines, vec![2]);
}

#[test]
fn separators_other_than_commas_are_named() {
    for (sep, shown) in [(";", "`;`"), ("\t", "`\\t`"), ("|", "`|`")] {
        let text = format!(
            "t_s{sep}load_n{sep}pressure_mpa{sep}contraction\n0{sep}100{sep}0.1{sep}0.02\n"
        );
        let e = parse(&text).unwrap_err();
        assert_eq!(
            e.kind,
            DataErrorKind::WrongSeparator(sep.chars().next().unwrap())
        );
        assert!(e.to_string().contains(shown), "{e}");
    }
}

#[test]
fn binary_input_is_refused_at_its_first_bad_byte() {
    let e = parse_csv("x.bin", &b"t_s,load\x00_n"[..]).unwrap_err();
    assert_eq!(e.kind, DataErrorKind::Binary { offset: 8 });
    let e = parse_csv("x.bin", &b"\xff\xfe\x00t"[..]).unwrap_err();
    assert_eq!(e.kind, DataErrorKind::Binary { offset: 0 });
}

#[test]
fn an_endless_input_stops_at_the_byte_limit() {
    // A header, then one comment line that never ends.
    let endless = std::io::Read::chain(
        &b"t_s,load_n,pressure_mpa,contraction\n#"[..],
        std::io::repeat(b'x'),
    );
    let e = parse_csv("endless", endless).unwrap_err();
    assert_eq!(e.kind, DataErrorKind::TooLarge);
}

#[test]
fn units_are_recognised_in_the_header_and_in_values() {
    let e = parse("t_s,load_n,pressure_bar,contraction\n0,100,1,0.02\n").unwrap_err();
    assert!(matches!(e.kind, DataErrorKind::WrongUnit { .. }), "{e}");
    assert_eq!(e.column.as_deref(), Some("pressure_mpa"));
    let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,250,0.02\n").unwrap_err();
    assert!(e.to_string().contains("looks like kPa"), "{e}");
    assert!(!e.to_string().contains("psi"), "{e}");
    // 87 may be psi (a McKibben muscle's 0.6 MPa) or kPa: both are named.
    let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,87,0.02\n").unwrap_err();
    assert!(
        e.to_string()
            .contains("kPa (divide by 1000) or psi (multiply by 0.006895)"),
        "{e}"
    );
    let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,0.1,15\n").unwrap_err();
    assert!(e.to_string().contains("looks like per cent"), "{e}");
    // Beyond any unit: plain impossible.
    let e = parse("t_s,load_n,pressure_mpa,contraction\n0,100,20000,0.02\n").unwrap_err();
    assert!(matches!(e.kind, DataErrorKind::Impossible { .. }), "{e}");
}

#[test]
fn numbers_are_printed_short() {
    assert_eq!(num(1e30), "1e30");
    assert_eq!(num(-2.5e-7), "-2.5e-7");
    assert_eq!(num(0.25), "0.25");
    assert_eq!(num(0.0), "0");
    assert_eq!(num32(0.498_863_34), "0.49886334");
}

fn record(f: impl Fn(usize) -> Sample, n: usize) -> Record {
    Record::from_samples("r.csv", (0..n).map(f).collect())
}

fn ramp(i: usize) -> Sample {
    let u = (i % 200) as f64 / 200.0;
    Sample {
        t_s: i as f64 * 0.02,
        load_n: 100.0,
        pressure_mpa: 0.5 * u,
        contraction: 0.02 + 0.2 * u,
    }
}

#[test]
fn record_checks_find_time_constant_and_stuck_channels() {
    assert!(check_record(&record(ramp, 3000), Purpose::Fit).is_ok());
    let e = check_record(
        &record(
            |i| Sample {
                t_s: 0.0,
                ..ramp(i)
            },
            3000,
        ),
        Purpose::Simulate,
    )
    .unwrap_err();
    assert_eq!(e.kind, DataErrorKind::TimeNeverAdvances);
    let e = check_record(
        &record(
            |i| Sample {
                contraction: 0.1,
                ..ramp(i)
            },
            3000,
        ),
        Purpose::Fit,
    )
    .unwrap_err();
    assert_eq!(e.kind, DataErrorKind::Constant { value: 0.1 });
    // Simulate needs no varying contraction, but a stuck sensor is one.
    let e = check_record(
        &record(
            |i| Sample {
                contraction: 0.1,
                ..ramp(i)
            },
            3000,
        ),
        Purpose::Simulate,
    )
    .unwrap_err();
    assert!(matches!(e.kind, DataErrorKind::Stuck { .. }), "{e}");
    let stuck = record(
        |i| {
            let mut s = ramp(i);
            if (1000..2000).contains(&i) {
                s.contraction = 0.07;
            }
            s
        },
        3000,
    );
    let e = check_record(&stuck, Purpose::Fit).unwrap_err();
    assert_eq!((e.line, e.column.as_deref()), (1002, Some("contraction")));
    assert!(
        matches!(
            e.kind,
            DataErrorKind::Stuck {
                samples: 1000,
                until_line: 2001,
                ..
            }
        ),
        "{e}"
    );
    // A hold (nothing moves) is no fault.
    let hold = record(
        |i| {
            if (1000..2000).contains(&i) {
                Sample {
                    t_s: i as f64 * 0.02,
                    ..ramp(999)
                }
            } else {
                ramp(i)
            }
        },
        3000,
    );
    assert!(check_record(&hold, Purpose::Fit).is_ok());
    let e = check_record(&record(ramp, 60), Purpose::Diagnose).unwrap_err();
    assert!(matches!(e.kind, DataErrorKind::TooFewSamples(_)));
}

#[test]
fn a_held_length_is_the_protocol_not_a_stuck_sensor() {
    // Held at exact lengths throughout (an imported isometric test):
    // the protocol, whatever the load does.
    let held = record(
        |i| Sample {
            contraction: if i < 1500 { 0.0 } else { 0.04 },
            ..ramp(i)
        },
        3000,
    );
    assert!(check_record(&held, Purpose::Fit).is_ok());
    // One stretch held while the force follows the pressure: a hold.
    let answered = |load: fn(&Sample) -> f64| {
        record(
            move |i| {
                let mut s = ramp(i);
                if (1000..2000).contains(&i) {
                    s.contraction = 0.07;
                    s.load_n = load(&s);
                }
                s
            },
            3000,
        )
    };
    let force = answered(|s| 50.0 + 400.0 * s.pressure_mpa);
    assert!(check_record(&force, Purpose::Fit).is_ok());
    // A hung load that does not answer: a stuck sensor.
    let hung = answered(|s| s.load_n);
    let e = check_record(&hung, Purpose::Fit).unwrap_err();
    assert!(matches!(e.kind, DataErrorKind::Stuck { .. }), "{e}");
}

/// A triangle of pressure between 0 and 0.5 MPa at `rate_mpa_per_s`,
/// sampled every `dt_s`, held for `hold_s` at each end, with a
/// deterministic ±1 kPa of sensor noise; times written as `time_scale`
/// times seconds.
fn triangle(rate_mpa_per_s: f64, dt_s: f64, hold_s: f64, n: usize, time_scale: f64) -> Record {
    let ramp_s = 0.5 / rate_mpa_per_s;
    let period = 2.0 * (ramp_s + hold_s);
    record(
        |i| {
            let t = i as f64 * dt_s;
            let u = t % period;
            let p = if u < ramp_s {
                u * rate_mpa_per_s
            } else if u < ramp_s + hold_s {
                0.5
            } else if u < 2.0 * ramp_s + hold_s {
                0.5 - (u - ramp_s - hold_s) * rate_mpa_per_s
            } else {
                0.0
            };
            let noise = 0.001 * (((i * 7_919) % 1_000) as f64 / 500.0 - 1.0);
            Sample {
                t_s: t * time_scale,
                load_n: 100.0,
                pressure_mpa: p + noise,
                contraction: 0.2 * p,
            }
        },
        n,
    )
}

fn warns_of_milliseconds(r: &Record) -> bool {
    unit_warnings(r)
        .iter()
        .any(|w| w.contains("divide it by 1000"))
}

#[test]
fn time_in_milliseconds_is_told_by_its_slow_pressure_also_on_a_short_record() {
    // 10 s at 1 kHz and 20 s at 100 Hz, ramps of 0.25 MPa/s, logged in ms:
    // under 3 "hours", so only the rate tells.
    assert!(warns_of_milliseconds(&triangle(
        0.25, 0.001, 0.5, 10_000, 1000.0
    )));
    assert!(warns_of_milliseconds(&triangle(
        0.25, 0.01, 0.5, 2_000, 1000.0
    )));
    // The same in seconds.
    assert!(!warns_of_milliseconds(&triangle(
        0.25, 0.001, 0.5, 10_000, 1.0
    )));
    // A true slow test: 1 Hz, 5 kPa/s ramps with 60 s holds, 3 hours.
    assert!(!warns_of_milliseconds(&triangle(
        0.005,
        1.0,
        60.0,
        3 * 3_600,
        1.0
    )));
    // A creep test: 2 h at 1 Hz, one 0.3 MPa step in a second, held; noise.
    let creep = record(
        |i| Sample {
            t_s: i as f64,
            load_n: 100.0,
            pressure_mpa: if i < 600 { 0.1 } else { 0.4 }
                + 0.001 * (((i * 7_919) % 1_000) as f64 / 500.0 - 1.0),
            contraction: 0.1,
        },
        7_200,
    );
    assert!(!warns_of_milliseconds(&creep));
    // A record of hours at a second a sample is still told by its length.
    assert!(warns_of_milliseconds(&triangle(
        0.25,
        1.0,
        0.0,
        6 * 3_600,
        1.0
    )));
}

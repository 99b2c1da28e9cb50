//! A logger's isometric test, as the public Festo records are published
//! (no header; force in N with its offset, pressure in kPa, time in s, a
//! phase column; one file per held length and test; a logger clock that
//! restarts inside a file), generated from a physical muscle (the
//! Chou–Hannaford static law, a threshold pressure and braid friction: not
//! pam-core's equations), through `pam-lab import` and `pam-lab fit
//! --validate`.

use std::path::Path;

#[path = "support/cli.rs"]
mod cli_support;
use cli_support::pam_lab;
use pam_lab::synth::chou_hannaford_force_n;

/// The pressure sensor's view of the muscle: `None`, the muscle's own
/// pressure; or a sensor at the valve, ahead of the muscle by a line of
/// time constant `lag_s`, where the valve's pulses ring; or a force
/// answering the sensor's pressure `delay_s` later (a load cell's filter,
/// a logger sampling its channels apart). `cycles`: fill-hold-vent cycles
/// per file (1: one over the file; more, each that much faster).
#[derive(Clone, Copy)]
struct Sensor {
    lag_s: Option<f64>,
    delay_s: Option<f64>,
    cycles: f64,
}

/// The muscle's own pressure read at once, one cycle a file.
const AT_ONCE: Sensor = Sensor {
    lag_s: None,
    delay_s: None,
    cycles: 1.0,
};

/// One test at one held length: fill to 0.62 MPa, hold, vent to a floor;
/// 1.8 ms samples. `reset_at`: the logger's clock restarts at that sample.
/// With a sensor ahead of the muscle, the valve fills and vents in pulses
/// that swing the sensor's pressure by ±30 kPa at 8 Hz, and the muscle's
/// pressure is the sensor's through a first-order lag (the line and the
/// bladder's volume).
fn write_test(path: &Path, eps: f64, seed: u64, reset_at: Option<usize>, sensor: Sensor) {
    let mut rng = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut noise = || {
        rng = rng
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((rng >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let mut text = String::new();
    let n = 8000;
    let mut t_clock = 0.0;
    let mut muscle: Option<f64> = None;
    let period = n as f64 * 0.0018;
    let profile = |t: f64| {
        let t = if t > 0.0 {
            (t * sensor.cycles).rem_euclid(period)
        } else {
            0.0
        };
        if t < 7.0 {
            (0.62 * (t.max(0.0) / 7.0), true)
        } else if t < 9.0 {
            (0.62, true)
        } else {
            (0.07 + 0.55 * (-(t - 9.0) / 1.2).exp(), false)
        }
    };
    for i in 0..n {
        let t = i as f64 * 0.0018;
        let (mut p, filling) = profile(t);
        let p_muscle = match sensor.lag_s {
            None => sensor.delay_s.map_or(p, |d| profile(t - d).0),
            Some(tau) => {
                if !(7.0..9.0).contains(&t) {
                    p += 0.03 * (2.0 * std::f64::consts::PI * 8.0 * t).sin();
                }
                let k = 1.0 - (-0.0018 / tau).exp();
                let m = muscle.map_or(p, |m| m + k * (p - m));
                muscle = Some(m);
                m
            }
        };
        let f = chou_hannaford_force_n(p_muscle, eps, filling);
        // The load cell reads −4.6 N at no force, ±0.7 N of noise; the
        // pressure sensor is quantised to 0.766 kPa.
        let force = f - 4.6 + 1.4 * noise();
        let kpa = ((p * 1000.0 + 0.8 * noise()) / 0.766).round() * 0.766;
        if Some(i) == reset_at {
            t_clock = 0.0;
        }
        text.push_str(&format!(
            "{force:.4},{kpa:.3},{t_clock:.4},{}\n",
            if filling { 1 } else { 2 }
        ));
        t_clock += 0.0018;
    }
    std::fs::write(path, text).unwrap();
}

const HELD_CM: [f64; 4] = [8.3, 7.975, 7.65, 7.325];

/// The generated logger files of four held lengths, tests 8 and 9 (train)
/// and 10 (test), imported through a mapping into `dir/records`: the
/// records' directory and import's stdout and stderr.
fn imported(dir: &Path) -> (std::path::PathBuf, bool, String, String) {
    imported_with(dir, AT_ONCE)
}

/// [`imported`] with the pressure read by `sensor`.
fn imported_with(dir: &Path, sensor: Sensor) -> (std::path::PathBuf, bool, String, String) {
    let data = dir.join("logger");
    std::fs::create_dir(&data).unwrap();
    let mut map = String::from(
        "header = false\n[columns]\nload = { column = 1, unit = \"N\" }\n\
         pressure = { column = 2, unit = \"kPa\" }\ntime = { column = 3, unit = \"s\" }\n",
    );
    for (name, tests) in [("train", &[8u64, 9][..]), ("test", &[10][..])] {
        map.push_str(&format!(
            "[[record]]\nname = \"{name}\"\nrest_length = 8.3\nfiles = [\n"
        ));
        for (k, held) in HELD_CM.iter().enumerate() {
            for &t in tests {
                let file = format!("m_{k}_Test{t}.csv");
                let eps = (8.3 - held) / 8.3;
                let reset = (k == 1 && t == 9).then_some(4205);
                write_test(&data.join(&file), eps, t * 10 + k as u64, reset, sensor);
                map.push_str(&format!(
                    "  {{ path = \"{file}\", held_length = {held} }},\n"
                ));
            }
        }
        map.push_str("]\n");
    }
    let map_path = dir.join("map.toml");
    std::fs::write(&map_path, map).unwrap();
    let out = dir.join("records");
    let (ok, stdout, stderr) = pam_lab(&[
        "import",
        map_path.to_str().unwrap(),
        "--data-dir",
        data.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    (out, ok, stdout, stderr)
}

#[test]
fn a_logger_isometric_test_is_imported_fitted_and_validated() {
    let dir = tempfile::tempdir().unwrap();
    let (out, ok, stdout, stderr) = imported(dir.path());
    assert!(ok, "{stdout}{stderr}");
    // The reset is a new segment, said with its file and line.
    assert!(
        stderr.contains("m_1_Test9.csv:4206: the logger's clock restarts"),
        "{stderr}"
    );
    assert!(stderr.contains("load readings below 0 N"), "{stderr}");
    assert!(
        stdout.contains("train: 64000 samples, 9 segments"),
        "{stdout}"
    );
    let train = std::fs::read_to_string(out.join("train.csv")).unwrap();
    assert_eq!(train.matches("# segment").count(), 9);
    // Time runs on across files and the reset.
    let times: Vec<f64> = train
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('t'))
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert!(times.windows(2).all(|w| w[1] > w[0]));

    // Held lengths are the protocol, not a stuck sensor; isometric detected.
    let fit_dir = dir.path().join("fit");
    let (ok, stdout, stderr) = pam_lab(&[
        "fit",
        out.join("train.csv").to_str().unwrap(),
        "--validate",
        out.join("test.csv").to_str().unwrap(),
        "--holdout",
        "none",
        "--no-plot",
        "-o",
        fit_dir.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}{stderr}");
    assert!(stdout.contains("test: isometric (detected)"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fit_dir.join("model.json")).unwrap())
            .unwrap();
    let v = &json["fit"]["validation"];
    let model = v["model"]["total"]["pressure_rms_mpa"].as_f64().unwrap();
    let reference = v["reference_rms_mpa"].as_f64().unwrap();
    // The static surface follows this smooth muscle to within its friction
    // (±6 N and 6 % of the force: about ±20 kPa of static loop); the model is
    // reported beside it.
    assert!(reference < 0.03, "{reference}");
    eprintln!("validation pressure RMS: model {model:.4} MPa, reference {reference:.4} MPa");
    assert!(model.is_finite() && model > 0.0, "{model}");
    assert!(stdout.contains("reference surface"), "{stdout}");
    // The errors per test: each part of both records that has samples
    // under load, named by its seam, its samples adding up to the total.
    let test_seams = std::fs::read_to_string(out.join("test.csv"))
        .unwrap()
        .matches("# segment")
        .count();
    let parts = v["segments"].as_array().expect("validation.segments");
    assert!(parts.len() >= 2 && parts.len() <= test_seams, "{parts:?}");
    assert!(parts
        .iter()
        .all(|p| p["label"].as_str().unwrap().contains("_Test10.csv")));
    let in_parts: u64 = parts
        .iter()
        .map(|p| p["stats"]["samples"].as_u64().unwrap())
        .sum();
    assert_eq!(in_parts, v["model"]["total"]["samples"].as_u64().unwrap());
    assert!(
        parts
            .iter()
            .all(|p| p["reference_pressure_rms_mpa"].as_f64().is_some()),
        "{parts:?}"
    );
    let fitted_parts = json["fit"]["segments"].as_array().expect("fit.segments");
    assert!(
        fitted_parts.len() >= 2 && fitted_parts.len() <= 9,
        "{fitted_parts:?}"
    );
    assert!(stdout.contains("per part of the record"), "{stdout}");
    // The Chou–Hannaford curve is outside the cubic family: fit adds the
    // static shape's stroke table (blob version 3), and with it and the
    // hysteresis the model predicts the other test no worse than the
    // static surface; the cubic alone cannot.
    let blob = std::fs::read(fit_dir.join("model.blob")).unwrap();
    assert_eq!(u16::from_le_bytes([blob[4], blob[5]]), 3);
    assert!(model <= reference, "{model} vs {reference}");
    let cubic_dir = dir.path().join("fit-cubic");
    let (ok, stdout, stderr) = pam_lab(&[
        "fit",
        out.join("train.csv").to_str().unwrap(),
        "--validate",
        out.join("test.csv").to_str().unwrap(),
        "--holdout",
        "none",
        "--no-plot",
        "--no-static-shape",
        "-o",
        cubic_dir.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}{stderr}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cubic_dir.join("model.json")).unwrap())
            .unwrap();
    let cubic = json["fit"]["validation"]["model"]["total"]["pressure_rms_mpa"]
        .as_f64()
        .unwrap();
    eprintln!("the cubic alone: {cubic:.4} MPa");
    assert!(cubic > 1.5 * model, "{cubic} vs {model}");

    // simulate judges the same samples: the slack ones are left out.
    let (ok, stdout, stderr) = pam_lab(&[
        "simulate",
        fit_dir.join("model.json").to_str().unwrap(),
        out.join("test.csv").to_str().unwrap(),
        "-o",
        dir.path().join("sim.csv").to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}{stderr}");
    assert!(
        stdout.contains("isometric test, the ") && stdout.contains(" slack ones left out"),
        "{stdout}"
    );

    // fit's count of training samples leaves the slack ones out, as its fit
    // does: no more than simulate's samples under load of the same record.
    let (ok, sim_stdout, stderr) = pam_lab(&[
        "simulate",
        fit_dir.join("model.json").to_str().unwrap(),
        out.join("train.csv").to_str().unwrap(),
        "-o",
        dir.path().join("sim-train.csv").to_str().unwrap(),
    ]);
    assert!(ok, "{sim_stdout}{stderr}");
    let number_after = |text: &str, key: &str| -> usize {
        let at = text
            .find(key)
            .unwrap_or_else(|| panic!("{key:?} in {text}"))
            + key.len();
        text[at..]
            .split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    let under_load = number_after(&sim_stdout, "isometric test, the ");
    let fit_stdout = std::fs::read_to_string(fit_dir.join("model.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&fit_stdout).unwrap();
    let training = json["fit"]["training_samples"].as_u64().unwrap() as usize;
    assert!(
        training > 0 && training <= under_load,
        "{training} training samples, {under_load} under load"
    );
}

/// diagnose on the same records: an isometric record is diagnosed, not
/// refused (its holds are its segments, its slack samples judged on
/// nothing), every candidate says why it was or was not added, and the
/// diagnosed model predicts the other test's pressure, every effect in,
/// better than the paper's model it started from. In release builds only
/// (`.ci/run` runs it): a diagnosis of 64 000 samples takes minutes in a
/// debug build.
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn a_logger_isometric_test_is_diagnosed_and_validated() {
    let dir = tempfile::tempdir().unwrap();
    let (out, ok, stdout, stderr) = imported(dir.path());
    assert!(ok, "{stdout}{stderr}");
    let diag = dir.path().join("diagnose");
    let (ok, stdout, stderr) = pam_lab(&[
        "diagnose",
        out.join("train.csv").to_str().unwrap(),
        "--validate",
        out.join("test.csv").to_str().unwrap(),
        "-o",
        diag.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}{stderr}");
    eprintln!("{stdout}");
    assert!(
        stdout.contains("cycles cut at changes of the held length"),
        "{stdout}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(diag.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["test_kind"], "isometric");
    // Every candidate says why it was or was not added.
    for c in report["rounds"][0]["candidates"].as_array().unwrap() {
        let verdict = c["verdict"].as_str().unwrap();
        assert!(
            verdict.starts_with("earns it") || verdict.starts_with("not earned: "),
            "{verdict}"
        );
    }
    let v = &report["validation"];
    let model = v["model"]["pressure_rms_mpa"].as_f64().unwrap();
    let base = v["base"]["pressure_rms_mpa"].as_f64().unwrap();
    let reference = v["reference_rms_mpa"].as_f64().unwrap();
    eprintln!("validation pressure RMS: base {base:.4}, diagnosed {model:.4}, reference {reference:.4} MPa");
    assert!(model.is_finite() && reference.is_finite());
    assert!(model < base, "{model} vs {base}");
    // The diagnosed model's errors per test of the validation record.
    let parts = v["segments"].as_array().expect("validation.segments");
    assert!(parts.len() >= 2, "{parts:?}");
    assert!(stdout.contains("per part of the record"), "{stdout}");
    // The reference surface beside each part.
    assert!(
        parts.iter().all(|p| p["reference_pressure_rms_mpa"]
            .as_f64()
            .is_some_and(|r| r > 0.0 && r.is_finite())),
        "{parts:?}"
    );
    // This muscle's static curve is outside the cubic family: the shape is
    // named.
    assert_eq!(report["named"], "constraint_shape");
    // The model it writes is the one it validated, and the firmware's
    // decoder takes its blob.
    let blob = std::fs::read(diag.join("model.blob")).unwrap();
    assert!(pam_core::blob::decode_model(&blob).is_ok());
    // Its static model is the one `pam-lab fit` writes with the same
    // options, the stroke ends' shifts included (a check that took a
    // shape with shifts for another variant wrote the diagnosis's own
    // training-part model instead: Festo 40 cm, test 10, 1.50x the
    // reference surface against fit's 1.08x).
    assert!(
        stdout.contains("the model written is the static model `pam-lab fit"),
        "{stdout}"
    );
    let fit_dir = dir.path().join("fit");
    let (ok, fit_stdout, stderr) = pam_lab(&[
        "fit",
        out.join("train.csv").to_str().unwrap(),
        "--no-plot",
        "-o",
        fit_dir.to_str().unwrap(),
    ]);
    assert!(ok, "{fit_stdout}{stderr}");
    let model_json = |d: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("model.json")).unwrap()).unwrap()
    };
    let (fitted, diagnosed) = (model_json(&fit_dir), model_json(&diag));
    assert_eq!(diagnosed["params"], fitted["params"]);
    assert_eq!(diagnosed["effects"]["shape"], fitted["effects"]["shape"]);
    // Its plots, in pressure (residual.png) and pressure against force
    // (loops.png).
    for png in ["residual.png", "loops.png"] {
        assert!(diag.join(png).metadata().unwrap().len() > 10_000, "{png}");
    }
}

/// A sensor ahead of the muscle (a 50 ms line, the valve's pulses
/// swinging the sensor's pressure): diagnose adds the pressure lag and
/// finds its time constant, and the model it writes carries it. Release
/// only, as above.
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn a_sensor_ahead_of_the_muscle_is_diagnosed_as_a_pressure_lag() {
    let (report, blob) = diagnosed_with(Sensor {
        lag_s: Some(0.05),
        ..AT_ONCE
    });
    let added = effects_added(&report);
    assert!(added.iter().any(|e| e == "pressure_lag"), "{added:?}");
    let tau = report["effects"]["pressure_lag"]["time_constant_s"]
        .as_f64()
        .unwrap();
    // Longer than the line's 50 ms (0.21 s measured): the static error
    // this muscle keeps after the shape (18 kPa held-out) trades off with
    // the lag's time constant. Not a time constant of creep either.
    assert!((0.025..=0.5).contains(&tau), "{tau}");
    // The model with the lag predicts the other test's pressure better than
    // the reference surface, which has no lag (0.72× measured; the lead is
    // the model's own, `pam_lab::evaluate::simulate::lag_lead`).
    let v = &report["validation"];
    let model = v["model"]["pressure_rms_mpa"].as_f64().unwrap();
    let reference = v["reference_rms_mpa"].as_f64().unwrap();
    assert!(model < reference, "{model} vs {reference}");
    let (_, effects) = pam_core::blob::decode_model(&blob).unwrap();
    assert!(effects.pressure_lag.is_some());
}

/// A force that answers the sensor's pressure 12 ms later, on four
/// cycles a file (the Festo records' force follows their pressure by
/// 10–16 ms, on fills of about a second; on the one slow cycle of the
/// other tests a 12 ms delay moves the pressure by 1–5 kPa against the
/// braid friction's ±20 kPa loop): diagnose estimates the delay from the
/// data, names `pressure_delay` after the static shape, writes fit's
/// static model refitted on the retimed training part with it (blob
/// version 5), and that model predicts the other test's pressure better
/// than the static reference surface, which has no delay; without the
/// delay, the same muscle gets none. Fails on a diagnosis without the
/// delay candidate (no `pressure_delay`). Release only, as above.
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn a_force_answering_the_pressure_late_is_diagnosed_as_a_pressure_delay() {
    let diagnosed = |delay_s| {
        diagnosed_with(Sensor {
            delay_s,
            cycles: 4.0,
            ..AT_ONCE
        })
    };
    let added = effects_added;
    // The same muscle and protocol without a delay: none is named (its
    // braid friction's loop is not taken for one; read against a static
    // surface without the branch's surface, or with the branches of the
    // pressure as measured instead of as moved, it was: 18 ms, named).
    // By a small margin: the estimate reads 3.6 ms, and that delay's
    // candidate cuts 19.9 % of the held-out error but 14.8 % in its regime,
    // under the 15 % rule.
    let (report, _) = diagnosed(None);
    assert!(
        !added(&report).iter().any(|e| e == "pressure_delay"),
        "{:?}",
        added(&report)
    );
    let (report, blob) = diagnosed(Some(0.012));
    let names = added(&report);
    assert_eq!(
        names.first().map(String::as_str),
        Some("constraint_shape"),
        "{names:?}"
    );
    assert!(names.iter().any(|e| e == "pressure_delay"), "{names:?}");
    let d = report["effects"]["pressure_delay"]["delay_s"]
        .as_f64()
        .unwrap();
    // Within two samples (1.8 ms each) of the truth: the estimate read
    // 12.6 ms, and the one of it and its neighbours a sample either side
    // whose static model fits its training part best is written (14.4 ms).
    assert!((d - 0.012).abs() <= 0.0037, "{d}");
    let v = &report["validation"];
    let model = v["model"]["pressure_rms_mpa"].as_f64().unwrap();
    let reference = v["reference_rms_mpa"].as_f64().unwrap();
    eprintln!("validation pressure RMS: diagnosed {model:.4}, reference {reference:.4} MPa");
    assert!(model < reference, "{model} vs {reference}");
    assert_eq!(u16::from_le_bytes([blob[4], blob[5]]), 5);
    let (_, effects) = pam_core::blob::decode_model(&blob).unwrap();
    assert!(effects.pressure_delay.is_some());
}

/// The generated records read by `sensor`, imported, and diagnosed with
/// test 10 validating: the report and the blob written.
fn diagnosed_with(sensor: Sensor) -> (serde_json::Value, Vec<u8>) {
    let dir = tempfile::tempdir().unwrap();
    let (out, ok, stdout, stderr) = imported_with(dir.path(), sensor);
    assert!(ok, "{stdout}{stderr}");
    let diag = dir.path().join("diagnose");
    let (ok, stdout, stderr) = pam_lab(&[
        "diagnose",
        out.join("train.csv").to_str().unwrap(),
        "--validate",
        out.join("test.csv").to_str().unwrap(),
        "--no-plot",
        "-o",
        diag.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}{stderr}");
    eprintln!("{stdout}{stderr}");
    // The static fits run side by side before the rounds (seconds each on
    // a long record) each say when they are done, so a redirected stderr
    // is not silent while they run.
    let progress = |what: &str| {
        stderr
            .lines()
            .any(|l| l.starts_with('[') && l.contains(what) && l.contains(": fitted"))
    };
    assert!(
        progress("the paper's model on the training part"),
        "{stderr}"
    );
    assert!(
        progress("fit's static shape on the training part"),
        "{stderr}"
    );
    assert!(
        progress("the static model pam-lab fit writes for the whole record"),
        "{stderr}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(diag.join("report.json")).unwrap()).unwrap();
    if report["effects_added"]
        .as_array()
        .is_some_and(|a| a.iter().any(|e| e == "pressure_delay"))
    {
        assert!(progress("with each pressure taken"), "{stderr}");
    }
    (report, std::fs::read(diag.join("model.blob")).unwrap())
}

/// The effects a diagnosis added, in order.
fn effects_added(report: &serde_json::Value) -> Vec<String> {
    report["effects_added"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect()
}

#[test]
fn import_refuses_bad_input_with_its_place_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let good = "header = false\n[columns]\nload = { column = 1, unit = \"N\" }\n\
                pressure = { column = 2, unit = \"kPa\" }\ntime = { column = 3, unit = \"s\" }\n\
                [[record]]\nname = \"r\"\nrest_length = 8.3\n\
                files = [{ path = \"a.csv\", held_length = 8.3 }, { path = \"b.csv\", held_length = 8.0 }]\n";
    std::fs::write(dir.path().join("a.csv"), "1,100,0\n2,200,0.01\n").unwrap();
    std::fs::write(dir.path().join("b.csv"), "1,100,0\n2,2x0,0.01\n").unwrap();
    std::fs::write(
        dir.path().join("neg.csv"),
        "-1,100,0\n-2,200,0.01\n-3,300,0.02\n",
    )
    .unwrap();
    let out = dir.path().join("out");
    let cases = [
        (
            good.replace("\"kPa\"", "\"kpa\""),
            "map.toml: columns.pressure: unit `kpa` is not known",
        ),
        (
            good.replace("header = false", "header = false\nbogus = 1"),
            "map.toml:2: column 1: unknown field `bogus`",
        ),
        (good.to_string(), "b.csv:2: column 2: `2x0` is not a number"),
        (
            good.replace("b.csv", "missing.csv"),
            "missing.csv: cannot read",
        ),
        (
            good.replace("\"a.csv\"", "\"neg.csv\"")
                .replace("\"b.csv\"", "\"a.csv\""),
            "is the load cell's sign reversed? set `scale = -1`",
        ),
    ];
    for (map, want) in cases {
        let map_path = dir.path().join("map.toml");
        std::fs::write(&map_path, map).unwrap();
        let (ok, stdout, stderr) = pam_lab(&[
            "import",
            map_path.to_str().unwrap(),
            "--data-dir",
            dir.path().to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(!ok && stdout.is_empty(), "{stdout}{stderr}");
        assert!(stderr.contains(want), "want `{want}`: {stderr}");
        assert!(!out.exists(), "{want}: wrote {}", out.display());
    }
}

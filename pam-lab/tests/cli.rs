//! The command line: bad input gives a located error and a non-zero exit
//! code and leaves no output behind; good input writes every output.

use std::path::Path;
use std::process::Command;

use pam_core::Params;
use pam_lab::synth::{generate, Protocol};

#[path = "support/cli.rs"]
mod cli_support;
use cli_support::pam_lab;

fn write_record(path: &Path, loads: &[f64]) {
    let rec = generate(&Params::DEFAULT, &Protocol::quick(loads), 0.001, 0.0008, 5);
    let mut text = String::from("# generated\nt_s,load_n,pressure_mpa,contraction,note\n");
    for s in &rec.samples {
        text.push_str(&format!(
            "{:.3},{},{:.5},{:.5},x\n",
            s.t_s, s.load_n, s.pressure_mpa, s.contraction
        ));
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn progress_is_a_line_per_stage_when_redirected() {
    // The test's stderr is a pipe: the default `--progress auto` writes
    // plain lines there (a bar only on a terminal), `never` nothing.
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("rig.csv");
    write_record(&data, &[100.0, 300.0]);
    let fit = |out: &str, extra: &[&str]| {
        let out = dir.path().join(out);
        let mut args = vec![
            "fit",
            data.to_str().unwrap(),
            "--no-plot",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        pam_lab(&args)
    };
    let (ok, stdout, stderr) = fit("auto", &[]);
    assert!(ok, "{stdout}\n{stderr}");
    let stage = |line: &str| line.starts_with('[') && line.contains(" s] ");
    assert!(
        stderr
            .lines()
            .any(|l| stage(l) && l.contains("least squares")),
        "{stderr}"
    );
    let (ok, stdout, stderr) = fit("never", &["--progress", "never"]);
    assert!(ok, "{stdout}\n{stderr}");
    assert!(!stderr.lines().any(stage), "{stderr}");
}

#[test]
fn fit_reports_the_errors_of_each_part_of_a_joined_record() {
    // Two tests of one muscle joined as `pam-lab import` joins them, the
    // second needing 0.02 MPa more pressure throughout: the model fits
    // between them, and the report shows each part's offset.
    let rec = generate(
        &Params::DEFAULT,
        &Protocol::quick(&[100.0, 300.0]),
        0.001,
        0.0008,
        5,
    );
    let span = rec.samples.last().unwrap().t_s + 0.1;
    let mut text = String::from("t_s,load_n,pressure_mpa,contraction\n");
    for (k, label) in ["test8.csv (new file)", "test9.csv (new file)"]
        .iter()
        .enumerate()
    {
        text.push_str(&format!("# segment: {label}\n"));
        for s in &rec.samples {
            text.push_str(&format!(
                "{:.3},{},{:.5},{:.5}\n",
                s.t_s + k as f64 * span,
                s.load_n,
                s.pressure_mpa + 0.02 * k as f64,
                s.contraction
            ));
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("joined.csv");
    std::fs::write(&data, text).unwrap();
    let out = dir.path().join("out");
    let (ok, stdout, stderr) = pam_lab(&[
        "fit",
        data.to_str().unwrap(),
        "--no-plot",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    assert!(stdout.contains("per part of the record"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("model.json")).unwrap()).unwrap();
    let parts = json["fit"]["segments"]
        .as_array()
        .expect("segments in model.json");
    assert_eq!(parts.len(), 2, "{parts:?}");
    assert_eq!(parts[1]["label"], "test9.csv (new file)");
    let mean = |k: usize| parts[k]["pressure_mean_mpa"].as_f64().unwrap();
    assert!(mean(0) > 0.005 && mean(1) < -0.005, "{parts:?}");
    assert!((mean(0) - mean(1) - 0.02).abs() < 0.005, "{parts:?}");
    // The reference surface beside each part, on the same samples: fitted
    // to both tests, it sits between them too (and has no loop).
    for part in parts {
        let model = part["stats"]["pressure_rms_mpa"].as_f64().unwrap();
        let reference = part["reference_pressure_rms_mpa"].as_f64().unwrap();
        assert!(reference >= 0.01 && reference > model, "{parts:?}");
    }
    assert!(stdout.contains("reference_p_rms_mpa"), "{stdout}");
}

#[test]
fn fit_then_simulate_writes_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("rig.csv");
    write_record(&data, &[100.0, 300.0]);
    let out = dir.path().join("out");
    let (ok, stdout, stderr) = pam_lab(&[
        "fit",
        data.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--progress",
        "always",
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    assert!(stdout.contains("held-out errors"), "{stdout}");
    assert!(
        stderr.contains("least squares"),
        "progress on stderr when asked for: {stderr}"
    );
    for f in ["model.json", "model.blob", "model_params.rs", "fit.png"] {
        assert!(out.join(f).metadata().unwrap().len() > 0, "{f}");
    }
    let coeffs = pam_core::blob::decode(&std::fs::read(out.join("model.blob")).unwrap()).unwrap();
    let truth = Params::DEFAULT.points.root_contraction;
    assert!((coeffs.params().points.root_contraction - truth).abs() < 2e-3);
    let sim = dir.path().join("sim.csv");
    let png = dir.path().join("sim.png");
    let (ok, stdout, stderr) = pam_lab(&[
        "simulate",
        out.join("model.blob").to_str().unwrap(),
        data.to_str().unwrap(),
        "-o",
        sim.to_str().unwrap(),
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    let text = std::fs::read_to_string(&sim).unwrap();
    assert!(text.starts_with(
        "t_s,load_n,pressure_mpa,measured_contraction,predicted_contraction,error_contraction"
    ));
    assert!(png.exists());
}

#[test]
fn bad_inputs_fail_with_file_line_and_column_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "t_s,load_n,contraction\n0,100,0.02\n",
            "bad.csv:1: column `pressure_mpa`: missing",
        ),
        (
            "t_s,load_n,pressure_mpa,contraction\n0,100,0.1,0.02\n0.02,100,abc,0.02\n",
            "bad.csv:3: column `pressure_mpa`: `abc` is not a number",
        ),
        (
            "t_s,load_n,pressure_mpa,contraction\n0,100,0.1,NaN\n",
            "bad.csv:2: column `contraction`: value is NaN",
        ),
        (
            "t_s,load_n,pressure_mpa,contraction\n# c\n1,100,0.1,0.02\n0.9,100,0.1,0.02\n",
            "bad.csv:4: column `t_s`: time goes backwards",
        ),
        (
            "t_s,load_n,pressure_mpa,contraction\n0,100,0.1,1.5\n",
            "bad.csv:2: column `contraction`: value 1.5 is out of range",
        ),
    ];
    for (text, want) in cases {
        let data = dir.path().join("bad.csv");
        std::fs::write(&data, text).unwrap();
        let out = dir.path().join("out");
        let (ok, _, stderr) =
            pam_lab(&["fit", data.to_str().unwrap(), "-o", out.to_str().unwrap()]);
        assert!(!ok);
        assert!(stderr.contains(want), "want `{want}` in: {stderr}");
        assert!(!out.exists(), "no output directory on failure");
    }
}

#[test]
fn too_few_samples_per_load_and_branch_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("one_load.csv");
    write_record(&data, &[100.0]);
    let out = dir.path().join("out");
    let (ok, _, stderr) = pam_lab(&["fit", data.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(!ok);
    assert!(
        stderr.contains("one_load.csv: column `load_n`: too few samples to identify the model"),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn simulate_refuses_a_corrupt_blob_and_keeps_the_old_output() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("rig.csv");
    write_record(&data, &[100.0, 300.0]);
    let blob = dir.path().join("model.blob");
    let mut bytes = pam_core::blob::encode(&Params::DEFAULT);
    bytes[30] ^= 4;
    std::fs::write(&blob, bytes).unwrap();
    let out = dir.path().join("sim.csv");
    std::fs::write(&out, "old").unwrap();
    let (ok, _, stderr) = pam_lab(&[
        "simulate",
        blob.to_str().unwrap(),
        data.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        stderr.contains("model.blob") && stderr.contains("CRC"),
        "{stderr}"
    );
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "old");
}

#[test]
fn compare_puts_fit_and_the_preisach_model_side_by_side_and_refuses_isometric() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("rig.csv");
    write_record(&data, &[100.0, 200.0, 300.0]);
    let out = dir.path().join("cmp");
    let (ok, stdout, stderr) = pam_lab(&[
        "compare",
        data.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    assert!(std::fs::metadata(out.join("compare.png")).unwrap().len() > 1000);
    // The Preisach table identified, as pam-core's blob reader accepts it.
    let blob = std::fs::read(out.join("preisach.blob")).unwrap();
    assert!(pam_core::preisach::blob::decode::<16, 6>(&blob).is_ok());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("compare.json")).unwrap()).unwrap();
    let entries = json["entries"].as_array().unwrap();
    assert_eq!(entries.len(), 2);
    // Both are flashable (the firmware boots a Preisach blob too); pam
    // flashes the Preisach model only where it is the more accurate on both
    // held-out sets.
    assert_eq!(entries[0]["flashable"], true);
    assert_eq!(entries[1]["flashable"], true);
    let better = |k: &str| entries[1][k].as_f64().unwrap() < entries[0][k].as_f64().unwrap();
    let preisach = better("heldout_rms") && better("heldout_loads_rms");
    assert_eq!(json["chosen"], usize::from(preisach));
    let flashed = if preisach {
        "pam would flash: Preisach"
    } else {
        "pam would flash: fit's model"
    };
    assert!(stdout.contains(flashed), "{stdout}");
    // Trained again without the middle load, scored there.
    let left_out = json["heldout_loads_n"].as_array().unwrap();
    assert_eq!(left_out.len(), 1);
    assert!(
        (left_out[0].as_f64().unwrap() - 200.0).abs() < 5.0,
        "{left_out:?}"
    );
    for e in entries {
        // The record's noise is 0.0008: both models are within a few of it,
        // on held-out cycles and at the load left out.
        for key in ["heldout_rms", "heldout_loads_rms"] {
            let rms = e[key].as_f64().unwrap();
            assert!(rms > 0.0 && rms < 0.01, "{key}: {e}");
        }
        assert!(e["instructions_mean"].as_f64().unwrap() > 0.0, "{e}");
    }
    // An isometric record: refused with the reason, nothing written.
    let iso = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/isometric.csv");
    let out = dir.path().join("iso");
    let (ok, _, stderr) = pam_lab(&[
        "compare",
        iso.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok && stderr.contains("isotonic"), "{stderr}");
    assert!(!out.join("compare.json").exists());
}

fn pam_lab_in(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_pam-lab"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

#[test]
fn simulate_to_a_closed_pipe_ends_quietly() {
    use std::io::Read;
    let dir = tempfile::tempdir().unwrap();
    write_record(&dir.path().join("rig.csv"), &[100.0, 300.0]);
    std::fs::write(
        dir.path().join("model.blob"),
        pam_core::blob::encode(&Params::DEFAULT),
    )
    .unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_pam-lab"))
        .args(["simulate", "model.blob", "rig.csv", "-o", "-"])
        .current_dir(dir.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Read the header line only, then close the pipe (as `| head -1` does).
    let mut stdout = child.stdout.take().unwrap();
    let mut first = [0u8; 16];
    stdout.read_exact(&mut first).unwrap();
    assert_eq!(&first, b"t_s,load_n,press");
    drop(stdout);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(out.status.code(), Some(0), "{stderr}");
}

#[test]
fn outputs_have_ordinary_permissions_and_quiet_prints_nothing() {
    let dir = tempfile::tempdir().unwrap();
    write_record(&dir.path().join("rig.csv"), &[100.0, 300.0]);
    let out = pam_lab_in(dir.path(), &["fit", "rig.csv", "-o", "fit", "-q"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.stdout.is_empty() && out.stderr.is_empty(), "quiet");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // What a file created the ordinary way gets under this umask.
        let probe = dir.path().join("probe");
        std::fs::write(&probe, b"").unwrap();
        let ordinary = probe.metadata().unwrap().permissions().mode() & 0o777;
        for f in ["model.json", "model.blob", "model_params.rs", "fit.png"] {
            let mode = dir
                .path()
                .join("fit")
                .join(f)
                .metadata()
                .unwrap()
                .permissions()
                .mode();
            assert_eq!(mode & 0o777, ordinary, "{f}: {:o}", mode & 0o777);
        }
    }
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().all(|n| !n.starts_with(".pam-lab")),
        "no staging left: {names:?}"
    );
}

#[test]
fn simulate_warns_about_loads_outside_the_calibrated_range() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rig.csv");
    write_record(&path, &[100.0, 300.0]);
    // The second half of the record at 5000 N.
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let half = lines.len() / 2;
    let mut edited = String::new();
    for (i, l) in lines.iter().enumerate() {
        if i >= half && !l.starts_with('#') && !l.starts_with("t_s") {
            let mut f: Vec<&str> = l.split(',').collect();
            f[1] = "5000";
            edited.push_str(&f.join(","));
        } else {
            edited.push_str(l);
        }
        edited.push('\n');
    }
    std::fs::write(&path, edited).unwrap();
    std::fs::write(
        dir.path().join("model.json"),
        pam_lab::export::model_file::ModelFile::new(Params::DEFAULT, None).to_json(),
    )
    .unwrap();
    let out = pam_lab_in(
        dir.path(),
        &["simulate", "model.json", "rig.csv", "-o", "sim.csv"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let first_line = half + 1;
    assert!(
        stderr.contains(&format!(
            "warning: rig.csv:{first_line}: load outside the model's calibrated range"
        )),
        "{stderr}"
    );
    assert!(stderr.contains("..5000)"), "{stderr}");
    assert!(dir.path().join("sim.csv").is_file());
}

#[test]
fn diagnose_writes_its_report_plots_and_model_at_once() {
    let dir = tempfile::tempdir().unwrap();
    write_record(&dir.path().join("rig.csv"), &[100.0, 200.0, 300.0]);
    let out = pam_lab_in(dir.path(), &["diagnose", "rig.csv", "-o", "diag"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "report.json",
        "model.json",
        "model.blob",
        "model_params.rs",
        "residual.png",
        "loops.png",
    ] {
        assert!(
            dir.path().join("diag").join(f).metadata().unwrap().len() > 0,
            "{f}"
        );
        assert!(stdout.contains(&format!("wrote diag/{f}")), "{stdout}");
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("diag/report.json")).unwrap())
            .unwrap();
    assert!(json.get("named").is_some(), "{json}");
    // The blob is the model diagnose ended with, as the firmware reads it.
    let blob = std::fs::read(dir.path().join("diag/model.blob")).unwrap();
    let (coeffs, _effects) = pam_core::blob::decode_model(&blob).unwrap();
    let final_params: pam_core::Params =
        serde_json::from_value(json["final_params"].clone()).unwrap();
    assert_eq!(coeffs.params(), &final_params);
}

#[test]
fn diagnose_with_no_rounds_reports_the_refitted_paper_model() {
    let dir = tempfile::tempdir().unwrap();
    write_record(&dir.path().join("rig.csv"), &[100.0, 200.0, 300.0]);
    let out = pam_lab_in(
        dir.path(),
        &[
            "diagnose",
            "rig.csv",
            "-o",
            "diag",
            "--max-effects",
            "0",
            "--no-plot",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("diag/report.json")).unwrap())
            .unwrap();
    assert_eq!(json["named"], "none", "{json}");
    assert_eq!(json["rounds"].as_array().map(Vec::len), Some(0), "{json}");
    assert_eq!(json["rms_after"], json["rms_before"], "{json}");
    assert!(!dir.path().join("diag/residual.png").exists());
}

/// `simulate` runs the effects a model file carries (a `diagnose` output),
/// from JSON and from the blob alike, and says which it ran.
#[test]
fn simulate_runs_the_effects_of_the_model_file() {
    use pam_core::effects::{Creep, Effects, NonLocalMemory};
    use pam_lab::export::model_file::model_files;
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("rig.csv");
    write_record(&data, &[100.0, 300.0]);
    let effects = Effects {
        memory: Some(NonLocalMemory::with_shape(2.0)),
        creep: Some(Creep {
            gain: 0.3,
            time_constant_s: 2.0,
        }),
        ..Effects::NONE
    };
    let predicted = |name: &str, effects: &Effects| {
        let model_dir = dir.path().join(name);
        std::fs::create_dir_all(&model_dir).unwrap();
        let files = model_files(&Params::DEFAULT, effects, None, "test").unwrap();
        let mut columns = Vec::new();
        for (file, bytes) in files.iter().filter(|(f, _)| *f != "model_params.rs") {
            let path = model_dir.join(file);
            std::fs::write(&path, bytes).unwrap();
            let sim = model_dir.join(format!("{file}.csv"));
            let (ok, stdout, stderr) = pam_lab(&[
                "simulate",
                path.to_str().unwrap(),
                data.to_str().unwrap(),
                "-o",
                sim.to_str().unwrap(),
            ]);
            assert!(ok, "{stdout}\n{stderr}");
            let ran_effects = stdout.contains("non_local_memory + creep");
            assert_eq!(ran_effects, effects.memory.is_some(), "{stdout}");
            let text = std::fs::read_to_string(&sim).unwrap();
            let column: Vec<f64> = text
                .lines()
                .skip(1)
                .map(|l| l.split(',').nth(4).unwrap().parse().unwrap())
                .collect();
            columns.push(column);
        }
        assert_eq!(columns[0], columns[1], "JSON and blob run the same model");
        columns.pop().unwrap()
    };
    let plain = predicted("plain", &Effects::NONE);
    let with = predicted("effects", &effects);
    assert_eq!(plain.len(), with.len());
    let differ = plain
        .iter()
        .zip(&with)
        .filter(|(a, b)| (*a - *b).abs() > 1e-3)
        .count();
    assert!(
        differ > plain.len() / 10,
        "the effects change the prediction: {differ} of {}",
        plain.len()
    );
}

#[test]
fn a_pressure_in_psi_is_named() {
    // examples/reference.csv with its pressure in psi (x 145.04): tops of
    // about 87 psi, which must not be taken for kPa alone.
    let dir = tempfile::tempdir().unwrap();
    let reference = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../examples/reference.csv"
    ))
    .unwrap();
    let mut lines = reference.lines();
    let mut text = format!("{}\n", lines.next().unwrap());
    for l in lines {
        let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
        let p: f64 = f[2].parse().unwrap();
        f[2] = format!("{:.4}", p * 145.04);
        text.push_str(&f.join(","));
        text.push('\n');
    }
    let data = dir.path().join("psi.csv");
    std::fs::write(&data, text).unwrap();
    let out = dir.path().join("out");
    let (ok, _, stderr) = pam_lab(&[
        "fit",
        data.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--no-plot",
        "-q",
    ]);
    assert!(!ok, "{stderr}");
    assert!(stderr.contains("psi (multiply by 0.006895)"), "{stderr}");
}

/// A generated record written with its time in milliseconds and its
/// pressure times `pressure_scale` (10: bar), in `dir`.
fn mis_scaled_record(dir: &std::path::Path, pressure_scale: f64) -> std::path::PathBuf {
    let rec = generate(
        &Params::DEFAULT,
        &Protocol::quick(&[100.0, 300.0]),
        0.001,
        0.0008,
        5,
    );
    let mut text = String::from("t_s,load_n,pressure_mpa,contraction\n");
    for s in &rec.samples {
        text.push_str(&format!(
            "{:.1},{},{:.5},{:.5}\n",
            s.t_s * 1000.0,
            s.load_n,
            s.pressure_mpa * pressure_scale,
            s.contraction
        ));
    }
    let data = dir.join("units.csv");
    std::fs::write(&data, text).unwrap();
    data
}

#[test]
fn units_that_look_wrong_are_warned() {
    let dir = tempfile::tempdir().unwrap();
    // Pressure in bar, time in milliseconds.
    let data = mis_scaled_record(dir.path(), 10.0);
    let out = dir.path().join("out");
    let (ok, _, stderr) = pam_lab(&[
        "fit",
        data.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--no-plot",
        "-q",
    ]);
    assert!(ok, "{stderr}");
    assert!(
        stderr.contains("column `pressure_mpa` reaches") && stderr.contains("divide it by 10"),
        "{stderr}"
    );
    assert!(
        stderr.contains("column `t_s` steps") && stderr.contains("divide it by 1000"),
        "{stderr}"
    );
}

#[test]
fn diagnose_warns_of_a_time_column_in_milliseconds() {
    // The effects' time constants are in seconds: a record logged in ms
    // would be diagnosed 1000× too slow (a rate law read as memory).
    let dir = tempfile::tempdir().unwrap();
    let data = mis_scaled_record(dir.path(), 1.0);
    let out = dir.path().join("out");
    let (_, _, stderr) = pam_lab(&[
        "diagnose",
        data.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--max-effects",
        "0",
        "--no-plot",
        "-q",
    ]);
    assert!(
        stderr.contains("column `t_s` steps") && stderr.contains("divide it by 1000"),
        "{stderr}"
    );
}

#[test]
fn simulate_writes_its_errors_as_model_minus_measured() {
    // The paper model's own noise-free record with the measured contraction
    // lowered by 0.01: the model lies above the measurement, so the
    // contraction error is +0.01 and the pressure the model needs at the
    // lower measured contraction is below the measured one (negative).
    let dir = tempfile::tempdir().unwrap();
    let rec = generate(
        &Params::DEFAULT,
        &Protocol::quick(&[100.0, 300.0]),
        0.0,
        0.0,
        1,
    );
    let mut text = String::from("t_s,load_n,pressure_mpa,contraction\n");
    for s in &rec.samples {
        text.push_str(&format!(
            "{},{},{},{}\n",
            s.t_s,
            s.load_n,
            s.pressure_mpa,
            s.contraction - 0.01
        ));
    }
    let data = dir.path().join("low.csv");
    std::fs::write(&data, text).unwrap();
    let model = dir.path().join("model.json");
    std::fs::write(
        &model,
        pam_lab::export::model_file::ModelFile::new(Params::DEFAULT, None).to_json(),
    )
    .unwrap();
    let out = dir.path().join("sim.csv");
    let (ok, _, stderr) = pam_lab(&[
        "simulate",
        model.to_str().unwrap(),
        data.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    let csv = std::fs::read_to_string(&out).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (ex, ep) = (col("error_contraction"), col("error_pressure_mpa"));
    let (mut x_median, mut p_median): (Vec<f64>, Vec<f64>) = lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            (v[ex].parse::<f64>().unwrap(), v[ep].parse::<f64>().unwrap())
        })
        .unzip();
    x_median.sort_by(f64::total_cmp);
    p_median.sort_by(f64::total_cmp);
    let (x, p) = (x_median[x_median.len() / 2], p_median[p_median.len() / 2]);
    assert!((x - 0.01).abs() < 0.002, "median contraction error {x}");
    assert!(p < -0.005, "median pressure error {p} MPa");
}

/// The number after `label` in `text`, up to the next space.
fn number_after(text: &str, label: &str) -> f64 {
    let at = text
        .find(label)
        .unwrap_or_else(|| panic!("no `{label}` in:\n{text}"))
        + label.len();
    text[at..]
        .split_whitespace()
        .next()
        .and_then(|v| v.trim_end_matches(',').parse().ok())
        .unwrap_or_else(|| panic!("no number after `{label}` in:\n{text}"))
}

#[test]
fn simulate_judges_an_isometric_record_as_fit_does() {
    // The model fit writes for an isometric record (with its stroke table),
    // simulated on the same record: the pressure error under load is the
    // one fit reports, not the bare paper model's at a load model 20 N
    // behind the force (6.6x fit's before simulate followed the force and
    // carried the shape).
    let dir = tempfile::tempdir().unwrap();
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/isometric.csv");
    let fit_dir = dir.path().join("fit");
    let (ok, fit_out, err) = pam_lab(&[
        "fit",
        data,
        "--holdout",
        "none",
        "--no-plot",
        "-o",
        fit_dir.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let fitted = number_after(&fit_out, "training pressure error RMS ");
    let model = fit_dir.join("model.json");
    let sim = dir.path().join("sim.csv");
    let png = dir.path().join("sim.png");
    let (ok, sim_out, err) = pam_lab(&[
        "simulate",
        model.to_str().unwrap(),
        data,
        "-o",
        sim.to_str().unwrap(),
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    // Drawn in pressure (the slack samples left out): a PNG is written.
    assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
    let simulated = number_after(&sim_out, "as fit leaves them out): pressure error RMS ");
    assert!(
        simulated <= 1.25 * fitted,
        "simulate {simulated} MPa vs fit {fitted} MPa\n{sim_out}"
    );
}

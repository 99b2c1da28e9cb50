//! `pam-lab adapt`: the stroke scale the firmware adapted online, made into
//! a model of its own and compared on a record of the worn muscle.

use std::path::Path;

use pam_core::{blob, Coeffs, Params};
use pam_lab::synth::{generate, Protocol};

#[path = "support/cli.rs"]
mod cli_support;
use cli_support::pam_lab;

/// A record of a muscle whose stroke is `scale` times the default model's
/// about each load's root, with sensor noise.
fn write_worn_record(path: &Path, scale: f64) {
    let mut rec = generate(
        &Params::DEFAULT,
        &Protocol::quick(&[100.0, 300.0, 600.0]),
        0.001,
        0.0,
        5,
    );
    let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
    let mut text = String::from("t_s,load_n,pressure_mpa,contraction\n");
    for (i, s) in rec.samples.iter_mut().enumerate() {
        let r = f64::from(
            coeffs
                .load_model_clamped(s.load_n as f32)
                .root_contraction(),
        );
        let noise = 0.0005 * ((i * 7919 % 1000) as f64 / 500.0 - 1.0);
        let x = r + scale * (s.contraction - r) + noise;
        text.push_str(&format!(
            "{:.3},{},{:.5},{:.5}\n",
            s.t_s, s.load_n, s.pressure_mpa, x
        ));
    }
    std::fs::write(path, text).unwrap();
}

fn rms_of(report: &str, name: &str) -> f64 {
    report
        .lines()
        .find_map(|l| l.trim().strip_prefix(name)?.trim().parse().ok())
        .unwrap_or_else(|| panic!("no `{name}` row in:\n{report}"))
}

#[test]
fn the_adapted_stroke_becomes_a_blob_that_follows_the_worn_muscle() {
    let dir = tempfile::tempdir().unwrap();
    let flashed = dir.path().join("flashed.blob");
    std::fs::write(&flashed, blob::encode(&Params::DEFAULT)).unwrap();
    let worn = dir.path().join("worn.csv");
    write_worn_record(&worn, 0.9);
    let out = dir.path().join("adapted");
    let (ok, stdout, stderr) = pam_lab(&[
        "adapt",
        flashed.to_str().unwrap(),
        "--stroke-scale",
        "0.9",
        "--record",
        worn.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{stderr}");
    for f in ["model.json", "model.blob", "model_params.rs"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let bytes = std::fs::read(out.join("model.blob")).unwrap();
    let (params, _) = blob::decode_model_params(&bytes).expect("the blob decodes");
    assert!(Coeffs::new(params).is_ok());
    let (flashed_rms, adapted_rms) = (rms_of(&stdout, "flashed"), rms_of(&stdout, "adapted"));
    assert!(
        adapted_rms < 0.5 * flashed_rms,
        "adapted {adapted_rms} vs flashed {flashed_rms}\n{stdout}"
    );
}

#[test]
fn a_scale_out_of_range_or_a_model_with_effects_is_refused_with_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let flashed = dir.path().join("flashed.blob");
    std::fs::write(&flashed, blob::encode(&Params::DEFAULT)).unwrap();
    let out = dir.path().join("adapted");
    for scale in ["0.3", "NaN", "1.7"] {
        let (ok, _, stderr) = pam_lab(&[
            "adapt",
            flashed.to_str().unwrap(),
            "--stroke-scale",
            scale,
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(!ok);
        assert!(stderr.contains("--stroke-scale"), "{stderr}");
        assert!(!out.exists());
    }
    let with_memory = dir.path().join("memory.blob");
    let effects = pam_core::Effects {
        memory: Some(pam_core::effects::NonLocalMemory::with_shape(1.0)),
        ..pam_core::Effects::NONE
    };
    std::fs::write(&with_memory, blob::encode_v2(&Params::DEFAULT, &effects)).unwrap();
    let (ok, _, stderr) = pam_lab(&[
        "adapt",
        with_memory.to_str().unwrap(),
        "--stroke-scale",
        "0.9",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        stderr.contains("non-local memory") && stderr.contains("paper's model only"),
        "{stderr}"
    );
    assert!(!out.exists());
}

//! `fit` on host-sim's rig (an independent Tondu–Lopez + Maxwell-slip
//! plant, not the paper's equations), tested isotonically and isometrically:
//! both give a model pam-core accepts, with held-out pressure and
//! contraction errors reported and bounded.
//!
//! ```sh
//! cargo test --release -p pam-lab --test fit_rigs -- --nocapture
//! ```

use pam_core::Coeffs;
use pam_lab::data::{Record, Sample};
use pam_lab::fit::{fit, FitConfig, TestKind};

fn record(name: &str, run: Vec<host_sim::rig::Sample>) -> Record {
    Record::from_samples(
        name,
        run.into_iter()
            .map(|s| Sample {
                t_s: s.t_s,
                load_n: s.load_n,
                pressure_mpa: s.pressure_mpa,
                contraction: s.contraction,
            })
            .collect(),
    )
}

#[test]
fn isometric_record_fits_with_its_pressure_error_reported() {
    let rec = record("isometric", host_sim::isometric_run(1));
    let r = fit(&rec, &FitConfig::default()).unwrap();
    Coeffs::new(r.params).unwrap();
    eprintln!(
        "isometric: held-out pressure RMS {:.5} MPa, contraction RMS {:.5}; loads {}..{} N; {}\n{}",
        r.test.total.pressure_rms_mpa,
        r.test.total.contraction_rms,
        r.params.min_load_n,
        r.params.max_load_n,
        r.shape.statement(),
        r.test.to_text()
    );
    assert_eq!(r.test_kind, TestKind::Isometric);
    // The loads are the clamp's force: from slack (0 N) to about 1 kN.
    assert!(r.params.min_load_n < 25.0, "{:?}", r.params);
    assert!(r.params.max_load_n > 500.0, "{:?}", r.params);
    // The rig's pressure range is 0.5 MPa; its loop about 0.04 MPa high.
    assert!(r.test.total.pressure_rms_mpa < 0.03, "{}", r.test.to_text());
}

#[test]
fn isotonic_record_fits_with_both_errors_reported() {
    let rec = record("isotonic", host_sim::characterisation_run(2));
    let r = fit(&rec, &FitConfig::default()).unwrap();
    Coeffs::new(r.params).unwrap();
    eprintln!(
        "isotonic: held-out pressure RMS {:.5} MPa, contraction RMS {:.5}; {}",
        r.test.total.pressure_rms_mpa,
        r.test.total.contraction_rms,
        r.shape.statement()
    );
    assert_eq!(r.test_kind, TestKind::Isotonic);
    assert!(r.test.total.contraction_rms < 0.02, "{}", r.test.to_text());
}

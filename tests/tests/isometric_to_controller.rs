//! An isometric record (held lengths, force as the load: the public Festo
//! tests' protocol) from a physical muscle — the Chou–Hannaford law with a
//! threshold pressure and braid friction, not pam-core's equations —
//! through `pam-lab fit` to a booted controller whose feedforward is the
//! fitted model's inverse over the record's range.

use firmware::controller::Sample as ControllerSample;
use firmware::{Controller, ControllerConfig};
use pam_core::{blob, Coeffs};
use pam_lab::identify::fit::{fit, FitConfig, Holdout, TestKind};
use pam_lab::record::{Record, Sample};
use pam_lab::synth::chou_hannaford_force_n;

fn isometric_record() -> Record {
    let mut samples = Vec::new();
    let mut t = 0.0;
    for eps in [0.0, 0.04, 0.08, 0.12] {
        for cycle in 0..3 {
            for i in 0..4000 {
                let u = f64::from(i) / 2000.0;
                let (p, filling) = if u < 1.0 {
                    (0.62 * u, true)
                } else {
                    (0.62 * (2.0 - u), false)
                };
                let wobble = 1e-3 * f64::from((i * 7 + cycle * 13) % 11) - 5e-3;
                samples.push(Sample {
                    t_s: t,
                    load_n: chou_hannaford_force_n(p, eps, filling) + 5.0 * wobble,
                    pressure_mpa: p + 0.2 * wobble,
                    contraction: eps,
                });
                t += 0.002;
            }
        }
    }
    Record::from_samples("isometric", samples)
}

#[test]
fn a_fitted_isometric_record_boots_the_controller_with_its_inverse() {
    let record = isometric_record();
    let cfg = FitConfig {
        holdout: Holdout::None,
        ..FitConfig::default()
    };
    let report = fit(&record, &cfg).expect("an isometric record fits");
    assert_eq!(report.test_kind, TestKind::Isometric);
    let coeffs = Coeffs::new(report.params).unwrap();
    let bytes = blob::encode(&report.params);
    let (lo, hi) = (report.params.min_load_n, report.params.max_load_n);
    // Over the record's range (its loads, its held contractions), the
    // booted controller's feedforward is the fitted model's pressure.
    for load in [lo, 0.5 * (lo + hi), hi] {
        let mut controller =
            Controller::from_blob(&bytes, ControllerConfig::DEFAULT, load).expect("blob boots");
        let model = coeffs.load_model(load).unwrap();
        for x in [0.0f32, 0.04, 0.08, 0.12] {
            let sample = ControllerSample {
                pressure_mpa: Ok(0.3),
                contraction: Ok(x),
                load_n: Ok(load),
            };
            let step = controller.update(&sample, x);
            let expected = model.pressure_mpa(x, step.branch);
            assert!(
                (step.feedforward_mpa - expected).abs() < 1e-5,
                "{load} N, x {x}: feedforward {} vs model {expected}",
                step.feedforward_mpa
            );
            assert!((0.0..=report.params.points.max_pressure_mpa).contains(&step.feedforward_mpa));
        }
    }
}

//! From a rig record to a booted controller: record → `pam-lab fit` → coefficient
//! blob → firmware `Controller::from_blob` → the feedforward the controller
//! computes is the fitted model's, and a damaged blob is refused.

use firmware::controller::Sample;
use firmware::{Controller, ControllerConfig};
use pam_core::{blob, Branch, Coeffs, Params};
use pam_lab::identify::fit::{fit, FitConfig};
use pam_lab::synth::{generate, Protocol};

fn fitted() -> (Params, Params) {
    let truth = Params::DEFAULT;
    let protocol = Protocol::standard(&[100.0, 200.0, 300.0], 0.5, 50.0);
    let record = generate(&truth, &protocol, 0.001, 0.0008, 7);
    let report = fit(&record, &FitConfig::default()).expect("fit");
    (truth, report.params)
}

#[test]
fn a_fitted_blob_boots_the_controller_and_drives_the_fitted_model() {
    let (truth, params) = fitted();

    // The fit recovers the muscle it was given: pressure within 5 kPa on both
    // branches over the stroke at the calibrated loads.
    let (t, f) = (Coeffs::new(truth).unwrap(), Coeffs::new(params).unwrap());
    for load in [100.0, 200.0, 300.0] {
        let (mt, mf) = (t.load_model(load).unwrap(), f.load_model(load).unwrap());
        for i in 1..20 {
            let x = mt.root_contraction()
                + (mt.max_contraction() - mt.root_contraction()) * i as f32 / 20.0;
            for br in [Branch::Contraction, Branch::Expansion] {
                let (pt, pf) = (mt.pressure_mpa(x, br), mf.pressure_mpa(x, br));
                assert!(
                    (pt - pf).abs() < 0.005,
                    "{load} N, x {x}, {br:?}: {pt} vs {pf}"
                );
            }
        }
    }

    // The blob the tool writes is what the firmware boots from.
    let bytes = blob::encode(&params);
    let mut controller =
        Controller::from_blob(&bytes, ControllerConfig::DEFAULT, 200.0).expect("blob accepted");
    let sample = Sample {
        pressure_mpa: Ok(0.25),
        contraction: Ok(0.10),
        load_n: Ok(200.0),
    };
    let step = controller.update(&sample, 0.12);
    assert!(step.fault.is_none(), "{:?}", step.fault);
    let model = f.load_model(200.0).unwrap();
    let expected = model.pressure_mpa(0.12, step.branch);
    assert!(
        (step.feedforward_mpa - expected).abs() < 1e-5,
        "feedforward {} vs fitted model {expected}",
        step.feedforward_mpa
    );
}

#[test]
fn a_damaged_blob_is_refused_at_boot() {
    let mut bytes = blob::encode(&Params::DEFAULT);
    bytes[20] ^= 0x10;
    assert!(Controller::from_blob(&bytes, ControllerConfig::DEFAULT, 200.0).is_err());
    assert!(Controller::from_blob(&bytes[..10], ControllerConfig::DEFAULT, 200.0).is_err());
}

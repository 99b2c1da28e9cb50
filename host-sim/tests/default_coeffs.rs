//! pam-core's built-in `Params::DEFAULT` is the output of `pam-lab fit` on
//! host-sim's characterisation run: this test re-runs that fit, exactly as
//! the documented commands do it, and fails if the two drift apart.
//!
//! ```sh
//! cargo run --release -p host-sim     # writes target/host-sim-report/characterisation.csv
//! cargo run --release -p pam-lab -- fit target/host-sim-report/characterisation.csv -o fit/
//! ```

use pam_core::{Coeffs, Params};
use pam_lab::identify::fit::{fit, FitConfig};

/// Largest allowed difference per parameter (contraction as a fraction of
/// rest length, MPa, or per load step). The fit is deterministic and the
/// default is its `f32` output as `model_params.rs` prints it (round-trip
/// exact), so the two agree to `f32` rounding; the tolerance only absorbs a
/// platform's last-bit differences in `exp`/`sqrt`, far below any change of
/// the rig or of the fit (which move parameters by 1e-3 and more).
const TOLERANCE: f32 = 1e-5;

/// The record as the CLI sees it: host-sim's run written as the project CSV
/// (`host_sim::write_samples_csv`, what the main job writes) and read back.
fn characterisation_csv(seed: u64) -> pam_lab::record::Record {
    let dir = std::env::temp_dir().join(format!(
        "pam-lab-default-coeffs-{}-{seed}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("characterisation.csv");
    host_sim::write_samples_csv(&path, &host_sim::characterisation_run(seed)).unwrap();
    let rec = pam_lab::record::read_csv(&path).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    rec
}

/// Every parameter as `(name, value)`.
fn fields(p: &Params) -> [(&'static str, f32); Params::FIELD_COUNT] {
    p.named_fields()
}

#[test]
fn default_params_are_the_fit_of_host_sims_characterisation_run() {
    let rec = characterisation_csv(1);
    // The built-in model is the paper's alone: no static shape.
    let cfg = FitConfig {
        static_shape: false,
        ..FitConfig::default()
    };
    let fitted = fit(&rec, &cfg).unwrap().params;
    // Deterministic: a second run gives the same parameters, bit for bit.
    let again = fit(&rec, &cfg).unwrap().params;
    for ((name, a), (_, b)) in fields(&fitted).into_iter().zip(fields(&again)) {
        assert_eq!(a.to_bits(), b.to_bits(), "{name}: {a} vs {b}");
    }
    let mut drift = Vec::new();
    for ((name, d), (_, f)) in fields(&Params::DEFAULT).into_iter().zip(fields(&fitted)) {
        if (d - f).abs() > TOLERANCE {
            drift.push(format!("{name}: DEFAULT {d} vs fit {f}"));
        }
    }
    assert!(
        drift.is_empty(),
        "Params::DEFAULT has drifted from `pam-lab fit` on characterisation_run(1) \
         (regenerate it, see its doc comment):\n{}\nfitted: {fitted:#?}",
        drift.join("\n")
    );
}

#[test]
fn default_params_validate_over_the_whole_load_range() {
    let c = Coeffs::new(Params::DEFAULT).unwrap();
    assert_eq!(
        (c.params().min_load_n, c.params().max_load_n),
        (100.0, 600.0)
    );
    for load in (100..=600).step_by(5) {
        let m = c.load_model(load as f32).unwrap();
        // Rising from zero at the first root to Pmax at the stroke end.
        let mut prev = -1.0;
        for k in 0..=100 {
            let x = m.root_contraction()
                + (m.max_contraction() - m.root_contraction()) * k as f32 / 100.0;
            let p = m.constraint_pressure_mpa(x);
            assert!(p >= prev - 1e-6, "{load} N: not rising at {x}");
            prev = p;
        }
        assert!((prev - 0.50096667).abs() < 1e-4, "{load} N: {prev}");
    }
}

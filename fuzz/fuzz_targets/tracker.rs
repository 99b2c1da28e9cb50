//! `Tracker::update` over a sequence of arbitrary `(drive, load_n)` pairs,
//! with perturbed (validated) parameters and tracker configuration.
//!
//! Asserts after every sample: the active load stays in the calibrated range
//! and the active model's stroke is finite and non-empty; a reported load
//! switch lands on the active load; a reported branch switch is the branch
//! now; the flags match the inputs (non-finite, out of range); the active
//! model's evaluation stays finite and in range.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_core::Tracker;
use pam_fuzz::{check_eval, check_model, Floats};

fuzz_target!(|data: &[u8]| {
    let mut f = Floats::new(data);
    let coeffs = f.coeffs();
    let p = *coeffs.params();
    let config = f.tracker_config();
    let initial_load_n = f.around(p.min_load_n, p.max_load_n);
    let branch = f.branch();
    let mut t = Tracker::new(&coeffs, config, initial_load_n, branch).expect("config validated");
    check_model(&coeffs, t.model());
    while !f.is_empty() {
        let drive = f.around(0.0, p.points.max_pressure_mpa);
        let load_n = f.around(p.min_load_n, p.max_load_n);
        let u = t.update(&coeffs, drive, load_n);

        let active = t.load_n();
        assert!(
            active.is_finite() && coeffs.load_in_range(active),
            "active load {active} outside [{}, {}]",
            p.min_load_n,
            p.max_load_n
        );
        check_model(&coeffs, t.model());
        if let Some(s) = u.load_switch {
            assert_eq!(s.to_n, active, "switch target is not the active load");
            assert!(coeffs.load_in_range(s.from_n));
        }
        if let Some(b) = u.branch_switch {
            assert_eq!(b, t.branch());
        }
        assert_eq!(
            u.non_finite_input,
            !(drive.is_finite() && load_n.is_finite())
        );
        assert_eq!(u.load_out_of_range, !coeffs.load_in_range(load_n));
        check_eval(t.model(), drive, drive, t.branch());
    }
});

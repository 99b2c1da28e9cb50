//! Property tests over the whole f32 domain (NaN, ±inf, subnormals and
//! out-of-range values included) for every public evaluation function.

use pam_core::load_model::INVERSE_TOLERANCE_MPA;
use pam_core::{blob, Branch, Coeffs, Params, Tracker, TrackerConfig};
use proptest::prelude::*;

mod common;
use common::{any_f32, coeffs};

fn branch() -> impl Strategy<Value = Branch> {
    prop_oneof![Just(Branch::Contraction), Just(Branch::Expansion)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn forward_is_finite_and_within_zero_to_pmax(x in any_f32(), load in any_f32(), br in branch()) {
        let m = coeffs().load_model_clamped(load);
        let p = m.pressure_mpa(x, br);
        prop_assert!(p.is_finite());
        let pmax = Params::DEFAULT.points.max_pressure_mpa;
        prop_assert!((0.0..=pmax).contains(&p), "p = {p}");
        let cm = m.constraint_pressure_mpa(x);
        prop_assert!(cm.is_finite());
        prop_assert!(m.offset_mpa(x).is_finite() && m.offset_mpa(x) >= 0.0);
    }

    #[test]
    fn inverse_is_finite_and_within_the_stroke(p in any_f32(), load in any_f32(), br in branch()) {
        let m = coeffs().load_model_clamped(load);
        let x = m.contraction(p, br);
        prop_assert!(x.is_finite());
        prop_assert!(x >= m.root_contraction() && x <= m.max_contraction());
    }

    #[test]
    fn forward_of_inverse_is_identity(t in 0.0f32..=1.0, load in 100.0f32..=600.0, br in branch()) {
        let m = coeffs().load_model(load).unwrap();
        // The whole operating range, Pmax included.
        let p = t * m.max_pressure_mpa();
        let x = m.contraction(p, br);
        let back = m.pressure_mpa(x, br);
        // Where the branch is increasing (everywhere on the default muscle's
        // clamped branches, up to and including Pmax) the round trip is exact
        // to the stated tolerance.
        prop_assert!((back - p).abs() <= INVERSE_TOLERANCE_MPA, "p {p} -> x {x} -> {back}");
    }

    #[test]
    fn inverse_of_forward_is_identity_where_monotone(t in 0.05f32..0.95, load in 100.0f32..=600.0, br in branch()) {
        let m = coeffs().load_model(load).unwrap();
        let x = m.root_contraction() + t * (m.max_contraction() - m.root_contraction());
        let p = m.pressure_mpa(x, br);
        // Away from the clamped ends the branch is strictly increasing, so the
        // contraction comes back; the error is the pressure tolerance over the slope.
        prop_assume!(p > 0.0 && p < m.max_pressure_mpa());
        let back = m.contraction(p, br);
        prop_assert!((back - x).abs() <= 2e-3, "x {x} -> p {p} -> {back}");
    }

    #[test]
    fn load_model_errors_never_panic(load in any_f32()) {
        let c = coeffs();
        match c.load_model(load) {
            Ok(m) => prop_assert!(c.load_in_range(load) && m.load_n() == load),
            Err(_) => prop_assert!(!c.load_in_range(load)),
        }
    }

    #[test]
    fn arbitrary_params_never_panic(v in proptest::collection::vec(any_f32(), 14)) {
        let p = Params {
            min_load_n: v[0], max_load_n: v[1], load_step_n: v[2],
            points: pam_core::CriticalPoints {
                root_contraction: v[3], max_contraction: v[4], max_pressure_mpa: v[5],
                tangency: pam_core::Point { contraction: v[6], pressure_mpa: v[7] },
                inflection: pam_core::Point { contraction: v[8], pressure_mpa: v[9] },
            },
            root_regression_per_step: v[10], max_regression_per_step: v[11],
            c_growth_per_step: v[12], ellipse_height_mpa: v[13],
        };
        if let Ok(c) = Coeffs::new(p) {
            let m = c.load_model_clamped(v[0]);
            prop_assert!(m.pressure_mpa(v[3], Branch::Contraction).is_finite());
            prop_assert!(m.contraction(v[5], Branch::Expansion).is_finite());
        }
    }

    #[test]
    fn arbitrary_blobs_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..100)) {
        let _ = blob::decode(&bytes);
    }

    #[test]
    fn tracker_never_panics(samples in proptest::collection::vec((any_f32(), any_f32()), 1..200)) {
        let c = coeffs();
        let mut t = Tracker::new(&c, TrackerConfig::DEFAULT_PRESSURE, 100.0, Branch::Contraction).unwrap();
        for (d, l) in samples {
            t.update(&c, d, l);
            prop_assert!(c.load_in_range(t.load_n()));
        }
    }

    #[test]
    fn tracker_never_flips_on_noise_below_the_deadband(
        level in 0.0f32..=0.501,
        noise in proptest::collection::vec(-0.5f32..0.5, 1..500),
        br in branch(),
    ) {
        let c = coeffs();
        let cfg = TrackerConfig::DEFAULT_PRESSURE;
        let mut t = Tracker::new(&c, cfg, 200.0, br).unwrap();
        // Peak-to-peak noise strictly below the deadband.
        for n in noise {
            let u = t.update(&c, level + n * 0.99 * cfg.direction_deadband, 200.0);
            prop_assert!(u.branch_switch.is_none());
        }
        prop_assert_eq!(t.branch(), br);
    }
}

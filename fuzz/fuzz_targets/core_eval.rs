//! pam-core's public evaluation with arbitrary `f32`s: parameters through
//! `Coeffs::new`, loads through `load_model` / `load_model_clamped`,
//! contractions and pressures through `pressure_mpa`, `contraction`,
//! `constraint_pressure_mpa`, `offset_mpa` and the scaled-offset inverse
//! `effects::branch_contraction`.
//!
//! Asserts: accepted parameters give a non-empty finite stroke at every load;
//! `load_model` succeeds exactly for loads in range; every output is finite
//! and inside its documented range.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_core::effects::{branch_contraction, MAX_OFFSET_SCALE};
use pam_fuzz::{check_eval, check_model, Floats};

fuzz_target!(|data: &[u8]| {
    let mut f = Floats::new(data);
    let coeffs = f.coeffs();
    let p = *coeffs.params();
    for _ in 0..3 {
        let load_n = f.around(p.min_load_n, p.max_load_n);
        let m = coeffs.load_model_clamped(load_n);
        check_model(&coeffs, &m);
        match coeffs.load_model(load_n) {
            Ok(exact) => {
                assert!(coeffs.load_in_range(load_n));
                assert_eq!(exact, m, "in-range load: clamped and exact models differ");
            }
            Err(_) => assert!(!coeffs.load_in_range(load_n)),
        }
        for _ in 0..8 {
            let x = f.around(m.root_contraction(), m.max_contraction());
            let q = f.around(0.0, m.max_pressure_mpa());
            let br = f.branch();
            check_eval(&m, x, q, br);
            let scale = f.around(0.0, MAX_OFFSET_SCALE);
            let xs = branch_contraction(&m, q, br, scale);
            assert!(
                xs.is_finite() && xs >= m.root_contraction() && xs <= m.max_contraction(),
                "branch_contraction({q:e}, {br:?}, {scale:e}) = {xs:e}"
            );
            if f.is_empty() {
                return;
            }
        }
    }
});

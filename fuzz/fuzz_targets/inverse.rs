//! `ModelInverse::pressure_mpa` (pam-core's feedforward inverse of the model
//! with every effect) over arbitrary desired contractions, branches, branch
//! switches and loads, with perturbed effect parameters and period.
//!
//! Asserts after every call: the pressure is finite and in `[0, Pmax]` of
//! the model it was given, the memory holds at most `N` reversals, and the
//! offset scale it used is in `[0, MAX_OFFSET_SCALE]`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_core::effects::MAX_OFFSET_SCALE;
use pam_core::{InverseState, ModelInverse};
use pam_fuzz::Floats;

const N: usize = 4;

fuzz_target!(|data: &[u8]| {
    let mut f = Floats::new(data);
    let coeffs = f.coeffs();
    let p = *coeffs.params();
    let effects = f.effects();
    let dt_s = f.near(1e-3, 2.0);
    let Ok(inverse) = ModelInverse::new(effects, dt_s) else {
        return; // refused by validation
    };
    let mut state = InverseState::<N>::default();
    let mut load_n = f.around(p.min_load_n, p.max_load_n);
    let mut model = coeffs.load_model_clamped(load_n);
    while !f.is_empty() {
        let sel = f.byte();
        if sel % 16 == 0 {
            // A load switch: a new model, the memory cleared (as the
            // firmware does).
            load_n = f.around(p.min_load_n, p.max_load_n);
            model = coeffs.load_model_clamped(load_n);
            state.clear_memory();
        }
        let x = f.around(model.root_contraction(), model.max_contraction());
        let branch = f.branch();
        let switch = sel & 1 != 0;
        let pressure_mpa = inverse.pressure_mpa(&mut state, &p, &model, load_n, x, branch, switch);
        assert!(
            pressure_mpa.is_finite() && (0.0..=model.max_pressure_mpa()).contains(&pressure_mpa),
            "pressure_mpa({x:e}, {branch:?}) = {pressure_mpa:e}"
        );
        assert!(state.reversals().len() <= N);
        let s = state.offset_scale();
        assert!((0.0..=MAX_OFFSET_SCALE).contains(&s), "offset scale {s}");
    }
});

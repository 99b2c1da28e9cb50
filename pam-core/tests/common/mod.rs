//! Shared pieces of pam-core's property tests.
#![allow(dead_code)] // each test binary uses its own subset

use pam_core::{Coeffs, Params};
use proptest::prelude::*;

/// The built-in default muscle.
pub fn coeffs() -> Coeffs {
    Coeffs::new(Params::DEFAULT).unwrap()
}

/// Any f32, with NaN, ±inf, the physical ranges (contraction in (−1, 1),
/// pressure in [0, 0.6] MPa) and out-of-range magnitudes weighted in.
pub fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        proptest::num::f32::ANY,
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        -1.0f32..1.0,
        0.0f32..0.6,
        -1000.0f32..1000.0,
    ]
}

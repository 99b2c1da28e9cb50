#![doc = include_str!("../README.md")]
// Always `no_std` (the unit tests link `std`): the error type implements
// `core::error::Error`, which host tools use as `std::error::Error`.
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate throughout validation: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod blob;
pub mod branch;
pub mod coeffs;
pub mod constraint;
pub mod effects;
pub mod ellipse;
pub mod error;
pub mod feedforward;
pub mod load_family;
pub mod load_model;
mod math;
pub mod params;
pub mod preisach;
pub mod simulator;
pub mod tracker;

pub use branch::Branch;
pub use coeffs::Coeffs;
pub use constraint::{FactorCubic, GeneralCubic};
pub use effects::Effects;
pub use ellipse::Ellipse;
pub use error::Error;
pub use feedforward::{InverseState, ModelInverse};
pub use load_family::{LoadCubic, LoadFamily, ShapeMargins};
pub use load_model::LoadModel;
pub use math::clamp;
pub use params::{CriticalPoints, Params, Point};
pub use simulator::Simulator;
pub use tracker::{LoadSwitch, Tracker, TrackerConfig, Update};

#[cfg(test)]
pub(crate) mod testing {
    /// `|a − b| ≤ atol + rtol·|b|`, the usual closeness test.
    pub fn isclose(a: f64, b: f64, rtol: f64, atol: f64) -> bool {
        (a - b).abs() <= atol + rtol * b.abs()
    }
}

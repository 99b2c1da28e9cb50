//! # pam-core
//!
//! `no_std`, allocation-free and panic-free evaluation of the hysteresis model
//! of a pneumatic artificial muscle (McKibben muscle) from *Hysteresis
//! Modelling of Pneumatic Artificial Muscle using General Cubic Equation and
//! Factor Theorem Prediction Method* (the paper; equation numbers in comments
//! refer to it).
//!
//! The model, in the paper's terms:
//!
//! * a **constraint model** per load: pressure as a cubic of contraction,
//!   `CM(x) = (x − R)(a x² − b x + c)` (eqs. 1–3, 15, 21), identified at the
//!   minimum load from four critical points (eqs. 7–14, [`constraint`]);
//! * a **load family**: the first real root `R` and the maximum contraction
//!   `Rx` regress and the quadratic constant `c` grows linearly with load
//!   (eqs. 16–20, [`load_family`]);
//! * a **hysteresis offset**: half an ellipse over `[R, Rx]` added on the
//!   contraction branch and subtracted on the expansion branch (eqs. 22–26,
//!   [`hysteresis`]);
//! * a **mode tracker** that follows direction and load changes and switches
//!   the active model ([`tracker`]).
//!
//! Units are in names: `pressure_mpa` in MPa, `load_n` in newtons,
//! `contraction` as a fraction of the muscle's rest length.
//!
//! ```
//! use pam_core::{Branch, Coeffs, Params};
//!
//! let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
//! let model = coeffs.load_model(200.0).unwrap();
//! let up = model.pressure_mpa(0.15, Branch::Contraction);
//! let down = model.pressure_mpa(0.15, Branch::Expansion);
//! assert!(up > down, "contraction needs more pressure than expansion");
//! // The inverse undoes the forward evaluation on the monotone part of a branch.
//! let x = model.contraction(up, Branch::Contraction);
//! assert!((x - 0.15).abs() < 1e-3);
//! ```
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate throughout validation: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod blob;
pub mod branch;
pub mod constraint;
pub mod effects;
pub mod error;
pub mod hysteresis;
pub mod load_family;
mod math;
pub mod params;
pub mod tracker;

pub use branch::Branch;
pub use constraint::{FactorCubic, GeneralCubic};
pub use effects::{Effects, Simulator};
pub use error::Error;
pub use hysteresis::LoadModel;
pub use load_family::Coeffs;
pub use params::{CriticalPoints, Params, Point};
pub use tracker::{LoadSwitch, Tracker, TrackerConfig, Update};

#[cfg(test)]
pub(crate) mod testing {
    /// `|a − b| ≤ atol + rtol·|b|`, the usual closeness test.
    pub fn isclose(a: f64, b: f64, rtol: f64, atol: f64) -> bool {
        (a - b).abs() <= atol + rtol * b.abs()
    }
}

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
//!   (eqs. 15–21, [`load_family`], in `f64`: construction and host tools);
//!   [`coeffs`] validates a parameter set once;
//! * a **hysteresis offset**: half an ellipse over `[R, Rx]` (eqs. 22–24,
//!   [`ellipse`]) added on the contraction branch and subtracted on the
//!   expansion branch: the per-load model with its forward and inverse
//!   evaluation (eqs. 25–26, [`load_model`], in `f32`: the per-sample path);
//! * a **mode tracker** that follows direction and load changes and switches
//!   the active model ([`tracker`]);
//! * the **effects** the paper leaves for future work ([`effects`]) and a
//!   [`simulator`] that runs the model with them.
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
pub mod coeffs;
pub mod constraint;
pub mod effects;
pub mod ellipse;
pub mod error;
pub mod load_family;
pub mod load_model;
mod math;
pub mod params;
pub mod simulator;
pub mod tracker;

pub use branch::Branch;
pub use coeffs::Coeffs;
pub use constraint::{FactorCubic, GeneralCubic};
pub use effects::Effects;
pub use ellipse::Ellipse;
pub use error::Error;
pub use load_family::{LoadCubic, LoadFamily, ShapeMargins};
pub use load_model::LoadModel;
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

//! # pam-lab
//!
//! Host-side tools around [`pam_core`]: identify the paper's hysteresis model
//! from test-rig measurements ([`fit`]), drive the model with measured
//! pressure and load ([`simulate`]), find where simulation and measurement
//! disagree, name the missing effect and add it ([`diagnose`]), and export
//! what the firmware flashes ([`model_file`]: the model file, the coefficient
//! blob and a Rust constants file).
//!
//! The binary `pam-lab` is a thin command-line layer over these modules
//! (`fit`, `simulate`, `diagnose`); the library is the reusable part, for
//! tests, fuzzing and your own scripts.
//!
//! ```
//! use pam_lab::{data, fit, synth};
//! use pam_core::Params;
//!
//! // A characterisation record generated from the built-in reference muscle.
//! let record = synth::generate(&Params::DEFAULT, &synth::Protocol::quick(&[100.0, 300.0]), 0.0, 0.0, 1);
//! let report = fit::fit(&record, &fit::FitConfig::default()).unwrap();
//! let got = report.params.points.root_contraction;
//! assert!((got - Params::DEFAULT.points.root_contraction).abs() < 1e-3);
//! # let _ = data::Record::default();
//! ```
#![warn(missing_docs)]

pub mod commands;
pub mod data;
pub mod diagnose;
pub mod diagnose_plot;
pub mod fit;
pub mod import;
pub mod lsq;
pub mod model_file;
pub mod output;
pub mod plot;
pub mod reference;
pub mod simulate;
pub mod split;
pub mod stats;
pub mod synth;

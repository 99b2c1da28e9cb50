//! # pam-lab
//!
//! Host-side tools around [`pam_core`], one pipeline, a module a stage:
//!
//! 1. [`record`]: read a record (pam's CSV, or a logger's files through a
//!    column map, [`record::import`]), validate it, split its branches.
//! 2. [`evaluate`]: drive a model over the record with pam-core's simulator
//!    ([`evaluate::simulate`]) and measure its errors.
//! 3. [`identify`]: the paper's model from the record
//!    ([`identify::fit`]), the effects it misses ([`identify::diagnose`]),
//!    the generic surface both are judged against ([`identify::reference`]).
//! 4. [`export`]: the model file, the coefficient blob, Rust constants.
//! 5. Plots of every stage: [`report`].
//!
//! [`commands`] runs the stages for the binary's commands and writes their
//! files all or none ([`output`]); [`synth`] generates test records.
//! The library is the reusable part, for tests, fuzzing and your own scripts.
//!
//! ```
//! use pam_lab::identify::fit;
//! use pam_lab::{record, synth};
//! use pam_core::Params;
//!
//! // A characterisation record generated from the built-in reference muscle.
//! let record = synth::generate(&Params::DEFAULT, &synth::Protocol::quick(&[100.0, 300.0]), 0.0, 0.0, 1);
//! let report = fit::fit(&record, &fit::FitConfig::default()).unwrap();
//! let got = report.params.points.root_contraction;
//! assert!((got - Params::DEFAULT.points.root_contraction).abs() < 1e-3);
//! # let _ = record::Record::default();
//! ```
#![warn(missing_docs)]

pub mod commands;
pub mod evaluate;
pub mod export;
pub mod identify;
pub mod output;
pub mod record;
pub mod report;
pub mod rng;
pub mod synth;

//! # host-sim
//!
//! The bench where the firmware's controller meets a simulated muscle rig on
//! the host. The rig — a Tondu–Lopez McKibben muscle with Maxwell-slip
//! friction ([`plant`]), ISO 6358 valve flow into a polytropic chamber
//! ([`pneumatics`]), and noisy, quantized, fault-injectable sensors
//! ([`sensors`]) — is independent of pam-core's equations, so the scenario
//! tests are not circular.
//!
//! [`characterisation_run`] produces the isotonic data that pam-core's
//! default coefficients are fitted from.

pub mod characterisation;
pub mod plant;
pub mod pneumatics;
pub mod report;
pub mod rig;
pub mod sensors;

pub use characterisation::{
    characterisation_run, isometric_run, isometric_run_on, to_record, write_samples_csv,
    IsometricProtocol,
};
pub use rig::{Rig, Sample, TrueState};
pub mod bench;
pub mod effect_rigs;
pub mod end_to_end;
pub mod faults;
pub mod hal_mocks;
pub mod harness;
pub mod preisach;
pub mod scenarios;
pub mod wear;

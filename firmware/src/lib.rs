#![doc = include_str!("../README.md")]
//!
//! ## Example
//!
//! The controller on the simulated bus: contract, then a sensor fault.
//!
//! ```
//! use firmware::controller::{Controller, ControllerConfig, Io, ValveCommand};
//! use firmware::hal::{PressureCalibration, ValvePair, ValvePairConfig};
//! use firmware::plant::{SimBus, SimContraction, SimLoad, SimPressure, SimPwm};
//!
//! let blob = pam_core::blob::encode(&pam_core::Params::DEFAULT);
//! let mut ctl = Controller::from_blob(&blob, ControllerConfig::DEFAULT, 200.0).unwrap();
//! let bus = SimBus::new();
//! let cal = PressureCalibration::ADC12_0_1MPA;
//! let mut io = Io {
//!     pressure: SimPressure { bus: &bus, calibration: cal },
//!     contraction: SimContraction(&bus),
//!     load: SimLoad(&bus),
//!     valve: ValvePair::new(SimPwm(&bus.inlet_duty), SimPwm(&bus.exhaust_duty), ValvePairConfig::DEFAULT).unwrap(),
//! };
//! // Muscle at rest, asked to contract by 10 %: the inlet opens.
//! bus.pressure_counts.set(cal.to_counts(0.0));
//! bus.contraction.set(0.02);
//! bus.load_n.set(200.0);
//! let step = ctl.step(&mut io, 0.10);
//! assert_eq!(step.fault, None);
//! assert!(matches!(step.command, ValveCommand::Flow(f) if f > 0.0));
//! assert!(bus.inlet_duty.get() > 0 && bus.exhaust_duty.get() == 0);
//! // A NaN from the position sensor: exhaust in the same step.
//! bus.contraction.set(f32::NAN);
//! let step = ctl.step(&mut io, 0.10);
//! assert!(step.new_fault.is_some());
//! assert_eq!((bus.inlet_duty.get(), bus.exhaust_duty.get()), (0, SimPwm::MAX_DUTY));
//! ```
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate in validation: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod controller;
pub mod hal;
pub mod plant;
pub mod scenario;
pub mod wiring;

#[cfg(all(target_os = "none", feature = "chip"))]
pub mod board;

/// The coefficient blob the images carry, placed by `memory.x` at the start
/// of the COEFFS flash sector (0x080E0000) so it can be rewritten on its
/// own (`probe-rs download --base-address 0x080E0000`).
// `link_section` is flagged by the `unsafe_code` lint; placing read-only
// bytes in a dedicated flash region is the whole effect here.
#[cfg(all(target_os = "none", feature = "rt"))]
#[allow(unsafe_code)]
#[used]
#[link_section = ".pam_coeffs"]
pub static COEFFS_BLOB: [u8; pam_core::blob::BLOB_LEN] =
    *include_bytes!(concat!(env!("OUT_DIR"), "/coeffs.bin"));

/// The blob in flash, read at run time: `black_box` keeps the compiler from
/// folding the build-time bytes, so a rewritten sector takes effect.
#[cfg(all(target_os = "none", feature = "rt"))]
pub fn coeffs_blob() -> &'static [u8] {
    core::hint::black_box(&COEFFS_BLOB)
}

pub use controller::{Controller, ControllerConfig, Fault, Io, SafetyConfig, Step};

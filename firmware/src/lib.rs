#![doc = include_str!("../README.md")]
//!
//! ## Example
//!
//! One control period on a sample (what [`Controller::step`] does between
//! reading the sensors and writing the valves): contract, then a sensor
//! fault.
//!
//! ```
//! use firmware::controller::{Controller, ControllerConfig, Fault, Sample, SensorId, ValveCommand};
//! use firmware::hal::SafeState;
//!
//! let blob = pam_core::blob::encode(&pam_core::Params::DEFAULT);
//! let mut ctl = Controller::from_blob(&blob, ControllerConfig::DEFAULT, 200.0).unwrap();
//! // Muscle at rest, asked to contract by 10 %: the inlet opens.
//! let rest = Sample { pressure_mpa: Ok(0.0), contraction: Ok(0.02), load_n: Ok(200.0) };
//! let step = ctl.update(&rest, 0.10);
//! assert_eq!(step.fault, None);
//! assert!(matches!(step.command, ValveCommand::Flow(f) if f > 0.0));
//! // A NaN from the position sensor: exhaust in the same step.
//! let bad = Sample { contraction: Ok(f32::NAN), ..rest };
//! let step = ctl.update(&bad, 0.10);
//! assert_eq!(step.new_fault, Some(Fault::NonFinite(SensorId::Contraction)));
//! assert_eq!(step.command, ValveCommand::Safe(SafeState::Exhaust));
//! ```
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate in validation: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod boot;
pub mod controller;
pub mod crash;
pub mod exercise;
pub mod hal;
pub mod wiring;

// The simulated muscle, the self-test scenario and the simulated sensors and
// PWM channels (also host-sim's): only in the self-test images (feature
// `sim`, enabled by `selftest` and `qemu`), host benches and tests; the
// board controller does not contain them.
#[cfg(any(test, feature = "sim"))]
pub mod plant;
#[cfg(any(test, feature = "sim"))]
pub mod scenario;
#[cfg(any(test, feature = "sim"))]
pub mod sim_io;

#[cfg(all(target_os = "none", feature = "chip"))]
pub mod board;

/// Bytes of the blob region in flash: the longest blob the images boot,
/// the paper model's of any version or a Preisach blob of the flashed size
/// ([`controller::preisach::PREISACH_BLOB_LEN`]). `build.rs` writes the
/// region at this length (the array below has no other size).
pub const BLOB_REGION_LEN: usize = {
    let paper = pam_core::blob::MAX_BLOB_LEN;
    let preisach = controller::preisach::PREISACH_BLOB_LEN;
    if paper > preisach {
        paper
    } else {
        preisach
    }
};

/// The blob the images carry, placed by `memory.x` at the start
/// of the COEFFS flash sector (0x080E0000) so it can be rewritten on its
/// own (`probe-rs download --base-address 0x080E0000`).
// `link_section` is flagged by the `unsafe_code` lint; placing read-only
// bytes in a dedicated flash region is the whole effect here.
#[cfg(all(target_os = "none", feature = "rt"))]
#[allow(unsafe_code)]
#[used]
#[link_section = ".pam_coeffs"]
pub static COEFFS_BLOB: [u8; BLOB_REGION_LEN] =
    *include_bytes!(concat!(env!("OUT_DIR"), "/coeffs.bin"));

/// The blob in flash, read at run time: `black_box` keeps the compiler from
/// folding the build-time bytes, so a rewritten sector takes effect. The
/// region holds the longest blob the images boot; a shorter one is
/// followed by erased bytes, and the header's length says where it ends
/// (no blob header: the whole region, which the decoder refuses).
#[cfg(all(target_os = "none", feature = "rt"))]
pub fn coeffs_blob() -> &'static [u8] {
    framed_blob(core::hint::black_box(&COEFFS_BLOB))
}

/// The blob framed at the start of a flash region: the paper model's
/// (`PAMC`) or a Preisach blob (`PAMP`), as its header's length says; the
/// whole region when neither header is there (the decoder refuses it).
pub fn framed_blob(region: &[u8]) -> &[u8] {
    let len =
        pam_core::blob::framed_len(region).or_else(|| pam_core::preisach::blob::framed_len(region));
    match len {
        Some(len) => region.get(..len).unwrap_or(region),
        None => region,
    }
}

pub use controller::{Controller, ControllerConfig, Fault, Io, SafetyConfig, Step};

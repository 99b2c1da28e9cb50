//! A long record for timing `pam-lab` on a user-sized file: the reference
//! muscle ([`host_sim::Rig::reference`]) through the end-to-end run's
//! protocol ([`IsotonicProtocol::WITH_FAST_CYCLE`]: 100–600 N, two slow
//! cycles, reversals inside the loop, one 0.2 MPa/s cycle) logged at
//! 250 Hz instead of 25 Hz: 103 500 rows.
//!
//! ```sh
//! cargo run --release -p host-sim --example long_record -- long.csv
//! ```
//!
//! Deterministic: the same code writes the same bytes.

use host_sim::characterisation::{isotonic_run_on, write_samples_csv, IsotonicProtocol};

/// Logging rate, Hz: ten times the end-to-end run's.
const LOG_HZ: f64 = 250.0;

fn main() -> std::process::ExitCode {
    let Some(path) = std::env::args_os().nth(1) else {
        eprintln!("usage: long_record OUT.csv");
        return std::process::ExitCode::from(2);
    };
    let protocol = IsotonicProtocol {
        log_rate_hz: LOG_HZ,
        ..IsotonicProtocol::WITH_FAST_CYCLE
    };
    let samples = isotonic_run_on(host_sim::Rig::reference(100.0, 1), &protocol);
    match write_samples_csv(std::path::Path::new(&path), &samples) {
        Ok(()) => {
            eprintln!("wrote {} rows to {}", samples.len(), path.to_string_lossy());
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {}: {e}", path.to_string_lossy());
            std::process::ExitCode::FAILURE
        }
    }
}

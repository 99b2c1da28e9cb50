//! Regenerate the example records in the repository's `examples/` folder
//! (see `examples/README.md`): the project's own simulated rig
//! ([`host_sim::Rig`]: Tondu–Lopez muscle, Maxwell-slip friction, regulated
//! chamber, noisy sensors) run through one short isotonic protocol, each
//! record with one effect turned up.
//!
//! ```sh
//! cargo run --release -p host-sim --example example_records            # into examples/
//! cargo run --release -p host-sim --example example_records -- OUT_DIR
//! ```
//!
//! Deterministic: the same code writes the same bytes.

use std::path::PathBuf;

use host_sim::characterisation::{
    isotonic_run_on, run_moves, IsotonicProtocol, MOVES_WITH_FAST_CYCLE, SETTLE_S,
};
use host_sim::plant::MuscleParams;
use host_sim::pneumatics::PneumaticParams;
use host_sim::rig::IsometricClamp;
use host_sim::{Rig, Sample};

/// Logging rate, Hz (half the characterisation run's, to keep the files small).
const LOG_HZ: f64 = 25.0;
/// Loads of the isotonic records, N.
const LOADS_N: [f64; 4] = [100.0, 200.0, 300.0, 400.0];
/// Contractions the isometric record holds.
const HOLDS: [f64; 3] = [0.10, 0.14, 0.18];

/// The example records' protocol at the rig's present load or clamp.
fn protocol(rig: &mut Rig, out: &mut Vec<Sample>) {
    run_moves(rig, &MOVES_WITH_FAST_CYCLE, SETTLE_S, LOG_HZ, out);
}

/// An isotonic record (the hung load in the load column).
fn isotonic(muscle: MuscleParams, seed: u64) -> Vec<Sample> {
    let rig = Rig::new(muscle, PneumaticParams::DEFAULT, LOADS_N[0], seed);
    isotonic_run_on(
        rig,
        &IsotonicProtocol {
            loads_n: &LOADS_N,
            moves: &MOVES_WITH_FAST_CYCLE,
            settle_s: SETTLE_S,
            log_rate_hz: LOG_HZ,
        },
    )
}

fn isometric(seed: u64) -> Vec<Sample> {
    let mut rig = Rig::reference(0.0, seed);
    let mut out = Vec::new();
    for hold in HOLDS {
        rig.set_clamp(Some(IsometricClamp {
            hold_contraction: hold,
            stiffness_n_per_m: host_sim::characterisation::CLAMP_STIFFNESS_N_PER_M,
        }));
        protocol(&mut rig, &mut out);
    }
    out
}

fn main() -> std::io::Result<()> {
    let dir = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../examples"));
    std::fs::create_dir_all(&dir)?;
    let reference = MuscleParams::DEFAULT;
    // Rate dependence: viscous damping 300 -> 1500 N per unit contraction
    // per second, so the loop widens on the 0.2 MPa/s cycle.
    let rate = MuscleParams {
        damping_n_s: 1500.0,
        ..reference
    };
    // Load-dependent width: the end-to-end run's width rig, friction
    // mostly in the load's path, so the loop's height grows with the load.
    let width = host_sim::effect_rigs::WIDTH_MUSCLE;
    let records = [
        ("reference.csv", isotonic(reference, 1)),
        ("rate_dependence.csv", isotonic(rate, 2)),
        ("load_dependent_width.csv", isotonic(width, 3)),
        ("isometric.csv", isometric(4)),
    ];
    for (name, mut samples) in records {
        let t0 = samples.first().map_or(0.0, |s| s.t_s);
        for s in &mut samples {
            s.t_s -= t0;
        }
        let path = dir.join(name);
        host_sim::write_samples_csv(&path, &samples)?;
        println!("wrote {} ({} samples)", path.display(), samples.len());
    }
    Ok(())
}

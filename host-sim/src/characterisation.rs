//! The characterisation run: the reference rig tested isotonically, the data
//! pam-core's coefficients are fitted from.
//!
//! Protocol, at each load 100, 200, …, 600 N in turn (the load is hung with
//! the muscle empty, then held):
//! 1. 2 s settling at 0 MPa;
//! 2. two full cycles 0 → 0.5 → 0 MPa at 0.05 MPa/s;
//! 3. partial cycles reversing inside the loop, at 0.05 MPa/s:
//!    0 → 0.3 → 0.15 → 0.4 → 0.25 → 0.5 → 0 MPa.
//!
//! The pressure is held to the ramp by the rig's own regulator
//! ([`Rig::advance_regulated`]); samples are logged at 50 Hz with the rig's
//! sensor noise (about 0.8 kPa on pressure, 3e-4 on contraction, 1.5 N on
//! load) and the transducer's +3 kPa zero offset left in, as a real logger
//! would record. 444 s of data, 22 200 samples.

use crate::rig::{IsometricClamp, Rig, Sample};
use std::io::Write;
use std::path::Path;

/// Logging rate of the characterisation run, Hz.
pub const LOG_RATE_HZ: f64 = 50.0;
/// Pressure ramp rate, MPa/s.
pub const RAMP_MPA_PER_S: f64 = 0.05;
/// The loads, N.
pub const LOADS_N: [f64; 6] = [100.0, 200.0, 300.0, 400.0, 500.0, 600.0];
/// Pressure turning points at each load after the settling, MPa.
pub const PRESSURE_KNOTS_MPA: [f64; 11] = [0.0, 0.5, 0.0, 0.5, 0.0, 0.3, 0.15, 0.4, 0.25, 0.5, 0.0];
/// Settling time at 0 MPa after each load change, s.
pub const SETTLE_S: f64 = 2.0;

/// Run the characterisation protocol on the reference rig.
///
/// Deterministic: the same `seed` gives the same samples (the seed only
/// drives sensor noise; the muscle is [`crate::plant::MuscleParams::DEFAULT`]).
///
/// ```
/// let a = host_sim::characterisation_run(1);
/// assert_eq!(a.len(), 22_200);
/// assert_eq!(a[..100], host_sim::characterisation_run(1)[..100]);
/// // Columns: time, load, measured pressure, measured contraction.
/// assert!(a.iter().all(|s| s.pressure_mpa < 0.52 && s.contraction < 0.27));
/// ```
pub fn characterisation_run(seed: u64) -> Vec<Sample> {
    let dt = 1.0 / LOG_RATE_HZ;
    let mut rig = Rig::reference(LOADS_N[0], seed);
    let mut out = Vec::new();
    for &load in LOADS_N.iter() {
        rig.set_load_n(load);
        pressure_protocol(&mut rig, dt, &mut out);
    }
    retime_from_zero(&mut out);
    out
}

/// Contractions at which [`isometric_run`] holds the muscle.
pub const ISOMETRIC_HOLDS: [f64; 4] = [0.10, 0.13, 0.16, 0.19];
/// Stiffness of the isometric clamp and load cell, N/m.
pub const CLAMP_STIFFNESS_N_PER_M: f64 = 2e6;

/// An isometric characterisation run on the reference rig: the muscle is
/// clamped at each of [`ISOMETRIC_HOLDS`] in turn (through a stiff load
/// cell, [`IsometricClamp`]), and at each the pressure runs the same
/// protocol as [`characterisation_run`] (settle, two full cycles to 0.5 MPa,
/// the partial cycles), logged at 50 Hz. The load column is the force the
/// muscle pulls with (0 N while it is slack, up to about 1.1 kN), as a
/// real isometric test records it. 296 s, 14 800 samples.
///
/// ```
/// let run = host_sim::isometric_run(1);
/// assert_eq!(run.len(), 14_800);
/// let max_load = run.iter().map(|s| s.load_n).fold(0.0, f64::max);
/// assert!(max_load > 500.0 && max_load < 2000.0, "{max_load}");
/// ```
pub fn isometric_run(seed: u64) -> Vec<Sample> {
    let rig = Rig::reference(0.0, seed);
    isometric_run_on(rig, &IsometricProtocol::REFERENCE)
}

/// How an isometric test runs: where the muscle is held, how far and how
/// fast the pressure goes, how often the logger samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsometricProtocol<'a> {
    /// Contractions the muscle is clamped at, in turn.
    pub holds: &'a [f64],
    /// Top of the pressure cycles, MPa ([`PRESSURE_KNOTS_MPA`] are scaled
    /// from their 0.5 MPa).
    pub max_pressure_mpa: f64,
    /// Pressure ramp rate, MPa/s.
    pub ramp_mpa_per_s: f64,
    /// Logging rate, Hz.
    pub log_rate_hz: f64,
}

impl IsometricProtocol<'_> {
    /// [`isometric_run`]'s protocol.
    pub const REFERENCE: IsometricProtocol<'static> = IsometricProtocol {
        holds: &ISOMETRIC_HOLDS,
        max_pressure_mpa: 0.5,
        ramp_mpa_per_s: RAMP_MPA_PER_S,
        log_rate_hz: LOG_RATE_HZ,
    };
}

/// An isometric run of `protocol` on `rig` (its muscle, valves and sensors).
pub fn isometric_run_on(mut rig: Rig, protocol: &IsometricProtocol) -> Vec<Sample> {
    let dt = 1.0 / protocol.log_rate_hz;
    let scale = protocol.max_pressure_mpa / 0.5;
    let mut out = Vec::new();
    for &hold in protocol.holds {
        rig.set_clamp(Some(IsometricClamp {
            hold_contraction: hold,
            stiffness_n_per_m: CLAMP_STIFFNESS_N_PER_M,
        }));
        pressure_protocol_scaled(&mut rig, dt, scale, protocol.ramp_mpa_per_s, &mut out);
    }
    retime_from_zero(&mut out);
    out
}

/// [`MOVES_WITH_FAST_CYCLE`], then a step up to 0.3 MPa held 5 s, a step
/// down to 0.1 MPa held 5 s, and a ramp back to 0 (a negative rate is a
/// step held that many seconds, [`run_moves`]).
pub const MOVES_WITH_STEPS: [(f64, f64); 14] = {
    let steps = [(0.3, -5.0), (0.1, -5.0), (0.0, 0.05)];
    let mut out = [(0.0, 0.0); 14];
    let mut i = 0;
    while i < out.len() {
        out[i] = if i < MOVES_WITH_FAST_CYCLE.len() {
            MOVES_WITH_FAST_CYCLE[i]
        } else {
            steps[i - MOVES_WITH_FAST_CYCLE.len()]
        };
        i += 1;
    }
    out
};

/// Pressure moves of [`IsotonicProtocol::WITH_FAST_CYCLE`] after the
/// settling, `(to MPa, rate MPa/s)`: two full cycles at 0.05 MPa/s,
/// reversals inside the loop, one fast full cycle at 0.2 MPa/s (the example
/// records' protocol: the fast cycle shows a rate effect, the holds-free
/// reversals the memory).
pub const MOVES_WITH_FAST_CYCLE: [(f64, f64); 11] = [
    (0.5, 0.05),
    (0.0, 0.05),
    (0.5, 0.05),
    (0.0, 0.05),
    (0.3, 0.05),
    (0.15, 0.05),
    (0.4, 0.05),
    (0.25, 0.05),
    (0.0, 0.05),
    (0.5, 0.2),
    (0.0, 0.2),
];

/// How an isotonic test runs: the loads hung in turn and, at each, the
/// regulated pressure's moves after a settling time at 0 MPa.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsotonicProtocol<'a> {
    /// Loads hung in turn, N.
    pub loads_n: &'a [f64],
    /// Pressure moves at each load, `(to MPa, rate MPa/s)`, from 0 MPa.
    pub moves: &'a [(f64, f64)],
    /// Settling time at 0 MPa after each load change, s.
    pub settle_s: f64,
    /// Logging rate, Hz.
    pub log_rate_hz: f64,
}

impl IsotonicProtocol<'_> {
    /// [`MOVES_WITH_FAST_CYCLE`] at every load of [`LOADS_N`] (the scenarios'
    /// 100–600 N), 2 s settling, logged at 25 Hz: 414 s, 10 356 samples.
    pub const WITH_FAST_CYCLE: IsotonicProtocol<'static> = IsotonicProtocol {
        loads_n: &LOADS_N,
        moves: &MOVES_WITH_FAST_CYCLE,
        settle_s: SETTLE_S,
        log_rate_hz: 25.0,
    };

    /// [`MOVES_WITH_STEPS`] at every load of [`LOADS_N`], 2 s settling,
    /// logged at 25 Hz: 486 s, 12 156 samples; the protocol
    /// pam-lab/DIAGNOSE.md asks a user for (steps held for seconds show
    /// creep and the loop at rest).
    pub const WITH_STEPS: IsotonicProtocol<'static> = IsotonicProtocol {
        loads_n: &LOADS_N,
        moves: &MOVES_WITH_STEPS,
        settle_s: SETTLE_S,
        log_rate_hz: 25.0,
    };
}

/// An isotonic run of `protocol` on `rig`. The load column is the hung
/// load, as a test log records the weight it hangs.
///
/// ```
/// use host_sim::characterisation::{isotonic_run_on, IsotonicProtocol};
/// let run = isotonic_run_on(host_sim::Rig::reference(100.0, 1), &IsotonicProtocol::WITH_FAST_CYCLE);
/// assert_eq!(run.len(), 10_356);
/// assert!(run.iter().all(|s| [100.0, 200.0, 300.0, 400.0, 500.0, 600.0].contains(&s.load_n)));
/// ```
pub fn isotonic_run_on(mut rig: Rig, protocol: &IsotonicProtocol) -> Vec<Sample> {
    let mut out = Vec::new();
    for &load in protocol.loads_n {
        rig.set_load_n(load);
        let from = out.len();
        run_moves(
            &mut rig,
            protocol.moves,
            protocol.settle_s,
            protocol.log_rate_hz,
            &mut out,
        );
        for s in &mut out[from..] {
            s.load_n = load;
        }
    }
    retime_from_zero(&mut out);
    out
}

/// At the rig's present load or clamp: `settle_s` at 0 MPa, then each of
/// `moves` (`(to MPa, rate MPa/s)`) as a regulated ramp, logging a sample
/// every `1/log_rate_hz` seconds. A negative rate is a step: the regulator's
/// target jumps to `to` and holds there for `−rate` seconds.
pub fn run_moves(
    rig: &mut Rig,
    moves: &[(f64, f64)],
    settle_s: f64,
    log_rate_hz: f64,
    out: &mut Vec<Sample>,
) {
    let dt = 1.0 / log_rate_hz;
    for _ in 0..(settle_s * log_rate_hz) as usize {
        out.push(rig.measure());
        rig.advance_regulated(0.0, dt);
    }
    let mut p = 0.0;
    for &(to, rate) in moves {
        if rate < 0.0 {
            for _ in 0..(-rate / dt).round() as usize {
                out.push(rig.measure());
                rig.advance_regulated(to, dt);
            }
            p = to;
            continue;
        }
        let n = ((to - p).abs() / rate / dt).round() as usize;
        let from = p;
        for k in 0..n {
            out.push(rig.measure());
            let target = from + (to - from) * (k + 1) as f64 / n as f64;
            rig.advance_regulated(target, dt);
        }
        p = to;
    }
}

/// At the rig's present load or clamp: settle at 0 MPa, then ramp the
/// regulated pressure through [`PRESSURE_KNOTS_MPA`] at [`RAMP_MPA_PER_S`],
/// logging a sample every `dt` seconds.
fn pressure_protocol(rig: &mut Rig, dt: f64, out: &mut Vec<Sample>) {
    pressure_protocol_scaled(rig, dt, 1.0, RAMP_MPA_PER_S, out);
}

/// [`pressure_protocol`] with the knots scaled by `scale` and ramped at
/// `ramp_mpa_per_s`.
fn pressure_protocol_scaled(
    rig: &mut Rig,
    dt: f64,
    scale: f64,
    ramp_mpa_per_s: f64,
    out: &mut Vec<Sample>,
) {
    let mut p_ref = 0.0;
    let settle = (SETTLE_S / dt).round() as usize;
    for _ in 0..settle {
        out.push(rig.measure());
        rig.advance_regulated(p_ref, dt);
    }
    for w in PRESSURE_KNOTS_MPA.windows(2) {
        let (from, to) = (scale * w[0], scale * w[1]);
        let n = ((to - from).abs() / ramp_mpa_per_s / dt).round() as usize;
        for k in 0..n {
            out.push(rig.measure());
            p_ref = from + (to - from) * (k + 1) as f64 / n as f64;
            rig.advance_regulated(p_ref, dt);
        }
    }
}

/// Re-time from zero (the logger's clock starts with the first sample).
fn retime_from_zero(out: &mut [Sample]) {
    let t0 = out.first().map(|s| s.t_s).unwrap_or(0.0);
    for s in out.iter_mut() {
        s.t_s -= t0;
    }
}

/// `samples` as the record pam-lab reads from a CSV file (`source` names it
/// in messages): what `fit` and `diagnose` would see of the rig's log.
pub fn to_record(source: impl Into<String>, samples: &[Sample]) -> pam_lab::record::Record {
    pam_lab::record::Record::from_samples(
        source,
        samples
            .iter()
            .map(|s| pam_lab::record::Sample {
                t_s: s.t_s,
                load_n: s.load_n,
                pressure_mpa: s.pressure_mpa,
                contraction: s.contraction,
            })
            .collect(),
    )
}

/// Write samples as the project's CSV, `t_s,load_n,pressure_mpa,contraction`,
/// with the precision of the example records.
pub fn write_samples_csv(path: &Path, samples: &[Sample]) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(w, "t_s,load_n,pressure_mpa,contraction")?;
    for s in samples {
        writeln!(
            w,
            "{:.3},{:.1},{:.5},{:.5}",
            s.t_s, s.load_n, s.pressure_mpa, s.contraction
        )?;
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_covers_every_load_and_the_pressure_range() {
        let run = characterisation_run(3);
        for &load in LOADS_N.iter() {
            let at: Vec<&Sample> = run
                .iter()
                .filter(|s| (s.load_n - load).abs() < 10.0)
                .collect();
            assert!(at.len() > 3500, "{load} N: {}", at.len());
            let pmax = at.iter().map(|s| s.pressure_mpa).fold(f64::MIN, f64::max);
            let xmin = at.iter().map(|s| s.contraction).fold(f64::MAX, f64::min);
            let xmax = at.iter().map(|s| s.contraction).fold(f64::MIN, f64::max);
            assert!((pmax - 0.5).abs() < 0.01, "{load} N: pmax {pmax}");
            assert!(xmin < 0.025 && xmin > -0.005, "{load} N: xmin {xmin}");
            assert!(xmax > 0.13 && xmax < 0.27, "{load} N: xmax {xmax}");
        }
        // 100 N: about 2 % at 0 MPa and 25 % at 0.5 MPa.
        let first = &run[..100];
        let x0 = first.iter().map(|s| s.contraction).sum::<f64>() / 100.0;
        assert!((x0 - 0.02).abs() < 0.003, "{x0}");
        let t = run.windows(2).all(|w| w[1].t_s > w[0].t_s);
        assert!(t, "time strictly increasing");
    }

    #[test]
    fn loop_height_at_mid_stroke_is_about_0_04_mpa() {
        // Second full cycle at 100 N: pressure at contraction 0.13 on the way
        // up minus on the way down.
        let run = characterisation_run(5);
        let start = (SETTLE_S * LOG_RATE_HZ) as usize + 1000; // second cycle
        let cycle = &run[start..start + 1000];
        let crossing = |rising: bool| {
            let mut acc = Vec::new();
            for w in cycle.windows(2) {
                let up = w[1].pressure_mpa > w[0].pressure_mpa;
                if up == rising && (w[0].contraction - 0.13).abs() < 0.004 {
                    acc.push(w[0].pressure_mpa);
                }
            }
            acc.iter().sum::<f64>() / acc.len() as f64
        };
        let height = crossing(true) - crossing(false);
        eprintln!("loop height {height} MPa");
        assert!(height > 0.025 && height < 0.06, "loop height {height} MPa");
    }
}

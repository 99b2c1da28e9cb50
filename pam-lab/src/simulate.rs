//! Driving the model with measured pressure and load, as the firmware would.
//!
//! pam-core's [`Tracker`] follows the measured pressure (the drive signal) and
//! the measured load; the predicted contraction is the active load model's
//! inverse on the tracker's branch at the measured pressure. A reversal inside
//! the loop jumps to the other branch, as the paper's model does.

use pam_core::{Branch, Coeffs, Tracker, TrackerConfig};

use crate::data::Sample;

/// One simulated sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSample {
    /// Time, s.
    pub t_s: f64,
    /// Measured load, N.
    pub load_n: f64,
    /// Measured pressure, MPa.
    pub pressure_mpa: f64,
    /// Measured contraction.
    pub measured_contraction: f64,
    /// Model contraction.
    pub predicted_contraction: f64,
    /// The tracker's branch.
    pub branch: Branch,
    /// The tracker's active load, N.
    pub active_load_n: f64,
}

impl SimSample {
    /// Predicted − measured contraction.
    pub fn error(&self) -> f64 {
        self.predicted_contraction - self.measured_contraction
    }
}

/// Simulate `samples` with `coeffs`; the tracker starts on the contraction
/// branch at the first sample's load.
pub fn simulate(coeffs: &Coeffs, config: TrackerConfig, samples: &[Sample]) -> Vec<SimSample> {
    let first_load = samples.first().map_or(0.0, |s| s.load_n as f32);
    let Ok(mut tracker) = Tracker::new(coeffs, config, first_load, Branch::Contraction) else {
        return Vec::new();
    };
    samples
        .iter()
        .map(|s| {
            tracker.update(coeffs, s.pressure_mpa as f32, s.load_n as f32);
            let x = tracker
                .model()
                .contraction(s.pressure_mpa as f32, tracker.branch());
            SimSample {
                t_s: s.t_s,
                load_n: s.load_n,
                pressure_mpa: s.pressure_mpa,
                measured_contraction: s.contraction,
                predicted_contraction: f64::from(x),
                branch: tracker.branch(),
                active_load_n: f64::from(tracker.load_n()),
            }
        })
        .collect()
}

/// RMS and maximum |error| of a simulation.
pub fn summary(sim: &[SimSample]) -> (f64, f64) {
    let n = sim.len().max(1) as f64;
    let rms = (sim.iter().map(|s| s.error().powi(2)).sum::<f64>() / n).sqrt();
    let max = sim.iter().map(|s| s.error().abs()).fold(0.0, f64::max);
    (rms, max)
}

/// Write a simulation as CSV: the input columns, the prediction, the error
/// and the tracker's state.
pub fn write_csv(w: &mut dyn std::io::Write, sim: &[SimSample]) -> std::io::Result<()> {
    writeln!(
        w,
        "t_s,load_n,pressure_mpa,measured_contraction,predicted_contraction,error_contraction,branch,active_load_n"
    )?;
    for s in sim {
        writeln!(
            w,
            "{},{},{},{},{:.6},{:.6},{},{}",
            s.t_s,
            s.load_n,
            s.pressure_mpa,
            s.measured_contraction,
            s.predicted_contraction,
            s.error(),
            match s.branch {
                Branch::Contraction => "contraction",
                Branch::Expansion => "expansion",
            },
            s.active_load_n
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Protocol};
    use pam_core::Params;

    #[test]
    fn noise_free_full_cycles_are_reproduced() {
        // Full cycles only (no reversal inside the loop, where the tracker's
        // deadband delays the jump): prediction equals the generating model
        // except within the deadband after each reversal.
        let mut proto = Protocol::quick(&[100.0, 300.0]);
        for st in &mut proto.stages {
            st.moves.truncate(4);
        }
        let rec = generate(&Params::DEFAULT, &proto, 0.0, 0.0, 1);
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let sim = simulate(&coeffs, TrackerConfig::DEFAULT_PRESSURE, &rec.samples);
        assert_eq!(sim.len(), rec.len());
        let bad = sim.iter().filter(|s| s.error().abs() > 1e-4).count();
        // Each reversal at the ends costs at most deadband/step = 3 samples.
        assert!(bad <= 4 * 2 * 4, "{bad}");
        assert_eq!(sim[1990].active_load_n, 300.0);
        let mut out = Vec::new();
        write_csv(&mut out, &sim[..2]).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(text.lines().count(), 3);
    }
}

//! A lag between the pressure measured and the muscle's answer to it, on an
//! isometric record: the shift of the measured pressure that the diagnosed
//! model's pressure matches best.
//!
//! The pressure sensor of a rig sits at the valve or in the line; the
//! muscle's own pressure follows it through the tube and the bladder's
//! volume, and the load cell's filter delays the force. A static model,
//! hysteresis or not, has no term for it: its error then grows with the
//! pressure's rate on both branches alike. The report gives the shift that
//! fits best whatever the model; the `pressure_lag` candidate
//! ([`pam_core::effects::PressureLag`]) is the effect that models it, and
//! once it is in, the best shift is near zero.

use serde::Serialize;

use crate::evaluate::errors::median_step_s;
use crate::record::Sample;

/// The longest lag looked for, s.
pub const MAX_LAG_S: f64 = 0.1;

/// The lag the model's pressure matches best.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PressureLag {
    /// How much later the model's pressure follows the measured one, s
    /// (negative: earlier).
    pub lag_s: f64,
    /// RMS of the model's pressure against the measured pressure at the
    /// same instant, MPa.
    pub rms_unshifted_mpa: f64,
    /// RMS against the pressure measured `lag_s` earlier, MPa.
    pub rms_at_lag_mpa: f64,
    /// Samples compared (the same set at every shift).
    pub samples: usize,
}

impl PressureLag {
    /// The share of the RMS the shift removes.
    pub fn cut(&self) -> f64 {
        if self.rms_unshifted_mpa > 0.0 {
            1.0 - self.rms_at_lag_mpa / self.rms_unshifted_mpa
        } else {
            0.0
        }
    }
}

/// The shift of the measured pressure, within ±[`MAX_LAG_S`] in steps of
/// the record's median sampling interval, with the lowest RMS against
/// `predicted_mpa` over the samples `include` marks. The measured pressure
/// at a shifted instant is interpolated linearly within the sample's run of
/// rising time (a logger's clock jitters, and restarts where files are
/// joined); the samples compared are the same at every shift: those at
/// least [`MAX_LAG_S`] from either end of their run. `None` when fewer
/// than 100 samples qualify.
pub fn pressure_lag(
    samples: &[Sample],
    predicted_mpa: &[f64],
    include: impl Fn(usize) -> bool,
) -> Option<PressureLag> {
    let dt = median_step_s(samples);
    if !(dt.is_finite() && dt > 0.0) {
        return None;
    }
    let k_max = ((MAX_LAG_S / dt).round() as i64).clamp(1, 200);
    let span = k_max as f64 * dt;
    // Runs of rising time: [start, end).
    let mut runs: Vec<(usize, usize)> = Vec::new();
    let mut start = 0;
    for i in 1..=samples.len() {
        if i == samples.len() || samples[i].t_s <= samples[i - 1].t_s {
            runs.push((start, i));
            start = i;
        }
    }
    // The samples compared, run by run.
    let used: Vec<(usize, Vec<usize>)> = runs
        .iter()
        .enumerate()
        .map(|(r, &(a, b))| {
            let (t_a, t_b) = (samples[a].t_s, samples[b - 1].t_s);
            let idx = (a..b)
                .filter(|&i| {
                    include(i)
                        && predicted_mpa.get(i).is_some_and(|p| p.is_finite())
                        && samples[i].t_s - span >= t_a
                        && samples[i].t_s + span <= t_b
                })
                .collect();
            (r, idx)
        })
        .collect();
    let count: usize = used.iter().map(|(_, v)| v.len()).sum();
    if count < 100 {
        return None;
    }
    let rms_at = |shift_s: f64| -> f64 {
        let mut ss = 0.0;
        for (r, idx) in &used {
            let (a, b) = runs[*r];
            let mut j = a;
            for &i in idx {
                let target = samples[i].t_s - shift_s;
                while j + 2 < b && samples[j + 1].t_s <= target {
                    j += 1;
                }
                let (s0, s1) = (&samples[j], &samples[j + 1]);
                let w = ((target - s0.t_s) / (s1.t_s - s0.t_s)).clamp(0.0, 1.0);
                let p = s0.pressure_mpa + w * (s1.pressure_mpa - s0.pressure_mpa);
                let e = predicted_mpa[i] - p;
                ss += e * e;
            }
        }
        (ss / count as f64).sqrt()
    };
    let (best, rms_best) = (-k_max..=k_max)
        .map(|k| (k, rms_at(k as f64 * dt)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    Some(PressureLag {
        lag_s: best as f64 * dt,
        rms_unshifted_mpa: rms_at(0.0),
        rms_at_lag_mpa: rms_best,
        samples: count,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramps(n: usize, dt: f64) -> Vec<Sample> {
        (0..n)
            .map(|i| {
                let t = i as f64 * dt;
                Sample {
                    t_s: t,
                    load_n: 100.0,
                    pressure_mpa: 0.3 + 0.2 * (t * 1.3).sin() + 0.05 * (t * 7.0).sin(),
                    contraction: 0.1,
                }
            })
            .collect()
    }

    #[test]
    fn a_pressure_read_20_ms_early_is_found() {
        let dt = 0.002;
        let s = ramps(5000, dt);
        // The model's pressure is the measured one 10 samples (20 ms) back.
        let predicted: Vec<f64> = (0..s.len())
            .map(|i| s[i.saturating_sub(10)].pressure_mpa)
            .collect();
        let lag = pressure_lag(&s, &predicted, |_| true).unwrap();
        assert!((lag.lag_s - 0.020).abs() < 1e-9, "{lag:?}");
        assert!(lag.rms_at_lag_mpa < 1e-12, "{lag:?}");
        assert!(lag.cut() > 0.99, "{lag:?}");
    }

    #[test]
    fn no_lag_is_no_shift() {
        let s = ramps(5000, 0.002);
        let predicted: Vec<f64> = s.iter().map(|x| x.pressure_mpa + 0.001).collect();
        let lag = pressure_lag(&s, &predicted, |_| true).unwrap();
        assert_eq!(lag.lag_s, 0.0);
        assert!(lag.cut().abs() < 1e-12);
    }

    #[test]
    fn a_clock_reset_never_pairs_two_segments() {
        let dt = 0.002;
        let mut s = ramps(400, dt);
        // The clock restarts at sample 200: no sample within 100 ms of
        // either end of a run is compared.
        for (i, x) in s.iter_mut().enumerate().skip(200) {
            x.t_s = (i - 200) as f64 * dt;
        }
        let predicted: Vec<f64> = s.iter().map(|x| x.pressure_mpa).collect();
        let lag = pressure_lag(&s, &predicted, |_| true).unwrap();
        // (Up to a sample at each edge, where t ± 100 ms meets the run's
        // end within rounding.)
        assert!(
            (400 - 4 * 51..=400 - 4 * 50).contains(&lag.samples),
            "{lag:?}"
        );
        assert!(pressure_lag(&s[..150], &predicted[..150], |_| true).is_none());
    }

    #[test]
    fn a_jittering_clock_is_interpolated() {
        // Steps of 1, 2 and 3 ms in turn; the model 16 ms behind.
        let mut t = 0.0;
        let s: Vec<Sample> = (0..6000)
            .map(|i| {
                t += [0.001, 0.002, 0.003][i % 3];
                Sample {
                    t_s: t,
                    load_n: 100.0,
                    pressure_mpa: 0.3 + 0.2 * (t * 1.3).sin(),
                    contraction: 0.1,
                }
            })
            .collect();
        let predicted: Vec<f64> = s
            .iter()
            .map(|x| 0.3 + 0.2 * ((x.t_s - 0.016) * 1.3).sin())
            .collect();
        let lag = pressure_lag(&s, &predicted, |_| true).unwrap();
        assert!((lag.lag_s - 0.016).abs() < 0.0011, "{lag:?}");
        assert!(lag.cut() > 0.9, "{lag:?}");
    }
}

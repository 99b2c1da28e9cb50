//! A record's channels moved in time against each other: what a
//! [`PressureDelay`](pam_core::effects::PressureDelay) does to a record.
//!
//! The delay says the muscle answers the pressure measured `d` earlier. A
//! stream of samples keeps no history, so the record simulator does it
//! here, on the record: the muscle's pressure at a sample is the measured
//! pressure `d` before it ([`delayed_pressures`]), and the measured
//! pressure a model predicts at a sample is the muscle's `d` after it
//! ([`shifted`]). Values between samples are interpolated linearly within
//! the sample's run of rising time (a logger's clock restarts where files
//! are joined; a gap longer than pam-core's `MAX_STEP_S` ends a run too),
//! and held at the run's ends.

use pam_core::effects::MAX_STEP_S;

use crate::record::Sample;

/// The runs of rising time, `[start, end)`: consecutive samples whose
/// steps are in `(0, MAX_STEP_S]`.
pub fn runs(samples: &[Sample]) -> Vec<(usize, usize)> {
    let max_step = f64::from(MAX_STEP_S);
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=samples.len() {
        let breaks = i == samples.len() || {
            let dt = samples[i].t_s - samples[i - 1].t_s;
            !(dt > 0.0 && dt <= max_step)
        };
        if breaks {
            if i > start {
                out.push((start, i));
            }
            start = i;
        }
    }
    out
}

/// `values` (one per sample) at each sample's time plus `shift_s`, within
/// its run of rising time: interpolated linearly between samples, held at
/// the run's first or last value beyond its ends. A `NaN` at either
/// neighbour gives `NaN`.
pub fn shifted(samples: &[Sample], values: &[f64], shift_s: f64) -> Vec<f64> {
    let n = samples.len().min(values.len());
    let mut out = vec![f64::NAN; n];
    for (a, b) in runs(&samples[..n]) {
        // `j`: the last sample of the run at or before the target time
        // (targets rise with `i`, so it only moves forward).
        let mut j = a;
        for i in a..b {
            let target = samples[i].t_s + shift_s;
            while j + 1 < b && samples[j + 1].t_s <= target {
                j += 1;
            }
            out[i] = if target <= samples[a].t_s {
                values[a]
            } else if j + 1 >= b {
                values[b - 1]
            } else {
                let (t0, t1) = (samples[j].t_s, samples[j + 1].t_s);
                let w = ((target - t0) / (t1 - t0)).clamp(0.0, 1.0);
                values[j] + w * (values[j + 1] - values[j])
            };
        }
    }
    out
}

/// Each sample's measured pressure `delay_s` earlier ([`shifted`] by
/// `−delay_s`): the pressure the muscle answers at that sample.
pub fn delayed_pressures(samples: &[Sample], delay_s: f64) -> Vec<f64> {
    let p: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
    shifted(samples, &p, -delay_s)
}

/// The samples with each pressure replaced by the one measured `delay_s`
/// earlier ([`delayed_pressures`]): a record a static model can be fitted
/// to as if the muscle answered at once.
pub fn with_delayed_pressure(samples: &[Sample], delay_s: f64) -> Vec<Sample> {
    samples
        .iter()
        .zip(delayed_pressures(samples, delay_s))
        .map(|(s, p)| Sample {
            pressure_mpa: p,
            ..*s
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(times: &[f64]) -> Vec<Sample> {
        times
            .iter()
            .map(|&t| Sample {
                t_s: t,
                load_n: 0.0,
                pressure_mpa: 10.0 * t,
                contraction: 0.0,
            })
            .collect()
    }

    #[test]
    fn a_shift_interpolates_within_a_run_and_holds_at_its_ends() {
        // Two runs: the clock restarts at the fourth sample.
        let s = ramp(&[0.0, 0.01, 0.02, 0.0, 0.01, 0.02]);
        let p = delayed_pressures(&s, 0.005);
        let want = [0.0, 0.05, 0.15, 0.0, 0.05, 0.15];
        for (a, b) in p.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{p:?}");
        }
        let ahead = shifted(&s, &p, 0.005);
        let want = [0.025, 0.1, 0.15, 0.025, 0.1, 0.15];
        for (a, b) in ahead.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{ahead:?}");
        }
        assert_eq!(runs(&s), vec![(0, 3), (3, 6)]);
    }

    #[test]
    fn a_delay_moves_the_pressure_and_nothing_else() {
        let s = ramp(&[0.0, 0.001, 0.002, 0.003]);
        let d = with_delayed_pressure(&s, 0.002);
        assert_eq!(d.len(), 4);
        assert_eq!(d[3].t_s, 0.003);
        assert!((d[3].pressure_mpa - 0.01).abs() < 1e-12);
        assert_eq!(d[0].pressure_mpa, 0.0);
        assert!(shifted(&s, &[f64::NAN; 4], 0.001)
            .iter()
            .all(|v| v.is_nan()));
    }
}

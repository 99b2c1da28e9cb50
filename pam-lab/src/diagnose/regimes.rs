//! Branches with hindsight and the regimes the residual is located by.

use pam_core::{Branch, Coeffs, Tracker, TrackerConfig};

use crate::data::Sample;

/// Samples the pressure must stay within the tracker's deadband of a
/// sweep's extreme for [`hindsight_branches`] to treat it as a hold (1 s at
/// 50 Hz).
pub const HOLD_SAMPLES: usize = 50;

/// The branch of every sample with hindsight: the tracker's reversals
/// (deadband `tracker.direction_deadband`) moved back to the extreme of
/// the sweep they end, where the muscle really turned.
pub fn hindsight_branches(
    samples: &[Sample],
    coeffs: &Coeffs,
    tracker: TrackerConfig,
) -> Vec<Branch> {
    let n = samples.len();
    let first_load = samples.first().map_or(0.0, |s| s.load_n) as f32;
    let Ok(mut t) = Tracker::new(coeffs, tracker, first_load, Branch::Contraction) else {
        return vec![Branch::Contraction; n];
    };
    let mut out = Vec::with_capacity(n);
    let mut sweep_start = 0usize;
    let mut extreme_at = 0usize;
    for (i, s) in samples.iter().enumerate() {
        let before = t.branch();
        t.update(coeffs, s.pressure_mpa as f32, s.load_n as f32);
        if t.branch() != before {
            // The turn was where the pressure last left its extreme (within
            // a third of the deadband, the filtered noise, on a ramp). After
            // a hold (the pressure within the deadband of its extreme for at
            // least `HOLD_SAMPLES`) it is the hold's last sample: the hold's
            // noise dips below a third of the deadband often, and turning
            // at such a dip starts the other branch early, seconds before a
            // step.
            let e = samples[extreme_at].pressure_mpa;
            let band = f64::from(tracker.direction_deadband);
            let near = |j: usize, tol: f64| (samples[j].pressure_mpa - e).abs() <= tol;
            let last_in_band = (sweep_start..i).rev().find(|&j| near(j, band));
            let held = last_in_band.is_some_and(|j| {
                j >= sweep_start + HOLD_SAMPLES && (j - HOLD_SAMPLES..=j).all(|k| near(k, band))
            });
            // On a ramp the running median flattens the peak into a short
            // plateau around the true turn: take the middle of the samples
            // within a third of the deadband (the last of them turns a few
            // samples late, a one-sample spike of the branch gap).
            let turn = match last_in_band {
                Some(j) if held => j,
                _ => {
                    let last = (sweep_start..i).rev().find(|&j| near(j, band / 3.0));
                    let first = (sweep_start..i).find(|&j| near(j, band / 3.0));
                    match (first, last) {
                        (Some(a), Some(b)) => (a + b) / 2,
                        _ => extreme_at,
                    }
                }
            };
            for b in out.iter_mut().take(i).skip(turn + 1) {
                *b = t.branch();
            }
            sweep_start = i;
            extreme_at = i;
        } else {
            let p = s.pressure_mpa;
            let e = samples[extreme_at].pressure_mpa;
            let beyond = match before {
                Branch::Contraction => p > e,
                Branch::Expansion => p < e,
            };
            if beyond || extreme_at < sweep_start {
                extreme_at = i;
            }
        }
        out.push(t.branch());
    }
    out
}

/// Which regime each sample is in (they overlap).
#[derive(Clone, Debug, Default)]
pub struct Regimes {
    /// On a sweep that began at a reversal inside the loop (turning pressure
    /// between 10 % and 90 % of `Pmax`).
    pub after_inner_reversal: Vec<bool>,
    /// Pressure rate above 0.1 MPa/s (not at a step).
    pub fast_ramp: Vec<bool>,
    /// Pressure rate between 0.005 and 0.035 MPa/s.
    pub slow_ramp: Vec<bool>,
    /// Within 10 s after a pressure step while the pressure holds.
    pub hold_after_step: Vec<bool>,
}

impl Regimes {
    /// Names and masks, for reports.
    pub fn named(&self) -> [(&'static str, &Vec<bool>); 4] {
        [
            ("after_inner_reversal", &self.after_inner_reversal),
            ("fast_ramp", &self.fast_ramp),
            ("slow_ramp", &self.slow_ramp),
            ("hold_after_step", &self.hold_after_step),
        ]
    }
}

/// Label the regimes of a record from its pressure.
pub fn regimes(samples: &[Sample], coeffs: &Coeffs, tracker_cfg: TrackerConfig) -> Regimes {
    let n = samples.len();
    let p: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
    let pmax = f64::from(coeffs.params().points.max_pressure_mpa);
    let dt = if n > 1 {
        ((samples[n - 1].t_s - samples[0].t_s) / (n - 1) as f64).max(1e-6)
    } else {
        0.02
    };
    // Rate: central difference over ±0.2 s.
    let w = ((0.2 / dt).round() as usize).max(1);
    let rate: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(w), (i + w).min(n.saturating_sub(1)));
            if b > a {
                (p[b] - p[a]) / ((b - a) as f64 * dt)
            } else {
                0.0
            }
        })
        .collect();
    // Steps: the pressure moves by more than 0.05 MPa within 3 samples.
    let step: Vec<bool> = (0..n)
        .map(|i| {
            let b = (i + 3).min(n.saturating_sub(1));
            (p[b] - p[i]).abs() > 0.05 && (p[b] - p[i]).abs() / ((b - i).max(1) as f64 * dt) > 1.0
        })
        .collect();
    let mut r = Regimes {
        after_inner_reversal: vec![false; n],
        fast_ramp: vec![false; n],
        slow_ramp: vec![false; n],
        hold_after_step: vec![false; n],
    };
    let hold_len = (10.0 / dt) as usize;
    let near_step = (0.5 / dt) as usize;
    let mut since_step = usize::MAX;
    let mut since_step_any = usize::MAX;
    let mut tracker = match Tracker::new(
        coeffs,
        tracker_cfg,
        samples.first().map_or(0.0, |s| s.load_n) as f32,
        Branch::Contraction,
    ) {
        Ok(t) => t,
        Err(_) => return r,
    };
    let mut extreme = p.first().copied().unwrap_or(0.0);
    let mut inner = false;
    for i in 0..n {
        if step[i] {
            since_step = 0;
            since_step_any = 0;
        } else {
            since_step = since_step.saturating_add(1);
            since_step_any = since_step_any.saturating_add(1);
        }
        let u = tracker.update(coeffs, p[i] as f32, samples[i].load_n as f32);
        if u.branch_switch.is_some() {
            inner = extreme > 0.1 * pmax && extreme < 0.9 * pmax && since_step_any > near_step;
            extreme = p[i];
        } else {
            let beyond = match tracker.branch() {
                Branch::Contraction => p[i] > extreme,
                Branch::Expansion => p[i] < extreme,
            };
            if beyond {
                extreme = p[i];
            }
        }
        if u.load_switch.is_some() {
            inner = false;
        }
        let a = rate[i].abs();
        r.after_inner_reversal[i] = inner && since_step_any > near_step;
        r.fast_ramp[i] = a > 0.1 && since_step_any > near_step;
        r.slow_ramp[i] = a > 0.005 && a < 0.035 && since_step_any > near_step;
        if a > 0.01 && since_step > near_step {
            since_step = usize::MAX;
        }
        r.hold_after_step[i] = since_step <= hold_len && a < 0.01;
    }
    r
}

//! Branches with hindsight and the regimes the residual is located by.

use pam_core::{Branch, Coeffs, Tracker, TrackerConfig};

use crate::record::Sample;

/// Where the muscle turned within a run `a..=b` of samples whose pressure
/// stays within `band` of a sweep's extreme: at a turn (a peak of a ramp,
/// a triangle's corner, a sinusoid's smooth top, whatever the rate) the run
/// is curved, and the turn is the vertex of a parabola fitted to it; in a
/// hold the run is flat, and the muscle turns only when the pressure leaves
/// it, at the run's last sample. The run counts as curved when the fitted
/// parabola falls by at least half the band from its vertex to the run's
/// ends, the right way round for `branch` (the branch the run ends), with
/// the vertex inside the run.
///
/// Why not a time limit: a slow sinusoid stays within the band of its top
/// for longer than a short hold does (0.4 s at a 16 s period), so a fixed
/// hold duration puts the turn late at every smooth peak; the curvature
/// tells the two apart at any rate and sample rate.
fn turn_in_run(p: &[f64], a: usize, b: usize, band: f64, branch: Branch) -> usize {
    if b <= a + 3 {
        return (a + b) / 2;
    }
    let mid = 0.5 * (a + b) as f64;
    // Least squares of p = c0 + c1·t + c2·t², t in samples from the middle.
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut v = nalgebra::Vector3::<f64>::zeros();
    for (j, &pj) in p.iter().enumerate().take(b + 1).skip(a) {
        let t = j as f64 - mid;
        let basis = nalgebra::Vector3::new(1.0, t, t * t);
        m += basis * basis.transpose();
        v += basis * pj;
    }
    let Some(c) = m.lu().solve(&v) else {
        return b;
    };
    let half = 0.5 * (b - a) as f64;
    let drop = c[2].abs() * half * half;
    // A maximum ends a contraction sweep (the next branch is expansion).
    let right_way = match branch {
        Branch::Expansion => c[2] < 0.0,
        Branch::Contraction => c[2] > 0.0,
    };
    let vertex = mid - c[1] / (2.0 * c[2]);
    if right_way && drop >= 0.5 * band && vertex >= a as f64 && vertex <= b as f64 {
        vertex.round() as usize
    } else {
        b
    }
}

/// How far from the turn found from the pressure [`hindsight_branches`]
/// looks for the measured contraction's jump, s.
pub const JUMP_SEARCH_S: f64 = 0.06;

/// The sample before the largest significant contraction step the right way
/// for a switch onto `to` within [`JUMP_SEARCH_S`] of `turn` (and inside
/// `lo..hi`), if any.
fn jump_near(
    samples: &[Sample],
    turn: usize,
    lo: usize,
    hi: usize,
    to: Branch,
    noise: f64,
) -> Option<usize> {
    if noise.is_nan() || noise <= 0.0 || hi < 2 {
        return None;
    }
    let dt = samples
        .get(turn + 1)
        .zip(samples.get(turn))
        .map_or(0.02, |(b, a)| (b.t_s - a.t_s).abs().max(1e-4));
    let w = ((JUMP_SEARCH_S / dt).round() as usize).max(2);
    let (a, b) = (turn.saturating_sub(w).max(lo), (turn + w).min(hi - 1));
    let sign = match to {
        Branch::Expansion => 1.0,
        Branch::Contraction => -1.0,
    };
    (a..b)
        .map(|j| {
            (
                j,
                sign * (samples[j + 1].contraction - samples[j].contraction),
            )
        })
        .filter(|(_, d)| *d > 6.0 * noise)
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .map(|(j, _)| j)
}

/// The branch of every sample with hindsight: the tracker's reversals
/// (deadband `tracker.direction_deadband`) moved back to the extreme of
/// the sweep they end, where the muscle really turned.
///
/// Where the measured contraction shows the jump the paper's model makes at
/// a switch — a step between two samples larger than six noise sigmas
/// (`contraction_noise`), the right way for the branch it switches to
/// (up onto the expansion branch, down onto the contraction branch),
/// within `JUMP_SEARCH_S` of the turn found from the pressure — the
/// switch is put at that step: the pressure noise alone places a turn a
/// few samples either way, and on a steep muscle every sample on the wrong
/// branch is an error of the whole branch gap.
pub fn hindsight_branches(
    samples: &[Sample],
    coeffs: &Coeffs,
    tracker: TrackerConfig,
    contraction_noise: f64,
) -> Vec<Branch> {
    let n = samples.len();
    let first_load = samples.first().map_or(0.0, |s| s.load_n) as f32;
    let Ok(mut t) = Tracker::new(coeffs, tracker, first_load, Branch::Contraction) else {
        return vec![Branch::Contraction; n];
    };
    let pressure: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
    let mut out = Vec::with_capacity(n);
    let mut sweep_start = 0usize;
    let mut extreme_at = 0usize;
    for (i, s) in samples.iter().enumerate() {
        let before = t.branch();
        t.update(coeffs, s.pressure_mpa as f32, s.load_n as f32);
        if t.branch() != before {
            // The samples within the deadband of the sweep's extreme (the
            // median-filtered noise stays inside it) around its last visit:
            // where the muscle turned is in that run (`turn_in_run`).
            let e = samples[extreme_at].pressure_mpa;
            let band = f64::from(tracker.direction_deadband);
            let near = |j: usize| (samples[j].pressure_mpa - e).abs() <= band;
            let turn = match (sweep_start..i).rev().find(|&j| near(j)) {
                Some(last) => {
                    let mut first = last.min(extreme_at);
                    while first > sweep_start && near(first - 1) {
                        first -= 1;
                    }
                    turn_in_run(&pressure, first, last, band, t.branch())
                }
                None => extreme_at,
            };
            let turn = jump_near(samples, turn, sweep_start, i, t.branch(), contraction_noise)
                .unwrap_or(turn);
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
    /// Pressure rate above 0.1 MPa/s, steps included: where a delay of
    /// the muscle behind its pressure shows (its error is the rate times
    /// the delay, largest at a step).
    pub pressure_moving: Vec<bool>,
    /// Pressure rate between 0.005 and 0.035 MPa/s.
    pub slow_ramp: Vec<bool>,
    /// Within 10 s after a pressure step while the pressure holds.
    pub hold_after_step: Vec<bool>,
    /// The fastest ramp of the record, MPa/s: the largest pressure rate
    /// (over ±0.2 s) at least 0.5 s away from any step. A rate law fitted
    /// to the record saturates here, so it cannot widen a loop beyond what
    /// the record shows.
    pub max_ramp_rate_mpa_per_s: f64,
}

impl Regimes {
    /// Names and masks, for reports.
    pub fn named(&self) -> [(&'static str, &Vec<bool>); 5] {
        [
            ("after_inner_reversal", &self.after_inner_reversal),
            ("fast_ramp", &self.fast_ramp),
            ("pressure_moving", &self.pressure_moving),
            ("slow_ramp", &self.slow_ramp),
            ("hold_after_step", &self.hold_after_step),
        ]
    }
}

/// The largest `|rate|` at samples farther than `margin` samples from any
/// step (either side: the rate window reaches ahead of the sample).
fn max_ramp_rate(rate: &[f64], step: &[bool], margin: usize) -> f64 {
    let n = rate.len();
    let mut last_step: Option<usize> = None;
    let mut next_step: Vec<Option<usize>> = vec![None; n];
    let mut next = None;
    for i in (0..n).rev() {
        if step[i] {
            next = Some(i);
        }
        next_step[i] = next;
    }
    let mut top = 0.0f64;
    for i in 0..n {
        if step[i] {
            last_step = Some(i);
        }
        let far_behind = last_step.is_none_or(|s| i - s > margin);
        let far_ahead = next_step[i].is_none_or(|s| s - i > margin);
        if far_behind && far_ahead && rate[i].is_finite() {
            top = top.max(rate[i].abs());
        }
    }
    top
}

/// The sample period, the pressure rate (central difference over ±0.2 s)
/// and the steps (the pressure moves by more than 0.05 MPa within 3
/// samples, faster than 1 MPa/s) of a record.
struct PressureMotion {
    dt_s: f64,
    rate_window: usize,
    rate_mpa_per_s: Vec<f64>,
    step: Vec<bool>,
}

fn pressure_motion(samples: &[Sample]) -> PressureMotion {
    let n = samples.len();
    let p: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
    let dt = if n > 1 {
        ((samples[n - 1].t_s - samples[0].t_s) / (n - 1) as f64).max(1e-6)
    } else {
        0.02
    };
    let w = ((0.2 / dt).round() as usize).max(1);
    let rate = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(w), (i + w).min(n.saturating_sub(1)));
            if b > a {
                (p[b] - p[a]) / ((b - a) as f64 * dt)
            } else {
                0.0
            }
        })
        .collect();
    let step = (0..n)
        .map(|i| {
            let b = (i + 3).min(n.saturating_sub(1));
            (p[b] - p[i]).abs() > 0.05 && (p[b] - p[i]).abs() / ((b - i).max(1) as f64 * dt) > 1.0
        })
        .collect();
    PressureMotion {
        dt_s: dt,
        rate_window: w,
        rate_mpa_per_s: rate,
        step,
    }
}

/// The regimes that the pressure alone decides (fast and slow ramps, holds
/// after a step, the fastest ramp); `after_inner_reversal` is left empty
/// (all false): it needs the model's tracker, see [`regimes`]. Known before
/// any fit, so the hold-out can make sure each of them is held out too
/// ([`crate::record::split::cover_regime`]).
pub fn pressure_regimes(samples: &[Sample]) -> Regimes {
    pressure_regimes_of(samples, &pressure_motion(samples))
}

/// [`pressure_regimes`] from the record's motion `m`
/// ([`pressure_motion`] of `samples`).
fn pressure_regimes_of(samples: &[Sample], m: &PressureMotion) -> Regimes {
    let n = samples.len();
    let dt = m.dt_s;
    let mut r = Regimes {
        after_inner_reversal: vec![false; n],
        fast_ramp: vec![false; n],
        pressure_moving: vec![false; n],
        slow_ramp: vec![false; n],
        hold_after_step: vec![false; n],
        max_ramp_rate_mpa_per_s: max_ramp_rate(
            &m.rate_mpa_per_s,
            &m.step,
            (0.5 / dt) as usize + m.rate_window + 3,
        ),
    };
    let hold_len = (10.0 / dt) as usize;
    let near_step = (0.5 / dt) as usize;
    let mut since_step = usize::MAX;
    let mut since_step_any = usize::MAX;
    for i in 0..n {
        if m.step[i] {
            since_step = 0;
            since_step_any = 0;
        } else {
            since_step = since_step.saturating_add(1);
            since_step_any = since_step_any.saturating_add(1);
        }
        let a = m.rate_mpa_per_s[i].abs();
        r.fast_ramp[i] = a > 0.1 && since_step_any > near_step;
        r.pressure_moving[i] = a > 0.1 || m.step[i];
        r.slow_ramp[i] = a > 0.005 && a < 0.035 && since_step_any > near_step;
        if a > 0.01 && since_step > near_step {
            since_step = usize::MAX;
        }
        r.hold_after_step[i] = since_step <= hold_len && a < 0.01;
    }
    r
}

/// Label the regimes of a record from its pressure: [`pressure_regimes`],
/// and the sweeps after a reversal inside the loop from `coeffs`' tracker.
pub fn regimes(samples: &[Sample], coeffs: &Coeffs, tracker_cfg: TrackerConfig) -> Regimes {
    let n = samples.len();
    let m = pressure_motion(samples);
    let mut r = pressure_regimes_of(samples, &m);
    let p: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
    let pmax = f64::from(coeffs.params().points.max_pressure_mpa);
    let near_step = (0.5 / m.dt_s) as usize;
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
        if m.step[i] {
            since_step_any = 0;
        } else {
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
        r.after_inner_reversal[i] = inner && since_step_any > near_step;
    }
    r
}

//! `pam-lab diagnose`: find where the paper's model and a measurement
//! disagree, name the missing effect, add it, and show the gap shrink.
//!
//! # Workflow
//! 1. **Split.** The record is cut into load blocks (runs of one load). Odd
//!    blocks are held out, even blocks train ([`holdout_by_load_block`]): with
//!    the examples' protocol that trains on the 100 N and 300 N blocks and
//!    holds out the 200 N block, so every regime (full and partial cycles,
//!    three rates, steps and holds) is in both parts.
//! 2. **Base model.** The paper's model is fitted on the training part with
//!    [`crate::fit::fit`], then the whole record is simulated from the
//!    measured pressure and load with [`pam_core::Simulator`] (state carries
//!    through the held-out parts), and the residual is located by regime
//!    ([`Regimes`]: after reversals inside the loop, fast ramps, slow ramps,
//!    holds after steps, and per load).
//! 3. **Candidates.** Each effect of [`EffectKind`] is added in turn and only
//!    its own parameters are fitted (Levenberg–Marquardt on the training
//!    samples' contraction residuals, the base parameters fixed, a few
//!    starts).
//! 4. **Evidence rule.** A candidate earns its place when *both*
//!    * its held-out RMS is at least [`DiagnoseConfig::min_improvement`]
//!      (default 15 %) below the current model's, and
//!    * its BIC on the training part, counted over the effective number of
//!      independent residuals (`n / τ`, `τ` the residual's correlation length
//!      in samples), falls by at least [`DiagnoseConfig::min_bic_drop`]
//!      (default 10, "very strong" on the usual scale), and
//!    * its held-out RMS in its own regime (its *signature*: after inner
//!      reversals for the memory, fast ramps for the rate, holds after steps
//!      for creep, the worst load for the width) is cut by at least the same
//!      fraction — a candidate that only helps elsewhere is absorbing some
//!      other misfit, not showing its effect.
//!
//!    Of those that earn it, the one with the lowest held-out RMS is added;
//!    then the remaining candidates are tried on top of it, until none earns
//!    its parameters or [`DiagnoseConfig::max_effects`] are in. No candidate
//!    earning it is the answer `none`.

use std::path::Path;

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use pam_core::effects::memory::MIN_MERGE_SPAN;
use pam_core::effects::rate::RATE_EXPONENT_RANGE;
use pam_core::effects::{Creep, LoadDependentWidth, NonLocalMemory, RateDependence};
use pam_core::{Branch, Coeffs, Effects, Params, Simulator, Tracker, TrackerConfig};
use serde::Serialize;

use crate::data::{Record, Sample};
use crate::fit::{FitConfig, Holdout};

/// Capacity of the reversal memory the diagnosis simulates with.
pub const MEMORY_DEPTH: usize = 16;

/// A candidate effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    /// Minor loops with wiping-out ([`NonLocalMemory`]).
    NonLocalMemory,
    /// Loop height growing with the pressure rate ([`RateDependence`]).
    RateDependence,
    /// Slow relaxation after steps ([`Creep`]).
    Creep,
    /// Loop height linear in load ([`LoadDependentWidth`]).
    LoadDependentWidth,
}

impl EffectKind {
    /// Every candidate, in the order they are tried.
    pub const ALL: [EffectKind; 4] = [
        EffectKind::NonLocalMemory,
        EffectKind::RateDependence,
        EffectKind::Creep,
        EffectKind::LoadDependentWidth,
    ];

    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::NonLocalMemory => "non_local_memory",
            EffectKind::RateDependence => "rate_dependence",
            EffectKind::Creep => "creep",
            EffectKind::LoadDependentWidth => "load_dependent_width",
        }
    }

    /// Number of parameters the effect adds (the rate's exponent, chosen
    /// from [`RATE_EXPONENTS`] by the fit, counts as one).
    pub fn parameter_count(self) -> usize {
        match self {
            EffectKind::RateDependence => 4,
            _ => 2,
        }
    }

    /// How many leading entries of `theta` the optimiser moves; the rest
    /// (the rate's exponent) are fixed per start.
    fn free_count(self) -> usize {
        match self {
            EffectKind::RateDependence => 3,
            _ => 2,
        }
    }

    /// The regime where its signature should show.
    pub fn regime(self) -> &'static str {
        match self {
            EffectKind::NonLocalMemory => "after_inner_reversal",
            EffectKind::RateDependence => "fast_ramp",
            EffectKind::Creep => "hold_after_step",
            EffectKind::LoadDependentWidth => "per_load",
        }
    }

    /// Starting points of the fit, in the unbounded coordinates of
    /// [`Self::apply`].
    fn starts(self) -> Vec<Vec<f64>> {
        match self {
            // A rescaled branch that merges within 0.03 of contraction, and
            // a quicker blend that is not limited.
            EffectKind::NonLocalMemory => vec![
                vec![MEMORY_SHAPE.theta(1.0), MERGE_SPAN.theta(0.03)],
                vec![MEMORY_SHAPE.theta(5.0), MERGE_SPAN.theta(0.5)],
            ],
            // One start per exponent: factor 1 at rest, 5 per (MPa/s)^n,
            // a 0.2 s filter.
            EffectKind::RateDependence => RATE_EXPONENTS
                .iter()
                .map(|&n| {
                    vec![
                        logit(1.0 / 4.0),
                        logit(5.0 / 100.0),
                        rate_filter_theta(0.2),
                        n,
                    ]
                })
                .collect(),
            EffectKind::Creep => vec![
                vec![logit(0.1 / 0.95), 1.0f64.ln()],
                vec![logit(0.1 / 0.95), 5.0f64.ln()],
            ],
            EffectKind::LoadDependentWidth => vec![vec![logit(1.0 / 4.0), 0.0]],
        }
    }

    /// `effects` with this effect on, its parameters from unbounded `theta`
    /// (logistic and exponential maps keep them inside their validation
    /// ranges, so the optimiser needs no bounds).
    pub fn apply(self, effects: Effects, theta: &[f64]) -> Effects {
        let t = |i: usize| theta.get(i).copied().unwrap_or(0.0);
        let mut e = effects;
        match self {
            EffectKind::NonLocalMemory => {
                e.memory = Some(NonLocalMemory {
                    shape: MEMORY_SHAPE.value(t(0)) as f32,
                    merge_span: MERGE_SPAN.value(t(1)) as f32,
                })
            }
            EffectKind::RateDependence => {
                let (n_lo, n_hi) = RATE_EXPONENT_RANGE;
                let exponent = match theta.get(3) {
                    Some(n) if n.is_finite() => (*n as f32).clamp(n_lo, n_hi),
                    _ => 1.0,
                };
                e.rate = Some(RateDependence {
                    scale_at_rest: (4.0 * sigmoid(t(0))) as f32,
                    scale_per_mpa_per_s: (100.0 * sigmoid(t(1))) as f32,
                    exponent,
                    filter_time_s: rate_filter_time(t(2)) as f32,
                })
            }
            EffectKind::Creep => {
                e.creep = Some(Creep {
                    gain: (0.95 * sigmoid(t(0))) as f32,
                    time_constant_s: t(1).exp().clamp(0.02, 100.0) as f32,
                })
            }
            EffectKind::LoadDependentWidth => {
                e.width = Some(LoadDependentWidth {
                    scale_at_min_load: (4.0 * sigmoid(t(0))) as f32,
                    scale_per_step: (4.0 * t(1).tanh()) as f32,
                })
            }
        }
        e
    }

    fn is_on(self, e: &Effects) -> bool {
        match self {
            EffectKind::NonLocalMemory => e.memory.is_some(),
            EffectKind::RateDependence => e.rate.is_some(),
            EffectKind::Creep => e.creep.is_some(),
            EffectKind::LoadDependentWidth => e.width.is_some(),
        }
    }
}

/// Exponents of the rate law the diagnosis tries: the ones pam-core
/// evaluates with square roots (`powf` is a software routine on the M4).
pub const RATE_EXPONENTS: [f64; 3] = [0.5, 0.75, 1.0];

/// The rate filter's time constant from its unbounded coordinate: logistic
/// over `[0.02, 1]` s.
fn rate_filter_time(theta: f64) -> f64 {
    (0.02 + 0.98 * sigmoid(theta)).clamp(0.02, 1.0)
}

fn rate_filter_theta(tau: f64) -> f64 {
    logit((tau - 0.02) / 0.98)
}

/// A logarithmic range `[lo, lo·ratio]` (clamped to `[lo, hi]`) mapped from
/// an unbounded coordinate: `lo·ratio^sigmoid(θ)`.
#[derive(Clone, Copy)]
struct LogRange {
    lo: f64,
    ratio: f64,
    hi: f64,
}

impl LogRange {
    fn value(self, theta: f64) -> f64 {
        (self.lo * self.ratio.powf(sigmoid(theta))).clamp(self.lo, self.hi)
    }

    fn theta(self, value: f64) -> f64 {
        logit((value / self.lo).ln() / self.ratio.ln())
    }
}

/// The memory's `k`: logarithmic over `[0.05, 50]` (the blend is symmetric
/// in `ln k`).
const MEMORY_SHAPE: LogRange = LogRange {
    lo: 0.05,
    ratio: 1000.0,
    hi: 50.0,
};

/// The memory's merge span: logarithmic over `[MIN_MERGE_SPAN, 1]`.
const MERGE_SPAN: LogRange = LogRange {
    lo: MIN_MERGE_SPAN as f64,
    ratio: 1.0 / (MIN_MERGE_SPAN as f64),
    hi: 1.0,
};

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

/// Settings of the diagnosis.
#[derive(Clone, Debug)]
pub struct DiagnoseConfig {
    /// Settings of the base fit (its `holdout` is overridden: the diagnosis
    /// fits on its own training part).
    pub fit: FitConfig,
    /// Smallest relative cut of the held-out RMS for a candidate to count.
    pub min_improvement: f64,
    /// Smallest fall of the effective-sample BIC for a candidate to count.
    pub min_bic_drop: f64,
    /// Most effects added.
    pub max_effects: usize,
    /// Iteration budget of each candidate's optimiser (LM patience).
    pub patience: usize,
    /// Damped Gauss–Newton iterations of the joint base refit
    /// ([`BASE_REFIT_FIELDS`]); 0 keeps `fit::fit`'s base.
    pub refit_iterations: usize,
}

impl Default for DiagnoseConfig {
    fn default() -> Self {
        DiagnoseConfig {
            fit: FitConfig::default(),
            min_improvement: 0.15,
            min_bic_drop: 10.0,
            max_effects: 2,
            patience: 8,
            refit_iterations: 3,
        }
    }
}

/// Held-out mask: load blocks (runs of one load, within 1 N) alternate
/// training (even) and held out (odd). A record of one load block holds out
/// its last 30 %.
pub fn holdout_by_load_block(samples: &[Sample]) -> Vec<bool> {
    let mut block = 0usize;
    let mut out = Vec::with_capacity(samples.len());
    let mut last = samples.first().map_or(0.0, |s| s.load_n);
    for s in samples {
        if (s.load_n - last).abs() > 1.0 {
            block += 1;
            last = s.load_n;
        }
        out.push(block % 2 == 1);
    }
    if block == 0 {
        let first = (samples.len() as f64 * 0.7) as usize;
        return (0..samples.len()).map(|i| i >= first).collect();
    }
    out
}

/// Half-width of the centred running median applied to the measured
/// pressure before it drives the simulation, samples.
///
/// Why: where the muscle's curve is flat (around the inflection point) the
/// contraction moves by 10–20 per MPa, so 0.001 MPa of sensor noise becomes
/// 0.01–0.02 of simulated contraction, which would swamp every effect. A
/// median (unlike a mean) keeps pressure steps sharp, so it does not fake a
/// creep or a lag.
pub const PRESSURE_MEDIAN_HALF_WIDTH: usize = 4;

/// `samples` with the pressure through a centred running median of
/// `2·half + 1` samples (shrinking at the ends).
pub fn denoise_pressure(samples: &[Sample], half: usize) -> Vec<Sample> {
    let n = samples.len();
    let mut window = Vec::with_capacity(2 * half + 1);
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half).min(n - 1));
            window.clear();
            window.extend(samples[a..=b].iter().map(|s| s.pressure_mpa));
            window.sort_by(f64::total_cmp);
            let mut s = samples[i];
            s.pressure_mpa = window[window.len() / 2];
            s
        })
        .collect()
}

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

/// Simulate the model (base `coeffs` plus `effects`) over `samples` from the
/// measured pressure and load, on the given branches (see
/// [`hindsight_branches`]); one predicted contraction per sample.
pub fn simulate(
    coeffs: &Coeffs,
    effects: Effects,
    tracker: TrackerConfig,
    samples: &[Sample],
    branches: &[Branch],
) -> Vec<f64> {
    let first_load = samples.first().map_or(0.0, |s| s.load_n) as f32;
    let Ok(mut sim) = Simulator::<MEMORY_DEPTH>::new(*coeffs, effects, tracker, first_load) else {
        return vec![f64::NAN; samples.len()];
    };
    samples
        .iter()
        .zip(branches)
        .map(|(s, &b)| {
            f64::from(sim.step_on_branch(s.t_s as f32, s.pressure_mpa as f32, s.load_n as f32, b))
        })
        .collect()
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

fn rms_where(res: &[f64], mask: impl Fn(usize) -> bool) -> (f64, usize) {
    let (mut s, mut k) = (0.0, 0usize);
    for (i, r) in res.iter().enumerate() {
        if mask(i) && r.is_finite() {
            s += r * r;
            k += 1;
        }
    }
    if k == 0 {
        (f64::NAN, 0)
    } else {
        ((s / k as f64).sqrt(), k)
    }
}

/// Correlation length of a residual series, samples: the first lag at which
/// its autocorrelation falls below `1/e` (at least 1, at most 500).
pub fn correlation_length(res: &[f64]) -> f64 {
    let n = res.len();
    if n < 4 {
        return 1.0;
    }
    let mean = res.iter().sum::<f64>() / n as f64;
    let var: f64 = res.iter().map(|r| (r - mean) * (r - mean)).sum::<f64>();
    if var.is_nan() || var <= 0.0 {
        return 1.0;
    }
    for lag in 1..500.min(n - 1) {
        let c: f64 = (0..n - lag)
            .map(|i| (res[i] - mean) * (res[i + lag] - mean))
            .sum();
        if c / var < (-1.0f64).exp() {
            return lag as f64;
        }
    }
    500.0
}

/// Errors of one model.
#[derive(Clone, Debug, Serialize)]
pub struct ModelErrors {
    /// Held-out RMS contraction error.
    pub rms_heldout: f64,
    /// Training RMS contraction error.
    pub rms_train: f64,
    /// BIC over the effective number of independent training residuals.
    pub bic: f64,
    /// Held-out RMS per regime.
    pub regimes: Vec<RegimeError>,
    /// Held-out RMS per load.
    pub loads: Vec<LoadError>,
}

/// RMS in one regime.
#[derive(Clone, Debug, Serialize)]
pub struct RegimeError {
    /// Regime name.
    pub regime: String,
    /// Held-out samples in it.
    pub samples: usize,
    /// Held-out RMS contraction error.
    pub rms: f64,
}

/// RMS at one load.
#[derive(Clone, Debug, Serialize)]
pub struct LoadError {
    /// Load, N.
    pub load_n: f64,
    /// Held-out samples at it.
    pub samples: usize,
    /// Held-out RMS contraction error.
    pub rms: f64,
}

/// What is shared by every evaluation of one record.
struct Setup<'a> {
    samples: &'a [Sample],
    coeffs: Coeffs,
    tracker: TrackerConfig,
    heldout: Vec<bool>,
    train_idx: Vec<usize>,
    regimes: Regimes,
    branches: Vec<Branch>,
    /// Effective-sample divisor: the base residual's correlation length.
    corr_len: f64,
}

impl Setup<'_> {
    fn residuals(&self, effects: Effects) -> Vec<f64> {
        self.residuals_with(&self.coeffs, effects)
    }

    fn residuals_with(&self, coeffs: &Coeffs, effects: Effects) -> Vec<f64> {
        simulate(coeffs, effects, self.tracker, self.samples, &self.branches)
            .iter()
            .zip(self.samples)
            .map(|(x, s)| s.contraction - x)
            .collect()
    }

    fn errors(
        &self,
        coeffs: &Coeffs,
        effects: Effects,
        n_params: usize,
    ) -> (ModelErrors, Vec<f64>) {
        let res = self.residuals_with(coeffs, effects);
        let (rms_heldout, _) = rms_where(&res, |i| self.heldout[i]);
        let (rms_train, n_train) = rms_where(&res, |i| !self.heldout[i]);
        let n_eff = (n_train as f64 / self.corr_len).max(1.0);
        let bic = n_eff * (rms_train * rms_train).max(1e-300).ln() + n_params as f64 * n_eff.ln();
        let regimes = self
            .regimes
            .named()
            .iter()
            .map(|(name, mask)| {
                let (rms, samples) = rms_where(&res, |i| self.heldout[i] && mask[i]);
                RegimeError {
                    regime: name.to_string(),
                    samples,
                    rms,
                }
            })
            .collect();
        let mut loads: Vec<f64> = self
            .samples
            .iter()
            .zip(&self.heldout)
            .filter(|(_, h)| **h)
            .map(|(s, _)| s.load_n.round())
            .collect();
        loads.sort_by(f64::total_cmp);
        loads.dedup();
        let loads = loads
            .into_iter()
            .map(|l| {
                let (rms, samples) = rms_where(&res, |i| {
                    self.heldout[i] && self.samples[i].load_n.round() == l
                });
                LoadError {
                    load_n: l,
                    samples,
                    rms,
                }
            })
            .collect();
        (
            ModelErrors {
                rms_heldout,
                rms_train,
                bic,
                regimes,
                loads,
            },
            res,
        )
    }
}

/// Fitting one candidate's parameters: residuals on the training samples.
struct CandidateProblem<'s, 'a> {
    setup: &'s Setup<'a>,
    coeffs: Coeffs,
    kind: EffectKind,
    base: Effects,
    /// The parameters the optimiser moves.
    theta: DVector<f64>,
    /// The ones it does not (appended to `theta` for [`EffectKind::apply`]).
    fixed: Vec<f64>,
}

impl CandidateProblem<'_, '_> {
    fn full(&self, theta: &[f64]) -> Vec<f64> {
        theta.iter().chain(&self.fixed).copied().collect()
    }

    fn residuals_at(&self, theta: &[f64]) -> DVector<f64> {
        let res = self
            .setup
            .residuals_with(&self.coeffs, self.kind.apply(self.base, &self.full(theta)));
        DVector::from_iterator(
            self.setup.train_idx.len(),
            self.setup.train_idx.iter().map(|&i| res[i]),
        )
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for CandidateProblem<'_, '_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.theta.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let r = self.residuals_at(self.theta.as_slice());
        r.iter().all(|v| v.is_finite()).then_some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        // Forward differences, one simulation per parameter, in parallel.
        let base = self.residuals_at(self.theta.as_slice());
        let k = self.theta.len();
        let h: Vec<f64> = (0..k).map(|j| 1e-3 * (1.0 + self.theta[j].abs())).collect();
        let cols: Vec<DVector<f64>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..k)
                .map(|j| {
                    let mut t = self.theta.as_slice().to_vec();
                    t[j] += h[j];
                    let me = &*self;
                    s.spawn(move || me.residuals_at(&t))
                })
                .collect();
            handles
                .into_iter()
                .map(|hd| hd.join().unwrap_or_else(|_| DVector::zeros(0)))
                .collect()
        });
        let mut jac = DMatrix::zeros(base.len(), k);
        for (j, col) in cols.iter().enumerate() {
            if col.len() != base.len() {
                return None;
            }
            jac.set_column(j, &((col - &base) / h[j]));
        }
        jac.iter().all(|v| v.is_finite()).then_some(jac)
    }
}

/// One candidate's result in one round.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateResult {
    /// Effect name.
    pub name: &'static str,
    /// Held-out RMS with the effect added to the current model.
    pub rms: f64,
    /// Relative cut of the held-out RMS against the current model.
    pub improvement: f64,
    /// Fall of the BIC against the current model (positive is better).
    pub bic_drop: f64,
    /// Parameters added.
    pub parameters: usize,
    /// Whether it met the evidence rule.
    pub earned: bool,
    /// Held-out RMS in the effect's own regime, before and after.
    pub signature: Signature,
    /// The fitted effects of the candidate model.
    pub effects: Effects,
    /// Full error breakdown.
    pub errors: ModelErrors,
    /// The base parameters refitted with the candidate on.
    pub base_params: Params,
    /// Their coefficients (not serialised).
    #[serde(skip)]
    pub coeffs: Coeffs,
}

/// Whether the improvement sits in the regime the effect explains.
#[derive(Clone, Debug, Serialize)]
pub struct Signature {
    /// The regime.
    pub regime: &'static str,
    /// Held-out RMS there with the current model.
    pub rms_before: f64,
    /// Held-out RMS there with the candidate.
    pub rms_after: f64,
}

/// One round of candidate selection.
#[derive(Clone, Debug, Serialize)]
pub struct Round {
    /// Held-out RMS of the model the round started from.
    pub rms_start: f64,
    /// Every candidate tried.
    pub candidates: Vec<CandidateResult>,
    /// The effect added, if any earned it.
    pub added: Option<&'static str>,
}

/// The outcome of a diagnosis.
#[derive(Clone, Debug, Serialize)]
pub struct DiagnoseReport {
    /// The record diagnosed.
    pub source: String,
    /// Effects added, in order (empty: `none`).
    pub effects_added: Vec<&'static str>,
    /// What was named: the first effect added, or `none`.
    pub named: &'static str,
    /// Held-out RMS contraction error of the base model.
    pub rms_before: f64,
    /// The same after the additions.
    pub rms_after: f64,
    /// First round's candidates against the base model: name and held-out RMS.
    pub candidates: Vec<CandidateSummary>,
    /// Every round in full.
    pub rounds: Vec<Round>,
    /// The base model's errors.
    pub base: ModelErrors,
    /// The final model's errors.
    pub after: ModelErrors,
    /// Held-out RMS of the paper's model as `fit::fit` gives it, before the
    /// base refit on the simulated record.
    pub rms_paper_fit: f64,
    /// The base model's parameters (after its refit).
    pub base_params: Params,
    /// The final model's base parameters (refitted jointly with its effects).
    pub final_params: Params,
    /// The final model's effects.
    pub effects: Effects,
    /// Samples held out and trained on.
    pub heldout_samples: usize,
    /// Training samples.
    pub train_samples: usize,
    /// Correlation length of the base residual, samples.
    pub correlation_length: f64,
    /// The evidence rule's thresholds.
    pub min_improvement: f64,
    /// BIC threshold.
    pub min_bic_drop: f64,
    /// Predicted contraction of the base and final models (not serialised).
    #[serde(skip)]
    pub predicted_base: Vec<f64>,
    /// Final model prediction (not serialised).
    #[serde(skip)]
    pub predicted_after: Vec<f64>,
    /// Held-out mask (not serialised).
    #[serde(skip)]
    pub heldout: Vec<bool>,
    /// Regimes (not serialised).
    #[serde(skip)]
    pub regimes: Regimes,
}

/// A candidate's name and held-out RMS (first round).
#[derive(Clone, Debug, Serialize)]
pub struct CandidateSummary {
    /// Effect name.
    pub name: &'static str,
    /// Held-out RMS contraction error with it added to the base model.
    pub rms: f64,
}

/// Why a diagnosis failed.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// The base fit failed.
    #[error("base fit: {0}")]
    Fit(#[from] crate::fit::FitError),
    /// Too little data.
    #[error("{0}")]
    Data(String),
}

/// Tracker settings for the denoised pressure of a record whose raw
/// pressure noise is `noise_mpa` and load noise `load_noise_n`: a deadband
/// of three raw sigmas (the median leaves about 0.4 of the noise, so its
/// peak-to-peak stays inside), at least 0.002 MPa. A wider band delays every
/// reversal, which where the curve is flat costs more than the noise it
/// rejects.
///
/// The controller debounces a load change over several samples because its
/// load cell is noisy; a record whose load column is clean (the rig's set
/// load, held then stepped: noise below 1 N) switches the load model on the
/// first sample of a step, as the muscle does. Otherwise every load step
/// would leave a few samples on the old load's curve, a residual spike that
/// no effect explains.
fn tracker_config(noise_mpa: f64, load_noise_n: f64) -> TrackerConfig {
    let mut cfg = TrackerConfig::DEFAULT_PRESSURE;
    cfg.direction_deadband = (3.0 * noise_mpa).max(0.002) as f32;
    if load_noise_n < 1.0 {
        cfg.load_debounce_samples = 1;
    }
    cfg
}

/// Run the diagnosis on `record`.
pub fn diagnose(record: &Record, cfg: &DiagnoseConfig) -> Result<DiagnoseReport, DiagnoseError> {
    let samples = &record.samples;
    if samples.len() < 100 {
        return Err(DiagnoseError::Data(format!(
            "{}: {} samples, need at least 100",
            record.source,
            samples.len()
        )));
    }
    let denoised = denoise_pressure(samples, PRESSURE_MEDIAN_HALF_WIDTH);
    let samples = &denoised;
    let heldout = holdout_by_load_block(samples);
    let keep = |i: &usize| !heldout[*i];
    let train_record = Record {
        source: format!("{} (training part)", record.source),
        samples: (0..samples.len())
            .filter(keep)
            .map(|i| record.samples[i])
            .collect(),
        lines: (0..samples.len())
            .filter(keep)
            .map(|i| record.line(i))
            .collect(),
    };
    let mut fit_cfg = cfg.fit.clone();
    fit_cfg.holdout = Holdout::None;
    let fit = crate::fit::fit(&train_record, &fit_cfg)?;
    // The held-out blocks may go beyond the training loads (the examples'
    // random loads reach 350 N, the training blocks 300 N): widen the
    // calibrated range to the record's so the load family extrapolates
    // linearly (eqs. 17–19) instead of clamping, when the shape stays valid.
    let record_max_load = samples.iter().map(|s| s.load_n).fold(0.0f64, f64::max) as f32;
    let mut base_params = fit.params;
    let coeffs = if record_max_load > base_params.max_load_n {
        base_params.max_load_n = record_max_load;
        match Coeffs::new(base_params) {
            Ok(c) => c,
            Err(_) => {
                base_params = fit.params;
                fit.coeffs
            }
        }
    } else {
        fit.coeffs
    };
    let tracker = tracker_config(
        crate::split::noise_std(record.samples.iter().map(|s| s.pressure_mpa)),
        crate::split::noise_std(record.samples.iter().map(|s| s.load_n)),
    );
    let train_idx: Vec<usize> = (0..samples.len()).filter(|&i| !heldout[i]).collect();
    let regimes = regimes(samples, &coeffs, tracker);
    let branches = hindsight_branches(samples, &coeffs, tracker);
    let mut setup = Setup {
        samples,
        coeffs,
        tracker,
        heldout,
        train_idx,
        regimes,
        branches,
        corr_len: 1.0,
    };
    let base_res = setup.residuals(Effects::NONE);
    let train_res: Vec<f64> = setup.train_idx.iter().map(|&i| base_res[i]).collect();
    setup.corr_len = correlation_length(&train_res);
    let (paper_errors, _) = setup.errors(&setup.coeffs, Effects::NONE, 0);
    // The base the effects are judged against: the paper's model refitted
    // on the simulated training record by the same joint refit every
    // candidate gets, so that a candidate's gain is the effect's, not the
    // refit's.
    let (mut model_params, mut model_coeffs) = refit_base(
        &setup,
        base_params,
        setup.coeffs,
        Effects::NONE,
        cfg.refit_iterations,
    );
    let (base_errors, _) = setup.errors(&model_coeffs, Effects::NONE, 0);
    let refit_base_params = model_params;
    let refit_base_coeffs = model_coeffs;

    let mut current = Effects::NONE;
    let mut current_errors = base_errors.clone();
    let mut current_params = 0usize;
    let mut added = Vec::new();
    let mut rounds = Vec::new();
    while added.len() < cfg.max_effects {
        let remaining: Vec<EffectKind> = EffectKind::ALL
            .into_iter()
            .filter(|k| !k.is_on(&current))
            .collect();
        if remaining.is_empty() {
            break;
        }
        let mut results = Vec::new();
        for kind in remaining {
            results.push(evaluate_candidate(
                &setup,
                kind,
                (model_params, model_coeffs),
                current,
                &current_errors,
                current_params,
                cfg,
            ));
        }
        let best = results
            .iter()
            .filter(|c| c.earned)
            .min_by(|a, b| a.rms.total_cmp(&b.rms))
            .cloned();
        rounds.push(Round {
            rms_start: current_errors.rms_heldout,
            candidates: results,
            added: best.as_ref().map(|b| b.name),
        });
        let Some(best) = best else { break };
        current = best.effects;
        current_errors = best.errors;
        model_params = best.base_params;
        model_coeffs = best.coeffs;
        current_params += best.parameters;
        added.push(best.name);
    }

    let predicted_base = simulate(
        &refit_base_coeffs,
        Effects::NONE,
        tracker,
        samples,
        &setup.branches,
    );
    let predicted_after = simulate(&model_coeffs, current, tracker, samples, &setup.branches);
    let candidates = rounds
        .first()
        .map(|r| {
            r.candidates
                .iter()
                .map(|c| CandidateSummary {
                    name: c.name,
                    rms: c.rms,
                })
                .collect()
        })
        .unwrap_or_default();
    let heldout_samples = setup.heldout.iter().filter(|h| **h).count();
    Ok(DiagnoseReport {
        source: record.source.clone(),
        named: added.first().copied().unwrap_or("none"),
        effects_added: added,
        rms_before: base_errors.rms_heldout,
        rms_after: current_errors.rms_heldout,
        candidates,
        rounds,
        base: base_errors,
        after: current_errors,
        rms_paper_fit: paper_errors.rms_heldout,
        base_params: refit_base_params,
        final_params: model_params,
        effects: current,
        heldout_samples,
        train_samples: samples.len() - heldout_samples,
        correlation_length: setup.corr_len,
        min_improvement: cfg.min_improvement,
        min_bic_drop: cfg.min_bic_drop,
        predicted_base,
        predicted_after,
        heldout: setup.heldout,
        regimes: setup.regimes,
    })
}

/// Base parameters the joint refit moves: the critical points (the curve's
/// shape through the stroke), the stroke ends, the ellipse height and the
/// load family (the cubic's growth, the regressions of the stroke ends).
pub const BASE_REFIT_FIELDS: [&str; 10] = [
    "tangency.pressure_mpa",
    "inflection.pressure_mpa",
    "max_contraction",
    "ellipse_height_mpa",
    "c_growth_per_step",
    "root_contraction",
    "tangency.contraction",
    "inflection.contraction",
    "root_regression_per_step",
    "max_regression_per_step",
];

fn base_field(p: &mut Params, k: usize) -> Option<&mut f32> {
    match k {
        0 => Some(&mut p.points.tangency.pressure_mpa),
        1 => Some(&mut p.points.inflection.pressure_mpa),
        2 => Some(&mut p.points.max_contraction),
        3 => Some(&mut p.ellipse_height_mpa),
        4 => Some(&mut p.c_growth_per_step),
        5 => Some(&mut p.points.root_contraction),
        6 => Some(&mut p.points.tangency.contraction),
        7 => Some(&mut p.points.inflection.contraction),
        8 => Some(&mut p.root_regression_per_step),
        9 => Some(&mut p.max_regression_per_step),
        _ => None,
    }
}

/// Refit [`BASE_REFIT_FIELDS`] of `params` with `effects` on, on the
/// training samples' simulated residuals: `iterations` damped Gauss–Newton
/// steps (forward-difference Jacobian, a step is kept only when the
/// training cost falls, the damping grows when it does not). Returns the
/// input when nothing improves or a step leaves the valid parameters.
fn refit_base(
    setup: &Setup<'_>,
    params: Params,
    coeffs: Coeffs,
    effects: Effects,
    iterations: usize,
) -> (Params, Coeffs) {
    let train = |c: &Coeffs| -> Option<DVector<f64>> {
        let res = setup.residuals_with(c, effects);
        let v = DVector::from_iterator(
            setup.train_idx.len(),
            setup.train_idx.iter().map(|&i| res[i]),
        );
        v.iter().all(|r| r.is_finite()).then_some(v)
    };
    let with = |p: &Params, delta: &[f64]| -> Option<(Params, Coeffs)> {
        let mut q = *p;
        for (k, d) in delta.iter().enumerate() {
            let f = base_field(&mut q, k)?;
            *f += *d as f32;
        }
        Coeffs::new(q).ok().map(|c| (q, c))
    };
    let (mut p, mut c) = (params, coeffs);
    let Some(mut r) = train(&c) else {
        return (p, c);
    };
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let m = BASE_REFIT_FIELDS.len();
    for _ in 0..iterations {
        let h: Vec<f64> = (0..m)
            .map(|k| {
                let mut q = p;
                let v = base_field(&mut q, k).map_or(0.0, |f| f64::from(*f));
                1e-3 * v.abs().max(1e-2)
            })
            .collect();
        let cols: Vec<Option<DVector<f64>>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..m)
                .map(|k| {
                    let mut d = vec![0.0; m];
                    d[k] = h[k];
                    let (with, train, p) = (&with, &train, &p);
                    s.spawn(move || with(p, &d).and_then(|(_, c)| train(&c)))
                })
                .collect();
            handles
                .into_iter()
                .map(|hd| hd.join().ok().flatten())
                .collect()
        });
        let mut jac = DMatrix::zeros(r.len(), m);
        for (k, col) in cols.iter().enumerate() {
            let Some(col) = col else { return (p, c) };
            jac.set_column(k, &((col - &r) / h[k]));
        }
        let jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * &r;
        let mut improved = false;
        for _ in 0..4 {
            let mut a = jtj.clone();
            for k in 0..m {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(step) = a.lu().solve(&(-&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            if let Some((q, qc)) = with(&p, step.as_slice()) {
                if let Some(qr) = train(&qc) {
                    let qcost = qr.norm_squared();
                    if qcost < cost {
                        (p, c, r, cost) = (q, qc, qr, qcost);
                        lambda = (lambda * 0.3).max(1e-6);
                        improved = true;
                        break;
                    }
                }
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (p, c)
}

fn evaluate_candidate(
    setup: &Setup<'_>,
    kind: EffectKind,
    model: (Params, Coeffs),
    current: Effects,
    current_errors: &ModelErrors,
    current_params: usize,
    cfg: &DiagnoseConfig,
) -> CandidateResult {
    let fit_effect = |coeffs: Coeffs, starts: Vec<Vec<f64>>| -> Vec<f64> {
        let mut best: Option<(f64, Vec<f64>)> = None;
        for mut start in starts {
            let fixed = start.split_off(kind.free_count().min(start.len()));
            let problem = CandidateProblem {
                setup,
                coeffs,
                kind,
                base: current,
                theta: DVector::from_vec(start),
                fixed,
            };
            let (problem, report) = LevenbergMarquardt::new()
                .with_patience(cfg.patience)
                .minimize(problem);
            let cost = report.objective_function;
            if cost.is_finite() && best.as_ref().is_none_or(|(c, _)| cost < *c) {
                best = Some((cost, problem.full(problem.theta.as_slice())));
            }
        }
        best.map(|(_, t)| t).unwrap_or_default()
    };
    // The effect's parameters on the current base, then the base refitted
    // with the effect on (an effect the base fit could not see biases it:
    // creep lags every ramp the static curve was fitted to), then the
    // effect's parameters again on that base.
    let theta = fit_effect(model.1, kind.starts());
    let (base_params, coeffs) = refit_base(
        setup,
        model.0,
        model.1,
        kind.apply(current, &theta),
        cfg.refit_iterations,
    );
    let theta = if cfg.refit_iterations > 0 {
        fit_effect(coeffs, vec![theta])
    } else {
        theta
    };
    let effects = kind.apply(current, &theta);
    let n_params = current_params + kind.parameter_count();
    let (errors, _) = setup.errors(&coeffs, effects, n_params);
    let improvement = 1.0 - errors.rms_heldout / current_errors.rms_heldout;
    let bic_drop = current_errors.bic - errors.bic;
    let regime_rms = |e: &ModelErrors| -> f64 {
        match kind {
            EffectKind::LoadDependentWidth => {
                // Per load: the worst load's RMS is where a width error shows.
                e.loads.iter().map(|l| l.rms).fold(f64::NAN, f64::max)
            }
            _ => e
                .regimes
                .iter()
                .find(|r| r.regime == kind.regime())
                .map_or(f64::NAN, |r| r.rms),
        }
    };
    let signature = Signature {
        regime: kind.regime(),
        rms_before: regime_rms(current_errors),
        rms_after: regime_rms(&errors),
    };
    let signature_cut = 1.0 - signature.rms_after / signature.rms_before;
    let earned = improvement >= cfg.min_improvement
        && bic_drop >= cfg.min_bic_drop
        && signature_cut >= cfg.min_improvement;
    CandidateResult {
        name: kind.name(),
        rms: errors.rms_heldout,
        improvement,
        bic_drop,
        parameters: kind.parameter_count(),
        earned,
        signature,
        effects,
        errors,
        base_params,
        coeffs,
    }
}

/// A short summary a person can read.
pub fn summary(r: &DiagnoseReport) -> String {
    let mut s = String::new();
    let pct = |x: f64| 100.0 * x;
    s.push_str(&format!(
        "diagnose {}: {} training / {} held-out samples (load blocks alternate)\n",
        r.source, r.train_samples, r.heldout_samples
    ));
    s.push_str(&format!(
        "base model (paper): held-out RMS contraction error {:.5}\n",
        r.rms_before
    ));
    let worst = r
        .base
        .regimes
        .iter()
        .filter(|g| g.samples > 0)
        .max_by(|a, b| a.rms.total_cmp(&b.rms));
    if let Some(w) = worst {
        s.push_str(&format!(
            "  largest disagreement: {} (RMS {:.5} over {} held-out samples)\n",
            w.regime, w.rms, w.samples
        ));
    }
    for (k, round) in r.rounds.iter().enumerate() {
        s.push_str(&format!(
            "round {}: candidates against RMS {:.5}\n",
            k + 1,
            round.rms_start
        ));
        for c in &round.candidates {
            s.push_str(&format!(
                "  {:<22} RMS {:.5}  ({:+.1} %, BIC drop {:>8.1}, {} in {}: {:.5} -> {:.5}){}\n",
                c.name,
                c.rms,
                -pct(c.improvement),
                c.bic_drop,
                c.parameters,
                c.signature.regime,
                c.signature.rms_before,
                c.signature.rms_after,
                if c.earned { "  earns it" } else { "" }
            ));
        }
        match round.added {
            Some(n) => s.push_str(&format!("  -> added {n}\n")),
            None => s.push_str("  -> no candidate earns its parameters\n"),
        }
    }
    s.push_str(&format!(
        "named: {}; effects added: [{}]\nheld-out RMS {:.5} -> {:.5} ({:.1} % lower)\n",
        r.named,
        r.effects_added.join(", "),
        r.rms_before,
        r.rms_after,
        pct(1.0 - r.rms_after / r.rms_before)
    ));
    s
}

/// Write `report.json`, `residual.png` and `loops.png` into `dir`, all or
/// none ([`crate::output::OutputSet`]).
pub fn write_outputs(r: &DiagnoseReport, record: &Record, dir: &Path) -> anyhow::Result<()> {
    let mut set = crate::output::OutputSet::new();
    crate::commands::stage_diagnose(&mut set, dir, r, record, true)?;
    set.commit()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(t: f64, load: f64) -> Sample {
        Sample {
            t_s: t,
            load_n: load,
            pressure_mpa: 0.0,
            contraction: 0.0,
        }
    }

    #[test]
    fn load_blocks_alternate() {
        let v: Vec<Sample> = [100.0, 100.0, 200.0, 200.0, 300.0, 150.0]
            .iter()
            .enumerate()
            .map(|(i, &l)| s(i as f64, l))
            .collect();
        assert_eq!(
            holdout_by_load_block(&v),
            vec![false, false, true, true, false, true]
        );
        let one: Vec<Sample> = (0..10).map(|i| s(i as f64, 100.0)).collect();
        assert_eq!(
            holdout_by_load_block(&one).iter().filter(|h| **h).count(),
            3
        );
    }

    #[test]
    fn parameter_maps_stay_valid() {
        for kind in EffectKind::ALL {
            for t in [-50.0, -1.0, 0.0, 1.0, 50.0] {
                let e = kind.apply(Effects::NONE, &[t, -t]);
                assert!(e.validate().is_ok(), "{kind:?} {t}: {e:?}");
                assert!(kind.is_on(&e));
            }
        }
        for n in [0.5, 0.75, 1.0, 0.0, 9.0, f64::NAN] {
            for t in [-50.0, 0.0, 50.0] {
                let e = EffectKind::RateDependence.apply(Effects::NONE, &[t, -t, t, n]);
                assert!(e.validate().is_ok(), "{n} {t}: {e:?}");
            }
        }
        for start in EffectKind::RateDependence.starts() {
            let r = EffectKind::RateDependence
                .apply(Effects::NONE, &start)
                .rate
                .unwrap();
            assert!(RATE_EXPONENTS.contains(&f64::from(r.exponent)));
            assert!((r.filter_time_s - 0.2).abs() < 1e-6, "{r:?}");
        }
    }

    #[test]
    fn correlation_length_of_white_noise_is_one_and_of_a_slow_signal_is_long() {
        let white: Vec<f64> = (0..1000)
            .map(|i| ((i * 7919 % 1013) as f64 / 1013.0) - 0.5)
            .collect();
        assert!(correlation_length(&white) <= 2.0);
        let slow: Vec<f64> = (0..2000).map(|i| (i as f64 / 200.0).sin()).collect();
        assert!(correlation_length(&slow) > 50.0);
    }
}

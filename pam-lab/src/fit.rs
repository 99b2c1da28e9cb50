//! Identification of the paper's model from a record: every parameter of
//! [`Params`] (critical points at the minimum load, `RG_L`, `RG_U`, `GR_c`,
//! `be`; `Pmax` measured from the record or given) by nonlinear least squares
//! (Levenberg–Marquardt, the `levenberg-marquardt` crate), on the training
//! part of the record; errors are then reported on the held-out part.
//!
//! # Residual
//! For each labelled training sample, the forward model's pressure at the
//! measured contraction, load and branch minus the measured pressure (the
//! model is a function `pressure(contraction, load, branch)`, eqs. 21–26;
//! isotonic and isometric tests both sample it). Both measurements are noisy,
//! so each residual is divided by its effective standard deviation
//! `√(σp² + (CM'(x)·σx)²)` (noise estimated from the record): where the
//! curve is steep a small contraction error is a large pressure error, and
//! without this weight the stroke ends would dominate the fit.
//!
//! # Parametrisation
//! The fit varies `R1`, `Rx1`, the constraint model's pressure at 1/3 and 2/3
//! of the stroke at the minimum load, `RG_L`, `RG_U`, `GR_c` and `be`: a
//! minimal set (the paper's four critical points over-determine a cubic once
//! `R1`, `Rx1`, `Pmax` are fixed). Shapes that `pam_core::Coeffs::new` would
//! refuse (a second real root, a falling curve, at any calibrated load) are
//! kept out by penalty residuals that are zero on valid shapes. The exported
//! critical points are the fitted cubic's inflection point and the point
//! halfway between `R1` and it (any two interior points give the same cubic).

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use pam_core::{Branch, Coeffs, CriticalPoints, Params, Point};
use serde::Serialize;

use crate::data::{DataError, DataErrorKind, Record, Sample};
use crate::split::{split_branches, Split, SplitConfig};
use crate::stats::{error_table, ErrorTable};

/// Which part of the record is held out of the fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Holdout {
    /// Nothing held out (the report is then on the training data).
    None,
    /// Every `k`-th cycle (cycles `k−1, 2k−1, …`): held-out data from every
    /// load and every part of the protocol.
    EveryKthCycle(u32),
    /// The last fraction of the record (a contiguous later part).
    Tail(f64),
}

impl std::str::FromStr for Holdout {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || {
            format!("holdout `{s}`: expected `none`, `every:K` (K >= 2) or `tail:F` (0 < F < 1)")
        };
        if s == "none" {
            return Ok(Holdout::None);
        }
        let (kind, v) = s.split_once(':').ok_or_else(bad)?;
        match kind {
            "every" => match v.parse::<u32>() {
                Ok(k) if k >= 2 => Ok(Holdout::EveryKthCycle(k)),
                _ => Err(bad()),
            },
            "tail" => match v.parse::<f64>() {
                Ok(f) if f > 0.0 && f < 1.0 => Ok(Holdout::Tail(f)),
                _ => Err(bad()),
            },
            _ => Err(bad()),
        }
    }
}

impl std::fmt::Display for Holdout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Holdout::None => write!(f, "none"),
            Holdout::EveryKthCycle(k) => write!(f, "every:{k}"),
            Holdout::Tail(x) => write!(f, "tail:{x}"),
        }
    }
}

/// Fit settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FitConfig {
    /// `Pmax`, MPa; `None` measures it (the top of the smoothed pressure).
    pub max_pressure_mpa: Option<f64>,
    /// Load step `ΔL` of the regression and growth factors, N.
    pub load_step_n: f64,
    /// What to hold out.
    pub holdout: Holdout,
    /// Branch split settings.
    pub split: SplitConfig,
    /// Width of the load bins for grouping and reports, N.
    pub load_bin_n: f64,
    /// Fewest training samples per branch in a load bin for it to count.
    pub min_samples_per_group: usize,
    /// Iteration budget of the optimiser (in units of residual evaluations
    /// per parameter, as MINPACK's `patience`).
    pub patience: usize,
}

impl Default for FitConfig {
    fn default() -> Self {
        FitConfig {
            max_pressure_mpa: None,
            load_step_n: 100.0,
            holdout: Holdout::EveryKthCycle(4),
            split: SplitConfig::default(),
            load_bin_n: 25.0,
            min_samples_per_group: 50,
            patience: 100,
        }
    }
}

/// Progress of a long fit, for display.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Progress {
    /// A stage started.
    Stage(&'static str),
    /// The optimiser evaluated the residuals: the evaluation count and the
    /// cost `½·Σr²` of the current parameters.
    Evaluation {
        /// Residual evaluations so far.
        count: usize,
        /// `½·Σr²`.
        cost: f64,
    },
}

/// Why a fit failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// The record cannot identify the model (too few samples, one load only…).
    #[error("{0}")]
    Data(#[from] DataError),
    /// The optimiser did not produce a model that pam-core accepts.
    #[error(
        "{source_name}: the fitted parameters are not a valid model: {error} (params: {params:?})"
    )]
    Invalid {
        /// The record.
        source_name: String,
        /// What pam-core said.
        error: pam_core::Error,
        /// The parameters.
        params: Params,
    },
    /// The optimiser failed numerically.
    #[error("{source_name}: the optimiser failed: {why}")]
    Optimiser {
        /// The record.
        source_name: String,
        /// What happened.
        why: String,
    },
}

/// Where `Pmax` came from.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PmaxSource {
    /// Given by the user.
    Given,
    /// Measured from the record.
    Measured,
}

/// The outcome of [`fit`].
#[derive(Clone, Debug)]
pub struct FitReport {
    /// The identified parameters (validated: `Coeffs::new` accepts them).
    pub params: Params,
    /// `Coeffs::new(params)`.
    pub coeffs: Coeffs,
    /// The branch split of the whole record.
    pub split: Split,
    /// Which samples were held out.
    pub heldout: Vec<bool>,
    /// Errors on the training samples.
    pub train: ErrorTable,
    /// Errors on the held-out samples (the training samples when nothing is
    /// held out).
    pub test: ErrorTable,
    /// Where `Pmax` came from.
    pub pmax_source: PmaxSource,
    /// The hold-out rule used.
    pub holdout: Holdout,
    /// Residual evaluations of the optimiser.
    pub evaluations: usize,
    /// The optimiser's termination reason.
    pub termination: String,
    /// Final cost `½·Σr²` (weighted residuals).
    pub cost: f64,
    /// The starting point derived from the data.
    pub initial: Params,
}

// ---------------------------------------------------------------------------
// The model in f64, as pam-core evaluates it.

/// Number of fitted parameters.
const NP: usize = 8;
/// Fractions of the stroke at which the minimum-load cubic is parametrised.
const U1: f64 = 1.0 / 3.0;
const U2: f64 = 2.0 / 3.0;
/// Loads across the calibrated range at which the shape penalty is checked.
const PENALTY_LOADS: usize = 17;

/// Fixed quantities of a fit.
#[derive(Clone, Copy, Debug)]
struct Fixed {
    pmax: f64,
    min_load_n: f64,
    max_load_n: f64,
    load_step_n: f64,
}

/// The load family in f64: factor form at the minimum load plus the factors.
#[derive(Clone, Copy, Debug)]
struct Family {
    r1: f64,
    rx1: f64,
    b: f64,
    c1: f64,
    rg_l: f64,
    rg_u: f64,
    gr_c: f64,
    be: f64,
    fixed: Fixed,
}

/// The model at one load: eqs. (16)–(26) as `pam_core::LoadModel` has them.
#[derive(Clone, Copy, Debug)]
struct AtLoad {
    root: f64,
    rx: f64,
    a: f64,
    b: f64,
    c: f64,
    centre: f64,
    inv_half: f64,
    be: f64,
    pmax: f64,
}

impl Family {
    /// From the fit vector `[R1, Rx1, y(1/3), y(2/3), RG_L, RG_U, GR_c, be]`.
    fn from_theta(t: &[f64], fixed: Fixed) -> Family {
        let (r1, rx1) = (t[0], t[1]);
        let s = rx1 - r1;
        // The quadratic factor q(x) = a x² − b x + c through the points
        // (x_k, y_k/(x_k − R1)): Lagrange interpolation, then its coefficients.
        let xs = [r1 + U1 * s, r1 + U2 * s, rx1];
        let ys = [t[2], t[3], fixed.pmax];
        let qs: Vec<f64> = xs.iter().zip(ys).map(|(x, y)| y / (x - r1)).collect();
        let (mut qa, mut qb, mut qc) = (0.0, 0.0, 0.0); // q = qa x² + qb x + qc
        for k in 0..3 {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let d = (xs[k] - xs[i]) * (xs[k] - xs[j]);
            let w = qs[k] / d;
            qa += w;
            qb -= w * (xs[i] + xs[j]);
            qc += w * xs[i] * xs[j];
        }
        let _ = qa; // a at the minimum load follows from eq. (16) in at_load
        Family {
            r1,
            rx1,
            b: -qb,
            c1: qc,
            rg_l: t[4],
            rg_u: t[5],
            gr_c: t[6],
            be: t[7],
            fixed,
        }
    }

    /// From pam-core parameters (through pam-core's own construction).
    #[cfg(test)]
    fn from_coeffs(coeffs: &Coeffs) -> Family {
        let p = coeffs.params();
        let f = coeffs.factor_cubic();
        Family {
            r1: f.root,
            rx1: f64::from(p.points.max_contraction),
            b: f.b,
            c1: f.c,
            rg_l: f64::from(p.root_regression_per_step),
            rg_u: f64::from(p.max_regression_per_step),
            gr_c: f64::from(p.c_growth_per_step),
            be: f64::from(p.ellipse_height_mpa),
            fixed: Fixed {
                pmax: f64::from(p.points.max_pressure_mpa),
                min_load_n: f64::from(p.min_load_n),
                max_load_n: f64::from(p.max_load_n),
                load_step_n: f64::from(p.load_step_n),
            },
        }
    }

    /// eqs. (16)–(19) at `load_n` (clamped to the calibrated range).
    fn at_load(&self, load_n: f64) -> AtLoad {
        let f = &self.fixed;
        let load_n = load_n.clamp(f.min_load_n, f.max_load_n);
        let s = (load_n - f.min_load_n) / f.load_step_n;
        let root = self.r1 - self.rg_l * s; // eq. (17)
        let rx = self.rx1 - self.rg_u * s; // eq. (18)
        let c = self.c1 + self.gr_c * s; // eq. (19)
        let b = self.b;
        let a = ((f.pmax + c * root) / (rx * rx) - (c + b * root) / rx + b) / (rx - root); // eq. (16)
        let half = 0.5 * (rx - root);
        AtLoad {
            root,
            rx,
            a,
            b,
            c,
            centre: root + half,
            inv_half: 1.0 / half,
            be: self.be,
            pmax: f.pmax,
        }
    }
}

impl AtLoad {
    /// `(pressure, CM slope)` at `x`: eqs. (21), (23)–(26), clamped as
    /// `pam_core::LoadModel::pressure_mpa` clamps.
    #[inline]
    fn pressure_and_slope(&self, x: f64, sign: f64) -> (f64, f64) {
        let inside = x > self.root && x < self.rx;
        let x = x.clamp(self.root, self.rx);
        let q = (self.a * x - self.b) * x + self.c;
        let cm = (x - self.root) * q;
        // The slope of the function evaluated: zero outside the stroke,
        // where the clamp holds the pressure at 0 or Pmax. (With the cubic's
        // slope there, a sample past `Rx` got the small weight of the steep
        // stroke end, and shrinking `Rx1` below the data cost almost nothing.)
        let slope = if inside {
            q + (x - self.root) * (2.0 * self.a * x - self.b)
        } else {
            0.0
        };
        let u = (x - self.centre) * self.inv_half;
        let w = 1.0 - u * u;
        let y = if w > 0.0 { self.be * w.sqrt() } else { 0.0 };
        ((cm + sign * y).clamp(0.0, self.pmax), slope)
    }

    /// Smallest value of the quadratic factor (> 0: one real root), and the
    /// smallest slope on `[R, Rx]` (> 0: increasing) — pam-core's checks.
    fn shape_margins(&self) -> (f64, f64) {
        let q_min = if self.a > 0.0 {
            self.c - self.b * self.b / (4.0 * self.a)
        } else {
            -1.0
        };
        let slope = |x: f64| {
            (self.a * x - self.b) * x + self.c + (x - self.root) * (2.0 * self.a * x - self.b)
        };
        let mut m = slope(self.root).min(slope(self.rx));
        if self.a != 0.0 {
            let xi = (self.b + self.a * self.root) / (3.0 * self.a);
            if xi > self.root && xi < self.rx {
                m = m.min(slope(xi));
            }
        }
        (q_min, m)
    }
}

// ---------------------------------------------------------------------------
// The least-squares problem.

/// Training samples, sorted by load so that the per-load model is computed
/// once per run of equal loads.
struct TrainSet {
    x: Vec<f64>,
    p: Vec<f64>,
    sign: Vec<f64>,
    /// `(load, start, end)` runs of equal load.
    runs: Vec<(f64, usize, usize)>,
    sigma_p: f64,
    sigma_x: f64,
}

impl TrainSet {
    fn len(&self) -> usize {
        self.x.len()
    }
}

struct Problem<'a> {
    theta: DVector<f64>,
    data: &'a TrainSet,
    fixed: Fixed,
    /// Penalty weight: large against the data term of ~1 per sample.
    penalty_weight: f64,
    /// Slope scale `Pmax/(Rx1 − R1)` of the initial guess, MPa per unit contraction.
    slope_scale: f64,
    evaluations: std::sync::atomic::AtomicUsize,
    progress: &'a (dyn Fn(Progress) + Sync),
}

impl Problem<'_> {
    fn n_residuals(&self) -> usize {
        self.data.len() + 2 * PENALTY_LOADS + 2
    }

    fn residuals_at(&self, theta: &[f64], out: &mut [f64]) {
        let fam = Family::from_theta(theta, self.fixed);
        let d = self.data;
        let (vp, vx) = (d.sigma_p * d.sigma_p, d.sigma_x * d.sigma_x);
        for &(load, start, end) in &d.runs {
            let m = fam.at_load(load);
            let rows = d.x[start..end]
                .iter()
                .zip(&d.sign[start..end])
                .zip(&d.p[start..end]);
            for (o, ((&x, &sign), &pm)) in out[start..end].iter_mut().zip(rows) {
                let (p, slope) = m.pressure_and_slope(x, sign);
                *o = (p - pm) / (vp + slope * slope * vx).sqrt();
            }
        }
        // Shape penalties: zero while pam-core would accept the shape with a
        // margin of 2 % of the mean slope.
        let n = d.len();
        let f = &self.fixed;
        let margin = 0.02 * self.slope_scale;
        let w = self.penalty_weight / self.slope_scale;
        for k in 0..PENALTY_LOADS {
            let load = f.min_load_n
                + (f.max_load_n - f.min_load_n) * k as f64 / (PENALTY_LOADS - 1) as f64;
            let m = fam.at_load(load);
            let (q_min, slope_min) = m.shape_margins();
            let bad = |v: f64| {
                if v.is_finite() {
                    (margin - v).max(0.0)
                } else {
                    1e3 * margin
                }
            };
            out[n + 2 * k] = w * bad(q_min);
            out[n + 2 * k + 1] = w * bad(slope_min);
        }
        // The stroke must stay open at the maximum load, and be >= 0.
        let top = fam.at_load(f.max_load_n);
        let stroke_min = 0.05 * (theta[1] - theta[0]).abs();
        out[n + 2 * PENALTY_LOADS] =
            self.penalty_weight * 100.0 * (stroke_min - (top.rx - top.root)).max(0.0);
        out[n + 2 * PENALTY_LOADS + 1] = self.penalty_weight * (-theta[7] / f.pmax).max(0.0);
        for v in out.iter_mut() {
            if !v.is_finite() {
                *v = 1e6;
            }
        }
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
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
        let mut r = DVector::zeros(self.n_residuals());
        self.residuals_at(self.theta.as_slice(), r.as_mut_slice());
        let count = 1 + self
            .evaluations
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        (self.progress)(Progress::Evaluation {
            count,
            cost: 0.5 * r.norm_squared(),
        });
        Some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        // Forward differences, one column per parameter, the columns shared
        // between two threads (the machine has two cores).
        let m = self.n_residuals();
        let theta: Vec<f64> = self.theta.iter().copied().collect();
        let mut base = vec![0.0; m];
        self.residuals_at(&theta, &mut base);
        let mut jac = DMatrix::zeros(m, NP);
        let steps: Vec<f64> = theta
            .iter()
            .enumerate()
            .map(|(j, v)| 1e-7 * v.abs().max(param_scale(j, &self.fixed)))
            .collect();
        let (left, right): (Vec<_>, Vec<_>) = jac
            .as_mut_slice()
            .chunks_mut(m)
            .enumerate()
            .partition(|(j, _)| j % 2 == 0);
        let work = |list: Vec<(usize, &mut [f64])>| {
            let mut t = theta.clone();
            for (j, col) in list {
                t[j] = theta[j] + steps[j];
                self.residuals_at(&t, col);
                t[j] = theta[j];
                for (c, b) in col.iter_mut().zip(&base) {
                    *c = (*c - b) / steps[j];
                }
            }
        };
        std::thread::scope(|s| {
            s.spawn(|| work(right));
            work(left);
        });
        Some(jac)
    }
}

/// Typical magnitude of parameter `j`, for finite-difference steps.
fn param_scale(j: usize, fixed: &Fixed) -> f64 {
    match j {
        0..=1 => 0.1,
        2..=3 => fixed.pmax,
        4..=5 => 0.01,
        6 => 0.1,
        _ => 0.01 * fixed.pmax,
    }
}

// ---------------------------------------------------------------------------
// The fit.

/// [`fit_with_progress`] without progress reports.
pub fn fit(record: &Record, cfg: &FitConfig) -> Result<FitReport, FitError> {
    fit_with_progress(record, cfg, &|_| {})
}

fn quantile(mut v: Vec<f64>, q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    let (_, m, _) = v.select_nth_unstable_by(k, f64::total_cmp);
    Some(*m)
}

/// Which samples of a record of `n` with cycles `cycle` are held out.
pub fn heldout_mask(holdout: Holdout, cycle: &[u32]) -> Vec<bool> {
    let n = cycle.len();
    match holdout {
        Holdout::None => vec![false; n],
        Holdout::EveryKthCycle(k) => cycle.iter().map(|c| c % k == k - 1).collect(),
        Holdout::Tail(f) => {
            let first = ((1.0 - f) * n as f64).round() as usize;
            (0..n).map(|i| i >= first).collect()
        }
    }
}

/// Identify the model from `record`; `progress` hears about long work.
pub fn fit_with_progress(
    record: &Record,
    cfg: &FitConfig,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<FitReport, FitError> {
    let samples = &record.samples;
    let data_err = |line: u64, what: String| {
        FitError::Data(DataError {
            file: record.source.clone(),
            line,
            column: None,
            kind: DataErrorKind::TooFewSamples(what),
        })
    };
    progress(Progress::Stage("splitting branches"));
    let split = split_branches(samples, &cfg.split);
    let heldout = heldout_mask(cfg.holdout, &split.cycle);
    let is_train = |i: usize| split.branch[i].is_some() && !heldout[i];

    // Pmax: given, or the top of the smoothed pressure (the noise averaged out).
    let (pmax, pmax_source) = match cfg.max_pressure_mpa {
        Some(p) => (p, PmaxSource::Given),
        None => {
            let p: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
            let ps = crate::split::moving_average(&p, 9);
            (ps.iter().copied().fold(0.0, f64::max), PmaxSource::Measured)
        }
    };
    if !(pmax > 0.0 && pmax <= 10.0) {
        return Err(data_err(
            0,
            format!("Pmax {pmax} MPa is not in (0, 10] (does the pressure ever rise?)"),
        ));
    }

    // The calibrated load range: the median loads of the lowest and highest
    // load bins (a load cell's noise must not move the minimum load, which
    // is where the critical points are taken).
    let bin = cfg.load_bin_n;
    let lowest = samples
        .iter()
        .map(|s| (s.load_n / bin).round() as i64)
        .min();
    let highest = samples
        .iter()
        .map(|s| (s.load_n / bin).round() as i64)
        .max();
    let median_in = |key: Option<i64>| {
        quantile(
            samples
                .iter()
                .filter(|s| Some((s.load_n / bin).round() as i64) == key)
                .map(|s| s.load_n)
                .collect(),
            0.5,
        )
        .unwrap_or(0.0)
    };
    let min_load_n = median_in(lowest);
    let max_load_n = median_in(highest).max(min_load_n);

    // Enough training samples per load bin and branch?
    let mut groups: std::collections::BTreeMap<i64, [usize; 2]> = Default::default();
    let mut first_line: std::collections::BTreeMap<i64, u64> = Default::default();
    for (i, s) in samples.iter().enumerate() {
        if !is_train(i) {
            continue;
        }
        let key = (s.load_n / bin).round() as i64;
        let b = usize::from(split.branch[i] == Some(Branch::Expansion));
        groups.entry(key).or_default()[b] += 1;
        first_line.entry(key).or_insert(record.line(i));
    }
    let need = cfg.min_samples_per_group;
    let usable: Vec<i64> = groups
        .iter()
        .filter(|(_, c)| c[0] >= need && c[1] >= need)
        .map(|(k, _)| *k)
        .collect();
    let min_key = (min_load_n / bin).round() as i64;
    let describe = |k: i64| {
        let c = groups.get(&k).copied().unwrap_or_default();
        format!(
            "load {} N (first training line {}): {} contraction-branch and {} expansion-branch training samples, need {need} of each",
            k as f64 * bin,
            first_line.get(&k).copied().unwrap_or(0),
            c[0],
            c[1]
        )
    };
    if !usable.contains(&min_key) {
        return Err(data_err(
            first_line.get(&min_key).copied().unwrap_or(0),
            format!("at the minimum load, {}", describe(min_key)),
        ));
    }
    if usable.len() < 2 {
        let others: Vec<String> = groups
            .keys()
            .filter(|k| **k != min_key)
            .map(|k| describe(*k))
            .collect();
        return Err(data_err(
            0,
            format!(
                "the load factors need a second load with both branches; {}",
                if others.is_empty() {
                    "the record has one load only".to_string()
                } else {
                    others.join("; ")
                }
            ),
        ));
    }

    let fixed = Fixed {
        pmax,
        min_load_n,
        max_load_n,
        load_step_n: cfg.load_step_n,
    };

    // Training set, sorted by load.
    let mut idx: Vec<usize> = (0..samples.len()).filter(|&i| is_train(i)).collect();
    idx.sort_by(|&a, &b| samples[a].load_n.total_cmp(&samples[b].load_n));
    let mut train = TrainSet {
        x: Vec::with_capacity(idx.len()),
        p: Vec::with_capacity(idx.len()),
        sign: Vec::with_capacity(idx.len()),
        runs: Vec::new(),
        sigma_p: split.pressure_noise_mpa.max(1e-4),
        sigma_x: split.contraction_noise.max(1e-5),
    };
    for (k, &i) in idx.iter().enumerate() {
        let s = &samples[i];
        if train.runs.last().is_none_or(|r| r.0 != s.load_n) {
            train.runs.push((s.load_n, k, k));
        }
        if let Some(r) = train.runs.last_mut() {
            r.2 = k + 1;
        }
        train.x.push(s.contraction);
        train.p.push(s.pressure_mpa);
        train
            .sign
            .push(f64::from(split.branch[i].map_or(1.0, Branch::offset_sign)));
    }

    progress(Progress::Stage("initial guess"));
    let theta0 = initial_guess(samples, &split, &is_train, &fixed, bin);
    let initial = export(&Family::from_theta(&theta0, fixed));

    progress(Progress::Stage("least squares"));
    // The shape penalty is a hinge with a finite weight, so where the data
    // pull towards a shape pam-core refuses (a plateau that dips), the
    // optimum may sit just past the margin: then the weight is raised and
    // the fit continued from there, until pam-core accepts the parameters.
    let mut theta = theta0.to_vec();
    let mut evaluations = 0;
    let mut last_error = None;
    let mut outcome = None;
    for weight in [10.0, 100.0, 1e3, 1e4] {
        let problem = Problem {
            theta: DVector::from_column_slice(&theta),
            data: &train,
            fixed,
            penalty_weight: weight * (train.len() as f64).sqrt(),
            slope_scale: pmax / (theta0[1] - theta0[0]).max(1e-3),
            evaluations: Default::default(),
            progress,
        };
        let (problem, report) = LevenbergMarquardt::new()
            .with_patience(cfg.patience)
            .minimize(problem);
        evaluations += problem
            .evaluations
            .load(std::sync::atomic::Ordering::Relaxed);
        // Running out of patience still leaves the best point found; other
        // unsuccessful terminations are numerical failures.
        if !report.termination.was_successful()
            && !matches!(
                report.termination,
                levenberg_marquardt::TerminationReason::LostPatience
            )
        {
            return Err(FitError::Optimiser {
                source_name: record.source.clone(),
                why: format!("{:?}", report.termination),
            });
        }
        theta = problem.theta.as_slice().to_vec();
        let params = export(&Family::from_theta(&theta, fixed));
        match Coeffs::new(params) {
            Ok(coeffs) => {
                outcome = Some((params, coeffs, report));
                break;
            }
            Err(error) => last_error = Some((error, params)),
        }
    }
    let Some((params, coeffs, report)) = outcome else {
        let (error, params) = last_error.unwrap_or((pam_core::Error::Singular, initial));
        return Err(FitError::Invalid {
            source_name: record.source.clone(),
            error,
            params,
        });
    };

    progress(Progress::Stage("errors"));
    let train_table = error_table(&coeffs, samples, &split.branch, |i| !heldout[i], bin);
    let any_heldout = heldout.iter().any(|h| *h);
    let test_table = if any_heldout {
        error_table(&coeffs, samples, &split.branch, |i| heldout[i], bin)
    } else {
        train_table.clone()
    };
    Ok(FitReport {
        params,
        coeffs,
        heldout,
        train: train_table,
        test: test_table,
        pmax_source,
        holdout: cfg.holdout,
        evaluations,
        termination: format!("{:?}", report.termination),
        cost: report.objective_function,
        initial,
        split,
    })
}

/// A starting point from the data: stroke ends from the samples near zero
/// and full pressure, the cubic's interior values from the mean of both
/// branches, load factors by linear regression over the load bins, the
/// ellipse height from the gap between the branches at mid-stroke.
fn initial_guess(
    samples: &[Sample],
    split: &Split,
    is_train: &dyn Fn(usize) -> bool,
    fixed: &Fixed,
    bin: f64,
) -> [f64; NP] {
    let pmax = fixed.pmax;
    // Per load bin: the contractions near p = 0 and near Pmax.
    // Contractions near zero pressure and near Pmax.
    type Ends = (Vec<f64>, Vec<f64>);
    let mut ends: std::collections::BTreeMap<i64, Ends> = Default::default();
    for (i, s) in samples.iter().enumerate() {
        if !is_train(i) {
            continue;
        }
        let e = ends.entry((s.load_n / bin).round() as i64).or_default();
        if s.pressure_mpa < 0.03 * pmax {
            e.0.push(s.contraction);
        } else if s.pressure_mpa > 0.97 * pmax {
            e.1.push(s.contraction);
        }
    }
    let min_key = (fixed.min_load_n / bin).round() as i64;
    let all_x: Vec<f64> = samples.iter().map(|s| s.contraction).collect();
    let x_lo = quantile(all_x.clone(), 0.01).unwrap_or(0.0);
    let x_hi = quantile(all_x, 0.99).unwrap_or(0.2);
    let (r1, rx1) = ends
        .get(&min_key)
        .map(|(lo, hi)| {
            (
                quantile(lo.clone(), 0.5).unwrap_or(x_lo),
                quantile(hi.clone(), 0.5).unwrap_or(x_hi),
            )
        })
        .unwrap_or((x_lo, x_hi));
    let rx1 = if rx1 > r1 + 1e-3 { rx1 } else { r1 + 0.1 };
    // Regression of the ends on the load step count.
    let slope_of = |pick: &dyn Fn(&Ends) -> &Vec<f64>| {
        let pts: Vec<(f64, f64)> = ends
            .iter()
            .filter_map(|(k, e)| {
                let s = (*k as f64 * bin - fixed.min_load_n) / fixed.load_step_n;
                quantile(pick(e).clone(), 0.5).map(|x| (s, x))
            })
            .collect();
        if pts.len() < 2 {
            return 0.0;
        }
        let n = pts.len() as f64;
        let (ms, mx) = (
            pts.iter().map(|p| p.0).sum::<f64>() / n,
            pts.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let sxx: f64 = pts.iter().map(|p| (p.0 - ms).powi(2)).sum();
        let sxy: f64 = pts.iter().map(|p| (p.0 - ms) * (p.1 - mx)).sum();
        if sxx > 0.0 {
            -sxy / sxx
        } else {
            0.0
        }
    };
    let rg_l = slope_of(&|e| &e.0);
    let rg_u = slope_of(&|e| &e.1);

    // Interior pressures and branch gap at the minimum load.
    let stroke = rx1 - r1;
    let mean_near = |x0: f64, br: Branch| {
        let (mut s, mut n) = (0.0, 0usize);
        for (i, smp) in samples.iter().enumerate() {
            if is_train(i)
                && split.branch[i] == Some(br)
                && (smp.load_n / bin).round() as i64 == min_key
                && (smp.contraction - x0).abs() < 0.04 * stroke
            {
                s += smp.pressure_mpa;
                n += 1;
            }
        }
        (n > 0).then(|| s / n as f64)
    };
    let cm_at = |u: f64| {
        let x0 = r1 + u * stroke;
        match (
            mean_near(x0, Branch::Contraction),
            mean_near(x0, Branch::Expansion),
        ) {
            (Some(a), Some(b)) => 0.5 * (a + b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => u * pmax,
        }
    };
    let (y1, y2) = (cm_at(U1), cm_at(U2));
    let be = match (
        mean_near(r1 + 0.5 * stroke, Branch::Contraction),
        mean_near(r1 + 0.5 * stroke, Branch::Expansion),
    ) {
        (Some(a), Some(b)) => (0.5 * (a - b)).clamp(0.0, 0.25 * pmax),
        _ => 0.02 * pmax,
    };
    [r1, rx1, y1, y2.max(y1 + 1e-3 * pmax), rg_l, rg_u, 0.0, be]
}

/// The fitted family as pam-core parameters: critical points at the
/// inflection point of the minimum-load cubic and halfway between `R1` and
/// it (if the inflection lies well inside the stroke; else at 1/3 and 2/3).
fn export(fam: &Family) -> Params {
    let f = &fam.fixed;
    let m = fam.at_load(f.min_load_n);
    let cm = |x: f64| (x - m.root) * ((m.a * x - m.b) * x + m.c);
    let stroke = m.rx - m.root;
    let xi = (m.b + m.a * m.root) / (3.0 * m.a);
    let (x_tan, x_inf) = if xi.is_finite() && xi > m.root + 0.2 * stroke && xi < m.rx - 0.1 * stroke
    {
        (0.5 * (m.root + xi), xi)
    } else {
        (m.root + U1 * stroke, m.root + U2 * stroke)
    };
    let pt = |x: f64| Point {
        contraction: x as f32,
        pressure_mpa: cm(x) as f32,
    };
    Params {
        min_load_n: f.min_load_n as f32,
        max_load_n: f.max_load_n as f32,
        load_step_n: f.load_step_n as f32,
        points: CriticalPoints {
            root_contraction: fam.r1 as f32,
            max_contraction: fam.rx1 as f32,
            max_pressure_mpa: f.pmax as f32,
            tangency: pt(x_tan),
            inflection: pt(x_inf),
        },
        root_regression_per_step: fam.rg_l as f32,
        max_regression_per_step: fam.rg_u as f32,
        c_growth_per_step: fam.gr_c as f32,
        ellipse_height_mpa: fam.be as f32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Protocol};

    #[test]
    fn f64_model_matches_pam_core() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let fam = Family::from_coeffs(&coeffs);
        for load in [100.0, 170.0, 420.0, 600.0] {
            let m64 = fam.at_load(load);
            let m32 = coeffs.load_model(load as f32).unwrap();
            for k in 0..=200 {
                let x = -0.01 + 0.28 * k as f64 / 200.0;
                for br in [Branch::Contraction, Branch::Expansion] {
                    let (p, _) = m64.pressure_and_slope(x, f64::from(br.offset_sign()));
                    let q = f64::from(m32.pressure_mpa(x as f32, br));
                    assert!((p - q).abs() < 2e-5, "{load} N x {x} {br:?}: {p} vs {q}");
                }
            }
        }
    }

    #[test]
    fn theta_parametrisation_round_trips_through_export() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let fam = Family::from_coeffs(&coeffs);
        let m = fam.at_load(100.0);
        let cm = |x: f64| (x - m.root) * ((m.a * x - m.b) * x + m.c);
        let s = fam.rx1 - fam.r1;
        let theta = [
            fam.r1,
            fam.rx1,
            cm(fam.r1 + U1 * s),
            cm(fam.r1 + U2 * s),
            fam.rg_l,
            fam.rg_u,
            fam.gr_c,
            fam.be,
        ];
        let back = Family::from_theta(&theta, fam.fixed);
        assert!(
            (back.b - fam.b).abs() < 1e-6 * fam.b.abs(),
            "{back:?} {fam:?}"
        );
        assert!((back.c1 - fam.c1).abs() < 1e-6 * fam.c1.abs().max(1.0));
        let p = export(&back);
        let c2 = Coeffs::new(p).unwrap();
        let (m1, m2) = (
            coeffs.load_model(300.0).unwrap(),
            c2.load_model(300.0).unwrap(),
        );
        for k in 0..=50 {
            let x = 0.02 + 0.2 * k as f32 / 50.0;
            let d =
                m1.pressure_mpa(x, Branch::Contraction) - m2.pressure_mpa(x, Branch::Contraction);
            assert!(d.abs() < 1e-4, "x {x}: {d}");
        }
    }

    #[test]
    fn holdout_parses_and_masks() {
        assert_eq!("every:4".parse(), Ok(Holdout::EveryKthCycle(4)));
        assert_eq!("tail:0.2".parse(), Ok(Holdout::Tail(0.2)));
        assert_eq!("none".parse(), Ok(Holdout::None));
        assert!("every:1".parse::<Holdout>().is_err());
        assert!("tail:1.5".parse::<Holdout>().is_err());
        assert_eq!(
            heldout_mask(Holdout::EveryKthCycle(2), &[0, 0, 1, 1, 2, 3]),
            vec![false, false, true, true, false, true]
        );
        assert_eq!(
            heldout_mask(Holdout::Tail(0.25), &[0; 8]),
            vec![false, false, false, false, false, false, true, true]
        );
    }

    #[test]
    fn noise_free_data_recovers_the_parameters() {
        let truth = Params::DEFAULT;
        let rec = generate(
            &truth,
            &Protocol::quick(&[100.0, 300.0, 600.0]),
            0.0,
            0.0,
            1,
        );
        let r = fit(&rec, &FitConfig::default()).unwrap();
        assert!(r.test.total.pressure_rms_mpa < 1e-3, "{}", r.test.to_text());
        let p = r.params;
        assert!(
            (p.points.root_contraction - truth.points.root_contraction).abs() < 5e-4,
            "{p:?}"
        );
        assert!(
            (p.points.max_contraction - truth.points.max_contraction).abs() < 1e-3,
            "{p:?}"
        );
        assert!(
            (p.ellipse_height_mpa - truth.ellipse_height_mpa).abs() < 1e-3,
            "{p:?}"
        );
    }

    #[test]
    fn one_load_only_is_refused_with_a_clear_message() {
        let rec = generate(
            &Params::DEFAULT,
            &Protocol::quick(&[100.0]),
            0.001,
            0.0005,
            3,
        );
        let e = fit(&rec, &FitConfig::default()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.starts_with("generated: too few samples"), "{msg}");
        assert!(msg.contains("one load only"), "{msg}");
    }
}

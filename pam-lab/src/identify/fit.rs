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
//! # Parametrisation: every point visited is a valid model
//! The optimiser varies `R1`, `Rx1`, the constraint model's pressure at 1/3
//! and 2/3 of the stroke at the minimum load, `RG_L`, `RG_U`, `GR_c` and `be`
//! (a minimal set: the paper's four critical points over-determine a cubic
//! once `R1`, `Rx1`, `Pmax` are fixed), turned into a
//! [`pam_core::LoadFamily`] and evaluated only through pam-core.
//!
//! Most points of that space are not models the paper allows (a second real
//! root, a falling curve, at some load). So the residuals are evaluated at a
//! *feasible projection* of the optimiser's point: if the point is not a
//! valid model at every load pam-core checks (with a small margin), it is
//! moved along the straight line to an anchor that is valid by construction
//! (the same stroke, no load factors, the cubic `u³ − u² + u` over the
//! stroke), to the last valid point of that line (bisection). A penalty
//! proportional to the distance moved keeps the optimiser near the feasible
//! set. The fit therefore returns the closest valid model it reached when
//! the muscle's curve is outside the cubic family (near-linear, concave,
//! S-shaped), and says so: [`ShapeFit`].
//!
//! The exported critical points are those of [`pam_core::LoadFamily::to_params`];
//! the result is checked by `Coeffs::new` once more after the `f32`
//! rounding, and moved further toward the anchor if the rounding broke it.
//!
//! # Records
//! Isotonic records (load held, pressure swept) and isometric records
//! (contraction held at a few values, load and pressure varying) are both
//! samples of `pressure(contraction, load, branch)`: the fit needs neither
//! samples at zero pressure or `Pmax` per load nor a fixed load protocol.
//! The kind of test is detected from the record ([`TestKind`]) and decides
//! which error is the primary one in the reports (pressure for isometric
//! tests, contraction for isotonic ones).

// `!(x > y)` is deliberate in the checks below: it is also true for NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use pam_core::{Branch, Coeffs, LoadFamily, Params};
use serde::Serialize;

use crate::evaluate::errors::{error_table, load_bin, ErrorTable};
use crate::identify::reference::ReferenceSurface;
use crate::record::split::{split_branches, Split, SplitConfig};
use crate::record::{DataError, DataErrorKind, Record, Sample};

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
    /// The kind of test; `None` detects it from the record.
    pub test: Option<TestKind>,
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
            test: None,
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
    /// A setting is out of its range; nothing was read or computed.
    #[error("invalid setting `{option}`: {why}")]
    Config {
        /// The setting (its command-line name).
        option: &'static str,
        /// What is allowed.
        why: String,
    },
    /// The record cannot identify the model (too few samples, one load
    /// only, a channel that does not vary…).
    #[error(transparent)]
    Data(#[from] DataError),
    /// No valid model could be made from the record's ranges (for example
    /// a stroke outside `(-1, 1)`); pam-core's reason is given.
    #[error("{source_name}: no valid model fits this record's ranges: {error}")]
    Invalid {
        /// The record.
        source_name: String,
        /// What pam-core said of the closest candidate.
        error: pam_core::Error,
    },
    /// The optimiser failed numerically.
    #[error("{source_name}: the optimiser failed: {why}")]
    Optimiser {
        /// The record.
        source_name: String,
        /// What happened.
        why: String,
    },
    /// The fitted model's files could not be made or did not read back.
    #[error("{source_name}: the model files could not be made: {why}")]
    Export {
        /// The record.
        source_name: String,
        /// What happened.
        why: String,
    },
}

impl FitConfig {
    /// Check every setting before any work is done.
    pub fn validate(&self) -> Result<(), FitError> {
        let bad = |option: &'static str, why: &str| {
            Err(FitError::Config {
                option,
                why: why.to_string(),
            })
        };
        if let Some(p) = self.max_pressure_mpa {
            if !(p.is_finite() && p > 0.0 && p <= 10.0) {
                return bad("--pmax", "must be a number in (0, 10] MPa");
            }
        }
        if !(self.load_step_n.is_finite() && self.load_step_n >= 1e-3) {
            return bad("--load-step", "must be a finite number of newtons >= 0.001");
        }
        if !(self.load_bin_n.is_finite() && self.load_bin_n >= 1e-3) {
            return bad("--load-bin", "must be a finite number of newtons >= 0.001");
        }
        if let Some(d) = self.split.deadband_mpa {
            if !(d.is_finite() && d >= 0.0) {
                return bad("--deadband", "must be a finite pressure >= 0 MPa");
            }
        }
        if let Some(g) = self.split.guard_mpa {
            if !(g.is_finite() && g >= 0.0) {
                return bad("--guard", "must be a finite pressure >= 0 MPa");
            }
        }
        if self.split.smooth_samples == 0 {
            return bad("--smooth", "must be at least 1 sample");
        }
        if self.min_samples_per_group == 0 {
            return bad("--min-samples", "must be at least 1");
        }
        if self.patience == 0 {
            return bad("--patience", "must be at least 1");
        }
        if let Holdout::Tail(f) = self.holdout {
            if !(f > 0.0 && f < 1.0) {
                return bad("--holdout", "tail fraction must be in (0, 1)");
            }
        }
        if let Holdout::EveryKthCycle(k) = self.holdout {
            if k < 2 {
                return bad("--holdout", "every:K needs K >= 2");
            }
        }
        Ok(())
    }
}

/// The kind of characterisation test a record is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TestKind {
    /// Load held at a few values, pressure swept, contraction measured.
    Isotonic,
    /// Contraction held at a few values, pressure swept, load (force) measured.
    Isometric,
    /// Neither channel holds: load and contraction both move.
    Mixed,
}

impl std::str::FromStr for TestKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "isotonic" => Ok(TestKind::Isotonic),
            "isometric" => Ok(TestKind::Isometric),
            "mixed" => Ok(TestKind::Mixed),
            _ => Err(format!(
                "test `{s}`: expected `isotonic`, `isometric` or `mixed`"
            )),
        }
    }
}

impl std::fmt::Display for TestKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            TestKind::Isotonic => "isotonic",
            TestKind::Isometric => "isometric",
            TestKind::Mixed => "mixed",
        })
    }
}

/// How well the paper's cubic family can follow the record's static curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ShapeFit {
    /// Systematic pressure misfit on the training samples, MPa: the RMS of
    /// the mean residual per (load bin, branch, 1/20 of the stroke) cell,
    /// weighted by samples. Noise averages out of it; shape error does not.
    pub systematic_pressure_rms_mpa: f64,
    /// The record's pressure noise, MPa (standard deviation).
    pub pressure_noise_mpa: f64,
    /// The fitted model lies at the edge of the shapes the paper allows
    /// (the optimiser pressed against the one-real-root or monotone
    /// condition at some load): the data would pull it outside.
    pub at_shape_limit: bool,
    /// Smallest shape margin over the calibrated loads, relative to the mean
    /// slope (see `pam_core::ShapeMargins::relative`).
    pub worst_shape_margin: f64,
}

impl ShapeFit {
    /// Whether the static curve is beyond what the cubic family can follow:
    /// pressed against the shape limits with a systematic misfit above
    /// twice the noise.
    pub fn cubic_cannot_follow(&self) -> bool {
        self.at_shape_limit && self.systematic_pressure_rms_mpa > 2.0 * self.pressure_noise_mpa
    }

    /// One sentence for a report.
    pub fn statement(&self) -> String {
        let ratio = self.systematic_pressure_rms_mpa / self.pressure_noise_mpa.max(1e-12);
        if self.cubic_cannot_follow() {
            format!(
                "the paper's cubic cannot follow this muscle's static curve: the fit is the closest \
                 valid model, pressed against the paper's shape conditions, with a systematic \
                 pressure misfit of {:.4} MPa RMS ({ratio:.1}x the {:.4} MPa noise)",
                self.systematic_pressure_rms_mpa, self.pressure_noise_mpa
            )
        } else {
            format!(
                "systematic pressure misfit {:.4} MPa RMS ({ratio:.1}x the {:.4} MPa noise){}",
                self.systematic_pressure_rms_mpa,
                self.pressure_noise_mpa,
                if self.at_shape_limit {
                    "; the fit touches the paper's shape conditions"
                } else {
                    ""
                }
            )
        }
    }
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
    /// The identified parameters (`Coeffs::new` accepts them, always).
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
    /// The kind of test (given or detected).
    pub test_kind: TestKind,
    /// How well the cubic family follows the record's static curve.
    pub shape: ShapeFit,
    /// The best smooth static surface on the same training samples
    /// ([`ReferenceSurface`]), when there are enough of them.
    pub reference: Option<ReferenceSurface>,
    /// The reference's RMS pressure error on the samples of `test`, MPa.
    pub reference_test_rms_mpa: Option<f64>,
}

/// A fitted model and its reference surface on a record neither was
/// fitted to (`pam-lab fit --validate`).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Validation {
    /// The record.
    pub source: String,
    /// The model's errors per load bin and branch.
    pub model: ErrorTable,
    /// The reference surface's RMS pressure error on the same samples, MPa.
    pub reference_rms_mpa: Option<f64>,
}

/// Evaluate a fit on another record: its branches split as the fit split
/// its own, slack samples of an isometric test left out as the fit leaves
/// them out.
pub fn validate(report: &FitReport, record: &Record, cfg: &FitConfig) -> Validation {
    let samples = &record.samples;
    let split = split_branches(samples, &cfg.split);
    let slack = slack_mask(samples, report.test_kind);
    let include = |i: usize| split.branch[i].is_some() && !slack[i];
    let model = error_table(
        &report.coeffs,
        samples,
        &split.branch,
        |i| !slack[i],
        cfg.load_bin_n,
    );
    Validation {
        source: record.source.clone(),
        model,
        reference_rms_mpa: report
            .reference
            .as_ref()
            .and_then(|r| r.rms_mpa(samples, include))
            .map(|(rms, _)| rms),
    }
}

// ---------------------------------------------------------------------------
// The fitted variables and the feasible set.

/// Number of fitted parameters.
const NP: usize = 8;
/// Fractions of the stroke at which the minimum-load cubic is parametrised.
const U1: f64 = 1.0 / 3.0;
const U2: f64 = 2.0 / 3.0;
/// Shape margin (relative to the mean slope) every visited point keeps, so
/// that the `f32` rounding of the export stays inside pam-core's check.
const SHAPE_MARGIN: f64 = 1e-3;
/// Largest ellipse height the fit considers, as a fraction of `Pmax`
/// (pam-core allows up to one half).
const MAX_HEIGHT_OF_PMAX: f64 = 0.45;
/// The stroke at the maximum load may not shrink below this fraction of
/// the stroke at the minimum load.
const MIN_STROKE_RATIO: f64 = 0.05;
/// Bisection steps of the feasible projection.
const PROJECTION_STEPS: usize = 40;

/// Fixed quantities of a fit.
#[derive(Clone, Copy, Debug)]
struct Fixed {
    pmax: f64,
    min_load_n: f64,
    max_load_n: f64,
    load_step_n: f64,
}

/// The valid-by-construction cubic `g(u) = u³ − u² + u` over the stroke
/// (`g(0) = 0`, `g(1) = 1`, `g' ≥ 2/3`, quadratic factor `u² − u + 1 ≥ 3/4`).
fn anchor_shape(u: f64) -> f64 {
    u * (u * u - u + 1.0)
}

/// pam-core's load family for the fit vector
/// `[R1, Rx1, y(1/3), y(2/3), RG_L, RG_U, GR_c, be]`.
fn family(t: &[f64], fixed: &Fixed) -> LoadFamily {
    let (r1, rx1) = (t[0], t[1]);
    let s = rx1 - r1;
    // The quadratic factor q(x) = a x² − b x + c through the points
    // (x_k, y_k/(x_k − R1)): Lagrange interpolation, then its coefficients.
    let xs = [r1 + U1 * s, r1 + U2 * s, rx1];
    let ys = [t[2], t[3], fixed.pmax];
    let (mut qb, mut qc) = (0.0, 0.0); // q = qa x² + qb x + qc; qa follows from eq. (16)
    for k in 0..3 {
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let w = ys[k] / (xs[k] - r1) / ((xs[k] - xs[i]) * (xs[k] - xs[j]));
        qb -= w * (xs[i] + xs[j]);
        qc += w * xs[i] * xs[j];
    }
    LoadFamily {
        min_load_n: fixed.min_load_n,
        max_load_n: fixed.max_load_n,
        load_step_n: fixed.load_step_n,
        max_pressure_mpa: fixed.pmax,
        root_contraction: r1,
        max_contraction: rx1,
        b: -qb,
        c: qc,
        root_regression_per_step: t[4],
        max_regression_per_step: t[5],
        c_growth_per_step: t[6],
        ellipse_height_mpa: t[7],
    }
}

/// Whether `t` is a model the fit may visit: pam-core's shape check with a
/// margin at every checked load, an open stroke at every load, a height in
/// `[0, 0.45·Pmax]`.
fn feasible(t: &[f64], fixed: &Fixed) -> bool {
    if !t.iter().all(|v| v.is_finite()) {
        return false;
    }
    let be = t[7];
    if !(be >= 0.0 && be <= MAX_HEIGHT_OF_PMAX * fixed.pmax) {
        return false;
    }
    let stroke1 = t[1] - t[0];
    if !(stroke1 > 0.0) {
        return false;
    }
    let fam = family(t, fixed);
    let top = fam.at_load(fixed.max_load_n);
    if !(top.max_contraction - top.cubic.root >= MIN_STROKE_RATIO * stroke1) {
        return false;
    }
    fam.check(SHAPE_MARGIN).is_ok()
}

/// The anchor for a stroke `[r1, rx1]`: no load factors, the cubic
/// [`anchor_shape`], height `be`. Feasible whenever the stroke lies inside
/// `(-1, 1)` and `0 ≤ be ≤ 0.45·Pmax`.
fn anchor(r1: f64, rx1: f64, be: f64, pmax: f64) -> [f64; NP] {
    [
        r1,
        rx1,
        pmax * anchor_shape(U1),
        pmax * anchor_shape(U2),
        0.0,
        0.0,
        0.0,
        be,
    ]
}

/// The last feasible point on the segment from `anchor` (feasible) to `t`,
/// and whether `t` itself was feasible.
fn project(t: &[f64], anchor: &[f64; NP], fixed: &Fixed) -> ([f64; NP], bool) {
    let mut out = [0.0; NP];
    let at = |s: f64, out: &mut [f64; NP]| {
        for j in 0..NP {
            out[j] = anchor[j] + s * (t[j] - anchor[j]);
        }
    };
    at(1.0, &mut out);
    if feasible(&out, fixed) {
        return (out, true);
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..PROJECTION_STEPS {
        let mid = 0.5 * (lo + hi);
        at(mid, &mut out);
        if feasible(&out, fixed) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    at(lo, &mut out);
    (out, false)
}

/// The fitted point as pam-core parameters (an ellipse height below pam-core's
/// smallest non-zero one is zero).
fn export(t: &[f64], fixed: &Fixed) -> Params {
    let mut p = family(t, fixed).to_params();
    if p.ellipse_height_mpa < pam_core::coeffs::MIN_ELLIPSE_HEIGHT_MPA {
        p.ellipse_height_mpa = 0.0;
    }
    p
}

// ---------------------------------------------------------------------------
// The least-squares problem.

/// Training samples, sorted by load so that the per-load model is computed
/// once per run of equal loads.
struct TrainSet {
    x: Vec<f64>,
    p: Vec<f64>,
    branch: Vec<Branch>,
    /// `(load, start, end)` runs of equal load.
    runs: Vec<(f64, usize, usize)>,
    sigma_p: f64,
    sigma_x: f64,
}

impl TrainSet {
    fn len(&self) -> usize {
        self.x.len()
    }

    /// Weighted residuals of the family `fam` into `out[..len]`.
    fn residuals(&self, fam: &LoadFamily, out: &mut [f64]) {
        let (vp, vx) = (self.sigma_p * self.sigma_p, self.sigma_x * self.sigma_x);
        for &(load, start, end) in &self.runs {
            let m = fam.at_load(load);
            let rows = self.x[start..end]
                .iter()
                .zip(&self.branch[start..end])
                .zip(&self.p[start..end]);
            for (o, ((&x, &br), &pm)) in out[start..end].iter_mut().zip(rows) {
                let (p, slope) = m.pressure_and_slope(x, br, 1.0);
                *o = (p - pm) / (vp + slope * slope * vx).sqrt();
            }
        }
    }
}

struct Problem<'a> {
    theta: DVector<f64>,
    anchor: [f64; NP],
    data: &'a TrainSet,
    fixed: Fixed,
    /// Weight of the distance to the feasible set, per parameter scale.
    penalty_weight: f64,
    evaluations: std::sync::atomic::AtomicUsize,
    progress: &'a (dyn Fn(Progress) + Sync),
}

impl Problem<'_> {
    fn n_residuals(&self) -> usize {
        self.data.len() + NP
    }

    fn residuals_at(&self, theta: &[f64], out: &mut [f64]) {
        let (inside, _) = project(theta, &self.anchor, &self.fixed);
        let n = self.data.len();
        self.data
            .residuals(&family(&inside, &self.fixed), &mut out[..n]);
        for j in 0..NP {
            out[n + j] = self.penalty_weight * (theta[j] - inside[j]) / param_scale(j, &self.fixed);
        }
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
        let theta: Vec<f64> = self.theta.iter().copied().collect();
        let steps: Vec<f64> = theta
            .iter()
            .enumerate()
            .map(|(j, v)| 1e-7 * v.abs().max(param_scale(j, &self.fixed)))
            .collect();
        Some(crate::identify::lsq::forward_difference_jacobian(
            &theta,
            &steps,
            self.n_residuals(),
            &|t, out| self.residuals_at(t, out),
        ))
    }
}

/// Typical magnitude of parameter `j`, for finite-difference steps and the
/// feasibility penalty.
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
        Holdout::EveryKthCycle(k) => cycle.iter().map(|c| k >= 2 && c % k == k - 1).collect(),
        Holdout::Tail(f) => {
            let first = ((1.0 - f) * n as f64).round() as usize;
            (0..n).map(|i| i >= first).collect()
        }
    }
}

/// Share of samples at which a channel is holding: its smoothed value moves
/// less than `tol` over `lag` samples.
fn holding_share(v: &[f64], lag: usize, tol: f64) -> f64 {
    if v.len() <= lag {
        return 1.0;
    }
    let s = crate::record::split::moving_average(v, 9);
    let held = s
        .windows(lag + 1)
        .filter(|w| (w[lag] - w[0]).abs() <= tol)
        .count();
    held as f64 / (s.len() - lag) as f64
}

/// Detect the kind of test: the channel that holds while the pressure
/// sweeps. A channel holds at a sample when it moves by less than 1 % of
/// its range (and 3× its noise) over 1 % of the record; the test is
/// isotonic (isometric) when the load (contraction) holds at a quarter of
/// the samples more than the other channel, else mixed.
pub fn detect_test(samples: &[Sample]) -> TestKind {
    let x: Vec<f64> = samples.iter().map(|s| s.contraction).collect();
    let l: Vec<f64> = samples.iter().map(|s| s.load_n).collect();
    let range = |v: &[f64]| {
        let q = |f| quantile(v.to_vec(), f).unwrap_or(0.0);
        q(0.99) - q(0.01)
    };
    let lag = (samples.len() / 100).clamp(5, 1000);
    let tol = |v: &[f64]| (0.01 * range(v)).max(3.0 * crate::record::noise_std(v.iter().copied()));
    let (hx, hl) = (
        holding_share(&x, lag, tol(&x)),
        holding_share(&l, lag, tol(&l)),
    );
    // One channel holds clearly more often than the other.
    if hl > hx + 0.25 {
        TestKind::Isotonic
    } else if hx > hl + 0.25 {
        TestKind::Isometric
    } else {
        TestKind::Mixed
    }
}

/// The samples of an isometric test where the force is at the load cell's
/// floor (5× its noise, at least 1 % of the record's largest load): a slack
/// muscle held by the fixture, not a muscle in balance with 0 N. Such
/// samples bound the model (pressure below the 0 N curve) but are no sample
/// of it. None in other tests.
pub fn slack_mask(samples: &[Sample], test: TestKind) -> Vec<bool> {
    if test == TestKind::Isometric {
        let max_load = samples.iter().map(|s| s.load_n).fold(0.0, f64::max);
        let noise = crate::record::noise_std(samples.iter().map(|s| s.load_n));
        let floor = (5.0 * noise).max(0.01 * max_load);
        samples.iter().map(|s| s.load_n <= floor).collect()
    } else {
        vec![false; samples.len()]
    }
}

/// Mistakes a record shows against the options, before any work: a
/// `--test` the record contradicts, a `--pmax` below most of the samples,
/// and (isotonic records) a contraction that falls as the pressure rises.
fn check_against_record(
    record: &Record,
    cfg: &FitConfig,
    detected: TestKind,
) -> Result<(), FitError> {
    let samples = &record.samples;
    if let Some(given) = cfg.test {
        let pure = |k| matches!(k, TestKind::Isotonic | TestKind::Isometric);
        if pure(given) && pure(detected) && given != detected {
            let (holds, moves) = match detected {
                TestKind::Isotonic => ("load", "contraction"),
                _ => ("contraction", "load"),
            };
            return Err(FitError::Config {
                option: "--test",
                why: format!(
                    "`{given}`, but in {} the {holds} holds while the {moves} moves: it is \
                     {detected} (leave --test out to detect it, or check the columns)",
                    record.source
                ),
            });
        }
    }
    if let Some(pmax) = cfg.max_pressure_mpa {
        let above = samples.iter().filter(|s| s.pressure_mpa > pmax).count();
        let top = samples
            .iter()
            .map(|s| s.pressure_mpa)
            .fold(f64::MIN, f64::max);
        if 2 * above > samples.len() {
            return Err(FitError::Config {
                option: "--pmax",
                why: format!(
                    "{pmax} MPa, but {:.0} % of the samples of {} lie above it (its top is {} \
                     MPa): Pmax is where the loop closes, at the top of the record; leave \
                     --pmax out to measure it",
                    100.0 * above as f64 / samples.len() as f64,
                    record.source,
                    crate::record::num(top)
                ),
            });
        }
    }
    let test = cfg.test.unwrap_or(detected);
    if test == TestKind::Isotonic {
        let r = crate::record::correlation(samples, |s| s.pressure_mpa, |s| s.contraction);
        if r < -0.5 {
            return Err(FitError::Data(DataError {
                file: record.source.clone(),
                line: 0,
                column: Some("contraction".into()),
                kind: DataErrorKind::Implausible(format!(
                    "falls as the pressure rises (correlation {r:.2} over the record): a muscle \
                     shortens when pressurised, so contraction = (rest length − length)/rest \
                     length rises with pressure; is its sign flipped?"
                )),
            }));
        }
    }
    Ok(())
}

/// Identify the model from `record`; `progress` hears about long work.
pub fn fit_with_progress(
    record: &Record,
    cfg: &FitConfig,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<FitReport, FitError> {
    cfg.validate()?;
    let samples = &record.samples;
    let data_err = |line: u64, column: Option<&str>, what: String| {
        FitError::Data(DataError {
            file: record.source.clone(),
            line,
            column: column.map(str::to_string),
            kind: DataErrorKind::TooFewSamples(what),
        })
    };
    // At least a handful of samples per fitted parameter and branch.
    let min_samples = 4 * NP;
    if samples.len() < 2 * min_samples {
        return Err(data_err(
            0,
            None,
            format!(
                "the record has {} samples; the fit needs at least {}",
                samples.len(),
                2 * min_samples
            ),
        ));
    }
    // Channels that must vary: time, pressure, contraction.
    let spread = |f: &dyn Fn(&Sample) -> f64| {
        let v: Vec<f64> = samples.iter().map(f).collect();
        let noise = crate::record::noise_std(v.iter().copied());
        let q = |p| quantile(v.clone(), p).unwrap_or(0.0);
        (q(0.99) - q(0.01), noise)
    };
    let (t0, t1) = (samples[0].t_s, samples[samples.len() - 1].t_s);
    if !(t1 > t0) {
        return Err(data_err(
            0,
            Some("t_s"),
            format!("time never increases (every time stamp is {t0} s)"),
        ));
    }
    let (p_range, _) = spread(&|s| s.pressure_mpa);
    if !(p_range > 0.01) {
        return Err(data_err(
            0,
            Some("pressure_mpa"),
            format!(
                "the pressure hardly varies ({p_range:.2e} MPa between its 1st and 99th \
                 percentiles; the model needs a sweep of at least 0.01 MPa)"
            ),
        ));
    }
    let (x_range, x_noise) = spread(&|s| s.contraction);
    if !(x_range > (10.0 * x_noise).max(1e-3)) {
        return Err(data_err(
            0,
            Some("contraction"),
            format!(
                "the contraction hardly varies ({x_range:.2e} between its 1st and 99th \
                 percentiles; is the sensor connected?)"
            ),
        ));
    }
    let detected = detect_test(samples);
    let test = cfg.test.unwrap_or(detected);
    check_against_record(record, cfg, detected)?;

    progress(Progress::Stage("splitting branches"));
    let split = split_branches(samples, &cfg.split);
    let heldout = heldout_mask(cfg.holdout, &split.cycle);
    // In an isometric test a force at the load cell's floor means a slack
    // muscle held by the fixture, not a muscle in balance with 0 N: such
    // samples bound the model (pressure below the 0 N curve) but are no
    // sample of it, and are left out of fit and errors.
    let slack = slack_mask(samples, test);
    let is_train = |i: usize| split.branch[i].is_some() && !heldout[i] && !slack[i];

    // Pmax: given, or the top of the smoothed pressure (the noise averaged out).
    let (pmax, pmax_source) = match cfg.max_pressure_mpa {
        Some(p) => (p, PmaxSource::Given),
        None => {
            let p: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
            let ps = crate::record::split::moving_average(&p, 9);
            (ps.iter().copied().fold(0.0, f64::max), PmaxSource::Measured)
        }
    };
    if !(pmax > 0.0 && pmax <= 10.0) {
        return Err(data_err(
            0,
            Some("pressure_mpa"),
            format!("Pmax {pmax} MPa is not in (0, 10] (does the pressure ever rise?)"),
        ));
    }

    // The calibrated load range: the median loads of the lowest and highest
    // load bins (a load cell's noise must not move the minimum load, which
    // is where the critical points are taken), never below 0 N.
    let bin = cfg.load_bin_n;
    let key_of = |load_n: f64| (load_n / bin).round() as i64;
    let in_use = || {
        samples
            .iter()
            .zip(&slack)
            .filter(|(_, sl)| !**sl)
            .map(|(s, _)| s)
    };
    let lowest = in_use().map(|s| key_of(s.load_n)).min();
    let highest = in_use().map(|s| key_of(s.load_n)).max();
    let median_in = |key: Option<i64>| {
        quantile(
            in_use()
                .filter(|s| Some(key_of(s.load_n)) == key)
                .map(|s| s.load_n)
                .collect(),
            0.5,
        )
        .unwrap_or(0.0)
    };
    let min_load_n = median_in(lowest).max(0.0);
    let max_load_n = median_in(highest).max(min_load_n);

    // Enough training samples on each branch, and a second load bin with
    // both branches for the load factors.
    let mut groups: std::collections::BTreeMap<i64, [usize; 2]> = Default::default();
    let mut first_line: std::collections::BTreeMap<i64, u64> = Default::default();
    let mut per_branch = [0usize; 2];
    for (i, s) in samples.iter().enumerate() {
        if !is_train(i) {
            continue;
        }
        let key = key_of(s.load_n);
        let b = usize::from(split.branch[i] == Some(Branch::Expansion));
        groups.entry(key).or_default()[b] += 1;
        per_branch[b] += 1;
        first_line.entry(key).or_insert(record.line(i));
    }
    if per_branch[0] < min_samples || per_branch[1] < min_samples {
        return Err(data_err(
            0,
            Some("pressure_mpa"),
            format!(
                "{} contraction-branch and {} expansion-branch training samples (rising and \
                 falling pressure), need {min_samples} of each (does the pressure go up and \
                 down, and is a whole cycle left after the hold-out?)",
                per_branch[0], per_branch[1]
            ),
        ));
    }
    let need = cfg
        .min_samples_per_group
        .min(per_branch[0])
        .min(per_branch[1]);
    let usable = groups
        .values()
        .filter(|c| c[0] >= need && c[1] >= need)
        .count();
    if groups.len() < 2 || usable < 2 {
        let describe = |k: i64| {
            let c = groups.get(&k).copied().unwrap_or_default();
            format!(
                "load {} N (first training line {}): {} contraction-branch and {} \
                 expansion-branch training samples",
                load_bin(k as f64 * bin, bin),
                first_line.get(&k).copied().unwrap_or(1),
                c[0],
                c[1]
            )
        };
        let all: Vec<String> = groups.keys().map(|k| describe(*k)).collect();
        return Err(data_err(
            0,
            Some("load_n"),
            format!(
                "the load factors need two loads (bins of {bin} N) with {need} samples on \
                 each branch; {}{}",
                if groups.len() < 2 {
                    "the record has one load only: "
                } else {
                    ""
                },
                all.join("; ")
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
        branch: Vec::with_capacity(idx.len()),
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
            .branch
            .push(split.branch[i].unwrap_or(Branch::Contraction));
    }

    progress(Progress::Stage("initial guess"));
    let raw = initial_guess(samples, &split, &is_train, &fixed, bin);
    let anchor = anchor(raw[0], raw[1], raw[7], pmax);
    if !feasible(&anchor, &fixed) {
        let error =
            Coeffs::new(export(&anchor, &fixed))
                .err()
                .unwrap_or(pam_core::Error::OutOfRange(
                    "root_contraction",
                    "the record's stroke leaves (-1, 1)",
                ));
        return Err(FitError::Invalid {
            source_name: record.source.clone(),
            error,
        });
    }
    let (theta0, _) = project(&raw, &anchor, &fixed);
    let initial = export(&theta0, &fixed);

    progress(Progress::Stage("least squares"));
    let problem = Problem {
        theta: DVector::from_column_slice(&theta0),
        anchor,
        data: &train,
        fixed,
        penalty_weight: (train.len() as f64).sqrt(),
        evaluations: Default::default(),
        progress,
    };
    let (problem, report) = LevenbergMarquardt::new()
        .with_patience(cfg.patience)
        .minimize(problem);
    let evaluations = problem
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
    let (theta, was_inside) = project(problem.theta.as_slice(), &anchor, &fixed);

    // The f32 export must pass pam-core's own check; the margin makes that
    // the rule, and where rounding still breaks it, step toward the anchor.
    let mut accepted = None;
    let mut last_error = pam_core::Error::Singular;
    for k in 0..=PROJECTION_STEPS {
        let s = 1.0 - (k as f64 / PROJECTION_STEPS as f64);
        let t: Vec<f64> = (0..NP)
            .map(|j| anchor[j] + s * (theta[j] - anchor[j]))
            .collect();
        let params = export(&t, &fixed);
        match Coeffs::new(params) {
            Ok(coeffs) => {
                accepted = Some((t, params, coeffs));
                break;
            }
            Err(e) => last_error = e,
        }
    }
    let Some((theta, params, coeffs)) = accepted else {
        return Err(FitError::Invalid {
            source_name: record.source.clone(),
            error: last_error,
        });
    };

    progress(Progress::Stage("errors"));
    let fam = family(&theta, &fixed);
    let worst_shape_margin = fam.worst_margin();
    let shape = ShapeFit {
        systematic_pressure_rms_mpa: systematic_misfit(&train, &fam, bin),
        pressure_noise_mpa: split.pressure_noise_mpa,
        at_shape_limit: !was_inside || worst_shape_margin < 2.0 * SHAPE_MARGIN,
        worst_shape_margin,
    };
    let train_table = error_table(
        &coeffs,
        samples,
        &split.branch,
        |i| !heldout[i] && !slack[i],
        bin,
    );
    let any_heldout = heldout.iter().any(|h| *h);
    let test_table = if any_heldout {
        error_table(
            &coeffs,
            samples,
            &split.branch,
            |i| heldout[i] && !slack[i],
            bin,
        )
    } else {
        train_table.clone()
    };
    let labelled = |i: usize| split.branch[i].is_some() && !slack[i];
    let reference = ReferenceSurface::fit(samples, |i| labelled(i) && !heldout[i]);
    let reference_test_rms_mpa = reference
        .as_ref()
        .and_then(|r| r.rms_mpa(samples, |i| labelled(i) && (heldout[i] || !any_heldout)))
        .map(|(rms, _)| rms);
    Ok(FitReport {
        params,
        coeffs,
        reference,
        reference_test_rms_mpa,
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
        test_kind: test,
        shape,
    })
}

/// RMS of the mean pressure residual per (load bin, branch, 1/20 of the
/// stroke) cell, weighted by the cell's samples.
fn systematic_misfit(train: &TrainSet, fam: &LoadFamily, bin: f64) -> f64 {
    let mut cells: std::collections::HashMap<(i64, bool, i64), (f64, usize)> = Default::default();
    for &(load, start, end) in &train.runs {
        let m = fam.at_load(load);
        let stroke = (m.max_contraction - m.cubic.root).max(1e-6);
        for i in start..end {
            let (x, br) = (train.x[i], train.branch[i]);
            let r = m.pressure_mpa(x, br) - train.p[i];
            let key = (
                (load / bin).round() as i64,
                br == Branch::Expansion,
                ((x - m.cubic.root) / stroke * 20.0).floor() as i64,
            );
            let c = cells.entry(key).or_default();
            c.0 += r;
            c.1 += 1;
        }
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for (s, k) in cells.values() {
        // Cells of a few samples carry their noise: they are left out.
        if *k >= 5 {
            let mean = s / *k as f64;
            sum += mean * mean * *k as f64;
            n += k;
        }
    }
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

/// A starting point from the data (not necessarily feasible: it is
/// projected). Stroke ends: where the record has samples near zero and full
/// pressure at the minimum load (isotonic tests), their median contraction;
/// otherwise (isometric tests, partial sweeps) where a surface
/// `p = k0 + k1·x + k2·s + k3·x·s` fitted to all training samples reaches 0
/// and `Pmax`. Load factors from the same ends per load bin or the surface;
/// the cubic's interior values from the mean of both branches; the ellipse
/// height from the gap between the branches at mid-stroke.
fn initial_guess(
    samples: &[Sample],
    split: &Split,
    is_train: &dyn Fn(usize) -> bool,
    fixed: &Fixed,
    bin: f64,
) -> [f64; NP] {
    let pmax = fixed.pmax;
    let steps = |load_n: f64| (load_n - fixed.min_load_n) / fixed.load_step_n;
    let max_steps = steps(fixed.max_load_n);
    // Per load bin: the contractions near zero pressure and near Pmax.
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
    let surface = bilinear_surface(samples, is_train, &steps);
    let from_surface = |p: f64, s: f64| {
        surface.and_then(|k| {
            let slope = k[1] + k[3] * s;
            let x = (p - k[0] - k[2] * s) / slope;
            (slope > 0.0 && x.is_finite()).then_some(x)
        })
    };
    let measured = ends
        .get(&min_key)
        .filter(|(lo, hi)| lo.len() >= 5 && hi.len() >= 5)
        .and_then(|(lo, hi)| Some((quantile(lo.clone(), 0.5)?, quantile(hi.clone(), 0.5)?)));
    let all_x: Vec<f64> = samples.iter().map(|s| s.contraction).collect();
    let x_lo = quantile(all_x.clone(), 0.01).unwrap_or(0.0);
    let x_hi = quantile(all_x, 0.99).unwrap_or(0.2);
    let (r1, rx1) = match (measured, from_surface(0.0, 0.0), from_surface(pmax, 0.0)) {
        (Some(m), _, _) => m,
        (None, Some(a), Some(b)) => (a, b),
        _ => (x_lo, x_hi),
    };
    // Keep the stroke open and inside (-1, 1) so the anchor is a model.
    let r1 = r1.clamp(-0.5, 0.8);
    let rx1 = if rx1 > r1 + 1e-3 {
        rx1.min(0.95)
    } else {
        (r1 + 0.1).min(0.95)
    };
    // Regression of the ends on the load step count.
    let slope_of = |pick: &dyn Fn(&Ends) -> &Vec<f64>, p: f64| {
        let pts: Vec<(f64, f64)> = ends
            .iter()
            .filter(|(_, e)| pick(e).len() >= 5)
            .filter_map(|(k, e)| {
                quantile(pick(e).clone(), 0.5).map(|x| (steps(*k as f64 * bin), x))
            })
            .collect();
        if pts.len() < 2 {
            // The surface's ends at the two ends of the load range.
            return match (from_surface(p, 0.0), from_surface(p, max_steps)) {
                (Some(a), Some(b)) if max_steps > 0.0 => -(b - a) / max_steps,
                _ => 0.0,
            };
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
    let rg_l = slope_of(&|e| &e.0, 0.0);
    let rg_u = slope_of(&|e| &e.1, pmax);

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
        (n >= 5).then(|| s / n as f64)
    };
    let cm_at = |u: f64| {
        let x0 = r1 + u * stroke;
        match (
            mean_near(x0, Branch::Contraction),
            mean_near(x0, Branch::Expansion),
        ) {
            (Some(a), Some(b)) => 0.5 * (a + b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => pmax * anchor_shape(u),
        }
    };
    let (y1, y2) = (cm_at(U1), cm_at(U2));
    let be = match (
        mean_near(r1 + 0.5 * stroke, Branch::Contraction),
        mean_near(r1 + 0.5 * stroke, Branch::Expansion),
    ) {
        (Some(a), Some(b)) => (0.5 * (a - b)).clamp(0.0, 0.25 * pmax),
        _ => branch_gap(samples, split, is_train).clamp(0.0, 0.25 * pmax),
    };
    [r1, rx1, y1, y2.max(y1 + 1e-3 * pmax), rg_l, rg_u, 0.0, be]
}

/// Least-squares `p ≈ k0 + k1·x + k2·s + k3·x·s` over the training samples
/// (`s` the load step count), or `None` when singular.
fn bilinear_surface(
    samples: &[Sample],
    is_train: &dyn Fn(usize) -> bool,
    steps: &dyn Fn(f64) -> f64,
) -> Option<[f64; 4]> {
    let mut ata = nalgebra::Matrix4::<f64>::zeros();
    let mut atb = nalgebra::Vector4::<f64>::zeros();
    for (i, s) in samples.iter().enumerate() {
        if !is_train(i) {
            continue;
        }
        let st = steps(s.load_n);
        let row = nalgebra::Vector4::new(1.0, s.contraction, st, s.contraction * st);
        ata += row * row.transpose();
        atb += row * s.pressure_mpa;
    }
    let k = ata.lu().solve(&atb)?;
    k.iter()
        .all(|v| v.is_finite())
        .then(|| [k[0], k[1], k[2], k[3]])
}

/// Half the typical pressure gap between the branches at equal contraction
/// and load: the mean rising-branch minus falling-branch pressure over
/// cells of (load bin of 5 % of the loads, 1/20 of the contraction range).
fn branch_gap(samples: &[Sample], split: &Split, is_train: &dyn Fn(usize) -> bool) -> f64 {
    let xs: Vec<f64> = samples.iter().map(|s| s.contraction).collect();
    let ls: Vec<f64> = samples.iter().map(|s| s.load_n).collect();
    let (x0, x1) = (
        quantile(xs.clone(), 0.0).unwrap_or(0.0),
        quantile(xs, 1.0).unwrap_or(1.0),
    );
    let (l0, l1) = (
        quantile(ls.clone(), 0.0).unwrap_or(0.0),
        quantile(ls, 1.0).unwrap_or(1.0),
    );
    let cell = |s: &Sample| {
        (
            ((s.contraction - x0) / (x1 - x0).max(1e-9) * 20.0) as i64,
            ((s.load_n - l0) / (l1 - l0).max(1e-9) * 20.0) as i64,
        )
    };
    let mut acc: std::collections::HashMap<(i64, i64), [(f64, usize); 2]> = Default::default();
    for (i, s) in samples.iter().enumerate() {
        let Some(br) = split.branch[i].filter(|_| is_train(i)) else {
            continue;
        };
        let a = &mut acc.entry(cell(s)).or_default()[usize::from(br == Branch::Expansion)];
        a.0 += s.pressure_mpa;
        a.1 += 1;
    }
    let gaps: Vec<f64> = acc
        .values()
        .filter(|c| c[0].1 >= 3 && c[1].1 >= 3)
        .map(|c| 0.5 * (c[0].0 / c[0].1 as f64 - c[1].0 / c[1].1 as f64))
        .collect();
    quantile(gaps, 0.5).unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Protocol};

    fn fixed() -> Fixed {
        Fixed {
            pmax: 0.5,
            min_load_n: 100.0,
            max_load_n: 600.0,
            load_step_n: 100.0,
        }
    }

    #[test]
    fn the_anchor_is_a_valid_model_for_any_stroke() {
        let f = fixed();
        for (r1, rx1) in [(0.0, 0.2), (-0.3, 0.9), (0.1, 0.1011), (0.5, 0.95)] {
            for be in [0.0, 0.01, 0.2] {
                let a = anchor(r1, rx1, be, f.pmax);
                assert!(feasible(&a, &f), "{r1} {rx1} {be}");
                Coeffs::new(export(&a, &f)).unwrap();
            }
        }
    }

    #[test]
    fn the_projection_always_lands_on_a_valid_model() {
        // Points far outside the feasible set in every direction.
        let f = fixed();
        let a = anchor(0.02, 0.22, 0.02, f.pmax);
        let mut rng = crate::synth::Rng::new(5);
        for _ in 0..2000 {
            let t: Vec<f64> = (0..NP)
                .map(|j| a[j] + param_scale(j, &f) * 20.0 * (rng.uniform() - 0.5))
                .collect();
            let (p, inside) = project(&t, &a, &f);
            assert!(feasible(&p, &f));
            assert_eq!(inside, feasible(&t, &f));
        }
    }

    #[test]
    fn theta_parametrisation_round_trips_through_export() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let fam = *coeffs.family();
        let m = fam.at_load(fam.min_load_n);
        let s = fam.max_contraction - fam.root_contraction;
        let theta = [
            fam.root_contraction,
            fam.max_contraction,
            m.cubic.eval(fam.root_contraction + U1 * s),
            m.cubic.eval(fam.root_contraction + U2 * s),
            fam.root_regression_per_step,
            fam.max_regression_per_step,
            fam.c_growth_per_step,
            fam.ellipse_height_mpa,
        ];
        let fx = Fixed {
            pmax: fam.max_pressure_mpa,
            min_load_n: fam.min_load_n,
            max_load_n: fam.max_load_n,
            load_step_n: fam.load_step_n,
        };
        let back = family(&theta, &fx);
        assert!(
            (back.b - fam.b).abs() < 1e-6 * fam.b.abs(),
            "{back:?} {fam:?}"
        );
        assert!((back.c - fam.c).abs() < 1e-6 * fam.c.abs().max(1.0));
        let c2 = Coeffs::new(export(&theta, &fx)).unwrap();
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
        assert_eq!(r.test_kind, TestKind::Isotonic);
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
        assert!(!r.shape.cubic_cannot_follow(), "{}", r.shape.statement());
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
        assert!(
            msg.starts_with("generated: column `load_n`: too few samples"),
            "{msg}"
        );
        assert!(msg.contains("one load only"), "{msg}");
    }

    #[test]
    fn settings_out_of_range_are_refused_before_any_work() {
        let rec = Record::from_samples("empty", Vec::new());
        let cases: [(&str, FitConfig); 6] = [
            (
                "--load-step",
                FitConfig {
                    load_step_n: 0.0,
                    ..FitConfig::default()
                },
            ),
            (
                "--load-step",
                FitConfig {
                    load_step_n: f64::NAN,
                    ..FitConfig::default()
                },
            ),
            (
                "--load-step",
                FitConfig {
                    load_step_n: 1e-9,
                    ..FitConfig::default()
                },
            ),
            (
                "--load-bin",
                FitConfig {
                    load_bin_n: -5.0,
                    ..FitConfig::default()
                },
            ),
            (
                "--pmax",
                FitConfig {
                    max_pressure_mpa: Some(f64::INFINITY),
                    ..FitConfig::default()
                },
            ),
            (
                "--deadband",
                FitConfig {
                    split: SplitConfig {
                        deadband_mpa: Some(-1.0),
                        ..SplitConfig::default()
                    },
                    ..FitConfig::default()
                },
            ),
        ];
        for (option, cfg) in cases {
            match fit(&rec, &cfg) {
                Err(FitError::Config { option: o, .. }) => assert_eq!(o, option),
                other => panic!("{option}: {other:?}"),
            }
        }
    }

    #[test]
    fn degenerate_records_are_refused_with_the_channel_named() {
        let good = generate(
            &Params::DEFAULT,
            &Protocol::quick(&[100.0, 300.0]),
            0.001,
            0.0005,
            3,
        );
        let with = |f: &dyn Fn(&mut Sample)| {
            let mut s = good.samples.clone();
            s.iter_mut().for_each(f);
            Record::from_samples("rec.csv", s)
        };
        for (rec, column) in [
            (with(&|s| s.contraction = 0.0), "contraction"),
            (with(&|s| s.pressure_mpa = 0.2), "pressure_mpa"),
            (with(&|s| s.t_s = 0.0), "t_s"),
            (with(&|s| s.load_n = 200.0), "load_n"),
        ] {
            let e = fit(&rec, &FitConfig::default()).unwrap_err();
            let msg = e.to_string();
            assert!(
                msg.starts_with(&format!("rec.csv: column `{column}`: ")),
                "{column}: {msg}"
            );
        }
    }
}

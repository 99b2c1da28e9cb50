//! The static-shape stage: pam-core's constraint-shape correction
//! ([`ConstraintShape`]) identified jointly with the paper's parameters,
//! when the cubic alone leaves a systematic misfit.
//!
//! A measured muscle's static curve is rarely the paper's cubic (the Festo
//! records' pressure rises steeply near the stroke's root and bends with
//! load, a Chou–Hannaford or Tondu–Lopez muscle is hyperbolic at its end).
//! The paper's model then fits only by pressing against its own shape
//! conditions at some load, which distorts it everywhere. This stage frees
//! it: the eight paper variables and six shape variables (bulge and tilt
//! at the minimum load and their change up to the maximum load, the
//! stroke ends' quadratic bend with load) are fitted together, each sample's
//! pressure evaluated as the feedforward evaluates it
//! ([`ConstraintShape::pressure_and_slope_f64`], pam-core's `f64` path).
//!
//! Its feasible set is held by penalties, not a projection: the projection
//! of the first stage stops at the first shape condition the straight line
//! to its anchor crosses, so an optimum on the boundary (the normal case for
//! a real muscle) is out of reach. Here every condition pam-core checks at
//! its [`pam_core::load_family::SHAPE_CHECK_LOADS`] loads (one real root,
//! monotone, an open stroke) and the shape's slope limit is a residual that
//! is zero inside with a margin and grows with the violation, so the
//! optimiser slides along the boundary. The result is then moved back along
//! the line to the (feasible) first-stage model until pam-core accepts its
//! `f32` export, if it is not accepted as it is.
//!
//! The stage's model is kept only when it earns its six parameters:
//! Bayesian information criterion on the training residuals
//! (`n·ln(SSE₂/SSE₁) + 6·ln n < 0`).

use pam_core::effects::ConstraintShape;
use pam_core::load_family::SHAPE_CHECK_LOADS;

use super::*;

/// Shape variables of the stage.
pub(super) const NS: usize = 6;
/// Largest `|bulge| + |tilt| + |end_shift − root_shift|` the stage lets
/// the shape reach at a checked load (pam-core's limit is 0.9; at the limit
/// the chip scales the shape back, which the fit's residual would not see
/// as a change).
const SHAPE_SUM_LIMIT: f64 = 0.85;
/// The shape margin the penalty asks for, relative to the mean slope: twice
/// the first stage's, so that the rounding to `f32` stays inside.
const PENALTY_MARGIN: f64 = 2.0 * SHAPE_MARGIN;

/// What the stage found.
pub(super) struct ShapeStage {
    /// The paper's variables.
    pub(super) theta: [f64; NP],
    /// The exported parameters, pam-core's coefficients of them, and the
    /// exported shape (all accepted by pam-core).
    pub(super) params: Params,
    pub(super) coeffs: Coeffs,
    pub(super) shape: ConstraintShape,
    /// Residual evaluations spent.
    pub(super) evaluations: usize,
}

/// Load steps from the minimum load to the maximum.
fn top_steps(fixed: &Fixed) -> f64 {
    ((fixed.max_load_n - fixed.min_load_n) / fixed.load_step_n).max(1e-9)
}

/// The shape's coefficients for the stage's variables `v`: bulge and tilt
/// at the minimum load, their change to the maximum load, and the root's
/// and far end's shift at the maximum load (quadratic in load, zero at the
/// minimum load: the paper's own `R1`, `Rx1` and regressions hold the
/// linear part).
pub(super) fn shape_coefficients(v: &[f64], fixed: &Fixed) -> [f64; 10] {
    let top = top_steps(fixed);
    [
        v[0],
        v[1],
        v[2] / top,
        v[3] / top,
        0.0,
        0.0,
        0.0,
        0.0,
        v[4] / (top * top),
        v[5] / (top * top),
    ]
}

impl TrainSet {
    /// Weighted residuals of `fam` with the shape `shape` into `out[..len]`.
    pub(super) fn shaped_residuals(&self, fam: &LoadFamily, shape: [f64; 10], out: &mut [f64]) {
        let (vp, vx) = (self.sigma_p * self.sigma_p, self.sigma_x * self.sigma_x);
        for &(load, start, end) in &self.runs {
            let m = fam.at_load(load);
            let steps = (load.clamp(fam.min_load_n, fam.max_load_n) - fam.min_load_n)
                / fam.load_step_n;
            let (at, _) = ConstraintShape::at_steps_f64(shape, steps);
            let rows = self.x[start..end]
                .iter()
                .zip(&self.branch[start..end])
                .zip(&self.p[start..end]);
            for (o, ((&x, &br), &pm)) in out[start..end].iter_mut().zip(rows) {
                let (p, slope) = ConstraintShape::pressure_and_slope_f64(at, &m, x, br);
                *o = (p - pm) / (vp + slope * slope * vx).sqrt();
            }
        }
    }
}

/// Penalty rows: per checked load the shape margin, the open stroke and the
/// shape's slope sum; the ellipse height's bounds.
const PENALTY_ROWS: usize = 3 * SHAPE_CHECK_LOADS as usize + 2;

/// The penalties of `z = [θ, v]` into `out` (zero where every condition
/// holds with its margin), each scaled by `weight`.
fn penalties(z: &[f64], fixed: &Fixed, weight: f64, out: &mut [f64]) {
    let fam = family(&z[..NP], fixed);
    let shape = shape_coefficients(&z[NP..], fixed);
    let stroke1 = (z[1] - z[0]).abs().max(1e-6);
    let mut k_out = 0;
    for k in 0..SHAPE_CHECK_LOADS {
        let load = fam.check_load_n(k);
        let at = fam.at_load(load);
        let open = at.max_contraction - at.cubic.root;
        let margin = if open > 0.0 {
            at.shape_margins().relative()
        } else {
            -1.0
        };
        let margin = if margin.is_finite() { margin } else { -1.0 };
        out[k_out] = weight * (PENALTY_MARGIN - margin).max(0.0);
        out[k_out + 1] = weight * (MIN_STROKE_RATIO * stroke1 - open).max(0.0) / stroke1;
        let (_, sum) = ConstraintShape::at_steps_f64(shape, (load - fam.min_load_n) / fam.load_step_n);
        out[k_out + 2] = weight * (sum - SHAPE_SUM_LIMIT).max(0.0);
        k_out += 3;
    }
    let be = z[7];
    let scale = 0.01 * fixed.pmax;
    out[k_out] = weight * (-be).max(0.0) / scale;
    out[k_out + 1] = weight * (be - MAX_HEIGHT_OF_PMAX * fixed.pmax).max(0.0) / scale;
}

/// Whether `z` is a point the stage may return: the first stage's feasible
/// set, and the shape's sum inside pam-core's limit at every checked load.
fn stage_feasible(z: &[f64], fixed: &Fixed) -> bool {
    if !feasible(&z[..NP], fixed) {
        return false;
    }
    let fam = family(&z[..NP], fixed);
    let shape = shape_coefficients(&z[NP..], fixed);
    (0..SHAPE_CHECK_LOADS).all(|k| {
        let steps = (fam.check_load_n(k) - fam.min_load_n) / fam.load_step_n;
        let (_, sum) = ConstraintShape::at_steps_f64(shape, steps);
        sum <= f64::from(pam_core::effects::shape::MAX_SHAPE_SLOPE) - 0.01
    })
}

/// Sum of squares of the training residuals of `z`, halved.
fn data_cost(train: &TrainSet, z: &[f64], fixed: &Fixed) -> f64 {
    let mut r = vec![0.0; train.len()];
    train.shaped_residuals(
        &family(&z[..NP], fixed),
        shape_coefficients(&z[NP..], fixed),
        &mut r,
    );
    0.5 * r.iter().map(|v| v * v).sum::<f64>()
}

/// Whether pam-core accepts `z`'s `f32` export: the parameters
/// (`Coeffs::new`) and the shape (`ConstraintShape::validate`).
fn exported(z: &[f64], fixed: &Fixed) -> Option<(Params, Coeffs, ConstraintShape)> {
    let params = export(&z[..NP], fixed);
    let coeffs = Coeffs::new(params).ok()?;
    let shape = ConstraintShape::from_coefficients_f64(shape_coefficients(&z[NP..], fixed));
    shape.validate().ok()?;
    Some((params, coeffs, shape))
}

/// The stage from the first stage's (feasible, exported) variables `theta1`.
/// `None` when the shape does not earn its parameters or nothing better
/// than the first stage is accepted by pam-core.
pub(super) fn fit_static_shape(
    train: &TrainSet,
    fixed: &Fixed,
    theta1: &[f64],
    patience: usize,
    progress: &(dyn Fn(Progress) + Sync),
) -> Option<ShapeStage> {
    let n = train.len();
    let mut z0 = [0.0; NP + NS];
    z0[..NP].copy_from_slice(&theta1[..NP]);
    // The penalties' weight: a violation of 10⁻³ (margins are relative to
    // the mean slope, the stroke's to the stroke) costs about the whole
    // first-stage misfit, so the optimum sits on the boundary, not past it.
    let cost_before = data_cost(train, &z0, fixed);
    // Continuation: from the unconstrained optimum (penalty weight 0, where
    // the data alone lead) the penalties grow by decades to their final
    // weight, each round warm-started; a violation of 10⁻³ at the final
    // weight costs about the whole first-stage misfit.
    let base = (2.0 * cost_before).sqrt().max(1.0);
    let scale = |j: usize| {
        if j < NP {
            param_scale(j, fixed)
        } else {
            0.1
        }
    };
    let on_evaluation = |count, cost| progress(Progress::Evaluation { count, cost });
    let mut theta = z0.to_vec();
    let mut evaluations = 0;
    let mut last = None;
    let ws: Vec<f64> = std::env::var("PAM_WS").ok().map(|v| v.split(',').map(|x| x.parse().unwrap()).collect()).unwrap_or(vec![0.0, 1.0, 10.0, 100.0, 1e3]);
    for weight in ws {
        let weight = weight * base;
        let residuals = |z: &[f64], out: &mut [f64]| {
            let fam = family(&z[..NP], fixed);
            train.shaped_residuals(&fam, shape_coefficients(&z[NP..], fixed), &mut out[..n]);
            penalties(z, fixed, weight, &mut out[n..]);
        };
        let m = lsq::minimize(
            &lsq::Residuals {
                m: n + PENALTY_ROWS,
                residuals: &residuals,
                step: &|j, v| 1e-7 * v.abs().max(scale(j)),
                on_evaluation: &on_evaluation,
            },
            &theta,
            patience,
        );
        evaluations += m.evaluations;
        eprintln!("DBG w {weight:e} {:?} cost {} data {}", m.termination, m.cost, data_cost(train, &m.theta, fixed));
        if !m.usable() {
            break;
        }
        theta = m.theta.clone();
        last = Some(m);
    }
    let Some(mut minimum) = last else {
        return None;
    };
    minimum.evaluations = evaluations;
    if !minimum.usable() {
        return None;
    }
    {
        let mut pen = vec![0.0; PENALTY_ROWS];
        penalties(&minimum.theta, fixed, 1.0, &mut pen);
        let fam = family(&minimum.theta[..NP], fixed);
        for k in 0..SHAPE_CHECK_LOADS as usize {
            if pen[3*k]+pen[3*k+1]+pen[3*k+2] > 0.0 || k % 4 == 0 { let at = fam.at_load(fam.check_load_n(k as u32)); eprintln!("DBG k{k} L{:.0} R{:.4} Rx{:.4} pen {:.2e} {:.2e} {:.2e}", fam.check_load_n(k as u32), at.cubic.root, at.max_contraction, pen[3*k], pen[3*k+1], pen[3*k+2]); }
        }
        eprintln!("DBG theta {:?}", minimum.theta);
    }
    // Back along the line to the first stage until the stage's conditions
    // and pam-core's export both hold.
    let at = |s: f64| -> Vec<f64> {
        (0..NP + NS)
            .map(|j| z0[j] + s * (minimum.theta[j] - z0[j]))
            .collect()
    };
    let mut s_ok = if stage_feasible(&at(1.0), fixed) {
        1.0
    } else {
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..PROJECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            if stage_feasible(&at(mid), fixed) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    };
    let (z, (params, coeffs, shape)) = loop {
        let z = at(s_ok);
        if let Some(e) = exported(&z, fixed) {
            break (z, e);
        }
        if s_ok <= 0.0 {
            return None;
        }
        s_ok = (s_ok - 1.0 / PROJECTION_STEPS as f64).max(0.0);
    };
    eprintln!("DBG s_ok {s_ok} before {} after {} feas1 {}", cost_before, data_cost(train, &z, fixed), stage_feasible(&at(1.0), fixed));
    let cost_after = data_cost(train, &z, fixed);
    // BIC: n·ln(SSE₂/SSE₁) + k·ln n < 0.
    let nf = n as f64;
    let earns = cost_after > 0.0
        && cost_before > 0.0
        && nf * (cost_after / cost_before).ln() + NS as f64 * nf.ln() < 0.0;
    if !earns {
        return None;
    }
    let mut theta = [0.0; NP];
    theta.copy_from_slice(&z[..NP]);
    Some(ShapeStage {
        theta,
        params,
        coeffs,
        shape,
        evaluations: minimum.evaluations,
    })
}

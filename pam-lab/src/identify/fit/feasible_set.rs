//! The fitted variables and the feasible set: the fit vector as a
//! pam-core load family, the valid-by-construction anchor and the
//! projection toward it.

use super::*;

/// Number of fitted parameters.
pub(super) const NP: usize = 8;
/// Fractions of the stroke at which the minimum-load cubic is parametrised.
pub(super) const U1: f64 = 1.0 / 3.0;
pub(super) const U2: f64 = 2.0 / 3.0;
/// Shape margin (relative to the mean slope) every visited point keeps, so
/// that the `f32` rounding of the export stays inside pam-core's check.
pub(super) const SHAPE_MARGIN: f64 = 1e-3;
/// Largest ellipse height the fit considers, as a fraction of `Pmax`
/// (pam-core allows up to one half).
pub(super) const MAX_HEIGHT_OF_PMAX: f64 = 0.45;
/// The stroke at the maximum load may not shrink below this fraction of
/// the stroke at the minimum load.
pub(super) const MIN_STROKE_RATIO: f64 = 0.05;
/// Bisection steps of the feasible projection.
pub(super) const PROJECTION_STEPS: usize = 40;

/// Fixed quantities of a fit.
#[derive(Clone, Copy, Debug)]
pub(super) struct Fixed {
    pub(super) pmax: f64,
    pub(super) min_load_n: f64,
    pub(super) max_load_n: f64,
    pub(super) load_step_n: f64,
}

/// The valid-by-construction cubic `g(u) = u³ − u² + u` over the stroke
/// (`g(0) = 0`, `g(1) = 1`, `g' ≥ 2/3`, quadratic factor `u² − u + 1 ≥ 3/4`).
pub(super) fn anchor_shape(u: f64) -> f64 {
    u * (u * u - u + 1.0)
}

/// pam-core's load family for the fit vector
/// `[R1, Rx1, y(1/3), y(2/3), RG_L, RG_U, GR_c, be]`.
pub(super) fn family(t: &[f64], fixed: &Fixed) -> LoadFamily {
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
pub(super) fn feasible(t: &[f64], fixed: &Fixed) -> bool {
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
pub(super) fn anchor(r1: f64, rx1: f64, be: f64, pmax: f64) -> [f64; NP] {
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
pub(super) fn project(t: &[f64], anchor: &[f64; NP], fixed: &Fixed) -> ([f64; NP], bool) {
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
pub(super) fn export(t: &[f64], fixed: &Fixed) -> Params {
    let mut p = family(t, fixed).to_params();
    if p.ellipse_height_mpa < pam_core::coeffs::MIN_ELLIPSE_HEIGHT_MPA {
        p.ellipse_height_mpa = 0.0;
    }
    p
}

/// The `f32` export of `theta` that pam-core accepts: the margin makes that
/// the rule, and where rounding still breaks it, steps toward the anchor.
/// The point exported, its parameters and coefficients, or the last error.
pub(super) fn exported(
    theta: &[f64],
    anchor: &[f64; NP],
    fixed: &Fixed,
) -> Result<(Vec<f64>, Params, Coeffs), pam_core::Error> {
    let mut last_error = pam_core::Error::Singular;
    for k in 0..=PROJECTION_STEPS {
        let s = 1.0 - (k as f64 / PROJECTION_STEPS as f64);
        let t: Vec<f64> = (0..NP)
            .map(|j| anchor[j] + s * (theta[j] - anchor[j]))
            .collect();
        let params = export(&t, fixed);
        match Coeffs::new(params) {
            Ok(coeffs) => return Ok((t, params, coeffs)),
            Err(e) => last_error = e,
        }
    }
    Err(last_error)
}

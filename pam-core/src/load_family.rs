//! The load family of constraint models, eqs. (15)–(21), and [`Coeffs`]: the
//! validated, precomputed form of [`Params`].
//!
//! The paper steps the load on a grid (`i = 1, 2, 3…` at 100 N) and claims
//! 1 N resolution; here the regression and growth factors are applied to the
//! fractional step count `s = (L − L_min)/ΔL`, so any load in the calibrated
//! range evaluates and grid loads give exactly the paper's values.

use crate::constraint::{FactorCubic, GeneralCubic};
use crate::error::Error;
use crate::hysteresis::LoadModel;
use crate::params::Params;

/// How many loads across the calibrated range [`Coeffs::new`] checks for the
/// paper's shape conditions (one real root, monotone), ends included.
pub const SHAPE_CHECK_LOADS: u32 = 65;

/// Smallest non-zero ellipse height `be` [`Coeffs::new`] accepts, MPa (1 Pa).
pub const MIN_ELLIPSE_HEIGHT_MPA: f32 = 1e-6;

/// Validated parameters with the minimum-load cubic precomputed.
///
/// Build once with [`Coeffs::new`] (host or boot); then [`Coeffs::load_model`]
/// gives the per-load [`LoadModel`] whose evaluation is the per-sample path.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Coeffs {
    params: Params,
    general: GeneralCubic,
    factor: FactorCubic,
}

/// The constraint model's parameters at one load, eqs. (16)–(21).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadCubic {
    /// The load, N.
    pub load_n: f32,
    /// Factor form at this load: `R_i`, `a_i`, `b`, `c_i`.
    pub cubic: FactorCubic,
    /// `Rx_i`, contraction at `Pmax` at this load.
    pub max_contraction: f64,
}

impl Coeffs {
    /// Validate `params` and precompute the minimum-load cubic.
    ///
    /// Refuses non-finite values, empty or inverted ranges, critical points
    /// outside `(R1, Rx1)`, and any parameter set whose constraint model loses
    /// the paper's shape (one real root, increasing on `[R_i, Rx_i]`), or
    /// whose stroke leaves `-1 < R_i < Rx_i < 1`, at one of
    /// [`SHAPE_CHECK_LOADS`] loads across the calibrated range.
    pub fn new(params: Params) -> Result<Coeffs, Error> {
        check_finite(&params)?;
        let p = &params.points;
        if !(params.min_load_n >= 0.0) {
            return Err(Error::OutOfRange("min_load_n", "must be >= 0 N"));
        }
        if !(params.max_load_n >= params.min_load_n) {
            return Err(Error::OutOfRange("max_load_n", "must be >= min_load_n"));
        }
        if !(params.load_step_n > 0.0) {
            return Err(Error::OutOfRange("load_step_n", "must be > 0 N"));
        }
        if !(p.max_pressure_mpa > 0.0 && p.max_pressure_mpa <= 10.0) {
            return Err(Error::OutOfRange(
                "max_pressure_mpa",
                "must be in (0, 10] MPa",
            ));
        }
        if !(p.root_contraction > -1.0
            && p.max_contraction < 1.0
            && p.max_contraction > p.root_contraction)
        {
            return Err(Error::OutOfRange(
                "max_contraction",
                "need -1 < root_contraction < max_contraction < 1",
            ));
        }
        let inside = |x: f32| x > p.root_contraction && x < p.max_contraction;
        if !inside(p.tangency.contraction) {
            return Err(Error::OutOfRange(
                "tangency.contraction",
                "must lie in (R1, Rx1)",
            ));
        }
        if !inside(p.inflection.contraction) {
            return Err(Error::OutOfRange(
                "inflection.contraction",
                "must lie in (R1, Rx1)",
            ));
        }
        // A height below 1 Pa (1e-6 MPa) has no physical meaning, and its
        // square, stored per load, would be an f32 subnormal that keeps only a
        // few significant bits (fuzz `core_eval` found the offset 1 % above
        // `be` at be = 1.3e-22 MPa): such heights must be exactly 0.
        let be = params.ellipse_height_mpa;
        if !((be == 0.0 || be >= MIN_ELLIPSE_HEIGHT_MPA) && be < 0.5 * p.max_pressure_mpa) {
            return Err(Error::OutOfRange(
                "ellipse_height_mpa",
                "must be 0 or in [1e-6, Pmax/2) MPa",
            ));
        }

        let general = GeneralCubic::through_points(p)?;
        let factor = general.factor(f64::from(p.root_contraction));
        let coeffs = Coeffs {
            params,
            general,
            factor,
        };

        let span = params.max_load_n - params.min_load_n;
        for k in 0..SHAPE_CHECK_LOADS {
            let load_n = params.min_load_n + span * (k as f32) / ((SHAPE_CHECK_LOADS - 1) as f32);
            let at = coeffs.load_cubic(load_n);
            // The bounds checked above at the minimum load hold at every load
            // (huge regressions put R_i and Rx_i at ±1e13), and the stroke is
            // non-empty in the f32 the model evaluates in (fuzz: blob_decode).
            if !(at.cubic.root > -1.0) {
                return Err(Error::OutOfRange(
                    "root_regression_per_step",
                    "R_i falls to -1 inside the load range",
                ));
            }
            if !(at.max_contraction < 1.0) {
                return Err(Error::OutOfRange(
                    "max_regression_per_step",
                    "Rx_i reaches 1 inside the load range",
                ));
            }
            if !(at.max_contraction as f32 > at.cubic.root as f32) {
                return Err(Error::OutOfRange(
                    "max_regression_per_step",
                    "Rx_i falls to R_i inside the load range",
                ));
            }
            at.cubic.check_shape(at.max_contraction, load_n)?;
        }
        Ok(coeffs)
    }

    /// The parameters this was built from.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// General cubic at the minimum load, eqs. (8)–(11).
    pub fn general_cubic(&self) -> &GeneralCubic {
        &self.general
    }

    /// Factor form at the minimum load, eqs. (12)–(14).
    pub fn factor_cubic(&self) -> &FactorCubic {
        &self.factor
    }

    /// Whether `load_n` is inside the calibrated range (NaN is not).
    pub fn load_in_range(&self, load_n: f32) -> bool {
        load_n >= self.params.min_load_n && load_n <= self.params.max_load_n
    }

    /// `load_n` limited to the calibrated range; NaN maps to the minimum load.
    pub fn clamp_load_n(&self, load_n: f32) -> f32 {
        crate::math::clamp(load_n, self.params.min_load_n, self.params.max_load_n)
    }

    /// Constraint-model parameters at `load_n` (clamped to the calibrated
    /// range), eqs. (16)–(21).
    pub fn load_cubic(&self, load_n: f32) -> LoadCubic {
        let load_n = self.clamp_load_n(load_n);
        let p = &self.params;
        let s = f64::from(load_n - p.min_load_n) / f64::from(p.load_step_n);
        // eq. (17)
        let root = self.factor.root - f64::from(p.root_regression_per_step) * s;
        // eq. (18)
        let rx = f64::from(p.points.max_contraction) - f64::from(p.max_regression_per_step) * s;
        // eq. (19) from c1 of eq. (14); eq. (20) prints c1 = D1/R1, but the
        // factor form's constant is −cR (eq. 5), so c1 = −D1/R1 — which is
        // what eq. (14) gives (checked in the constraint tests).
        let c = self.factor.c + f64::from(p.c_growth_per_step) * s;
        let b = self.factor.b; // shared by all loads, eq. (21)
        let pmax = f64::from(p.points.max_pressure_mpa);
        // eq. (16): the amplitude that puts CM_i(Rx_i) = Pmax.
        let a = ((pmax + c * root) / (rx * rx) - (c + b * root) / rx + b) / (rx - root);
        LoadCubic {
            load_n,
            cubic: FactorCubic { root, a, b, c },
            max_contraction: rx,
        }
    }

    /// The per-load model (constraint model plus ellipse offset, with its
    /// inverse tables) at `load_n`; a load outside the calibrated range is an
    /// error.
    pub fn load_model(&self, load_n: f32) -> Result<LoadModel, Error> {
        if self.load_in_range(load_n) {
            Ok(LoadModel::new(self, load_n))
        } else {
            Err(Error::LoadOutOfRange { load_n })
        }
    }

    /// The per-load model at `load_n` clamped to the calibrated range (NaN →
    /// minimum load). Never fails.
    pub fn load_model_clamped(&self, load_n: f32) -> LoadModel {
        LoadModel::new(self, self.clamp_load_n(load_n))
    }
}

fn check_finite(p: &Params) -> Result<(), Error> {
    for (name, v) in p.named_fields() {
        if !v.is_finite() {
            return Err(Error::NonFinite(name));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::isclose;

    #[test]
    fn default_params_validate() {
        Coeffs::new(Params::DEFAULT).unwrap();
    }

    #[test]
    fn constraint_model_hits_root_and_pmax_at_every_load() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let pmax = f64::from(Params::DEFAULT.points.max_pressure_mpa);
        for load in (100..=600).step_by(25) {
            let at = coeffs.load_cubic(load as f32);
            assert!(
                at.cubic.eval(at.cubic.root).abs() < 1e-12,
                "CM(R_i) at {load} N"
            );
            let top = at.cubic.eval(at.max_contraction);
            assert!(
                isclose(top, pmax, 1e-9, 0.0),
                "CM(Rx_i) = {top} at {load} N"
            );
        }
    }

    #[test]
    fn grid_loads_follow_the_paper_recursions() {
        // eqs. (17)–(19) as recursions over the 100 N grid.
        let p = Params::DEFAULT;
        let coeffs = Coeffs::new(p).unwrap();
        let mut prev = coeffs.load_cubic(p.min_load_n);
        for i in 1..=5 {
            let at = coeffs.load_cubic(p.min_load_n + p.load_step_n * i as f32);
            assert!(isclose(
                at.cubic.root,
                prev.cubic.root - f64::from(p.root_regression_per_step),
                0.0,
                1e-7
            ));
            assert!(isclose(
                at.max_contraction,
                prev.max_contraction - f64::from(p.max_regression_per_step),
                0.0,
                1e-7
            ));
            assert!(isclose(
                at.cubic.c,
                prev.cubic.c + f64::from(p.c_growth_per_step),
                0.0,
                1e-6
            ));
            assert_eq!(at.cubic.b, prev.cubic.b);
            prev = at;
        }
    }

    #[test]
    fn non_finite_and_inverted_params_are_refused() {
        let mut p = Params::DEFAULT;
        p.points.tangency.pressure_mpa = f32::NAN;
        assert_eq!(
            Coeffs::new(p),
            Err(Error::NonFinite("tangency.pressure_mpa"))
        );
        let mut p = Params::DEFAULT;
        p.max_load_n = 50.0;
        assert!(matches!(
            Coeffs::new(p),
            Err(Error::OutOfRange("max_load_n", _))
        ));
        let mut p = Params::DEFAULT;
        p.load_step_n = 0.0;
        assert!(matches!(
            Coeffs::new(p),
            Err(Error::OutOfRange("load_step_n", _))
        ));
    }

    #[test]
    fn a_family_that_loses_shape_at_high_load_is_refused() {
        // Rx regresses so fast that the curve would have to fall to reach Pmax.
        let mut p = Params::DEFAULT;
        p.max_regression_per_step = 0.05;
        assert!(Coeffs::new(p).is_err());
    }

    #[test]
    fn loads_outside_the_range_are_errors_or_clamped() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        assert_eq!(
            coeffs.load_model(50.0).err(),
            Some(Error::LoadOutOfRange { load_n: 50.0 })
        );
        assert!(coeffs.load_model(f32::NAN).is_err());
        assert_eq!(coeffs.load_model_clamped(1e9).load_n(), 600.0);
        assert_eq!(coeffs.load_model_clamped(f32::NAN).load_n(), 100.0);
    }
}

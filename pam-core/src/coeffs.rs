//! [`Coeffs`]: the validated, precomputed form of [`Params`] — the
//! minimum-load cubic (eqs. 7–14) and the load family (eqs. 15–21) — from
//! which the per-load [`LoadModel`] is built.

use crate::constraint::{FactorCubic, GeneralCubic};
use crate::error::Error;
use crate::load_family::{LoadCubic, LoadFamily};
use crate::load_model::LoadModel;
use crate::params::Params;

pub use crate::load_family::SHAPE_CHECK_LOADS;

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
    family: LoadFamily,
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
        if !(p.root_contraction > -1.0) {
            return Err(Error::OutOfRange(
                "root_contraction",
                "need -1 < root_contraction < max_contraction < 1",
            ));
        }
        if !(p.max_contraction < 1.0 && p.max_contraction > p.root_contraction) {
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
        let family = LoadFamily::from_factor(&params, &factor);
        family.check(0.0)?;
        // The chip builds a load's model in `f32` (the tracker's load
        // switch): it must be finite wherever the `f64` family was checked.
        let family_f32 = crate::load_model::FamilyF32::new(&family);
        for k in 0..SHAPE_CHECK_LOADS {
            if !family_f32.model_is_finite(family.check_load_n(k) as f32) {
                return Err(Error::OutOfRange(
                    "max_load_n",
                    "the model overflows f32 inside the load range",
                ));
            }
        }
        Ok(Coeffs {
            params,
            general,
            factor,
            family,
        })
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

    /// The load family in `f64` (eqs. 15–21), as validated.
    pub fn family(&self) -> &LoadFamily {
        &self.family
    }

    /// Constraint-model parameters at `load_n` (clamped to the calibrated
    /// range), eqs. (16)–(21). The step count is taken from the `f32` load
    /// difference, as the chip computes it.
    pub fn load_cubic(&self, load_n: f32) -> LoadCubic {
        let load_n = self.clamp_load_n(load_n);
        let p = &self.params;
        let s = f64::from(load_n - p.min_load_n) / f64::from(p.load_step_n);
        self.family.at_steps(s, f64::from(load_n))
    }

    /// The per-load model (constraint model plus ellipse offset, with its
    /// inverse tables) at `load_n`; a load outside the calibrated range is an
    /// error.
    pub fn load_model(&self, load_n: f32) -> Result<LoadModel, Error> {
        if self.load_in_range(load_n) {
            Ok(LoadModel::new(&self.load_cubic(load_n)))
        } else {
            Err(Error::LoadOutOfRange { load_n })
        }
    }

    /// The per-load model at `load_n` clamped to the calibrated range (NaN →
    /// minimum load). Never fails.
    pub fn load_model_clamped(&self, load_n: f32) -> LoadModel {
        LoadModel::new(&self.load_cubic(load_n))
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

    #[test]
    fn a_load_range_whose_f32_model_overflows_is_refused() {
        // Found by fuzz `effects`: a calibrated range up to 1.9e31 N passed
        // the f64 shape check, and the tracker's f32 model there was NaN.
        let mut p = Params::DEFAULT;
        p.max_load_n = 1.9e31;
        p.root_regression_per_step = 0.0;
        p.max_regression_per_step = 0.0;
        p.c_growth_per_step = 1e-30;
        match Coeffs::new(p) {
            Err(_) => {}
            Ok(c) => {
                let m = c.load_model_clamped(p.max_load_n);
                assert!(m.root_contraction().is_finite(), "{m:?}");
            }
        }
        // Every accepted range evaluates finitely at its ends.
        let c = Coeffs::new(Params::DEFAULT).unwrap();
        assert!(c.load_model_clamped(600.0).root_contraction().is_finite());
    }

    #[test]
    fn default_params_validate() {
        Coeffs::new(Params::DEFAULT).unwrap();
    }

    /// Each refusal names the field that is wrong, not a neighbour.
    #[test]
    fn errors_name_the_field_at_fault() {
        let field = |f: &dyn Fn(&mut Params)| {
            let mut p = Params::DEFAULT;
            f(&mut p);
            match Coeffs::new(p) {
                Err(Error::OutOfRange(name, _)) => name,
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(
            field(&|p| p.points.root_contraction = -5.0),
            "root_contraction"
        );
        assert_eq!(
            field(&|p| p.points.max_contraction = 5.0),
            "max_contraction"
        );
        assert_eq!(
            field(&|p| p.points.max_contraction = -0.5),
            "max_contraction"
        );
        assert_eq!(
            field(&|p| p.root_regression_per_step = -5.0),
            "root_regression_per_step"
        );
        assert_eq!(
            field(&|p| p.max_regression_per_step = 5.0),
            "max_regression_per_step"
        );
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

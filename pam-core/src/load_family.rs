//! The load family of constraint models, eqs. (15)–(21), in `f64`: the one
//! home of the model's construction, used by [`crate::Coeffs::new`] (at boot
//! or on the host) and by host tools that identify or evaluate the model
//! (`pam-lab fit`), so that both check and evaluate exactly the same thing.
//!
//! The paper steps the load on a grid (`i = 1, 2, 3…` at 100 N) and claims
//! 1 N resolution; here the regression and growth factors are applied to the
//! fractional step count `s = (L − L_min)/ΔL`, so any load in the calibrated
//! range evaluates and grid loads give exactly the paper's values.
//!
//! The per-sample path never sees this module: it evaluates the `f32`
//! [`crate::LoadModel`] built from a [`LoadCubic`].

use crate::branch::Branch;
use crate::constraint::{FactorCubic, GeneralCubic};
use crate::ellipse::Ellipse;
use crate::error::Error;
use crate::math::clamp_f64;
use crate::params::{CriticalPoints, Params, Point};

/// How many loads across the calibrated range the shape conditions (one real
/// root, increasing) are checked at, ends included.
pub const SHAPE_CHECK_LOADS: u32 = 65;

/// The whole load family: the factor form at the minimum load (eqs. 12–14)
/// and the linear load factors (eqs. 17–19), with `Pmax` and the ellipse
/// height.
///
/// Every field is free: this is the form an optimiser varies. Whether it is
/// a model the paper's shape conditions allow is [`LoadFamily::check`]'s
/// answer (the same check [`crate::Coeffs::new`] makes).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoadFamily {
    /// Minimum calibrated load, N (`i = 1`).
    pub min_load_n: f64,
    /// Maximum calibrated load, N.
    pub max_load_n: f64,
    /// Load step `ΔL` of the factors, N.
    pub load_step_n: f64,
    /// `Pmax`, MPa: every load's constraint model reaches it at `Rx_i` (eq. 16).
    pub max_pressure_mpa: f64,
    /// `R1`, the first real root at the minimum load.
    pub root_contraction: f64,
    /// `Rx1`, contraction at `Pmax` at the minimum load.
    pub max_contraction: f64,
    /// `b` of the factor form, shared by every load (eq. 21).
    pub b: f64,
    /// `c1` of the factor form at the minimum load (eq. 14).
    pub c: f64,
    /// `RG_L` per load step (eq. 17).
    pub root_regression_per_step: f64,
    /// `RG_U` per load step (eq. 18).
    pub max_regression_per_step: f64,
    /// `GR_c` per load step (eq. 19).
    pub c_growth_per_step: f64,
    /// `be`, MPa (eq. 24).
    pub ellipse_height_mpa: f64,
}

/// The model at one load, eqs. (16)–(21), with the ellipse's height and
/// `Pmax` so that it evaluates both branches on its own (the `f64` host path
/// of [`crate::LoadModel`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoadCubic {
    /// The load, N.
    pub load_n: f64,
    /// Factor form at this load: `R_i`, `a_i`, `b`, `c_i`.
    pub cubic: FactorCubic,
    /// `Rx_i`, contraction at `Pmax` at this load.
    pub max_contraction: f64,
    /// `be`, MPa.
    pub ellipse_height_mpa: f64,
    /// `Pmax`, MPa.
    pub max_pressure_mpa: f64,
}

/// How far one load's constraint model is from losing the paper's shape.
/// Both margins are slopes, MPa per unit contraction; the shape holds when
/// both are positive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeMargins {
    /// Smallest value over all `x` of the quadratic factor `a x² − b x + c`
    /// (positive: one real root, the root `R_i`); `−∞` when `a ≤ 0`.
    pub quadratic_min: f64,
    /// Smallest slope `CM'(x)` on `[R_i, Rx_i]` (positive: increasing).
    pub slope_min: f64,
    /// `Pmax/(Rx_i − R_i)`, the mean slope: the scale to compare them with.
    pub mean_slope: f64,
}

impl ShapeMargins {
    /// The smaller margin relative to the mean slope (NaN counts as `−∞`).
    pub fn relative(&self) -> f64 {
        let m = self.quadratic_min.min(self.slope_min) / self.mean_slope;
        if m.is_nan() {
            f64::NEG_INFINITY
        } else {
            m
        }
    }
}

impl LoadFamily {
    /// The family of `params`: the general cubic through the critical points
    /// (eqs. 7–11), its factor form about `R1` (eqs. 12–14), and the factors.
    /// Fails only when the points are singular (repeated contractions).
    pub fn from_params(params: &Params) -> Result<LoadFamily, Error> {
        let p = &params.points;
        let general = GeneralCubic::through_points(p)?;
        Ok(LoadFamily::from_factor(
            params,
            &general.factor(f64::from(p.root_contraction)),
        ))
    }

    /// The family of `params` with the minimum-load factor form given.
    pub(crate) fn from_factor(params: &Params, factor: &FactorCubic) -> LoadFamily {
        LoadFamily {
            min_load_n: f64::from(params.min_load_n),
            max_load_n: f64::from(params.max_load_n),
            load_step_n: f64::from(params.load_step_n),
            max_pressure_mpa: f64::from(params.points.max_pressure_mpa),
            root_contraction: factor.root,
            max_contraction: f64::from(params.points.max_contraction),
            b: factor.b,
            c: factor.c,
            root_regression_per_step: f64::from(params.root_regression_per_step),
            max_regression_per_step: f64::from(params.max_regression_per_step),
            c_growth_per_step: f64::from(params.c_growth_per_step),
            ellipse_height_mpa: f64::from(params.ellipse_height_mpa),
        }
    }

    /// The model at `load_n`, clamped to the calibrated range (NaN → the
    /// minimum load), eqs. (16)–(21).
    pub fn at_load(&self, load_n: f64) -> LoadCubic {
        let load_n = clamp_f64(load_n, self.min_load_n, self.max_load_n);
        self.at_steps((load_n - self.min_load_n) / self.load_step_n, load_n)
    }

    /// The model `s` load steps above the minimum load (`load_n` is only
    /// recorded), eqs. (16)–(21).
    pub fn at_steps(&self, s: f64, load_n: f64) -> LoadCubic {
        // eq. (17)
        let root = self.root_contraction - self.root_regression_per_step * s;
        // eq. (18)
        let rx = self.max_contraction - self.max_regression_per_step * s;
        // eq. (19) from c1 of eq. (14); eq. (20) prints c1 = D1/R1, but the
        // factor form's constant is −cR (eq. 5), so c1 = −D1/R1 — which is
        // what eq. (14) gives (checked in the constraint tests).
        let c = self.c + self.c_growth_per_step * s;
        let b = self.b; // shared by all loads, eq. (21)
        let pmax = self.max_pressure_mpa;
        // eq. (16): the amplitude that puts CM_i(Rx_i) = Pmax.
        let a = ((pmax + c * root) / (rx * rx) - (c + b * root) / rx + b) / (rx - root);
        LoadCubic {
            load_n,
            cubic: FactorCubic { root, a, b, c },
            max_contraction: rx,
            ellipse_height_mpa: self.ellipse_height_mpa,
            max_pressure_mpa: pmax,
        }
    }

    /// The `k`-th of the [`SHAPE_CHECK_LOADS`] loads the shape is checked at.
    pub fn check_load_n(&self, k: u32) -> f64 {
        let span = self.max_load_n - self.min_load_n;
        self.min_load_n + span * f64::from(k) / f64::from(SHAPE_CHECK_LOADS - 1)
    }

    /// Whether every one of the [`SHAPE_CHECK_LOADS`] loads keeps the paper's
    /// shape with `margin` to spare (relative to the mean slope, see
    /// [`ShapeMargins::relative`]; 0 is [`crate::Coeffs::new`]'s check) and a
    /// stroke inside `−1 < R_i < Rx_i < 1`. The first failure is the error.
    pub fn check(&self, margin: f64) -> Result<(), Error> {
        for k in 0..SHAPE_CHECK_LOADS {
            let at = self.at_load(self.check_load_n(k));
            // The bounds [`crate::Coeffs::new`] checks at the minimum load hold
            // at every load (huge regressions put R_i and Rx_i at ±1e13), and
            // the stroke is non-empty in the f32 the model evaluates in (fuzz:
            // blob_decode).
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
                // Name the factor that closes the stroke: the root's when R_i
                // rises above R_1 (a negative root regression), else Rx's.
                return Err(if at.cubic.root > self.root_contraction {
                    Error::OutOfRange(
                        "root_regression_per_step",
                        "R_i rises to Rx_i inside the load range",
                    )
                } else {
                    Error::OutOfRange(
                        "max_regression_per_step",
                        "Rx_i falls to R_i inside the load range",
                    )
                });
            }
            at.check_shape(margin)?;
        }
        Ok(())
    }

    /// The smallest [`ShapeMargins::relative`] over the checked loads (`−∞`
    /// when a stroke is empty or inverted somewhere).
    pub fn worst_margin(&self) -> f64 {
        let mut worst = f64::INFINITY;
        for k in 0..SHAPE_CHECK_LOADS {
            let at = self.at_load(self.check_load_n(k));
            let open = at.max_contraction > at.cubic.root;
            let m = if open {
                at.shape_margins().relative()
            } else {
                f64::NEG_INFINITY
            };
            worst = worst.min(m);
        }
        worst
    }

    /// Critical points that give this family's minimum-load cubic, as
    /// [`Params`] (rounded to `f32`). The paper's tangency point is not a
    /// point where anything is tangent in the factor form pam-core uses: any
    /// two interior points determine the cubic once `R1`, `Rx1` and `Pmax`
    /// are fixed. This takes the inflection point and the point halfway from
    /// `R1` to it when the inflection lies well inside the stroke, else the
    /// points at 1/3 and 2/3 of it.
    pub fn to_params(&self) -> Params {
        let m = self.at_load(self.min_load_n);
        let (root, rx) = (m.cubic.root, m.max_contraction);
        let stroke = rx - root;
        let xi = (m.cubic.b + m.cubic.a * root) / (3.0 * m.cubic.a);
        let (x_tan, x_inf) = if xi.is_finite() && xi > root + 0.2 * stroke && xi < rx - 0.1 * stroke
        {
            (0.5 * (root + xi), xi)
        } else {
            (root + stroke / 3.0, root + 2.0 * stroke / 3.0)
        };
        let pt = |x: f64| Point {
            contraction: x as f32,
            pressure_mpa: m.cubic.eval(x) as f32,
        };
        Params {
            min_load_n: self.min_load_n as f32,
            max_load_n: self.max_load_n as f32,
            load_step_n: self.load_step_n as f32,
            points: CriticalPoints {
                root_contraction: self.root_contraction as f32,
                max_contraction: self.max_contraction as f32,
                max_pressure_mpa: self.max_pressure_mpa as f32,
                tangency: pt(x_tan),
                inflection: pt(x_inf),
            },
            root_regression_per_step: self.root_regression_per_step as f32,
            max_regression_per_step: self.max_regression_per_step as f32,
            c_growth_per_step: self.c_growth_per_step as f32,
            ellipse_height_mpa: self.ellipse_height_mpa as f32,
        }
    }
}

impl LoadCubic {
    /// The ellipse of eq. (24) over this load's stroke.
    pub fn ellipse(&self) -> Ellipse {
        Ellipse {
            root_contraction: self.cubic.root,
            max_contraction: self.max_contraction,
            height_mpa: self.ellipse_height_mpa,
        }
    }

    /// How far this load's constraint model is from losing the paper's shape.
    pub fn shape_margins(&self) -> ShapeMargins {
        let f = &self.cubic;
        let quadratic_min = if f.a > 0.0 {
            (4.0 * f.a * f.c - f.b * f.b) / (4.0 * f.a)
        } else {
            f64::NEG_INFINITY
        };
        // f' is a quadratic in x: its minimum on [R, Rx] is at an end or at
        // the inflection point (b + aR)/(3a).
        let (r, rx) = (f.root, self.max_contraction);
        let mut slope_min = f.slope(r).min(f.slope(rx));
        let xi = (f.b + f.a * r) / (3.0 * f.a);
        if xi > r && xi < rx {
            slope_min = slope_min.min(f.slope(xi));
        }
        ShapeMargins {
            quadratic_min,
            slope_min,
            mean_slope: self.max_pressure_mpa / (rx - r),
        }
    }

    /// The paper's two shape conditions with `margin` to spare (relative to
    /// the mean slope): a single real root (`a > 0` and `b² − 4ac < 0`, so the
    /// quadratic factor has complex roots) and a strictly increasing curve
    /// on `[R_i, Rx_i]`.
    pub fn check_shape(&self, margin: f64) -> Result<(), Error> {
        let m = self.shape_margins();
        let load_n = self.load_n as f32;
        let need = margin * m.mean_slope;
        if !(m.quadratic_min > need) {
            return Err(Error::NotOneRealRoot { load_n });
        }
        if !(m.slope_min > need) {
            // Where the slope is lowest, for the message.
            let f = &self.cubic;
            let xi = (f.b + f.a * f.root) / (3.0 * f.a);
            let mut x_low = f.root;
            for x in [self.max_contraction, xi] {
                if x >= f.root && x <= self.max_contraction && f.slope(x) < f.slope(x_low) {
                    x_low = x;
                }
            }
            return Err(Error::NotMonotone {
                load_n,
                contraction: x_low as f32,
            });
        }
        Ok(())
    }

    /// Constraint model `CM(x)`, eq. (21), with `x` clamped to `[R_i, Rx_i]`
    /// (NaN → `R_i`), and its slope (zero outside the open stroke, where the
    /// clamp holds the pressure at 0 or `Pmax`).
    pub fn constraint_pressure_and_slope(&self, contraction: f64) -> (f64, f64) {
        let f = &self.cubic;
        let inside = contraction > f.root && contraction < self.max_contraction;
        let x = clamp_f64(contraction, f.root, self.max_contraction);
        (f.eval(x), if inside { f.slope(x) } else { 0.0 })
    }

    /// Forward model, eqs. (25)–(26): the pressure that holds `contraction`
    /// on `branch`, clamped to `[0, Pmax]` as [`crate::LoadModel::pressure_mpa`]
    /// clamps, with the offset scaled by `offset_scale` (1: the paper's),
    /// and the slope of the constraint model there (the branch slope without
    /// the ellipse, whose slope is infinite at the stroke ends).
    pub fn pressure_and_slope(
        &self,
        contraction: f64,
        branch: Branch,
        offset_scale: f64,
    ) -> (f64, f64) {
        let (cm, slope) = self.constraint_pressure_and_slope(contraction);
        let y = self.ellipse().offset_mpa(contraction);
        let sign = f64::from(branch.offset_sign());
        let p = clamp_f64(cm + sign * offset_scale * y, 0.0, self.max_pressure_mpa);
        (p, slope)
    }

    /// [`Self::pressure_and_slope`]'s pressure with the paper's offset.
    pub fn pressure_mpa(&self, contraction: f64, branch: Branch) -> f64 {
        self.pressure_and_slope(contraction, branch, 1.0).0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::isclose;
    use crate::Coeffs;

    fn family() -> LoadFamily {
        LoadFamily::from_params(&Params::DEFAULT).unwrap()
    }

    #[test]
    fn constraint_model_hits_root_and_pmax_at_every_load() {
        let fam = family();
        for load in (100..=600).step_by(25) {
            let at = fam.at_load(f64::from(load));
            assert!(
                at.cubic.eval(at.cubic.root).abs() < 1e-12,
                "CM(R_i) at {load} N"
            );
            let top = at.cubic.eval(at.max_contraction);
            assert!(
                isclose(top, fam.max_pressure_mpa, 1e-9, 0.0),
                "CM(Rx_i) = {top} at {load} N"
            );
        }
    }

    #[test]
    fn grid_loads_follow_the_paper_recursions() {
        // eqs. (17)–(19) as recursions over the 100 N grid.
        let p = Params::DEFAULT;
        let fam = family();
        let mut prev = fam.at_load(f64::from(p.min_load_n));
        for i in 1..=5 {
            let at = fam.at_load(f64::from(p.min_load_n + p.load_step_n * i as f32));
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
    fn the_f64_path_agrees_with_the_f32_load_model() {
        let fam = family();
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        for load in [100.0f32, 170.0, 420.0, 600.0] {
            let m64 = fam.at_load(f64::from(load));
            let m32 = coeffs.load_model(load).unwrap();
            for k in 0..=200 {
                let x = -0.01 + 0.28 * f64::from(k) / 200.0;
                for br in [Branch::Contraction, Branch::Expansion] {
                    let p = m64.pressure_mpa(x, br);
                    let q = f64::from(m32.pressure_mpa(x as f32, br));
                    assert!((p - q).abs() < 2e-5, "{load} N x {x} {br:?}: {p} vs {q}");
                }
            }
        }
    }

    #[test]
    fn to_params_round_trips_the_family() {
        let fam = family();
        let back = LoadFamily::from_params(&fam.to_params()).unwrap();
        for load in [100.0, 350.0, 600.0] {
            let (a, b) = (fam.at_load(load), back.at_load(load));
            for k in 0..=50 {
                let x = 0.02 + 0.2 * f64::from(k) / 50.0;
                let d =
                    a.pressure_mpa(x, Branch::Contraction) - b.pressure_mpa(x, Branch::Contraction);
                assert!(d.abs() < 1e-5, "{load} N x {x}: {d}");
            }
        }
    }

    #[test]
    fn margins_are_positive_on_the_default_and_say_how_far_it_is_from_the_edge() {
        let fam = family();
        fam.check(0.0).unwrap();
        let worst = fam.worst_margin();
        assert!(worst > 0.0 && worst < 1.0, "{worst}");
        // A margin just above the worst one fails, just below passes.
        assert!(fam.check(worst * 1.001).is_err());
        fam.check(worst * 0.999).unwrap();
    }

    #[test]
    fn a_family_that_loses_shape_at_high_load_is_refused() {
        // Rx regresses so fast that the curve would have to fall to reach Pmax.
        let mut fam = family();
        fam.max_regression_per_step = 0.05;
        assert!(fam.check(0.0).is_err());
        assert!(fam.worst_margin() < 0.0);
    }
}

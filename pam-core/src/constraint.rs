//! The constraint model at the minimum load: the general cubic of eqs. (7)–(11)
//! through the four critical points, and its factor-theorem form (eqs. 12–14).
//!
//! Construction runs once (on the host or at boot) in `f64`; the per-sample
//! path only ever sees the `f32` factor form.

use crate::error::Error;
use crate::params::CriticalPoints;

/// General cubic in the paper's sign convention, eq. (7):
/// `f(x) = A x³ − B x² + C x + D`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GeneralCubic {
    /// `A`, the coefficient of `x³`.
    pub a3: f64,
    /// `B`, the coefficient of `−x²`.
    pub b2: f64,
    /// `C`, the coefficient of `x`.
    pub c1: f64,
    /// `D`, the constant.
    pub d0: f64,
}

/// Factor-theorem form, eqs. (5) and (21): `f(x) = (x − R)(a x² − b x + c)`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FactorCubic {
    /// `R`, the first (and only) real root: contraction at zero pressure.
    pub root: f64,
    /// `a`, amplitude.
    pub a: f64,
    /// `b`, width and gradient (shared by all loads, eq. 21).
    pub b: f64,
    /// `c`, the quadratic's intersection constant.
    pub c: f64,
}

impl GeneralCubic {
    /// Solve eqs. (8)–(11) for the cubic through `(R1, 0)`, `(Rx1, Pmax)`,
    /// `(x_tan, y_tan)` and `(x_inf, y_inf)`.
    ///
    /// Three misprints of the paper are corrected here (the third, eq. 10's
    /// `E2/E` for `E2/E1`, is noted at the line):
    /// * `F1`, `F2` are printed with `+ (X − R1)`; eliminating `A` (eq. 8)
    ///   from `A(X³−R1³) − B(X²−R1²) + C(X−R1) = Y` gives `− (X − R1)`
    ///   (`B·E − C·F = Y − G` only holds with the minus sign);
    /// * the line `B·E2 − C·F2 = x_tan − G2` must read `y_tan − G2`.
    pub fn through_points(p: &CriticalPoints) -> Result<GeneralCubic, Error> {
        let r1 = f64::from(p.root_contraction);
        let rx1 = f64::from(p.max_contraction);
        let pmax = f64::from(p.max_pressure_mpa);
        let (x_tan, y_tan) = (
            f64::from(p.tangency.contraction),
            f64::from(p.tangency.pressure_mpa),
        );
        let (x_inf, y_inf) = (
            f64::from(p.inflection.contraction),
            f64::from(p.inflection.pressure_mpa),
        );

        // Ratios of the cubic differences to the inflection point's.
        let d3_inf = cube(x_inf) - cube(r1);
        let k1 = (cube(rx1) - cube(r1)) / d3_inf;
        let k2 = (cube(x_tan) - cube(r1)) / d3_inf;
        let e1 = k1 * (x_inf * x_inf - r1 * r1) - (rx1 * rx1 - r1 * r1);
        let e2 = k2 * (x_inf * x_inf - r1 * r1) - (x_tan * x_tan - r1 * r1);
        let f1 = k1 * (x_inf - r1) - (rx1 - r1); // corrected sign, see above
        let f2 = k2 * (x_inf - r1) - (x_tan - r1); // corrected sign, see above
        let g1 = k1 * y_inf;
        let g2 = k2 * y_inf;

        // eq. (10); its second printing has `E2/E` in the denominator, a
        // misprint of `E2/E1` (the first printing and the derivation agree).
        let e21 = e2 / e1;
        let c = (e21 * pmax - e21 * g1 - y_tan + g2) / (f2 - e21 * f1);
        // eq. (9)
        let b = (pmax - g1 + c * f1) / e1;
        // eq. (8)
        let a = (y_inf + b * (x_inf * x_inf - r1 * r1) - c * (x_inf - r1)) / d3_inf;
        // eq. (11)
        let d = -a * cube(r1) + b * r1 * r1 - c * r1;

        let cubic = GeneralCubic {
            a3: a,
            b2: b,
            c1: c,
            d0: d,
        };
        if [a, b, c, d].iter().all(|v| v.is_finite()) {
            Ok(cubic)
        } else {
            Err(Error::Singular)
        }
    }

    /// `f(x)`, eq. (7).
    pub fn eval(&self, x: f64) -> f64 {
        ((self.a3 * x - self.b2) * x + self.c1) * x + self.d0
    }

    /// Factor form about the real root `r1`, eqs. (12)–(14).
    pub fn factor(&self, r1: f64) -> FactorCubic {
        let a = self.a3; // eq. (12)
        let b = self.b2 - a * r1; // eq. (13)
        let c = self.c1 - b * r1; // eq. (14)
        FactorCubic { root: r1, a, b, c }
    }
}

impl FactorCubic {
    /// `f(x) = (x − R)(a x² − b x + c)`, eq. (21).
    pub fn eval(&self, x: f64) -> f64 {
        (x - self.root) * ((self.a * x - self.b) * x + self.c)
    }

    /// Slope `f'(x)`.
    pub fn slope(&self, x: f64) -> f64 {
        let q = (self.a * x - self.b) * x + self.c;
        let dq = 2.0 * self.a * x - self.b;
        q + (x - self.root) * dq
    }

    /// Back to the general form, eq. (5):
    /// `A = a`, `B = b + aR`, `C = c + bR`, `D = −cR`.
    pub fn general(&self) -> GeneralCubic {
        GeneralCubic {
            a3: self.a,
            b2: self.b + self.a * self.root,
            c1: self.c + self.b * self.root,
            d0: -self.c * self.root,
        }
    }
}

fn cube(x: f64) -> f64 {
    x * x * x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Params;
    use crate::testing::isclose;

    /// The shape check of the load family at the minimum load.
    fn shape_at_min_load(points: CriticalPoints) -> Result<(), Error> {
        let params = Params {
            points,
            ..Params::DEFAULT
        };
        let fam = crate::LoadFamily::from_params(&params)?;
        fam.at_load(fam.min_load_n).check_shape(0.0)
    }

    #[test]
    fn general_cubic_passes_through_the_four_points() {
        let p = Params::DEFAULT.points;
        let g = GeneralCubic::through_points(&p).unwrap();
        let pts = [
            (p.root_contraction, 0.0),
            (p.max_contraction, p.max_pressure_mpa),
            (p.tangency.contraction, p.tangency.pressure_mpa),
            (p.inflection.contraction, p.inflection.pressure_mpa),
        ];
        for (x, y) in pts {
            let fx = g.eval(f64::from(x));
            assert!(
                isclose(fx, f64::from(y), 0.0, 1e-9),
                "f({x}) = {fx}, want {y}"
            );
        }
    }

    #[test]
    fn general_cubic_matches_a_direct_linear_solve() {
        // Cross-check the paper's elimination against Cramer's rule on the 4×4
        // system, for a cubic chosen by its coefficients.
        let truth = GeneralCubic {
            a3: 120.0,
            b2: 50.0,
            c1: 7.5,
            d0: -0.12,
        };
        let xs = [0.02f32, 0.24, 0.08, 0.14];
        let y = |x: f32| truth.eval(f64::from(x)) as f32;
        let p = CriticalPoints {
            root_contraction: xs[0],
            max_contraction: xs[1],
            max_pressure_mpa: y(xs[1]),
            tangency: crate::Point {
                contraction: xs[2],
                pressure_mpa: y(xs[2]),
            },
            inflection: crate::Point {
                contraction: xs[3],
                pressure_mpa: y(xs[3]),
            },
        };
        // The root is not exactly xs[0] for `truth`; shift D so that it is.
        let d_shift = -truth.eval(f64::from(xs[0]));
        let truth = GeneralCubic {
            d0: truth.d0 + d_shift,
            ..truth
        };
        let p = CriticalPoints {
            max_pressure_mpa: truth.eval(f64::from(xs[1])) as f32,
            tangency: crate::Point {
                contraction: xs[2],
                pressure_mpa: truth.eval(f64::from(xs[2])) as f32,
            },
            inflection: crate::Point {
                contraction: xs[3],
                pressure_mpa: truth.eval(f64::from(xs[3])) as f32,
            },
            ..p
        };
        let g = GeneralCubic::through_points(&p).unwrap();
        // f32 rounding of the inputs bounds the agreement.
        assert!(isclose(g.a3, truth.a3, 1e-3, 0.0), "{g:?} vs {truth:?}");
        assert!(isclose(g.b2, truth.b2, 1e-3, 0.0));
        assert!(isclose(g.c1, truth.c1, 1e-3, 0.0));
        assert!(isclose(g.d0, truth.d0, 1e-3, 1e-6));
    }

    #[test]
    fn factor_form_equals_general_form() {
        let p = Params::DEFAULT.points;
        let g = GeneralCubic::through_points(&p).unwrap();
        let f = g.factor(f64::from(p.root_contraction));
        for i in 0..=100 {
            let x = -0.1 + 0.5 * f64::from(i) / 100.0;
            assert!(isclose(f.eval(x), g.eval(x), 1e-9, 1e-9), "x = {x}");
        }
        let back = f.general();
        assert!(isclose(back.a3, g.a3, 1e-12, 0.0));
        assert!(isclose(back.b2, g.b2, 1e-12, 0.0));
        assert!(isclose(back.c1, g.c1, 1e-12, 0.0));
        assert!(isclose(back.d0, g.d0, 1e-9, 1e-12));
        // eq. (20), with its sign corrected: c1 = −D1/R1.
        assert!(isclose(f.c, -g.d0 / f.root, 1e-9, 0.0));
    }

    #[test]
    fn default_has_one_real_root_and_is_monotone() {
        let p = Params::DEFAULT.points;
        shape_at_min_load(p).unwrap();
    }

    #[test]
    fn a_point_set_with_three_real_roots_is_refused() {
        // Pressure dips back to zero inside the stroke: three real roots.
        let mut p = Params::DEFAULT.points;
        p.tangency = crate::Point {
            contraction: 0.08,
            pressure_mpa: 0.0,
        };
        p.inflection = crate::Point {
            contraction: 0.12,
            pressure_mpa: 0.02,
        };
        assert!(shape_at_min_load(p).is_err());
    }

    #[test]
    fn a_non_monotone_point_set_is_refused() {
        // The tangency point above the inflection point: the curve must fall.
        let mut p = Params::DEFAULT.points;
        p.tangency = crate::Point {
            contraction: 0.07,
            pressure_mpa: 0.35,
        };
        assert!(matches!(
            shape_at_min_load(p),
            Err(Error::NotMonotone { .. }) | Err(Error::NotOneRealRoot { .. })
        ));
    }

    #[test]
    fn repeated_contraction_is_singular() {
        let mut p = Params::DEFAULT.points;
        p.tangency.contraction = p.inflection.contraction;
        assert_eq!(GeneralCubic::through_points(&p), Err(Error::Singular));
    }
}

#[cfg(test)]
mod paper_relations {
    use super::*;
    use crate::params::Params;

    /// The figures stated on [`crate::CriticalPoints::tangency`]: on the
    /// default muscle the cubic's `b/(2a)` is far from the given tangency
    /// point and `b² − 4ac < 0`, so the paper's `h` has no real value.
    #[test]
    fn the_tangency_point_is_an_interior_point_not_b_over_2a() {
        let p = Params::DEFAULT.points;
        let f = GeneralCubic::through_points(&p)
            .unwrap()
            .factor(f64::from(p.root_contraction));
        let x_tan_paper = f.b / (2.0 * f.a);
        assert!((f64::from(p.tangency.contraction) - 0.068).abs() < 5e-4);
        assert!((x_tan_paper - 0.174).abs() < 5e-4, "b/(2a) = {x_tan_paper}");
        assert!(f.b * f.b - 4.0 * f.a * f.c < 0.0);
    }
}

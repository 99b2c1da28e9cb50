//! The hysteresis model at one load, eqs. (22)–(26): the constraint model plus
//! (contraction branch) or minus (expansion branch) half an ellipse over the
//! stroke `[R_i, Rx_i]`, with forward and inverse evaluation.
//!
//! # Clamps (all documented, none fails)
//! * Contraction outside `[R_i, Rx_i]` is clamped to it; NaN maps to `R_i`.
//! * Pressure out of the forward evaluation is clamped to `[0, Pmax]`: near
//!   `R_i` the ellipse's vertical tangent pulls the expansion branch below zero
//!   (a muscle cannot hold negative gauge pressure), and near `Rx_i` it pushes
//!   the contraction branch above `Pmax` (the supply cannot give more).
//! * Pressure into the inverse is clamped to `[0, Pmax]`; NaN maps to 0.
//!
//! # Inverse at the branch ends
//! Clamped as above, each branch is continuous but not strictly monotone at
//! its ends: the expansion branch is flat at 0 from `R_i` to where it crosses
//! zero, the contraction branch reaches `Pmax` before `Rx_i`. The inverse works
//! on the branch's monotone hull (its running maximum from `R_i`) and returns
//! the *largest* contraction whose hull pressure does not exceed the pressure
//! asked for. So `contraction(Pmax, ·)` is `Rx_i`; `contraction(0, Expansion)`
//! is a contraction at which the expansion branch is at zero pressure, no
//! further than one table interval (1/32 of the stroke) before the point
//! where it leaves zero (the dip is about `2·be²/(ae·CM'(R))`, 2·10⁻⁴ for the
//! default muscle); and where a branch is strictly increasing
//! `pressure_mpa(contraction(p)) = p` within [`INVERSE_TOLERANCE_MPA`].
//!
//! The inverse is bounded work: a binary search over a table of
//! [`INVERSE_KNOTS`] hull values per branch built with the model, then
//! [`INVERSE_NEWTON_STEPS`] bracketed Newton steps.

use crate::branch::Branch;
use crate::load_family::Coeffs;
use crate::math::{clamp, sqrt};

/// Knots of the inverse table per branch (uniform in contraction over
/// `[R_i, Rx_i]`, ends included). A power of two plus one keeps the binary
/// search at a fixed `log2(INVERSE_KNOTS − 1)` steps.
pub const INVERSE_KNOTS: usize = 33;

/// Bracketed Newton steps after the table look-up.
pub const INVERSE_NEWTON_STEPS: usize = 3;

/// Bound on `|pressure_mpa(contraction(p, br), br) − p|` on the strictly
/// increasing part of a branch, MPa; checked by the property tests.
pub const INVERSE_TOLERANCE_MPA: f32 = 2e-4;

/// The hysteresis model at one load, ready for per-sample evaluation.
///
/// Built by [`Coeffs::load_model`]; holds `f32` coefficients and the inverse
/// tables, about 300 bytes, no references.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadModel {
    load_n: f32,
    /// `R_i`.
    root: f32,
    /// `Rx_i`.
    max_contraction: f32,
    /// `a_i`, `b`, `c_i` of eq. (21).
    a: f32,
    b: f32,
    c: f32,
    /// `h_i` of eq. (24).
    centre: f32,
    /// `1/ae_i` of eq. (24).
    inv_half_width: f32,
    /// `be` of eq. (24), MPa.
    height_mpa: f32,
    max_pressure_mpa: f32,
    knot_step: f32,
    /// Running maximum of each clamped branch at the knots: `[contraction, expansion]`.
    hull_mpa: [[f32; INVERSE_KNOTS]; 2],
}

impl LoadModel {
    pub(crate) fn new(coeffs: &Coeffs, load_n: f32) -> LoadModel {
        let at = coeffs.load_cubic(load_n);
        let params = coeffs.params();
        let root = at.cubic.root as f32;
        let max_contraction = at.max_contraction as f32;
        // eq. (24): ae_i = (Rx_i − R_i)/2, and the centre h_i = R_i + ae_i. The
        // paper prints h_i = R_1 + ae_i, which centres every load's ellipse on
        // the minimum load's root; the ellipse must span [R_i, Rx_i] so that
        // both branches meet the constraint model at the stroke ends.
        let half_width = 0.5 * (at.max_contraction - at.cubic.root);
        let mut model = LoadModel {
            load_n: at.load_n,
            root,
            max_contraction,
            a: at.cubic.a as f32,
            b: at.cubic.b as f32,
            c: at.cubic.c as f32,
            centre: (at.cubic.root + half_width) as f32,
            inv_half_width: (1.0 / half_width) as f32,
            height_mpa: params.ellipse_height_mpa,
            max_pressure_mpa: params.points.max_pressure_mpa,
            knot_step: (max_contraction - root) / (INVERSE_KNOTS - 1) as f32,
            hull_mpa: [[0.0; INVERSE_KNOTS]; 2],
        };
        for (bi, branch) in [Branch::Contraction, Branch::Expansion]
            .into_iter()
            .enumerate()
        {
            let mut running = 0.0f32;
            for k in 0..INVERSE_KNOTS {
                let p = model.pressure_mpa(model.knot(k), branch);
                running = if p > running { p } else { running };
                model.hull_mpa[bi][k] = running;
            }
        }
        model
    }

    fn knot(&self, k: usize) -> f32 {
        if k + 1 >= INVERSE_KNOTS {
            self.max_contraction
        } else {
            self.root + self.knot_step * k as f32
        }
    }

    /// The load this model is for, N.
    pub fn load_n(&self) -> f32 {
        self.load_n
    }

    /// `R_i`: contraction at zero pressure on the constraint model.
    pub fn root_contraction(&self) -> f32 {
        self.root
    }

    /// `Rx_i`: contraction at `Pmax`.
    pub fn max_contraction(&self) -> f32 {
        self.max_contraction
    }

    /// `Pmax`, MPa.
    pub fn max_pressure_mpa(&self) -> f32 {
        self.max_pressure_mpa
    }

    /// `be`, the ellipse height, MPa.
    pub fn ellipse_height_mpa(&self) -> f32 {
        self.height_mpa
    }

    /// Constraint model `CM_ij = (x_j − R_i)(a_i x_j² − b x_j + c_i)`, eq. (21),
    /// with `x` clamped to `[R_i, Rx_i]` (NaN → `R_i`).
    #[inline]
    pub fn constraint_pressure_mpa(&self, contraction: f32) -> f32 {
        let x = clamp(contraction, self.root, self.max_contraction);
        self.cubic(x)
    }

    #[inline(always)]
    fn cubic(&self, x: f32) -> f32 {
        (x - self.root) * ((self.a * x - self.b) * x + self.c)
    }

    /// Ellipse offset `y_hys = k + be·√(1 − (x − h)²/ae²)` with `k = 0`,
    /// eqs. (23)–(24); zero outside `[R_i, Rx_i]`.
    #[inline]
    pub fn offset_mpa(&self, contraction: f32) -> f32 {
        let u = (contraction - self.centre) * self.inv_half_width;
        let w = 1.0 - u * u;
        // Outside the ellipse (and for NaN) the radicand is not positive: no offset.
        if w > 0.0 {
            self.height_mpa * sqrt(w)
        } else {
            0.0
        }
    }

    /// Forward model, eqs. (25) and (26): the pressure that holds `contraction`
    /// on `branch`, `HMC = CM + y_hys`, `HME = CM − y_hys` (the paper prints
    /// `HMC` for both). Clamped as the module docs say; never NaN.
    #[inline]
    pub fn pressure_mpa(&self, contraction: f32, branch: Branch) -> f32 {
        let x = clamp(contraction, self.root, self.max_contraction);
        let p = self.cubic(x) + branch.offset_sign() * self.offset_mpa(x);
        clamp(p, 0.0, self.max_pressure_mpa)
    }

    /// Unclamped branch pressure and its slope with respect to contraction.
    fn branch_and_slope(&self, x: f32, sign: f32) -> (f32, f32) {
        let q = (self.a * x - self.b) * x + self.c;
        let dq = 2.0 * self.a * x - self.b;
        let u = (x - self.centre) * self.inv_half_width;
        let w = 1.0 - u * u;
        let (y, dy) = if w > 0.0 {
            let r = sqrt(w);
            (
                self.height_mpa * r,
                -self.height_mpa * u * self.inv_half_width / r,
            )
        } else {
            (0.0, 0.0)
        };
        (
            (x - self.root) * q + sign * y,
            q + (x - self.root) * dq + sign * dy,
        )
    }

    /// Inverse model: the contraction at which `branch` has `pressure_mpa`.
    ///
    /// Returns a value in `[R_i, Rx_i]`, never NaN; see the module docs for
    /// the branch ends. Bounded work: 5 table comparisons and
    /// [`INVERSE_NEWTON_STEPS`] Newton steps.
    pub fn contraction(&self, pressure_mpa: f32, branch: Branch) -> f32 {
        let p = clamp(pressure_mpa, 0.0, self.max_pressure_mpa);
        let hull = match branch {
            Branch::Contraction => &self.hull_mpa[0],
            Branch::Expansion => &self.hull_mpa[1],
        };
        let last = INVERSE_KNOTS - 1;
        if p >= hull[last] {
            return self.max_contraction;
        }
        // Invariant: hull[lo] <= p < hull[hi]. hull[0] is the pressure at R_i,
        // which is 0 on both branches, so it holds from the start.
        let (mut lo, mut hi) = (0usize, last);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            // `get` keeps the search panic-free; mid < last always holds.
            if hull.get(mid).copied().unwrap_or(f32::INFINITY) <= p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let (h_lo, h_hi) = (
            hull.get(lo).copied().unwrap_or(0.0),
            hull.get(hi).copied().unwrap_or(0.0),
        );
        let (mut x_lo, mut x_hi) = (self.knot(lo), self.knot(hi));
        // Since the hull rises at `hi`, branch(x_hi) = hull[hi] > p while
        // branch(x_lo) <= hull[lo] <= p: [x_lo, x_hi] brackets the crossing.
        let frac = if h_hi > h_lo {
            (p - h_lo) / (h_hi - h_lo)
        } else {
            0.5
        };
        let mut x = x_lo + frac * (x_hi - x_lo);
        let sign = branch.offset_sign();
        for _ in 0..INVERSE_NEWTON_STEPS {
            let (g, dg) = self.branch_and_slope(x, sign);
            if g <= p {
                x_lo = x;
            } else {
                x_hi = x;
            }
            let next = x + (p - g) / dg;
            // Newton only while it stays inside the bracket (this also catches
            // dg = 0 or ±inf at the ellipse ends); bisect otherwise.
            x = if next >= x_lo && next <= x_hi {
                next
            } else {
                0.5 * (x_lo + x_hi)
            };
        }
        clamp(x, self.root, self.max_contraction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Params;

    fn model(load_n: f32) -> LoadModel {
        Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model(load_n)
            .unwrap()
    }

    #[test]
    fn both_branches_meet_the_constraint_model_at_the_stroke_ends() {
        for load in [100.0, 250.0, 600.0] {
            let m = model(load);
            for x in [m.root_contraction(), m.max_contraction()] {
                let cm = m.constraint_pressure_mpa(x);
                for br in [Branch::Contraction, Branch::Expansion] {
                    let p = m.pressure_mpa(x, br);
                    assert!(
                        (p - cm).abs() < 1e-5,
                        "{load} N, x {x}, {br:?}: {p} vs {cm}"
                    );
                }
            }
            assert!(m.constraint_pressure_mpa(m.root_contraction()).abs() < 1e-6);
            assert!((m.constraint_pressure_mpa(m.max_contraction()) - 0.5).abs() < 1e-5);
        }
    }

    #[test]
    fn offset_peaks_at_the_centre_with_the_ellipse_height() {
        let m = model(300.0);
        let mid = 0.5 * (m.root_contraction() + m.max_contraction());
        assert!((m.offset_mpa(mid) - 0.02).abs() < 1e-6);
        let up = m.pressure_mpa(mid, Branch::Contraction);
        let down = m.pressure_mpa(mid, Branch::Expansion);
        assert!((up - down - 0.04).abs() < 1e-5, "loop height 2·be");
    }

    #[test]
    fn paper_relation_between_loads_heavier_needs_more_pressure() {
        let (light, heavy) = (model(100.0), model(300.0));
        for x in [0.05, 0.1, 0.15] {
            assert!(heavy.constraint_pressure_mpa(x) > light.constraint_pressure_mpa(x));
        }
    }

    #[test]
    fn inverse_at_branch_ends() {
        let m = model(200.0);
        assert_eq!(m.contraction(0.5, Branch::Contraction), m.max_contraction());
        assert_eq!(
            m.contraction(0.0, Branch::Contraction),
            m.root_contraction()
        );
        // The expansion branch rests where it leaves zero pressure.
        let x0 = m.contraction(0.0, Branch::Expansion);
        assert!(x0 >= m.root_contraction());
        assert_eq!(m.pressure_mpa(x0, Branch::Expansion), 0.0);
        let stroke = m.max_contraction() - m.root_contraction();
        assert!(m.pressure_mpa(x0 + stroke / 32.0, Branch::Expansion) > 0.0);
        // The expansion branch does dip below zero (clamped) right after R_i.
        let e = m.constraint_pressure_mpa(m.root_contraction() + 1e-5)
            - m.offset_mpa(m.root_contraction() + 1e-5);
        assert!(e < 0.0);
        assert_eq!(
            m.contraction(f32::NAN, Branch::Contraction),
            m.root_contraction()
        );
    }

    #[test]
    fn inverse_round_trip_on_a_dense_grid() {
        for load in [100.0, 175.0, 350.0, 600.0] {
            let m = model(load);
            for br in [Branch::Contraction, Branch::Expansion] {
                let mut worst = 0.0f32;
                for i in 1..1000 {
                    let p = 0.5 * i as f32 / 1000.0;
                    let x = m.contraction(p, br);
                    worst = worst.max((m.pressure_mpa(x, br) - p).abs());
                }
                assert!(
                    worst <= INVERSE_TOLERANCE_MPA,
                    "{load} N {br:?}: worst {worst}"
                );
            }
        }
    }
}

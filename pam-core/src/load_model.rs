//! The hysteresis model at one load, eqs. (25)–(26), on the per-sample `f32`
//! path: the constraint model (eq. 21) plus (contraction branch) or minus
//! (expansion branch) the ellipse offset of eqs. (22)–(24)
//! ([`crate::ellipse`]), with forward and inverse evaluation.
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
//! asked for. So `contraction(Pmax, ·)` is `Rx_i`, `contraction(0, Expansion)`
//! is where the expansion branch leaves zero (the dip is about
//! `2·be²/(ae·CM'(R)²)`: 4.9·10⁻⁴ of contraction at 100 N and 3.4·10⁻⁴ at
//! 600 N for the default muscle), and where a branch is strictly increasing
//! `pressure_mpa(contraction(p)) = p` within [`INVERSE_TOLERANCE_MPA`], up to
//! and including `Pmax`.
//!
//! The exact inverse is non-decreasing in pressure. The evaluated one is
//! piecewise (one table interval, one Newton step each) and may step back at
//! a table node by a few `f32` rounding errors of the Newton step: at most
//! [`INVERSE_STEP_BACK`] of contraction (1.0·10⁻⁵ measured on 2·10⁶-point
//! pressure grids at 100–600 N; checked by a unit test).
//!
//! # Cost
//! Building a model (at start-up and on every load switch) solves the inverse
//! precisely at [`INVERSE_INTERVALS`]` + 1` pressures per branch. Per sample,
//! the inverse is then one table look-up indexed directly by pressure (no
//! search), a linear interpolation and one Newton step kept inside the table
//! interval: fixed work, two divisions and one square root.

use crate::branch::Branch;
use crate::load_family::LoadCubic;
use crate::math::{clamp, sqrt};

/// Intervals of the inverse table per branch, uniform in pressure over
/// `[0, Pmax]`.
pub const INVERSE_INTERVALS: usize = 64;

/// Contraction knots of the forward hull used while building the inverse table.
const BUILD_KNOTS: usize = 33;

/// Safeguarded Newton iterations per table entry while building.
const BUILD_ITERATIONS: usize = 12;

/// Bound on `|pressure_mpa(contraction(p, br), br) − p|` on the strictly
/// increasing part of a branch, MPa; checked by the unit and property tests.
pub const INVERSE_TOLERANCE_MPA: f32 = 2e-4;

/// Bound on how far [`LoadModel::contraction`] can step back (decrease) as the
/// pressure rises across a table node, in contraction; checked by the tests.
pub const INVERSE_STEP_BACK: f32 = 2e-5;

/// The hysteresis model at one load, ready for per-sample evaluation.
///
/// Built by [`crate::Coeffs::load_model`]; holds `f32` coefficients and the inverse
/// tables (about 560 bytes), no references.
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
    /// `be` of eq. (24), MPa.
    height_mpa: f32,
    /// `h_i` of eq. (24).
    centre: f32,
    /// `(be/ae_i)²`, MPa² (`ae_i` of eq. 24): the ellipse in the form
    /// `y_hys = √((be/ae_i)²·(x − R_i)(Rx_i − x))`, eq. (24) with
    /// `ae_i² − (x − h_i)² = (x − R_i)(Rx_i − x)`.
    ellipse_k2: f32,
    max_pressure_mpa: f32,
    /// `INVERSE_INTERVALS / Pmax`: table index per MPa.
    intervals_per_mpa: f32,
    /// Contraction at pressures `k·Pmax/INVERSE_INTERVALS` on each branch,
    /// `[contraction, expansion]`; the last entry is the left limit at `Pmax`.
    inverse_table: [[f32; INVERSE_INTERVALS + 1]; 2],
}

impl LoadModel {
    /// The `f32` model of `at` with its inverse tables (the load family's
    /// `f64` construction rounded once).
    pub(crate) fn new(at: &LoadCubic) -> LoadModel {
        let root = at.cubic.root as f32;
        let max_contraction = at.max_contraction as f32;
        let ellipse = at.ellipse();
        let height_mpa = at.ellipse_height_mpa as f32;
        let max_pressure_mpa = at.max_pressure_mpa as f32;
        let mut model = LoadModel {
            load_n: at.load_n as f32,
            root,
            max_contraction,
            a: at.cubic.a as f32,
            b: at.cubic.b as f32,
            c: at.cubic.c as f32,
            height_mpa,
            // eq. (24), centre corrected to R_i + ae_i (see `Ellipse::centre`).
            centre: ellipse.centre() as f32,
            ellipse_k2: ellipse.k2() as f32,
            max_pressure_mpa,
            intervals_per_mpa: INVERSE_INTERVALS as f32 / max_pressure_mpa,
            inverse_table: [[0.0; INVERSE_INTERVALS + 1]; 2],
        };
        model.inverse_table = [
            model.build_inverse(Branch::Contraction),
            model.build_inverse(Branch::Expansion),
        ];
        model
    }

    /// The inverse table of one branch, solved precisely from the branch's
    /// monotone hull on [`BUILD_KNOTS`] contraction knots.
    fn build_inverse(&self, branch: Branch) -> [f32; INVERSE_INTERVALS + 1] {
        let step = (self.max_contraction - self.root) / (BUILD_KNOTS - 1) as f32;
        let knot = |j: usize| {
            if j + 1 >= BUILD_KNOTS {
                self.max_contraction
            } else {
                self.root + step * j as f32
            }
        };
        let mut hull = [0.0f32; BUILD_KNOTS];
        let mut running = 0.0f32;
        for (j, h) in hull.iter_mut().enumerate() {
            let p = self.pressure_mpa(knot(j), branch);
            running = if p > running { p } else { running };
            *h = running;
        }
        let top = hull[BUILD_KNOTS - 1];
        let mut table = [0.0f32; INVERSE_INTERVALS + 1];
        for (k, x) in table.iter_mut().enumerate() {
            let last = k == INVERSE_INTERVALS;
            // Entry k: sup{x : hull(x) <= p_k}; the last entry: the left limit
            // at the hull's top, inf{x : hull(x) >= top}.
            let p = if last {
                top
            } else {
                self.max_pressure_mpa * k as f32 / INVERSE_INTERVALS as f32
            };
            let j = if last {
                hull.iter()
                    .position(|&h| h >= top)
                    .unwrap_or(BUILD_KNOTS - 1)
            } else {
                // Largest j with hull[j] <= p, then the crossing lies in [j, j + 1].
                hull.iter().rposition(|&h| h <= p).unwrap_or(0) + 1
            };
            *x = if j == 0 {
                self.root
            } else if j >= BUILD_KNOTS {
                self.max_contraction
            } else {
                self.solve_crossing(knot(j - 1), knot(j), p, branch, last)
            };
        }
        table
    }

    /// Bracketed Newton with bisection fallback for `branch(x) = p` in
    /// `[lo, hi]`, where `branch(lo) <= p` and `branch(hi) > p` (or `>= p`
    /// when `upper`, the left-limit case).
    fn solve_crossing(&self, mut lo: f32, mut hi: f32, p: f32, branch: Branch, upper: bool) -> f32 {
        let sign = branch.offset_sign();
        let mut x = 0.5 * (lo + hi);
        for _ in 0..BUILD_ITERATIONS {
            let (g, dg) = self.branch_and_slope(x, sign);
            let below = if upper { g < p } else { g <= p };
            if below {
                lo = x;
            } else {
                hi = x;
            }
            let next = x + (p - g) / dg;
            x = if next > lo && next < hi {
                next
            } else {
                0.5 * (lo + hi)
            };
        }
        if upper {
            hi
        } else {
            x
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
        let w = self.radicand(contraction);
        // Outside the ellipse (and for NaN) the radicand is not positive: no offset.
        if w > 0.0 {
            sqrt(w)
        } else {
            0.0
        }
    }

    /// `be²·(1 − (x − h)²/ae²) = (be/ae)²·(x − R_i)(Rx_i − x)`, the square of
    /// the ellipse offset, eq. (24). In this form it is exactly zero at both
    /// stroke ends and positive exactly for `R_i < x < Rx_i` (when `be > 0`);
    /// not positive outside, and NaN for NaN.
    #[inline(always)]
    fn radicand(&self, x: f32) -> f32 {
        self.ellipse_k2 * ((x - self.root) * (self.max_contraction - x))
    }

    /// Forward model, eqs. (25) and (26): the pressure that holds `contraction`
    /// on `branch`, `HMC = CM + y_hys`, `HME = CM − y_hys` (the paper prints
    /// `HMC` for both). Clamped as the module docs say; never NaN.
    #[inline]
    pub fn pressure_mpa(&self, contraction: f32, branch: Branch) -> f32 {
        let w = self.radicand(contraction);
        let p = if w > 0.0 {
            // A positive radicand means R_i < x < Rx_i (see `radicand`): the
            // contraction clamp would not change x, so it is skipped. Finite.
            self.cubic(contraction) + branch.offset_sign() * sqrt(w)
        } else {
            // Outside the ellipse (or NaN, or `be = 0`): no offset, and the
            // contraction clamped to the stroke as documented.
            self.cubic(clamp(contraction, self.root, self.max_contraction))
        };
        clamp(p, 0.0, self.max_pressure_mpa)
    }

    /// Unclamped branch pressure and its slope with respect to contraction.
    fn branch_and_slope(&self, x: f32, sign: f32) -> (f32, f32) {
        let q = (self.a * x - self.b) * x + self.c;
        let dq = 2.0 * self.a * x - self.b;
        let w = self.radicand(x);
        let (y, dy) = if w > 0.0 {
            let y = sqrt(w);
            // d/dx √(k²(x − R)(Rx − x)) = k²(h − x)/√(…), h = (R + Rx)/2.
            (y, self.ellipse_k2 * (self.centre - x) / y)
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
    /// the branch ends. Fixed work: one table look-up, one interpolation, one
    /// Newton step (two divisions, one square root).
    pub fn contraction(&self, pressure_mpa: f32, branch: Branch) -> f32 {
        let p = clamp(pressure_mpa, 0.0, self.max_pressure_mpa);
        if p >= self.max_pressure_mpa {
            return self.max_contraction;
        }
        let table = match branch {
            Branch::Contraction => &self.inverse_table[0],
            Branch::Expansion => &self.inverse_table[1],
        };
        let t = p * self.intervals_per_mpa;
        // `as` saturates, and `min` keeps k + 1 inside the table.
        let k = (t as usize).min(INVERSE_INTERVALS - 1);
        let frac = t - k as f32;
        let (x_lo, x_hi) = match (table.get(k), table.get(k + 1)) {
            (Some(&a), Some(&b)) => (a, b),
            _ => return self.root, // unreachable: k < INVERSE_INTERVALS
        };
        // Where the ellipse's vertical tangent meets the stroke end (contraction
        // branch at R_i, expansion branch at Rx_i), pressure goes as the square
        // root of the distance to the end, so contraction goes as the square of
        // the pressure: interpolate quadratically there, linearly elsewhere.
        let w = match branch {
            Branch::Contraction if k == 0 => frac * frac,
            Branch::Expansion if k == INVERSE_INTERVALS - 1 => 1.0 - (1.0 - frac) * (1.0 - frac),
            _ => frac,
        };
        let x = x_lo + w * (x_hi - x_lo);
        let (g, dg) = self.branch_and_slope(x, branch.offset_sign());
        // One Newton step, kept inside [x_lo, x_hi] (a step that leaves it:
        // dg = 0 or ±inf, NaN, is not taken). In the expansion branch's last
        // interval the step is taken in `s = sqrt(Rx_i − x)`, in which the
        // branch is nearly linear; in `x` it stalls against the ellipse's
        // vertical tangent and misses the tolerance next to Pmax. (At `R_i`
        // on the contraction branch the same change of variable loses more
        // to `f32` rounding of `x − R_i` than it gains: the `x` step holds
        // the tolerance there.)
        let next = match branch {
            Branch::Expansion if k == INVERSE_INTERVALS - 1 => {
                let s = sqrt(x_hi - x);
                let s_next = s - (p - g) / (2.0 * s * dg);
                x_hi - s_next * s_next
            }
            _ => x + (p - g) / dg,
        };
        if next >= x_lo && next <= x_hi {
            next
        } else {
            x
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Params;
    use crate::Coeffs;

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
            let pmax = Params::DEFAULT.points.max_pressure_mpa;
            assert!((m.constraint_pressure_mpa(m.max_contraction()) - pmax).abs() < 1e-5);
        }
    }

    #[test]
    fn offset_peaks_at_the_centre_with_the_ellipse_height() {
        let m = model(300.0);
        let mid = 0.5 * (m.root_contraction() + m.max_contraction());
        let be = Params::DEFAULT.ellipse_height_mpa;
        assert!((m.offset_mpa(mid) - be).abs() < 1e-6);
        let up = m.pressure_mpa(mid, Branch::Contraction);
        let down = m.pressure_mpa(mid, Branch::Expansion);
        assert!((up - down - 2.0 * be).abs() < 1e-5, "loop height 2·be");
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
        let pmax = Params::DEFAULT.points.max_pressure_mpa;
        assert_eq!(
            m.contraction(pmax, Branch::Contraction),
            m.max_contraction()
        );
        assert!((m.contraction(0.0, Branch::Contraction) - m.root_contraction()).abs() < 1e-5);
        // The expansion branch rests where it leaves zero pressure.
        let x0 = m.contraction(0.0, Branch::Expansion);
        assert!(x0 > m.root_contraction());
        assert!(m.pressure_mpa(x0 - 1e-5, Branch::Expansion) == 0.0);
        assert!(m.pressure_mpa(x0 + 1e-5, Branch::Expansion) > 0.0);
        // The expansion branch does dip below zero (clamped) right after R_i.
        let e = m.constraint_pressure_mpa(m.root_contraction() + 1e-5)
            - m.offset_mpa(m.root_contraction() + 1e-5);
        assert!(e < 0.0);
        // NaN pressure reads as zero pressure.
        assert_eq!(
            m.contraction(f32::NAN, Branch::Contraction),
            m.contraction(0.0, Branch::Contraction)
        );
    }

    #[test]
    fn inverse_round_trip_on_a_dense_grid_up_to_pmax() {
        let pmax = Params::DEFAULT.points.max_pressure_mpa;
        for load in [100.0, 175.0, 350.0, 600.0] {
            let m = model(load);
            for br in [Branch::Contraction, Branch::Expansion] {
                let mut worst = 0.0f32;
                // The last 200 points sit within 1e-3 MPa of Pmax, where the
                // expansion branch meets the ellipse's vertical tangent.
                let near_pmax = (0..=200).map(|i| pmax - 1e-3 * i as f32 / 200.0);
                for p in (1..=20_000)
                    .map(|i| pmax * i as f32 / 20_000.0)
                    .chain(near_pmax)
                {
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

    #[test]
    fn inverse_steps_back_by_at_most_the_stated_bound() {
        let pmax = Params::DEFAULT.points.max_pressure_mpa;
        for load in [100.0, 200.0, 350.0, 600.0] {
            let m = model(load);
            for br in [Branch::Contraction, Branch::Expansion] {
                let mut highest = f32::NEG_INFINITY;
                let mut worst = 0.0f32;
                for i in 0..=200_000 {
                    let x = m.contraction(pmax * i as f32 / 200_000.0, br);
                    worst = worst.max(highest - x);
                    highest = highest.max(x);
                }
                assert!(worst <= INVERSE_STEP_BACK, "{load} N {br:?}: {worst}");
            }
        }
    }

    #[test]
    fn expansion_zero_crossing_follows_the_stated_estimate() {
        // The module docs: the expansion branch leaves zero about
        // 2·be²/(ae·CM'(R)²) after R_i.
        for load in [100.0, 600.0] {
            let m = model(load);
            let r = m.root_contraction();
            let h = 1e-4;
            let slope = (m.constraint_pressure_mpa(r + h) - m.constraint_pressure_mpa(r)) / h;
            let ae = 0.5 * (m.max_contraction() - r);
            let be = m.ellipse_height_mpa();
            let estimate = 2.0 * be * be / (ae * slope * slope);
            let dip = m.contraction(0.0, Branch::Expansion) - r;
            assert!(
                (dip / estimate - 1.0).abs() < 0.05,
                "{load} N: dip {dip}, estimate {estimate}"
            );
        }
    }
}

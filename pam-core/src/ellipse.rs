//! The hysteresis offset, eqs. (22)–(24): half an ellipse over the stroke
//! `[R_i, Rx_i]` of one load, added on the contraction branch and subtracted
//! on the expansion branch (eqs. 25–26, [`crate::LoadModel`]).
//!
//! This is the `f64` form the host tools and model construction use; the
//! per-sample `f32` path in [`crate::LoadModel`] evaluates the same expression
//! in the same algebraic form.

use crate::math::sqrt_f64;

/// The ellipse of eq. (24) at one load.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipse {
    /// `R_i`, where the ellipse starts (contraction).
    pub root_contraction: f64,
    /// `Rx_i`, where it ends (contraction).
    pub max_contraction: f64,
    /// `be`, its height, MPa.
    pub height_mpa: f64,
}

impl Ellipse {
    /// `h_i = R_i + ae_i`, the centre. The paper prints `h_i = R_1 + ae_i`,
    /// which centres every load's ellipse on the minimum load's root; the
    /// ellipse must span `[R_i, Rx_i]` so that both branches meet the
    /// constraint model at the stroke ends (eq. 24 corrected).
    pub fn centre(&self) -> f64 {
        self.root_contraction + self.half_width()
    }

    /// `ae_i = (Rx_i − R_i)/2`, the half width (eq. 24).
    pub fn half_width(&self) -> f64 {
        0.5 * (self.max_contraction - self.root_contraction)
    }

    /// `(be/ae_i)²`, MPa²: eq. (24) in the form
    /// `y_hys² = (be/ae_i)²·(x − R_i)(Rx_i − x)`, using
    /// `ae_i² − (x − h_i)² = (x − R_i)(Rx_i − x)`. In this form the square is
    /// exactly zero at both stroke ends and positive only between them.
    pub fn k2(&self) -> f64 {
        let k = self.height_mpa / self.half_width();
        k * k
    }

    /// `y_hys(x) = be·√(1 − (x − h_i)²/ae_i²)` (eqs. 23–24, with `k = 0`);
    /// zero outside `[R_i, Rx_i]` and for NaN.
    pub fn offset_mpa(&self, contraction: f64) -> f64 {
        self.offset_and_slope(contraction).0
    }

    /// `(y_hys(x), dy_hys/dx)`; both zero outside the open stroke (the slope
    /// is infinite at the ends and is reported as 0 there).
    pub fn offset_and_slope(&self, contraction: f64) -> (f64, f64) {
        let k2 = self.k2();
        let w = k2 * ((contraction - self.root_contraction) * (self.max_contraction - contraction));
        if w > 0.0 {
            let y = sqrt_f64(w);
            // d/dx √(k²(x − R)(Rx − x)) = k²(h − x)/√(…).
            (y, k2 * (self.centre() - contraction) / y)
        } else {
            (0.0, 0.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_offset_is_half_an_ellipse_over_the_stroke() {
        let e = Ellipse {
            root_contraction: 0.02,
            max_contraction: 0.22,
            height_mpa: 0.03,
        };
        assert_eq!(e.offset_mpa(0.02), 0.0);
        assert_eq!(e.offset_mpa(0.22), 0.0);
        assert_eq!(e.offset_mpa(0.3), 0.0);
        assert_eq!(e.offset_mpa(f64::NAN), 0.0);
        assert!((e.offset_mpa(0.12) - 0.03).abs() < 1e-15);
        // Eq. (24) as printed: be·√(1 − (x − h)²/ae²).
        for x in [0.03, 0.07, 0.15, 0.21] {
            let u: f64 = (x - 0.12) / 0.1;
            let paper = 0.03 * (1.0 - u * u).sqrt();
            assert!((e.offset_mpa(x) - paper).abs() < 1e-12, "{x}");
        }
        // The slope by central differences.
        let (_, dy) = e.offset_and_slope(0.05);
        let fd = (e.offset_mpa(0.05 + 1e-7) - e.offset_mpa(0.05 - 1e-7)) / 2e-7;
        assert!((dy - fd).abs() < 1e-5 * fd.abs(), "{dy} vs {fd}");
    }
}

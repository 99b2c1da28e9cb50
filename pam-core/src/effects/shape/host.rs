//! The host path of the shape (`f64`): the chip's map in double precision,
//! for identification.

use super::table::{self, StrokeTable, TABLE_KNOTS};
use super::{ConstraintShape, MAX_SHAPE_SLOPE};
use crate::branch::Branch;
use crate::load_family::LoadCubic;

/// The host path (`f64`): the same map as the `f32` one the chip runs
/// ([`ConstraintShape::at_load`], [`ConstraintShape::apply`],
/// [`super::ShapeInverse::model_contraction`]) in double precision, for an
/// identification whose finite differences need more than `f32`'s seven
/// digits. Test `f64_path_agrees_with_the_chip`.
impl ConstraintShape {
    /// The ten coefficients in field order, as `f64`: what
    /// [`Self::at_steps_f64`] takes, so that a fit can vary them in double
    /// precision and round to the `f32` fields once, at the end.
    pub fn coefficients_f64(&self) -> [f64; 10] {
        [
            self.bulge,
            self.tilt,
            self.bulge_per_step,
            self.tilt_per_step,
            self.root_shift,
            self.end_shift,
            self.root_shift_per_step,
            self.end_shift_per_step,
            self.root_shift_per_step_sq,
            self.end_shift_per_step_sq,
        ]
        .map(f64::from)
    }

    /// The shape with these coefficients (field order, rounded to `f32`).
    pub fn from_coefficients_f64(c: [f64; 10]) -> ConstraintShape {
        let c = c.map(|v| v as f32);
        ConstraintShape {
            bulge: c[0],
            tilt: c[1],
            bulge_per_step: c[2],
            tilt_per_step: c[3],
            root_shift: c[4],
            end_shift: c[5],
            root_shift_per_step: c[6],
            end_shift_per_step: c[7],
            root_shift_per_step_sq: c[8],
            end_shift_per_step_sq: c[9],
            table: StrokeTable::NEUTRAL,
        }
    }

    /// [`Self::at_load`] of the shape with coefficients `c`
    /// ([`Self::coefficients_f64`]): `(bulge, tilt, root_shift, end_shift)`
    /// at `steps = (L − L_min)/ΔL`, scaled back to [`MAX_SHAPE_SLOPE`] as
    /// the chip's is, and the unscaled sum `|bulge| + |tilt| + |end_shift −
    /// root_shift|` (for a fit that keeps it inside the limit).
    pub fn at_steps_f64(c: [f64; 10], steps: f64) -> ([f64; 4], f64) {
        let steps = if steps.is_finite() { steps } else { 0.0 };
        let b = c[0] + c[2] * steps;
        let t = c[1] + c[3] * steps;
        let r = c[4] + c[6] * steps + c[8] * steps * steps;
        let e = c[5] + c[7] * steps + c[9] * steps * steps;
        let sum = b.abs() + t.abs() + (e - r).abs();
        let limit = f64::from(MAX_SHAPE_SLOPE);
        let k = if sum > limit && sum.is_finite() {
            limit / sum
        } else if sum.is_finite() {
            1.0
        } else {
            0.0
        };
        ([b * k, t * k, r * k, e * k], sum)
    }

    /// The model's pressure with the shape `at` ([`Self::at_steps_f64`])
    /// at the muscle's `contraction` on `branch`, and its slope along the
    /// muscle's contraction: what the feedforward computes (the contraction
    /// held to the stroke, the shape's inverse, eqs. 21–26 on the branch),
    /// in `f64`. `table`: the stroke table's knots at the load
    /// ([`table::at_fraction_f64`]), `None` for the identity.
    pub fn pressure_and_slope_f64(
        at: [f64; 4],
        table: Option<&[f64; TABLE_KNOTS]>,
        model: &LoadCubic,
        contraction: f64,
        branch: Branch,
    ) -> (f64, f64) {
        let (r, rx) = (model.cubic.root, model.max_contraction);
        let s = rx - r;
        if !(s > 0.0) {
            return model.pressure_and_slope(contraction, branch, 1.0);
        }
        let target = ((contraction - r) / s).clamp(0.0, 1.0);
        let v = Self::inverse_fraction_f64(at, target);
        let (_, poly_slope) = Self::map_fraction_f64(at, v);
        let (u, table_slope) = match table {
            Some(k) => table::inverse_f64(k, v),
            None => (v, 1.0),
        };
        let (p, slope) = model.pressure_and_slope(r + s * u, branch, 1.0);
        (p, slope / (poly_slope * table_slope).max(1e-6))
    }

    /// The stroke fraction's map and its slope for `(bulge, tilt,
    /// root_shift, end_shift)` from [`Self::at_steps_f64`].
    pub fn map_fraction_f64([b, t, r, e]: [f64; 4], u: f64) -> (f64, f64) {
        let d = e - r;
        let value = r + u + u * d + u * (1.0 - u) * ((b - t) + 2.0 * t * u);
        let slope = (1.0 + (b - t) + d) + 2.0 * (3.0 * t - b) * u - 6.0 * t * u * u;
        (value, slope)
    }

    /// The stroke fraction `u ∈ [0, 1]` whose map is `target` (clamped to
    /// the map's ends): a bracketed Newton iteration to `f64` precision.
    /// With the map's slope at least `1 − MAX_SHAPE_SLOPE` it converges in
    /// a few steps; at most 60 (then it is a bisection's answer).
    pub fn inverse_fraction_f64(shape: [f64; 4], target: f64) -> f64 {
        let (lo_end, _) = Self::map_fraction_f64(shape, 0.0);
        let (hi_end, _) = Self::map_fraction_f64(shape, 1.0);
        let target = if target.is_finite() {
            target.clamp(lo_end.min(hi_end), hi_end.max(lo_end))
        } else {
            lo_end
        };
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        let span = hi_end - lo_end;
        let mut u = if span > 0.0 {
            ((target - lo_end) / span).clamp(0.0, 1.0)
        } else {
            0.5
        };
        for _ in 0..60 {
            let (f, slope) = Self::map_fraction_f64(shape, u);
            let f = f - target;
            if f <= 0.0 {
                lo = u;
            } else {
                hi = u;
            }
            let next = u - f / slope;
            let next = if next >= lo && next <= hi {
                next
            } else {
                0.5 * (lo + hi)
            };
            if (next - u).abs() <= 1e-15 {
                return next;
            }
            u = next;
        }
        u
    }
}

//! Constraint shape: a static curve the paper's cubic cannot follow, as a
//! correction along the stroke that both branches share.
//!
//! The paper's constraint model is a cubic between the stroke ends
//! (eqs. 7–14). A muscle whose static curve is outside that family (a
//! nearly vertical start, a hyperbolic end) leaves an error that depends on
//! where along the stroke the muscle is, the same on the contraction and
//! expansion branches. This effect maps the model's contraction `x` to
//!
//! `x' = R + S·(u + u·(1 − u)·(bulge + tilt·(2u − 1)) + (1 − u)·root_shift + u·end_shift)`,
//! `u = (x − R)/S`,
//!
//! with `R`, `S = Rx − R` the active load's stroke (eqs. 17–19), so the
//! correction follows each load of the family in proportion to its stroke.
//! The bulge and tilt vanish at both stroke ends and change linearly with
//! load; the shifts move the stroke ends themselves, quadratic in load
//! (the paper's stroke ends are linear in load, eqs. 17–18; a muscle whose
//! ends bend with load, as the Tondu–Lopez law's do, leaves an error at the
//! ends of the stroke that grows and changes sign along the load family).
//! The map is strictly increasing in `x` whenever
//! `|bulge| + |tilt| + |end_shift − root_shift| < 1` (the derivative of
//! `u·(1 − u)·(a + b·(2u − 1))` is within `±(|a| + |b|)` on `[0, 1]`).
//! Validation and [`ConstraintShape::at_load`] keep that sum within
//! `MAX_SHAPE_SLOPE`, so the map always has an inverse
//! ([`ConstraintShape::model_contraction`]) for a feedforward.

mod host;
pub mod table;

pub use table::StrokeTable;

use crate::error::Error;
use crate::load_model::LoadModel;
use crate::math::clamp;
use crate::params::Params;

/// Largest `|bulge| + |tilt|`: the corrected curve's slope along the stroke
/// stays at least `1 − MAX_SHAPE_SLOPE` of the model's.
pub const MAX_SHAPE_SLOPE: f32 = 0.9;

/// Safeguarded Newton steps of [`ConstraintShape::model_contraction`]. The
/// map's slope along the stroke is within `[1 − MAX_SHAPE_SLOPE,
/// 1 + MAX_SHAPE_SLOPE]`, so from the chord's estimate the steps converge
/// fast: over 200 000 random shapes at the slope limit the inverse is
/// within 1.2·10⁻⁶ of the stroke after these steps (9.5·10⁻⁷ measured;
/// test `newton_inverse_matches_a_long_bisection`), against 24 bisection
/// steps before (about 580 instructions on the M4F per call; 180 now,
/// with the shape's part of the work done once per load,
/// [`ShapeInverse`]). Three steps are not enough (2.6·10⁻⁴).
pub const SHAPE_INVERSE_STEPS: usize = 4;

/// Parameters of the constraint-shape correction (fractions of the stroke).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ConstraintShape {
    /// Symmetric bulge: positive moves mid-stroke contraction up.
    pub bulge: f32,
    /// Antisymmetric part: positive moves the upper half of the stroke up
    /// and the lower half down.
    pub tilt: f32,
    /// Change of `bulge` per load step `ΔL` (`Params::load_step_n`).
    pub bulge_per_step: f32,
    /// Change of `tilt` per load step.
    pub tilt_per_step: f32,
    /// Shift of the stroke's root end, a fraction of the stroke, at the
    /// minimum load.
    pub root_shift: f32,
    /// Shift of the stroke's far end (`Rx`), a fraction of the stroke, at
    /// the minimum load.
    pub end_shift: f32,
    /// Change of `root_shift` per load step `ΔL`.
    pub root_shift_per_step: f32,
    /// Change of `end_shift` per load step.
    pub end_shift_per_step: f32,
    /// Change of `root_shift` per squared load step,
    /// `((L − L_min)/ΔL)²`.
    pub root_shift_per_step_sq: f32,
    /// Change of `end_shift` per squared load step.
    pub end_shift_per_step_sq: f32,
    /// The stroke table ([`StrokeTable`]): a monotone piecewise-linear map
    /// of the stroke fraction per load, applied before the polynomial part.
    /// A model without it (older files) has the identity.
    #[cfg_attr(feature = "serde", serde(default))]
    pub table: StrokeTable,
}

impl ConstraintShape {
    /// No correction.
    pub const NEUTRAL: ConstraintShape = ConstraintShape {
        bulge: 0.0,
        tilt: 0.0,
        bulge_per_step: 0.0,
        tilt_per_step: 0.0,
        root_shift: 0.0,
        end_shift: 0.0,
        root_shift_per_step: 0.0,
        end_shift_per_step: 0.0,
        root_shift_per_step_sq: 0.0,
        end_shift_per_step_sq: 0.0,
        table: StrokeTable::NEUTRAL,
    };

    /// The shape at `load_n` (no load dependence left). Where the load
    /// terms carry `|bulge| + |tilt| + |end_shift − root_shift|` beyond
    /// [`MAX_SHAPE_SLOPE`] all four are scaled down to it, so the map stays
    /// increasing at every load; a non-finite load gives the shape at the
    /// minimum load.
    pub fn at_load(&self, params: &Params, load_n: f32) -> ConstraintShape {
        let bend = self.bend_at_load(params, load_n);
        ConstraintShape {
            bulge: bend.bulge,
            tilt: bend.tilt,
            bulge_per_step: 0.0,
            tilt_per_step: 0.0,
            root_shift: bend.root_shift,
            end_shift: bend.end_shift,
            root_shift_per_step: 0.0,
            end_shift_per_step: 0.0,
            root_shift_per_step_sq: 0.0,
            end_shift_per_step_sq: 0.0,
            table: StrokeTable {
                knots: [self.table.knots_at_load(params, load_n); table::TABLE_LOADS],
            },
        }
    }

    /// The polynomial part at `load_n`, as [`Self::at_load`] has it.
    fn bend_at_load(&self, params: &Params, load_n: f32) -> Bend {
        let steps = (load_n - params.min_load_n) / params.load_step_n;
        let steps = if steps.is_finite() { steps } else { 0.0 };
        let b = self.bulge + self.bulge_per_step * steps;
        let t = self.tilt + self.tilt_per_step * steps;
        let r = self.root_shift
            + self.root_shift_per_step * steps
            + self.root_shift_per_step_sq * steps * steps;
        let e = self.end_shift
            + self.end_shift_per_step * steps
            + self.end_shift_per_step_sq * steps * steps;
        let sum = b.abs() + t.abs() + (e - r).abs();
        let k = if sum > MAX_SHAPE_SLOPE && sum.is_finite() {
            MAX_SHAPE_SLOPE / sum
        } else if sum.is_finite() {
            1.0
        } else {
            0.0
        };
        Bend {
            bulge: b * k,
            tilt: t * k,
            root_shift: r * k,
            end_shift: e * k,
        }
    }

    /// Finite, `|bulge| + |tilt| + |end_shift − root_shift| ≤
    /// MAX_SHAPE_SLOPE` (strictly increasing), shifts and their load terms
    /// within `±MAX_SHAPE_SLOPE`.
    pub fn validate(&self) -> Result<(), Error> {
        for (v, name) in [
            (self.root_shift, "shape.root_shift"),
            (self.end_shift, "shape.end_shift"),
            (self.root_shift_per_step, "shape.root_shift_per_step"),
            (self.end_shift_per_step, "shape.end_shift_per_step"),
            (self.root_shift_per_step_sq, "shape.root_shift_per_step_sq"),
            (self.end_shift_per_step_sq, "shape.end_shift_per_step_sq"),
        ] {
            if !v.is_finite() {
                return Err(Error::NonFinite(name));
            }
            if !(v.abs() <= MAX_SHAPE_SLOPE) {
                return Err(Error::OutOfRange(
                    name,
                    "shifts must be within +-MAX_SHAPE_SLOPE",
                ));
            }
        }
        if !self.bulge.is_finite() {
            return Err(Error::NonFinite("shape.bulge"));
        }
        if !self.tilt.is_finite() {
            return Err(Error::NonFinite("shape.tilt"));
        }
        if !self.bulge_per_step.is_finite() {
            return Err(Error::NonFinite("shape.bulge_per_step"));
        }
        if !self.tilt_per_step.is_finite() {
            return Err(Error::NonFinite("shape.tilt_per_step"));
        }
        if !(self.bulge_per_step.abs() <= MAX_SHAPE_SLOPE
            && self.tilt_per_step.abs() <= MAX_SHAPE_SLOPE)
        {
            return Err(Error::OutOfRange(
                "shape.bulge_per_step",
                "per-step terms must be within +-MAX_SHAPE_SLOPE",
            ));
        }
        // A rounding's tolerance: the map is increasing up to a sum of 1.
        if !(self.bulge.abs() + self.tilt.abs() + (self.end_shift - self.root_shift).abs()
            <= MAX_SHAPE_SLOPE + 1e-6)
        {
            return Err(Error::OutOfRange(
                "shape.bulge",
                "|bulge| + |tilt| + |end_shift - root_shift| must be at most MAX_SHAPE_SLOPE",
            ));
        }
        self.table.validate()?;
        Ok(())
    }

    /// The stroke fraction `u` corrected: `u + u·(1 − u)·(bulge + tilt·(2u − 1))
    /// + (1 − u)·root_shift + u·end_shift`.
    fn map_fraction(&self, u: f32) -> f32 {
        self.bend().map_fraction(u)
    }

    /// The polynomial part at the minimum load.
    fn bend(&self) -> Bend {
        Bend {
            bulge: self.bulge,
            tilt: self.tilt,
            root_shift: self.root_shift,
            end_shift: self.end_shift,
        }
    }

    /// The muscle's contraction where `model` predicts `contraction`, with
    /// the shape at the minimum load (see [`Self::at_load`] for the rest).
    ///
    /// The input is clamped to the model's stroke `[R, Rx]` (NaN → `R`); the
    /// result lies in the shifted stroke `[R + S·root_shift, Rx + S·end_shift]`.
    pub fn apply(&self, model: &LoadModel, contraction: f32) -> f32 {
        let (r, rx) = (model.root_contraction(), model.max_contraction());
        let s = rx - r;
        if !(s > 0.0) {
            return r;
        }
        let x = if contraction.is_finite() {
            contraction
        } else {
            r
        };
        let u = clamp((x - r) / s, 0.0, 1.0);
        let k = &self.table.knots[0];
        let u = if table::is_identity(k) {
            u
        } else {
            table::map(k, u)
        };
        r + s * clamp(
            self.map_fraction(u),
            self.map_fraction(0.0),
            self.map_fraction(1.0),
        )
    }

    /// The inverse of [`Self::apply`]: the model's contraction whose
    /// corrected value is `contraction` (for a feedforward, which inverts
    /// the model at the model's contraction), with the shape at the minimum
    /// load as [`Self::apply`] has it. [`ShapeInverse::model_contraction`]
    /// on [`ShapeInverse::new`]: a feedforward that inverts every period
    /// keeps the [`ShapeInverse`] of the active load instead (see
    /// [`Self::inverse_at_load`]). The input is clamped to the shifted
    /// stroke, the result is in `[R, Rx]`.
    pub fn model_contraction(&self, model: &LoadModel, contraction: f32) -> f32 {
        ShapeInverse::new(*self).model_contraction(model, contraction)
    }

    /// [`Self::at_load`] ready for its inverse: what a feedforward computes
    /// once per load switch.
    pub fn inverse_at_load(&self, params: &Params, load_n: f32) -> ShapeInverse {
        ShapeInverse::from_parts(
            self.bend_at_load(params, load_n),
            self.table.knots_at_load(params, load_n),
        )
    }

    /// [`Self::inverse_at_load`] for a shape whose table is the identity
    /// (the caller checked [`StrokeTable::is_neutral`] once): no table work.
    pub fn inverse_at_load_without_table(&self, params: &Params, load_n: f32) -> ShapeInverse {
        ShapeInverse::from_parts_without_table(self.bend_at_load(params, load_n))
    }
}

/// The polynomial part of a shape at one load (no load terms).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Bend {
    bulge: f32,
    tilt: f32,
    root_shift: f32,
    end_shift: f32,
}

impl Bend {
    /// The stroke fraction `u` corrected: `u + u·(1 − u)·(bulge + tilt·(2u − 1))
    /// + (1 − u)·root_shift + u·end_shift`.
    fn map_fraction(&self, u: f32) -> f32 {
        u + u * (1.0 - u) * (self.bulge + self.tilt * (2.0 * u - 1.0))
            + (1.0 - u) * self.root_shift
            + u * self.end_shift
    }
}

/// A shape ready for its inverse: what [`ConstraintShape::model_contraction`]
/// computes from the shape alone, done once (a feedforward keeps it per
/// load, [`ConstraintShape::inverse_at_load`]). With `d = end_shift −
/// root_shift` the map is
/// `root_shift + u + u·d + u·(1 − u)·((bulge − tilt) + 2·tilt·u)` (the same
/// map as [`ConstraintShape::apply`]'s, rounded differently) and its slope
/// `c₁ + 2c₂u + 3c₃u²` with `c₁ = 1 + bulge − tilt + d`,
/// `c₂ = 3·tilt − bulge`, `c₃ = −2·tilt`. The load terms are not used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeInverse {
    bend: Bend,
    /// `end_shift − root_shift`, `bulge − tilt`, `2·tilt`.
    d: f32,
    bulge_minus_tilt: f32,
    two_tilt: f32,
    /// `c₁`, `2c₂`, `3c₃` of the slope.
    c1: f32,
    c2x2: f32,
    c3x3: f32,
    /// The map at 0 and at 1.
    lo_end: f32,
    hi_end: f32,
    /// `1/(hi_end − lo_end)`, 0 for an empty span (then the steps start
    /// at the middle).
    inv_span: f32,
    /// The table at this load's knots, when it is not the identity.
    table: Option<[f32; table::TABLE_KNOTS]>,
    /// The polynomial part is the identity (all four terms zero, as in
    /// the stroke table `pam-lab fit` writes): its map is `u` and its
    /// inverse the target, bit for bit, so both are skipped.
    bend_is_identity: bool,
    /// The polynomial part is linear in `u` (no bulge, no tilt: the ends'
    /// shifts alone, as `pam-lab fit` writes them beside its stroke table):
    /// `r + u·(1 + e − r)`, whose inverse is the chord's estimate itself,
    /// one multiplication, no Newton step.
    bend_is_linear: bool,
}

impl ShapeInverse {
    /// `shape` ready for its inverse (one division), with its shape at the
    /// minimum load (see [`ConstraintShape::at_load`]).
    pub fn new(shape: ConstraintShape) -> ShapeInverse {
        ShapeInverse::from_parts(shape.bend(), shape.table.knots[0])
    }

    /// The polynomial part and the table's knots at one load ready for the
    /// inverse; a table that is the identity is skipped from then on.
    fn from_parts(bend: Bend, knots: [f32; table::TABLE_KNOTS]) -> ShapeInverse {
        ShapeInverse {
            table: (!table::is_identity(&knots)).then_some(knots),
            ..ShapeInverse::from_parts_without_table(bend)
        }
    }

    /// The polynomial part alone ready for the inverse.
    fn from_parts_without_table(bend: Bend) -> ShapeInverse {
        let (b, t) = (bend.bulge, bend.tilt);
        let d = bend.end_shift - bend.root_shift;
        let (lo_end, hi_end) = (bend.map_fraction(0.0), bend.map_fraction(1.0));
        let span = hi_end - lo_end;
        ShapeInverse {
            bend,
            d,
            bulge_minus_tilt: b - t,
            two_tilt: 2.0 * t,
            c1: 1.0 + (b - t) + d,
            c2x2: 2.0 * (3.0 * t - b),
            c3x3: -6.0 * t,
            lo_end,
            hi_end,
            inv_span: if span > 0.0 { 1.0 / span } else { 0.0 },
            table: None,
            bend_is_identity: b == 0.0
                && t == 0.0
                && bend.root_shift == 0.0
                && bend.end_shift == 0.0,
            bend_is_linear: b == 0.0 && t == 0.0,
        }
    }

    /// [`ConstraintShape::apply`] with the table's check made once, at
    /// [`ShapeInverse::new`]: what a controller calls every period (its
    /// model check maps its band's ends through the shape).
    pub fn apply(&self, model: &LoadModel, contraction: f32) -> f32 {
        let (r, rx) = (model.root_contraction(), model.max_contraction());
        let s = rx - r;
        if !(s > 0.0) {
            return r;
        }
        let x = if contraction.is_finite() {
            contraction
        } else {
            r
        };
        let u = clamp((x - r) / s, 0.0, 1.0);
        let u = match &self.table {
            Some(k) => table::map(k, u),
            None => u,
        };
        let v = if self.bend_is_identity {
            u
        } else {
            clamp(self.bend.map_fraction(u), self.lo_end, self.hi_end)
        };
        r + s * v
    }

    /// [`ConstraintShape::model_contraction`]: [`SHAPE_INVERSE_STEPS`]
    /// Newton steps from the chord's estimate, each kept inside the
    /// bracket the previous ones established (a step that leaves it
    /// bisects instead): bounded work, and never worse than a bisection.
    /// The input is clamped to the shifted stroke (NaN and infinities → its
    /// root end), the result is in `[R, Rx]`.
    pub fn model_contraction(&self, model: &LoadModel, contraction: f32) -> f32 {
        let (r, rx) = (model.root_contraction(), model.max_contraction());
        let s = rx - r;
        if !(s > 0.0) {
            return r;
        }
        let (lo_end, hi_end) = (self.lo_end, self.hi_end);
        let target = if contraction.is_finite() {
            clamp((contraction - r) / s, lo_end, hi_end)
        } else {
            lo_end
        };
        let u = if self.bend_is_identity {
            target
        } else if self.bend_is_linear {
            clamp((target - lo_end) * self.inv_span, 0.0, 1.0)
        } else {
            self.bend_inverse(target)
        };
        let u = match &self.table {
            Some(k) => table::inverse(k, u),
            None => u,
        };
        clamp(r + s * u, r, rx)
    }

    /// The polynomial part's inverse: the `u` in `[0, 1]` whose map is
    /// `target` (in `[lo_end, hi_end]`), by [`SHAPE_INVERSE_STEPS`]
    /// bracketed Newton steps.
    fn bend_inverse(&self, target: f32) -> f32 {
        let lo_end = self.lo_end;
        let (d, bt, t2) = (self.d, self.bulge_minus_tilt, self.two_tilt);
        let (c1, c2x2, c3x3) = (self.c1, self.c2x2, self.c3x3);
        // The map's constant term less the target, once.
        let offset = self.bend.root_shift - target;
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        let mut u = if self.inv_span > 0.0 {
            clamp((target - lo_end) * self.inv_span, 0.0, 1.0)
        } else {
            0.5
        };
        for _ in 0..SHAPE_INVERSE_STEPS {
            let f = (u + u * d) + u * (1.0 - u) * (bt + t2 * u) + offset;
            if f <= 0.0 {
                lo = u;
            } else {
                hi = u;
            }
            let slope = (c3x3 * u + c2x2) * u + c1;
            let next = u - f / slope;
            // NaN (a zero slope) and steps out of the bracket bisect.
            u = if next >= lo && next <= hi {
                next
            } else {
                0.5 * (lo + hi)
            };
        }
        u
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coeffs::Coeffs;

    /// A long bisection of the map: the reference for the Newton inverse.
    fn bisect(shape: &ConstraintShape, target: f32) -> f32 {
        let (mut lo, mut hi) = (0.0f32, 1.0f32);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if shape.map_fraction(mid) <= target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    #[test]
    fn a_table_alone_skips_the_polynomial_bit_for_bit() {
        // fit's stroke table with the polynomial part at zero: the map and
        // the inverse without the polynomial's steps are the ones with
        // them, to the bit.
        let m = model();
        let mut knots = [[0.0f32; table::TABLE_KNOTS]; table::TABLE_LOADS];
        for (i, row) in knots.iter_mut().enumerate() {
            for (j, k) in row.iter_mut().enumerate() {
                let u = (j + 1) as f32 / table::TABLE_SEGMENTS as f32;
                *k = u + 0.08 * (i as f32 + 1.0) * u * (1.0 - u) * (1.0 - 0.3 * u);
            }
        }
        let shape = ConstraintShape {
            table: StrokeTable { knots },
            ..ConstraintShape::NEUTRAL
        };
        shape.validate().unwrap();
        let p = Params::DEFAULT;
        for load in [p.min_load_n, 250.0, p.max_load_n] {
            let fast = shape.inverse_at_load(&p, load);
            assert!(fast.bend_is_identity && fast.table.is_some());
            let slow = ShapeInverse {
                bend_is_identity: false,
                bend_is_linear: false,
                ..fast
            };
            let (r, rx) = (m.root_contraction(), m.max_contraction());
            for i in 0..=400 {
                let x = r - 0.01 + (rx - r + 0.02) * i as f32 / 400.0;
                assert_eq!(
                    fast.apply(&m, x).to_bits(),
                    slow.apply(&m, x).to_bits(),
                    "map at {x}"
                );
                assert_eq!(
                    fast.model_contraction(&m, x).to_bits(),
                    slow.model_contraction(&m, x).to_bits(),
                    "inverse at {x}"
                );
            }
            for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                assert_eq!(
                    fast.model_contraction(&m, x).to_bits(),
                    slow.model_contraction(&m, x).to_bits()
                );
            }
        }
        // Any polynomial term turns the steps back on.
        let bent = ConstraintShape {
            end_shift: -0.01,
            ..shape
        };
        assert!(!bent.inverse_at_load(&p, p.min_load_n).bend_is_identity);
    }

    #[test]
    fn shifted_ends_alone_invert_in_one_step() {
        // The ends' shifts without bulge or tilt (fit's stroke table with
        // its ends moved): the polynomial part is linear, its inverse the
        // chord's estimate. It agrees with the Newton steps it replaces to
        // a few f32 roundings, and the map of the inverse is the muscle's
        // contraction back, along the shifted stroke and across loads.
        let m = model();
        let p = Params::DEFAULT;
        let (r, rx) = (m.root_contraction(), m.max_contraction());
        for (root, end, end_sq) in [
            (0.0, -0.05, 0.0),
            (0.04, -0.1, -0.004),
            (-0.03, 0.08, 0.003),
        ] {
            let shape = ConstraintShape {
                root_shift: root,
                end_shift: end,
                end_shift_per_step_sq: end_sq,
                ..ConstraintShape::NEUTRAL
            };
            shape.validate().unwrap();
            for load in [p.min_load_n, 250.0, p.max_load_n] {
                let fast = shape.inverse_at_load(&p, load);
                assert!(fast.bend_is_linear && !fast.bend_is_identity);
                let newton = ShapeInverse {
                    bend_is_linear: false,
                    ..fast
                };
                let (lo, hi) = (r + (rx - r) * fast.lo_end, r + (rx - r) * fast.hi_end);
                for i in 0..=400 {
                    let x = lo + (hi - lo) * i as f32 / 400.0;
                    let u = fast.model_contraction(&m, x);
                    assert!(
                        (u - newton.model_contraction(&m, x)).abs() < 2e-6,
                        "{load} {x}"
                    );
                    assert!((fast.apply(&m, u) - x).abs() < 2e-6, "{load} {x}");
                }
            }
        }
    }

    #[test]
    fn newton_inverse_matches_a_long_bisection() {
        let m = model();
        let (r, rx) = (m.root_contraction(), m.max_contraction());
        let s = rx - r;
        // A deterministic spread of shapes, half of them at the slope limit.
        let mut seed = 0x2545_f491_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        let mut worst = 0.0f32;
        for k in 0..200_000 {
            let (a, b, c) = (2.0 * next() - 1.0, 2.0 * next() - 1.0, 2.0 * next() - 1.0);
            let shift = 0.4 * (2.0 * next() - 1.0);
            let total = a.abs() + b.abs() + c.abs() + 1e-6;
            let limit = if k % 2 == 0 {
                MAX_SHAPE_SLOPE
            } else {
                MAX_SHAPE_SLOPE * next()
            };
            let shape = ConstraintShape {
                bulge: a * limit / total,
                tilt: b * limit / total,
                root_shift: shift,
                end_shift: shift + c * limit / total,
                ..ConstraintShape::NEUTRAL
            };
            assert!(shape.validate().is_ok() || shape.end_shift.abs() > MAX_SHAPE_SLOPE);
            let x = r + s
                * (shape.map_fraction(0.0)
                    + next() * (shape.map_fraction(1.0) - shape.map_fraction(0.0)));
            let target = (x - r) / s;
            let exact = r + s * bisect(&shape, target);
            let err = (shape.model_contraction(&m, x) - exact).abs() / s;
            worst = worst.max(err);
        }
        eprintln!("worst Newton inverse error: {worst:e} of the stroke");
        assert!(worst <= 1.2e-6, "{worst}");
    }

    #[test]
    fn f64_path_agrees_with_the_chip() {
        let params = Params::DEFAULT;
        let coeffs = Coeffs::new(params).unwrap();
        let shape = ConstraintShape {
            bulge: 0.3,
            tilt: -0.2,
            bulge_per_step: 0.05,
            tilt_per_step: 0.02,
            root_shift: 0.01,
            end_shift: 0.03,
            root_shift_per_step_sq: 0.002,
            end_shift_per_step_sq: -0.004,
            ..ConstraintShape::NEUTRAL
        };
        for load_n in [params.min_load_n, 150.0, 330.0, params.max_load_n] {
            let m = coeffs.load_model_clamped(load_n);
            let steps = f64::from((load_n - params.min_load_n) / params.load_step_n);
            let (at, _) = ConstraintShape::at_steps_f64(shape.coefficients_f64(), steps);
            let chip = shape.at_load(&params, load_n);
            let want = [chip.bulge, chip.tilt, chip.root_shift, chip.end_shift];
            for (a, w) in at.iter().zip(want) {
                assert!((a - f64::from(w)).abs() < 1e-6, "{at:?} {want:?}");
            }
            let (r, rx) = (m.root_contraction(), m.max_contraction());
            for k in 0..=10 {
                let x = r + (rx - r) * k as f32 / 10.0;
                let u = f64::from((x - r) / (rx - r));
                let (mapped, _) = ConstraintShape::map_fraction_f64(at, u);
                let fwd = f64::from(r) + f64::from(rx - r) * mapped;
                assert!(
                    (fwd - f64::from(chip.apply(&m, x))).abs() < 2e-6,
                    "{load_n} {x}"
                );
                let back = ConstraintShape::inverse_fraction_f64(at, mapped);
                assert!((back - u).abs() < 1e-12, "{back} {u}");
                let chip_back = chip.inverse_at_load(&params, params.min_load_n);
                let xm = chip_back.model_contraction(&m, fwd as f32);
                assert!((f64::from(xm) - f64::from(x)).abs() < 1e-5, "{xm} {x}");
            }
        }
    }

    fn model() -> LoadModel {
        Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model_clamped(200.0)
    }

    #[test]
    fn neutral_is_the_identity_and_the_stroke_ends_stay() {
        let m = model();
        let (r, rx) = (m.root_contraction(), m.max_contraction());
        for k in 0..=20 {
            let x = r + (rx - r) * k as f32 / 20.0;
            assert!((ConstraintShape::NEUTRAL.apply(&m, x) - x).abs() < 1e-6);
        }
        let s = ConstraintShape {
            bulge: 0.5,
            tilt: -0.3,
            ..ConstraintShape::NEUTRAL
        };
        assert!((s.apply(&m, r) - r).abs() < 1e-6);
        assert!((s.apply(&m, rx) - rx).abs() < 1e-6);
        // Mid-stroke moves by bulge/4 of the stroke.
        let mid = 0.5 * (r + rx);
        assert!((s.apply(&m, mid) - (mid + 0.125 * (rx - r))).abs() < 1e-5);
    }

    #[test]
    fn valid_shapes_are_increasing_and_invert() {
        let m = model();
        let (r, rx) = (m.root_contraction(), m.max_contraction());
        for (bulge, tilt) in [
            (0.9, 0.0),
            (-0.9, 0.0),
            (0.45, 0.45),
            (-0.3, -0.6),
            (0.0, 0.9),
        ] {
            let s = ConstraintShape {
                bulge,
                tilt,
                ..ConstraintShape::NEUTRAL
            };
            assert!(s.validate().is_ok());
            let mut last = f32::NEG_INFINITY;
            for k in 0..=200 {
                let x = r + (rx - r) * k as f32 / 200.0;
                let y = s.apply(&m, x);
                assert!(y > last || k == 0, "{bulge} {tilt} at {k}");
                last = y;
                assert!((s.model_contraction(&m, y) - x).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn load_terms_are_linear_in_load_steps_and_kept_increasing() {
        let p = Params::DEFAULT;
        let s = ConstraintShape {
            bulge: 0.2,
            tilt: 0.1,
            bulge_per_step: 0.1,
            tilt_per_step: -0.05,
            ..ConstraintShape::NEUTRAL
        };
        assert!(s.validate().is_ok());
        let at = s.at_load(&p, p.min_load_n + 2.0 * p.load_step_n);
        assert!((at.bulge - 0.4).abs() < 1e-6 && at.tilt.abs() < 1e-6);
        assert_eq!(s.at_load(&p, f32::NAN).bulge, 0.2);
        let far = s.at_load(&p, 1e9);
        assert!(far.bulge.abs() + far.tilt.abs() <= MAX_SHAPE_SLOPE + 1e-6);
        assert!(far.validate().is_ok());
    }

    #[test]
    fn end_shifts_move_the_stroke_ends_quadratically_in_load_and_invert() {
        let p = Params::DEFAULT;
        let s = ConstraintShape {
            bulge: 0.2,
            tilt: -0.1,
            root_shift_per_step_sq: -0.01,
            end_shift_per_step_sq: 0.03,
            end_shift_per_step: -0.01,
            ..ConstraintShape::NEUTRAL
        };
        assert!(s.validate().is_ok());
        // Two load steps up: shifts of 4× the per-step² terms and 2× the
        // per-step ones.
        let at = s.at_load(&p, p.min_load_n + 2.0 * p.load_step_n);
        assert!((at.root_shift + 0.04).abs() < 1e-6 && (at.end_shift - 0.10).abs() < 1e-6);
        assert!(at.validate().is_ok());
        let m = model();
        let (r, rx) = (m.root_contraction(), m.max_contraction());
        let st = rx - r;
        assert!((at.apply(&m, r) - (r - 0.04 * st)).abs() < 1e-6);
        assert!((at.apply(&m, rx) - (rx + 0.10 * st)).abs() < 1e-6);
        // Increasing, and the inverse gives the model's contraction back.
        let mut last = f32::NEG_INFINITY;
        for k in 0..=200 {
            let x = r + st * k as f32 / 200.0;
            let y = at.apply(&m, x);
            assert!(y > last, "{k}");
            last = y;
            assert!((at.model_contraction(&m, y) - x).abs() < 1e-5, "{k}");
        }
        // Far loads: scaled back into the increasing range.
        for load in [1e4f32, 1e9] {
            let far = s.at_load(&p, load);
            assert!(far.validate().is_ok(), "{far:?}");
            assert!(far.map_fraction(1.0) > far.map_fraction(0.0));
        }
        for bad in [f32::NAN, 0.95, -0.95] {
            let b = ConstraintShape {
                end_shift_per_step_sq: bad,
                ..s
            };
            assert!(b.validate().is_err(), "{bad}");
        }
        // The sum with the ends' difference is limited too.
        let steep = ConstraintShape {
            bulge: 0.5,
            root_shift: -0.3,
            end_shift: 0.3,
            ..ConstraintShape::NEUTRAL
        };
        assert!(steep.validate().is_err());
    }

    #[test]
    fn out_of_range_and_non_finite_are_refused_and_inputs_clamped() {
        for (bulge, tilt) in [
            (0.6, 0.6),
            (f32::NAN, 0.0),
            (0.0, f32::INFINITY),
            (-1.0, 0.0),
        ] {
            let s = ConstraintShape {
                bulge,
                tilt,
                ..ConstraintShape::NEUTRAL
            };
            assert!(s.validate().is_err());
        }
        let m = model();
        let s = ConstraintShape {
            bulge: 0.4,
            tilt: 0.2,
            ..ConstraintShape::NEUTRAL
        };
        for x in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -5.0, 5.0] {
            let y = s.apply(&m, x);
            assert!(y >= m.root_contraction() && y <= m.max_contraction());
            let z = s.model_contraction(&m, x);
            assert!(z >= m.root_contraction() && z <= m.max_contraction());
        }
    }

    #[test]
    fn the_simulator_applies_it_to_the_paper_model_on_both_branches() {
        use crate::effects::Effects;
        use crate::simulator::Simulator;
        use crate::tracker::TrackerConfig;
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let shape = ConstraintShape {
            bulge: 0.4,
            tilt: 0.1,
            bulge_per_step: -0.1,
            tilt_per_step: 0.0,
            end_shift_per_step_sq: 0.02,
            ..ConstraintShape::NEUTRAL
        };
        let with = Effects {
            shape: Some(shape),
            ..Effects::NONE
        };
        let cfg = TrackerConfig::DEFAULT_PRESSURE;
        let mut plain = Simulator::<4>::new(coeffs, Effects::NONE, cfg, 200.0).unwrap();
        let mut corrected = Simulator::<4>::new(coeffs, with, cfg, 200.0).unwrap();
        let m = coeffs.load_model_clamped(200.0);
        let mut moved = 0.0f32;
        for k in 0..=1000 {
            let p = 0.5 * (1.0 - (k as f32 * 0.0126).cos()) * 0.5;
            let t = k as f32 * 0.02;
            let x = plain.step(t, p, 200.0);
            let y = corrected.step(t, p, 200.0);
            let at = shape.at_load(coeffs.params(), 200.0);
            assert!((y - at.apply(&m, x)).abs() < 1e-6, "{k}");
            moved = moved.max((y - x).abs());
        }
        assert!(moved > 0.01, "{moved}");
    }
}

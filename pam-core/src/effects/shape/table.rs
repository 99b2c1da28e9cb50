//! The stroke table: a monotone piecewise-linear map of the stroke
//! fraction, tabulated at a few loads, for static curves far from the
//! paper's cubic.
//!
//! The polynomial part of the shape ([`super::ConstraintShape`]'s bulge,
//! tilt and shifts) bends the cubic by a few tenths of the stroke, with its
//! slope kept within `1 ± MAX_SHAPE_SLOPE`. A measured muscle can need more:
//! the public Festo 10 mm records' pressure rises about ten times faster
//! near the stroke's root than the cubic lets it, and the bend changes with
//! load. The table takes that part: at each of [`TABLE_LOADS`] loads, evenly
//! spaced from the minimum to the maximum calibrated load, the values
//! `T(j/K)` of the map at the [`TABLE_KNOTS`] interior knots of
//! [`TABLE_SEGMENTS`] equal segments (`T(0) = 0`, `T(1) = 1`: the stroke's
//! ends stay where the paper puts them), linear between knots and between
//! loads. Each load's table is strictly increasing with every segment's
//! slope at least [`MIN_TABLE_SLOPE`], so every blend of two is too: the map
//! has an exact inverse (a search over the segments and one division) at
//! every load.
//!
//! The whole shape maps the model's stroke fraction `u` to
//! `P(T(u))`, `P` the polynomial part: the table first.

use crate::error::Error;
use crate::math::clamp;
use crate::params::Params;

/// Equal segments of the stroke fraction.
pub const TABLE_SEGMENTS: usize = 12;
/// Interior knots per load (the ends are 0 and 1).
pub const TABLE_KNOTS: usize = TABLE_SEGMENTS - 1;
/// Loads the table is given at: the minimum calibrated load, the maximum,
/// and evenly between.
pub const TABLE_LOADS: usize = 6;
/// Smallest slope of a segment, relative to the identity's (`1/K` of the
/// fraction per segment): the map is strictly increasing, and its inverse's
/// slope at most `1/MIN_TABLE_SLOPE`.
pub const MIN_TABLE_SLOPE: f32 = 0.05;

/// The table's knots per load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StrokeTable {
    /// `knots[i][j] = T((j + 1)/K)` at the `i`-th load.
    pub knots: [[f32; TABLE_KNOTS]; TABLE_LOADS],
}

/// The identity's knots, `j/K`.
const IDENTITY: [f32; TABLE_KNOTS] = {
    let mut k = [0.0; TABLE_KNOTS];
    let mut j = 0;
    while j < TABLE_KNOTS {
        k[j] = (j + 1) as f32 / TABLE_SEGMENTS as f32;
        j += 1;
    }
    k
};

impl Default for StrokeTable {
    fn default() -> Self {
        StrokeTable::NEUTRAL
    }
}

impl StrokeTable {
    /// The identity at every load.
    pub const NEUTRAL: StrokeTable = StrokeTable {
        knots: [IDENTITY; TABLE_LOADS],
    };

    /// Whether this is the identity at every load (the map is skipped).
    pub fn is_neutral(&self) -> bool {
        self.knots.iter().all(is_identity)
    }

    /// Finite, and at every load strictly increasing from 0 to 1 with every
    /// segment's slope at least [`MIN_TABLE_SLOPE`].
    pub fn validate(&self) -> Result<(), Error> {
        let gap = MIN_TABLE_SLOPE / TABLE_SEGMENTS as f32;
        for k in &self.knots {
            let mut last = 0.0f32;
            for &v in k.iter().chain(core::iter::once(&1.0)) {
                if !v.is_finite() {
                    return Err(Error::NonFinite("shape.table"));
                }
                // `!(a >= b)`: also true for NaN.
                if !(v - last >= gap * (1.0 - 1e-3)) {
                    return Err(Error::OutOfRange(
                        "shape.table",
                        "knots must rise from 0 to 1 with every segment's slope at least MIN_TABLE_SLOPE",
                    ));
                }
                last = v;
            }
        }
        Ok(())
    }

    /// The knots at `load_n` (clamped to the calibrated range; NaN → the
    /// minimum load): the blend of the two nearest loads' (the identity's
    /// blend is the identity, bit for bit).
    pub fn knots_at_load(&self, params: &Params, load_n: f32) -> [f32; TABLE_KNOTS] {
        let span = params.max_load_n - params.min_load_n;
        let f = if span > 0.0 {
            (load_n - params.min_load_n) / span
        } else {
            0.0
        };
        let f = if f.is_finite() {
            clamp(f, 0.0, 1.0)
        } else {
            0.0
        };
        let pos = f * (TABLE_LOADS - 1) as f32;
        // `pos` is in [0, TABLE_LOADS − 1]: the cast cannot wrap.
        let i = (pos as usize).min(TABLE_LOADS - 2);
        let t = pos - i as f32;
        // No index that could fail: the pair is found, not indexed.
        let (a, b) = match self.knots.windows(2).nth(i) {
            Some([a, b]) => (a, b),
            _ => (&self.knots[0], &self.knots[0]),
        };
        let mut k = [0.0; TABLE_KNOTS];
        for (j, v) in k.iter_mut().enumerate() {
            *v = a[j] + t * (b[j] - a[j]);
        }
        k
    }
}

/// Whether one load's knots are the identity's (bit for bit).
pub fn is_identity(k: &[f32; TABLE_KNOTS]) -> bool {
    k.iter()
        .zip(&IDENTITY)
        .all(|(a, b)| a.to_bits() == b.to_bits())
}

/// The map of `u ∈ [0, 1]` (clamped; NaN → 0) by the knots `k` of one load.
pub fn map(k: &[f32; TABLE_KNOTS], u: f32) -> f32 {
    let u = if u.is_finite() {
        clamp(u, 0.0, 1.0)
    } else {
        0.0
    };
    let pos = u * TABLE_SEGMENTS as f32;
    let j = (pos as usize).min(TABLE_SEGMENTS - 1);
    // The segment's ends: 0 before the first knot, 1 after the last.
    let lo = k.get(j.wrapping_sub(1)).copied().unwrap_or(0.0);
    let hi = k.get(j).copied().unwrap_or(1.0);
    lo + (pos - j as f32) * (hi - lo)
}

/// The inverse of [`map`]: the `u` whose map is `v` (clamped to `[0, 1]`,
/// NaN → 0). At most [`TABLE_KNOTS`] comparisons and one division.
///
/// The host path: [`map_f64`] and [`inverse_f64`] with their slopes, for
/// identification.
pub fn inverse(k: &[f32; TABLE_KNOTS], v: f32) -> f32 {
    let v = if v.is_finite() {
        clamp(v, 0.0, 1.0)
    } else {
        0.0
    };
    let mut j = 0;
    while j < TABLE_KNOTS && v > k[j] {
        j += 1;
    }
    let lo = if j == 0 { 0.0 } else { k[j - 1] };
    let hi = if j == TABLE_KNOTS { 1.0 } else { k[j] };
    let d = hi - lo;
    let t = if d > 0.0 {
        clamp((v - lo) / d, 0.0, 1.0)
    } else {
        0.0
    };
    (j as f32 + t) / TABLE_SEGMENTS as f32
}

/// [`map`] in `f64` on one load's knots, with the map's slope.
pub fn map_f64(k: &[f64; TABLE_KNOTS], u: f64) -> (f64, f64) {
    let u = if u.is_finite() {
        u.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let pos = u * TABLE_SEGMENTS as f64;
    let j = (pos as usize).min(TABLE_SEGMENTS - 1);
    let lo = if j == 0 { 0.0 } else { k[j - 1] };
    let hi = if j == TABLE_KNOTS { 1.0 } else { k[j] };
    (
        lo + (pos - j as f64) * (hi - lo),
        (hi - lo) * TABLE_SEGMENTS as f64,
    )
}

/// [`inverse`] in `f64` on one load's knots, with the map's slope there.
pub fn inverse_f64(k: &[f64; TABLE_KNOTS], v: f64) -> (f64, f64) {
    let v = if v.is_finite() {
        v.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut j = 0;
    while j < TABLE_KNOTS && v > k[j] {
        j += 1;
    }
    let lo = if j == 0 { 0.0 } else { k[j - 1] };
    let hi = if j == TABLE_KNOTS { 1.0 } else { k[j] };
    let d = hi - lo;
    let t = if d > 0.0 {
        ((v - lo) / d).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (
        (j as f64 + t) / TABLE_SEGMENTS as f64,
        d * TABLE_SEGMENTS as f64,
    )
}

/// The two table loads [`at_fraction_f64`] blends at the load fraction `f`:
/// `(i, t)`, the knots `nodes[i] + t·(nodes[i + 1] − nodes[i])`. The
/// result depends on `nodes[i + 1]` only where `t > 0`.
pub fn blend_f64(f: f64) -> (usize, f64) {
    let f = if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let pos = f * (TABLE_LOADS - 1) as f64;
    let i = (pos as usize).min(TABLE_LOADS - 2);
    (i, pos - i as f64)
}

/// [`StrokeTable::knots_at_load`] in `f64` on knots per load `nodes`, at the load
/// fraction `f = (L − L_min)/(L_max − L_min)` (clamped; NaN → 0).
pub fn at_fraction_f64(nodes: &[[f64; TABLE_KNOTS]; TABLE_LOADS], f: f64) -> [f64; TABLE_KNOTS] {
    let (i, t) = blend_f64(f);
    let mut k = [0.0; TABLE_KNOTS];
    for (j, v) in k.iter_mut().enumerate() {
        *v = nodes[i][j] + t * (nodes[i + 1][j] - nodes[i][j]);
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bent() -> StrokeTable {
        // Steep near the root, flat after: the shape the Festo records need.
        let node = |s: f32| {
            let mut k = [0.0; TABLE_KNOTS];
            for (j, v) in k.iter_mut().enumerate() {
                let u = (j + 1) as f32 / TABLE_SEGMENTS as f32;
                *v = u + s * u * (1.0 - u);
            }
            k
        };
        let mut knots = [[0.0; TABLE_KNOTS]; TABLE_LOADS];
        for (i, k) in knots.iter_mut().enumerate() {
            *k = node(0.9 * (1.0 - i as f32 / (TABLE_LOADS - 1) as f32));
        }
        StrokeTable { knots }
    }

    #[test]
    fn neutral_is_the_identity_and_valid() {
        assert!(StrokeTable::NEUTRAL.is_neutral());
        assert!(StrokeTable::NEUTRAL.validate().is_ok());
        for n in 0..=40 {
            let u = n as f32 / 40.0;
            assert!((map(&IDENTITY, u) - u).abs() < 1e-6);
            assert!((inverse(&IDENTITY, u) - u).abs() < 1e-6);
        }
    }

    #[test]
    fn inverse_undoes_map_at_every_load() {
        let t = bent();
        assert!(t.validate().is_ok());
        let p = Params::DEFAULT;
        for l in 0..=10 {
            let load = p.min_load_n + (p.max_load_n - p.min_load_n) * l as f32 / 10.0;
            let at = StrokeTable {
                knots: [t.knots_at_load(&p, load); TABLE_LOADS],
            };
            assert!(at.validate().is_ok());
            for n in 0..=200 {
                let u = n as f32 / 200.0;
                let v = map(&at.knots[0], u);
                assert!((inverse(&at.knots[0], v) - u).abs() < 2e-6, "{load} {u}");
            }
        }
    }

    #[test]
    fn a_falling_or_flat_table_is_refused() {
        let mut t = bent();
        t.knots[2][3] = t.knots[2][2];
        assert!(t.validate().is_err());
        let mut t = bent();
        t.knots[0][6] = 1.0;
        assert!(t.validate().is_err());
        let mut t = bent();
        t.knots[1][0] = f32::NAN;
        assert_eq!(t.validate(), Err(Error::NonFinite("shape.table")));
    }

    #[test]
    fn loads_outside_the_range_take_the_end_tables() {
        let t = bent();
        let p = Params::DEFAULT;
        assert_eq!(t.knots_at_load(&p, p.min_load_n - 50.0), t.knots[0]);
        assert_eq!(t.knots_at_load(&p, f32::NAN), t.knots[0]);
        assert_eq!(
            t.knots_at_load(&p, p.max_load_n + 50.0),
            t.knots[TABLE_LOADS - 1]
        );
        let n = StrokeTable::NEUTRAL;
        assert!(is_identity(&n.knots_at_load(&p, 333.3)));
    }
}

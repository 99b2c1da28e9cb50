//! The static shape's variables: the stroke table's knots per load and the
//! stroke ends' shifts, as the stage's search moves them (every point a
//! shape pam-core accepts). The training residuals under such a shape are
//! `TrainSet::table_residuals` (`problem.rs`), which the stage and the
//! paper model's refit under the shape both minimise.

use pam_core::effects::shape::table::{MIN_TABLE_SLOPE, TABLE_KNOTS, TABLE_LOADS, TABLE_SEGMENTS};
use pam_core::effects::shape::MAX_SHAPE_SLOPE;

/// The table's variables: per load, the log-lengths of segments 2..K.
pub(crate) const NT: usize = TABLE_LOADS * (TABLE_SEGMENTS - 1);

/// The stroke ends' variables after the table's: the root's and the far
/// end's shift, each constant, per load step and per squared load step
/// ([`ConstraintShape`]'s coefficients 4–9).
pub(crate) const NS: usize = 6;

/// The stage's variables: the table's, then the ends'.
pub(crate) const NV: usize = NT + NS;

/// The static shape the stage fits: the stroke table's knots per load and
/// the polynomial part's coefficients (`ConstraintShape::coefficients_f64`;
/// the ends' shifts, the bulge and tilt left at zero: the table bends the
/// stroke, the shifts move its ends, which the table keeps where the
/// paper's load-linear stroke ends put them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct StaticShape {
    pub(crate) nodes: [[f64; TABLE_KNOTS]; TABLE_LOADS],
    pub(crate) coefficients: [f64; 10],
}

impl StaticShape {
    /// The shape of the stage's variables `w` ([`NV`]).
    pub(crate) fn of(w: &[f64]) -> StaticShape {
        // Each within what pam-core accepts at every point the optimiser
        // visits: the shifts at the minimum load within half the slope
        // limit each (so their difference within it), the load terms within
        // it (the chip scales the sum back at other loads, as
        // `at_steps_f64` does here).
        let limit = 0.999 * f64::from(MAX_SHAPE_SLOPE);
        let mut coefficients = [0.0; 10];
        for (j, (c, v)) in coefficients[4..].iter_mut().zip(&w[NT..NV]).enumerate() {
            let bound = if j < 2 { 0.5 * limit } else { limit };
            *c = bound * v.tanh();
        }
        StaticShape {
            nodes: knots(&w[..NT]),
            coefficients,
        }
    }
}

/// Each segment's least length in the fitted tables, a fraction of the
/// stroke: pam-core's least slope with a margin for the `f32` rounding.
pub(crate) const MIN_SEGMENT: f64 = 1.5 * MIN_TABLE_SLOPE as f64 / TABLE_SEGMENTS as f64;

/// The knots per load of the variables `w`: segment lengths
/// `MIN_SEGMENT + (1 − K·MIN_SEGMENT)·eʷ/Σeʷ` (the first segment's `w` is
/// 0), accumulated.
pub(crate) fn knots(w: &[f64]) -> [[f64; TABLE_KNOTS]; TABLE_LOADS] {
    let mut out = [[0.0; TABLE_KNOTS]; TABLE_LOADS];
    for (i, node) in out.iter_mut().enumerate() {
        let mut e = [1.0; TABLE_SEGMENTS];
        for (j, v) in e.iter_mut().enumerate().skip(1) {
            // Bounded: a segment at e^±30 of another is at its least length.
            *v = w[i * (TABLE_SEGMENTS - 1) + j - 1].clamp(-30.0, 30.0).exp();
        }
        let sum: f64 = e.iter().sum();
        let free = 1.0 - TABLE_SEGMENTS as f64 * MIN_SEGMENT;
        let mut acc = 0.0;
        for (j, k) in node.iter_mut().enumerate() {
            acc += MIN_SEGMENT + free * e[j] / sum;
            *k = acc;
        }
    }
    out
}

//! The residual the fits run on for an isometric record: each sample's
//! contraction error carried into pressure along the static model's own
//! curve.
//!
//! An isometric test holds the length and measures the pressure it takes,
//! so its error is a pressure error. The exact one
//! ([`crate::evaluate::simulate::pressure_to_reach`], a search of several
//! simulator steps a sample) judges every model; the fits need something
//! a single simulation gives. The simulator predicts the contraction `x̂`
//! at the measured pressure; its error in pressure is how far the static
//! curve `P` at that sample's load and branch rises between the two
//! contractions, `P(x) − P(x̂)`.
//!
//! The curve's slope at the measured contraction times `x − x̂` (the
//! tangent) is not enough where the curve bends within the error: with
//! fit's stroke table the public Festo muscle's curve is steep at the
//! stroke's root and flat a few thousandths further, so on Festo 10 cm the
//! tangent put 97 % of its squares on the 1.6 % of training samples under
//! 20 N (0.0695 MPa RMS against the exact 0.0128), and every candidate was
//! fitted to them. The secant is the exact error where the model is static
//! (`x̂ = P⁻¹(p)`: 0.0129 there), and follows it to first order where an
//! effect moves `x̂`.
//!
//! Each sample's curve is tabulated once per static model the candidates
//! are fitted on (the base's, or a path's once it carries a static shape)
//! at [`CURVE_POINTS`] contractions evenly over the stroke at its load,
//! from pam-core's static model with its shape
//! ([`ModelCache`](crate::evaluate::errors::ModelCache)), and read by
//! linear interpolation (both contractions on the same table: a perfect
//! prediction is a zero residual, bit for bit).

use pam_core::effects::ConstraintShape;
use pam_core::{Branch, Coeffs};

use crate::evaluate::errors::ModelCache;
use crate::record::Sample;

/// Points of each sample's tabulated curve, evenly over the stroke.
pub const CURVE_POINTS: usize = 33;

/// Each sample's static pressure curve over the stroke at its load and
/// branch.
#[derive(Clone, Debug, PartialEq)]
pub struct PressureCurves {
    /// Per sample: the stroke's ends at its load (the table's range).
    stroke: Vec<(f32, f32)>,
    /// Per sample, [`CURVE_POINTS`] pressures (MPa) evenly over the stroke.
    values: Vec<f32>,
}

impl PressureCurves {
    /// The curves of the static model `coeffs` with `shape` at each
    /// sample's load and branch; excluded samples get none (their
    /// residual is `NaN`).
    pub fn new(
        coeffs: &Coeffs,
        shape: Option<&ConstraintShape>,
        samples: &[Sample],
        branches: &[Branch],
        excluded: &[bool],
    ) -> PressureCurves {
        let mut cache = ModelCache::new(coeffs, shape);
        let n = samples.len();
        let mut stroke = vec![(0.0, 0.0); n];
        let mut values = vec![f32::NAN; n * CURVE_POINTS];
        for (i, (s, &b)) in samples.iter().zip(branches).enumerate() {
            if excluded.get(i).copied().unwrap_or(true) {
                continue;
            }
            let load = s.load_n as f32;
            let (lo, hi) = {
                let (m, _) = cache.get(load);
                (m.root_contraction(), m.max_contraction())
            };
            stroke[i] = (lo, hi);
            let row = &mut values[i * CURVE_POINTS..(i + 1) * CURVE_POINTS];
            for (j, v) in row.iter_mut().enumerate() {
                let x = lo + (hi - lo) * j as f32 / (CURVE_POINTS - 1) as f32;
                *v = cache.pressure_mpa(x, load, b);
            }
        }
        PressureCurves { stroke, values }
    }

    /// Sample `i`'s curve at `contraction` (held to the stroke), MPa;
    /// `NaN` for an excluded sample or a `NaN` contraction.
    pub fn at(&self, i: usize, contraction: f64) -> f64 {
        let Some(&(lo, hi)) = self.stroke.get(i) else {
            return f64::NAN;
        };
        let Some(row) = self.values.get(i * CURVE_POINTS..(i + 1) * CURVE_POINTS) else {
            return f64::NAN;
        };
        let (lo, hi) = (f64::from(lo), f64::from(hi));
        let span = hi - lo;
        if span.is_nan() || span <= 0.0 || contraction.is_nan() {
            return f64::from(row[0]);
        }
        let pos = ((contraction - lo) / span).clamp(0.0, 1.0) * (CURVE_POINTS - 1) as f64;
        // `pos` is in [0, CURVE_POINTS − 1]: the cast cannot wrap.
        let j = (pos as usize).min(CURVE_POINTS - 2);
        let t = pos - j as f64;
        let (a, b) = (f64::from(row[j]), f64::from(row[j + 1]));
        a + t * (b - a)
    }

    /// The pressure residual of sample `i` (measured contraction `x`,
    /// predicted `x̂`): `P(x) − P(x̂)`, the model's pressure at the held
    /// length minus the measured one where the model is static.
    pub fn residual(&self, i: usize, measured: f64, predicted: f64) -> f64 {
        self.at(i, measured) - self.at(i, predicted)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pam_core::effects::shape::table::{TABLE_KNOTS, TABLE_LOADS, TABLE_SEGMENTS};
    use pam_core::effects::StrokeTable;
    use pam_core::Params;

    /// A stroke table steep near the root, as fit's is for the Festo
    /// muscle.
    fn steep_root() -> ConstraintShape {
        let mut knots = [[0.0; TABLE_KNOTS]; TABLE_LOADS];
        for node in &mut knots {
            for (j, v) in node.iter_mut().enumerate() {
                let u = (j + 1) as f32 / TABLE_SEGMENTS as f32;
                *v = u + 0.9 * u * (1.0 - u);
            }
        }
        let shape = ConstraintShape {
            table: StrokeTable { knots },
            ..ConstraintShape::NEUTRAL
        };
        shape.validate().unwrap();
        shape
    }

    #[test]
    fn the_residual_is_the_pressure_error_of_a_static_model_and_bounded_where_the_tangent_is_not() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let shape = steep_root();
        let mut cache = ModelCache::new(&coeffs, Some(&shape));
        let (lo, hi) = {
            let (m, _) = cache.get(200.0);
            (m.root_contraction(), m.max_contraction())
        };
        let at = |f: f32| lo + f * (hi - lo);
        // Held lengths along the stroke, each predicted by the static
        // model's own inverse at a measured pressure 0.02 MPa above the
        // model's there.
        let held: Vec<f32> = (1..10).map(|k| at(k as f32 / 10.0)).collect();
        let samples: Vec<Sample> = held
            .iter()
            .map(|&x| Sample {
                t_s: 0.0,
                load_n: 200.0,
                pressure_mpa: f64::from(cache.pressure_mpa(x, 200.0, Branch::Contraction)) + 0.02,
                contraction: f64::from(x),
            })
            .collect();
        let branches = vec![Branch::Contraction; samples.len()];
        let excluded = vec![false; samples.len()];
        let curves = PressureCurves::new(&coeffs, Some(&shape), &samples, &branches, &excluded);
        for (i, s) in samples.iter().enumerate() {
            let predicted =
                cache.contraction(s.pressure_mpa as f32, 200.0, Branch::Contraction) as f64;
            let r = curves.residual(i, s.contraction, predicted);
            // The model's pressure at the held length minus the measured:
            // −0.02 MPa, within the tabulation's chord error.
            assert!((r + 0.02).abs() < 2e-3, "{i}: {r}");
            // A perfect prediction is exactly zero.
            assert_eq!(curves.residual(i, s.contraction, s.contraction), 0.0);
        }
        // A prediction at the far end of the stroke: the residual is the
        // curve's whole rise, never more (the tangent at a steep root
        // would multiply the whole stroke by the root's slope).
        let rise = f64::from(cache.pressure_mpa(hi, 200.0, Branch::Contraction))
            - f64::from(cache.pressure_mpa(held[0], 200.0, Branch::Contraction));
        let r = curves.residual(0, samples[0].contraction, f64::from(hi) + 0.05);
        assert!((r + rise).abs() < 2e-3, "{r} vs {rise}");
        // Excluded samples have no curve.
        let none = PressureCurves::new(&coeffs, Some(&shape), &samples, &branches, &[true; 9]);
        assert!(none.residual(0, 0.1, 0.1).is_nan());
    }
}

//! Simulating a model over the record and measuring its errors.

use pam_core::{Branch, Coeffs, Effects, TrackerConfig};
use serde::Serialize;

use super::regimes::Regimes;
use crate::evaluate::errors::rms_where;
use crate::evaluate::simulate::InverseTables;
use crate::record::Sample;

/// Simulate the model (base `coeffs` plus `effects`) over `samples` from the
/// measured pressure and load, on the given branches (see
/// [`super::regimes::hindsight_branches`]); one predicted contraction per sample.
pub fn simulate(
    coeffs: &Coeffs,
    effects: Effects,
    tracker: TrackerConfig,
    samples: &[Sample],
    branches: &[Branch],
    tables: InverseTables,
) -> Vec<f64> {
    let mut out = vec![f64::NAN; samples.len()];
    crate::evaluate::simulate::run_record(
        coeffs,
        &effects,
        tracker,
        samples,
        Some(branches),
        tables,
        |i, _, x| out[i] = f64::from(x),
    );
    out
}

/// BIC of a model with training RMS `rms_train` over `n_train` samples
/// whose residual is correlated over `corr_len` samples (`n_train /
/// corr_len` independent ones), with `n_params` parameters.
pub fn bic(rms_train: f64, n_train: usize, corr_len: f64, n_params: usize) -> f64 {
    let n_eff = (n_train as f64 / corr_len.max(1.0)).max(1.0);
    n_eff * (rms_train * rms_train).max(1e-300).ln() + n_params as f64 * n_eff.ln()
}

/// Errors of one model.
#[derive(Clone, Debug, Serialize)]
pub struct ModelErrors {
    /// Held-out RMS contraction error.
    pub rms_heldout: f64,
    /// Training RMS contraction error.
    pub rms_train: f64,
    /// BIC over the effective number of independent training residuals.
    pub bic: f64,
    /// Held-out RMS per regime.
    pub regimes: Vec<RegimeError>,
    /// Held-out RMS per load.
    pub loads: Vec<LoadError>,
    /// The held-out error that depends on the load and the position along
    /// the stroke alone, both branches pooled: the RMS (weighted by
    /// samples) of the mean residual per (load, stroke bin) cell. A static curve the
    /// model cannot follow shows here; a loop-height or rate error, whose
    /// sign flips between the branches, mostly cancels.
    pub static_shape: f64,
}

/// RMS in one regime.
#[derive(Clone, Debug, Serialize)]
pub struct RegimeError {
    /// Regime name.
    pub regime: String,
    /// Held-out samples in it.
    pub samples: usize,
    /// Held-out RMS contraction error.
    pub rms: f64,
}

/// RMS at one load.
#[derive(Clone, Debug, Serialize)]
pub struct LoadError {
    /// Load, N: the middle of its group (1 N wide on a record that holds
    /// its load, 25 N on an isometric record, whose force moves).
    pub load_n: f64,
    /// Held-out samples at it.
    pub samples: usize,
    /// Held-out RMS contraction error.
    pub rms: f64,
}

/// What is shared by every evaluation of one record.
#[derive(Clone)]
pub(super) struct Setup<'a> {
    pub(super) samples: &'a [Sample],
    pub(super) coeffs: Coeffs,
    pub(super) tracker: TrackerConfig,
    pub(super) heldout: Vec<bool>,
    pub(super) train_idx: Vec<usize>,
    pub(super) regimes: Regimes,
    pub(super) branches: Vec<Branch>,
    /// Effective-sample divisor: the base residual's correlation length.
    pub(super) corr_len: f64,
    /// The noise floor of the residual: the record's contraction noise,
    /// or on an isometric record (residual in pressure) its pressure noise.
    pub(super) noise_residual: f64,
    /// Each sample's factor from contraction residual to pressure residual,
    /// on an isometric record ([`pressure_weights`]); `None`: the residual
    /// is the contraction's.
    pub(super) pressure_weight: Option<Vec<f64>>,
    /// Where the joint refit may move `Pmax`: from this (the record's top
    /// pressure, when `Pmax` was measured from it) up to
    /// [`super::refit::PMAX_CEILING_OF_TOP`] times it, or `None`: held (given by
    /// the user).
    pub(super) pmax_floor_mpa: Option<f32>,
    /// Each sample's bin of measured contraction along the record's stroke
    /// ([`stroke_bins`]).
    pub(super) stroke_bin: Vec<usize>,
    /// The effects the base model carries: fit's static shape (its stroke
    /// table), when fit found one; every candidate is added on top.
    pub(super) base_effects: Effects,
    /// Samples no model is judged on: an isometric test's slack samples
    /// (force at the load cell's floor, [`crate::identify::fit::slack_mask`]),
    /// where the held length says nothing about the muscle. Their residual
    /// is `NaN`, and they are in neither part.
    pub(super) excluded: Vec<bool>,
    /// Width of the load groups of [`ModelErrors::loads`], N: 1 for a
    /// record whose load is held at a few values (isotonic), wider for an
    /// isometric record whose load is a force that changes every sample.
    pub(super) load_group_n: f64,
    /// When the simulation builds inverse tables: never on an isometric
    /// record, whose force switches the load model every few samples.
    pub(super) tables: InverseTables,
    /// fit's static shape on the training part, where fit keeps one (its
    /// stroke table, judged by fit's own held-out rule), with the paper's
    /// parameters fitted under it: the start of the `constraint_shape`
    /// candidate's second variant.
    pub(super) stroke_table: Option<(pam_core::Params, pam_core::effects::ConstraintShape)>,
}

/// Bins along the stroke of [`stroke_bins`].
pub const STROKE_BINS: usize = 12;

/// Each sample's bin of measured contraction: [`STROKE_BINS`] equal bins
/// between the record's 1st and 99th percentiles (clamped to the end bins).
pub fn stroke_bins(samples: &[Sample]) -> Vec<usize> {
    let mut x: Vec<f64> = samples
        .iter()
        .map(|s| s.contraction)
        .filter(|x| x.is_finite())
        .collect();
    if x.len() < 2 {
        return vec![0; samples.len()];
    }
    x.sort_by(f64::total_cmp);
    let q = |f: f64| x[((x.len() - 1) as f64 * f).round() as usize];
    let (lo, hi) = (q(0.01), q(0.99));
    let w = ((hi - lo) / STROKE_BINS as f64).max(1e-9);
    samples
        .iter()
        .map(|s| {
            let b = ((s.contraction - lo) / w).floor();
            if b.is_finite() {
                b.clamp(0.0, (STROKE_BINS - 1) as f64) as usize
            } else {
                0
            }
        })
        .collect()
}

impl Setup<'_> {
    fn static_shape(&self, res: &[f64]) -> f64 {
        // Cells of (load, 25 N bins) × stroke bin; both branches pooled.
        let mut cells: std::collections::HashMap<(i64, usize), (f64, usize)> =
            std::collections::HashMap::new();
        for (i, r) in res.iter().enumerate() {
            if self.heldout[i] && r.is_finite() {
                let load = (self.samples[i].load_n / 25.0).round() as i64;
                let b = self.stroke_bin.get(i).copied().unwrap_or(0);
                let c = cells.entry((load, b)).or_insert((0.0, 0));
                c.0 += r;
                c.1 += 1;
            }
        }
        let total: usize = cells.values().map(|c| c.1).sum();
        if total == 0 {
            return f64::NAN;
        }
        let ss: f64 = cells.values().map(|(s, c)| s * s / *c as f64).sum();
        (ss / total as f64).sqrt()
    }

    pub(super) fn residuals(&self, effects: Effects) -> Vec<f64> {
        self.residuals_with(&self.coeffs, effects)
    }

    /// The residual every error of the diagnosis is judged by: the
    /// contraction's ([`Self::residuals_with`]), or on an isometric record
    /// the exact pressure error, the pressure the model needs to reach each
    /// held length minus the measured one
    /// ([`crate::evaluate::simulate::pressure_to_reach`], a search of
    /// several simulator steps a sample: once per model judged, while the fits run on the
    /// first-order residual of [`Self::residuals_with`]).
    pub(super) fn judged_residuals(&self, coeffs: &Coeffs, effects: Effects) -> Vec<f64> {
        if self.pressure_weight.is_none() {
            return self.residuals_with(coeffs, effects);
        }
        self.residual_of(
            &self.predicted_raw(coeffs, effects),
            |s| s.pressure_mpa,
            None,
        )
    }

    /// The model's prediction of the quantity its residual measures: the
    /// contraction simulated from the measured pressure, or on an isometric
    /// record the pressure each held length takes
    /// ([`crate::evaluate::simulate::pressure_to_reach`]); `NaN` on the
    /// samples no model is judged on.
    pub(super) fn predicted(&self, coeffs: &Coeffs, effects: Effects) -> Vec<f64> {
        let mut out = self.predicted_raw(coeffs, effects);
        for (v, &excluded) in out.iter_mut().zip(&self.excluded) {
            if excluded {
                *v = f64::NAN;
            }
        }
        out
    }

    fn predicted_raw(&self, coeffs: &Coeffs, effects: Effects) -> Vec<f64> {
        if self.pressure_weight.is_none() {
            return self.contraction(coeffs, effects);
        }
        crate::evaluate::simulate::pressure_to_reach(
            coeffs,
            &effects,
            self.tracker,
            self.samples,
            Some(&self.branches),
            self.tables,
            coeffs.params().points.max_pressure_mpa,
        )
    }

    fn contraction(&self, coeffs: &Coeffs, effects: Effects) -> Vec<f64> {
        simulate(
            coeffs,
            effects,
            self.tracker,
            self.samples,
            &self.branches,
            self.tables,
        )
    }

    /// `predicted` minus the measured value (`measured`), times each
    /// sample's `weight` when given; `NaN` on the excluded samples.
    fn residual_of(
        &self,
        predicted: &[f64],
        measured: impl Fn(&Sample) -> f64,
        weight: Option<&[f64]>,
    ) -> Vec<f64> {
        predicted
            .iter()
            .zip(self.samples)
            .zip(&self.excluded)
            .enumerate()
            .map(|(i, ((p, s), &excluded))| {
                if excluded {
                    f64::NAN
                } else {
                    weight.map_or(1.0, |w| w[i]) * (p - measured(s))
                }
            })
            .collect()
    }

    /// The residual the fits run on: measured minus simulated contraction,
    /// on an isometric record times each sample's pressure weight
    /// ([`pressure_weights`]: then about the model's pressure minus the
    /// measured one); `NaN` on the excluded samples.
    pub(super) fn residuals_with(&self, coeffs: &Coeffs, effects: Effects) -> Vec<f64> {
        let x = self.contraction(coeffs, effects);
        self.residual_of(&x, |s| s.contraction, self.pressure_weight.as_deref())
            .into_iter()
            .map(|r| -r)
            .collect()
    }

    pub(super) fn errors(
        &self,
        coeffs: &Coeffs,
        effects: Effects,
        n_params: usize,
    ) -> (ModelErrors, Vec<f64>) {
        let res = self.judged_residuals(coeffs, effects);
        let (rms_heldout, _) = rms_where(&res, |i| self.heldout[i]);
        let (rms_train, n_train) = rms_where(&res, |i| !self.heldout[i]);
        let bic = bic(rms_train, n_train, self.corr_len, n_params);
        let regimes = self
            .regimes
            .named()
            .iter()
            .map(|(name, mask)| {
                let (rms, samples) = rms_where(&res, |i| self.heldout[i] && mask[i]);
                RegimeError {
                    regime: name.to_string(),
                    samples,
                    rms,
                }
            })
            .collect();
        let group = |load_n: f64| (load_n / self.load_group_n).round() * self.load_group_n;
        let mut loads: Vec<f64> = self
            .samples
            .iter()
            .zip(&self.heldout)
            .zip(&self.excluded)
            .filter(|((_, h), x)| **h && !**x)
            .map(|((s, _), _)| group(s.load_n))
            .collect();
        loads.sort_by(f64::total_cmp);
        loads.dedup();
        let loads = loads
            .into_iter()
            .map(|l| {
                let (rms, samples) = rms_where(&res, |i| {
                    self.heldout[i] && group(self.samples[i].load_n) == l
                });
                LoadError {
                    load_n: l,
                    samples,
                    rms,
                }
            })
            .collect();
        let static_shape = self.static_shape(&res);
        (
            ModelErrors {
                rms_heldout,
                rms_train,
                bic,
                regimes,
                loads,
                static_shape,
            },
            res,
        )
    }
}

/// Bounds of [`pressure_weights`] around their median: a weight is kept
/// within this factor of it either way.
pub const PRESSURE_WEIGHT_SPREAD: f64 = 20.0;

/// An isometric record's residual in pressure, to first order: each
/// sample's contraction residual times the slope `|dp/dx|` of the static
/// model (`coeffs` with its static `shape`, when it has one) at the
/// measured contraction, load and branch (central
/// difference over 1e-4 of rest length, the chip's `f32` evaluation,
/// [`ModelCache`](crate::evaluate::errors::ModelCache)). The held length is
/// the input of an isometric test and the pressure its answer: a model
/// error in contraction where the curve is steep is a large pressure
/// error, where it is flat a small one, and the diagnosis weighs them as
/// the user's pressure does. Fixed per model the candidates are fitted on
/// (the base model's slopes, or a path's once it carries a static shape:
/// the shape moves the slope most where the curve is steep), so every
/// candidate is simulated once per evaluation, as on an isotonic record;
/// the exact pressure (`pressure_to_reach`) judges the result on
/// `--validate`. Bounded to [`PRESSURE_WEIGHT_SPREAD`] times the median
/// either way: at a stroke end the slope is 0 or without bound.
pub fn pressure_weights(
    coeffs: &Coeffs,
    shape: Option<&pam_core::effects::ConstraintShape>,
    samples: &[Sample],
    branches: &[Branch],
    excluded: &[bool],
) -> Vec<f64> {
    let mut cache = crate::evaluate::errors::ModelCache::new(coeffs, shape);
    let h = 1e-4f32;
    let raw: Vec<f64> = samples
        .iter()
        .zip(branches)
        .map(|(s, &b)| {
            let (x, l) = (s.contraction as f32, s.load_n as f32);
            let up = cache.pressure_mpa(x + h, l, b);
            let down = cache.pressure_mpa(x - h, l, b);
            f64::from((up - down).abs()) / (2.0 * f64::from(h))
        })
        .collect();
    let mut used: Vec<f64> = raw
        .iter()
        .zip(excluded)
        .filter(|(w, x)| !**x && w.is_finite() && **w > 0.0)
        .map(|(w, _)| *w)
        .collect();
    if used.is_empty() {
        return vec![1.0; samples.len()];
    }
    let mid = used.len() / 2;
    let (_, median, _) = used.select_nth_unstable_by(mid, f64::total_cmp);
    let (lo, hi) = (
        *median / PRESSURE_WEIGHT_SPREAD,
        *median * PRESSURE_WEIGHT_SPREAD,
    );
    raw.iter()
        .map(|w| if w.is_finite() { w.clamp(lo, hi) } else { hi })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluate::errors::ModelCache;
    use pam_core::effects::shape::table::{TABLE_KNOTS, TABLE_LOADS, TABLE_SEGMENTS};
    use pam_core::effects::{ConstraintShape, StrokeTable};
    use pam_core::Params;

    #[test]
    fn the_pressure_weights_are_the_slopes_of_the_model_with_its_static_shape() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        // A stroke table that bends the curve at every load, most near
        // the stroke's root.
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
        let m = coeffs.load_model_clamped(200.0);
        let (x0, x1) = (m.root_contraction(), m.max_contraction());
        let samples: Vec<Sample> = [0.1f32, 0.5, 0.9]
            .iter()
            .map(|f| Sample {
                t_s: 0.0,
                load_n: 200.0,
                pressure_mpa: 0.3,
                contraction: f64::from(x0 + f * (x1 - x0)),
            })
            .collect();
        let branches = [Branch::Contraction; 3];
        let excluded = [false; 3];
        let plain = pressure_weights(&coeffs, None, &samples, &branches, &excluded);
        let shaped = pressure_weights(&coeffs, Some(&shape), &samples, &branches, &excluded);
        // Near the root the table changes the slope the residual is
        // weighed by ...
        assert!(
            (shaped[0] / plain[0] - 1.0).abs() > 0.2,
            "{plain:?} {shaped:?}"
        );
        // ... and each weight is the shaped model's own |dp/dx|.
        let mut cache = ModelCache::new(&coeffs, Some(&shape));
        let h = 1e-4f32;
        for (s, w) in samples.iter().zip(&shaped) {
            let x = s.contraction as f32;
            let up = cache.pressure_mpa(x + h, 200.0, Branch::Contraction);
            let down = cache.pressure_mpa(x - h, 200.0, Branch::Contraction);
            let slope = f64::from((up - down).abs()) / (2.0 * f64::from(h));
            assert!((w - slope).abs() <= 1e-9 * slope.max(1.0), "{w} {slope}");
        }
    }
}

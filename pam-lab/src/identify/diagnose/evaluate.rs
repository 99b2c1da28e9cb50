//! Simulating a model over the record and measuring its errors.

use pam_core::{Branch, Coeffs, Effects, TrackerConfig};
use serde::Serialize;

use std::sync::Arc;

use super::pressure_curves::PressureCurves;
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
    /// Whether the training part holds the pressure after steps for at
    /// least [`super::MIN_TRAINING_HOLD_S`] (the loop at rest is seen).
    pub(super) rest_in_training: bool,
    pub(super) branches: Vec<Branch>,
    /// Effective-sample divisor: the base residual's correlation length.
    pub(super) corr_len: f64,
    /// The noise floor of the residual: the record's contraction noise,
    /// or on an isometric record (residual in pressure) its pressure noise.
    pub(super) noise_residual: f64,
    /// Each sample's static pressure curve, on an isometric record (the
    /// fits' residual is in pressure, [`PressureCurves`]); `None`: the
    /// residual is the contraction's.
    pub(super) pressure_curves: Option<Arc<PressureCurves>>,
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
    /// fit's static model (the paper's parameters and the static shape)
    /// on the training part with each pressure taken the record's delay
    /// earlier, and that delay (`delay.rs`): the `pressure_delay`
    /// candidate, on an isometric record where fit keeps a static shape
    /// and the record shows a delay.
    pub(super) delayed_static: Option<DelayedStatic>,
    /// fit's static model refitted on the training part with the measured
    /// contraction moved (`backfit.rs`): on an isotonic record, in the
    /// diagnosis's own setup (not the base refit's).
    pub(super) refit_static: Option<Arc<RefitStatic<'a>>>,
}

/// fit's static model (the paper's parameters and the static shape)
/// refitted on the training part with each sample's measured contraction
/// moved by a correction (one per sample of the record; a `NaN` leaves
/// the sample as measured). `None` where fit keeps no static shape there.
pub(super) type RefitStatic<'a> = dyn Fn(&[f64]) -> Option<(pam_core::Params, pam_core::effects::ConstraintShape)>
    + Send
    + Sync
    + 'a;

/// The `pressure_delay` candidate's static model ([`Setup::delayed_static`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct DelayedStatic {
    /// The paper's parameters fitted under the shape.
    pub(super) params: pam_core::Params,
    /// fit's static shape on the retimed training part.
    pub(super) shape: pam_core::effects::ConstraintShape,
    /// The delay estimated.
    pub(super) delay: pam_core::effects::PressureDelay,
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
        if self.pressure_curves.is_none() {
            return self.residuals_with(coeffs, effects);
        }
        self.residual_of(&self.predicted_raw(coeffs, effects), |s| s.pressure_mpa)
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
        if self.pressure_curves.is_none() {
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

    /// `predicted` minus the measured value (`measured`); `NaN` on the
    /// excluded samples.
    fn residual_of(&self, predicted: &[f64], measured: impl Fn(&Sample) -> f64) -> Vec<f64> {
        predicted
            .iter()
            .zip(self.samples)
            .zip(&self.excluded)
            .map(
                |((p, s), &excluded)| {
                    if excluded {
                        f64::NAN
                    } else {
                        p - measured(s)
                    }
                },
            )
            .collect()
    }

    /// The residual the fits run on: measured minus simulated contraction,
    /// or on an isometric record that error carried into pressure along
    /// the static curve ([`PressureCurves::residual`]: the model's
    /// pressure minus the measured one where the model is static); `NaN`
    /// on the excluded samples.
    pub(super) fn residuals_with(&self, coeffs: &Coeffs, effects: Effects) -> Vec<f64> {
        let x = self.contraction(coeffs, effects);
        let Some(curves) = &self.pressure_curves else {
            return self
                .residual_of(&x, |s| s.contraction)
                .into_iter()
                .map(|r| -r)
                .collect();
        };
        x.iter()
            .zip(self.samples)
            .zip(&self.excluded)
            .enumerate()
            .map(|(i, ((&predicted, s), &excluded))| {
                if excluded {
                    f64::NAN
                } else {
                    curves.residual(i, s.contraction, predicted)
                }
            })
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

/// One fitted variant of a candidate: base parameters, their
/// coefficients, the effects, their errors and residual, and the
/// parameters it adds.
pub(super) type Variant = (
    pam_core::Params,
    Coeffs,
    Effects,
    ModelErrors,
    Vec<f64>,
    usize,
);

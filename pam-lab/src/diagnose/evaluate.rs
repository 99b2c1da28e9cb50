//! Simulating a model over the record and measuring its errors.

use pam_core::{Branch, Coeffs, Effects, Simulator, TrackerConfig};
use serde::Serialize;

use super::regimes::Regimes;
use super::MEMORY_DEPTH;
use crate::data::Sample;
use crate::stats::rms_where;

/// Simulate the model (base `coeffs` plus `effects`) over `samples` from the
/// measured pressure and load, on the given branches (see
/// [`hindsight_branches`]); one predicted contraction per sample.
pub fn simulate(
    coeffs: &Coeffs,
    effects: Effects,
    tracker: TrackerConfig,
    samples: &[Sample],
    branches: &[Branch],
) -> Vec<f64> {
    let first_load = samples.first().map_or(0.0, |s| s.load_n) as f32;
    let Ok(mut sim) = Simulator::<MEMORY_DEPTH>::new(*coeffs, effects, tracker, first_load) else {
        return vec![f64::NAN; samples.len()];
    };
    samples
        .iter()
        .zip(branches)
        .map(|(s, &b)| {
            f64::from(sim.step_on_branch(s.t_s as f32, s.pressure_mpa as f32, s.load_n as f32, b))
        })
        .collect()
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
    /// Load, N.
    pub load_n: f64,
    /// Held-out samples at it.
    pub samples: usize,
    /// Held-out RMS contraction error.
    pub rms: f64,
}

/// What is shared by every evaluation of one record.
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
}

impl Setup<'_> {
    pub(super) fn residuals(&self, effects: Effects) -> Vec<f64> {
        self.residuals_with(&self.coeffs, effects)
    }

    pub(super) fn residuals_with(&self, coeffs: &Coeffs, effects: Effects) -> Vec<f64> {
        simulate(coeffs, effects, self.tracker, self.samples, &self.branches)
            .iter()
            .zip(self.samples)
            .map(|(x, s)| s.contraction - x)
            .collect()
    }

    pub(super) fn errors(
        &self,
        coeffs: &Coeffs,
        effects: Effects,
        n_params: usize,
    ) -> (ModelErrors, Vec<f64>) {
        let res = self.residuals_with(coeffs, effects);
        let (rms_heldout, _) = rms_where(&res, |i| self.heldout[i]);
        let (rms_train, n_train) = rms_where(&res, |i| !self.heldout[i]);
        let n_eff = (n_train as f64 / self.corr_len).max(1.0);
        let bic = n_eff * (rms_train * rms_train).max(1e-300).ln() + n_params as f64 * n_eff.ln();
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
        let mut loads: Vec<f64> = self
            .samples
            .iter()
            .zip(&self.heldout)
            .filter(|(_, h)| **h)
            .map(|(s, _)| s.load_n.round())
            .collect();
        loads.sort_by(f64::total_cmp);
        loads.dedup();
        let loads = loads
            .into_iter()
            .map(|l| {
                let (rms, samples) = rms_where(&res, |i| {
                    self.heldout[i] && self.samples[i].load_n.round() == l
                });
                LoadError {
                    load_n: l,
                    samples,
                    rms,
                }
            })
            .collect();
        (
            ModelErrors {
                rms_heldout,
                rms_train,
                bic,
                regimes,
                loads,
            },
            res,
        )
    }
}

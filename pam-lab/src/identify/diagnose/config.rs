//! The diagnosis' settings ([`DiagnoseConfig`]) and the constants it works
//! with, shared by the search and its parts.

use crate::identify::fit::FitConfig;

/// Settings of the diagnosis.
#[derive(Clone, Debug)]
pub struct DiagnoseConfig {
    /// Settings of the base fit. Its `holdout` is how the static model
    /// diagnose writes is fitted on the record, as `pam-lab fit` with that
    /// hold-out writes it; the diagnosis itself fits on its own training
    /// part.
    pub fit: FitConfig,
    /// Smallest relative cut of the held-out RMS for a candidate to count.
    pub min_improvement: f64,
    /// Smallest fall of the effective-sample BIC for a candidate to count.
    pub min_bic_drop: f64,
    /// Most effects added.
    pub max_effects: usize,
    /// Iteration budget of each candidate's optimiser (LM patience).
    pub patience: usize,
    /// Levenberg–Marquardt iterations of the joint base refit
    /// ([`BASE_REFIT_FIELDS`](super::refit::BASE_REFIT_FIELDS)); 0 keeps `fit::fit`'s base.
    pub refit_iterations: usize,
}

impl Default for DiagnoseConfig {
    fn default() -> Self {
        DiagnoseConfig {
            fit: FitConfig::default(),
            min_improvement: 0.15,
            min_bic_drop: 10.0,
            max_effects: 2,
            patience: 8,
            refit_iterations: 3,
        }
    }
}

/// Half-width of the centred running median applied to the measured
/// pressure before it drives the simulation, samples.
///
/// Why: where the muscle's curve is flat (around the inflection point) the
/// contraction moves by 10–20 per MPa, so 0.001 MPa of sensor noise becomes
/// 0.01–0.02 of simulated contraction, which would swamp every effect. A
/// median (unlike a mean) keeps pressure steps sharp, so it does not fake a
/// creep or a lag.
pub const PRESSURE_MEDIAN_HALF_WIDTH: usize = 4;

/// One in how many segments (cycles, cut at load changes) is held out
/// ([`crate::record::split::holdout_by_segment`]).
pub const HOLDOUT_EVERY: usize = 3;

/// Width of the held-out load groups of an isometric record, N
/// ([`ModelErrors::loads`](super::evaluate::ModelErrors::loads)).
pub const ISOMETRIC_LOAD_GROUP_N: f64 = 25.0;

//! Mode tracker: follows the direction of motion (which branch) and the load
//! (which constraint model), the behaviour of the paper's Figs. 6–8.
//!
//! Fed one sample per control period — a *drive signal* that rises on the
//! contraction branch and falls on the expansion branch (measured or demanded
//! pressure, or contraction), and the load — it:
//!
//! * switches branch only when the signal has moved back from its extreme by
//!   more than `direction_deadband` (so sensor noise below the deadband never
//!   flips the direction);
//! * switches the active load model when the load lies beyond
//!   `load_threshold_n` from the active load, *on the same side*, for
//!   `load_debounce_samples` consecutive samples, to the mean of those
//!   samples (a single spike never switches; a load alternating across the
//!   active one never switches; a non-finite load restarts the count);
//! * reports each switch in the returned [`Update`].
//!
//! # Work per sample
//! A few comparisons. A load switch needs the new load's [`LoadModel`]:
//! its coefficients (eqs. 16–21, in `f32`: four divisions), which the switch
//! makes active at once, and its two inverse tables (at most
//! [`BUILD_UNITS_MAX`](crate::load_model::BUILD_UNITS_MAX) work units of one
//! forward evaluation or one Newton step each). By default
//! ([`Tracker::new`]) the tables are built within the update that switches,
//! as host tools want. A real-time caller sets a budget with
//! [`Tracker::set_build_budget`]: the tables are then built a bounded
//! number of units per update, and until they are complete
//! ([`Tracker::inverse_ready`]) the model evaluates forward (eqs. 25/26) at
//! full speed while its inverse falls back to a slow bisection, which a
//! real-time caller skips. No update does more than its budget.
//! Non-finite samples are ignored (and reported), never stored.

use crate::branch::Branch;
use crate::coeffs::Coeffs;
use crate::error::Error;
use crate::load_model::{FamilyF32, LoadModel, TableBuild};

/// Tuning of the tracker.
///
/// `direction_deadband` is in the drive signal's unit: build the
/// configuration with [`TrackerConfig::for_pressure_drive`] (MPa) or
/// [`TrackerConfig::for_contraction_drive`] (fraction of rest length), which
/// name it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerConfig {
    /// How far, in the drive signal's unit (MPa for a pressure drive, a
    /// fraction of rest length for a contraction drive), the signal must move
    /// back from its last extreme before the branch switches. Set it above
    /// the signal's peak-to-peak noise.
    pub direction_deadband: f32,
    /// Load difference from the active load that counts as a change, N.
    pub load_threshold_n: f32,
    /// Consecutive samples beyond the threshold (on one side) before the
    /// model switches.
    pub load_debounce_samples: u16,
}

impl TrackerConfig {
    /// For a pressure drive signal in MPa with noise up to ±0.002 MPa and a
    /// load cell with noise up to ±5 N, sampled at 100–1000 Hz.
    pub const DEFAULT_PRESSURE: TrackerConfig = TrackerConfig::for_pressure_drive(0.005, 20.0, 5);

    /// For a contraction drive signal (the firmware controller's noise-free
    /// set-point), 1 kHz: a deadband of 0.002 of rest length.
    pub const DEFAULT_CONTRACTION: TrackerConfig =
        TrackerConfig::for_contraction_drive(0.002, 20.0, 5);

    /// A tracker driven by pressure: the direction deadband in MPa.
    pub const fn for_pressure_drive(
        direction_deadband_mpa: f32,
        load_threshold_n: f32,
        load_debounce_samples: u16,
    ) -> TrackerConfig {
        TrackerConfig {
            direction_deadband: direction_deadband_mpa,
            load_threshold_n,
            load_debounce_samples,
        }
    }

    /// A tracker driven by contraction (measured or desired): the direction
    /// deadband as a fraction of the muscle's rest length.
    pub const fn for_contraction_drive(
        direction_deadband_contraction: f32,
        load_threshold_n: f32,
        load_debounce_samples: u16,
    ) -> TrackerConfig {
        TrackerConfig {
            direction_deadband: direction_deadband_contraction,
            load_threshold_n,
            load_debounce_samples,
        }
    }

    /// Validate: finite, positive deadband and threshold, debounce ≥ 1.
    pub fn validate(&self) -> Result<(), Error> {
        if !(self.direction_deadband.is_finite() && self.direction_deadband >= 0.0) {
            return Err(Error::OutOfRange(
                "direction_deadband",
                "must be finite and >= 0",
            ));
        }
        if !(self.load_threshold_n.is_finite() && self.load_threshold_n > 0.0) {
            return Err(Error::OutOfRange(
                "load_threshold_n",
                "must be finite and > 0 N",
            ));
        }
        if self.load_debounce_samples == 0 {
            return Err(Error::OutOfRange("load_debounce_samples", "must be >= 1"));
        }
        Ok(())
    }
}

/// A switch of the active load model.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoadSwitch {
    /// Previous active load, N.
    pub from_n: f32,
    /// New active load, N (clamped to the calibrated range).
    pub to_n: f32,
}

/// What one [`Tracker::update`] did.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Update {
    /// `Some(new branch)` when the direction switched on this sample.
    pub branch_switch: Option<Branch>,
    /// `Some` when the active load model switched on this sample.
    pub load_switch: Option<LoadSwitch>,
    /// The load sample was outside the calibrated range (or not finite).
    pub load_out_of_range: bool,
    /// The drive signal or the load sample was not finite and was ignored.
    pub non_finite_input: bool,
}

/// Tracks the branch and the active load; owns the active [`LoadModel`].
#[derive(Clone, Debug)]
pub struct Tracker {
    config: TrackerConfig,
    branch: Branch,
    /// Extreme of the drive signal since the last reversal (max on the
    /// contraction branch, min on the expansion branch); NaN before the first
    /// sample (every comparison with it is false: the first finite drive
    /// becomes the extreme and cannot reverse). A plain `f32` rather than an
    /// `Option` saves the tag's load, test and store per sample.
    extreme: f32,
    /// The load family in `f32`: a new load's coefficients without `f64`.
    family: FamilyF32,
    model: LoadModel,
    /// The active model's table build, while `!model.inverse_ready()`.
    build: TableBuild,
    /// Work units of the table build per update; 0: all at once.
    build_units: u16,
    /// The caller advances the build ([`Tracker::advance_build`]).
    build_deferred: bool,
    candidate_count: u16,
    candidate_sum_n: f32,
    /// The side of the active load the candidate's samples lie on.
    candidate_above: bool,
}

impl Tracker {
    /// A tracker starting on `branch` with the model at `initial_load_n`
    /// (clamped to the calibrated range), its tables built. A load switch
    /// builds the new model's tables within the update that switches (no
    /// build budget; see [`set_build_budget`](Self::set_build_budget)).
    pub fn new(
        coeffs: &Coeffs,
        config: TrackerConfig,
        initial_load_n: f32,
        branch: Branch,
    ) -> Result<Tracker, Error> {
        config.validate()?;
        let family = FamilyF32::new(coeffs.family());
        Ok(Tracker {
            config,
            branch,
            extreme: f32::NAN,
            model: family.model(coeffs.clamp_load_n(initial_load_n)),
            family,
            build: TableBuild::new(),
            build_units: 0,
            build_deferred: false,
            candidate_count: 0,
            candidate_sum_n: 0.0,
            candidate_above: false,
        })
    }

    /// Bound the work of a load switch per [`update`](Self::update): at most
    /// `units_per_update` work units of the new model's table build (each
    /// one forward evaluation, one table bracket or one Newton step: at most
    /// one division, one square root and a few dozen `f32` operations); 0
    /// builds at once. The build then spans up to
    /// `BUILD_UNITS_MAX / units_per_update` updates, during which
    /// [`inverse_ready`](Self::inverse_ready) is false.
    ///
    /// ```
    /// use pam_core::{Branch, Coeffs, Params, Tracker, TrackerConfig};
    ///
    /// let c = Coeffs::new(Params::DEFAULT).unwrap();
    /// let cfg = TrackerConfig::DEFAULT_PRESSURE;
    /// let mut t = Tracker::new(&c, cfg, 100.0, Branch::Contraction).unwrap();
    /// t.set_build_budget(10);
    /// // A load step: after the debounce the new load's model is active...
    /// let switched = (0..cfg.load_debounce_samples)
    ///     .filter_map(|_| t.update(&c, 0.2, 400.0).load_switch)
    ///     .last();
    /// assert_eq!(switched.map(|s| s.to_n), Some(400.0));
    /// assert_eq!(t.load_n(), 400.0);
    /// // ...and its inverse tables follow over the next updates.
    /// assert!(!t.inverse_ready());
    /// let mut updates = 0;
    /// while !t.inverse_ready() {
    ///     t.update(&c, 0.2, 400.0);
    ///     updates += 1;
    /// }
    /// assert!(updates > 1 && updates <= pam_core::load_model::BUILD_UNITS_MAX / 10 + 1);
    /// ```
    pub fn set_build_budget(&mut self, units_per_update: u16) {
        self.build_units = units_per_update;
        self.build_deferred = false;
    }

    /// Leave the table build to the caller: [`update`](Self::update) does
    /// none of it, and [`advance_build`](Self::advance_build) does a given
    /// number of units (a controller that knows what else its period spent).
    pub fn defer_build(&mut self) {
        self.build_deferred = true;
    }

    /// Advance the active model's table build by at most `units` work units
    /// (see [`set_build_budget`](Self::set_build_budget)); `true` once the
    /// tables are complete ([`inverse_ready`](Self::inverse_ready)).
    pub fn advance_build(&mut self, units: u16) -> bool {
        if self.model.inverse_ready() {
            return true;
        }
        self.model.advance_build(&mut self.build, units)
    }

    /// The branch the muscle is on.
    pub fn branch(&self) -> Branch {
        self.branch
    }

    /// The active per-load model.
    #[inline]
    pub fn model(&self) -> &LoadModel {
        &self.model
    }

    /// Whether the active model's inverse tables are complete (always,
    /// without a build budget); see [`LoadModel::inverse_ready`].
    #[inline]
    pub fn inverse_ready(&self) -> bool {
        self.model.inverse_ready()
    }

    /// The active load, N.
    pub fn load_n(&self) -> f32 {
        self.model.load_n()
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// Feed one sample of the drive signal and the load.
    #[inline]
    pub fn update(&mut self, coeffs: &Coeffs, drive: f32, load_n: f32) -> Update {
        let mut out = Update::default();
        if drive.is_finite() {
            out.branch_switch = self.update_direction(drive);
        } else {
            out.non_finite_input = true;
        }
        if load_n.is_finite() {
            out.load_out_of_range = !coeffs.load_in_range(load_n);
            out.load_switch = self.update_load(coeffs, load_n);
        } else {
            // A non-finite load is no evidence of a load change: the run of
            // consecutive samples beyond the threshold ends here.
            self.reset_candidate();
            out.non_finite_input = true;
            out.load_out_of_range = true;
        }
        if !self.build_deferred && !self.model.inverse_ready() {
            self.advance_own_build();
        }
        out
    }

    /// `drive` is finite here (checked by `update`).
    fn update_direction(&mut self, drive: f32) -> Option<Branch> {
        let extreme = self.extreme;
        let band = self.config.direction_deadband;
        // With `extreme` NaN (no sample yet) `reversed` is false and the
        // `!(…)` tests are true, so the drive becomes the extreme.
        let (reversed, further) = match self.branch {
            Branch::Contraction => (drive < extreme - band, !(drive <= extreme)),
            Branch::Expansion => (drive > extreme + band, !(drive >= extreme)),
        };
        if reversed {
            self.branch = self.branch.opposite();
            self.extreme = drive;
            Some(self.branch)
        } else {
            if further {
                self.extreme = drive;
            }
            None
        }
    }

    fn reset_candidate(&mut self) {
        self.candidate_count = 0;
        self.candidate_sum_n = 0.0;
    }

    /// The debounce. `load_n` is finite.
    fn update_load(&mut self, coeffs: &Coeffs, load_n: f32) -> Option<LoadSwitch> {
        let target = coeffs.clamp_load_n(load_n);
        let active = self.model.load_n();
        if (target - active).abs() <= self.config.load_threshold_n {
            self.reset_candidate();
            return None;
        }
        // Only a run of samples on one side of the active load is a load
        // change: samples alternating across it (a load oscillating about
        // the active one) restart the run instead of adding up to a switch
        // to their mean, which is the active load again.
        let above = target > active;
        if self.candidate_count > 0 && above != self.candidate_above {
            self.reset_candidate();
        }
        self.candidate_above = above;
        self.candidate_count = self.candidate_count.saturating_add(1);
        self.candidate_sum_n += target;
        if self.candidate_count < self.config.load_debounce_samples {
            return None;
        }
        Some(self.switch_load(coeffs))
    }

    /// The rare path of [`update_load`](Self::update_load): the model at the
    /// debounced mean load, its coefficients now (fixed work), its tables in
    /// [`advance_own_build`](Self::advance_own_build) or the caller's
    /// [`advance_build`](Self::advance_build). Out of line so that the
    /// per-sample path does not carry its stack frame.
    #[cold]
    #[inline(never)]
    fn switch_load(&mut self, coeffs: &Coeffs) -> LoadSwitch {
        let from_n = self.model.load_n();
        let to_n = coeffs.clamp_load_n(self.candidate_sum_n / f32::from(self.candidate_count));
        self.reset_candidate();
        // In place: the old tables and hull are overwritten by the build
        // before anything reads them (no 700-byte clear and copy).
        self.family.set_model_without_tables(&mut self.model, to_n);
        self.build.restart();
        LoadSwitch { from_n, to_n }
    }

    /// Advance the active model's table build by the budget (all of it
    /// without a budget: at most [`BUILD_UNITS_MAX`](crate::load_model::BUILD_UNITS_MAX) units).
    #[inline(never)]
    fn advance_own_build(&mut self) {
        let units = if self.build_units == 0 {
            u16::MAX
        } else {
            self.build_units
        };
        self.model.advance_build(&mut self.build, units);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Params;

    fn setup() -> (Coeffs, Tracker) {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let t = Tracker::new(
            &coeffs,
            TrackerConfig::DEFAULT_PRESSURE,
            100.0,
            Branch::Contraction,
        )
        .unwrap();
        (coeffs, t)
    }

    #[test]
    fn triangle_input_switches_once_per_reversal() {
        let (coeffs, mut t) = setup();
        let mut switches = heapless_free_log();
        // Two triangle cycles 0 → 0.5 → 0 MPa in steps of 0.001 MPa.
        let mut k = 0;
        for cycle in 0..2 {
            for i in (0..=500).chain((0..500).rev()) {
                let p = i as f32 * 0.001;
                if let Some(b) = t.update(&coeffs, p, 100.0).branch_switch {
                    switches.push((cycle, k, b));
                }
                k += 1;
            }
        }
        // Reversal at the top of each cycle and at the bottom between them.
        assert_eq!(switches.len(), 3, "{switches:?}");
        assert_eq!(switches[0].2, Branch::Expansion);
        assert_eq!(switches[1].2, Branch::Contraction);
        // Detected within deadband/step + 1 samples of the peak (k = 500).
        assert!(switches[0].1 <= 500 + 6);
    }

    fn heapless_free_log() -> std::vec::Vec<(i32, i32, Branch)> {
        std::vec::Vec::new()
    }

    #[test]
    fn load_step_is_debounced_and_switches_the_model() {
        let (coeffs, mut t) = setup();
        // One spike does not switch.
        assert!(t.update(&coeffs, 0.1, 300.0).load_switch.is_none());
        assert!(t.update(&coeffs, 0.1, 100.0).load_switch.is_none());
        assert_eq!(t.load_n(), 100.0);
        // A held step does, after the debounce count.
        let mut switched_at = None;
        for k in 0..20 {
            if let Some(s) = t.update(&coeffs, 0.1, 300.0).load_switch {
                switched_at = Some((k, s));
                break;
            }
        }
        let (k, s) = switched_at.unwrap();
        assert_eq!(
            k + 1,
            usize::from(TrackerConfig::DEFAULT_PRESSURE.load_debounce_samples)
        );
        assert_eq!(
            s,
            LoadSwitch {
                from_n: 100.0,
                to_n: 300.0
            }
        );
        assert_eq!(t.model().load_n(), 300.0);
    }

    #[test]
    fn out_of_range_load_is_flagged_and_clamped() {
        let (coeffs, mut t) = setup();
        let mut last = Update::default();
        for _ in 0..10 {
            last = t.update(&coeffs, 0.1, 900.0);
        }
        assert!(last.load_out_of_range);
        assert_eq!(t.load_n(), 600.0);
        let u = t.update(&coeffs, f32::NAN, f32::INFINITY);
        assert!(u.non_finite_input && u.load_out_of_range);
        assert_eq!(t.load_n(), 600.0);
    }

    #[test]
    fn a_load_alternating_across_the_active_load_never_switches() {
        // Issue 14: 250/349 N about an active 300 N used to switch 200 times
        // per 1000 samples (both sides counted toward one switch, to ~300 N).
        let (coeffs, _) = setup();
        let mut t = Tracker::new(
            &coeffs,
            TrackerConfig::DEFAULT_PRESSURE,
            300.0,
            Branch::Contraction,
        )
        .unwrap();
        let mut switches = 0;
        for k in 0..1000 {
            let load = if k % 2 == 0 { 250.0 } else { 349.0 };
            switches += usize::from(t.update(&coeffs, 0.1, load).load_switch.is_some());
        }
        assert_eq!(switches, 0);
        assert_eq!(t.load_n(), 300.0);
        // Two samples on one side then one on the other: still no switch.
        for k in 0..999 {
            let load = if k % 3 == 2 { 250.0 } else { 349.0 };
            switches += usize::from(t.update(&coeffs, 0.1, load).load_switch.is_some());
        }
        assert_eq!(switches, 0);
    }

    #[test]
    fn a_non_finite_load_restarts_the_debounce() {
        let (coeffs, mut t) = setup();
        let debounce = TrackerConfig::DEFAULT_PRESSURE.load_debounce_samples;
        // debounce − 1 samples at 300 N, a NaN, debounce − 1 again: no switch.
        for _ in 0..2 {
            for _ in 1..debounce {
                assert!(t.update(&coeffs, 0.1, 300.0).load_switch.is_none());
            }
            let u = t.update(&coeffs, 0.1, f32::NAN);
            assert!(u.non_finite_input && u.load_switch.is_none());
        }
        assert_eq!(t.load_n(), 100.0);
        // Then a full run switches.
        let mut switched = false;
        for _ in 0..debounce {
            switched |= t.update(&coeffs, 0.1, 300.0).load_switch.is_some();
        }
        assert!(switched);
    }

    #[test]
    fn a_budgeted_build_switches_the_forward_model_at_once_and_the_inverse_later() {
        let (coeffs, mut instant) = setup();
        let (_, mut t) = setup();
        t.set_build_budget(10);
        let debounce = usize::from(TrackerConfig::DEFAULT_PRESSURE.load_debounce_samples);
        let mut ready_at = None;
        for k in 0..2000 {
            let u = t.update(&coeffs, 0.1, 420.0);
            let v = instant.update(&coeffs, 0.1, 420.0);
            // Both switch on the same sample, after the debounce.
            assert_eq!(u.load_switch, v.load_switch, "{k}");
            assert_eq!(u.load_switch.is_some(), k + 1 == debounce, "{k}");
            assert!(instant.inverse_ready());
            if k + 1 >= debounce {
                assert_eq!(t.load_n(), 420.0);
                // The forward model is the new load's at once.
                for x in [0.05, 0.1, 0.15] {
                    let br = Branch::Contraction;
                    assert_eq!(
                        t.model().pressure_mpa(x, br),
                        instant.model().pressure_mpa(x, br)
                    );
                }
                if t.inverse_ready() {
                    ready_at = Some(k);
                    break;
                }
                // The inverse meanwhile: slow, but the same to the tolerance.
                for p in [0.0, 0.1, 0.3, 0.45] {
                    for br in [Branch::Contraction, Branch::Expansion] {
                        let (a, b) = (
                            t.model().contraction(p, br),
                            instant.model().contraction(p, br),
                        );
                        assert!((a - b).abs() < 1e-4, "{p} {br:?}: {a} vs {b}");
                    }
                }
            } else {
                assert!(t.inverse_ready());
            }
        }
        let k = ready_at.expect("tables built");
        eprintln!("tables complete {} updates after the load step", k + 1);
        let bound = debounce + crate::load_model::BUILD_UNITS_MAX.div_ceil(10);
        assert!(k > debounce && k < bound, "{k}");
        // The same model as built at once.
        assert_eq!(t.model(), instant.model());
    }

    #[test]
    fn a_deferred_build_advances_only_when_the_caller_says() {
        let (coeffs, mut t) = setup();
        t.defer_build();
        for _ in 0..TrackerConfig::DEFAULT_PRESSURE.load_debounce_samples {
            t.update(&coeffs, 0.1, 500.0);
        }
        assert_eq!(t.load_n(), 500.0);
        for _ in 0..3000 {
            t.update(&coeffs, 0.1, 500.0);
            assert!(!t.advance_build(0));
        }
        assert!(!t.inverse_ready(), "update builds nothing when deferred");
        let mut calls = 0;
        while !t.advance_build(10) {
            calls += 1;
            assert!(calls <= crate::load_model::BUILD_UNITS_MAX / 10);
        }
        assert!(t.inverse_ready());
        let (_, mut instant) = setup();
        for _ in 0..5 {
            instant.update(&coeffs, 0.1, 500.0);
        }
        assert_eq!(t.model(), instant.model());
    }

    #[test]
    fn the_f32_family_agrees_with_the_f64_construction() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let family = FamilyF32::new(coeffs.family());
        for load in [100.0, 137.0, 300.0, 512.5, 600.0] {
            let (m32, m64) = (family.model(load), coeffs.load_model(load).unwrap());
            for i in 0..=100 {
                let x = m64.root_contraction()
                    + (m64.max_contraction() - m64.root_contraction()) * i as f32 / 100.0;
                for br in [Branch::Contraction, Branch::Expansion] {
                    let (a, b) = (m32.pressure_mpa(x, br), m64.pressure_mpa(x, br));
                    assert!((a - b).abs() < 2e-5, "{load} N, x {x}: {a} vs {b}");
                }
            }
            for i in 0..=100 {
                let p = 0.5 * i as f32 / 100.0;
                for br in [Branch::Contraction, Branch::Expansion] {
                    let (a, b) = (m32.contraction(p, br), m64.contraction(p, br));
                    assert!((a - b).abs() < 2e-5, "{load} N, p {p}: {a} vs {b}");
                }
            }
        }
    }
}

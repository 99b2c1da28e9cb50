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
//! * switches the active load model when the load differs from the active
//!   load by more than `load_threshold_n` for `load_debounce_samples`
//!   consecutive samples, to the mean of those samples (a single spike never
//!   switches);
//! * reports each switch in the returned [`Update`].
//!
//! Work per sample is bounded: a few comparisons, and on a load switch one
//! [`LoadModel`] rebuild (`2 × INVERSE_KNOTS` forward evaluations).
//! Non-finite samples are ignored (and reported), never stored.

use crate::branch::Branch;
use crate::coeffs::Coeffs;
use crate::error::Error;
use crate::load_model::LoadModel;

/// Tuning of the tracker.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrackerConfig {
    /// How far, in the drive signal's unit, the signal must move back from its
    /// last extreme before the branch switches. Set it above the signal's
    /// peak-to-peak noise.
    pub direction_deadband: f32,
    /// Load difference from the active load that counts as a change, N.
    pub load_threshold_n: f32,
    /// Consecutive samples beyond the threshold before the model switches.
    pub load_debounce_samples: u16,
}

impl TrackerConfig {
    /// For a pressure drive signal in MPa with noise up to ±0.002 MPa and a
    /// load cell with noise up to ±5 N, sampled at 100–1000 Hz.
    pub const DEFAULT_PRESSURE: TrackerConfig = TrackerConfig {
        direction_deadband: 0.005,
        load_threshold_n: 20.0,
        load_debounce_samples: 5,
    };

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
    model: LoadModel,
    candidate_count: u16,
    candidate_sum_n: f32,
}

impl Tracker {
    /// A tracker starting on `branch` with the model at `initial_load_n`
    /// (clamped to the calibrated range).
    pub fn new(
        coeffs: &Coeffs,
        config: TrackerConfig,
        initial_load_n: f32,
        branch: Branch,
    ) -> Result<Tracker, Error> {
        config.validate()?;
        Ok(Tracker {
            config,
            branch,
            extreme: f32::NAN,
            model: coeffs.load_model_clamped(initial_load_n),
            candidate_count: 0,
            candidate_sum_n: 0.0,
        })
    }

    /// The branch the muscle is on.
    pub fn branch(&self) -> Branch {
        self.branch
    }

    /// The active per-load model.
    pub fn model(&self) -> &LoadModel {
        &self.model
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
            out.non_finite_input = true;
            out.load_out_of_range = true;
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

    fn update_load(&mut self, coeffs: &Coeffs, load_n: f32) -> Option<LoadSwitch> {
        let target = coeffs.clamp_load_n(load_n);
        if (target - self.model.load_n()).abs() <= self.config.load_threshold_n {
            self.candidate_count = 0;
            self.candidate_sum_n = 0.0;
            return None;
        }
        self.candidate_count = self.candidate_count.saturating_add(1);
        self.candidate_sum_n += target;
        if self.candidate_count < self.config.load_debounce_samples {
            return None;
        }
        Some(self.switch_load(coeffs))
    }

    /// The rare path of [`update_load`](Self::update_load): rebuild the model
    /// at the debounced mean load. Out of line so that the per-sample path
    /// does not carry the model's stack frame (about 560 bytes) and copy.
    #[cold]
    #[inline(never)]
    fn switch_load(&mut self, coeffs: &Coeffs) -> LoadSwitch {
        let active = self.model.load_n();
        let to_n = coeffs.clamp_load_n(self.candidate_sum_n / f32::from(self.candidate_count));
        self.candidate_count = 0;
        self.candidate_sum_n = 0.0;
        self.model = coeffs.load_model_clamped(to_n);
        LoadSwitch {
            from_n: active,
            to_n,
        }
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
}

//! Online adaptation of the flashed model's stroke: a bounded recursive
//! least-squares estimate, with forgetting, of how far the worn muscle
//! contracts against the model at the same pressure, load and branch.
//!
//! A McKibben muscle's braid and bladder fatigue while it is worn: the
//! stroke shrinks and the loop widens (host-sim's worn muscle,
//! `host-sim/src/wear.rs`). The parameter adapted is the **stroke scale**
//! `s`: the muscle's contraction above the active model's root `R` is `s`
//! times the model's,
//!
//! ```text
//! x − R = s · (x_model(p, branch) − R)
//! ```
//!
//! with `x_model` the paper's inverse, eqs. (25)/(26), at the measured
//! pressure `p`. The feedforward then asks the model for
//! `R + (x_ref − R)/s`. The regressor `φ = x_model − R` and the
//! measurement `y = x − R` come from the readings the monitor has already
//! checked; the estimate is scalar RLS with exponential forgetting
//! (`λ = 1 − dt/memory_s`), each update's change limited to
//! `max_rate_per_s · dt` so that adaptation is orders of magnitude slower
//! than any fault's detection.
//!
//! # Safety
//! * Adaptation never widens the model check's band. On a stroke that
//!   shrank (`s < 1`, the wear the muscle really has) the band moves with
//!   the adapted stroke and narrows with it: the check judges the flashed
//!   model's contraction `R + (x − R)/s`, so a distance `d` outside it is
//!   `s·d < d` of measured contraction. On a stroke that grew (`s ≥ 1`) the
//!   check judges the measured contraction against the flashed band.
//! * Frozen (no update) while a fault is active or the controller
//!   recovers from one, for `settle_periods` after that and after any load
//!   switch or branch switch, while the last valve flow command was at its
//!   limit (saturated),
//!   while the filtered pressure moves faster than
//!   `max_pressure_rate_mpa_per_s` (a transient), and where the model's
//!   contraction is within `min_stroke_fraction` of the stroke's root
//!   (no information on a scale there).
//! * Bounded: `s` stays within `1 ± bound`. Reaching the bound is
//!   [`Fault::Drifted`](super::Fault::Drifted), latched: the muscle has
//!   drifted beyond what its model can be adapted to, re-identify it.
//! * Rebooting returns to the flashed model (the scale lives in RAM).
//!
//! # Work per step
//! One branch inverse of the active model (its tables), a one-pole filter
//! and a dozen `f32` operations; no loop, no allocation, no panic.

use pam_core::{clamp, Branch, LoadModel};

/// Settings of the adaptation ([`ControllerConfig::adaptation`](super::ControllerConfig::adaptation)).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AdaptationConfig {
    /// Largest change of the stroke scale from the flashed model's 1, as a
    /// fraction (0.2: the scale stays in `[0.8, 1.2]`); reaching it is
    /// [`Fault::Drifted`](super::Fault::Drifted). In `(0, 0.5]`.
    pub bound: f32,
    /// Forgetting time, s: a sample's weight in the estimate falls by `1/e`
    /// over this much adapting time. At least 10 control periods.
    pub memory_s: f32,
    /// Fastest change of the scale, per second of adapting time.
    pub max_rate_per_s: f32,
    /// A sample is used only where the model's contraction lies above the
    /// root by at least this fraction of the stroke `Rx − R`. In `[0, 1)`.
    pub min_stroke_fraction: f32,
    /// Periods adaptation stays frozen after a fault, a recovery, a load
    /// switch or a branch switch.
    pub settle_periods: u16,
    /// Adaptation is frozen while the measured pressure, filtered over
    /// `pressure_filter_s`, changes faster than this, MPa/s.
    pub max_pressure_rate_mpa_per_s: f32,
    /// Time constant of the pressure filter for that rate, s (≥ 0; 0: the
    /// raw pressure).
    pub pressure_filter_s: f32,
}

impl AdaptationConfig {
    /// For host-sim's 100–600 N muscle at 1 kHz: a one-minute memory, at
    /// most 1 % of scale per second (so a fault's detection, at most a few
    /// hundred ms, sees the scale move by under 0.5 %), ±20 % bound.
    pub const DEFAULT: AdaptationConfig = AdaptationConfig {
        bound: 0.2,
        memory_s: 60.0,
        max_rate_per_s: 0.01,
        min_stroke_fraction: 0.15,
        settle_periods: 300,
        max_pressure_rate_mpa_per_s: 0.5,
        pressure_filter_s: 0.02,
    };

    /// Whether every field is in its range, for a control period `dt_s`.
    pub fn is_valid(&self, dt_s: f32) -> bool {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        positive(self.bound)
            && self.bound <= 0.5
            && positive(self.memory_s)
            && self.memory_s >= 10.0 * dt_s
            && positive(self.max_rate_per_s)
            && self.min_stroke_fraction.is_finite()
            && (0.0..1.0).contains(&self.min_stroke_fraction)
            && positive(self.max_pressure_rate_mpa_per_s)
            && self.pressure_filter_s.is_finite()
            && self.pressure_filter_s >= 0.0
    }
}

/// Largest covariance of the estimate: caps how far one sample can move it
/// after a long stretch without information.
const MAX_COVARIANCE: f32 = 1.0e4;

/// The adapted stroke scale and the estimator's state.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Adaptation {
    /// The stroke scale `s` (1: the flashed model).
    scale: f32,
    /// RLS covariance of `s` (per unit contraction²).
    covariance: f32,
    /// Periods left frozen.
    frozen: u16,
    /// Filtered pressure, MPa (NaN before the first sample).
    filtered_mpa: f32,
    /// Samples used since construction (saturating).
    updates: u32,
    /// Constants from the configuration and the period.
    forgetting: f32,
    max_step: f32,
    filter_gain: f32,
    max_pressure_step_mpa: f32,
    lo: f32,
    hi: f32,
    min_stroke_fraction: f32,
    settle_periods: u16,
}

/// What one period of adaptation did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Outcome {
    /// Frozen or no information: nothing changed.
    Held,
    /// The scale moved.
    Updated,
    /// The scale reached its bound: the muscle drifted beyond the model.
    AtBound,
}

impl Adaptation {
    /// The flashed model (`s = 1`) for a validated configuration.
    pub fn new(cfg: &AdaptationConfig, dt_s: f32) -> Adaptation {
        let filter_gain = if cfg.pressure_filter_s > 0.0 {
            clamp(dt_s / (cfg.pressure_filter_s + dt_s), 0.0, 1.0)
        } else {
            1.0
        };
        Adaptation {
            scale: 1.0,
            // A small start: the flashed model is trusted until samples say
            // otherwise.
            covariance: 1.0,
            frozen: cfg.settle_periods,
            filtered_mpa: f32::NAN,
            updates: 0,
            forgetting: 1.0 - dt_s / cfg.memory_s,
            max_step: cfg.max_rate_per_s * dt_s,
            filter_gain,
            max_pressure_step_mpa: cfg.max_pressure_rate_mpa_per_s * dt_s,
            lo: 1.0 - cfg.bound,
            hi: 1.0 + cfg.bound,
            min_stroke_fraction: cfg.min_stroke_fraction,
            settle_periods: cfg.settle_periods,
        }
    }

    /// The adapted stroke scale (1: the flashed model).
    pub fn scale(&self) -> f32 {
        self.scale
    }

    /// Samples the estimate has used.
    pub fn updates(&self) -> u32 {
        self.updates
    }

    /// Freeze for the settling time (a fault, a recovery, a load or branch
    /// switch).
    pub(super) fn freeze(&mut self) {
        self.frozen = self.settle_periods;
    }

    /// The measured contraction as the model check judges it: on a stroke
    /// shrunk to `s < 1` the flashed model's contraction `R + (x − R)/s`
    /// (the band moves with the adapted stroke and narrows with it, by `s`);
    /// at `s ≥ 1` the measured one itself (the flashed band, never wider).
    #[inline(always)]
    pub(super) fn checked_contraction(&self, model: &LoadModel, contraction: f32) -> f32 {
        if self.scale < 1.0 {
            let r = model.root_contraction();
            r + (contraction - r) / self.scale
        } else {
            contraction
        }
    }

    /// One period on checked readings while controlling. `saturated`: the
    /// last valve flow command was at its limit.
    pub(super) fn update(
        &mut self,
        model: &LoadModel,
        branch: Branch,
        pressure_mpa: f32,
        contraction: f32,
        saturated: bool,
    ) -> Outcome {
        if !(pressure_mpa.is_finite() && contraction.is_finite()) {
            return Outcome::Held;
        }
        let last = self.filtered_mpa;
        let filtered = if last.is_nan() {
            pressure_mpa
        } else {
            last + self.filter_gain * (pressure_mpa - last)
        };
        self.filtered_mpa = filtered;
        if self.frozen > 0 {
            self.frozen -= 1;
            return Outcome::Held;
        }
        // `!(a <= b)`: NaN freezes too.
        if saturated || !((filtered - last).abs() <= self.max_pressure_step_mpa) {
            return Outcome::Held;
        }
        let r = model.root_contraction();
        let stroke = model.max_contraction() - r;
        let phi = model.contraction(pressure_mpa, branch) - r;
        if !(phi >= self.min_stroke_fraction * stroke) {
            return Outcome::Held;
        }
        let y = contraction - r;
        // Scalar RLS with forgetting, the measurement noise as the unit.
        let p = (self.covariance / self.forgetting).min(MAX_COVARIANCE);
        let denominator = 1.0 + p * phi * phi;
        let gain = p * phi / denominator;
        let step = clamp(gain * (y - self.scale * phi), -self.max_step, self.max_step);
        self.covariance = p / denominator;
        self.updates = self.updates.saturating_add(1);
        let s = self.scale + step;
        if s <= self.lo || s >= self.hi {
            self.scale = clamp(s, self.lo, self.hi);
            return Outcome::AtBound;
        }
        self.scale = s;
        Outcome::Updated
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pam_core::{Coeffs, Params};

    fn model() -> LoadModel {
        Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model(300.0)
            .unwrap()
    }

    /// A muscle whose stroke is `true_scale` times the model's, sampled
    /// slowly over the stroke on both branches.
    fn run(a: &mut Adaptation, m: &LoadModel, true_scale: f32, periods: usize) -> Outcome {
        let r = m.root_contraction();
        let pmax = m.max_pressure_mpa();
        let mut last = Outcome::Held;
        for k in 0..periods {
            // A 20 s triangle over the pressure range.
            let phase = (k % 20_000) as f32 / 20_000.0;
            let (p, branch) = if phase < 0.5 {
                (pmax * 2.0 * phase, Branch::Contraction)
            } else {
                (pmax * 2.0 * (1.0 - phase), Branch::Expansion)
            };
            let x = r + true_scale * (m.contraction(p, branch) - r);
            last = a.update(m, branch, p, x, false);
            if last == Outcome::AtBound {
                return last;
            }
        }
        last
    }

    #[test]
    fn the_scale_converges_to_the_muscles_within_its_bound() {
        let m = model();
        for true_scale in [0.85f32, 0.92, 1.1] {
            let mut a = Adaptation::new(&AdaptationConfig::DEFAULT, 1e-3);
            // Five forgetting times (60 s each).
            let out = run(&mut a, &m, true_scale, 300_000);
            assert_ne!(out, Outcome::AtBound);
            assert!(
                (a.scale() - true_scale).abs() < 0.005,
                "true {true_scale}, adapted {}",
                a.scale()
            );
            assert!(a.updates() > 10_000);
        }
    }

    #[test]
    fn a_muscle_beyond_the_bound_reaches_it_and_says_so() {
        let m = model();
        let mut a = Adaptation::new(&AdaptationConfig::DEFAULT, 1e-3);
        assert_eq!(run(&mut a, &m, 0.7, 200_000), Outcome::AtBound);
        assert!((a.scale() - 0.8).abs() < 1e-6, "{}", a.scale());
    }

    #[test]
    fn the_change_per_period_is_rate_limited() {
        let m = model();
        let cfg = AdaptationConfig::DEFAULT;
        let mut a = Adaptation::new(&cfg, 1e-3);
        // 1 s of a muscle at half the model's stroke: at most 1 % moved.
        run(&mut a, &m, 0.5, 1_000 + usize::from(cfg.settle_periods));
        assert!(
            a.scale() >= 1.0 - cfg.max_rate_per_s * 1.0 - 1e-5,
            "{}",
            a.scale()
        );
    }

    #[test]
    fn frozen_while_settling_saturated_or_in_a_transient() {
        let m = model();
        let cfg = AdaptationConfig::DEFAULT;
        let mut a = Adaptation::new(&cfg, 1e-3);
        let p = 0.3;
        let x = 0.5 * m.contraction(p, Branch::Contraction);
        // Settling after construction.
        for _ in 0..cfg.settle_periods {
            assert_eq!(
                a.update(&m, Branch::Contraction, p, x, false),
                Outcome::Held
            );
        }
        assert_eq!(a.update(&m, Branch::Contraction, p, x, true), Outcome::Held);
        // A pressure step is a transient.
        assert_eq!(
            a.update(&m, Branch::Contraction, p + 0.1, x, false),
            Outcome::Held
        );
        a.freeze();
        for _ in 0..cfg.settle_periods {
            assert_eq!(
                a.update(&m, Branch::Contraction, p, x, false),
                Outcome::Held
            );
        }
        // NaN readings never update.
        let mut b = Adaptation::new(
            &AdaptationConfig {
                settle_periods: 0,
                ..cfg
            },
            1e-3,
        );
        assert_eq!(
            b.update(&m, Branch::Contraction, p, f32::NAN, false),
            Outcome::Held
        );
        assert_eq!(
            b.update(&m, Branch::Contraction, f32::NAN, x, false),
            Outcome::Held
        );
        assert_eq!(b.scale(), 1.0);
        assert_eq!(a.scale(), 1.0);
    }

    #[test]
    fn the_settings_are_checked() {
        let d = AdaptationConfig::DEFAULT;
        assert!(d.is_valid(1e-3));
        for bad in [
            AdaptationConfig { bound: 0.0, ..d },
            AdaptationConfig { bound: 0.6, ..d },
            AdaptationConfig {
                memory_s: 0.005,
                ..d
            },
            AdaptationConfig {
                max_rate_per_s: f32::NAN,
                ..d
            },
            AdaptationConfig {
                min_stroke_fraction: 1.0,
                ..d
            },
            AdaptationConfig {
                max_pressure_rate_mpa_per_s: 0.0,
                ..d
            },
            AdaptationConfig {
                pressure_filter_s: -1.0,
                ..d
            },
        ] {
            assert!(!bad.is_valid(1e-3), "{bad:?}");
        }
    }
}

//! Extensions of the paper's model, each a physically meaningful effect with
//! its own parameters; [`crate::Simulator`] runs the paper's model with any
//! of them from measured `(t_s, pressure_mpa, load_n)` samples.
//!
//! | effect | what it adds | parameters |
//! |---|---|---|
//! | [`NonLocalMemory`] | minor loops closing at the previous reversal, with wiping-out | `shape`, `merge_span` |
//! | [`RateDependence`] | ellipse height grows with a power of the pressure rate, saturating at a rate | `scale_at_rest`, `scale_per_mpa_per_s`, `exponent`, `filter_time_s`, `max_rate_mpa_per_s` |
//! | [`Creep`] | slow first-order relaxation after pressure steps | `gain`, `time_constant_s` |
//! | [`LoadDependentWidth`] | ellipse height linear in load | `scale_at_min_load`, `scale_per_step` |
//! | [`PressureLag`] | the muscle's pressure a first-order lag of the measured one | `time_constant_s` |
//! | [`PressureDelay`] | the muscle's pressure the measured one a fixed time earlier (applied by a record's driver: see its module) | `delay_s` |
//! | [`ConstraintShape`] | a static curve outside the cubic family: a monotone correction along each load's stroke, both branches alike, and its ends moved with load | `bulge`, `tilt` (and per load step), `root_shift`, `end_shift` (and per load step, per squared load step) |
//!
//! All are `no_std`, allocation-free, and panic-free per sample; the memory
//! holds at most `N` reversal points (a const generic).
//!
//! ```
//! use pam_core::effects::{Effects, NonLocalMemory};
//! use pam_core::{Coeffs, Params, Simulator, TrackerConfig};
//!
//! let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
//! let effects = Effects {
//!     memory: Some(NonLocalMemory::with_shape(1.0)),
//!     ..Effects::NONE
//! };
//! let mut sim = Simulator::<16>::new(coeffs, effects, TrackerConfig::DEFAULT_PRESSURE, 100.0).unwrap();
//! // Up to 0.3 MPa, then back: no jump at the reversal.
//! let mut x = 0.0;
//! for k in 0..=300 {
//!     x = sim.step(k as f32 * 0.02, k as f32 * 0.001, 100.0);
//! }
//! let mut after = x;
//! for k in 1..=10 {
//!     after = sim.step((300 + k) as f32 * 0.02, 0.3 - k as f32 * 0.001, 100.0);
//! }
//! assert!((after - x).abs() < 0.005);
//! ```

pub mod creep;
pub mod first_order;
pub mod memory;
pub mod offset;
pub mod pressure_delay;
pub mod pressure_lag;
pub mod rate;
pub mod shape;
pub mod width;

pub use creep::{Creep, CreepState};
pub use first_order::first_order_gain;
pub use memory::{NonLocalMemory, Reversal, ReversalStack};
pub use offset::{
    branch_contraction, branch_contraction_near, MAX_OFFSET_SCALE, SCALED_INVERSE_STEPS,
};
pub use pressure_delay::PressureDelay;
pub use pressure_lag::{PressureLag, PressureLagState};
pub use rate::{RateDependence, RateFilter, RateState};
pub use shape::{ConstraintShape, ShapeInverse, StrokeTable};
pub use width::LoadDependentWidth;

use crate::error::Error;

/// Largest sample interval the time-dependent effects integrate over, s; a
/// longer gap (or a non-finite or backwards time) holds their state.
pub const MAX_STEP_S: f32 = 1.0;

/// Which effects a [`crate::Simulator`] runs, with their parameters (`None`: off).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Effects {
    /// Minor loops with wiping-out.
    pub memory: Option<NonLocalMemory>,
    /// Ellipse height growing with the pressure rate.
    pub rate: Option<RateDependence>,
    /// Slow relaxation after pressure steps.
    pub creep: Option<Creep>,
    /// Ellipse height linear in load.
    pub width: Option<LoadDependentWidth>,
    /// A correction of the static curve along the stroke.
    pub shape: Option<ConstraintShape>,
    /// The muscle's pressure lagging the measured one (absent from the
    /// model files written before it: off).
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub pressure_lag: Option<PressureLag>,
    /// The muscle's pressure the measured one a fixed time earlier (absent
    /// from the model files written before it: off).
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub pressure_delay: Option<PressureDelay>,
}

impl Effects {
    /// The paper's model alone.
    pub const NONE: Effects = Effects {
        memory: None,
        rate: None,
        creep: None,
        width: None,
        shape: None,
        pressure_lag: None,
        pressure_delay: None,
    };

    /// Validate every effect that is on.
    pub fn validate(&self) -> Result<(), Error> {
        if let Some(m) = &self.memory {
            m.validate()?;
        }
        if let Some(r) = &self.rate {
            r.validate()?;
        }
        if let Some(c) = &self.creep {
            c.validate()?;
        }
        if let Some(w) = &self.width {
            w.validate()?;
        }
        if let Some(s) = &self.shape {
            s.validate()?;
        }
        if let Some(l) = &self.pressure_lag {
            l.validate()?;
        }
        if let Some(d) = &self.pressure_delay {
            d.validate()?;
        }
        Ok(())
    }
}

//! Load-dependent loop width: the ellipse height of eq. (24) varies linearly
//! with load (the paper fixes one `be` for every load).
//!
//! The effect yields a factor on the ellipse offset, applied by
//! [`super::offset::branch_contraction`]:
//! `be(L) = be · (scale_at_min_load + scale_per_step · (L − L_min)/ΔL)`.

use crate::error::Error;
use crate::math::clamp;
use crate::params::Params;

use super::offset::MAX_OFFSET_SCALE;

/// Parameters of the load-dependent loop width.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoadDependentWidth {
    /// Factor on `be` at the minimum calibrated load (1 = the paper's height).
    pub scale_at_min_load: f32,
    /// Change of the factor per load step `ΔL` (`Params::load_step_n`).
    pub scale_per_step: f32,
}

impl LoadDependentWidth {
    /// No effect: the paper's fixed height at every load.
    pub const NEUTRAL: LoadDependentWidth = LoadDependentWidth {
        scale_at_min_load: 1.0,
        scale_per_step: 0.0,
    };

    /// Finite; the factor at the minimum load within `[0, MAX_OFFSET_SCALE]`;
    /// the slope within `±MAX_OFFSET_SCALE` per step.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.scale_at_min_load.is_finite() {
            return Err(Error::NonFinite("width.scale_at_min_load"));
        }
        if !self.scale_per_step.is_finite() {
            return Err(Error::NonFinite("width.scale_per_step"));
        }
        if !(self.scale_at_min_load >= 0.0 && self.scale_at_min_load <= MAX_OFFSET_SCALE) {
            return Err(Error::OutOfRange(
                "width.scale_at_min_load",
                "must be in [0, MAX_OFFSET_SCALE]",
            ));
        }
        if !(self.scale_per_step.abs() <= MAX_OFFSET_SCALE) {
            return Err(Error::OutOfRange(
                "width.scale_per_step",
                "must be within +-MAX_OFFSET_SCALE",
            ));
        }
        Ok(())
    }

    /// Factor on the ellipse offset at `load_n`.
    ///
    /// Clamped to `[0, MAX_OFFSET_SCALE]`: a negative height would swap the
    /// branches, and a loop taller than that is outside any calibration.
    /// A non-finite load gives the factor at the minimum load.
    pub fn scale(&self, params: &Params, load_n: f32) -> f32 {
        let steps = (load_n - params.min_load_n) / params.load_step_n;
        let steps = if steps.is_finite() { steps } else { 0.0 };
        clamp(
            self.scale_at_min_load + self.scale_per_step * steps,
            0.0,
            MAX_OFFSET_SCALE,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_in_load_steps_and_clamped() {
        let w = LoadDependentWidth {
            scale_at_min_load: 1.0,
            scale_per_step: 0.5,
        };
        let p = Params::DEFAULT;
        assert_eq!(w.scale(&p, 100.0), 1.0);
        assert_eq!(w.scale(&p, 300.0), 2.0);
        assert_eq!(w.scale(&p, 1e9), MAX_OFFSET_SCALE);
        assert_eq!(w.scale(&p, f32::NAN), 1.0);
        let shrink = LoadDependentWidth {
            scale_at_min_load: 0.5,
            scale_per_step: -0.5,
        };
        assert_eq!(shrink.scale(&p, 600.0), 0.0);
    }

    #[test]
    fn validation_names_the_field() {
        let mut w = LoadDependentWidth::NEUTRAL;
        assert_eq!(w.validate(), Ok(()));
        w.scale_per_step = f32::NAN;
        assert_eq!(w.validate(), Err(Error::NonFinite("width.scale_per_step")));
        w.scale_per_step = 0.0;
        w.scale_at_min_load = -1.0;
        assert!(matches!(
            w.validate(),
            Err(Error::OutOfRange("width.scale_at_min_load", _))
        ));
    }
}

//! Rate dependence: the loop widens with the pressure rate (a viscous
//! contribution the paper's rate-independent ellipse lacks).
//!
//! `be(ṗ) = be · (scale_at_rest + scale_per_mpa_per_s · |ṗ|)`, where `ṗ` is the
//! pressure rate through a first-order low-pass of [`RATE_FILTER_TIME_S`]
//! (the raw difference of a 50 Hz signal with 0.001 MPa noise is ±0.07 MPa/s
//! of noise; the filter brings it to about ±0.01 MPa/s).

use crate::error::Error;
use crate::math::clamp;

use super::MAX_OFFSET_SCALE;

/// Time constant of the pressure-rate filter, s.
pub const RATE_FILTER_TIME_S: f32 = 0.3;

/// Largest pressure rate the filter accepts, MPa/s: a step is seen as this
/// rate, so that one sample of a valve jump cannot swamp the filter state.
pub const MAX_RATE_MPA_PER_S: f32 = 5.0;

/// Parameters of the rate dependence.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RateDependence {
    /// Factor on `be` when the pressure is held.
    pub scale_at_rest: f32,
    /// Growth of the factor per MPa/s of pressure rate.
    pub scale_per_mpa_per_s: f32,
}

/// Filter state of [`RateDependence`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RateState {
    /// Filtered pressure rate, MPa/s.
    rate_mpa_per_s: f32,
    /// Previous pressure, MPa; None before the first finite sample.
    last_pressure_mpa: Option<f32>,
}

impl RateDependence {
    /// No effect.
    pub const NEUTRAL: RateDependence = RateDependence {
        scale_at_rest: 1.0,
        scale_per_mpa_per_s: 0.0,
    };

    /// Finite; factor at rest in `[0, MAX_OFFSET_SCALE]`; growth in
    /// `[0, 100]` per MPa/s (a loop cannot narrow with speed in this model).
    pub fn validate(&self) -> Result<(), Error> {
        if !self.scale_at_rest.is_finite() {
            return Err(Error::NonFinite("rate.scale_at_rest"));
        }
        if !self.scale_per_mpa_per_s.is_finite() {
            return Err(Error::NonFinite("rate.scale_per_mpa_per_s"));
        }
        if !(self.scale_at_rest >= 0.0 && self.scale_at_rest <= MAX_OFFSET_SCALE) {
            return Err(Error::OutOfRange(
                "rate.scale_at_rest",
                "must be in [0, MAX_OFFSET_SCALE]",
            ));
        }
        if !(self.scale_per_mpa_per_s >= 0.0 && self.scale_per_mpa_per_s <= 100.0) {
            return Err(Error::OutOfRange(
                "rate.scale_per_mpa_per_s",
                "must be in [0, 100] per MPa/s",
            ));
        }
        Ok(())
    }

    /// Factor on the ellipse offset for the filtered rate in `state`,
    /// clamped to `[0, MAX_OFFSET_SCALE]`.
    pub fn scale(&self, state: &RateState) -> f32 {
        clamp(
            self.scale_at_rest + self.scale_per_mpa_per_s * state.rate_mpa_per_s.abs(),
            0.0,
            MAX_OFFSET_SCALE,
        )
    }
}

impl RateState {
    /// Filtered pressure rate, MPa/s.
    pub fn rate_mpa_per_s(&self) -> f32 {
        self.rate_mpa_per_s
    }

    /// Feed a pressure sample `dt_s` after the previous one. A non-finite
    /// pressure, or a `dt_s` that is not in `(0, 1]` s, leaves the state as
    /// it was (the rate is held rather than guessed).
    pub fn update(&mut self, pressure_mpa: f32, dt_s: f32) {
        if !pressure_mpa.is_finite() {
            return;
        }
        let Some(last) = self.last_pressure_mpa else {
            self.last_pressure_mpa = Some(pressure_mpa);
            return;
        };
        if !(dt_s > 0.0 && dt_s <= 1.0) {
            self.last_pressure_mpa = Some(pressure_mpa);
            return;
        }
        let raw = clamp(
            (pressure_mpa - last) / dt_s,
            -MAX_RATE_MPA_PER_S,
            MAX_RATE_MPA_PER_S,
        );
        // Exact first-order hold discretisation would need exp(); dt ≪ τ at
        // the rates this runs at, where dt/(τ + dt) is within 1 % of it.
        let alpha = dt_s / (RATE_FILTER_TIME_S + dt_s);
        self.rate_mpa_per_s += alpha * (raw - self.rate_mpa_per_s);
        self.last_pressure_mpa = Some(pressure_mpa);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filtered_rate_settles_on_a_ramp() {
        let mut s = RateState::default();
        for k in 0..500 {
            s.update(0.1 * k as f32 * 0.02, 0.02);
        }
        assert!((s.rate_mpa_per_s() - 0.1).abs() < 1e-3, "{s:?}");
        let r = RateDependence {
            scale_at_rest: 1.0,
            scale_per_mpa_per_s: 10.0,
        };
        assert!((r.scale(&s) - 2.0).abs() < 0.01);
    }

    #[test]
    fn bad_samples_are_ignored() {
        let mut s = RateState::default();
        s.update(0.1, 0.02);
        s.update(f32::NAN, 0.02);
        s.update(0.2, f32::NAN);
        s.update(0.3, -1.0);
        assert_eq!(s.rate_mpa_per_s(), 0.0);
        s.update(1e30, 0.02);
        assert!(s.rate_mpa_per_s() <= MAX_RATE_MPA_PER_S);
    }

    #[test]
    fn validation() {
        assert_eq!(RateDependence::NEUTRAL.validate(), Ok(()));
        let bad = RateDependence {
            scale_at_rest: 1.0,
            scale_per_mpa_per_s: -1.0,
        };
        assert!(bad.validate().is_err());
    }
}

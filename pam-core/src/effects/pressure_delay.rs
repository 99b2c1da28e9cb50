//! Pressure delay: the muscle answers the measured pressure a fixed time
//! later, `p_muscle(t) = p_measured(t − d)`.
//!
//! Where [`super::PressureLag`] smooths the measured pressure (a volume
//! behind a line), a delay shifts it whole: a sensor sampled ahead of the
//! load cell, a load cell's filter with a fixed group delay, a line's
//! transport time. On the public Festo 10 mm records the force follows the
//! pressure a few milliseconds late, and a shift fits there where a lag of
//! the same size does not (pam-lab's README, "Real muscles").
//!
//! A delay needs the pressure's history, which a stream of samples does not
//! keep: a record's driver steps the [`crate::Simulator`] with the pressure
//! measured `delay_s` earlier (pam-lab's record simulator), and predicts a
//! measured pressure as the muscle's `delay_s` later.
//!
//! The feedforward leads the command by the delay: it commands now what
//! the muscle needs `delay_s` later. It has no future set-point, so it
//! leads by the first-order term, the closed form a lag of the same time
//! constant takes ([`super::PressureLag::command_mpa`]: `p + d·ṗ` on a
//! ramp); on a set-point smooth over the delay the two agree to second
//! order in the delay ([`PressureDelay::lead_time_constant_s`]).

use crate::error::Error;

/// Parameters of the pressure delay.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressureDelay {
    /// How much later the muscle answers the measured pressure, s, in
    /// `[0.0005, 0.1]`.
    pub delay_s: f32,
}

impl PressureDelay {
    /// Shortest delay, s: half a millisecond, half a sample of a fast rig.
    pub const MIN_DELAY_S: f32 = 0.0005;
    /// Longest delay, s: a tenth of a second, beyond any line or filter.
    pub const MAX_DELAY_S: f32 = 0.1;

    /// Finite, in `[0.0005, 0.1]` s.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.delay_s.is_finite() {
            return Err(Error::NonFinite("pressure_delay.delay_s"));
        }
        if !(self.delay_s >= Self::MIN_DELAY_S && self.delay_s <= Self::MAX_DELAY_S) {
            return Err(Error::OutOfRange(
                "pressure_delay.delay_s",
                "must be in [0.0005, 0.1] s",
            ));
        }
        Ok(())
    }

    /// The time constant of the first-order lead the feedforward gives the
    /// delay: the delay itself (`e^(−s·d)` and `1/(1 + s·d)` agree to first
    /// order in `s·d`).
    pub fn lead_time_constant_s(&self) -> f32 {
        self.delay_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation() {
        let mut d = PressureDelay { delay_s: 0.006 };
        assert_eq!(d.validate(), Ok(()));
        d.delay_s = 0.0;
        assert!(d.validate().is_err());
        d.delay_s = 0.2;
        assert!(d.validate().is_err());
        d.delay_s = f32::NAN;
        assert_eq!(
            d.validate(),
            Err(Error::NonFinite("pressure_delay.delay_s"))
        );
    }
}

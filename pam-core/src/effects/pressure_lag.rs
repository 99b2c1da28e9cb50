//! Pressure lag: the muscle's own pressure follows the measured pressure
//! through a first-order lag (the tube and the bladder's volume behind the
//! sensor, or the sensor's filter ahead of the force), and the model runs
//! on the muscle's pressure: `τ·ṗ_muscle = p_measured − p_muscle`.
//!
//! Unlike creep (a slow part of the contraction, seconds after a step) it
//! lags the pressure alone, not the load, and it is fast: on the public
//! Festo records the force answers the pressure measured some 10–20 ms
//! earlier.
//!
//! The feedforward inverts it in closed form: the pressure to command so
//! that the lag's next output is the pressure the model needs
//! ([`PressureLag::command_mpa`]).

use crate::error::Error;

/// Parameters of the pressure lag.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressureLag {
    /// Time constant of the lag, s, in `[0.001, 0.5]`.
    pub time_constant_s: f32,
}

/// State of the lag: the muscle's pressure, MPa.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PressureLagState {
    lagged: Option<f32>,
}

impl PressureLag {
    /// Shortest time constant, s: a millisecond, a sample of a fast rig.
    pub const MIN_TIME_CONSTANT_S: f32 = 0.001;
    /// Longest time constant, s: a slower answer than this is creep or a
    /// valve's own dynamics, not a line's.
    pub const MAX_TIME_CONSTANT_S: f32 = 0.5;

    /// Finite, time constant in `[0.001, 0.5]` s.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.time_constant_s.is_finite() {
            return Err(Error::NonFinite("pressure_lag.time_constant_s"));
        }
        if !(self.time_constant_s >= Self::MIN_TIME_CONSTANT_S
            && self.time_constant_s <= Self::MAX_TIME_CONSTANT_S)
        {
            return Err(Error::OutOfRange(
                "pressure_lag.time_constant_s",
                "must be in [0.001, 0.5] s",
            ));
        }
        Ok(())
    }

    /// The lag's gain over one step of `dt_s`: `1 − e^(−dt/τ)`, the exact
    /// zero-order-hold step; 0 (the lag held) for a `dt_s` outside
    /// `(0, 10]` s. A controller with a fixed period computes it once.
    pub fn lag_gain(&self, dt_s: f32) -> f32 {
        super::first_order::first_order_gain(dt_s, self.time_constant_s)
    }

    /// Advance by `dt_s` with the measured pressure `pressure_mpa` and
    /// return the muscle's pressure. The first finite sample initialises
    /// the lag; a non-finite pressure returns the lagged value and leaves
    /// the state as it was.
    pub fn step(&self, state: &mut PressureLagState, pressure_mpa: f32, dt_s: f32) -> f32 {
        self.advance(state, pressure_mpa, self.lag_gain(dt_s))
    }

    /// [`Self::step`] with the lag's gain given ([`Self::lag_gain`]).
    pub fn advance(&self, state: &mut PressureLagState, pressure_mpa: f32, lag_gain: f32) -> f32 {
        if !pressure_mpa.is_finite() {
            return state.lagged.unwrap_or(0.0);
        }
        let y = match state.lagged {
            None => pressure_mpa,
            Some(y) => y + lag_gain * (pressure_mpa - y),
        };
        state.lagged = Some(y);
        y
    }

    /// The inverse of [`Self::advance`] for a feedforward: the pressure to
    /// command, within `[0, max_mpa]`, that brings the muscle's pressure to
    /// `muscle_mpa` on this step (as near as the bound allows), and the
    /// lag advanced with it. Closed form: the output is `y + k·(u − y)`
    /// for the command `u`, lag `y` and lag gain `k`, so `u = y + (p − y)/k`.
    /// A lag gain of 0 (no time step) or the first call commands the
    /// muscle's pressure itself. Never NaN for finite `muscle_mpa` and
    /// `max_mpa ≥ 0`.
    pub fn command_mpa(
        &self,
        state: &mut PressureLagState,
        muscle_mpa: f32,
        lag_gain: f32,
        max_mpa: f32,
    ) -> f32 {
        let u = match state.lagged {
            Some(y) if lag_gain > 0.0 => y + (muscle_mpa - y) / lag_gain,
            _ => muscle_mpa,
        };
        let u = if u.is_finite() {
            u.max(0.0).min(max_mpa)
        } else {
            muscle_mpa
        };
        self.advance(state, u, lag_gain);
        u
    }
}

impl PressureLagState {
    /// The muscle's pressure, if initialised.
    pub fn lagged(&self) -> Option<f32> {
        self.lagged
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_reaches_the_muscle_in_one_time_constant_to_63_percent() {
        let l = PressureLag {
            time_constant_s: 0.02,
        };
        let mut s = PressureLagState::default();
        assert_eq!(l.step(&mut s, 0.1, 0.001), 0.1);
        let mut p = 0.0;
        for _ in 0..20 {
            p = l.step(&mut s, 0.3, 0.001);
        }
        let want = 0.1 + 0.2 * (1.0 - (-1.0f32).exp());
        assert!((p - want).abs() < 1e-5, "{p} vs {want}");
    }

    #[test]
    fn the_command_brings_the_muscle_where_the_model_needs_it() {
        let l = PressureLag {
            time_constant_s: 0.015,
        };
        let k = l.lag_gain(0.001);
        let mut s = PressureLagState::default();
        assert_eq!(l.command_mpa(&mut s, 0.2, k, 0.6), 0.2);
        // A slow ramp is led by about τ times its rate.
        let mut u = 0.0;
        for i in 1..=200 {
            let want = 0.2 + 0.5 * i as f32 * 0.001;
            u = l.command_mpa(&mut s, want, k, 0.6);
            assert!((s.lagged().unwrap() - want).abs() < 1e-5);
        }
        let lead = u - 0.3;
        assert!((lead - 0.5 * 0.015).abs() < 0.001, "lead {lead}");
        // A step beyond the valve: commanded at the bound, the muscle on
        // its way.
        let u = l.command_mpa(&mut s, 0.59, k, 0.6);
        assert_eq!(u, 0.6);
        assert!(s.lagged().unwrap() < 0.59);
    }

    #[test]
    fn bad_inputs_hold_state() {
        let l = PressureLag {
            time_constant_s: 0.01,
        };
        let mut s = PressureLagState::default();
        assert_eq!(l.step(&mut s, f32::NAN, 0.001), 0.0);
        l.step(&mut s, 0.2, 0.001);
        let y = s.lagged();
        assert_eq!(l.step(&mut s, 0.4, f32::INFINITY), 0.2);
        assert_eq!(s.lagged(), y);
        assert!(l.command_mpa(&mut s, f32::NAN, 0.1, 0.6).is_nan());
    }

    #[test]
    fn validation() {
        let mut l = PressureLag {
            time_constant_s: 0.015,
        };
        assert_eq!(l.validate(), Ok(()));
        l.time_constant_s = 0.0;
        assert!(l.validate().is_err());
        l.time_constant_s = 1.0;
        assert!(l.validate().is_err());
        l.time_constant_s = f32::NAN;
        assert_eq!(
            l.validate(),
            Err(Error::NonFinite("pressure_lag.time_constant_s"))
        );
    }
}

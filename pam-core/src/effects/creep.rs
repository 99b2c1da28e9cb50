//! Creep: after a pressure step the contraction keeps relaxing for seconds
//! towards the static value (a slow visco-elastic element in series with the
//! rate-independent model).
//!
//! A fraction `gain` of the static contraction reaches the output through a
//! first-order lag of `time_constant_s`; the rest arrives at once:
//! `x = (1 − g)·x_static + g·y`, `τ·ẏ = x_static − y`.

use crate::error::Error;

/// Parameters of the creep element.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Creep {
    /// Fraction of a contraction change that arrives slowly, in `[0, 0.95]`.
    pub gain: f32,
    /// Time constant of the slow part, s, in `[0.02, 100]`.
    pub time_constant_s: f32,
}

/// State of the creep element: the lagged contraction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CreepState {
    lagged: Option<f32>,
}

impl Creep {
    /// Finite, gain in `[0, 0.95]` (all-slow would be a pure lag, not creep),
    /// time constant in `[0.02, 100]` s.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.gain.is_finite() {
            return Err(Error::NonFinite("creep.gain"));
        }
        if !self.time_constant_s.is_finite() {
            return Err(Error::NonFinite("creep.time_constant_s"));
        }
        if !(self.gain >= 0.0 && self.gain <= 0.95) {
            return Err(Error::OutOfRange("creep.gain", "must be in [0, 0.95]"));
        }
        if !(self.time_constant_s >= 0.02 && self.time_constant_s <= 100.0) {
            return Err(Error::OutOfRange(
                "creep.time_constant_s",
                "must be in [0.02, 100] s",
            ));
        }
        Ok(())
    }

    /// Advance by `dt_s` with the static contraction `static_contraction` and
    /// return the crept contraction.
    ///
    /// The first finite sample initialises the lag (no creep at start). A
    /// `dt_s` outside `(0, 10]` s holds the lag; a non-finite static value
    /// is returned unchanged by the lag and leaves the state as it was.
    pub fn step(&self, state: &mut CreepState, static_contraction: f32, dt_s: f32) -> f32 {
        if !static_contraction.is_finite() {
            return state.lagged.unwrap_or(0.0);
        }
        let y = match state.lagged {
            None => static_contraction,
            Some(y) if dt_s > 0.0 && dt_s <= 10.0 => {
                // Exact zero-order-hold step of τ·ẏ = u − y.
                let k = 1.0 - libm::expf(-dt_s / self.time_constant_s);
                y + k * (static_contraction - y)
            }
            Some(y) => y,
        };
        state.lagged = Some(y);
        (1.0 - self.gain) * static_contraction + self.gain * y
    }
}

impl CreepState {
    /// The lagged contraction, if initialised.
    pub fn lagged(&self) -> Option<f32> {
        self.lagged
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_response_is_first_order() {
        let c = Creep {
            gain: 0.4,
            time_constant_s: 2.0,
        };
        let mut s = CreepState::default();
        assert!((c.step(&mut s, 0.1, 0.02) - 0.1).abs() < 1e-7);
        // Step to 0.2: 60 % at once, the rest with τ = 2 s.
        let first = c.step(&mut s, 0.2, 0.02);
        assert!((first - (0.1 + 0.1 * (0.6 + 0.4 * (1.0 - (-0.01f32).exp())))).abs() < 1e-6);
        let mut x = first;
        for _ in 1..100 {
            x = c.step(&mut s, 0.2, 0.02);
        }
        // After 2 s (one τ): 1 − 0.4·e⁻¹ of the step.
        let want = 0.1 + 0.1 * (1.0 - 0.4 * (-1.0f32).exp());
        assert!((x - want).abs() < 1e-4, "{x} vs {want}");
    }

    #[test]
    fn bad_inputs_hold_state() {
        let c = Creep {
            gain: 0.5,
            time_constant_s: 1.0,
        };
        let mut s = CreepState::default();
        assert_eq!(c.step(&mut s, f32::NAN, 0.02), 0.0);
        c.step(&mut s, 0.1, 0.02);
        let y = s.lagged();
        c.step(&mut s, 0.3, f32::INFINITY);
        assert_eq!(s.lagged(), y);
        assert!(c.step(&mut s, f32::NAN, 0.02).is_finite());
    }

    #[test]
    fn validation() {
        let mut c = Creep {
            gain: 0.3,
            time_constant_s: 2.0,
        };
        assert_eq!(c.validate(), Ok(()));
        c.gain = 1.0;
        assert!(c.validate().is_err());
        c.gain = 0.3;
        c.time_constant_s = f32::NAN;
        assert_eq!(c.validate(), Err(Error::NonFinite("creep.time_constant_s")));
    }
}

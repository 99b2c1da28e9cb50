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
        self.advance(state, static_contraction, self.lag_gain(dt_s))
    }

    /// The lag's gain over one step of `dt_s`: `1 − e^(−dt/τ)`, the exact
    /// zero-order-hold step of `τ·ẏ = u − y`; 0 (the lag held) for a `dt_s`
    /// outside `(0, 10]` s. A controller with a fixed period computes it once.
    pub fn lag_gain(&self, dt_s: f32) -> f32 {
        super::first_order::first_order_gain(dt_s, self.time_constant_s)
    }

    /// [`Self::step`] with the lag's gain given ([`Self::lag_gain`]).
    pub fn advance(&self, state: &mut CreepState, static_contraction: f32, lag_gain: f32) -> f32 {
        if !static_contraction.is_finite() {
            return state.lagged.unwrap_or(0.0);
        }
        let y = match state.lagged {
            None => static_contraction,
            Some(y) => y + lag_gain * (static_contraction - y),
        };
        state.lagged = Some(y);
        (1.0 - self.gain) * static_contraction + self.gain * y
    }

    /// The inverse of [`Self::advance`] for a feedforward: the static
    /// contraction that makes the next output `contraction`, from the lag
    /// state (not changed; advance it with the result, clamped as the
    /// caller's model clamps it). Closed form: the output is
    /// `(1 − g·(1 − k))·u + g·(1 − k)·y` for the input `u`, lag `y`, gain
    /// `g` and lag gain `k`, and `1 − g·(1 − k) ≥ 1 − 0.95` for a validated
    /// gain. Before the first sample the output is the input. A non-finite
    /// `contraction` is returned as it is (the caller clamps it).
    pub fn static_contraction(&self, state: &CreepState, contraction: f32, lag_gain: f32) -> f32 {
        match state.lagged {
            None => contraction,
            Some(y) => {
                let slow = self.gain * (1.0 - lag_gain);
                (contraction - slow * y) / (1.0 - slow)
            }
        }
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
    fn static_contraction_inverts_advance() {
        let c = Creep {
            gain: 0.8,
            time_constant_s: 0.5,
        };
        let k = c.lag_gain(0.01);
        let mut s = CreepState::default();
        assert_eq!(c.static_contraction(&s, 0.12, k), 0.12);
        c.advance(&mut s, 0.1, k);
        for want in [0.15f32, 0.2, 0.05, 0.05, 0.3] {
            let u = c.static_contraction(&s, want, k);
            let mut trial = s;
            let got = c.advance(&mut trial, u, k);
            assert!((got - want).abs() < 1e-6, "{got} vs {want}");
            s = trial;
        }
        assert_eq!(c.lag_gain(f32::NAN), 0.0);
        assert_eq!(c.lag_gain(11.0), 0.0);
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

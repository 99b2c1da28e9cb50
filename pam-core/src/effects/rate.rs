//! Rate dependence: the loop widens with the pressure rate (a viscous
//! contribution the paper's rate-independent ellipse lacks).
//!
//! `be(ṗ) = be · (scale_at_rest + scale_per_mpa_per_s · (min(|ṗ|, ṗ_max)/ṗ_ref)^n)`,
//! `ṗ_ref` = 1 MPa/s, where `ṗ` is the pressure rate through a first-order
//! low-pass of time constant `filter_time_s` and `ṗ_max` is
//! `max_rate_mpa_per_s`, the rate where the law saturates. A pressure step
//! is a rate far above any ramp; without the saturation the loop would
//! blow up at every step. The filter's state saturates there too: a step
//! takes it to `ṗ_max` at once, and it relaxes from there as after a
//! ramp at `ṗ_max` that ends, so the loop is back at rest as soon after a
//! step as after a ramp's end (with only the law saturated, the filtered
//! rate of a step stayed above `ṗ_max`, and the loop at its widest, for a
//! few filter times after every step). A fit sets `ṗ_max` to the fastest
//! ramp its data shows, so the law never widens a loop beyond what was
//! measured. The filter's default time constant is
//! [`RATE_FILTER_TIME_S`]: the raw difference of a 50 Hz signal with
//! 0.001 MPa noise is ±0.07 MPa/s of noise; 0.3 s brings it to about
//! ±0.01 MPa/s.
//!
//! The exponent `n` is the power law of rate-dependent friction (rubber and
//! braid friction is commonly sub-linear in the sliding rate, `n < 1`);
//! `n = 1` is the linear law. Cost per sample: `n` = 1, 0.5 and 0.75 take
//! no, one and two square roots (`vsqrt` on the M4F, 14 cycles each); any
//! other `n` takes pam-core's own power (`math::powf`: within
//! 2·10⁻⁶ of the exact power on the law's rates, 115 instructions on the
//! M4F against `libm::powf`'s 241, bench-m4).

use crate::error::Error;
use crate::math::{clamp, sqrt};

use super::offset::MAX_OFFSET_SCALE;

/// Time constant of the pressure-rate filter, s.
pub const RATE_FILTER_TIME_S: f32 = 0.3;

/// Range of the rate exponent `n`.
pub const RATE_EXPONENT_RANGE: (f32, f32) = (0.3, 1.5);

/// Longest filter time constant, s.
pub const MAX_RATE_FILTER_TIME_S: f32 = 10.0;

/// Largest pressure rate the filter accepts, MPa/s (a step is seen as this
/// rate, so that one sample of a valve jump cannot swamp the filter state),
/// and the largest `ṗ_max`.
pub const MAX_RATE_MPA_PER_S: f32 = 5.0;

/// Parameters of the rate dependence.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RateDependence {
    /// Factor on `be` when the pressure is held.
    pub scale_at_rest: f32,
    /// Growth of the factor at a pressure rate of 1 MPa/s (per MPa/s when
    /// `exponent` is 1).
    pub scale_per_mpa_per_s: f32,
    /// Power `n` of the rate law, in [`RATE_EXPONENT_RANGE`]; 1 is linear.
    pub exponent: f32,
    /// Time constant of the pressure-rate filter, s, in
    /// `[0, MAX_RATE_FILTER_TIME_S]` (0: the raw difference).
    pub filter_time_s: f32,
    /// Filtered rate above which the factor stops growing, MPa/s, in
    /// `(0, MAX_RATE_MPA_PER_S]`: the law is bounded by its value here.
    pub max_rate_mpa_per_s: f32,
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
        exponent: 1.0,
        filter_time_s: RATE_FILTER_TIME_S,
        max_rate_mpa_per_s: MAX_RATE_MPA_PER_S,
    };

    /// The linear law (`n` = 1) with the default filter, saturating at
    /// [`MAX_RATE_MPA_PER_S`].
    pub const fn linear(scale_at_rest: f32, scale_per_mpa_per_s: f32) -> RateDependence {
        RateDependence {
            scale_at_rest,
            scale_per_mpa_per_s,
            exponent: 1.0,
            filter_time_s: RATE_FILTER_TIME_S,
            max_rate_mpa_per_s: MAX_RATE_MPA_PER_S,
        }
    }

    /// The largest factor the law gives (at or above
    /// `max_rate_mpa_per_s`), before the clamp to `MAX_OFFSET_SCALE`.
    pub fn max_scale(&self) -> f32 {
        self.scale_at_rest + self.scale_per_mpa_per_s * self.rate_term(self.max_rate_mpa_per_s)
    }

    /// Finite; factor at rest in `[0, MAX_OFFSET_SCALE]`; growth in
    /// `[0, 100]` at 1 MPa/s (a loop cannot narrow with speed in this model);
    /// exponent in [`RATE_EXPONENT_RANGE`]; filter time constant in
    /// `[0, MAX_RATE_FILTER_TIME_S]` s; saturation rate in
    /// `(0, MAX_RATE_MPA_PER_S]`.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.scale_at_rest.is_finite() {
            return Err(Error::NonFinite("rate.scale_at_rest"));
        }
        if !self.scale_per_mpa_per_s.is_finite() {
            return Err(Error::NonFinite("rate.scale_per_mpa_per_s"));
        }
        if !self.exponent.is_finite() {
            return Err(Error::NonFinite("rate.exponent"));
        }
        if !self.filter_time_s.is_finite() {
            return Err(Error::NonFinite("rate.filter_time_s"));
        }
        if !self.max_rate_mpa_per_s.is_finite() {
            return Err(Error::NonFinite("rate.max_rate_mpa_per_s"));
        }
        if !(self.max_rate_mpa_per_s > 0.0 && self.max_rate_mpa_per_s <= MAX_RATE_MPA_PER_S) {
            return Err(Error::OutOfRange(
                "rate.max_rate_mpa_per_s",
                "must be in (0, MAX_RATE_MPA_PER_S] MPa/s",
            ));
        }
        let (n_lo, n_hi) = RATE_EXPONENT_RANGE;
        if !(self.exponent >= n_lo && self.exponent <= n_hi) {
            return Err(Error::OutOfRange(
                "rate.exponent",
                "must be in RATE_EXPONENT_RANGE (0.3 to 1.5)",
            ));
        }
        if !(self.filter_time_s >= 0.0 && self.filter_time_s <= MAX_RATE_FILTER_TIME_S) {
            return Err(Error::OutOfRange(
                "rate.filter_time_s",
                "must be in [0, MAX_RATE_FILTER_TIME_S] s",
            ));
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

    /// Factor on the ellipse offset for the filtered rate in `state` (its
    /// magnitude saturated at `max_rate_mpa_per_s`), clamped to
    /// `[0, MAX_OFFSET_SCALE]`.
    pub fn scale(&self, state: &RateState) -> f32 {
        let r = state.rate_mpa_per_s.abs();
        // `min` that keeps a NaN saturation bound (refused by `validate`)
        // from passing an unbounded rate.
        let r = if r <= self.max_rate_mpa_per_s {
            r
        } else {
            self.max_rate_mpa_per_s
        };
        clamp(
            self.scale_at_rest + self.scale_per_mpa_per_s * self.rate_term(r),
            0.0,
            MAX_OFFSET_SCALE,
        )
    }

    /// `(|ṗ| / 1 MPa/s)^n`; finite and non-negative for any finite rate (the
    /// filtered rate is within `±MAX_RATE_MPA_PER_S`) and a validated `n`.
    fn rate_term(&self, rate_mpa_per_s: f32) -> f32 {
        let x = rate_mpa_per_s.abs();
        let n = self.exponent;
        if n == 1.0 {
            x
        } else if n == 0.5 {
            sqrt(x)
        } else if n == 0.75 {
            let s = sqrt(x);
            s * sqrt(s)
        } else if x > 0.0 {
            crate::math::powf(x, n)
        } else {
            0.0
        }
    }
}

impl RateState {
    /// Filtered pressure rate, MPa/s.
    pub fn rate_mpa_per_s(&self) -> f32 {
        self.rate_mpa_per_s
    }

    /// Feed a pressure sample `dt_s` after the previous one: its rate
    /// (bounded by [`MAX_RATE_MPA_PER_S`]) through a low-pass of time
    /// constant `filter_time_s` (negative or non-finite:
    /// [`RATE_FILTER_TIME_S`]) whose state saturates at
    /// `max_rate_mpa_per_s` (the law's `ṗ_max`; not in
    /// `(0, MAX_RATE_MPA_PER_S]`: [`MAX_RATE_MPA_PER_S`]). The state, not
    /// each raw difference, is bounded: a noisy ramp near `ṗ_max` reads its
    /// own rate (a raw difference of a 1 kHz signal with 0.001 MPa noise is
    /// ±1.4 MPa/s of noise, and clipping each one at 0.2 MPa/s read a
    /// 0.2 MPa/s ramp as 0.02). A non-finite pressure, or a `dt_s` that is
    /// not in `(0, 1]` s, leaves the state as it was (the rate is held
    /// rather than guessed).
    pub fn update(
        &mut self,
        pressure_mpa: f32,
        dt_s: f32,
        filter_time_s: f32,
        max_rate_mpa_per_s: f32,
    ) {
        match RateFilter::new(dt_s, filter_time_s, max_rate_mpa_per_s) {
            Some(f) => self.advance(pressure_mpa, &f),
            None => {
                if pressure_mpa.is_finite() {
                    self.last_pressure_mpa = Some(pressure_mpa);
                }
            }
        }
    }

    /// [`Self::update`] at the fixed period of `filter` (its constants made
    /// once, [`RateFilter::new`]): the same arithmetic, bit for bit.
    #[inline]
    pub fn advance(&mut self, pressure_mpa: f32, filter: &RateFilter) {
        if !pressure_mpa.is_finite() {
            return;
        }
        let Some(last) = self.last_pressure_mpa else {
            self.last_pressure_mpa = Some(pressure_mpa);
            return;
        };
        // A step is bounded as a rate first (one valve jump cannot swamp
        // the state numerically), the filter state at the law's `ṗ_max`.
        let raw = clamp(
            (pressure_mpa - last) / filter.dt_s,
            -MAX_RATE_MPA_PER_S,
            MAX_RATE_MPA_PER_S,
        );
        self.rate_mpa_per_s = clamp(
            self.rate_mpa_per_s + filter.alpha * (raw - self.rate_mpa_per_s),
            -filter.bound,
            filter.bound,
        );
        self.last_pressure_mpa = Some(pressure_mpa);
    }
}

/// The constants of [`RateState`]'s filter at a fixed period: made once
/// (by the feedforward's inverse, for a period it runs at), so that each
/// sample's update is the filter step alone ([`RateState::advance`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateFilter {
    /// The period, s, in `(0, 1]`.
    dt_s: f32,
    /// `dt/(τ + dt)`.
    alpha: f32,
    /// Where the state saturates, MPa/s.
    bound: f32,
}

impl RateFilter {
    /// The filter of time constant `filter_time_s` (negative, above
    /// [`MAX_RATE_FILTER_TIME_S`] or non-finite: [`RATE_FILTER_TIME_S`])
    /// whose state saturates at `max_rate_mpa_per_s` (not in
    /// `(0, MAX_RATE_MPA_PER_S]`: [`MAX_RATE_MPA_PER_S`]), at the period
    /// `dt_s`; `None` where `dt_s` is not in `(0, 1]` s.
    pub fn new(dt_s: f32, filter_time_s: f32, max_rate_mpa_per_s: f32) -> Option<RateFilter> {
        if !(dt_s > 0.0 && dt_s <= 1.0) {
            return None;
        }
        let bound = if max_rate_mpa_per_s > 0.0 && max_rate_mpa_per_s <= MAX_RATE_MPA_PER_S {
            max_rate_mpa_per_s
        } else {
            MAX_RATE_MPA_PER_S
        };
        // Exact first-order hold discretisation would need exp(); dt ≪ τ at
        // the rates this runs at, where dt/(τ + dt) is within 1 % of it.
        let tau = if (0.0..=MAX_RATE_FILTER_TIME_S).contains(&filter_time_s) {
            filter_time_s
        } else {
            RATE_FILTER_TIME_S
        };
        Some(RateFilter {
            dt_s,
            alpha: dt_s / (tau + dt_s),
            bound,
        })
    }

    /// The filter of the law `law` at the period `dt_s`.
    pub fn of(law: &RateDependence, dt_s: f32) -> Option<RateFilter> {
        RateFilter::new(dt_s, law.filter_time_s, law.max_rate_mpa_per_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filtered_rate_settles_on_a_ramp() {
        let mut s = RateState::default();
        for k in 0..500 {
            s.update(
                0.1 * k as f32 * 0.02,
                0.02,
                RATE_FILTER_TIME_S,
                MAX_RATE_MPA_PER_S,
            );
        }
        assert!((s.rate_mpa_per_s() - 0.1).abs() < 1e-3, "{s:?}");
        let r = RateDependence::linear(1.0, 10.0);
        assert!((r.scale(&s) - 2.0).abs() < 0.01);
    }

    #[test]
    fn exponent_gives_the_power_law() {
        let mut s = RateState::default();
        for k in 0..500 {
            s.update(
                0.2 * k as f32 * 0.02,
                0.02,
                RATE_FILTER_TIME_S,
                MAX_RATE_MPA_PER_S,
            );
        }
        let r = s.rate_mpa_per_s() as f64;
        assert!((r - 0.2).abs() < 1e-3, "{s:?}");
        for n in [0.3f32, 0.5, 0.7, 0.75, 1.0, 1.5] {
            let law = RateDependence {
                exponent: n,
                ..RateDependence::linear(1.0, 2.0)
            };
            assert_eq!(law.validate(), Ok(()));
            let want = 1.0 + 2.0 * r.powf(f64::from(n));
            let got = f64::from(law.scale(&s));
            assert!((got - want).abs() < 1e-4 * want, "n = {n}: {got} vs {want}");
        }
        // Sub-linear grows faster below 1 MPa/s: 0.2^0.5 = 0.447 > 0.2
        // (1.894 vs 1.4).
        let half = RateDependence {
            exponent: 0.5,
            ..RateDependence::linear(1.0, 2.0)
        };
        assert!(half.scale(&s) > RateDependence::linear(1.0, 2.0).scale(&s) + 0.4);
        // At rest every law gives the factor at rest, exactly.
        let rest = RateState::default();
        for n in [0.3f32, 0.5, 0.7, 0.75, 1.0, 1.5] {
            let law = RateDependence {
                exponent: n,
                ..RateDependence::linear(0.7, 2.0)
            };
            assert_eq!(law.scale(&rest), 0.7);
        }
    }

    #[test]
    fn filter_time_constant_sets_the_lag() {
        // After a step onto a ramp, the filtered rate reaches 63 % of it
        // after about one time constant.
        for tau in [0.1f32, 0.3, 1.0] {
            let mut s = RateState::default();
            let dt = 0.001;
            let steps = (tau / dt).round() as usize;
            for k in 0..=steps {
                s.update(k as f32 * dt, dt, tau, MAX_RATE_MPA_PER_S);
            }
            let r = s.rate_mpa_per_s();
            assert!((r - 0.632).abs() < 0.01, "tau = {tau}: {r}");
        }
        // tau = 0: the raw difference.
        let mut s = RateState::default();
        s.update(0.0, 0.02, 0.0, MAX_RATE_MPA_PER_S);
        s.update(0.01, 0.02, 0.0, MAX_RATE_MPA_PER_S);
        assert!((s.rate_mpa_per_s() - 0.5).abs() < 1e-6);
    }

    /// `0.6 + 2.2·|ṗ|^0.5` through a 0.05 s filter, saturating at the
    /// fastest ramp of the tests below, 0.2 MPa/s.
    fn square_root_law_saturating_at_ramps() -> RateDependence {
        RateDependence {
            exponent: 0.5,
            filter_time_s: 0.05,
            max_rate_mpa_per_s: 0.2,
            ..RateDependence::linear(0.6, 2.2)
        }
    }

    #[test]
    fn a_pressure_step_does_not_blow_the_factor_up() {
        // 100 Hz, a ramp at 0.2 MPa/s, then a 0.3 MPa step in one sample
        // (a raw rate of 30 MPa/s, bounded at 5; the filter state of the bounded
        // law at its 0.2 MPa/s saturation), then a hold.
        let dt = 0.01;
        let bounded = square_root_law_saturating_at_ramps();
        let unbounded = RateDependence {
            max_rate_mpa_per_s: MAX_RATE_MPA_PER_S,
            ..bounded
        };
        assert_eq!(bounded.validate(), Ok(()));
        let (mut s, mut su) = (RateState::default(), RateState::default());
        let mut p = 0.1f32;
        let (mut ramp_max, mut step_max, mut step_max_unbounded) = (0.0f32, 0.0f32, 0.0f32);
        for k in 0..600 {
            if k < 300 {
                p += 0.2 * dt;
            } else if k == 300 {
                p += 0.3;
            }
            s.update(p, dt, bounded.filter_time_s, bounded.max_rate_mpa_per_s);
            su.update(p, dt, unbounded.filter_time_s, unbounded.max_rate_mpa_per_s);
            if k < 300 {
                ramp_max = ramp_max.max(bounded.scale(&s));
            } else {
                step_max = step_max.max(bounded.scale(&s));
                step_max_unbounded = step_max_unbounded.max(unbounded.scale(&su));
            }
        }
        // The ramp reaches the saturation; the step goes no further.
        let top = 0.6 + 2.2 * 0.2f32.sqrt();
        assert!((bounded.max_scale() - top).abs() < 1e-5);
        assert!((ramp_max - top).abs() < 0.01 * top, "{ramp_max} vs {top}");
        assert!(step_max <= top + 1e-5, "{step_max} vs {top}");
        // Without the bound the same step takes the factor 75 % above that
        // of the fastest ramp (2.8 against 1.58).
        assert!(step_max_unbounded > 1.75 * top, "{step_max_unbounded}");
        // After the step, at rest again.
        assert!(
            (bounded.scale(&s) - 0.6).abs() < 1e-3,
            "{}",
            bounded.scale(&s)
        );
    }

    #[test]
    fn a_step_leaves_the_loop_widened_no_longer_than_a_ramps_end() {
        // 100 Hz, `ṗ_max` 0.2 MPa/s, a 0.05 s filter. Count the samples
        // after the pressure stops moving while the factor is still above
        // the middle of rest and top: after a ramp at `ṗ_max` that ends,
        // and after a 0.3 MPa step in one sample from a hold.
        let dt = 0.01;
        let law = square_root_law_saturating_at_ramps();
        let mid = 0.5 * (law.scale_at_rest + law.max_scale());
        let widened_after = |pressure: &dyn Fn(usize) -> f32| {
            let mut s = RateState::default();
            let mut count = 0;
            for k in 0..400 {
                s.update(pressure(k), dt, law.filter_time_s, law.max_rate_mpa_per_s);
                if k > 200 && law.scale(&s) > mid {
                    count += 1;
                }
            }
            count
        };
        let after_ramp = widened_after(&|k| 0.2 * dt * k.min(200) as f32);
        // The step's one moving sample is sample 200, the ramp's last.
        let after_step = widened_after(&|k| if k < 200 { 0.1 } else { 0.4 });
        // The ramp's end: ln(4)·τ ≈ 7 samples above the middle. Were the
        // filter's state not bounded (a raw 5 MPa/s entering the filter
        // and only the law saturated), the step would stay above it for
        // ln(16)·τ ≈ 14 samples.
        assert!((4..=10).contains(&after_ramp), "{after_ramp}");
        assert!(after_step <= after_ramp, "{after_step} vs {after_ramp}");
    }

    #[test]
    fn a_noisy_ramp_near_the_saturation_reads_its_own_rate() {
        // 1 kHz, a 0.2 MPa/s ramp with ±0.0017 MPa of uniform noise (σ
        // 0.001), the law saturating at 0.21 MPa/s, a 0.1 s filter. A raw
        // difference is ±3.4 MPa/s of noise: clipped one by one at 0.21
        // they read the ramp as about 0.02 MPa/s.
        let dt = 0.001;
        let mut seed = 0x2545_f491_u32;
        let mut noise = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            (seed as f32 / u32::MAX as f32 - 0.5) * 2.0 * 0.0017
        };
        let mut s = RateState::default();
        let (mut sum, mut n) = (0.0f32, 0);
        for k in 0..20_000 {
            s.update(0.2 * dt * k as f32 + noise(), dt, 0.1, 0.21);
            if k >= 10_000 {
                sum += s.rate_mpa_per_s().min(0.21);
                n += 1;
            }
        }
        let mean = sum / n as f32;
        assert!((mean - 0.2).abs() < 0.02, "{mean}");
    }

    #[test]
    fn bad_samples_are_ignored() {
        let mut s = RateState::default();
        s.update(0.1, 0.02, RATE_FILTER_TIME_S, f32::NAN);
        s.update(f32::NAN, 0.02, RATE_FILTER_TIME_S, MAX_RATE_MPA_PER_S);
        s.update(0.2, f32::NAN, RATE_FILTER_TIME_S, MAX_RATE_MPA_PER_S);
        s.update(0.3, -1.0, RATE_FILTER_TIME_S, MAX_RATE_MPA_PER_S);
        assert_eq!(s.rate_mpa_per_s(), 0.0);
        s.update(1e30, 0.02, f32::NAN, MAX_RATE_MPA_PER_S);
        assert!(s.rate_mpa_per_s() <= MAX_RATE_MPA_PER_S);
        // A saturation outside `(0, MAX_RATE_MPA_PER_S]` bounds the state
        // at MAX_RATE_MPA_PER_S, finite.
        for bad in [f32::NAN, f32::INFINITY, 0.0, -1.0, 100.0] {
            let mut s = RateState::default();
            s.update(0.0, 0.01, 0.0, bad);
            s.update(0.3, 0.01, 0.0, bad);
            assert_eq!(s.rate_mpa_per_s(), MAX_RATE_MPA_PER_S, "{bad}");
            s.update(0.3, 0.01, 0.0, bad);
            assert_eq!(s.rate_mpa_per_s(), 0.0, "{bad}");
        }
        assert!(s.rate_mpa_per_s().is_finite());
    }

    #[test]
    fn validation() {
        assert_eq!(RateDependence::NEUTRAL.validate(), Ok(()));
        assert!(RateDependence::linear(1.0, -1.0).validate().is_err());
        let ok = RateDependence::linear(1.0, 5.0);
        for n in [0.29f32, 1.51, f32::NAN, f32::INFINITY] {
            assert!(
                RateDependence { exponent: n, ..ok }.validate().is_err(),
                "{n}"
            );
        }
        for m in [0.0f32, -0.1, MAX_RATE_MPA_PER_S + 0.01, f32::NAN] {
            assert!(
                RateDependence {
                    max_rate_mpa_per_s: m,
                    ..ok
                }
                .validate()
                .is_err(),
                "{m}"
            );
        }
        for tau in [-0.01f32, 10.01, f32::NAN] {
            assert!(
                RateDependence {
                    filter_time_s: tau,
                    ..ok
                }
                .validate()
                .is_err(),
                "{tau}"
            );
        }
        assert_eq!(
            RateDependence {
                filter_time_s: 0.0,
                exponent: 0.3,
                ..ok
            }
            .validate(),
            Ok(())
        );
    }

    #[test]
    fn a_filter_made_once_steps_as_the_update_does_bit_for_bit() {
        // The feedforward's and the controller's filters advance with
        // constants made once; the host's update makes them each sample.
        for (dt, tau, max) in [(0.001, 0.3, 0.5), (0.02, 0.0, 5.0), (0.01, f32::NAN, -1.0)] {
            let f = RateFilter::new(dt, tau, max).unwrap();
            let (mut a, mut b) = (RateState::default(), RateState::default());
            for k in 0..500 {
                let p = 0.3 + 0.2 * (k as f32 * 0.05).sin() + if k == 250 { 0.3 } else { 0.0 };
                a.update(p, dt, tau, max);
                b.advance(p, &f);
                assert_eq!(a, b, "{dt} {tau} {max} {k}");
            }
        }
        assert_eq!(RateFilter::new(0.0, 0.3, 1.0), None);
        assert_eq!(RateFilter::new(1.5, 0.3, 1.0), None);
    }
}

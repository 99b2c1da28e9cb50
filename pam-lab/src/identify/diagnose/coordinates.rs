//! The candidates' parameters in the optimiser's unbounded coordinates:
//! each bounded parameter a logistic or logarithmic map of a free one, so
//! every point the optimiser visits is an effect pam-core accepts.

use pam_core::effects::memory::MIN_MERGE_SPAN;
use pam_core::effects::rate::MAX_RATE_MPA_PER_S;
use pam_core::effects::{PressureDelay, PressureLag};

/// The rate filter's time constant from its unbounded coordinate: logistic
/// over `[0.02, 1]` s.
pub(super) fn rate_filter_time(theta: f64) -> f64 {
    (0.02 + 0.98 * sigmoid(theta)).clamp(0.02, 1.0)
}

/// The rate law's saturation from its unbounded coordinate: logarithmic
/// between the record's fastest ramp (below which the data shows the law)
/// and [`MAX_RATE_MPA_PER_S`] (a step's rate), so the law cannot saturate
/// inside the measured ramps and cannot grow beyond what a step shows.
pub(super) fn rate_saturation(fastest_ramp: f64, theta: f64) -> f64 {
    let hi = f64::from(MAX_RATE_MPA_PER_S);
    let lo = fastest_ramp.clamp(0.01, hi);
    (lo * (hi / lo).powf(sigmoid(theta))).clamp(lo, hi)
}

/// The rate filter's unbounded coordinate for the time constant `tau`, s.
pub(super) fn rate_filter_theta(tau: f64) -> f64 {
    logit((tau - 0.02) / 0.98)
}

/// A logarithmic range `[lo, lo·ratio]` (clamped to `[lo, hi]`) mapped from
/// an unbounded coordinate: `lo·ratio^sigmoid(θ)`.
#[derive(Clone, Copy)]
pub(super) struct LogRange {
    lo: f64,
    ratio: f64,
    hi: f64,
}

impl LogRange {
    pub(super) fn value(self, theta: f64) -> f64 {
        (self.lo * self.ratio.powf(sigmoid(theta))).clamp(self.lo, self.hi)
    }

    pub(super) fn theta(self, value: f64) -> f64 {
        logit((value / self.lo).ln() / self.ratio.ln())
    }
}

/// The memory's `k`: logarithmic over `[0.05, 50]` (the blend is symmetric
/// in `ln k`).
pub(super) const MEMORY_SHAPE: LogRange = LogRange {
    lo: 0.05,
    ratio: 1000.0,
    hi: 50.0,
};

/// The pressure lag's time constant, s: logarithmic over pam-core's
/// range, `[0.001, 0.5]`.
pub(super) const PRESSURE_LAG_TIME: LogRange = LogRange {
    lo: PressureLag::MIN_TIME_CONSTANT_S as f64,
    ratio: (PressureLag::MAX_TIME_CONSTANT_S / PressureLag::MIN_TIME_CONSTANT_S) as f64,
    hi: PressureLag::MAX_TIME_CONSTANT_S as f64,
};

/// The pressure delay, s: logarithmic over pam-core's range,
/// `[0.0005, 0.1]`.
pub(super) const PRESSURE_DELAY_TIME: LogRange = LogRange {
    lo: PressureDelay::MIN_DELAY_S as f64,
    ratio: (PressureDelay::MAX_DELAY_S / PressureDelay::MIN_DELAY_S) as f64,
    hi: PressureDelay::MAX_DELAY_S as f64,
};

/// The memory's merge span: logarithmic over `[MIN_MERGE_SPAN, 1]`.
pub(super) const MERGE_SPAN: LogRange = LogRange {
    lo: MIN_MERGE_SPAN as f64,
    ratio: 1.0 / (MIN_MERGE_SPAN as f64),
    hi: 1.0,
};

pub(super) fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

pub(super) fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

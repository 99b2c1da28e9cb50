//! The safety monitor: what makes a [`Fault`], checked every period.
//!
//! * **Readings**, before anything else sees them (the mode tracker, the
//!   law): one rule per sensor in a table (`Rule`), used both by the fast
//!   path (every reading read fine and lies inside its range) and by the
//!   full check that names the first fault; the table is built once from
//!   the configuration and the coefficients. Per reading, in order: read
//!   error, non-finite, stuck, outside the plausible range, above the
//!   safe limit (the pressure's is `min(Pmax, max_command_mpa) +
//!   overpressure_margin_mpa`).
//! * **Responses** of the pressure to the valve command (`ResponseRule`):
//!   inlet open without a rise ([`Fault::SupplyLoss`]), exhaust open
//!   without a fall ([`Fault::Implausible`]`(`[`Check::Vent`]`)`).
//! * **The model as a virtual sensor**: the measured contraction against
//!   the band between the model's branches at the measured pressure
//!   ([`Fault::Implausible`]`(`[`Check::Model`]`)`).
//! * **Timing**: consecutive overruns reported by the image
//!   ([`Fault::Overrun`]).
//! * **Latch**: more than `latch_trips` trips within the window keep the
//!   valves safe until an explicit reset.

use super::config::SafetyConfig;
use super::io::Sample;
use crate::hal::SensorErrorKind;
use pam_core::{Branch, Coeffs, LoadModel};

/// What the monitor's rules need of the model the controller runs,
/// whichever family: its calibrated load range and the pressure it is
/// calibrated to (the paper model's `Pmax`, a Preisach table's top).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ModelLimits {
    /// Lightest calibrated load, N.
    pub min_load_n: f32,
    /// Heaviest calibrated load, N.
    pub max_load_n: f32,
    /// Highest pressure the model is calibrated to, MPa.
    pub max_pressure_mpa: f32,
}

impl ModelLimits {
    /// The paper model's: its load family's range and `Pmax`.
    pub fn of_coeffs(coeffs: &Coeffs) -> ModelLimits {
        let p = coeffs.params();
        ModelLimits {
            min_load_n: p.min_load_n,
            max_load_n: p.max_load_n,
            max_pressure_mpa: p.points.max_pressure_mpa,
        }
    }
}

/// Which sensor a [`Fault`] concerns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SensorId {
    /// The pressure transducer.
    Pressure,
    /// The contraction (position) sensor.
    Contraction,
    /// The load cell.
    Load,
}

/// Which plausibility check found the readings inconsistent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Check {
    /// The measured contraction is outside the model's band at the measured
    /// pressure and load ([`SafetyConfig::implausible_contraction`]).
    Model,
    /// The exhaust was commanded open and the pressure did not fall
    /// ([`SafetyConfig::vent_flow`]).
    Vent,
}

/// Why the controller put the valves in the safe state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Fault {
    /// A sensor read failed.
    Read {
        /// Which sensor.
        sensor: SensorId,
        /// How it failed.
        kind: SensorErrorKind,
    },
    /// A sensor returned NaN or an infinity.
    NonFinite(SensorId),
    /// A reading is outside its plausible range ([`SafetyConfig`]); for the
    /// load, outside the calibrated range of the coefficients by more than
    /// `load_margin_n`.
    OutOfRange(SensorId),
    /// A reading was bit-for-bit identical for more than `stuck_samples`
    /// samples: a frozen converter or a disconnected line held by a filter.
    Stuck(SensorId),
    /// The desired contraction is not finite.
    Setpoint,
    /// The valve driver refused a duty.
    Valve,
    /// The inlet was commanded (nearly) fully open for
    /// `supply_loss_periods` periods and the pressure did not rise by
    /// `supply_loss_rise_mpa`: no supply pressure (compressor off, hose
    /// off, regulator closed) or a supply too low for the command.
    SupplyLoss,
    /// The chamber pressure is above the highest command,
    /// `min(Pmax, max_command_mpa)`, plus `overpressure_margin_mpa`.
    OverPressure,
    /// The readings disagree with the model or with the valve command.
    Implausible(Check),
    /// `overrun_limit` control periods in a row overran.
    Overrun,
    /// The image was reset by the independent watchdog (a stalled control
    /// loop); set at boot with [`Controller::latch`](super::Controller::latch).
    Watchdog,
    /// The online adaptation's stroke scale reached its bound
    /// ([`AdaptationConfig::bound`](super::adapt::AdaptationConfig::bound)):
    /// the muscle has drifted beyond its model. Latched at once: re-identify
    /// the muscle (a reboot returns to the flashed model).
    Drifted,
}

impl core::fmt::Display for SensorId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            SensorId::Pressure => "pressure",
            SensorId::Contraction => "contraction",
            SensorId::Load => "load",
        })
    }
}

impl core::fmt::Display for Fault {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Fault::Read { sensor, kind } => write!(f, "{sensor} sensor read failed: {kind}"),
            Fault::NonFinite(s) => write!(f, "{s} reading not finite"),
            Fault::OutOfRange(s) => write!(f, "{s} reading out of range"),
            Fault::Stuck(s) => write!(f, "{s} reading stuck"),
            Fault::Setpoint => f.write_str("set-point not finite"),
            Fault::Valve => f.write_str("valve driver refused a duty"),
            Fault::SupplyLoss => f.write_str("inlet open but pressure not rising: supply lost"),
            Fault::OverPressure => {
                f.write_str("chamber pressure above the highest command + margin")
            }
            Fault::Implausible(Check::Model) => {
                f.write_str("contraction disagrees with the model at the measured pressure")
            }
            Fault::Implausible(Check::Vent) => f.write_str("exhaust open but pressure not falling"),
            Fault::Overrun => f.write_str("control periods overran in a row"),
            Fault::Watchdog => f.write_str("reset by the independent watchdog"),
            Fault::Drifted => f.write_str("the muscle has drifted beyond its model: re-identify"),
        }
    }
}

/// One sensor's row of the rule table.
#[derive(Clone, Copy, Debug)]
pub(super) struct Rule {
    sensor: SensorId,
    /// Plausible range, finite bounds.
    lo: f32,
    hi: f32,
    /// Safe limit within the range; above it is `over_limit`.
    limit: f32,
    over_limit: Fault,
    /// `min(hi, limit)`: the fast path's upper bound.
    fast_hi: f32,
}

impl Rule {
    fn new(sensor: SensorId, lo: f32, hi: f32, limit: f32, over_limit: Fault) -> Rule {
        // Each bound limited to the finite floats, so an infinite reading is
        // never inside.
        let (lo, hi) = (
            pam_core::clamp(lo, f32::MIN, f32::MAX),
            pam_core::clamp(hi, f32::MIN, f32::MAX),
        );
        let limit = pam_core::clamp(limit, f32::MIN, hi);
        Rule {
            sensor,
            lo,
            hi,
            limit,
            over_limit,
            fast_hi: limit,
        }
    }

    /// The full check of one reading, in the order of the module docs; the
    /// stuck counter observes every finite reading.
    fn check(
        &self,
        reading: Result<f32, SensorErrorKind>,
        stuck: &mut StuckMonitor,
        stuck_limit: u16,
    ) -> Option<Fault> {
        let sensor = self.sensor;
        let v = match reading {
            Ok(v) => v,
            Err(kind) => return Some(Fault::Read { sensor, kind }),
        };
        if !v.is_finite() {
            return Some(Fault::NonFinite(sensor));
        }
        if stuck.observe(v, stuck_limit) {
            return Some(Fault::Stuck(sensor));
        }
        if !(v >= self.lo && v <= self.hi) {
            return Some(Fault::OutOfRange(sensor));
        }
        if v > self.limit {
            return Some(self.over_limit);
        }
        None
    }
}

/// Consecutive identical readings of one sensor.
#[derive(Clone, Copy, Debug)]
struct StuckMonitor {
    /// Bits of the last finite reading; a NaN pattern before the first one
    /// (only finite readings are observed, so it never matches).
    last_bits: u32,
    repeats: u16,
}

impl Default for StuckMonitor {
    fn default() -> Self {
        StuckMonitor {
            last_bits: f32::NAN.to_bits(),
            repeats: 0,
        }
    }
}

impl StuckMonitor {
    /// Record the finite `v`; true when it has repeated more than `limit`
    /// times (`u16::MAX` for a disabled check, which the saturating count
    /// never exceeds).
    #[inline(always)]
    fn observe(&mut self, v: f32, limit: u16) -> bool {
        let bits = v.to_bits();
        if self.last_bits == bits {
            self.repeats = self.repeats.saturating_add(1);
        } else {
            self.last_bits = bits;
            self.repeats = 0;
        }
        self.repeats > limit
    }
}

/// A rule on the pressure's response to a saturated valve command: the
/// command `sign · flow ≥ flow` for `periods` periods, starting at a
/// pressure `≥ min_start_mpa`, and the pressure moved by less than
/// `change_mpa` in the direction `sign` since the start.
#[derive(Clone, Copy, Debug)]
pub(super) struct ResponseRule {
    sign: f32,
    flow: f32,
    periods: u16,
    change_mpa: f32,
    min_start_mpa: f32,
}

/// The state of one [`ResponseRule`].
#[derive(Clone, Copy, Debug, Default)]
struct Response {
    /// Consecutive periods with the command saturated, counting this one.
    periods: u16,
    /// Pressure read when the first of them was issued, MPa.
    start_mpa: f32,
}

impl Response {
    /// `flow_before` is the command issued by the previous update,
    /// `before_mpa` the pressure it read, `now_mpa` the pressure now.
    fn observe(
        &mut self,
        r: &ResponseRule,
        flow_before: f32,
        before_mpa: f32,
        now_mpa: f32,
    ) -> bool {
        if r.periods == 0 || !(flow_before * r.sign >= r.flow) {
            self.periods = 0;
            return false;
        }
        if self.periods == 0 {
            self.start_mpa = before_mpa;
        }
        if !(self.start_mpa >= r.min_start_mpa) {
            self.periods = 0;
            return false;
        }
        self.periods = self.periods.saturating_add(1);
        if (now_mpa - self.start_mpa) * r.sign >= r.change_mpa {
            // Responding: restart the window from here.
            self.periods = 0;
            return false;
        }
        self.periods >= r.periods
    }
}

/// Trips counted for the latch.
#[derive(Clone, Copy, Debug, Default)]
struct Latch {
    latched: bool,
    trips: u16,
    window_start: u32,
}

/// The monitor's configuration-derived tables and its state.
#[derive(Clone, Copy, Debug)]
pub(super) struct Monitor {
    rules: [Rule; 3],
    stuck_limit: u16,
    stuck: [StuckMonitor; 3],
    supply_rule: ResponseRule,
    vent_rule: ResponseRule,
    supply: Response,
    vent: Response,
    /// Flow command issued by the last update (0 after a safe state).
    pub last_flow: f32,
    /// Pressure read by the last good update, MPa.
    last_mpa: f32,
    band: f32,
    /// Per-period relaxation of the pressure envelope, `dt_s / lag` in [0, 1].
    envelope_gain: f32,
    /// Lagged minimum and maximum of the pressure, MPa (NaN before the
    /// first good sample).
    envelope_lo_mpa: f32,
    envelope_hi_mpa: f32,
    /// Lagged minimum and maximum of a Preisach model's predicted
    /// contraction ([`Monitor::check_prediction`]; NaN before the first).
    predicted_lo: f32,
    predicted_hi: f32,
    implausible_periods: u16,
    outside: u16,
    /// Due periods the model check left to the next one since it last
    /// judged ([`Monitor::defer_model_check`]): counted with the next
    /// judged period's verdict.
    deferred: u16,
    /// Periods the model check pauses after a load switch, and how many
    /// of them are left.
    settle_periods: u16,
    settling: u16,
    overrun_limit: u16,
    overruns: u16,
    latch_trips: u16,
    latch_window: u32,
    latch: Latch,
}

/// How far `x` lies outside `[lo, hi]`; 0 inside.
fn excess_outside(lo: f32, hi: f32, x: f32) -> f32 {
    if x < lo {
        lo - x
    } else if x > hi {
        x - hi
    } else {
        0.0
    }
}

/// How a model with effects widens the model check's band.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ModelBand<'a> {
    /// `(S − 1)·be` for the offset scale `S > 1` of width and rate the
    /// feedforward used, MPa (0 without them).
    pub extra_offset_mpa: f32,
    /// The shape correction at the active load, as the feedforward keeps
    /// it (borrowed: no copy per period).
    pub shape: Option<&'a pam_core::effects::ShapeInverse>,
    /// With a rate law: the offset scale at the measured pressure's rate.
    pub measured: Option<MeasuredRate<'a>>,
}

/// The offset scale a rate law gives the measured pressure's rate: the
/// loop the muscle itself is on. The feedforward's own scale follows the
/// desired motion (the rate of its constraint pressure); where the loop
/// corrects a disturbance, or the valves lag the command, the pressure the
/// muscle sees moves at another rate, and its loop is that rate's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasuredRate<'a> {
    /// The model's effects (its width and rate law).
    pub effects: &'a pam_core::effects::Effects,
    /// The model's parameters (the width's load steps).
    pub params: &'a pam_core::Params,
    /// The active load, N.
    pub load_n: f32,
    /// The measured pressure through the rate law's filter.
    pub rate: &'a pam_core::effects::RateState,
}

impl MeasuredRate<'_> {
    /// `(S − 1)·be` for the offset scale `S` at the measured rate, MPa
    /// (0 where `S ≤ 1`).
    pub fn extra_offset_mpa(&self, model: &LoadModel) -> f32 {
        let s =
            pam_core::feedforward::offset_scale(self.effects, self.params, self.load_n, self.rate);
        extra_offset_mpa(s, model)
    }
}

/// `(S − 1)·be` for an offset scale `S > 1`, MPa; 0 otherwise (a scale
/// below 1 narrows the loop, inside the paper's band).
pub fn extra_offset_mpa(scale: f32, model: &LoadModel) -> f32 {
    if scale > 1.0 {
        (scale - 1.0) * model.ellipse_height_mpa()
    } else {
        0.0
    }
}

impl Monitor {
    /// The rule table for `s` and the coefficients' calibrated load range
    /// and `Pmax`.
    ///
    /// `lag_time_constant_s`: the slowest lag of the model's answer, its
    /// creep's or its pressure lag's, if it has one. The contraction then
    /// keeps moving for a few time constants after the measured pressure
    /// stops, so the pressure envelope relaxes with the longer of that and
    /// `implausible_lag_s`.
    pub fn new(
        s: &SafetyConfig,
        limits: &ModelLimits,
        dt_s: f32,
        lag_time_constant_s: Option<f32>,
    ) -> Monitor {
        use SensorId::*;
        let pmax = limits.max_pressure_mpa;
        let load_lo = limits.min_load_n - s.load_margin_n;
        let load_hi = limits.max_load_n + s.load_margin_n;
        Monitor {
            rules: [
                Rule::new(
                    Pressure,
                    s.pressure_min_mpa,
                    s.pressure_max_mpa,
                    s.command_limit_mpa(pmax) + s.overpressure_margin_mpa,
                    Fault::OverPressure,
                ),
                Rule::new(
                    Contraction,
                    s.contraction_min,
                    s.contraction_max,
                    s.contraction_max,
                    Fault::OutOfRange(Contraction),
                ),
                // The load's plausible range is the calibrated range of the
                // model family widened by the margin; inside the margin the
                // tracker clamps the load to the calibrated range.
                Rule::new(Load, load_lo, load_hi, load_hi, Fault::OutOfRange(Load)),
            ],
            stuck_limit: if s.stuck_samples == 0 {
                u16::MAX
            } else {
                s.stuck_samples
            },
            stuck: [StuckMonitor::default(); 3],
            supply_rule: ResponseRule {
                sign: 1.0,
                flow: s.supply_loss_flow,
                periods: s.supply_loss_periods,
                change_mpa: s.supply_loss_rise_mpa,
                min_start_mpa: f32::NEG_INFINITY,
            },
            vent_rule: ResponseRule {
                sign: -1.0,
                flow: s.vent_flow,
                periods: s.vent_periods,
                change_mpa: s.vent_fall_mpa,
                min_start_mpa: s.vent_min_mpa,
            },
            supply: Response::default(),
            vent: Response::default(),
            last_flow: 0.0,
            last_mpa: 0.0,
            band: s.implausible_contraction,
            envelope_gain: {
                let lag_s = match lag_time_constant_s {
                    Some(tau) if tau > s.implausible_lag_s => tau,
                    _ => s.implausible_lag_s,
                };
                if lag_s > dt_s {
                    dt_s / lag_s
                } else {
                    1.0
                }
            },
            envelope_lo_mpa: f32::NAN,
            envelope_hi_mpa: f32::NAN,
            predicted_lo: f32::NAN,
            predicted_hi: f32::NAN,
            implausible_periods: s.implausible_periods,
            outside: 0,
            deferred: 0,
            // `as` saturates (and a NaN, excluded by validation, gives 0).
            settle_periods: (s.implausible_settle_s / dt_s + 0.5) as u16,
            // The check starts paused (`implausible_start_s`).
            settling: (s.implausible_start_s / dt_s + 0.5) as u16,
            overrun_limit: s.overrun_limit,
            overruns: 0,
            latch_trips: s.latch_trips,
            latch_window: s.latch_window_periods,
            latch: Latch::default(),
        }
    }

    /// The first fault in this sample's readings and set-point, in the order
    /// pressure, contraction, load, set-point. Every sensor is checked every
    /// step so that each stuck counter sees every sample.
    ///
    /// Fast path: every read succeeded and every reading is inside its
    /// rule's `[lo, fast_hi]` (finite bounds, so the reading is finite too)
    /// and the set-point is finite: only stuck readings remain possible.
    /// Anything else goes to [`check_full`](Self::check_full), which walks
    /// the same table and names the first fault.
    #[inline(always)]
    pub fn check(&mut self, sample: &Sample, desired_contraction: f32) -> Option<Fault> {
        let readings = sample.readings();
        let inside = readings
            .iter()
            .zip(&self.rules)
            .all(|(r, rule)| matches!(r, Ok(v) if *v >= rule.lo && *v <= rule.fast_hi));
        if inside && desired_contraction.is_finite() {
            let mut first = None;
            for ((r, rule), stuck) in readings.iter().zip(&self.rules).zip(&mut self.stuck) {
                if let Ok(v) = r {
                    if stuck.observe(*v, self.stuck_limit) && first.is_none() {
                        first = Some(Fault::Stuck(rule.sensor));
                    }
                }
            }
            return first;
        }
        self.check_full(&readings, desired_contraction)
    }

    /// Every check of every reading, in order (the path of a bad sample).
    #[cold]
    #[inline(never)]
    pub(super) fn check_full(
        &mut self,
        readings: &[Result<f32, SensorErrorKind>; 3],
        desired_contraction: f32,
    ) -> Option<Fault> {
        let mut first = None;
        for ((r, rule), stuck) in readings.iter().zip(&self.rules).zip(&mut self.stuck) {
            let f = rule.check(*r, stuck, self.stuck_limit);
            first = first.or(f);
        }
        first.or((!desired_contraction.is_finite()).then_some(Fault::Setpoint))
    }

    /// The checks on good readings that need the loop's history: the
    /// pressure's response to the last command, and overruns.
    #[inline(always)]
    pub fn check_response(&mut self, pressure_mpa: f32) -> Option<Fault> {
        let before = self.last_mpa;
        self.last_mpa = pressure_mpa;
        let flow = self.last_flow;
        let no_rise = self
            .supply
            .observe(&self.supply_rule, flow, before, pressure_mpa);
        let no_fall = self
            .vent
            .observe(&self.vent_rule, flow, before, pressure_mpa);
        if no_rise {
            Some(Fault::SupplyLoss)
        } else if no_fall {
            Some(Fault::Implausible(Check::Vent))
        } else if self.overrun_limit > 0 && self.overruns >= self.overrun_limit {
            Some(Fault::Overrun)
        } else {
            None
        }
    }

    /// The model check's period: the pressure envelope follows every good
    /// sample (lagged minimum and maximum, `p_lo` and `p_hi`), and whether
    /// the check judges this period ([`Self::check_model`]): not while
    /// paused (the start, a load switch, a table build: their settling
    /// time counts down), not while not `controlling` (the count restarts),
    /// and not when the check is off.
    #[inline(always)]
    pub fn model_check_due(&mut self, pressure_mpa: f32, controlling: bool) -> bool {
        let g = self.envelope_gain;
        let (lo, hi) = (self.envelope_lo_mpa, self.envelope_hi_mpa);
        // Follow at once outward (NaN: the first sample), relax inward.
        self.envelope_lo_mpa = if lo <= pressure_mpa {
            lo + g * (pressure_mpa - lo)
        } else {
            pressure_mpa
        };
        self.envelope_hi_mpa = if hi >= pressure_mpa {
            hi + g * (pressure_mpa - hi)
        } else {
            pressure_mpa
        };
        if self.implausible_periods == 0 || !controlling || self.settling > 0 {
            self.settling = self.settling.saturating_sub(1);
            self.outside = 0;
            self.deferred = 0;
            return false;
        }
        true
    }

    /// The model as a virtual sensor, on a period [`Self::model_check_due`]
    /// says is due: how far `contraction` lies outside the band
    /// `[x_C(p_lo), x_E(p_hi)]` of `model` (0 inside), and whether it has
    /// been beyond the band by more than the bound for
    /// `implausible_periods` periods in a row (a due period left to this
    /// one, [`Self::defer_model_check`], counts with its verdict).
    ///
    /// A model with effects widens the band ([`ModelBand`]): by the extra
    /// ellipse offset of its width and rate, and through its shape
    /// correction.
    #[inline(always)]
    pub fn check_model(
        &mut self,
        model: &LoadModel,
        widen: &ModelBand<'_>,
        contraction: f32,
    ) -> (f32, Option<Fault>) {
        // Inverse model, eqs. (25)/(26): the contraction each branch has at
        // a pressure. At one pressure the expansion branch is the longer
        // contraction (HME = HMC − 2·y_hys), so the two bound the loop and
        // every minor loop inside it.
        //
        // With the offset scaled by `S > 1` a branch at pressure `p` is the
        // paper's branch at `p ∓ (S − 1)·y_hys`, and `y_hys ≤ be`: the
        // paper's branches at pressures moved out by `(S − 1)·be` bound it
        // (a scale below 1 narrows the loop, inside the paper's band).
        let extra = widen.extra_offset_mpa;
        let mut excess = self.excess_beyond_band(model, extra, widen.shape, contraction);
        // Outside the loop of the feedforward's rate: judged by the loop
        // of the measured pressure's too, where that one is wider (only
        // then: the scale costs a power on a law whose exponent is not
        // 0.5, 0.75 or 1).
        if let Some(m) = &widen.measured {
            if excess > self.band {
                let wider = m.extra_offset_mpa(model);
                if wider > extra {
                    excess =
                        excess.min(self.excess_beyond_band(model, wider, widen.shape, contraction));
                }
            }
        }
        self.count(excess)
    }

    /// How far `contraction` lies outside the band of the pressure
    /// envelope widened by `extra` MPa (the shape applied), 0 inside.
    fn excess_beyond_band(
        &self,
        model: &LoadModel,
        extra: f32,
        shape: Option<&pam_core::effects::ShapeInverse>,
        contraction: f32,
    ) -> f32 {
        let a = model.contraction(self.envelope_lo_mpa - extra, Branch::Contraction);
        let b = model.contraction(self.envelope_hi_mpa + extra, Branch::Expansion);
        // The shape correction is increasing along the stroke: it maps the
        // band's ends to the corrected band's.
        let (a, b) = match shape {
            Some(s) => (s.apply(model, a), s.apply(model, b)),
            None => (a, b),
        };
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        excess_outside(lo, hi, contraction)
    }

    /// The model check for a Preisach model, whose forward evaluation
    /// gives one contraction at the measured pressure (`predicted`, from
    /// the relay states the measured pressure history left) rather than a
    /// band between two branches: the band is the lagged minimum and
    /// maximum of that prediction (following it at once outward, relaxing
    /// inward with the same time constant as the paper model's pressure
    /// envelope: the contraction follows its prediction with the muscle's
    /// and the load's dynamics), widened by `implausible_contraction`, the
    /// same bound, window and pauses as [`Self::check_model`].
    ///
    /// The prediction carries the minor loop the muscle is on, so this
    /// band is narrower than the paper model's (which spans the whole loop
    /// at a pressure): an offset or decoupled sensor leaves it sooner, and
    /// a model far from its muscle trips it sooner too (host-sim measures
    /// the distance on normal runs against the bound).
    #[inline(always)]
    pub fn check_prediction(
        &mut self,
        predicted: f32,
        contraction: f32,
        controlling: bool,
    ) -> (f32, Option<Fault>) {
        let g = self.envelope_gain;
        let (lo, hi) = (self.predicted_lo, self.predicted_hi);
        // Follow at once outward (NaN: the first sample), relax inward.
        self.predicted_lo = if lo <= predicted {
            lo + g * (predicted - lo)
        } else {
            predicted
        };
        self.predicted_hi = if hi >= predicted {
            hi + g * (predicted - hi)
        } else {
            predicted
        };
        if self.implausible_periods == 0 || !controlling || self.settling > 0 {
            self.settling = self.settling.saturating_sub(1);
            self.outside = 0;
            return (0.0, None);
        }
        self.judge(self.predicted_lo, self.predicted_hi, contraction)
    }

    /// How far `contraction` lies outside `[lo, hi]` (0 inside), and the
    /// fault once it has been beyond the bound for `implausible_periods`
    /// periods in a row.
    #[inline(always)]
    fn judge(&mut self, lo: f32, hi: f32, contraction: f32) -> (f32, Option<Fault>) {
        self.count(excess_outside(lo, hi, contraction))
    }

    /// Count a period `excess` outside the band (beyond the tolerance) or
    /// inside it; the fault once the count reaches its limit.
    fn count(&mut self, excess: f32) -> (f32, Option<Fault>) {
        if excess > self.band {
            self.outside = self.outside.saturating_add(1).saturating_add(self.deferred);
        } else {
            self.outside = 0;
        }
        self.deferred = 0;
        let fault =
            (self.outside >= self.implausible_periods).then_some(Fault::Implausible(Check::Model));
        (excess, fault)
    }

    /// A period the model check was due but left to the next one (the
    /// feedforward's minor loop took that period's work: a reversal's new
    /// loop, its search, a wipe-out's, or its ends moved to the rate law's
    /// new factor, every second period while that changes). The next
    /// judged period counts for it too, so the fault comes after
    /// `implausible_periods` periods in a row outside the band whether or
    /// not some were left to the next.
    pub fn defer_model_check(&mut self) {
        self.deferred = self.deferred.saturating_add(1);
    }

    /// The tracker switched the load model: pause the model check.
    pub fn load_switched(&mut self) {
        self.settling = self.settle_periods;
    }

    /// Record whether the last period overran.
    pub fn record_overrun(&mut self, overran: bool) {
        self.overruns = if overran {
            self.overruns.saturating_add(1)
        } else {
            0
        };
    }

    /// The valves went safe: no flow commanded, the windows restart.
    pub fn went_safe(&mut self) {
        self.last_flow = 0.0;
        self.supply.periods = 0;
        self.vent.periods = 0;
        self.outside = 0;
        self.deferred = 0;
    }

    /// A trip (control → safe state) at period `now`; latches on more than
    /// `latch_trips` trips within the window.
    pub fn trip(&mut self, now: u32) {
        let l = &mut self.latch;
        if l.trips == 0 || now.wrapping_sub(l.window_start) >= self.latch_window {
            l.window_start = now;
            l.trips = 0;
        }
        l.trips = l.trips.saturating_add(1);
        if self.latch_trips > 0 && l.trips > self.latch_trips {
            l.latched = true;
        }
    }

    /// Whether the safe state is latched.
    pub fn latched(&self) -> bool {
        self.latch.latched
    }

    /// Latch now (boot after a watchdog reset).
    pub fn latch(&mut self) {
        self.latch.latched = true;
    }

    /// The operator's reset: the latch and its trip count are cleared.
    pub fn reset_latch(&mut self) {
        self.latch = Latch::default();
    }
}

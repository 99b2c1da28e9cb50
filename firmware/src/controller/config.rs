//! Configuration of the controller and its validation: gains, rate,
//! feedforward, mode tracker and the safety monitor's limits. Validated once
//! ([`ControllerConfig::validate`], called by `Controller::new`); the step
//! never checks a setting again.

use super::adapt::AdaptationConfig;
use crate::hal::{HalConfigError, SafeState};
use pam_core::effects::{Effects, NonLocalMemory, MAX_STEP_S};
use pam_core::TrackerConfig;

/// Limits of the safety monitor ([`super::monitor`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SafetyConfig {
    /// What the valves do during a fault.
    pub safe_state: SafeState,
    /// Lowest plausible pressure reading, MPa gauge.
    pub pressure_min_mpa: f32,
    /// Highest plausible pressure reading, MPa gauge.
    pub pressure_max_mpa: f32,
    /// Lowest plausible contraction reading (fraction of rest length).
    pub contraction_min: f32,
    /// Highest plausible contraction reading.
    pub contraction_max: f32,
    /// Tolerance on the load reading beyond the calibrated range of the
    /// coefficients, N (≥ 0). A load cell at exactly `min_load_n` or
    /// `max_load_n` reads on both sides of it from noise alone; without a
    /// margin the controller would chatter in and out of the safe state.
    /// Within `[min_load_n − margin, max_load_n + margin]` the mode tracker
    /// clamps the load to the calibrated range (the model at the nearest
    /// end); beyond it the reading is [`Fault::OutOfRange`]`(Load)`.
    ///
    /// [`Fault::OutOfRange`]: super::Fault::OutOfRange
    pub load_margin_n: f32,
    /// Highest pressure the loop commands, MPa (> 0): the muscle's rating,
    /// or the top pressure it was characterised at, whichever is lower.
    /// The pressure command is clamped to the lower of this and the model's
    /// `Pmax` (where its loop closes), and over-pressure is judged from
    /// that lower limit. A model's `Pmax` may lie above the record it was
    /// identified from (`pam-lab diagnose` refits it up to 1.25× the
    /// record's top, pam-lab/DIAGNOSE.md); this limit, a property of the
    /// hardware, keeps such a model from commanding pressures the muscle
    /// never saw.
    pub max_command_mpa: f32,
    /// Over-pressure: a plausible pressure reading above the commanded
    /// limit (the lower of the model's `Pmax` and `max_command_mpa`) by
    /// more than this, MPa (> 0), is [`Fault::OverPressure`]. The loop
    /// never commands more than that limit, so a chamber above it means the
    /// inlet or the exhaust is not doing what it is told (inlet stuck open,
    /// exhaust stuck closed while the muscle is squeezed) or a stall let
    /// the inlet run.
    ///
    /// [`Fault::OverPressure`]: super::Fault::OverPressure
    pub overpressure_margin_mpa: f32,
    /// A reading identical to the bit for more than this many consecutive
    /// samples is stuck; 0 disables the check. Real converters dither by at
    /// least one count; a simulated sensor must add noise too.
    pub stuck_samples: u16,
    /// Consecutive good samples before leaving the safe state (≥ 1).
    pub recovery_samples: u16,
    /// Supply-loss check: a flow command at or above this (in `(0, 1]`)
    /// counts as "inlet open".
    ///
    /// What it mitigates: with the supply gone the inlet cannot fill the
    /// muscle (with a hose off it even vents it backwards), the error grows
    /// and the PI drives the inlet to full open; nothing else in the
    /// monitor notices, since every sensor reads fine. The check turns that
    /// into [`Fault::SupplyLoss`] and the safe state.
    ///
    /// Rule: the command issued in each of the last `supply_loss_periods`
    /// periods was `≥ supply_loss_flow`, and the pressure now is less than
    /// `supply_loss_rise_mpa` above the pressure read when the first of them
    /// was issued (a rise of at least that much restarts the window).
    ///
    /// False positives: a supply that is present but at or below the
    /// pressure the loop asks for (a regulator set below `Pmax` +
    /// `supply_loss_flow / pressure_gain_per_mpa`) also saturates the inlet
    /// without a rise, and trips it; at the default 0.95 and 20 /MPa the
    /// supply must exceed `Pmax` (0.5 MPa) by about 0.05 MPa, the rig's is
    /// 0.6 MPa. A healthy inlet at full opening fills by far more than
    /// `supply_loss_rise_mpa` in the window, also while the muscle contracts.
    ///
    /// Retry: the sensors are healthy during a supply loss, so control
    /// resumes after `recovery_samples` good samples like after any fault;
    /// if the supply is still gone the check trips again one window later
    /// (a retry every `supply_loss_periods + recovery_samples` periods, with
    /// the muscle vented in between), until the latch
    /// ([`latch_trips`](Self::latch_trips)) stops the retries.
    ///
    /// [`Fault::SupplyLoss`]: super::Fault::SupplyLoss
    pub supply_loss_flow: f32,
    /// Supply-loss window, control periods; 0 disables the check.
    pub supply_loss_periods: u16,
    /// Least pressure rise over the window with the inlet open, MPa (> 0;
    /// well above the pressure sensor's noise, 0.8 kPa RMS on the rig).
    pub supply_loss_rise_mpa: f32,
    /// Vent check, the mirror of the supply-loss check: a flow command at
    /// or below `−vent_flow` (in `(0, 1]`) counts as "exhaust open".
    ///
    /// What it mitigates: an exhaust valve stuck closed, or an inlet stuck
    /// open (which the open exhaust cannot out-vent): the loop asks for
    /// less pressure, saturates the exhaust, and the pressure does not
    /// fall. Rule: the command issued in each of the last `vent_periods`
    /// periods was `≤ −vent_flow`, the pressure when the first was issued
    /// was at least `vent_min_mpa`, and the pressure now is less than
    /// `vent_fall_mpa` below it → [`Fault::Implausible`]`(`[`Check::Vent`]`)`.
    ///
    /// [`Fault::Implausible`]: super::Fault::Implausible
    /// [`Check::Vent`]: super::Check::Vent
    pub vent_flow: f32,
    /// Vent window, control periods; 0 disables the check.
    pub vent_periods: u16,
    /// Least pressure fall over the window with the exhaust open, MPa (> 0).
    pub vent_fall_mpa: f32,
    /// The vent check applies only from this pressure up, MPa (≥ 0): near
    /// atmosphere an open exhaust has nothing left to vent.
    pub vent_min_mpa: f32,
    /// The model as a virtual sensor: the measured contraction must lie in
    /// the band between the model's two branches at the measured pressure
    /// and the active load, `[x_C(p), x_E(p)]` (inverse model, eqs. 25/26),
    /// widened by this much on each side (fraction of rest length, > 0).
    /// Outside it for more than `implausible_periods` periods in a row is
    /// [`Fault::Implausible`]`(`[`Check::Model`]`)`: a contraction sensor
    /// decoupled from the muscle or offset, or a muscle that does not
    /// contract as its pressure says (a torn braid, a wrong load).
    ///
    /// [`Fault::Implausible`]: super::Fault::Implausible
    /// [`Check::Model`]: super::Check::Model
    pub implausible_contraction: f32,
    /// Mechanical lag the band allows for, s (≥ 0): the contraction follows
    /// a pressure change with the muscle's and the load's dynamics, so the
    /// band is taken between the contraction branch at a *lagged minimum*
    /// of the pressure and the expansion branch at a *lagged maximum*
    /// (each follows the pressure at once in the direction that widens the
    /// band and relaxes back with this time constant). 0: no allowance.
    pub implausible_lag_s: f32,
    /// The model check pauses for this long after the tracker switches the
    /// load model, s (≥ 0): a load step moves the muscle along its
    /// dynamics, with the mass of the new load, onto the new load's loop,
    /// and until it gets there the new model's band does not hold it.
    pub implausible_settle_s: f32,
    /// The model check pauses for this long from the controller's start,
    /// s (≥ 0): its first periods drive the muscle from rest to the
    /// set-point, and a slow muscle lags that first rise of the pressure
    /// beyond the band's allowance (`implausible_lag_s`; host-sim's rate
    /// rig, five times the reference's damping, tripped 0.2 s into a run).
    /// The readings' own rules run from the first period.
    pub implausible_start_s: f32,
    /// Periods outside the band before the fault; 0 disables the check.
    /// Covers the mechanical lag behind a pressure change and the tracker's
    /// load debounce after a load step (the model is the old load's until
    /// the tracker switches).
    pub implausible_periods: u16,
    /// Consecutive control periods that overran (the next tick arrived
    /// before the step finished, reported by the image through
    /// `Controller::record_overrun`) before [`Fault::Overrun`]; 0 disables.
    ///
    /// [`Fault::Overrun`]: super::Fault::Overrun
    pub overrun_limit: u16,
    /// Latch: more than this many trips (entries into the safe state from
    /// control) within `latch_window_periods` keep the valves safe until
    /// an explicit `Controller::reset_latch`; 0 disables the latch.
    /// What it mitigates: an intermittent fault (a loose connector giving
    /// one bad sample every few tens of ms) would otherwise cycle the
    /// muscle between control and vent indefinitely.
    pub latch_trips: u16,
    /// The latch's window, control periods (≥ 1): it starts at a trip and
    /// the count restarts at the first trip after it ends.
    pub latch_window_periods: u32,
}

impl SafetyConfig {
    /// The highest pressure the loop commands for a model whose loop closes
    /// at `pmax_mpa`: the lower of it and [`Self::max_command_mpa`]. The law
    /// clamps its command to it; over-pressure is judged from it.
    pub fn command_limit_mpa(&self, pmax_mpa: f32) -> f32 {
        pmax_mpa.min(self.max_command_mpa)
    }
}

/// Which feedforward the outer loop adds to its PI term.
// The model's variant carries its effects (a shape's stroke table is 112
// bytes); the configuration is made once at boot and read by reference, so
// its size costs no copies in the control step.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Feedforward {
    /// The hysteresis model on the active branch, eqs. (25)/(26): the design.
    Hysteresis,
    /// The constraint model alone, eq. (21): no hysteresis compensation
    /// (for comparison).
    Constraint,
    /// None: PI feedback only (for comparison).
    Off,
    /// The hysteresis model with pam-core's non-local memory
    /// ([`pam_core::effects::memory`]): at a reversal inside the loop the
    /// feedforward follows a minor loop from the turning point back to the
    /// previous reversal instead of jumping by `2·be` to the other branch
    /// (the jump the paper's conclusion says non-local memory removes).
    /// With no reversal remembered it is exactly [`Feedforward::Hysteresis`].
    ///
    /// Work per step: pam-core's
    /// [`ReversalStack::feedforward_pressure_mpa`](pam_core::effects::ReversalStack::feedforward_pressure_mpa)
    /// (through [`ModelInverse`](pam_core::feedforward::ModelInverse)):
    /// the minor loop's closed-form solve (one square root) on the cached
    /// loop and one forward evaluation; when a loop starts, its two ends
    /// (branch inverses). Only where the closed form finds no candidate,
    /// [`MEMORY_INVERSE_STEPS`](super::MEMORY_INVERSE_STEPS) bisection steps
    /// of the loop's blend (one division each). bench-m4: 178 instructions
    /// on average, 305 at most, 615 when a loop starts (`memory_inverse`).
    HysteresisMemory(NonLocalMemory),
    /// The hysteresis model with every effect of a diagnosed model
    /// (pam-core's [`Effects`]: memory, rate, creep, width, shape), inverted
    /// by pam-core's [`ModelInverse`](pam_core::feedforward::ModelInverse):
    /// the creep lag in closed form, the shape correction, the offset scaled
    /// by width and rate, the memory's minor loop or the branch. With
    /// [`Effects::NONE`] it is [`Feedforward::Hysteresis`]; with the memory
    /// alone, [`Feedforward::HysteresisMemory`]. What a blob with effects
    /// gives ([`model_from_blob`](crate::boot::model_from_blob)).
    HysteresisEffects(Effects),
    /// The Preisach model of a Preisach blob ([`pam_core::preisach`], magic
    /// `PAMP`, as `pam-lab compare` writes it): pam-core's exact inverse
    /// from the relay states the measured pressure left
    /// ([`super::preisach`]). What a Preisach blob gives
    /// ([`boot`](crate::boot::boot)); only with a Preisach model, which runs
    /// this or [`Feedforward::Off`].
    ///
    /// Work per step: the model's relay update and output (the model
    /// check's prediction) and its inverse, at most `N` = 16 thresholds;
    /// bench-m4: `preisach16_step`, `preisach16_feedforward_far`.
    Preisach,
}

impl Feedforward {
    /// Whether this feedforward runs on a model of the Preisach family
    /// (`Some(true)`), the paper's (`Some(false)`), or either
    /// ([`Feedforward::Off`], `None`).
    pub fn needs_preisach(&self) -> Option<bool> {
        match self {
            Feedforward::Preisach => Some(true),
            Feedforward::Off => None,
            _ => Some(false),
        }
    }
}

/// Gains, rate and limits of the controller.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ControllerConfig {
    /// Control period, s.
    pub dt_s: f32,
    /// Outer loop proportional gain, MPa per unit contraction error.
    pub kp_mpa: f32,
    /// Outer loop integral gain, MPa per (unit contraction error · s).
    pub ki_mpa_per_s: f32,
    /// Bound on the integral term, MPa.
    pub integral_limit_mpa: f32,
    /// Inner loop gain: valve flow command per MPa of pressure error.
    pub pressure_gain_per_mpa: f32,
    /// Feedforward model.
    pub feedforward: Feedforward,
    /// Mode tracker; its drive signal is the desired contraction, so the
    /// direction deadband is in contraction units.
    pub tracker: TrackerConfig,
    /// Safety monitor.
    pub safety: SafetyConfig,
    /// Online adaptation of the model's stroke ([`super::adapt`]); `None`:
    /// the flashed model as it is. Only with [`Feedforward::Hysteresis`] or
    /// [`Feedforward::Constraint`] (the paper's model).
    pub adaptation: Option<AdaptationConfig>,
}

impl ControllerConfig {
    /// 1 kHz, tuned on the simulated muscle of host-sim (a 100–600 N
    /// McKibben muscle with on/off valves on a 0.6 MPa supply).
    pub const DEFAULT: ControllerConfig = ControllerConfig {
        dt_s: 1e-3,
        kp_mpa: 2.0,
        ki_mpa_per_s: 20.0,
        integral_limit_mpa: 0.1,
        pressure_gain_per_mpa: 20.0,
        feedforward: Feedforward::Hysteresis,
        tracker: TrackerConfig::DEFAULT_CONTRACTION,
        safety: SafetyConfig {
            safe_state: SafeState::Exhaust,
            pressure_min_mpa: -0.05,
            pressure_max_mpa: 0.8,
            contraction_min: -0.05,
            contraction_max: 0.4,
            // 5 % of the 100–600 N range of `Params::DEFAULT`; > 15 σ of a
            // 1.5 N RMS load cell.
            load_margin_n: 25.0,
            // host-sim's muscle is characterised to 0.5 MPa on a 0.6 MPa
            // supply; 0.54 + the 0.05 margin trips 10 kPa below the supply,
            // so an inlet stuck open is caught whatever `Pmax` a model has.
            max_command_mpa: 0.54,
            // Pmax 0.5 + 0.05 MPa: 60 σ of the rig's pressure noise, and
            // below the 0.6 MPa supply an inlet stuck open reaches.
            overpressure_margin_mpa: 0.05,
            stuck_samples: 200,
            recovery_samples: 50,
            // 100 ms at 1 kHz: a 1/8" inlet fills the muscle by tenths of
            // an MPa in that time; 10 kPa is 12 σ of the sensor noise.
            supply_loss_flow: 0.95,
            supply_loss_periods: 100,
            supply_loss_rise_mpa: 0.01,
            // The same window for the exhaust, from 0.05 MPa up.
            vent_flow: 0.95,
            vent_periods: 100,
            vent_fall_mpa: 0.01,
            vent_min_mpa: 0.05,
            // host-sim's rig, 900 s of normal runs (three scenarios, five
            // seeds): the largest distance outside the band is 0.025; an
            // offset of 0.05 on the contraction sensor is caught within
            // 160 ms at 100–600 N (host-sim/README.md).
            implausible_contraction: 0.035,
            // The rig's contraction settles within about 50 ms of a step
            // of the chamber pressure.
            implausible_lag_s: 0.05,
            implausible_settle_s: 1.0,
            implausible_start_s: 1.0,
            implausible_periods: 100,
            overrun_limit: 3,
            // A fourth trip within 10 s latches.
            latch_trips: 3,
            latch_window_periods: 10_000,
        },
        adaptation: None,
    };

    /// Check every field; the first bad one is named.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        let non_negative = |v: f32| v.is_finite() && v >= 0.0;
        let fraction = |v: f32| v > 0.0 && v <= 1.0;
        let ordered = |lo: f32, hi: f32| lo.is_finite() && hi.is_finite() && lo < hi;
        let s = &self.safety;
        let memory_ok = match &self.feedforward {
            Feedforward::HysteresisMemory(m) => m.validate().is_ok(),
            _ => true,
        };
        // The inverse integrates the rate filter and the creep lag over one
        // period, which pam-core accepts up to `MAX_STEP_S`.
        let effects_ok = match &self.feedforward {
            Feedforward::HysteresisEffects(e) => e.validate().is_ok() && self.dt_s <= MAX_STEP_S,
            Feedforward::HysteresisMemory(_) => self.dt_s <= MAX_STEP_S,
            _ => true,
        };
        let adaptation_ok = match &self.adaptation {
            Some(a) => {
                a.is_valid(self.dt_s)
                    && matches!(
                        self.feedforward,
                        Feedforward::Hysteresis | Feedforward::Constraint
                    )
            }
            None => true,
        };
        // One row per setting: (holds, setting). The first that fails is named.
        let rules = [
            (positive(self.dt_s), Setting::DtS),
            (non_negative(self.kp_mpa), Setting::KpMpa),
            (non_negative(self.ki_mpa_per_s), Setting::KiMpaPerS),
            (
                non_negative(self.integral_limit_mpa),
                Setting::IntegralLimitMpa,
            ),
            (
                non_negative(self.pressure_gain_per_mpa),
                Setting::PressureGainPerMpa,
            ),
            (
                ordered(s.pressure_min_mpa, s.pressure_max_mpa),
                Setting::PressureRange,
            ),
            (
                ordered(s.contraction_min, s.contraction_max),
                Setting::ContractionRange,
            ),
            (non_negative(s.load_margin_n), Setting::LoadMarginN),
            (positive(s.max_command_mpa), Setting::MaxCommandMpa),
            (
                positive(s.overpressure_margin_mpa),
                Setting::OverpressureMarginMpa,
            ),
            (fraction(s.supply_loss_flow), Setting::SupplyLossFlow),
            (positive(s.supply_loss_rise_mpa), Setting::SupplyLossRiseMpa),
            (fraction(s.vent_flow), Setting::VentFlow),
            (positive(s.vent_fall_mpa), Setting::VentFallMpa),
            (non_negative(s.vent_min_mpa), Setting::VentMinMpa),
            (
                positive(s.implausible_contraction),
                Setting::ImplausibleContraction,
            ),
            (non_negative(s.implausible_lag_s), Setting::ImplausibleLagS),
            (
                non_negative(s.implausible_settle_s),
                Setting::ImplausibleSettleS,
            ),
            (
                non_negative(s.implausible_start_s),
                Setting::ImplausibleStartS,
            ),
            (memory_ok, Setting::MemoryShape),
            (effects_ok, Setting::FeedforwardEffects),
            (s.recovery_samples >= 1, Setting::RecoverySamples),
            (s.latch_window_periods >= 1, Setting::LatchWindowPeriods),
            (adaptation_ok, Setting::Adaptation),
        ];
        for (holds, setting) in rules {
            if !holds {
                return Err(ConfigError::Invalid(setting));
            }
        }
        self.tracker.validate().map_err(ConfigError::Tracker)
    }
}

/// A controller setting, as named by [`ConfigError::Invalid`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Setting {
    /// `dt_s`: finite and > 0 s.
    DtS,
    /// `kp_mpa`: finite and ≥ 0.
    KpMpa,
    /// `ki_mpa_per_s`: finite and ≥ 0.
    KiMpaPerS,
    /// `integral_limit_mpa`: finite and ≥ 0.
    IntegralLimitMpa,
    /// `pressure_gain_per_mpa`: finite and ≥ 0.
    PressureGainPerMpa,
    /// `pressure_min_mpa`, `pressure_max_mpa`: finite, min < max.
    PressureRange,
    /// `contraction_min`, `contraction_max`: finite, min < max.
    ContractionRange,
    /// `load_margin_n`: finite and ≥ 0 N.
    LoadMarginN,
    /// `max_command_mpa`: finite and > 0 MPa.
    MaxCommandMpa,
    /// `overpressure_margin_mpa`: finite and > 0 MPa.
    OverpressureMarginMpa,
    /// `supply_loss_flow`: in (0, 1].
    SupplyLossFlow,
    /// `supply_loss_rise_mpa`: finite and > 0 MPa.
    SupplyLossRiseMpa,
    /// `vent_flow`: in (0, 1].
    VentFlow,
    /// `vent_fall_mpa`: finite and > 0 MPa.
    VentFallMpa,
    /// `vent_min_mpa`: finite and ≥ 0 MPa.
    VentMinMpa,
    /// `implausible_contraction`: finite and > 0.
    ImplausibleContraction,
    /// `implausible_lag_s`: finite and ≥ 0 s.
    ImplausibleLagS,
    /// `implausible_settle_s`: finite and ≥ 0 s.
    ImplausibleSettleS,
    /// `implausible_start_s`: finite and ≥ 0 s.
    ImplausibleStartS,
    /// The non-local memory's shape: finite and in [0.05, 50].
    MemoryShape,
    /// The effects of [`Feedforward::HysteresisEffects`]: each valid
    /// (pam-core's `Effects::validate`), and `dt_s` at most
    /// `pam_core::effects::MAX_STEP_S` for a feedforward with effects.
    FeedforwardEffects,
    /// `recovery_samples`: ≥ 1.
    RecoverySamples,
    /// `latch_window_periods`: ≥ 1.
    LatchWindowPeriods,
    /// `adaptation`: every field in its range
    /// ([`AdaptationConfig::is_valid`]), with the paper's model as
    /// feedforward.
    Adaptation,
    /// `feedforward` for the model the controller runs: a Preisach model
    /// runs [`Feedforward::Preisach`] or [`Feedforward::Off`], the paper's
    /// model every other mode.
    FeedforwardModel,
}

impl Setting {
    /// The field's name in [`ControllerConfig`] / [`SafetyConfig`].
    pub fn name(self) -> &'static str {
        match self {
            Setting::DtS => "dt_s",
            Setting::KpMpa => "kp_mpa",
            Setting::KiMpaPerS => "ki_mpa_per_s",
            Setting::IntegralLimitMpa => "integral_limit_mpa",
            Setting::PressureGainPerMpa => "pressure_gain_per_mpa",
            Setting::PressureRange => "pressure_min_mpa",
            Setting::ContractionRange => "contraction_min",
            Setting::LoadMarginN => "load_margin_n",
            Setting::MaxCommandMpa => "max_command_mpa",
            Setting::OverpressureMarginMpa => "overpressure_margin_mpa",
            Setting::SupplyLossFlow => "supply_loss_flow",
            Setting::SupplyLossRiseMpa => "supply_loss_rise_mpa",
            Setting::VentFlow => "vent_flow",
            Setting::VentFallMpa => "vent_fall_mpa",
            Setting::VentMinMpa => "vent_min_mpa",
            Setting::ImplausibleContraction => "implausible_contraction",
            Setting::ImplausibleLagS => "implausible_lag_s",
            Setting::ImplausibleSettleS => "implausible_settle_s",
            Setting::ImplausibleStartS => "implausible_start_s",
            Setting::MemoryShape | Setting::FeedforwardEffects | Setting::FeedforwardModel => {
                "feedforward"
            }
            Setting::RecoverySamples => "recovery_samples",
            Setting::LatchWindowPeriods => "latch_window_periods",
            Setting::Adaptation => "adaptation",
        }
    }

    /// What the setting must be.
    pub fn requirement(self) -> &'static str {
        match self {
            Setting::DtS => "must be finite and > 0 s",
            Setting::KpMpa
            | Setting::KiMpaPerS
            | Setting::IntegralLimitMpa
            | Setting::PressureGainPerMpa => "must be finite and >= 0",
            Setting::PressureRange => "need finite pressure_min_mpa < pressure_max_mpa",
            Setting::ContractionRange => "need finite contraction_min < contraction_max",
            Setting::LoadMarginN => "must be finite and >= 0 N",
            Setting::MaxCommandMpa
            | Setting::OverpressureMarginMpa
            | Setting::SupplyLossRiseMpa
            | Setting::VentFallMpa => "must be finite and > 0 MPa",
            Setting::SupplyLossFlow | Setting::VentFlow => "must be in (0, 1]",
            Setting::VentMinMpa => "must be finite and >= 0 MPa",
            Setting::ImplausibleLagS | Setting::ImplausibleSettleS | Setting::ImplausibleStartS => {
                "must be finite and >= 0 s"
            }
            Setting::ImplausibleContraction => "must be finite and > 0",
            Setting::MemoryShape => "memory shape must be finite and in [0.05, 50]",
            Setting::FeedforwardEffects => {
                "effects must pass pam-core's validation, with dt_s at most 1 s"
            }
            Setting::FeedforwardModel => {
                "must be Preisach or Off for a Preisach model, and not Preisach for the paper's model"
            }
            Setting::RecoverySamples | Setting::LatchWindowPeriods => "must be >= 1",
            Setting::Adaptation => {
                "needs bound in (0, 0.5], memory_s >= 10 dt_s, max_rate_per_s and max_pressure_rate_mpa_per_s > 0, min_stroke_fraction in [0, 1), pressure_filter_s >= 0, and feedforward Hysteresis or Constraint"
            }
        }
    }
}

/// Why a controller (or the hardware set-up around it) could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ConfigError {
    /// The coefficient blob or parameter set was refused by pam-core.
    Coefficients(pam_core::Error),
    /// The tracker configuration was refused by pam-core.
    Tracker(pam_core::Error),
    /// A controller setting is invalid.
    Invalid(Setting),
    /// A calibration or valve setting of the hardware layer is invalid.
    Hal(HalConfigError),
}

impl From<HalConfigError> for ConfigError {
    fn from(e: HalConfigError) -> Self {
        ConfigError::Hal(e)
    }
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::Coefficients(e) => write!(f, "coefficients refused: {e}"),
            ConfigError::Tracker(e) => write!(f, "tracker configuration refused: {e}"),
            ConfigError::Invalid(s) => write!(f, "`{}` {}", s.name(), s.requirement()),
            ConfigError::Hal(e) => write!(f, "hardware configuration refused: {e}"),
        }
    }
}

impl core::error::Error for ConfigError {}

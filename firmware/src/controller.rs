//! The position loop: hysteresis model as feedforward, PI on contraction,
//! an inner pressure loop to a valve flow command, and the safety monitor.
//!
//! One [`Controller::step`] per control period (`dt_s`):
//!
//! 1. read the pressure, contraction and load sensors ([`Sample::read`]);
//! 2. check every reading: a read error, a non-finite value, a value outside
//!    its plausible range, a reading frozen for more than `stuck_samples`
//!    samples, a load outside the calibrated range of the coefficients by
//!    more than `load_margin_n` (within it, clamped to the range), or a
//!    non-finite set-point is a [`Fault`];
//! 3. feed pam-core's [`Tracker`] with the *desired* contraction as drive
//!    signal (noise-free, so the branch switches as the set-point reverses
//!    instead of a deadband later on a noisy measurement) and the measured
//!    load (which picks the model of the load family, eqs. 16–21);
//! 4. feedforward: the pressure that holds the desired contraction on the
//!    active branch, `HMC` or `HME` of eqs. (25)/(26);
//! 5. PI on the contraction error, added to the feedforward, clamped to the
//!    model's pressure range;
//! 6. inner loop: proportional on the pressure error, to a flow command in
//!    `[-1, 1]` for the [`Valve`]. Proportional alone suffices there: the
//!    chamber integrates flow, so a constant pressure needs zero flow and
//!    the pressure loop has no steady-state error without leaks; leaks are
//!    taken up by the outer integrator.
//!
//! On a fault the valve goes to the configured [`SafeState`] in the same
//! step (so within one control period of the bad reading), the integrator is
//! cleared, and control resumes only after `recovery_samples` consecutive
//! good samples.
//!
//! # Clamps
//! * The desired contraction is clamped to the active model's stroke
//!   `[R_i, Rx_i]`: outside it no pressure holds it, and the integrator
//!   would wind up chasing it.
//! * The pressure command is clamped to `[0, Pmax]` of the model: the muscle
//!   cannot hold negative gauge pressure and the model is not calibrated
//!   above `Pmax`.
//! * The integral term is clamped to `±integral_limit_mpa`, and it is not
//!   advanced while the pressure command is saturated in the direction the
//!   error pushes it (conditional integration): together they bound windup
//!   when the valve or the supply cannot follow.
//! * The valve command is clamped to `[-1, 1]`.
//!
//! # Work per step
//! Three sensor reads, a fixed number of comparisons, one forward model
//! evaluation (one square root) and, on a load switch of the tracker, one
//! [`pam_core::LoadModel`] rebuild. No allocation, no loops over data, no
//! panicking operation (no indexing by runtime values, no division by a
//! runtime value other than in `f32`, which saturates to ±inf or NaN and is
//! clamped).

use crate::hal::{ContractionSensor, LoadCell, PressureSensor, SafeState, SensorErrorKind, Valve};
use pam_core::effects::{NonLocalMemory, Reversal, ReversalStack};
use pam_core::{Branch, Coeffs, LoadModel, Tracker, TrackerConfig, Update};

/// Reversal points the [`Feedforward::HysteresisMemory`] feedforward
/// remembers (nested minor loops); older ones are dropped.
pub const MEMORY_DEPTH: usize = 8;

/// Bisection steps of the minor-loop feedforward's inverse: `Pmax`
/// (0.5 MPa) over 2²⁰ is 5·10⁻⁷ MPa, far below the 2·10⁻⁴ MPa of
/// pam-core's inverse table (`pam_core::load_model::INVERSE_TOLERANCE_MPA`).
pub const MEMORY_INVERSE_STEPS: usize = 20;

/// The hardware a [`Controller`] drives: three sensors and a valve.
///
/// Fields are public so a simulation can reach its mocks between steps.
#[derive(Debug)]
pub struct Io<P, X, L, V> {
    /// Chamber pressure.
    pub pressure: P,
    /// Muscle contraction.
    pub contraction: X,
    /// Load on the muscle.
    pub load: L,
    /// The valve (or valve pair).
    pub valve: V,
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
        }
    }
}

/// Limits of the safety monitor.
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
    pub load_margin_n: f32,
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
    /// the muscle vented in between).
    pub supply_loss_flow: f32,
    /// Supply-loss window, control periods; 0 disables the check.
    pub supply_loss_periods: u16,
    /// Least pressure rise over the window with the inlet open, MPa (> 0;
    /// well above the pressure sensor's noise, 0.8 kPa RMS on the rig).
    pub supply_loss_rise_mpa: f32,
}

/// Which feedforward the outer loop adds to its PI term.
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
    /// Work per step: [`MEMORY_INVERSE_STEPS`] evaluations of the memory's
    /// pressure → contraction curve (each up to three table inverses and one
    /// `powf`) to invert it, since the memory is defined in that direction.
    HysteresisMemory(NonLocalMemory),
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
}

impl ControllerConfig {
    /// 1 kHz, tuned on the simulated muscle of [`crate::plant`] (a 100–600 N
    /// McKibben muscle with on/off valves on a 0.6 MPa supply).
    pub const DEFAULT: ControllerConfig = ControllerConfig {
        dt_s: 1e-3,
        kp_mpa: 2.0,
        ki_mpa_per_s: 20.0,
        integral_limit_mpa: 0.1,
        pressure_gain_per_mpa: 20.0,
        feedforward: Feedforward::Hysteresis,
        tracker: TrackerConfig {
            direction_deadband: 0.002,
            load_threshold_n: 20.0,
            load_debounce_samples: 5,
        },
        safety: SafetyConfig {
            safe_state: SafeState::Exhaust,
            pressure_min_mpa: -0.05,
            pressure_max_mpa: 0.8,
            contraction_min: -0.05,
            contraction_max: 0.4,
            // 5 % of the 100–600 N range of `Params::DEFAULT`; > 15 σ of a
            // 1.5 N RMS load cell.
            load_margin_n: 25.0,
            stuck_samples: 200,
            recovery_samples: 50,
            // 100 ms at 1 kHz: a 1/8" inlet fills the muscle by tenths of
            // an MPa in that time; 10 kPa is 12 σ of the sensor noise.
            supply_loss_flow: 0.95,
            supply_loss_periods: 100,
            supply_loss_rise_mpa: 0.01,
        },
    };

    /// Check every field; the first bad one is named.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let positive = |v: f32| v.is_finite() && v > 0.0;
        let non_negative = |v: f32| v.is_finite() && v >= 0.0;
        if !positive(self.dt_s) {
            return Err(ConfigError::Invalid("dt_s", "must be finite and > 0 s"));
        }
        if !non_negative(self.kp_mpa) {
            return Err(ConfigError::Invalid("kp_mpa", "must be finite and >= 0"));
        }
        if !non_negative(self.ki_mpa_per_s) {
            return Err(ConfigError::Invalid(
                "ki_mpa_per_s",
                "must be finite and >= 0",
            ));
        }
        if !non_negative(self.integral_limit_mpa) {
            return Err(ConfigError::Invalid(
                "integral_limit_mpa",
                "must be finite and >= 0",
            ));
        }
        if !non_negative(self.pressure_gain_per_mpa) {
            return Err(ConfigError::Invalid(
                "pressure_gain_per_mpa",
                "must be finite and >= 0",
            ));
        }
        let s = &self.safety;
        let ordered = |lo: f32, hi: f32| lo.is_finite() && hi.is_finite() && lo < hi;
        if !ordered(s.pressure_min_mpa, s.pressure_max_mpa) {
            return Err(ConfigError::Invalid(
                "pressure_min_mpa",
                "need finite pressure_min_mpa < pressure_max_mpa",
            ));
        }
        if !ordered(s.contraction_min, s.contraction_max) {
            return Err(ConfigError::Invalid(
                "contraction_min",
                "need finite contraction_min < contraction_max",
            ));
        }
        if !non_negative(s.load_margin_n) {
            return Err(ConfigError::Invalid(
                "load_margin_n",
                "must be finite and >= 0 N",
            ));
        }
        if !(s.supply_loss_flow > 0.0 && s.supply_loss_flow <= 1.0) {
            return Err(ConfigError::Invalid(
                "supply_loss_flow",
                "must be in (0, 1]",
            ));
        }
        if !positive(s.supply_loss_rise_mpa) {
            return Err(ConfigError::Invalid(
                "supply_loss_rise_mpa",
                "must be finite and > 0 MPa",
            ));
        }
        if let Feedforward::HysteresisMemory(m) = &self.feedforward {
            if m.validate().is_err() {
                return Err(ConfigError::Invalid(
                    "feedforward",
                    "memory shape must be finite and in [0.05, 50]",
                ));
            }
        }
        if s.recovery_samples == 0 {
            return Err(ConfigError::Invalid("recovery_samples", "must be >= 1"));
        }
        self.tracker.validate().map_err(ConfigError::Tracker)
    }
}

/// Why a controller could not be built.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ConfigError {
    /// The coefficient blob or parameter set was refused by pam-core.
    Coefficients(pam_core::Error),
    /// The tracker configuration was refused by pam-core.
    Tracker(pam_core::Error),
    /// A controller setting is invalid: the field and what it must be.
    Invalid(&'static str, &'static str),
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::Coefficients(e) => write!(f, "coefficients refused: {e}"),
            ConfigError::Tracker(e) => write!(f, "tracker configuration refused: {e}"),
            ConfigError::Invalid(field, want) => write!(f, "`{field}` {want}"),
        }
    }
}

impl core::error::Error for ConfigError {}

/// One sample of the three sensors, errors reduced to their kinds.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample {
    /// Chamber pressure, MPa gauge.
    pub pressure_mpa: Result<f32, SensorErrorKind>,
    /// Contraction, fraction of rest length.
    pub contraction: Result<f32, SensorErrorKind>,
    /// Load, N.
    pub load_n: Result<f32, SensorErrorKind>,
}

impl Sample {
    /// Read each sensor once.
    pub fn read<P, X, L>(pressure: &mut P, contraction: &mut X, load: &mut L) -> Sample
    where
        P: PressureSensor,
        X: ContractionSensor,
        L: LoadCell,
    {
        use crate::hal::SensorError;
        Sample {
            pressure_mpa: pressure.read_pressure_mpa(),
            contraction: contraction.read_contraction().map_err(|e| e.kind()),
            load_n: load.read_load_n().map_err(|e| e.kind()),
        }
    }
}

/// What the valve is told to do.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ValveCommand {
    /// Flow command in `[-1, 1]` ([`Valve::set_flow`]).
    Flow(f32),
    /// The safe state ([`Valve::set_safe`]).
    Safe(SafeState),
}

/// What one step did; the firmware logs `new_fault` and `recovered`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Step {
    /// The active fault (valves safe), if any.
    pub fault: Option<Fault>,
    /// A fault that began (or changed) on this step.
    pub new_fault: Option<Fault>,
    /// The controller left the safe state on this step.
    pub recovered: bool,
    /// Branch of the active model.
    pub branch: Branch,
    /// Feedforward pressure from the hysteresis model, MPa (0 in a fault).
    pub feedforward_mpa: f32,
    /// Pressure set-point of the inner loop, MPa (0 in a fault).
    pub pressure_cmd_mpa: f32,
    /// What the valve was told.
    pub command: ValveCommand,
    /// What the mode tracker did.
    pub tracker: Update,
}

/// Consecutive identical readings of one sensor.
#[derive(Clone, Copy, Debug)]
struct StuckMonitor {
    /// Bits of the last finite reading; a NaN pattern before the first one
    /// (only finite readings are observed, so it never matches). A plain
    /// `u32` rather than an `Option` saves the tag's test and store.
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
    /// times. `limit` is [`stuck_limit`]'s form of `stuck_samples`
    /// (`u16::MAX` for 0, which `repeats`, saturating, never exceeds).
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

/// `stuck_samples` as the bound [`StuckMonitor::observe`] compares with: 0
/// (check disabled) becomes `u16::MAX`, which a saturating count never exceeds.
fn stuck_limit(stuck_samples: u16) -> u16 {
    if stuck_samples == 0 {
        u16::MAX
    } else {
        stuck_samples
    }
}

/// The supply-loss check ([`SafetyConfig::supply_loss_flow`]): how long the
/// inlet has been commanded open and the pressure when that began.
#[derive(Clone, Copy, Debug, Default)]
struct SupplyMonitor {
    /// Flow command issued by the last update (0 after a safe state).
    last_flow: f32,
    /// Pressure read by the last update, MPa.
    last_mpa: f32,
    /// Consecutive periods with the inlet commanded open, counting this one.
    open_periods: u16,
    /// Pressure read when the first of them was issued, MPa.
    start_mpa: f32,
}

impl SupplyMonitor {
    /// Record the pressure read now; true when the supply is lost by the
    /// rule of [`SafetyConfig::supply_loss_flow`].
    fn observe(&mut self, pressure_mpa: f32, s: &SafetyConfig) -> bool {
        let before = self.last_mpa;
        self.last_mpa = pressure_mpa;
        if s.supply_loss_periods == 0 || !(self.last_flow >= s.supply_loss_flow) {
            self.open_periods = 0;
            return false;
        }
        if self.open_periods == 0 {
            self.start_mpa = before;
        }
        self.open_periods = self.open_periods.saturating_add(1);
        if pressure_mpa - self.start_mpa >= s.supply_loss_rise_mpa {
            // Filling: restart the window from here.
            self.open_periods = 0;
            return false;
        }
        self.open_periods >= s.supply_loss_periods
    }

    /// The valves went safe (no flow commanded).
    fn reset(&mut self) {
        self.last_flow = 0.0;
        self.open_periods = 0;
    }
}

/// State of the [`Feedforward::HysteresisMemory`] feedforward: the reversal
/// points `(feedforward pressure, desired contraction)` and the extreme of
/// the current sweep (the next reversal's turning point).
#[derive(Clone, Copy, Debug, Default)]
struct MemoryState {
    stack: ReversalStack<MEMORY_DEPTH>,
    extreme: Option<Reversal>,
}

impl MemoryState {
    fn clear(&mut self) {
        self.stack.clear();
        self.extreme = None;
    }

    /// The feedforward pressure that holds `x_ref` on the memory's curve for
    /// `branch`, then the memory's update for this sample.
    ///
    /// The mode tracker switches the branch only once the set-point has
    /// moved `direction_deadband` back from the sweep's extreme. In between,
    /// following the old branch backwards and then changing curve at the
    /// switch would jump by the two curves' slope difference times the
    /// deadband (up to 0.02 MPa where a minor loop is steep). So while the
    /// set-point is back from the extreme the feedforward already follows
    /// the curve the reversal will start, a trial copy of the memory with
    /// the extreme pushed, on the opposite branch; at the switch the real
    /// memory takes the same push and the feedforward continues without a
    /// step. If the set-point turns again first, that curve passes through
    /// the extreme, so the return to the old sweep is continuous too.
    fn feedforward_mpa(
        &mut self,
        params: &NonLocalMemory,
        model: &LoadModel,
        x_ref: f32,
        branch: Branch,
        branch_switch: bool,
    ) -> f32 {
        if branch_switch {
            if let Some(r) = self.extreme.take() {
                self.stack.push(r);
            }
        }
        if let Some(e) = self.extreme {
            let backing_off = match branch {
                Branch::Contraction => x_ref < e.contraction,
                Branch::Expansion => x_ref > e.contraction,
            };
            if backing_off {
                let mut trial = self.stack;
                trial.push(e);
                return inverse_mpa(&trial, params, model, x_ref, branch.opposite());
            }
        }
        let p_mpa = if self.stack.points().is_empty() {
            // No reversal remembered: `x(p)` is the branch inverse, whose
            // inverse is the forward model, eqs. (25)/(26).
            model.pressure_mpa(x_ref, branch)
        } else {
            inverse_mpa(&self.stack, params, model, x_ref, branch)
        };
        self.stack.wipe_out(p_mpa, branch);
        // At or beyond the sweep's extreme: the turning point of the next reversal.
        self.extreme = Some(Reversal {
            pressure_mpa: p_mpa,
            contraction: x_ref,
        });
        p_mpa
    }
}

/// The pressure in `[0, Pmax]` at which the memory's curve `x(p)` for
/// `branch` reaches `x_ref`: bisection of [`MEMORY_INVERSE_STEPS`] steps, each
/// on a copy of `stack` (a candidate applies its own wiping-out, so a minor
/// loop that closes within this step is inverted correctly).
///
/// Not inlined: it is called from two places, and its body inlines
/// pam-core's table inverse and `powf` (flash budget).
#[inline(never)]
fn inverse_mpa(
    stack: &ReversalStack<MEMORY_DEPTH>,
    params: &NonLocalMemory,
    model: &LoadModel,
    x_ref: f32,
    branch: Branch,
) -> f32 {
    let (mut lo, mut hi) = (0.0f32, model.max_pressure_mpa());
    for _ in 0..MEMORY_INVERSE_STEPS {
        let mid = 0.5 * (lo + hi);
        let mut trial = *stack;
        if trial.contraction(params, model, mid, branch, 1.0) <= x_ref {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The position controller. Holds the coefficients, the mode tracker and the
/// loop state; about 600 bytes, no references.
#[derive(Clone, Debug)]
pub struct Controller {
    coeffs: Coeffs,
    config: ControllerConfig,
    tracker: Tracker,
    integral_mpa: f32,
    fault: Option<Fault>,
    good_run: u16,
    stuck: [StuckMonitor; 3],
    supply: SupplyMonitor,
    memory: MemoryState,
    /// Derived from `config` and `coeffs` once, at construction (`config`
    /// is not changed afterwards), so the step does not recompute them.
    derived: Derived,
}

/// Per-configuration constants of the step, computed in [`Controller::new`].
#[derive(Clone, Copy, Debug)]
struct Derived {
    /// `ki_mpa_per_s · dt_s`: the integrator gain per step.
    ki_dt: f32,
    /// The load's plausible range: the calibrated range widened by
    /// `load_margin_n`, each bound limited to the finite floats (so an
    /// infinite reading is never inside it).
    load_min_n: f32,
    load_max_n: f32,
    /// [`stuck_limit`] of `stuck_samples`.
    stuck_limit: u16,
}

/// `x` limited to `[lo, hi]`, NaN → `lo` (never panics, unlike `f32::clamp`
/// with bad bounds).
fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    if x >= lo {
        if x <= hi {
            x
        } else {
            hi
        }
    } else {
        lo
    }
}

fn check_reading(
    sensor: SensorId,
    reading: Result<f32, SensorErrorKind>,
    lo: f32,
    hi: f32,
    stuck: &mut StuckMonitor,
    stuck_limit: u16,
) -> Option<Fault> {
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
    if !(v >= lo && v <= hi) {
        return Some(Fault::OutOfRange(sensor));
    }
    None
}

impl Controller {
    /// A controller for validated coefficients, starting on the contraction
    /// branch with the model at `initial_load_n` (clamped to the calibrated
    /// range).
    pub fn new(
        coeffs: Coeffs,
        config: ControllerConfig,
        initial_load_n: f32,
    ) -> Result<Controller, ConfigError> {
        config.validate()?;
        let tracker = Tracker::new(&coeffs, config.tracker, initial_load_n, Branch::Contraction)
            .map_err(ConfigError::Tracker)?;
        let p = coeffs.params();
        let s = &config.safety;
        let derived = Derived {
            ki_dt: config.ki_mpa_per_s * config.dt_s,
            load_min_n: clamp(p.min_load_n - s.load_margin_n, f32::MIN, f32::MAX),
            load_max_n: clamp(p.max_load_n + s.load_margin_n, f32::MIN, f32::MAX),
            stuck_limit: stuck_limit(s.stuck_samples),
        };
        Ok(Controller {
            derived,
            coeffs,
            config,
            tracker,
            integral_mpa: 0.0,
            fault: None,
            good_run: 0,
            stuck: [StuckMonitor::default(); 3],
            supply: SupplyMonitor::default(),
            memory: MemoryState::default(),
        })
    }

    /// A controller from a coefficient blob in pam-core's format
    /// ([`pam_core::blob`]: magic, version, length, CRC-32, then the
    /// parameters are validated). A blob that fails any check is refused.
    pub fn from_blob(
        blob: &[u8],
        config: ControllerConfig,
        initial_load_n: f32,
    ) -> Result<Controller, ConfigError> {
        let coeffs = pam_core::blob::decode(blob).map_err(ConfigError::Coefficients)?;
        Controller::new(coeffs, config, initial_load_n)
    }

    /// The coefficients.
    pub fn coeffs(&self) -> &Coeffs {
        &self.coeffs
    }

    /// The configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// The mode tracker (active branch and load model).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// The active fault; `None` while controlling.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// The outer loop's integral term, MPa.
    pub fn integral_mpa(&self) -> f32 {
        self.integral_mpa
    }

    /// One control period: read the sensors, compute, drive the valve.
    ///
    /// If the valve refuses the write, the fault is [`Fault::Valve`] and the
    /// safe state is written once more (best effort).
    pub fn step<P, X, L, V>(&mut self, io: &mut Io<P, X, L, V>, desired_contraction: f32) -> Step
    where
        P: PressureSensor,
        X: ContractionSensor,
        L: LoadCell,
        V: Valve,
    {
        let sample = Sample::read(&mut io.pressure, &mut io.contraction, &mut io.load);
        let mut step = self.update_inline(&sample, desired_contraction);
        let written = match step.command {
            ValveCommand::Flow(c) => io.valve.set_flow(c),
            ValveCommand::Safe(s) => io.valve.set_safe(s),
        };
        if written.is_err() {
            let safe = self.config.safety.safe_state;
            self.enter_fault(Fault::Valve, &mut step);
            step.recovered = false;
            step.command = ValveCommand::Safe(safe);
            // The driver just refused a write; retry the safe state once and
            // stay faulted whatever it returns (the next step retries again).
            let _ = io.valve.set_safe(safe);
        }
        step
    }

    /// The computation of one step on a given sample, without I/O: returns
    /// the valve command to apply. [`step`](Self::step) is `Sample::read`,
    /// this, and the valve write.
    pub fn update(&mut self, sample: &Sample, desired_contraction: f32) -> Step {
        self.update_inline(sample, desired_contraction)
    }

    /// [`update`](Self::update), inlined into [`step`](Self::step) so that
    /// the sample is not stored to memory and read back, and the step is
    /// built in place.
    #[inline(always)]
    fn update_inline(&mut self, sample: &Sample, desired_contraction: f32) -> Step {
        let load_n = sample.load_n.unwrap_or(f32::NAN);
        let tracker = self
            .tracker
            .update(&self.coeffs, desired_contraction, load_n);
        if tracker.load_switch.is_some() {
            // The turning points belong to the old load's loop.
            self.memory.clear();
        }
        let safe = ValveCommand::Safe(self.config.safety.safe_state);
        let mut step = Step {
            fault: None,
            new_fault: None,
            recovered: false,
            branch: self.tracker.branch(),
            feedforward_mpa: 0.0,
            pressure_cmd_mpa: 0.0,
            command: safe,
            tracker,
        };

        if let Some(f) = self.check(sample, desired_contraction) {
            self.enter_fault(f, &mut step);
            return step;
        }
        // The sensors are good here, so the pressure is finite and in range.
        if let Ok(p) = sample.pressure_mpa {
            if self.supply.observe(p, &self.config.safety) {
                self.enter_fault(Fault::SupplyLoss, &mut step);
                return step;
            }
        }
        if let Some(f) = self.fault {
            self.good_run = self.good_run.saturating_add(1);
            if self.good_run < self.config.safety.recovery_samples {
                step.fault = Some(f);
                return step;
            }
            self.fault = None;
            self.good_run = 0;
            step.recovered = true;
        }

        // `check` passed, so these are finite and in range.
        let (pressure_mpa, contraction) = match (sample.pressure_mpa, sample.contraction) {
            (Ok(p), Ok(x)) => (p, x),
            _ => return step,
        };
        let cfg = &self.config;
        let model = self.tracker.model();
        let branch = self.tracker.branch();
        // Clamp: the set-point to the active model's stroke [R_i, Rx_i].
        let x_ref = clamp(
            desired_contraction,
            model.root_contraction(),
            model.max_contraction(),
        );
        let feedforward_mpa = match cfg.feedforward {
            // eqs. (25)/(26): the pressure that holds x_ref on the active branch.
            Feedforward::Hysteresis => model.pressure_mpa(x_ref, branch),
            // eq. (21): the constraint model, between the two branches.
            Feedforward::Constraint => model.constraint_pressure_mpa(x_ref),
            Feedforward::Off => 0.0,
            // eqs. (25)/(26) with pam-core's minor loops between reversals.
            Feedforward::HysteresisMemory(mem) => self.memory.feedforward_mpa(
                &mem,
                model,
                x_ref,
                branch,
                step.tracker.branch_switch.is_some(),
            ),
        };
        let error = x_ref - contraction;
        let max_mpa = model.max_pressure_mpa();
        let unclamped_mpa = feedforward_mpa + cfg.kp_mpa * error + self.integral_mpa;
        // Clamp: the pressure command to the model's range [0, Pmax].
        let pressure_cmd_mpa = clamp(unclamped_mpa, 0.0, max_mpa);
        // Anti-windup, conditional integration: hold the integrator while the
        // command is saturated and the error would push it further out.
        let windup =
            (unclamped_mpa > max_mpa && error > 0.0) || (unclamped_mpa < 0.0 && error < 0.0);
        if !windup {
            // Clamp: the integral term to ±integral_limit_mpa.
            self.integral_mpa = clamp(
                self.integral_mpa + self.derived.ki_dt * error,
                -cfg.integral_limit_mpa,
                cfg.integral_limit_mpa,
            );
        }
        // Inner loop; clamp: the flow command to [-1, 1].
        let flow = clamp(
            cfg.pressure_gain_per_mpa * (pressure_cmd_mpa - pressure_mpa),
            -1.0,
            1.0,
        );
        step.feedforward_mpa = feedforward_mpa;
        step.pressure_cmd_mpa = pressure_cmd_mpa;
        step.command = ValveCommand::Flow(flow);
        self.supply.last_flow = flow;
        step
    }

    fn enter_fault(&mut self, fault: Fault, step: &mut Step) {
        if self.fault != Some(fault) {
            step.new_fault = Some(fault);
        }
        self.fault = Some(fault);
        self.good_run = 0;
        // Bumpless restart: the integral built up before the fault does not
        // apply to the state the muscle is in after it.
        self.integral_mpa = 0.0;
        // The safe state vents (or holds) the muscle: its loop history no
        // longer applies; restart on the major loop.
        self.memory.clear();
        self.supply.reset();
        step.fault = Some(fault);
        step.feedforward_mpa = 0.0;
        step.pressure_cmd_mpa = 0.0;
        step.command = ValveCommand::Safe(self.config.safety.safe_state);
    }

    /// The first fault in this sample, in the order pressure, contraction,
    /// load, set-point. Every sensor is checked every step so that each stuck
    /// counter sees every sample.
    ///
    /// Fast path: when all three reads succeeded and every reading is inside
    /// its plausible range (finite bounds, so the reading is finite too) and
    /// the set-point is finite, the only possible faults are stuck readings;
    /// each counter observes its reading, as in the full check. Anything
    /// else goes to [`check_full`](Self::check_full), which gives the same
    /// answer as before for every sample.
    #[inline(always)]
    fn check(&mut self, sample: &Sample, desired_contraction: f32) -> Option<Fault> {
        let s = &self.config.safety;
        let d = &self.derived;
        if let (Ok(p), Ok(x), Ok(l)) = (sample.pressure_mpa, sample.contraction, sample.load_n) {
            let inside = |v: f32, lo: f32, hi: f32| v >= lo && v <= hi;
            if inside(p, s.pressure_min_mpa, s.pressure_max_mpa)
                && inside(x, s.contraction_min, s.contraction_max)
                && inside(l, d.load_min_n, d.load_max_n)
                && desired_contraction.is_finite()
            {
                let [sp, sx, sl] = &mut self.stuck;
                let stuck_p = sp.observe(p, d.stuck_limit);
                let stuck_x = sx.observe(x, d.stuck_limit);
                let stuck_l = sl.observe(l, d.stuck_limit);
                return if stuck_p {
                    Some(Fault::Stuck(SensorId::Pressure))
                } else if stuck_x {
                    Some(Fault::Stuck(SensorId::Contraction))
                } else if stuck_l {
                    Some(Fault::Stuck(SensorId::Load))
                } else {
                    None
                };
            }
        }
        self.check_full(sample, desired_contraction)
    }

    /// Every check of every reading, in order (the path of a bad sample).
    #[cold]
    #[inline(never)]
    fn check_full(&mut self, sample: &Sample, desired_contraction: f32) -> Option<Fault> {
        let s = &self.config.safety;
        let d = self.derived;
        let [sp, sx, sl] = &mut self.stuck;
        let pressure = check_reading(
            SensorId::Pressure,
            sample.pressure_mpa,
            s.pressure_min_mpa,
            s.pressure_max_mpa,
            sp,
            d.stuck_limit,
        );
        let contraction = check_reading(
            SensorId::Contraction,
            sample.contraction,
            s.contraction_min,
            s.contraction_max,
            sx,
            d.stuck_limit,
        );
        // The load's plausible range is the calibrated range of the model
        // family widened by the margin; inside the margin the tracker clamps
        // the load to the calibrated range (`Coeffs::clamp_load_n`).
        let load = check_reading(
            SensorId::Load,
            sample.load_n,
            d.load_min_n,
            d.load_max_n,
            sl,
            d.stuck_limit,
        );
        let setpoint = (!desired_contraction.is_finite()).then_some(Fault::Setpoint);
        pressure.or(contraction).or(load).or(setpoint)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pam_core::Params;

    fn controller() -> Controller {
        controller_with(ControllerConfig::DEFAULT)
    }

    fn controller_with(config: ControllerConfig) -> Controller {
        Controller::new(Coeffs::new(Params::DEFAULT).unwrap(), config, 200.0).unwrap()
    }

    /// Constant readings for many samples, without tripping the stuck check
    /// or (no plant: the pressure does not follow the valve) the supply check.
    fn no_stuck_check() -> Controller {
        controller_with(synthetic())
    }

    /// [`ControllerConfig::DEFAULT`] for synthetic samples: stuck and
    /// supply-loss checks off.
    fn synthetic() -> ControllerConfig {
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.safety.stuck_samples = 0;
        cfg.safety.supply_loss_periods = 0;
        cfg
    }

    fn good(pressure_mpa: f32, contraction: f32, load_n: f32) -> Sample {
        Sample {
            pressure_mpa: Ok(pressure_mpa),
            contraction: Ok(contraction),
            load_n: Ok(load_n),
        }
    }

    #[test]
    fn at_the_set_point_the_command_is_the_branch_feedforward() {
        let mut c = controller();
        let model = c.tracker().model().clone();
        let x = 0.12;
        let ff = model.pressure_mpa(x, Branch::Contraction);
        let s = c.update(&good(ff, x, 200.0), x);
        assert_eq!(s.fault, None);
        assert_eq!(s.branch, Branch::Contraction);
        assert!((s.feedforward_mpa - ff).abs() < 1e-6);
        assert!((s.pressure_cmd_mpa - ff).abs() < 1e-6);
        assert_eq!(s.command, ValveCommand::Flow(0.0));
    }

    #[test]
    fn feedforward_follows_the_branch_of_the_set_point() {
        let mut c = no_stuck_check();
        let x = 0.12;
        let mut last = c.update(&good(0.2, x, 200.0), x);
        // Rise to 0.15, then fall back to 0.12: the branch turns to expansion
        // and the feedforward at 0.12 drops by twice the ellipse offset.
        let mut sp = x;
        while sp < 0.15 {
            sp += 1e-4;
            last = c.update(&good(0.2 + sp * 1e-3, sp, 200.0), sp);
        }
        assert_eq!(last.branch, Branch::Contraction);
        let up = c.tracker().model().pressure_mpa(x, Branch::Contraction);
        while sp > x {
            sp -= 1e-4;
            last = c.update(&good(0.2 - sp * 1e-3, sp, 200.0), sp);
        }
        assert_eq!(last.branch, Branch::Expansion);
        let m = c.tracker().model();
        let expected = up - 2.0 * m.offset_mpa(sp);
        assert!(
            (last.feedforward_mpa - m.pressure_mpa(sp, Branch::Expansion)).abs() < 1e-6
                && (last.feedforward_mpa - expected).abs() < 1e-3,
            "{} vs {expected}",
            last.feedforward_mpa
        );
    }

    #[test]
    fn pi_pushes_toward_the_set_point_and_the_inner_loop_toward_the_pressure() {
        let mut c = controller();
        // Muscle short of the set-point: more pressure, valve fills.
        let s = c.update(&good(0.1, 0.08, 200.0), 0.12);
        assert!(s.pressure_cmd_mpa > s.feedforward_mpa);
        assert!(matches!(s.command, ValveCommand::Flow(f) if f > 0.0));
        assert!(c.integral_mpa() > 0.0);
        // Pressure above the command: valve vents.
        let s = c.update(&good(0.45, 0.12, 200.0), 0.12);
        assert!(matches!(s.command, ValveCommand::Flow(f) if f < 0.0));
    }

    #[test]
    fn integrator_is_bounded_and_does_not_wind_up_in_saturation() {
        let mut c = no_stuck_check();
        // Set-point beyond reach: the command saturates at Pmax and the
        // integrator stops growing.
        for _ in 0..100_000 {
            let s = c.update(&good(0.5, 0.0, 200.0), 0.2);
            assert_eq!(s.fault, None);
            assert!(s.pressure_cmd_mpa <= Params::DEFAULT.points.max_pressure_mpa);
        }
        let held = c.integral_mpa();
        assert!(
            held < ControllerConfig::DEFAULT.integral_limit_mpa,
            "{held}"
        );
        // A small error unsaturated: bounded by the limit.
        let mut c = no_stuck_check();
        for _ in 0..100_000 {
            assert_eq!(c.update(&good(0.2, 0.119, 200.0), 0.12).fault, None);
        }
        assert!(c.integral_mpa() <= ControllerConfig::DEFAULT.integral_limit_mpa);
        assert!(c.integral_mpa() > 0.0);
    }

    #[test]
    fn set_point_outside_the_stroke_is_clamped() {
        let mut c = controller();
        let m = c.tracker().model().clone();
        let s = c.update(&good(0.5, m.max_contraction(), 200.0), 5.0);
        assert_eq!(s.fault, None);
        assert!((s.feedforward_mpa - m.max_pressure_mpa()).abs() < 1e-6);
    }

    fn faults_then_recovers(bad: Sample, expected: Fault) {
        let mut c = controller();
        let ok = good(0.2, 0.1, 200.0);
        c.update(&ok, 0.1);
        let s = c.update(&bad, 0.1);
        assert_eq!(s.fault, Some(expected));
        assert_eq!(s.new_fault, Some(expected));
        assert_eq!(s.command, ValveCommand::Safe(SafeState::Exhaust));
        assert_eq!(c.integral_mpa(), 0.0);
        let s = c.update(&bad, 0.1);
        assert_eq!(s.new_fault, None, "reported once");
        let n = ControllerConfig::DEFAULT.safety.recovery_samples;
        for k in 1..n {
            // Alternate the readings slightly so nothing looks stuck.
            let x = 0.1 + f32::from(k % 2) * 1e-4;
            let s = c.update(&good(0.2, x, 200.0), 0.1);
            assert_eq!(s.command, ValveCommand::Safe(SafeState::Exhaust), "{k}");
            assert!(!s.recovered);
        }
        let s = c.update(&ok, 0.1);
        assert!(s.recovered);
        assert!(matches!(s.command, ValveCommand::Flow(_)));
        assert_eq!(c.fault(), None);
    }

    #[test]
    fn every_bad_reading_faults_within_one_step_and_recovers_after_a_good_run() {
        use SensorId::*;
        let ok = good(0.2, 0.1, 200.0);
        let cases = [
            (
                Sample {
                    pressure_mpa: Err(SensorErrorKind::Timeout),
                    ..ok
                },
                Fault::Read {
                    sensor: Pressure,
                    kind: SensorErrorKind::Timeout,
                },
            ),
            (
                Sample {
                    contraction: Ok(f32::NAN),
                    ..ok
                },
                Fault::NonFinite(Contraction),
            ),
            (
                Sample {
                    contraction: Ok(f32::NEG_INFINITY),
                    ..ok
                },
                Fault::NonFinite(Contraction),
            ),
            (
                Sample {
                    pressure_mpa: Ok(2.0),
                    ..ok
                },
                Fault::OutOfRange(Pressure),
            ),
            (
                Sample {
                    load_n: Ok(650.0),
                    ..ok
                },
                Fault::OutOfRange(Load),
            ),
            (
                Sample {
                    load_n: Ok(50.0),
                    ..ok
                },
                Fault::OutOfRange(Load),
            ),
            (
                Sample {
                    load_n: Err(SensorErrorKind::Bus),
                    ..ok
                },
                Fault::Read {
                    sensor: Load,
                    kind: SensorErrorKind::Bus,
                },
            ),
        ];
        for (bad, f) in cases {
            faults_then_recovers(bad, f);
        }
    }

    /// A valve whose writes fail while `fail` is set; records the last call.
    struct FlakyValve {
        fail: bool,
        last: Option<ValveCommand>,
    }
    #[derive(Debug)]
    struct Refused;
    impl embedded_hal::pwm::Error for Refused {
        fn kind(&self) -> embedded_hal::pwm::ErrorKind {
            embedded_hal::pwm::ErrorKind::Other
        }
    }
    impl embedded_hal::pwm::ErrorType for FlakyValve {
        type Error = Refused;
    }
    impl Valve for FlakyValve {
        fn set_flow(&mut self, command: f32) -> Result<(), Refused> {
            self.last = Some(ValveCommand::Flow(command));
            if self.fail {
                Err(Refused)
            } else {
                Ok(())
            }
        }
        fn set_safe(&mut self, state: SafeState) -> Result<(), Refused> {
            self.last = Some(ValveCommand::Safe(state));
            if self.fail {
                Err(Refused)
            } else {
                Ok(())
            }
        }
    }

    #[test]
    fn a_refused_valve_write_faults_and_retries_the_safe_state() {
        use crate::plant::{SimBus, SimContraction, SimLoad, SimPressure};
        let bus = SimBus::new();
        let cal = crate::hal::PressureCalibration::ADC12_0_1MPA;
        let mut io = Io {
            pressure: SimPressure {
                bus: &bus,
                calibration: cal,
            },
            contraction: SimContraction(&bus),
            load: SimLoad(&bus),
            valve: FlakyValve {
                fail: false,
                last: None,
            },
        };
        let mut c = controller();
        let mut k = 0u16;
        let mut set = |bus: &SimBus| {
            k += 1;
            bus.pressure_counts
                .set(cal.to_counts(0.1 + f32::from(k % 3) * 1e-3));
            bus.contraction.set(0.05 + f32::from(k % 2) * 1e-4);
            bus.load_n.set(200.0 + f32::from(k % 2));
        };
        set(&bus);
        let s = c.step(&mut io, 0.1);
        assert_eq!(s.fault, None);
        assert!(matches!(io.valve.last, Some(ValveCommand::Flow(f)) if f > 0.0));
        io.valve.fail = true;
        set(&bus);
        let s = c.step(&mut io, 0.1);
        assert_eq!(s.new_fault, Some(Fault::Valve));
        assert_eq!(io.valve.last, Some(ValveCommand::Safe(SafeState::Exhaust)));
        // Writes accepted again: recovery after the good run.
        io.valve.fail = false;
        let n = ControllerConfig::DEFAULT.safety.recovery_samples;
        for _ in 1..n {
            set(&bus);
            assert_eq!(c.step(&mut io, 0.1).fault, Some(Fault::Valve));
        }
        set(&bus);
        assert!(c.step(&mut io, 0.1).recovered);
    }

    #[test]
    fn load_within_the_margin_is_clamped_beyond_it_faults() {
        let p = Params::DEFAULT;
        let margin = ControllerConfig::DEFAULT.safety.load_margin_n;
        assert!(margin > 0.0);
        for (edge, outward) in [(p.max_load_n, 1.0f32), (p.min_load_n, -1.0)] {
            let mut c = no_stuck_check();
            // A noisy cell at the calibrated edge: both sides of it, and up to
            // the margin, never fault.
            for k in 0..200u16 {
                let wobble = outward * margin * (f32::from(k % 5) / 4.0 - 0.25);
                let s = c.update(&good(0.2, 0.1, edge + wobble), 0.1);
                assert_eq!(s.fault, None, "{edge} {wobble}");
            }
            // Readings beyond the edge count as the edge (clamped), so the
            // model is within the inward wobble (a quarter margin) of it.
            let model_n = c.tracker().load_n();
            assert!(
                (model_n - edge).abs() <= 0.25 * margin && (model_n - edge) * outward <= 0.0,
                "{model_n}"
            );
            // Just beyond the margin: fault, same step, valves safe.
            let s = c.update(&good(0.2, 0.1, edge + outward * (margin + 0.5)), 0.1);
            assert_eq!(s.fault, Some(Fault::OutOfRange(SensorId::Load)));
            assert_eq!(s.command, ValveCommand::Safe(SafeState::Exhaust));
        }
        // A zero margin is exactly the calibrated range.
        let mut cfg = synthetic();
        cfg.safety.load_margin_n = 0.0;
        let mut c = controller_with(cfg);
        assert_eq!(c.update(&good(0.2, 0.1, 600.0), 0.1).fault, None);
        assert_eq!(
            c.update(&good(0.2, 0.1, 600.5), 0.1).fault,
            Some(Fault::OutOfRange(SensorId::Load))
        );
    }

    const MEMORY: Feedforward = Feedforward::HysteresisMemory(NonLocalMemory::with_shape(1.0));

    /// Sweep the set-point through `knots` at 1e-4 per sample with readings
    /// at the set-point; returns `(feedforward, branch switched)` per sample.
    fn sweep(c: &mut Controller, knots: &[f32]) -> std::vec::Vec<(f32, bool)> {
        let mut out = std::vec::Vec::new();
        let mut x = knots[0];
        for &target in &knots[1..] {
            while (target - x).abs() > 5e-5 {
                x += (target - x).clamp(-1e-4, 1e-4);
                let s = c.update(&good(0.2, x, 200.0), x);
                assert_eq!(s.fault, None);
                out.push((s.feedforward_mpa, s.tracker.branch_switch.is_some()));
            }
        }
        out
    }

    fn with_feedforward(ff: Feedforward) -> Controller {
        let mut cfg = synthetic();
        cfg.feedforward = ff;
        controller_with(cfg)
    }

    fn largest_jump_at_switch(trace: &[(f32, bool)]) -> f32 {
        trace
            .windows(2)
            .filter(|w| w[1].1)
            .map(|w| (w[1].0 - w[0].0).abs())
            .fold(0.0, f32::max)
    }

    #[test]
    fn memory_feedforward_follows_a_minor_loop_instead_of_jumping() {
        let knots = [0.06, 0.16, 0.08, 0.14, 0.06, 0.16];
        let plain = sweep(&mut with_feedforward(Feedforward::Hysteresis), &knots);
        let mut c = with_feedforward(MEMORY);
        let mem = sweep(&mut c, &knots);
        assert_eq!(plain.len(), mem.len());
        assert_eq!(mem.iter().filter(|s| s.1).count(), 4);
        // The paper's model jumps by about 2·be at each switch.
        let be2 = 2.0 * c.tracker().model().offset_mpa(0.11);
        assert!(largest_jump_at_switch(&plain) > 0.5 * be2);
        // With the memory the feedforward has no step at a switch: it
        // changes only as the set-point moves (1e-4 per sample).
        let at_switch = largest_jump_at_switch(&mem);
        assert!(at_switch < 2e-3, "{at_switch} vs 2be {be2}");
        let worst = mem
            .windows(2)
            .map(|w| (w[1].0 - w[0].0).abs())
            .fold(0.0, f32::max);
        assert!(worst < 2e-3, "{worst}");
        // Up to the first turning point it is the plain model exactly.
        let top = mem.iter().zip(&plain).position(|(m, p)| m != p).unwrap();
        let first = mem.iter().position(|s| s.1).unwrap();
        // 1000 samples from 0.06 to 0.16; it differs only once backing off.
        assert!(top >= 1000 && top < first, "{top} {first}");
        // After the last sweep passes every earlier turning point the loops
        // have closed: back on the contraction branch of the plain model.
        let (m, p) = (mem.last().unwrap().0, plain.last().unwrap().0);
        assert!((m - p).abs() < 1e-3, "{m} vs {p}");
    }

    #[test]
    fn memory_is_cleared_by_a_fault_and_by_a_load_switch() {
        let mut c = with_feedforward(MEMORY);
        sweep(&mut c, &[0.06, 0.16, 0.12]);
        let model = c.tracker().model().clone();
        // Inside a minor loop: between the branches.
        let x = 0.12;
        let s = c.update(&good(0.2, x + 1e-4, 200.0), x);
        let (up, down) = (
            model.pressure_mpa(x, Branch::Contraction),
            model.pressure_mpa(x, Branch::Expansion),
        );
        assert!(
            s.feedforward_mpa > down + 1e-3 && s.feedforward_mpa < up,
            "{s:?}"
        );
        // A fault vents the muscle: the loop history is gone.
        c.update(&good(2.0, x, 200.0), x);
        let n = ControllerConfig::DEFAULT.safety.recovery_samples;
        let mut last = None;
        for k in 0..n {
            last = Some(c.update(&good(0.2, x + f32::from(k % 2) * 1e-4, 200.0), x));
        }
        let s = last.unwrap();
        assert!(s.recovered);
        assert!((s.feedforward_mpa - down).abs() < 1e-6, "{s:?}");
        // A load switch: the old load's turning points do not apply.
        let mut c = with_feedforward(MEMORY);
        sweep(&mut c, &[0.06, 0.16, 0.12]);
        let mut s = c.update(&good(0.2, x, 400.0), x);
        while s.tracker.load_switch.is_none() {
            s = c.update(&good(0.2, x, 400.0), x);
        }
        let m = c.tracker().model();
        assert!((s.feedforward_mpa - m.pressure_mpa(x, Branch::Expansion)).abs() < 1e-6);
    }

    #[test]
    fn memory_shape_is_validated() {
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.feedforward = MEMORY;
        cfg.validate().unwrap();
        for shape in [0.0, f32::NAN, 51.0] {
            cfg.feedforward = Feedforward::HysteresisMemory(NonLocalMemory::with_shape(shape));
            assert!(matches!(
                cfg.validate(),
                Err(ConfigError::Invalid("feedforward", _))
            ));
        }
    }

    /// Readings with the muscle short of a far set-point (inlet saturated
    /// open), the pressure at `p` dithered by a count so nothing is stuck.
    fn starved(k: u32, p: f32) -> Sample {
        let d = (k % 2) as f32;
        good(p + d * 3e-4, 0.02 + (k % 3) as f32 * 1e-4, 200.0 + d)
    }

    #[test]
    fn supply_loss_faults_after_the_window_and_retries() {
        let s = ControllerConfig::DEFAULT.safety;
        let n = u32::from(s.supply_loss_periods);
        let mut c = controller();
        // Update 0 issues the first full-open command; update k sees the
        // pressure after k open periods. The pressure does not rise.
        for k in 0..n {
            let st = c.update(&starved(k, 0.1), 0.15);
            assert_eq!(st.fault, None, "update {k}");
            assert!(matches!(st.command, ValveCommand::Flow(f) if f >= s.supply_loss_flow));
        }
        let st = c.update(&starved(n, 0.1), 0.15);
        assert_eq!(st.new_fault, Some(Fault::SupplyLoss));
        assert_eq!(st.command, ValveCommand::Safe(SafeState::Exhaust));
        // Sensors are fine: control retries after the recovery run, and the
        // check trips again one window later while nothing rises.
        let r = u32::from(s.recovery_samples);
        let mut k = n + 1;
        let mut recovered_at = None;
        let mut tripped_at = None;
        while tripped_at.is_none() && k < 10 * n {
            let st = c.update(&starved(k, 0.1), 0.15);
            if st.recovered {
                recovered_at = Some(k);
            }
            if st.new_fault == Some(Fault::SupplyLoss) {
                tripped_at = Some(k);
            }
            k += 1;
        }
        assert_eq!(recovered_at, Some(n + r));
        assert_eq!(tripped_at, Some(n + r + n));
    }

    #[test]
    fn a_filling_muscle_never_trips_the_supply_check() {
        let s = ControllerConfig::DEFAULT.safety;
        let mut c = controller();
        // Rising by exactly the threshold per window, inlet saturated all along.
        let per_sample = s.supply_loss_rise_mpa / f32::from(s.supply_loss_periods) * 1.01;
        let mut open = 0;
        for k in 0..4000u32 {
            let p = k as f32 * per_sample;
            let st = c.update(&starved(k, p), 0.15);
            assert_eq!(st.fault, None, "update {k} at {p} MPa");
            if matches!(st.command, ValveCommand::Flow(f) if f >= s.supply_loss_flow) {
                open += 1;
            }
        }
        assert!(open > 3000, "{open}");
        // Slower than the threshold: trips.
        let mut c = controller();
        let per_sample = s.supply_loss_rise_mpa / f32::from(s.supply_loss_periods) * 0.9;
        let tripped = (0..4000u32)
            .map(|k| c.update(&starved(k, 0.1 + k as f32 * per_sample), 0.15))
            .any(|st| st.fault == Some(Fault::SupplyLoss));
        assert!(tripped);
        // Disabled with 0 periods.
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.safety.supply_loss_periods = 0;
        let mut c = controller_with(cfg);
        for k in 0..1000u32 {
            assert_eq!(c.update(&starved(k, 0.1), 0.15).fault, None);
        }
    }

    #[test]
    fn supply_loss_settings_are_validated() {
        for (flow, rise, field) in [
            (0.0, 0.01, "supply_loss_flow"),
            (1.5, 0.01, "supply_loss_flow"),
            (f32::NAN, 0.01, "supply_loss_flow"),
            (0.95, 0.0, "supply_loss_rise_mpa"),
            (0.95, f32::INFINITY, "supply_loss_rise_mpa"),
        ] {
            let mut cfg = ControllerConfig::DEFAULT;
            cfg.safety.supply_loss_flow = flow;
            cfg.safety.supply_loss_rise_mpa = rise;
            assert!(
                matches!(cfg.validate(), Err(ConfigError::Invalid(f, _)) if f == field),
                "{flow} {rise}"
            );
        }
    }

    #[test]
    fn non_finite_set_point_faults() {
        let mut c = controller();
        let s = c.update(&good(0.2, 0.1, 200.0), f32::NAN);
        assert_eq!(s.fault, Some(Fault::Setpoint));
    }

    #[test]
    fn frozen_reading_is_stuck_after_the_limit() {
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.safety.supply_loss_periods = 0;
        let mut c = controller_with(cfg);
        let limit = ControllerConfig::DEFAULT.safety.stuck_samples;
        for k in 0..=limit {
            let p = 0.2 + f32::from(k % 3) * 1e-4;
            let s = c.update(&good(p, 0.1, 200.0 + f32::from(k % 2)), 0.1);
            assert_eq!(s.fault, None, "sample {k}");
        }
        let s = c.update(&good(0.2, 0.1, 200.0), 0.1);
        assert_eq!(s.fault, Some(Fault::Stuck(SensorId::Contraction)));
    }

    #[test]
    fn config_validation_names_the_field() {
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.validate().unwrap();
        cfg.dt_s = f32::NAN;
        assert!(matches!(
            cfg.validate(),
            Err(ConfigError::Invalid("dt_s", _))
        ));
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.safety.recovery_samples = 0;
        assert!(matches!(
            cfg.validate(),
            Err(ConfigError::Invalid("recovery_samples", _))
        ));
        for bad in [-1.0, f32::NAN, f32::INFINITY] {
            let mut cfg = ControllerConfig::DEFAULT;
            cfg.safety.load_margin_n = bad;
            assert!(matches!(
                cfg.validate(),
                Err(ConfigError::Invalid("load_margin_n", _))
            ));
        }
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.tracker.load_debounce_samples = 0;
        assert!(matches!(cfg.validate(), Err(ConfigError::Tracker(_))));
    }

    #[test]
    fn blob_is_checked_at_construction() {
        let blob = pam_core::blob::encode(&Params::DEFAULT);
        assert!(Controller::from_blob(&blob, ControllerConfig::DEFAULT, 200.0).is_ok());
        let mut bad = blob;
        bad[20] ^= 0x10;
        assert_eq!(
            Controller::from_blob(&bad, ControllerConfig::DEFAULT, 200.0).unwrap_err(),
            ConfigError::Coefficients(pam_core::Error::Blob("CRC mismatch"))
        );
        let mut p = Params::DEFAULT;
        p.points.max_pressure_mpa = -1.0;
        assert!(matches!(
            Controller::from_blob(
                &pam_core::blob::encode(&p),
                ControllerConfig::DEFAULT,
                200.0
            ),
            Err(ConfigError::Coefficients(_))
        ));
    }

    #[test]
    fn arbitrary_samples_never_panic_and_never_command_nan() {
        for ff in [Feedforward::Hysteresis, MEMORY] {
            arbitrary_samples_with(ff);
        }
    }

    fn arbitrary_samples_with(ff: Feedforward) {
        let mut c = with_feedforward(ff);
        let values = [
            f32::NAN,
            f32::INFINITY,
            -1e30,
            -0.01,
            0.0,
            0.1,
            0.3,
            0.6,
            250.0,
            1e30,
        ];
        for &p in &values {
            for &x in &values {
                for &l in &values {
                    for &sp in &values {
                        let s = c.update(&good(p, x, l), sp);
                        if let ValveCommand::Flow(f) = s.command {
                            assert!((-1.0..=1.0).contains(&f), "{p} {x} {l} {sp}: {f}");
                        }
                        assert!(s.pressure_cmd_mpa.is_finite());
                        assert!(s.feedforward_mpa.is_finite());
                    }
                }
            }
        }
    }
}

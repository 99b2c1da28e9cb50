//! The position loop: hysteresis model as feedforward, PI on contraction,
//! an inner pressure loop to a valve flow command, and the safety monitor.
//!
//! | module | concept |
//! |---|---|
//! | [`config`] | [`ControllerConfig`], [`SafetyConfig`], their validation, typed [`ConfigError`] |
//! | [`io`] | [`Io`] (the hardware), [`Sample`], [`ValveCommand`] |
//! | [`monitor`] | the safety monitor: [`Fault`], the rule table, responses, the model as a virtual sensor, the latch |
//! | [`law`] | the control law: feedforward, PI with anti-windup, inner pressure loop |
//! | [`adapt`] | online adaptation of the model's stroke: bounded RLS with forgetting, frozen in transients and faults, [`Fault::Drifted`] at its bound |
//!
//! One [`Controller::step`] per control period (`dt_s`):
//!
//! 1. read the pressure, contraction and load sensors ([`Sample::read`]);
//! 2. check every reading *before anything uses it*: a read error, a
//!    non-finite value, a reading frozen for more than `stuck_samples`
//!    samples, a value outside its plausible range, a pressure above
//!    `min(Pmax, max_command_mpa) + overpressure_margin_mpa`, a load outside the calibrated range
//!    of the coefficients by more than `load_margin_n` (within it, clamped
//!    to the range), or a non-finite set-point is a [`Fault`];
//! 3. feed pam-core's [`Tracker`] with the *desired* contraction as drive
//!    signal (noise-free, so the branch switches as the set-point reverses
//!    instead of a deadband later on a noisy measurement) and the checked
//!    load (which picks the model of the load family, eqs. 16–21);
//! 4. check the pressure's response to the last valve command (supply
//!    loss, a vent that does not vent) and overruns;
//! 5. feedforward: the pressure that holds the desired contraction on the
//!    active branch, `HMC` or `HME` of eqs. (25)/(26);
//! 6. PI on the contraction error, added to the feedforward, clamped to the
//!    model's pressure range;
//! 7. inner loop: proportional on the pressure error, to a flow command in
//!    `[-1, 1]` for the [`Valve`]. Proportional alone suffices there: the
//!    chamber integrates flow, so a constant pressure needs zero flow and
//!    the pressure loop has no steady-state error without leaks; leaks are
//!    taken up by the outer integrator;
//! 8. check the measured contraction against the model's band at the
//!    measured pressure (the model as a virtual sensor); where it trips,
//!    the safe state replaces the command of step 7 in the same period. A
//!    period whose memory feedforward made a minor loop's ends leaves
//!    this check's two inverses to the next one: its count holds.
//!
//! On a fault the valve goes to the configured [`SafeState`] in the same
//! step (so within one control period of the bad reading), the integrator is
//! cleared, and control resumes only after `recovery_samples` consecutive
//! good samples — unless the fault was the `latch_trips + 1`-th trip within
//! `latch_window_periods`: then the safe state is latched until
//! [`Controller::reset_latch`].
//!
//! # Work per step
//! Three sensor reads, a fixed number of comparisons, one forward model
//! evaluation and two inverse evaluations (the plausibility band) and,
//! after a load switch, at most [`TABLE_BUILD_UNITS_PER_STEP`] units of the
//! new model's inverse-table build per step until it is complete (the new
//! model's forward evaluation is active from the switch). A feedforward
//! with effects adds pam-core's `ModelInverse` (bounded loops only: the
//! shape's Newton steps and the memory's bisections of fixed length, `N/2 + 1`
//! wipe-out passes) and builds [`TABLE_BUILD_UNITS_PER_STEP_EFFECTS`] units
//! per step instead ([`TABLE_BUILD_UNITS_PER_STEP_MEMORY_RATE`] with the
//! memory and the rate law together). No allocation, no loops over data, no
//! panicking operation (no indexing by runtime values, no division by a
//! runtime value other than in `f32`, which saturates to ±inf or NaN and is
//! clamped).

pub mod adapt;
pub mod config;
pub mod io;
pub mod law;
pub mod monitor;
pub mod preisach;
#[cfg(test)]
mod tests;

pub use adapt::{Adaptation, AdaptationConfig};
pub use config::{ConfigError, ControllerConfig, Feedforward, SafetyConfig, Setting};
pub use io::{Io, Sample, ValveCommand};
pub use law::{MEMORY_DEPTH, MEMORY_INVERSE_STEPS};
pub use monitor::{Check, Fault, ModelLimits, SensorId};
pub use preisach::{PreisachModel, PreisachTable16};

use crate::hal::{ContractionSensor, LoadCell, PressureSensor, SafeState, Valve};
use law::Law;
use monitor::Monitor;
use pam_core::{Branch, Coeffs, Tracker, Update};

/// Work units of a load switch's inverse-table build per step (one forward
/// evaluation or one Newton step each, see [`Tracker::set_build_budget`]),
/// done at the end of the step; none on a step whose memory feedforward
/// computed or searched for a minor loop's ends (`Law::rebuilt_loop`).
/// Chosen with bench-m4 so that the step's worst case stays under 2 000
/// instructions; a complete build then takes at most
/// `pam_core::load_model::BUILD_UNITS_MAX / 10` = 176 periods. The new
/// load's forward model (the feedforward) is active from the switch; while
/// its tables are built the model check is paused and the memory
/// feedforward's branch inverse is pam-core's slower table-free one.
pub const TABLE_BUILD_UNITS_PER_STEP: u16 = 10;

/// [`TABLE_BUILD_UNITS_PER_STEP`] for a feedforward that inverts effects
/// other than the memory ([`Feedforward::HysteresisEffects`]): its step costs
/// more (the shape's inverse, the rate law's `powf`), so fewer units keep
/// the worst case under 2 000 instructions (bench-m4); a complete build
/// then takes at most `BUILD_UNITS_MAX / 4` = 440 periods.
pub const TABLE_BUILD_UNITS_PER_STEP_EFFECTS: u16 = 4;

/// [`TABLE_BUILD_UNITS_PER_STEP_EFFECTS`] for a feedforward that inverts
/// the memory and the rate law together: the rate law changes the offset
/// scale every period, so every period on a minor loop moves the loop's two
/// ends (a Newton step each) and both its points to the new scale, about
/// 400 instructions on the M4F over a loop served from its cache. With four
/// units (100–120 instructions each) such periods of a build reached 2 072
/// (bench-m4's `memory_rate`), with three 2 009 once the memory's minor
/// loops were kept from running backwards (their inverse leaves a
/// reversal by its closed form, not at the turning point); with two they
/// stay under 2 000, and a complete build takes at most
/// `BUILD_UNITS_MAX / 2` = 880 periods.
pub const TABLE_BUILD_UNITS_PER_STEP_MEMORY_RATE: u16 = 2;

/// The table-build units per step for `feedforward`.
fn table_build_units(feedforward: &Feedforward) -> u16 {
    match feedforward {
        Feedforward::HysteresisEffects(e) if e.memory.is_some() && e.rate.is_some() => {
            TABLE_BUILD_UNITS_PER_STEP_MEMORY_RATE
        }
        Feedforward::HysteresisEffects(e)
            if e.rate.is_some() || e.creep.is_some() || e.width.is_some() || e.shape.is_some() =>
        {
            TABLE_BUILD_UNITS_PER_STEP_EFFECTS
        }
        _ => TABLE_BUILD_UNITS_PER_STEP,
    }
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
    /// The safe state is latched (until [`Controller::reset_latch`]).
    pub latched: bool,
    /// Branch of the active model.
    pub branch: Branch,
    /// Feedforward pressure from the hysteresis model, MPa (0 in a fault).
    pub feedforward_mpa: f32,
    /// Pressure set-point of the inner loop, MPa (0 in a fault).
    pub pressure_cmd_mpa: f32,
    /// What the valve was told.
    pub command: ValveCommand,
    /// What the mode tracker did (nothing on a step whose readings faulted:
    /// the tracker sees only checked readings).
    pub tracker: Update,
    /// How far the measured contraction lay outside the model's band at the
    /// measured pressure, before the bound `implausible_contraction` (0
    /// inside the band, or when the check did not run: in a fault, paused,
    /// or on a period whose memory feedforward made a minor loop's ends).
    pub model_excess: f32,
}

/// The model a controller runs, from its blob.
// The Preisach variant carries its table (6 KB) and the running model's
// two coefficient buffers; the controller is built once and stays in one
// place (a static on the chip), so the size costs no copies per step.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum Model {
    /// The paper's model: the coefficients and the mode tracker (branch,
    /// active load model, its inverse tables).
    Paper { coeffs: Coeffs, tracker: Tracker },
    /// A Preisach model ([`preisach`]).
    Preisach(PreisachModel),
}

/// The position controller: the model (coefficients and mode tracker, or a
/// Preisach table and its running model), configuration, the law's state
/// and the monitor's; no references.
#[derive(Clone, Debug)]
pub struct Controller {
    model: Model,
    config: ControllerConfig,
    law: Law,
    monitor: Monitor,
    fault: Option<Fault>,
    good_run: u16,
    /// `ki_mpa_per_s · dt_s`, computed once.
    ki_dt: f32,
    /// Table-build units per step ([`table_build_units`]).
    build_units: u16,
    /// Updates since construction (wrapping), for the latch window.
    period: u32,
    /// The online adaptation, when configured.
    adaptation: Option<Adaptation>,
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
        if config.feedforward.needs_preisach() == Some(true) {
            return Err(ConfigError::Invalid(Setting::FeedforwardModel));
        }
        let mut tracker =
            Tracker::new(&coeffs, config.tracker, initial_load_n, Branch::Contraction)
                .map_err(ConfigError::Tracker)?;
        // A load switch's table build, spread over the periods that follow
        // it: the step's worst case stays bounded (bench-m4 `load_switch`).
        tracker.defer_build();
        // `validate` checked the effects and the period the inverse needs.
        let law = Law::new(&config, coeffs.params().points.max_pressure_mpa)
            .map_err(ConfigError::Coefficients)?;
        Ok(Controller {
            monitor: Monitor::new(
                &config.safety,
                &ModelLimits::of_coeffs(&coeffs),
                config.dt_s,
                law::inverted_effects(&config.feedforward).and_then(|e| {
                    let creep = e.creep.map(|c| c.time_constant_s);
                    let lag = e.pressure_lag.map(|l| l.time_constant_s);
                    match (creep, lag) {
                        (Some(a), Some(b)) => Some(a.max(b)),
                        (a, b) => a.or(b),
                    }
                }),
            ),
            ki_dt: config.ki_mpa_per_s * config.dt_s,
            build_units: table_build_units(&config.feedforward),
            adaptation: config.adaptation.map(|a| Adaptation::new(&a, config.dt_s)),
            model: Model::Paper { coeffs, tracker },
            config,
            law,
            fault: None,
            good_run: 0,
            period: 0,
        })
    }

    /// A controller for a validated Preisach table (pam-core's blob
    /// decoder validates it), with the model at `initial_load_n` and every
    /// relay off (the muscle empty). The feedforward must be
    /// [`Feedforward::Preisach`] or [`Feedforward::Off`], without the
    /// online adaptation (it adapts the paper model's stroke).
    ///
    /// The safety monitor is the same: its load range and over-pressure
    /// limit come from the table ([`PreisachModel::limits`]), and the model
    /// check judges the measured contraction against the model's forward
    /// output at the measured pressure (`monitor::Monitor::check_prediction`).
    pub fn new_preisach(
        table: PreisachTable16,
        config: ControllerConfig,
        initial_load_n: f32,
    ) -> Result<Controller, ConfigError> {
        config.validate()?;
        if config.feedforward.needs_preisach() == Some(false) {
            return Err(ConfigError::Invalid(Setting::FeedforwardModel));
        }
        if config.adaptation.is_some() {
            return Err(ConfigError::Invalid(Setting::Adaptation));
        }
        let model = PreisachModel::new(table, initial_load_n);
        let limits = model.limits();
        let law = Law::new(&config, limits.max_pressure_mpa).map_err(ConfigError::Coefficients)?;
        Ok(Controller {
            monitor: Monitor::new(&config.safety, &limits, config.dt_s, None),
            ki_dt: config.ki_mpa_per_s * config.dt_s,
            build_units: table_build_units(&config.feedforward),
            adaptation: None,
            model: Model::Preisach(model),
            config,
            law,
            fault: None,
            good_run: 0,
            period: 0,
        })
    }

    /// The paper model's coefficients; `None` for a Preisach model.
    pub fn coeffs(&self) -> Option<&Coeffs> {
        match &self.model {
            Model::Paper { coeffs, .. } => Some(coeffs),
            Model::Preisach(_) => None,
        }
    }

    /// The Preisach model; `None` for the paper's.
    pub fn preisach(&self) -> Option<&PreisachModel> {
        match &self.model {
            Model::Paper { .. } => None,
            Model::Preisach(m) => Some(m),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// The mode tracker (active branch and load model) of the paper's
    /// model; `None` for a Preisach model.
    pub fn tracker(&self) -> Option<&Tracker> {
        match &self.model {
            Model::Paper { tracker, .. } => Some(tracker),
            Model::Preisach(_) => None,
        }
    }

    /// The load the active model is for, N (the tracker's, or the Preisach
    /// model's active load).
    pub fn model_load_n(&self) -> f32 {
        match &self.model {
            Model::Paper { tracker, .. } => tracker.load_n(),
            Model::Preisach(m) => m.load_n(),
        }
    }

    /// What the monitor's rules take from the model: its calibrated load
    /// range and the pressure it is calibrated to.
    pub fn model_limits(&self) -> ModelLimits {
        match &self.model {
            Model::Paper { coeffs, .. } => ModelLimits::of_coeffs(coeffs),
            Model::Preisach(m) => m.limits(),
        }
    }

    /// The active fault; `None` while controlling.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// Whether the safe state is latched.
    pub fn latched(&self) -> bool {
        self.monitor.latched()
    }

    /// The online adaptation's state (its stroke scale), when configured.
    pub fn adaptation(&self) -> Option<&Adaptation> {
        self.adaptation.as_ref()
    }

    /// The outer loop's integral term, MPa.
    pub fn integral_mpa(&self) -> f32 {
        self.law.integral_mpa
    }

    /// Enter the safe state latched with `fault`, without a step: for boot
    /// after a reset that must not resume control on its own (the board
    /// image does this after an independent-watchdog reset). The caller has
    /// already put the valves safe; every step from now on commands the
    /// safe state until [`reset_latch`](Self::reset_latch).
    pub fn latch(&mut self, fault: Fault) {
        self.fault = Some(fault);
        self.good_run = 0;
        self.law.reset();
        self.monitor.went_safe();
        self.monitor.latch();
    }

    /// The operator's reset of a latched safe state: the latch and its trip
    /// count are cleared, and control resumes after `recovery_samples` good
    /// samples from here (the valves stay safe until then).
    pub fn reset_latch(&mut self) {
        self.monitor.reset_latch();
        self.good_run = 0;
    }

    /// Report whether the control period that just ended overran (the next
    /// tick arrived before its step finished). `overrun_limit` overruns in
    /// a row are [`Fault::Overrun`] at the next step.
    pub fn record_overrun(&mut self, overran: bool) {
        self.monitor.record_overrun(overran);
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
        let step = self.compute(sample, desired_contraction);
        // The new load's tables, after everything else of the period: a
        // period whose memory feedforward computed a minor loop's ends (two
        // table-free inverses) or searched for them leaves the build to the
        // next one (and does not call it: a call for no units still costs
        // its entry). A Preisach model makes a new load's coefficients in
        // its own update.
        if let Model::Paper { tracker, .. } = &mut self.model {
            if !tracker.inverse_ready() && !self.law.rebuilt_loop() {
                tracker.advance_build(self.build_units);
            }
        }
        step
    }

    /// Everything of a period but the table build.
    #[inline(always)]
    fn compute(&mut self, sample: &Sample, desired_contraction: f32) -> Step {
        self.period = self.period.wrapping_add(1);
        let mut step = Step {
            fault: None,
            new_fault: None,
            recovered: false,
            latched: self.monitor.latched(),
            branch: match &self.model {
                Model::Paper { tracker, .. } => tracker.branch(),
                // No branches: see `preisach_period`.
                Model::Preisach(_) => Branch::Contraction,
            },
            feedforward_mpa: 0.0,
            pressure_cmd_mpa: 0.0,
            command: ValveCommand::Safe(self.config.safety.safe_state),
            tracker: Update::default(),
            model_excess: 0.0,
        };
        // 2. The readings, before the tracker or the law sees them.
        if let Some(f) = self.monitor.check(sample, desired_contraction) {
            self.enter_fault(f, &mut step);
            return step;
        }
        // `check` passed, so all three are finite and in range.
        let (pressure_mpa, contraction, load_n) =
            match (sample.pressure_mpa, sample.contraction, sample.load_n) {
                (Ok(p), Ok(x), Ok(l)) => (p, x, l),
                _ => return step,
            };
        match self.model {
            Model::Paper { .. } => {
                self.paper_period(step, desired_contraction, pressure_mpa, contraction, load_n)
            }
            Model::Preisach(_) => {
                self.preisach_period(step, desired_contraction, pressure_mpa, contraction, load_n)
            }
        }
    }

    /// Steps 3–7 with the paper's model, on checked readings.
    #[inline(always)]
    fn paper_period(
        &mut self,
        mut step: Step,
        desired_contraction: f32,
        pressure_mpa: f32,
        contraction: f32,
        load_n: f32,
    ) -> Step {
        let Model::Paper { coeffs, tracker } = &mut self.model else {
            return step;
        };
        // 3. The tracker.
        step.tracker = tracker.update(coeffs, desired_contraction, load_n);
        if step.tracker.load_switch.is_some() {
            self.law.load_switched();
            self.monitor.load_switched();
        } else if !tracker.inverse_ready() {
            // The new load's inverse tables are still being built: the
            // model check (two inverses) stays paused until they are, and
            // for its settling time after.
            self.monitor.load_switched();
        }
        step.branch = tracker.branch();
        // 4. Responses, timing, and (while controlling) the model.
        if let Some(f) = self.monitor.check_response(pressure_mpa) {
            self.enter_fault(f, &mut step);
            return step;
        }
        // The online adaptation, on checked readings, before the model check
        // sees the contraction: one branch in a period without it. The
        // check judges `judged` (the measured contraction, mapped to the
        // flashed model's on a stroke that shrank); the law the measured one.
        let judged = match &mut self.adaptation {
            None => contraction,
            Some(a) => {
                let switched =
                    step.tracker.load_switch.is_some() || step.tracker.branch_switch.is_some();
                let outcome = if self.fault.is_some() || switched {
                    // Faulted, recovering, or the model or branch just
                    // changed: frozen for the settling time.
                    a.freeze();
                    adapt::Outcome::Held
                } else if tracker.inverse_ready() {
                    a.update(
                        tracker.model(),
                        tracker.branch(),
                        pressure_mpa,
                        contraction,
                        self.monitor.last_flow.abs() >= 1.0,
                    )
                } else {
                    // A new load's tables are being built: its inverse
                    // would be the slow table-free one.
                    adapt::Outcome::Held
                };
                self.law.stroke_scale = a.scale();
                if outcome == adapt::Outcome::AtBound {
                    self.enter_fault(Fault::Drifted, &mut step);
                    self.monitor.latch();
                    step.latched = true;
                    return step;
                }
                a.checked_contraction(tracker.model(), contraction)
            }
        };
        let model_due = self
            .monitor
            .model_check_due(pressure_mpa, self.fault.is_none());
        if !resume(
            &mut self.fault,
            &mut self.good_run,
            &self.monitor,
            self.config.safety.recovery_samples,
            &mut step,
        ) {
            return step;
        }
        // 5.–7. The law.
        let c = self.law.command(
            &self.config,
            self.ki_dt,
            coeffs.params(),
            tracker.model(),
            tracker.load_n(),
            tracker.branch(),
            step.tracker.branch_switch.is_some(),
            desired_contraction,
            pressure_mpa,
            contraction,
        );
        // The model check, after the law: a period whose memory feedforward
        // made a minor loop's ends (a reversal's new loop, its search, a
        // wipe-out's, or its ends moved to the rate law's new factor) leaves
        // the check's two inverses to the next period, as it leaves the
        // table build; the next judged period counts for it, and the
        // command is replaced where the check trips.
        if model_due && self.law.rebuilt_loop() {
            self.monitor.defer_model_check();
        } else if model_due {
            let band = self
                .law
                .model_band(coeffs.params(), tracker.model(), tracker.load_n());
            let (excess, fault) = self.monitor.check_model(tracker.model(), &band, judged);
            step.model_excess = excess;
            if let Some(f) = fault {
                self.enter_fault(f, &mut step);
                return step;
            }
        }
        step.feedforward_mpa = c.feedforward_mpa;
        step.pressure_cmd_mpa = c.pressure_cmd_mpa;
        step.command = ValveCommand::Flow(c.flow);
        self.monitor.last_flow = c.flow;
        step
    }

    /// Steps 3–7 with a Preisach model, on checked readings: the model
    /// follows the measured load and pressure (its load switch, its relay
    /// states: [`preisach`]), the response checks, the model check against
    /// its forward output (`Monitor::check_prediction`), recovery, and
    /// the law with its inverse as feedforward.
    ///
    /// The Preisach model has no branches (its relay states carry the
    /// direction and the minor loop): `step.branch` stays
    /// [`Branch::Contraction`] and `step.tracker.branch_switch` `None`;
    /// `step.tracker.load_switch` reports a completed load switch. While a
    /// switch is under way, and for `implausible_settle_s` after it, the
    /// model check pauses, as after the paper tracker's.
    ///
    /// Not inlined: beside the paper model's period in one function it
    /// cost every paper-model period about 30 instructions (register
    /// pressure; bench-m4's `ctl_*` rows), which took `shape_memory`'s
    /// worst period over the 2 000 budget. A Preisach period pays one call.
    #[inline(never)]
    fn preisach_period(
        &mut self,
        mut step: Step,
        desired_contraction: f32,
        pressure_mpa: f32,
        contraction: f32,
        load_n: f32,
    ) -> Step {
        let Model::Preisach(model) = &mut self.model else {
            return step;
        };
        // 3. The model follows the checked readings.
        let followed = model.follow(pressure_mpa, load_n);
        if let Some((from_n, to_n)) = followed.switched {
            step.tracker.load_switch = Some(pam_core::tracker::LoadSwitch { from_n, to_n });
        }
        if followed.switching || followed.switched.is_some() {
            self.monitor.load_switched();
        }
        // 4. Responses, timing, and (while controlling) the model.
        if let Some(f) = self.monitor.check_response(pressure_mpa) {
            self.enter_fault(f, &mut step);
            return step;
        }
        let (excess, fault) =
            self.monitor
                .check_prediction(followed.predicted, contraction, self.fault.is_none());
        step.model_excess = excess;
        if let Some(f) = fault {
            self.enter_fault(f, &mut step);
            return step;
        }
        if !resume(
            &mut self.fault,
            &mut self.good_run,
            &self.monitor,
            self.config.safety.recovery_samples,
            &mut step,
        ) {
            return step;
        }
        // 5.–7. The law.
        let Model::Preisach(model) = &self.model else {
            return step;
        };
        let c = self.law.command_preisach(
            &self.config,
            self.ki_dt,
            model,
            desired_contraction,
            pressure_mpa,
            contraction,
        );
        step.feedforward_mpa = c.feedforward_mpa;
        step.pressure_cmd_mpa = c.pressure_cmd_mpa;
        step.command = ValveCommand::Flow(c.flow);
        self.monitor.last_flow = c.flow;
        step
    }

    fn enter_fault(&mut self, fault: Fault, step: &mut Step) {
        if self.fault.is_none() {
            // A trip: control → safe state.
            self.monitor.trip(self.period);
        }
        if self.fault != Some(fault) {
            step.new_fault = Some(fault);
        }
        self.fault = Some(fault);
        self.good_run = 0;
        self.law.reset();
        self.monitor.went_safe();
        step.fault = Some(fault);
        step.latched = self.monitor.latched();
        step.feedforward_mpa = 0.0;
        step.pressure_cmd_mpa = 0.0;
        step.command = ValveCommand::Safe(self.safe_state());
    }

    fn safe_state(&self) -> SafeState {
        self.config.safety.safe_state
    }
}

/// Recovery from the safe state: with a fault active, count this good
/// sample and leave the safe state after `recovery_samples` of them (never
/// while latched). Whether the law runs this period.
#[inline(always)]
fn resume(
    fault: &mut Option<Fault>,
    good_run: &mut u16,
    monitor: &Monitor,
    recovery_samples: u16,
    step: &mut Step,
) -> bool {
    let Some(f) = *fault else {
        return true;
    };
    step.fault = Some(f);
    if monitor.latched() {
        return false;
    }
    *good_run = good_run.saturating_add(1);
    if *good_run < recovery_samples {
        return false;
    }
    *fault = None;
    *good_run = 0;
    step.fault = None;
    step.recovered = true;
    true
}

//! Fault injection: the firmware's [`firmware::Controller`] closed-loop on
//! the rig ([`crate::harness`]), a fault injected mid-run and (unless it
//! persists) cleared again, and what the safety monitor did, measured in
//! control periods.
//!
//! For the sensor faults, "detectable" is decided here from what the
//! firmware was given (the mocks' taps of every reading, the commands it
//! issued, the write results), by the documented rule of each check,
//! independently of the firmware's code: a bad reading is detectable in the
//! period that reads it; a stuck reading once `stuck_samples + 2`
//! consecutive readings are bit-identical (`stuck_samples + 1` repeats:
//! "identical for more than `stuck_samples` samples"); a supply loss once the
//! rule of
//! [`SafetyConfig::supply_loss_flow`](firmware::SafetyConfig::supply_loss_flow)
//! holds over the recorded commands and pressure readings. For the faults
//! of the muscle and the valves (stuck valves, a lying contraction sensor,
//! over-pressure), of the program (stall, panic, overruns) and intermittent
//! ones, the latency from the injection is measured and bounded by the
//! tests. The tests (`tests/faults.rs`) and the main job's table use
//! [`run_case`] and [`boot`], so the table's numbers are the tested ones.

use crate::hal_mocks::RigPwm;
use crate::harness::{Harness, LoopState};
use firmware::controller::{Check, ConfigError, ControllerConfig, Fault, SensorId, ValveCommand};
use firmware::hal::{
    PressureCalibration, SafeState, SensorErrorKind, Valve, ValvePair, ValvePairConfig,
};
use firmware::sim_io::PWM_MAX_DUTY;
use pam_core::Params;

/// A fault the bench injects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Case {
    /// Every pressure read fails (conversion timeout).
    PressureReadError,
    /// The pressure converter freezes at its last code.
    PressureStuck,
    /// Open transducer line: the converter reads code 0, outside the
    /// calibration's valid window.
    PressureOutOfRange,
    /// One sample at a valid code that reads 1.0 MPa (above the plausible
    /// 0.8 MPa).
    PressureSpike,
    /// Every contraction read fails (bus error).
    ContractionReadError,
    /// The contraction sensor returns NaN.
    ContractionNan,
    /// The load cell returns NaN.
    LoadNan,
    /// The inlet valve's PWM channel refuses every write.
    ValveWriteError,
    /// The supply drops to atmosphere (hose off, compressor off).
    SupplyLoss,
    /// The load steps to 650 N, beyond 600 N + `load_margin_n`.
    LoadBeyondMargin,
    /// The load cell freezes at its last value.
    LoadStuck,
    /// The set-point source sends NaN.
    SetpointNan,
    /// The contraction sensor comes off the muscle: it reads 0.10 with a
    /// dither of one count, whatever the muscle does.
    ContractionDecoupled,
    /// The contraction sensor reads 0.05 (15 mm on 300 mm) too long.
    ContractionOffset,
    /// The inlet valve sticks open.
    InletStuckOpen,
    /// The exhaust valve sticks closed.
    ExhaustStuckClosed,
    /// Inlet stuck open and exhaust stuck closed: the chamber fills to
    /// the supply.
    OverPressure,
    /// The control loop stalls (stops stepping, valves at their last duty).
    Stall,
    /// The control step panics.
    Panic,
    /// One contraction NaN every 60 periods.
    IntermittentNan,
    /// Every control period overruns.
    Overrun,
}

/// Every closed-loop case, in table order.
pub const CASES: [Case; 21] = [
    Case::PressureReadError,
    Case::PressureStuck,
    Case::PressureOutOfRange,
    Case::PressureSpike,
    Case::ContractionReadError,
    Case::ContractionNan,
    Case::LoadNan,
    Case::ValveWriteError,
    Case::SupplyLoss,
    Case::LoadBeyondMargin,
    Case::LoadStuck,
    Case::SetpointNan,
    Case::ContractionDecoupled,
    Case::ContractionOffset,
    Case::InletStuckOpen,
    Case::ExhaustStuckClosed,
    Case::OverPressure,
    Case::Stall,
    Case::Panic,
    Case::IntermittentNan,
    Case::Overrun,
];

/// Periods after the clearing of [`Case::IntermittentNan`] at which the
/// operator resets the latch ([`firmware::Controller::reset_latch`]).
pub const RESET_AFTER_CLEAR: usize = 200;

/// Control period at which every fault is injected (2 s at 1 kHz, the
/// muscle rising on the triangle).
pub const INJECT_AT: usize = 2000;
/// Periods the run goes on after the fault is cleared.
pub const AFTER_CLEAR: usize = 1500;
/// Load of the run, N; [`Case::LoadBeyondMargin`] steps it to [`BEYOND_LOAD_N`].
pub const LOAD_N: f64 = 200.0;
/// The out-of-range load, N.
pub const BEYOND_LOAD_N: f64 = 650.0;
/// The spike's pressure, MPa (a valid code, implausible pressure).
pub const SPIKE_MPA: f32 = 1.0;

impl Case {
    /// Short description of the injected fault.
    pub fn label(self) -> &'static str {
        match self {
            Case::PressureReadError => "pressure read error (timeout)",
            Case::PressureStuck => "pressure stuck at its last code",
            Case::PressureOutOfRange => "pressure out of range (open wire, code 0)",
            Case::PressureSpike => "pressure spike (1 sample, 1.0 MPa)",
            Case::ContractionReadError => "contraction read error (bus)",
            Case::ContractionNan => "contraction NaN",
            Case::LoadNan => "load cell NaN",
            Case::ValveWriteError => "valve write error (inlet PWM refuses)",
            Case::SupplyLoss => "supply pressure loss (0.6 → 0 MPa)",
            Case::LoadBeyondMargin => "load step 200 → 650 N (> 600 + 25 N)",
            Case::LoadStuck => "load cell frozen at its last value",
            Case::SetpointNan => "set-point NaN",
            Case::ContractionDecoupled => "contraction sensor decoupled (reads 0.10 ± 1 count)",
            Case::ContractionOffset => "contraction sensor offset +0.05",
            Case::InletStuckOpen => "inlet valve stuck open",
            Case::ExhaustStuckClosed => "exhaust valve stuck closed",
            Case::OverPressure => "over-pressure: inlet stuck open and exhaust stuck closed",
            Case::Stall => "control loop stalls (valves at last duty)",
            Case::Panic => "panic in the control step",
            Case::IntermittentNan => "intermittent: one contraction NaN every 60 periods",
            Case::Overrun => "every control period overruns",
        }
    }

    /// The fault the firmware must report.
    pub fn expected(self) -> Fault {
        use SensorId::*;
        match self {
            Case::PressureReadError => Fault::Read {
                sensor: Pressure,
                kind: SensorErrorKind::Timeout,
            },
            Case::PressureStuck => Fault::Stuck(Pressure),
            Case::PressureOutOfRange => Fault::Read {
                sensor: Pressure,
                kind: SensorErrorKind::InvalidCode,
            },
            Case::PressureSpike => Fault::OutOfRange(Pressure),
            Case::ContractionReadError => Fault::Read {
                sensor: Contraction,
                kind: SensorErrorKind::Bus,
            },
            Case::ContractionNan => Fault::NonFinite(Contraction),
            Case::LoadNan => Fault::NonFinite(Load),
            Case::ValveWriteError => Fault::Valve,
            Case::SupplyLoss => Fault::SupplyLoss,
            Case::LoadBeyondMargin => Fault::OutOfRange(Load),
            Case::LoadStuck => Fault::Stuck(Load),
            Case::SetpointNan => Fault::Setpoint,
            Case::ContractionDecoupled | Case::ContractionOffset => {
                Fault::Implausible(Check::Model)
            }
            Case::InletStuckOpen | Case::ExhaustStuckClosed => Fault::Implausible(Check::Vent),
            Case::OverPressure => Fault::OverPressure,
            Case::Stall | Case::Panic => Fault::Watchdog,
            Case::IntermittentNan => Fault::NonFinite(Contraction),
            Case::Overrun => Fault::Overrun,
        }
    }

    /// The detection rule, as the table states it.
    pub fn rule(self) -> &'static str {
        match self {
            Case::PressureReadError | Case::ContractionReadError => "read returns `Err`",
            Case::PressureStuck => "`stuck_samples` + 2 (202) bit-identical readings in a row",
            Case::PressureOutOfRange => "code outside the calibration window [200, 3900]",
            Case::PressureSpike => "pressure > `pressure_max_mpa` (0.8 MPa)",
            Case::ContractionNan | Case::LoadNan => "reading not finite",
            Case::ValveWriteError => "a duty write returns `Err`",
            Case::SupplyLoss => {
                "flow command ≥ 0.95 for 100 periods and pressure rose < 0.01 MPa since the first"
            }
            Case::LoadBeyondMargin => "load > `max_load_n` + `load_margin_n` (625 N)",
            Case::LoadStuck => "`stuck_samples` + 2 (202) bit-identical readings in a row",
            Case::SetpointNan => "set-point not finite",
            Case::ContractionDecoupled | Case::ContractionOffset => {
                "contraction outside the model's band at the measured pressure by > 0.035 for 100 periods"
            }
            Case::InletStuckOpen | Case::ExhaustStuckClosed => {
                "flow command ≤ −0.95 for 100 periods from ≥ 0.05 MPa and pressure fell < 0.01 MPa"
            }
            Case::OverPressure => {
                "the vent check (above) first, then pressure > `min(Pmax, max_command_mpa)` + `overpressure_margin_mpa` (0.55 MPa)"
            }
            Case::Stall | Case::Panic => {
                "IWDG not fed for 20 ms: reset, boot writes the safe state and latches"
            }
            Case::IntermittentNan => {
                "reading not finite; the 4th trip within 10 s latches (`latch_trips` 3)"
            }
            Case::Overrun => "`overrun_limit` (3) overruns in a row",
        }
    }

    /// Periods the fault stays injected.
    pub fn duration_periods(self, cfg: &ControllerConfig) -> usize {
        match self {
            Case::PressureSpike => 1,
            // Long enough to be detected and held for a while.
            Case::PressureStuck => usize::from(cfg.safety.stuck_samples) + 300,
            // Ends inside the third trip's safe hold (trips 150 periods
            // apart: window + recovery run), so the recovery run shows.
            Case::SupplyLoss => 460,
            Case::LoadStuck => usize::from(cfg.safety.stuck_samples) + 300,
            // 10 NaNs: the 4th trip latches.
            Case::IntermittentNan => 600,
            // Faults that persist: never cleared within the run.
            _ if self.persists() => PERSIST_PERIODS,
            _ => 300,
        }
    }

    /// The fault is not cleared within the run (hardware that stays
    /// broken, or a program that was reset).
    pub fn persists(self) -> bool {
        matches!(
            self,
            Case::ContractionDecoupled
                | Case::ContractionOffset
                | Case::InletStuckOpen
                | Case::ExhaustStuckClosed
                | Case::OverPressure
                | Case::Stall
                | Case::Panic
        )
    }
}

/// How long a persisting fault is watched, periods.
pub const PERSIST_PERIODS: usize = 4000;

/// What one fault run measured (indices are control periods from the start).
#[derive(Clone, Debug, PartialEq)]
pub struct FaultRun {
    /// The injected fault.
    pub case: Case,
    /// First period with the fault present.
    pub injected_at: usize,
    /// First period with the fault gone again (the end of the run for a
    /// persisting fault).
    pub cleared_at: usize,
    /// First period in which the fault was detectable by its rule, for the
    /// sensor faults whose rule the bench re-states.
    pub detectable_at: Option<usize>,
    /// The first fault the controller held at or after the injection, and
    /// when (after a watchdog reset: the rebooted controller's).
    pub reported: Option<(usize, Fault)>,
    /// First period at or after the injection after which the valves were
    /// in the safe state (exhaust fully open and inlet closed; for
    /// [`Case::ValveWriteError`] the refusing inlet cannot be written, so
    /// exhaust fully open).
    pub safe_at: Option<usize>,
    /// Consecutive periods the valves stayed safe from `safe_at` on.
    pub safe_periods: usize,
    /// Periods from `safe_at` on in which the inlet's duty was not 0.
    pub inlet_open_after_safe: usize,
    /// The valves are in the safe state at the end of the run.
    pub safe_at_end: bool,
    /// Periods with a fault before the injection (must be 0).
    pub faults_before: usize,
    /// Every fault the controller held from the injection on, when it
    /// began (a change of fault counts).
    pub seen: Vec<(usize, Fault)>,
    /// Trips (entries into the safe state from control) from the injection on.
    pub trips: usize,
    /// First period at which the safe state was latched.
    pub latched_at: Option<usize>,
    /// Still latched at the end of the run.
    pub latched_at_end: bool,
    /// First period at or after the clearing from which on the controller
    /// is never in a fault again (`None` if it still is at the end).
    pub recovered_at: Option<usize>,
    /// Largest |reference − true contraction| over the last 500 periods.
    pub final_max_error: f64,
    /// Largest true chamber pressure from the injection on, MPa.
    pub max_pressure_mpa: f64,
}

impl FaultRun {
    /// Periods from the injection to the fault being detectable.
    pub fn detectable_after(&self) -> Option<usize> {
        self.detectable_at?.checked_sub(self.injected_at)
    }

    /// Periods from the injection to the controller holding a fault.
    pub fn reported_after(&self) -> Option<usize> {
        self.reported?.0.checked_sub(self.injected_at)
    }

    /// Periods from the injection to the controller first holding `fault`.
    pub fn first_after(&self, fault: Fault) -> Option<usize> {
        let at = self.seen.iter().find(|s| s.1 == fault)?.0;
        at.checked_sub(self.injected_at)
    }

    /// Periods from the injection to the valves safe.
    pub fn safe_after(&self) -> Option<usize> {
        self.safe_at?.checked_sub(self.injected_at)
    }

    /// Periods from detectable to the valves safe: 0 is the step that read
    /// the bad sample (before the next period starts).
    pub fn periods_to_safe(&self) -> Option<usize> {
        self.safe_at?.checked_sub(self.detectable_at?)
    }

    /// Periods from the clearing to the recovery step.
    pub fn recovery_periods(&self) -> Option<usize> {
        self.recovered_at?.checked_sub(self.cleared_at)
    }
}

/// The run's reference: hold 8 % for 1.5 s, then a triangle 8 % ↔ 14 %
/// with a 2 s period (at the injection, 2 s, it is half-way up: the loop is
/// filling the muscle).
pub fn reference_at(t_s: f64) -> f64 {
    if t_s < 1.5 {
        return 0.08;
    }
    let phase = ((t_s - 1.5) / 2.0).fract();
    let tri = if phase < 0.5 {
        2.0 * phase
    } else {
        2.0 - 2.0 * phase
    };
    0.08 + 0.06 * tri
}

/// Run `case` with [`ControllerConfig::DEFAULT`] and `Params::DEFAULT` on
/// the reference rig (sensor noise from `seed`).
///
/// # Panics
/// If the firmware refuses the default configuration (a bench set-up error).
pub fn run_case(case: Case, seed: u64) -> FaultRun {
    run_case_with(case, seed, ControllerConfig::DEFAULT)
}

/// [`run_case`] with the controller configured by `cfg` (the fault suite
/// with the online adaptation on, `tests/adaptation.rs`).
pub fn run_case_with(case: Case, seed: u64, cfg: ControllerConfig) -> FaultRun {
    let s = cfg.safety;
    let dt = f64::from(cfg.dt_s);
    let cal = PressureCalibration::ADC12_0_1MPA;
    let mut h = Harness::new(cfg, LOAD_N, seed);
    let supply_mpa = h.rig.borrow().chamber.params().supply_mpa;
    let injected_at = INJECT_AT;
    let cleared_at = injected_at + case.duration_periods(&cfg);
    let n = if case.persists() {
        cleared_at
    } else {
        cleared_at + AFTER_CLEAR
    };

    let mut counts: Vec<Option<u16>> = Vec::with_capacity(n);
    let mut loads: Vec<Option<f32>> = Vec::with_capacity(n);
    let mut flows: Vec<f32> = Vec::with_capacity(n);
    let mut detectable_at = None;
    let mut reported = None;
    let mut safe_at = None;
    let mut safe_periods = 0;
    let mut faults_before = 0;
    let mut trips = 0;
    let mut seen: Vec<(usize, Fault)> = Vec::new();
    let mut latched_at = None;
    let mut last_fault = None;
    let mut final_max_error = 0.0f64;
    let mut max_pressure_mpa = 0.0f64;
    let mut stuck_code = 0;
    let mut stuck_load = 0.0;
    let mut supply = ReplaySupply::default();
    let mut was_faulted = false;
    let mut inlet_open_after_safe = 0;

    for k in 0..n {
        let active = (injected_at..cleared_at).contains(&k);
        if k == injected_at {
            stuck_code = counts.last().copied().flatten().unwrap_or(0);
            stuck_load = loads.last().copied().flatten().unwrap_or(0.0);
        }
        let t = k as f64 * dt;
        let mut reference = reference_at(t) as f32;
        match case {
            Case::PressureReadError => h
                .sensors
                .pressure
                .error
                .set(active.then_some(SensorErrorKind::Timeout)),
            Case::PressureStuck | Case::PressureOutOfRange | Case::PressureSpike => {
                use crate::sensors::PressureFault;
                let code = match case {
                    Case::PressureStuck => stuck_code,
                    Case::PressureOutOfRange => 0,
                    _ => cal.to_counts(SPIKE_MPA).0,
                };
                h.rig.borrow_mut().pressure_sensor.fault = if active {
                    PressureFault::StuckAt(code)
                } else {
                    PressureFault::None
                };
            }
            Case::ContractionReadError => h
                .sensors
                .contraction
                .error
                .set(active.then_some(SensorErrorKind::Bus)),
            Case::ContractionNan => h.sensors.contraction.value.set(active.then_some(f32::NAN)),
            Case::LoadNan => h.sensors.load.value.set(active.then_some(f32::NAN)),
            Case::ValveWriteError => h.inlet.fail.set(active),
            Case::SupplyLoss => {
                h.rig
                    .borrow_mut()
                    .set_supply_mpa(if active { 0.0 } else { supply_mpa });
            }
            Case::LoadBeyondMargin => {
                h.rig
                    .borrow_mut()
                    .set_load_n(if active { BEYOND_LOAD_N } else { LOAD_N });
            }
            Case::LoadStuck => h.sensors.load.value.set(active.then_some(stuck_load)),
            Case::SetpointNan => {
                if active {
                    reference = f32::NAN;
                }
            }
            Case::ContractionDecoupled => {
                let dither = (k % 3) as f32 * 1e-4;
                h.sensors
                    .contraction
                    .value
                    .set(active.then_some(0.10 + dither));
            }
            Case::ContractionOffset => {
                h.rig.borrow_mut().contraction_sensor.offset = if active { 0.05 } else { 0.0 };
            }
            Case::InletStuckOpen => h.valves.inlet_stuck_open = active,
            Case::ExhaustStuckClosed => h.valves.exhaust_stuck_closed = active,
            Case::OverPressure => {
                h.valves.inlet_stuck_open = active;
                h.valves.exhaust_stuck_closed = active;
            }
            Case::Stall => {
                if k == injected_at {
                    h.state = LoopState::Stalled;
                }
            }
            Case::Panic => {
                if k == injected_at {
                    // The step of this period panics: the chip's handler
                    // takes over at once.
                    h.panic_handler();
                }
            }
            Case::IntermittentNan => {
                let nan = active && (k - injected_at).is_multiple_of(60);
                h.sensors.contraction.value.set(nan.then_some(f32::NAN));
            }
            Case::Overrun => h.ctl.record_overrun(active),
        }
        if case == Case::IntermittentNan && k == cleared_at + RESET_AFTER_CLEAR {
            // The operator's reset.
            h.ctl.reset_latch();
        }

        let step = h.period(reference);

        // What the firmware was given, and the rule that makes it detectable.
        let code = h.sensors.pressure.last.get();
        counts.push(code);
        loads.push(h.sensors.load.last.get());
        let pressure_mpa = code.and_then(|c| cal.to_mpa(firmware::hal::Counts(c)).ok());
        let need = usize::from(s.stuck_samples) + 2;
        let bad = match case {
            Case::PressureReadError => code.is_none(),
            Case::PressureOutOfRange => pressure_mpa.is_none() && code.is_some(),
            Case::PressureSpike => pressure_mpa.is_some_and(|p| p > s.pressure_max_mpa),
            Case::PressureStuck => {
                k + 1 >= need && {
                    let w = &counts[k + 1 - need..];
                    w.iter().all(|c| c.is_some() && *c == w[0])
                }
            }
            Case::LoadStuck => {
                k + 1 >= need && {
                    let w = &loads[k + 1 - need..];
                    w.iter().all(|l| l.is_some() && *l == w[0])
                }
            }
            Case::ContractionReadError => h.sensors.contraction.last.get().is_none(),
            Case::ContractionNan => h.sensors.contraction.last.get().is_some_and(f32::is_nan),
            Case::LoadNan => h.sensors.load.last.get().is_some_and(f32::is_nan),
            Case::ValveWriteError => h.inlet.fail.get(),
            Case::SupplyLoss => pressure_mpa.is_some_and(|p| {
                supply.observe(flows.last().copied().unwrap_or(0.0), p, &cfg.safety)
            }),
            Case::LoadBeyondMargin => h
                .sensors
                .load
                .last
                .get()
                .is_some_and(|l| l > Params::DEFAULT.max_load_n + s.load_margin_n),
            Case::SetpointNan => active,
            Case::IntermittentNan => h.sensors.contraction.last.get().is_some_and(f32::is_nan),
            Case::Overrun => active && k + 1 - injected_at >= usize::from(s.overrun_limit),
            _ => false,
        };
        flows.push(match step.map(|s| s.command) {
            Some(ValveCommand::Flow(f)) => f,
            _ => 0.0,
        });
        if bad && k >= injected_at && detectable_at.is_none() {
            detectable_at = Some(k);
        }

        let fault = h.ctl.fault();
        if k < injected_at {
            faults_before += usize::from(fault.is_some());
        } else {
            if reported.is_none() {
                reported = fault.map(|f| (k, f));
            }
            if fault.is_some() && !was_faulted {
                trips += 1;
            }
            if let Some(f) = fault {
                if seen.last().is_none_or(|l| l.1 != f) {
                    seen.push((k, f));
                }
            }
            if latched_at.is_none() && h.ctl.latched() {
                latched_at = Some(k);
            }
        }
        was_faulted = fault.is_some();
        let exhaust_open = h.exhaust.duty.get() == PWM_MAX_DUTY;
        let safe = exhaust_open && (case == Case::ValveWriteError || h.inlet.duty.get() == 0);
        // After a panic or a stall nothing of the old controller reports:
        // the panic handler, then the rebooted latched controller, hold the
        // valves.
        let holding = fault.is_some() || matches!(case, Case::Panic | Case::Stall);
        if k >= injected_at {
            match safe_at {
                None if safe && holding => {
                    safe_at = Some(k);
                    safe_periods = 1;
                }
                Some(at) if safe && safe_periods == k - at => safe_periods += 1,
                _ => {}
            }
        }
        if safe_at.is_some() && h.inlet.duty.get() > 0 {
            inlet_open_after_safe += 1;
        }
        if k >= cleared_at && fault.is_some() {
            last_fault = Some(k);
        }

        let r = h.rig.borrow();
        if k + 500 >= n {
            let e = (f64::from(reference_at(t) as f32) - r.muscle.contraction()).abs();
            final_max_error = final_max_error.max(e);
        }
        if k >= injected_at {
            max_pressure_mpa = max_pressure_mpa.max(r.chamber.pressure_mpa());
        }
    }
    let recovered_at = if case.persists() {
        None
    } else {
        Some(last_fault.map_or(cleared_at, |f| f + 1)).filter(|&k| k < n)
    };
    FaultRun {
        case,
        injected_at,
        cleared_at,
        detectable_at,
        reported,
        safe_at,
        safe_periods,
        inlet_open_after_safe,
        safe_at_end: h.valves_commanded_safe(),
        faults_before,
        seen,
        trips,
        latched_at,
        latched_at_end: h.ctl.latched(),
        recovered_at,
        final_max_error,
        max_pressure_mpa,
    }
}

/// The supply-loss rule of `SafetyConfig::supply_loss_flow`, re-stated on
/// the bench's records: `flow_before` is the command issued in the previous
/// period, `pressure_mpa` the reading now.
#[derive(Debug, Default)]
struct ReplaySupply {
    open: u16,
    start_mpa: f32,
    last_mpa: f32,
}

impl ReplaySupply {
    fn observe(&mut self, flow_before: f32, pressure_mpa: f32, s: &firmware::SafetyConfig) -> bool {
        let before = std::mem::replace(&mut self.last_mpa, pressure_mpa);
        if flow_before < s.supply_loss_flow {
            self.open = 0;
            return false;
        }
        if self.open == 0 {
            self.start_mpa = before;
        }
        self.open += 1;
        if pressure_mpa - self.start_mpa >= s.supply_loss_rise_mpa {
            self.open = 0;
            return false;
        }
        self.open >= s.supply_loss_periods
    }
}

/// What boot did with a coefficient blob.
#[derive(Clone, Debug, PartialEq)]
pub struct BootOutcome {
    /// The controller's verdict on the blob.
    pub result: Result<(), ConfigError>,
    /// Inlet and exhaust duty after boot, counts of [`PWM_MAX_DUTY`].
    pub duties: (u16, u16),
}

/// Boot as the image does (`firmware/src/main.rs`): valves to the safe state
/// first, then the blob is decoded and checked ([`firmware::boot::boot`]);
/// a refused blob leaves them there and no control step runs.
///
/// # Panics
/// If the valve configuration is refused (a bench set-up error).
pub fn boot(blob: &[u8]) -> BootOutcome {
    let (inlet, exhaust) = (RigPwm::default(), RigPwm::default());
    // Both channels start as a board's timers would after a fill command.
    inlet.duty.set(PWM_MAX_DUTY);
    let mut valve = ValvePair::new(inlet.clone(), exhaust.clone(), ValvePairConfig::DEFAULT)
        .expect("valve config");
    let cfg = ControllerConfig::DEFAULT;
    let _ = valve.set_safe(cfg.safety.safe_state);
    let result = firmware::boot::boot(blob, cfg, |_| LOAD_N as f32)
        .map(|_| ())
        .map_err(ConfigError::from);
    if result.is_err() {
        let _ = valve.set_safe(SafeState::Exhaust);
    }
    BootOutcome {
        result,
        duties: (inlet.duty.get(), exhaust.duty.get()),
    }
}

/// pam-core's encoding of `Params::DEFAULT` with one bit flipped in the
/// parameter bytes (the CRC catches it).
pub fn corrupt_blob() -> Vec<u8> {
    let mut b = pam_core::blob::encode(&Params::DEFAULT).to_vec();
    b[20] ^= 0x10;
    b
}

fn cell(v: Option<usize>) -> String {
    v.map_or_else(|| "never".to_string(), |v| v.to_string())
}

/// The README's fault table (Markdown) from measured runs and the boot check.
pub fn table(runs: &[FaultRun], boot: &BootOutcome) -> String {
    let mut out = String::from(
        "| fault injected | firmware `Fault` | detection rule | detected after injection (periods) | valves safe after injection (periods) | after clearing |\n|---|---|---|---|---|---|\n",
    );
    for r in runs {
        // The distinct faults in the order they began, with their periods
        // after the injection when more than one.
        let mut kinds: Vec<(usize, Fault)> = Vec::new();
        for &(k, f) in &r.seen {
            if !kinds.iter().any(|x| x.1 == f) {
                kinds.push((k - r.injected_at, f));
            }
        }
        let fault = match kinds.as_slice() {
            [] => "none".to_string(),
            [(_, f)] => format!("`{f:?}`"),
            many => many
                .iter()
                .map(|(k, f)| format!("`{f:?}` ({k})"))
                .collect::<Vec<_>>()
                .join(", then "),
        };
        let after = if r.case.persists() {
            match r.latched_at {
                Some(at) => format!(
                    "persists; {} trip(s), latched {} periods after injection",
                    r.trips,
                    at - r.injected_at
                ),
                None => format!("persists; {} trip(s), not latched", r.trips),
            }
        } else if let Some(at) = r.latched_at {
            format!(
                "latched {} periods after injection ({} trips); operator reset {} periods after clearing, recovered {} periods after clearing",
                at - r.injected_at,
                r.trips,
                RESET_AFTER_CLEAR,
                cell(r.recovery_periods())
            )
        } else {
            format!("recovered after {} periods", cell(r.recovery_periods()))
        };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            r.case.label(),
            fault,
            r.case.rule(),
            cell(r.reported_after()),
            cell(r.safe_after()),
            after,
        ));
    }
    let verdict = match &boot.result {
        Err(e) => format!("`Err({e:?})`"),
        Ok(()) => "accepted (wrong)".to_string(),
    };
    out.push_str(&format!(
        "| corrupt coefficient blob (1 bit) | boot: {verdict} | magic, version, length, CRC-32, parameter validation | at boot | at boot, before decoding (inlet {}, exhaust {}/{}); no step runs | none: refused, the image stops |\n",
        boot.duties.0,
        boot.duties.1,
        PWM_MAX_DUTY
    ));
    out
}

//! Fault injection: the firmware's [`Controller`] closed-loop on the rig, a
//! fault injected mid-run and cleared again, and what the safety monitor
//! did, measured in control periods.
//!
//! "Detectable" is decided here from what the firmware was given (the
//! mocks' taps of every reading, the commands it issued, the write results),
//! by the documented rule of each check, independently of the firmware's
//! code: a bad reading is detectable in the period that reads it; a stuck
//! reading once `stuck_samples + 2` consecutive readings are bit-identical
//! (`stuck_samples + 1` repeats: "identical for more than `stuck_samples`
//! samples"); a supply loss once the rule of
//! [`SafetyConfig::supply_loss_flow`](firmware::SafetyConfig::supply_loss_flow)
//! holds over the recorded commands and pressure readings. The tests
//! (`tests/faults.rs`) and the main job's table use [`run_case`] and
//! [`boot`], so the table's numbers are the tested ones.

use crate::hal_mocks::{valve_opening, SimContraction, SimLoad, SimPressure, SimPwm, ValveKind};
use crate::rig::Rig;
use firmware::controller::{ConfigError, Controller, ControllerConfig, Fault, Io, SensorId};
use firmware::hal::{
    PressureCalibration, SafeState, SensorErrorKind, Valve, ValvePair, ValvePairConfig,
};
use pam_core::{Coeffs, Params};
use std::cell::RefCell;
use std::rc::Rc;

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
}

/// Every closed-loop case, in table order.
pub const CASES: [Case; 10] = [
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
];

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
            _ => 300,
        }
    }
}

/// What one fault run measured (indices are control periods from the start).
#[derive(Clone, Debug, PartialEq)]
pub struct FaultRun {
    /// The injected fault.
    pub case: Case,
    /// First period with the fault present.
    pub injected_at: usize,
    /// First period with the fault gone again.
    pub cleared_at: usize,
    /// First period in which the fault was detectable by its rule.
    pub detectable_at: Option<usize>,
    /// The first fault the controller reported at or after the injection, and when.
    pub reported: Option<(usize, Fault)>,
    /// First period at or after the injection after whose step the valves
    /// were in the safe state (exhaust fully open and inlet closed; for
    /// [`Case::ValveWriteError`] the refusing inlet cannot be written, so
    /// exhaust fully open).
    pub safe_at: Option<usize>,
    /// Consecutive periods the valves stayed safe from `safe_at` on.
    pub safe_periods: usize,
    /// Periods with a fault before the injection (must be 0).
    pub faults_before: usize,
    /// First period at or after the clearing from which on the controller
    /// is never in a fault again (`None` if it still is at the end).
    pub recovered_at: Option<usize>,
    /// Largest |reference − true contraction| over the last 500 periods.
    pub final_max_error: f64,
}

impl FaultRun {
    /// Periods from the injection to the fault being detectable.
    pub fn detectable_after(&self) -> Option<usize> {
        self.detectable_at?.checked_sub(self.injected_at)
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
    let cfg = ControllerConfig::DEFAULT;
    let s = cfg.safety;
    let dt = f64::from(cfg.dt_s);
    let cal = PressureCalibration::ADC12_0_1MPA;
    let rig = Rc::new(RefCell::new(Rig::reference(LOAD_N, seed)));
    let supply_mpa = rig.borrow().chamber.params().supply_mpa;
    let coeffs = Coeffs::new(Params::DEFAULT).expect("default parameters");
    let mut ctl = Controller::new(coeffs, cfg, LOAD_N as f32).expect("default config");
    let (inlet, exhaust) = (SimPwm::new(), SimPwm::new());
    let mut io = Io {
        pressure: SimPressure::new(rig.clone(), cal),
        contraction: SimContraction::new(rig.clone()),
        load: SimLoad::new(rig.clone()),
        valve: ValvePair::new(inlet.clone(), exhaust.clone(), ValvePairConfig::DEFAULT)
            .expect("valve config"),
    };
    let injected_at = INJECT_AT;
    let cleared_at = injected_at + case.duration_periods(&cfg);
    let n = cleared_at + AFTER_CLEAR;

    let mut counts: Vec<Option<u16>> = Vec::with_capacity(n);
    let mut flows: Vec<f32> = Vec::with_capacity(n);
    let mut detectable_at = None;
    let mut reported = None;
    let mut safe_at = None;
    let mut safe_periods = 0;
    let mut faults_before = 0;
    let mut last_fault = None;
    let mut final_max_error = 0.0f64;
    let mut stuck_code = 0;
    let mut supply = ReplaySupply::default();

    for k in 0..n {
        let active = (injected_at..cleared_at).contains(&k);
        if k == injected_at {
            stuck_code = counts.last().copied().flatten().unwrap_or(0);
        }
        let t = k as f64 * dt;
        match case {
            Case::PressureReadError => io
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
                rig.borrow_mut().pressure_sensor.fault = if active {
                    PressureFault::StuckAt(code)
                } else {
                    PressureFault::None
                };
            }
            Case::ContractionReadError => io
                .contraction
                .error
                .set(active.then_some(SensorErrorKind::Bus)),
            Case::ContractionNan => io.contraction.value.set(active.then_some(f32::NAN)),
            Case::LoadNan => io.load.value.set(active.then_some(f32::NAN)),
            Case::ValveWriteError => inlet.fail.set(active),
            Case::SupplyLoss => {
                rig.borrow_mut()
                    .set_supply_mpa(if active { 0.0 } else { supply_mpa });
            }
            Case::LoadBeyondMargin => {
                rig.borrow_mut()
                    .set_load_n(if active { BEYOND_LOAD_N } else { LOAD_N });
            }
        }

        let reference = reference_at(t);
        let step = ctl.step(&mut io, reference as f32);

        // What the firmware was given, and the rule that makes it detectable.
        let code = io.pressure.last_counts.get();
        counts.push(code);
        let pressure_mpa = code.and_then(|c| cal.to_mpa(firmware::hal::Counts(c)).ok());
        let bad = match case {
            Case::PressureReadError => code.is_none(),
            Case::PressureOutOfRange => pressure_mpa.is_none() && code.is_some(),
            Case::PressureSpike => pressure_mpa.is_some_and(|p| p > s.pressure_max_mpa),
            Case::PressureStuck => {
                let need = usize::from(s.stuck_samples) + 2;
                k + 1 >= need && {
                    let w = &counts[k + 1 - need..];
                    w.iter().all(|c| c.is_some() && *c == w[0])
                }
            }
            Case::ContractionReadError => io.contraction.last.get().is_none(),
            Case::ContractionNan => io.contraction.last.get().is_some_and(f32::is_nan),
            Case::LoadNan => io.load.last.get().is_some_and(f32::is_nan),
            Case::ValveWriteError => inlet.fail.get(),
            Case::SupplyLoss => pressure_mpa.is_some_and(|p| {
                supply.observe(flows.last().copied().unwrap_or(0.0), p, &cfg.safety)
            }),
            Case::LoadBeyondMargin => io
                .load
                .last
                .get()
                .is_some_and(|l| l > Params::DEFAULT.max_load_n + s.load_margin_n),
        };
        flows.push(match step.command {
            firmware::controller::ValveCommand::Flow(f) => f,
            firmware::controller::ValveCommand::Safe(_) => 0.0,
        });
        if bad && k >= injected_at && detectable_at.is_none() {
            detectable_at = Some(k);
        }

        if k < injected_at {
            faults_before += usize::from(step.fault.is_some());
        } else if reported.is_none() {
            reported = step.new_fault.map(|f| (k, f));
        }
        let exhaust_open = exhaust.duty.get() == SimPwm::MAX_DUTY;
        let safe = exhaust_open && (case == Case::ValveWriteError || inlet.duty.get() == 0);
        if k >= injected_at {
            match safe_at {
                None if safe && step.fault.is_some() => {
                    safe_at = Some(k);
                    safe_periods = 1;
                }
                Some(at) if safe && safe_periods == k - at => safe_periods += 1,
                _ => {}
            }
        }
        if k >= cleared_at && step.fault.is_some() {
            last_fault = Some(k);
        }

        let opening = valve_opening(ValveKind::PAIR, inlet.fraction(), exhaust.fraction());
        let mut r = rig.borrow_mut();
        if k + 500 >= n {
            final_max_error = final_max_error.max((reference - r.muscle.contraction()).abs());
        }
        r.opening = opening;
        r.advance(dt);
    }
    let recovered_at = Some(last_fault.map_or(cleared_at, |f| f + 1)).filter(|&k| k < n);
    FaultRun {
        case,
        injected_at,
        cleared_at,
        detectable_at,
        reported,
        safe_at,
        safe_periods,
        faults_before,
        recovered_at,
        final_max_error,
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
    /// Inlet and exhaust duty after boot, counts of [`SimPwm::MAX_DUTY`].
    pub duties: (u16, u16),
}

/// Boot as the image does (`firmware/src/main.rs`): valves to the safe state
/// first, then the blob is decoded and checked; a refused blob leaves them
/// there and no control step runs.
///
/// # Panics
/// If the valve configuration is refused (a bench set-up error).
pub fn boot(blob: &[u8]) -> BootOutcome {
    let (inlet, exhaust) = (SimPwm::new(), SimPwm::new());
    // Both channels start as a board's timers would after a fill command.
    inlet.duty.set(SimPwm::MAX_DUTY);
    let mut valve = ValvePair::new(inlet.clone(), exhaust.clone(), ValvePairConfig::DEFAULT)
        .expect("valve config");
    let cfg = ControllerConfig::DEFAULT;
    let _ = valve.set_safe(cfg.safety.safe_state);
    let result = Controller::from_blob(blob, cfg, LOAD_N as f32).map(|_| ());
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
        "| fault injected | firmware `Fault` | detection rule | detectable after injection (periods) | to safe state after detectable (periods) | recovery after clearing (periods) |\n|---|---|---|---|---|---|\n",
    );
    for r in runs {
        let fault = r
            .reported
            .map_or_else(|| "none".to_string(), |(_, f)| format!("{f:?}"));
        out.push_str(&format!(
            "| {} | `{}` | {} | {} | {} | {} |\n",
            r.case.label(),
            fault,
            r.case.rule(),
            cell(r.detectable_after()),
            cell(r.periods_to_safe()),
            cell(r.recovery_periods()),
        ));
    }
    let verdict = match &boot.result {
        Err(e) => format!("`Err({e:?})`"),
        Ok(()) => "accepted (wrong)".to_string(),
    };
    out.push_str(&format!(
        "| corrupt coefficient blob (1 bit) | boot: {verdict} | magic, version, length, CRC-32, parameter validation | at boot | valves safe before decoding (inlet {}, exhaust {}/{}); no step runs | none: refused, the image stops |\n",
        boot.duties.0,
        boot.duties.1,
        SimPwm::MAX_DUTY
    ));
    out
}

//! The bench: the firmware's [`Controller`] driving the simulated rig through
//! the mock HALs, one control period at a time, with a trace of everything
//! and the metrics the scenario tests assert on.

use crate::hal_mocks::{rig_io, valve_opening, RigIo, SharedRig, ValveKind};
use crate::rig::Rig;
use crate::scenarios::Scenario;
use firmware::controller::{Controller, ControllerConfig, Fault, Feedforward, ValveCommand};
use pam_core::effects::NonLocalMemory;
use pam_core::{Branch, Coeffs, Params};
use std::cell::RefCell;
use std::rc::Rc;

/// Which controller the bench runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// The firmware's controller with pam-core's hysteresis model as
    /// feedforward plus PI: the project's controller.
    FeedforwardPi,
    /// [`Mode::FeedforwardPi`] with the firmware's
    /// [`Feedforward::HysteresisMemory`] ([`MEMORY`]): minor loops instead of
    /// the `2·be` jump at a branch switch.
    FeedforwardMemoryPi,
    /// The controller booted from the blob `pam-lab diagnose` wrote: the
    /// model with the effects the diagnosis added, as the firmware's
    /// feedforward runs it ([`crate::end_to_end`]).
    DiagnosedFeedforwardPi,
    /// The controller booted from a Preisach blob (`PAMP`) identified on
    /// the characterisation record ([`crate::preisach`]): the firmware's
    /// [`Feedforward::Preisach`].
    PreisachFeedforwardPi,
    /// PI feedback alone: the same controller, model and gains with
    /// [`Feedforward::Off`], and the integrator limit raised to
    /// [`PI_ONLY_INTEGRAL_LIMIT_MPA`] so that PI can reach the whole
    /// pressure range (with the default 0.1 MPa it could not hold the
    /// muscle above 0.1 MPa + `kp`·error).
    PiOnly,
}

impl Mode {
    /// Every mode.
    pub const ALL: [Mode; 5] = [
        Mode::FeedforwardPi,
        Mode::FeedforwardMemoryPi,
        Mode::DiagnosedFeedforwardPi,
        Mode::PreisachFeedforwardPi,
        Mode::PiOnly,
    ];
}

impl Mode {
    /// Short label.
    pub fn label(self) -> &'static str {
        match self {
            Mode::FeedforwardPi => "FF+PI",
            Mode::FeedforwardMemoryPi => "FF(mem)+PI",
            Mode::DiagnosedFeedforwardPi => "FF(diag)+PI",
            Mode::PreisachFeedforwardPi => "FF(Preisach)+PI",
            Mode::PiOnly => "PI",
        }
    }
}

/// Settings of one bench run.
#[derive(Clone, Copy, Debug)]
pub struct BenchConfig {
    /// The controller's model for [`Mode::FeedforwardPi`].
    pub params: Params,
    /// Controller settings (gains, rate, safety) for [`Mode::FeedforwardPi`];
    /// [`Mode::PiOnly`] uses the same gains with [`Feedforward::Off`] and
    /// `integral_limit_mpa` raised to [`PI_ONLY_INTEGRAL_LIMIT_MPA`].
    pub controller: ControllerConfig,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// Time excluded from the error statistics at the start (the muscle
    /// starts empty), s.
    pub warmup_s: f64,
}

/// Integrator limit of the PI-only baseline, MPa: `Pmax` of
/// `Params::DEFAULT`, so that the integral alone can hold any pressure the
/// model covers (the command is clamped to `[0, Pmax]` anyway).
pub const PI_ONLY_INTEGRAL_LIMIT_MPA: f32 = Params::DEFAULT.points.max_pressure_mpa;

impl BenchConfig {
    /// pam-core's default model, the firmware's default configuration,
    /// 3 s warm-up. The valves are an inlet/exhaust on/off pair
    /// ([`ValveKind::PAIR`]) driven by the firmware's `ValvePair`.
    pub fn default_with_seed(seed: u64) -> BenchConfig {
        BenchConfig {
            params: Params::DEFAULT,
            controller: ControllerConfig::DEFAULT,
            seed,
            warmup_s: 3.0,
        }
    }
}

/// One control period of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TraceRow {
    /// Time, s.
    pub t_s: f64,
    /// Reference contraction.
    pub reference: f64,
    /// True contraction.
    pub contraction: f64,
    /// True chamber pressure, MPa.
    pub pressure_mpa: f64,
    /// Pressure set-point of the inner loop, MPa.
    pub pressure_cmd_mpa: f64,
    /// Feedforward pressure, MPa.
    pub feedforward_mpa: f64,
    /// True load, N.
    pub load_n: f64,
    /// Load of the controller's active model, N.
    pub model_load_n: f64,
    /// +1 contraction branch, −1 expansion branch.
    pub branch: i8,
    /// Valve flow command in `[-1, 1]` (0 in a safe state).
    pub flow_cmd: f64,
    /// 1 while the controller is in a fault.
    pub fault: u8,
}

/// How one load step was handled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadStepResult {
    /// Time of the step, s.
    pub t_s: f64,
    /// Load before, N.
    pub from_n: f64,
    /// Load after, N.
    pub to_n: f64,
    /// Control periods from the step to the tracker's switch to a model
    /// within 20 N of the new load; `None` if it never did before the next step.
    pub detected_after_samples: Option<usize>,
}

/// What happened at one branch switch of the tracker.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwitchResult {
    /// Time, s.
    pub t_s: f64,
    /// New branch.
    pub to: Branch,
    /// Feedforward pressure change across the switching period, MPa: the
    /// jump the paper's model makes (the offset changes sign).
    pub feedforward_jump_mpa: f64,
    /// Pressure set-point change across the switching period, MPa.
    pub command_jump_mpa: f64,
    /// Largest change of the true chamber pressure over any 10 ms within
    /// ±50 ms of the switch, MPa.
    pub chamber_jump_mpa: f64,
}

/// Statistics of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct Metrics {
    /// RMS of true contraction − reference after the warm-up.
    pub rms_error: f64,
    /// Maximum |true contraction − reference| after the warm-up.
    pub max_error: f64,
    /// Load steps and their detection.
    pub load_steps: Vec<LoadStepResult>,
    /// Branch switches.
    pub switches: Vec<SwitchResult>,
    /// Control periods spent in a fault.
    pub fault_samples: usize,
    /// Largest |model load − true load| at the end of each load plateau, N.
    pub worst_model_load_error_n: f64,
}

impl Metrics {
    /// Largest |feedforward change| across a branch switch, MPa (0 without
    /// switches).
    pub fn max_feedforward_jump_mpa(&self) -> f64 {
        self.switches
            .iter()
            .map(|s| s.feedforward_jump_mpa.abs())
            .fold(0.0, f64::max)
    }
}

/// A finished run.
#[derive(Clone, Debug)]
pub struct Run {
    /// The scenario's name.
    pub scenario: &'static str,
    /// The controller variant.
    pub mode: Mode,
    /// One row per control period.
    pub trace: Vec<TraceRow>,
    /// Statistics.
    pub metrics: Metrics,
    /// The first fault the controller went to its safe state for, and when
    /// (s); `None` for a run without one.
    pub first_fault: Option<(f64, Fault)>,
}

/// Non-local memory of [`Mode::FeedforwardMemoryPi`]: pam-core's linear
/// blend (`shape` 1) between a turning point and the previous one.
pub const MEMORY: NonLocalMemory = NonLocalMemory::with_shape(1.0);

/// The controller configuration `mode` runs with.
pub fn controller_config(mode: Mode, cfg: &BenchConfig) -> ControllerConfig {
    let mut c = cfg.controller;
    match mode {
        Mode::FeedforwardPi | Mode::DiagnosedFeedforwardPi => {}
        Mode::FeedforwardMemoryPi => c.feedforward = Feedforward::HysteresisMemory(MEMORY),
        Mode::PreisachFeedforwardPi => c.feedforward = Feedforward::Preisach,
        Mode::PiOnly => {
            c.feedforward = Feedforward::Off;
            c.integral_limit_mpa = PI_ONLY_INTEGRAL_LIMIT_MPA;
        }
    }
    c
}

/// Run `scenario` on the reference rig with the firmware's controller.
///
/// # Panics
/// If the firmware refuses the configuration or the parameters (a bench
/// set-up error, not a run-time condition).
pub fn run(scenario: &Scenario, mode: Mode, cfg: &BenchConfig) -> Run {
    let load0 = scenario.load_at(0.0);
    let rig = Rig::reference(load0, cfg.seed);
    let ctl_cfg = controller_config(mode, cfg);
    let coeffs = Coeffs::new(cfg.params).expect("bench parameters");
    let ctl = Controller::new(coeffs, ctl_cfg, load0 as f32).expect("controller config");
    run_controller(scenario, rig, ctl, mode, cfg.warmup_s)
}

/// Run `scenario` on the reference rig with the controller booted from
/// `blob` through the firmware's boot path ([`firmware::boot::boot`]) with
/// `mode`'s configuration, the model at the scenario's first load; the
/// reason when the firmware refuses the blob.
pub fn run_booted(
    scenario: &Scenario,
    blob: &[u8],
    mode: Mode,
    cfg: &BenchConfig,
) -> Result<Run, String> {
    let load0 = scenario.load_at(0.0);
    let booted = firmware::boot::boot(blob, controller_config(mode, cfg), |_| load0 as f32)
        .map_err(|e| format!("boot refused the blob: {e}"))?;
    let rig = Rig::reference(load0, cfg.seed);
    Ok(run_controller(
        scenario,
        rig,
        booted.controller,
        mode,
        cfg.warmup_s,
    ))
}

/// Run `scenario` on `rig` with the controller `ctl` (however it was
/// configured: from parameters or booted from a blob); `mode` labels the
/// run, `warmup_s` is left out of the error statistics.
pub fn run_controller(
    scenario: &Scenario,
    rig: Rig,
    mut ctl: Controller,
    mode: Mode,
    warmup_s: f64,
) -> Run {
    let rig: SharedRig = Rc::new(RefCell::new(rig));
    let RigIo {
        mut io,
        inlet,
        exhaust,
        ..
    } = rig_io(&rig).expect("valve config");
    let dt = f64::from(ctl.config().dt_s);
    let n = (scenario.duration_s / dt).round() as usize;
    let mut trace = Vec::with_capacity(n);
    let mut switch_idx = Vec::new();
    let mut load_switch_idx: Vec<(usize, f32)> = Vec::new();
    let mut first_fault = None;
    for k in 0..n {
        let t = k as f64 * dt;
        let load = scenario.load_at(t);
        rig.borrow_mut().set_load_n(load);
        let reference = scenario.reference_at(t);
        let step = ctl.step(&mut io, reference as f32);
        if step.tracker.branch_switch.is_some() {
            switch_idx.push(k);
        }
        if first_fault.is_none() {
            first_fault = step.new_fault.map(|f| (t, f));
        }
        if let Some(s) = step.tracker.load_switch {
            load_switch_idx.push((k, s.to_n));
        }
        let opening = valve_opening(ValveKind::PAIR, inlet.fraction(), exhaust.fraction());
        let s = rig.borrow().true_state();
        trace.push(TraceRow {
            t_s: t,
            reference,
            contraction: s.contraction,
            pressure_mpa: s.pressure_mpa,
            pressure_cmd_mpa: f64::from(step.pressure_cmd_mpa),
            feedforward_mpa: f64::from(step.feedforward_mpa),
            load_n: s.load_n,
            model_load_n: f64::from(ctl.model_load_n()),
            branch: match step.branch {
                Branch::Contraction => 1,
                Branch::Expansion => -1,
            },
            flow_cmd: match step.command {
                ValveCommand::Flow(f) => f64::from(f),
                ValveCommand::Safe(_) => 0.0,
            },
            fault: u8::from(step.fault.is_some()),
        });
        let mut r = rig.borrow_mut();
        r.opening = opening;
        r.advance(dt);
    }
    let metrics = metrics(
        scenario,
        &trace,
        &switch_idx,
        &load_switch_idx,
        warmup_s,
        dt,
    );
    Run {
        scenario: scenario.name,
        mode,
        trace,
        metrics,
        first_fault,
    }
}

fn metrics(
    scenario: &Scenario,
    trace: &[TraceRow],
    switch_idx: &[usize],
    load_switch_idx: &[(usize, f32)],
    warmup_s: f64,
    dt: f64,
) -> Metrics {
    let after: Vec<f64> = trace
        .iter()
        .filter(|r| r.t_s >= warmup_s)
        .map(|r| r.contraction - r.reference)
        .collect();
    let rms_error = (after.iter().map(|e| e * e).sum::<f64>() / after.len().max(1) as f64).sqrt();
    let max_error = after.iter().fold(0.0f64, |m, e| m.max(e.abs()));

    let mut load_steps = Vec::new();
    let mut worst_model_load_error_n = 0.0f64;
    for (i, w) in scenario.loads.windows(2).enumerate() {
        let (t_step, to_n) = w[1];
        let k_step = (t_step / dt).round() as usize;
        let k_end = scenario
            .loads
            .get(i + 2)
            .map(|l| (l.0 / dt).round() as usize)
            .unwrap_or(trace.len());
        let detected_after_samples = load_switch_idx
            .iter()
            .find(|(k, to)| *k >= k_step && *k < k_end && (f64::from(*to) - to_n).abs() <= 20.0)
            .map(|(k, _)| k - k_step);
        if let Some(last) = trace.get(k_end.saturating_sub(1)) {
            worst_model_load_error_n =
                worst_model_load_error_n.max((last.model_load_n - last.load_n).abs());
        }
        load_steps.push(LoadStepResult {
            t_s: t_step,
            from_n: w[0].1,
            to_n,
            detected_after_samples,
        });
    }

    let window = (0.05 / dt).round() as usize;
    let span = (0.01 / dt).round().max(1.0) as usize;
    let switches = switch_idx
        .iter()
        .filter(|&&k| k >= 1 && k + window < trace.len() && k >= window)
        .map(|&k| {
            let (before, at) = (&trace[k - 1], &trace[k]);
            let mut chamber_jump_mpa = 0.0f64;
            for j in (k - window)..(k + window - span) {
                chamber_jump_mpa = chamber_jump_mpa
                    .max((trace[j + span].pressure_mpa - trace[j].pressure_mpa).abs());
            }
            SwitchResult {
                t_s: at.t_s,
                to: if at.branch > 0 {
                    Branch::Contraction
                } else {
                    Branch::Expansion
                },
                feedforward_jump_mpa: at.feedforward_mpa - before.feedforward_mpa,
                command_jump_mpa: at.pressure_cmd_mpa - before.pressure_cmd_mpa,
                chamber_jump_mpa,
            }
        })
        .collect();
    Metrics {
        rms_error,
        max_error,
        load_steps,
        switches,
        fault_samples: trace.iter().filter(|r| r.fault != 0).count(),
        worst_model_load_error_n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pi_only_is_the_same_controller_without_feedforward() {
        let cfg = BenchConfig::default_with_seed(1);
        let ff = controller_config(Mode::FeedforwardPi, &cfg);
        let pi = controller_config(Mode::PiOnly, &cfg);
        assert_eq!(ff.feedforward, Feedforward::Hysteresis);
        assert_eq!(pi.feedforward, Feedforward::Off);
        assert_eq!((pi.kp_mpa, pi.ki_mpa_per_s), (ff.kp_mpa, ff.ki_mpa_per_s));
        assert_eq!(pi.pressure_gain_per_mpa, ff.pressure_gain_per_mpa);
        // The integral alone must be able to reach Pmax.
        assert!(pi.integral_limit_mpa >= cfg.params.points.max_pressure_mpa);
    }
}

//! Unit tests of the controller: law, monitor, configuration.

use super::*;
use crate::hal::SensorErrorKind;
use pam_core::effects::{Effects, NonLocalMemory};
use pam_core::Params;

fn controller() -> Controller {
    controller_with(no_model())
}

/// [`ControllerConfig::DEFAULT`] without the model check: these tests feed
/// synthetic samples, not a muscle (the check has its own tests).
fn no_model() -> ControllerConfig {
    let mut cfg = ControllerConfig::DEFAULT;
    cfg.safety.implausible_periods = 0;
    cfg
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
/// supply-loss, vent and model checks off.
fn synthetic() -> ControllerConfig {
    let mut cfg = no_model();
    cfg.safety.stuck_samples = 0;
    cfg.safety.supply_loss_periods = 0;
    cfg.safety.vent_periods = 0;
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
    let model = c.tracker().unwrap().model().clone();
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
    let up = c
        .tracker()
        .unwrap()
        .model()
        .pressure_mpa(x, Branch::Contraction);
    while sp > x {
        sp -= 1e-4;
        last = c.update(&good(0.2 - sp * 1e-3, sp, 200.0), sp);
    }
    assert_eq!(last.branch, Branch::Expansion);
    let m = c.tracker().unwrap().model();
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
    let m = c.tracker().unwrap().model().clone();
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
    use crate::plant::SimBus;
    use crate::sim_io::{SimContraction, SimLoad, SimPressure};
    let bus = SimBus::new();
    let cal = crate::hal::PressureCalibration::ADC12_0_1MPA;
    let mut io = Io {
        pressure: SimPressure {
            source: &bus,
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
        let model_n = c.tracker().unwrap().load_n();
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
    let be2 = 2.0 * c.tracker().unwrap().model().offset_mpa(0.11);
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
    let model = c.tracker().unwrap().model().clone();
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
    let m = c.tracker().unwrap().model();
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
            Err(ConfigError::Invalid(Setting::MemoryShape))
        ));
    }
}

#[test]
fn effects_are_validated_and_each_runs_from_a_blob() {
    use pam_core::effects::{ConstraintShape, Creep, Effects, LoadDependentWidth, RateDependence};
    let none = Effects::NONE;
    let each = [
        Effects {
            rate: Some(RateDependence::linear(1.0, 2.0)),
            ..none
        },
        Effects {
            creep: Some(Creep {
                gain: 0.3,
                time_constant_s: 1.0,
            }),
            ..none
        },
        Effects {
            width: Some(LoadDependentWidth {
                scale_at_min_load: 1.0,
                scale_per_step: 0.2,
            }),
            ..none
        },
        Effects {
            shape: Some(ConstraintShape {
                bulge: 0.2,
                ..ConstraintShape::NEUTRAL
            }),
            ..none
        },
    ];
    for e in each {
        let blob = pam_core::blob::encode_v2(&Params::DEFAULT, &e);
        let (_, ff) = crate::boot::model_from_blob(&blob, Feedforward::Hysteresis).unwrap();
        assert_eq!(ff, Feedforward::HysteresisEffects(e));
        // The comparison modes stay as configured.
        let (_, off) = crate::boot::model_from_blob(&blob, Feedforward::Off).unwrap();
        assert_eq!(off, Feedforward::Off);
        let mut cfg = synthetic();
        cfg.feedforward = Feedforward::Hysteresis;
        let mut c = Controller::from_blob(&blob, cfg, 200.0).unwrap();
        // Up, back and up again (no fault on the way, `sweep` checks):
        // finite feedforward within [0, Pmax].
        for (ff_mpa, _) in sweep(&mut c, &[0.06, 0.16, 0.08, 0.12]) {
            assert!((0.0..=0.5).contains(&ff_mpa), "{e:?}: {ff_mpa}");
        }
    }
    // Invalid effects, or a period the inverse cannot integrate, are refused.
    let mut cfg = ControllerConfig::DEFAULT;
    cfg.feedforward = Feedforward::HysteresisEffects(Effects {
        creep: Some(Creep {
            gain: 2.0,
            time_constant_s: 1.0,
        }),
        ..none
    });
    assert_eq!(
        cfg.validate(),
        Err(ConfigError::Invalid(Setting::FeedforwardEffects))
    );
    cfg.feedforward = Feedforward::HysteresisEffects(each[1]);
    cfg.dt_s = 2.0;
    assert_eq!(
        cfg.validate(),
        Err(ConfigError::Invalid(Setting::FeedforwardEffects))
    );
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
    let mut cfg = no_model();
    cfg.safety.supply_loss_periods = 0;
    let mut c = controller_with(cfg);
    for k in 0..1000u32 {
        assert_eq!(c.update(&starved(k, 0.1), 0.15).fault, None);
    }
}

#[test]
fn supply_loss_settings_are_validated() {
    for (flow, rise, field) in [
        (0.0, 0.01, Setting::SupplyLossFlow),
        (1.5, 0.01, Setting::SupplyLossFlow),
        (f32::NAN, 0.01, Setting::SupplyLossFlow),
        (0.95, 0.0, Setting::SupplyLossRiseMpa),
        (0.95, f32::INFINITY, Setting::SupplyLossRiseMpa),
    ] {
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.safety.supply_loss_flow = flow;
        cfg.safety.supply_loss_rise_mpa = rise;
        assert!(
            cfg.validate() == Err(ConfigError::Invalid(field)),
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
    let mut cfg = no_model();
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
        Err(ConfigError::Invalid(Setting::DtS))
    ));
    let mut cfg = ControllerConfig::DEFAULT;
    cfg.safety.recovery_samples = 0;
    assert!(matches!(
        cfg.validate(),
        Err(ConfigError::Invalid(Setting::RecoverySamples))
    ));
    for bad in [-1.0, f32::NAN, f32::INFINITY] {
        let mut cfg = ControllerConfig::DEFAULT;
        cfg.safety.load_margin_n = bad;
        assert!(matches!(
            cfg.validate(),
            Err(ConfigError::Invalid(Setting::LoadMarginN))
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

/// [`synthetic`] with the model check on (default bound and time).
fn model_only() -> ControllerConfig {
    let mut cfg = synthetic();
    cfg.safety.implausible_periods = ControllerConfig::DEFAULT.safety.implausible_periods;
    cfg
}

/// A controller of `cfg` past the model check's pause at its start: fed
/// `implausible_start_s` of samples inside the band at `p` MPa.
fn past_start(cfg: ControllerConfig, p: f32) -> Controller {
    let mut c = controller_with(cfg);
    let x = c
        .tracker()
        .unwrap()
        .model()
        .contraction(p, Branch::Contraction);
    for k in 0..(cfg.safety.implausible_start_s / cfg.dt_s) as u32 + 1 {
        let d = (k % 2) as f32 * 1e-4;
        assert_eq!(c.update(&good(p + d, x + d, 200.0), 0.12).fault, None);
    }
    c
}

#[test]
fn the_model_check_starts_paused_as_after_a_load_switch() {
    // A muscle beyond the band from the first period (a slow muscle
    // still at rest while the pressure rises): no fault while the check
    // settles, then the fault after its time outside the band.
    let cfg = model_only();
    let s = cfg.safety;
    let mut c = controller_with(cfg);
    let p = 0.3;
    let settle = (s.implausible_start_s / cfg.dt_s + 0.5) as u32;
    let n = u32::from(s.implausible_periods);
    for k in 0..(settle + n + 10) {
        let st = c.update(
            &beside_band(&c, k, p, s.implausible_contraction + 0.01),
            0.12,
        );
        if let Some(f) = st.new_fault {
            assert_eq!(f, Fault::Implausible(Check::Model));
            assert!(k >= settle + n - 1, "{k}");
            return;
        }
    }
    panic!("never tripped after the start's settling");
}

#[test]
fn fast_and_full_checks_agree_on_every_sample() {
    // One rule table behind both paths: for every combination of readings
    // the fast path's answer is the full check's.
    let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
    let mut s = ControllerConfig::DEFAULT.safety;
    s.stuck_samples = 0;
    let values = [
        Err(SensorErrorKind::Timeout),
        Ok(f32::NAN),
        Ok(f32::NEG_INFINITY),
        Ok(-1.0),
        Ok(-0.04),
        Ok(0.0),
        Ok(0.1),
        Ok(0.39),
        Ok(0.52),
        Ok(0.56),
        Ok(0.79),
        Ok(0.81),
        Ok(90.0),
        Ok(200.0),
        Ok(620.0),
        Ok(630.0),
        Ok(f32::MAX),
    ];
    for &p in &values {
        for &x in &values {
            for &l in &values {
                for sp in [0.1, f32::NAN] {
                    let sample = Sample {
                        pressure_mpa: p,
                        contraction: x,
                        load_n: l,
                    };
                    let mut fast =
                        monitor::Monitor::new(&s, &ModelLimits::of_coeffs(&coeffs), 1e-3, None);
                    let mut full = fast;
                    assert_eq!(
                        fast.check(&sample, sp),
                        full.check_full(&sample.readings(), sp),
                        "{sample:?} {sp}"
                    );
                }
            }
        }
    }
}

#[test]
fn pressure_above_pmax_plus_the_margin_is_over_pressure() {
    let s = ControllerConfig::DEFAULT.safety;
    let limit = Params::DEFAULT.points.max_pressure_mpa + s.overpressure_margin_mpa;
    let mut c = no_stuck_check();
    assert_eq!(c.update(&good(limit - 0.005, 0.2, 200.0), 0.2).fault, None);
    let st = c.update(&good(limit + 0.005, 0.2, 200.0), 0.2);
    assert_eq!(st.new_fault, Some(Fault::OverPressure));
    assert_eq!(st.command, ValveCommand::Safe(SafeState::Exhaust));
    // Above the plausible range it is an implausible reading instead.
    let st = c.update(&good(s.pressure_max_mpa + 0.1, 0.2, 200.0), 0.2);
    assert_eq!(st.fault, Some(Fault::OutOfRange(SensorId::Pressure)));
}

#[test]
fn a_model_whose_pmax_lies_above_the_hardware_limit_never_commands_above_it() {
    // A model whose loop closes at 0.62 MPa (`pam-lab diagnose` may put
    // `Pmax` up to 1.25x a record's top) on hardware limited to 0.54 MPa.
    let s = synthetic().safety;
    let mut params = Params::DEFAULT;
    params.points.max_pressure_mpa = 0.62;
    let coeffs = Coeffs::new(params).unwrap();
    let mut c = Controller::new(coeffs, synthetic(), 200.0).unwrap();
    // A set-point beyond reach: the command saturates at the limit.
    let mut highest = 0.0f32;
    for _ in 0..2_000 {
        let st = c.update(&good(0.5, 0.0, 200.0), 0.3);
        assert_eq!(st.fault, None);
        highest = highest.max(st.pressure_cmd_mpa);
    }
    assert_eq!(highest, s.max_command_mpa);
    // Over-pressure is judged from the limit, not from the model's Pmax.
    let limit = s.max_command_mpa + s.overpressure_margin_mpa;
    let mut c = Controller::new(coeffs, synthetic(), 200.0).unwrap();
    assert_eq!(c.update(&good(limit - 0.005, 0.2, 200.0), 0.2).fault, None);
    let st = c.update(&good(limit + 0.005, 0.2, 200.0), 0.2);
    assert_eq!(st.new_fault, Some(Fault::OverPressure));
    // A model whose Pmax is below the limit keeps its own.
    let mut c = no_stuck_check();
    let pmax = Params::DEFAULT.points.max_pressure_mpa;
    assert!(pmax < s.max_command_mpa);
    let mut highest = 0.0f32;
    for _ in 0..2_000 {
        highest = highest.max(c.update(&good(0.5, 0.0, 200.0), 0.3).pressure_cmd_mpa);
    }
    assert_eq!(highest, pmax);
}

/// Readings at `p` with the contraction `dx` beyond the expansion branch
/// (or inside the band when `dx` is negative enough), dithered by a count.
fn beside_band(c: &Controller, k: u32, p: f32, dx: f32) -> Sample {
    let m = c.tracker().unwrap().model();
    let x = m.contraction(p, Branch::Expansion) + dx;
    let d = (k % 2) as f32 * 1e-4;
    good(p, x + d, 200.0)
}

#[test]
fn the_model_check_trips_after_its_time_outside_the_band() {
    let cfg = model_only();
    let s = cfg.safety;
    let n = u32::from(s.implausible_periods);
    let p = 0.3;
    let mut c = past_start(cfg, p);
    // Inside the band, and up to the bound beyond it: never.
    for k in 0..(3 * n) {
        let smp = beside_band(&c, k, p, s.implausible_contraction - 0.002);
        let st = c.update(&smp, 0.12);
        assert_eq!(st.fault, None, "{k}");
        assert!(st.model_excess <= s.implausible_contraction);
    }
    // Beyond it: the fault on the n-th period in a row, valves safe.
    for k in 1..n {
        let smp = beside_band(&c, k, p, s.implausible_contraction + 0.01);
        assert_eq!(c.update(&smp, 0.12).fault, None, "{k}");
    }
    let st = c.update(&beside_band(&c, 0, p, 0.05), 0.12);
    assert_eq!(st.new_fault, Some(Fault::Implausible(Check::Model)));
    assert_eq!(st.command, ValveCommand::Safe(SafeState::Exhaust));
    // Below the contraction branch too.
    let mut c = past_start(cfg, p);
    let m = c.tracker().unwrap().model().clone();
    let below = m.contraction(p, Branch::Contraction) - s.implausible_contraction - 0.01;
    let tripped = (0..n).map(|k| c.update(&good(p, below + (k % 2) as f32 * 1e-4, 200.0), 0.12));
    assert_eq!(
        tripped.last().unwrap().fault,
        Some(Fault::Implausible(Check::Model))
    );
    // Disabled with 0 periods.
    let mut c = controller_with(synthetic());
    for k in 0..(3 * n) {
        assert_eq!(c.update(&beside_band(&c, k, p, 0.1), 0.12).fault, None);
    }
}

#[test]
fn a_period_that_makes_a_minor_loop_leaves_the_model_check_to_the_next() {
    // A muscle beyond the band every period while the set-point rises and
    // turns back: the memory feedforward makes the turn's minor loop, and
    // on those periods the check does not judge (no excess reported); the
    // next judged period counts for them, so the trip comes after the
    // configured number of periods all the same. With a rate law the
    // loop's ends also move to the law's new factor, every second period
    // at most while the set-point moves: the check still judges at least
    // every second period.
    let memory = Effects {
        memory: Some(NonLocalMemory::with_shape(1.0)),
        ..Effects::NONE
    };
    let memory_rate = Effects {
        rate: Some(pam_core::effects::RateDependence::linear(1.0, 2.0)),
        ..memory
    };
    // Periods left to the next by the memory alone.
    let mut skipped_by_memory = 0;
    for (effects, rate) in [(memory, false), (memory_rate, true)] {
        let mut cfg = model_only();
        cfg.feedforward = Feedforward::HysteresisEffects(effects);
        let s = cfg.safety;
        let n = u32::from(s.implausible_periods);
        let p = 0.3;
        let mut c = past_start(cfg, p);
        let turn = n / 2;
        let mut skipped = 0;
        // Periods left to the next in a row just before this one.
        let mut skipped_before = 0;
        let mut tripped = false;
        for k in 0..(2 * n) {
            let back = k.saturating_sub(turn) as f32;
            let set_point = 0.12 + 1e-4 * (k.min(turn) as f32 - back);
            let st = c.update(
                &beside_band(&c, k, p, s.implausible_contraction + 0.01),
                set_point,
            );
            let left = c.law.rebuilt_loop();
            if left {
                skipped += 1;
                assert_eq!(st.model_excess, 0.0, "{k}");
            }
            if let Some(f) = st.new_fault {
                assert_eq!(f, Fault::Implausible(Check::Model));
                assert!(skipped > 0, "the turn made no minor loop");
                // The n-th period, or the first judged one after it.
                assert!(
                    k + 1 >= n && k + 1 - n <= skipped_before,
                    "{k}, {skipped}, rate {rate}"
                );
                // The rate law's new factors leave more periods to the
                // next, never more than the ones judged.
                if rate {
                    assert!(
                        skipped > skipped_by_memory && 2 * skipped <= k + 2,
                        "{skipped} of {k}, the memory alone {skipped_by_memory}"
                    );
                } else {
                    skipped_by_memory = skipped;
                }
                tripped = true;
                break;
            }
            skipped_before = if left { skipped_before + 1 } else { 0 };
        }
        assert!(tripped, "never tripped, rate {rate}");
    }
}

#[test]
fn the_model_band_follows_the_pressure_with_the_lag() {
    // A pressure step up: the contraction still at the old pressure's
    // band is accepted while the lagged minimum relaxes (lag 50 ms), then
    // not.
    let cfg = model_only();
    let mut c = past_start(cfg, 0.1);
    let m = c.tracker().unwrap().model().clone();
    let x_old = m.contraction(0.1, Branch::Contraction);
    for k in 0..200u32 {
        let d = (k % 2) as f32 * 1e-4;
        assert_eq!(c.update(&good(0.1 + d, x_old, 200.0), 0.12).fault, None);
    }
    let mut excess_at = Vec::new();
    for k in 0..400u32 {
        let d = (k % 2) as f32 * 1e-4;
        let st = c.update(&good(0.45 + d, x_old + d, 200.0), 0.12);
        excess_at.push(st.model_excess);
    }
    let bound = cfg.safety.implausible_contraction;
    assert!(excess_at[0] < 0.1 * bound, "{}", excess_at[0]);
    assert!(
        excess_at[399] > cfg.safety.implausible_contraction,
        "{excess_at:?}"
    );
}

#[test]
fn the_model_check_pauses_while_a_load_step_settles() {
    let cfg = model_only();
    let s = cfg.safety;
    let mut c = controller_with(cfg);
    let p = 0.35;
    let x = c
        .tracker()
        .unwrap()
        .model()
        .contraction(p, Branch::Contraction);
    // The load steps to 600 N; the muscle (this contraction) would belong
    // to 200 N, outside the new load's band.
    let heavy = Coeffs::new(Params::DEFAULT)
        .unwrap()
        .load_model_clamped(600.0);
    assert!(x > heavy.contraction(p, Branch::Expansion) + s.implausible_contraction);
    let mut switched_at = None;
    let settle = (s.implausible_settle_s / cfg.dt_s) as u32;
    // The check resumes after the new model's table build and the settling.
    let build = pam_core::load_model::BUILD_UNITS_MAX
        .div_ceil(usize::from(super::TABLE_BUILD_UNITS_PER_STEP)) as u32;
    for k in 0..(build + settle + u32::from(s.implausible_periods) + 10) {
        let d = (k % 2) as f32 * 1e-4;
        let st = c.update(&good(p + d, x, 600.0 + d), 0.12);
        if st.tracker.load_switch.is_some() {
            switched_at = Some(k);
        }
        if let Some(f) = st.new_fault {
            let at = k - switched_at.unwrap();
            assert_eq!(f, Fault::Implausible(Check::Model));
            assert!(at >= settle, "{at}");
            return;
        }
    }
    panic!("never tripped after settling");
}

/// Readings with the muscle beyond a set-point far below (exhaust
/// saturated open), the pressure at `p`, dithered by a count.
fn venting(k: u32, p: f32) -> Sample {
    let d = (k % 2) as f32 * 3e-4;
    good(p + d, 0.2 + (k % 3) as f32 * 1e-4, 200.0 + d)
}

#[test]
fn the_vent_check_faults_when_the_pressure_does_not_fall() {
    let mut cfg = synthetic();
    cfg.safety.vent_periods = ControllerConfig::DEFAULT.safety.vent_periods;
    let s = cfg.safety;
    let n = u32::from(s.vent_periods);
    let mut c = controller_with(cfg);
    for k in 0..n {
        let st = c.update(&venting(k, 0.3), 0.02);
        assert_eq!(st.fault, None, "{k}");
        assert!(matches!(st.command, ValveCommand::Flow(f) if f <= -s.vent_flow));
    }
    let st = c.update(&venting(n, 0.3), 0.02);
    assert_eq!(st.new_fault, Some(Fault::Implausible(Check::Vent)));
    // Falling by the threshold per window: never.
    let mut c = controller_with(cfg);
    let per = s.vent_fall_mpa / n as f32 * 1.05;
    for k in 0..(5 * n) {
        let p = 0.45 - k as f32 * per;
        assert_eq!(c.update(&venting(k, p), 0.02).fault, None, "{k} {p}");
    }
    // Near atmosphere there is nothing to vent: never.
    let mut c = controller_with(cfg);
    for k in 0..(5 * n) {
        let st = c.update(&venting(k, s.vent_min_mpa * 0.5), 0.0);
        assert_eq!(st.fault, None, "{k}");
    }
}

#[test]
fn overruns_in_a_row_fault_and_clear() {
    let limit = ControllerConfig::DEFAULT.safety.overrun_limit;
    let mut c = no_stuck_check();
    let ok = |k: u16| good(0.2, 0.1 + f32::from(k % 2) * 1e-4, 200.0);
    // Fewer than the limit in a row, repeatedly: never.
    for k in 0..1000u16 {
        c.record_overrun(k % limit != 0);
        assert_eq!(c.update(&ok(k), 0.1).fault, None);
    }
    for k in 0..limit {
        c.record_overrun(true);
        let st = c.update(&ok(k), 0.1);
        if k + 1 < limit {
            assert_eq!(st.fault, None);
        } else {
            assert_eq!(st.new_fault, Some(Fault::Overrun));
        }
    }
    c.record_overrun(false);
    let n = ControllerConfig::DEFAULT.safety.recovery_samples;
    let recovered = (0..n).map(|k| c.update(&ok(k), 0.1)).any(|st| st.recovered);
    assert!(recovered);
}

#[test]
fn repeated_trips_latch_until_the_operator_resets() {
    let s = ControllerConfig::DEFAULT.safety;
    let mut c = no_stuck_check();
    let ok = |k: u32| good(0.2, 0.1 + (k % 2) as f32 * 1e-4, 200.0);
    let nan = Sample {
        contraction: Ok(f32::NAN),
        ..ok(0)
    };
    // One NaN every 60 samples: each trip recovers after 50, until the
    // (latch_trips + 1)-th within the window latches.
    let mut trips = 0;
    for k in 0..(60 * u32::from(s.latch_trips + 1)) {
        let st = c.update(&(if k % 60 == 0 { nan } else { ok(k) }), 0.1);
        if st.new_fault.is_some() {
            trips += 1;
            assert_eq!(st.latched, trips > s.latch_trips);
        }
    }
    assert!(c.latched());
    // Good samples do not clear a latch.
    for k in 0..20_000 {
        let st = c.update(&ok(k), 0.1);
        assert_eq!(st.command, ValveCommand::Safe(SafeState::Exhaust));
        assert!(st.latched && !st.recovered);
    }
    // The operator's reset: control after the recovery run.
    c.reset_latch();
    assert!(!c.latched());
    let mut recovered_after = None;
    for k in 0..u32::from(s.recovery_samples) {
        if c.update(&ok(k), 0.1).recovered {
            recovered_after = Some(k + 1);
        }
    }
    assert_eq!(recovered_after, Some(u32::from(s.recovery_samples)));
    // Trips further apart than the window never latch.
    let mut c = no_stuck_check();
    let gap = s.latch_window_periods / u32::from(s.latch_trips) + 1;
    for k in 0..(gap * 10) {
        let st = c.update(&(if k % gap == 0 { nan } else { ok(k) }), 0.1);
        assert!(!st.latched, "{k}");
    }
}

#[test]
fn a_latch_at_boot_holds_the_safe_state_until_reset() {
    let mut c = no_stuck_check();
    c.latch(Fault::Watchdog);
    for k in 0..1000u32 {
        let st = c.update(&good(0.2, 0.1 + (k % 2) as f32 * 1e-4, 200.0), 0.1);
        assert_eq!(st.fault, Some(Fault::Watchdog));
        assert_eq!(st.command, ValveCommand::Safe(SafeState::Exhaust));
    }
    c.reset_latch();
    let n = u32::from(ControllerConfig::DEFAULT.safety.recovery_samples);
    let st = (0..n)
        .map(|k| c.update(&good(0.2, 0.1 + (k % 2) as f32 * 1e-4, 200.0), 0.1))
        .last()
        .unwrap();
    assert!(st.recovered);
}

#[test]
fn every_setting_names_itself_and_its_requirement() {
    let e = ConfigError::Invalid(Setting::ImplausibleContraction);
    assert_eq!(
        std::format!("{e}"),
        "`implausible_contraction` must be finite and > 0"
    );
    let mut cfg = ControllerConfig::DEFAULT;
    cfg.safety.overpressure_margin_mpa = 0.0;
    assert_eq!(
        cfg.validate(),
        Err(ConfigError::Invalid(Setting::OverpressureMarginMpa))
    );
    let mut cfg = ControllerConfig::DEFAULT;
    cfg.safety.max_command_mpa = f32::NAN;
    assert_eq!(
        cfg.validate(),
        Err(ConfigError::Invalid(Setting::MaxCommandMpa))
    );
    assert_eq!(
        std::format!("{}", ConfigError::Invalid(Setting::MaxCommandMpa)),
        "`max_command_mpa` must be finite and > 0 MPa"
    );
    let mut cfg = ControllerConfig::DEFAULT;
    cfg.safety.latch_window_periods = 0;
    assert_eq!(
        cfg.validate(),
        Err(ConfigError::Invalid(Setting::LatchWindowPeriods))
    );
    let mut cfg = ControllerConfig::DEFAULT;
    cfg.safety.implausible_lag_s = f32::NAN;
    assert_eq!(
        cfg.validate(),
        Err(ConfigError::Invalid(Setting::ImplausibleLagS))
    );
}

/// [`synthetic`] with the online adaptation updating from the first
/// period.
fn adapting() -> ControllerConfig {
    ControllerConfig {
        adaptation: Some(AdaptationConfig {
            settle_periods: 0,
            ..AdaptationConfig::DEFAULT
        }),
        ..synthetic()
    }
}

/// Readings of a muscle whose stroke is `scale` times the model's, holding
/// a slow pressure ramp at period `k`.
fn scaled_muscle(c: &Controller, scale: f32, k: usize) -> (Sample, f32) {
    let m = c.tracker().unwrap().model();
    let p = 0.15 + 0.2 * ((k % 4000) as f32 / 4000.0);
    let r = m.root_contraction();
    let x = r + scale * (m.contraction(p, Branch::Contraction) - r);
    (good(p, x, 200.0), x)
}

#[test]
fn the_adaptation_learns_the_stroke_and_the_feedforward_uses_it() {
    let mut c = controller_with(adapting());
    for k in 0..20_000 {
        let (s, x) = scaled_muscle(&c, 0.9, k);
        let step = c.update(&s, x);
        assert_eq!(step.fault, None);
    }
    let scale = c.adaptation().unwrap().scale();
    assert!((0.9 - 1e-3..0.99).contains(&scale), "{scale}");
    // The feedforward holds a set-point on the adapted stroke: the flashed
    // model's pressure for `R + (x − R)/s`.
    let m = c.tracker().unwrap().model().clone();
    let x = 0.12;
    let (s, _) = scaled_muscle(&c, 0.9, 0);
    let step = c.update(
        &Sample {
            contraction: Ok(x),
            ..s
        },
        x,
    );
    let scale = c.adaptation().unwrap().scale();
    let want = m.pressure_mpa(
        m.root_contraction() + (x - m.root_contraction()) / scale,
        step.branch,
    );
    assert!(
        (step.feedforward_mpa - want).abs() < 1e-4,
        "{} vs {want}",
        step.feedforward_mpa
    );
    // Not the flashed model's own pressure for x.
    assert!((step.feedforward_mpa - m.pressure_mpa(x, step.branch)).abs() > 0.005);
}

#[test]
fn the_adaptation_is_frozen_while_a_fault_is_active_and_while_recovering() {
    let mut c = controller_with(adapting());
    for k in 0..3_000 {
        let (s, x) = scaled_muscle(&c, 0.9, k);
        c.update(&s, x);
    }
    let before = c.adaptation().unwrap().scale();
    assert!(before < 1.0);
    // A pressure read error for 100 periods (the other readings those of
    // a muscle at half the stroke), then good readings: nothing may move
    // until the recovery run is over.
    let recovery = usize::from(c.config().safety.recovery_samples);
    for k in 0..100 {
        let (s, x) = scaled_muscle(&c, 0.5, k);
        let bad = Sample {
            pressure_mpa: Err(SensorErrorKind::Timeout),
            ..s
        };
        assert!(c.update(&bad, x).fault.is_some());
        assert_eq!(c.adaptation().unwrap().scale(), before);
    }
    for k in 0..recovery {
        let (s, x) = scaled_muscle(&c, 0.9, k);
        c.update(&s, x);
        assert_eq!(
            c.adaptation().unwrap().scale(),
            before,
            "period {k} of the recovery"
        );
    }
    // The test's configuration has no settling time: once recovered, and
    // the pressure filter past the jump from where the fault left it (a
    // transient), the estimate moves again.
    for k in 0..500 {
        let (s, x) = scaled_muscle(&c, 0.9, recovery + k);
        assert_eq!(c.update(&s, x).fault, None);
    }
    assert!(c.adaptation().unwrap().scale() < before);
}

#[test]
fn a_muscle_beyond_the_bound_is_the_drift_fault_latched_with_valves_safe() {
    let mut c = controller_with(adapting());
    let mut fault = None;
    for k in 0..200_000 {
        let (s, x) = scaled_muscle(&c, 0.6, k);
        let step = c.update(&s, x);
        if let Some(f) = step.new_fault {
            fault = Some((f, step.command, step.latched));
            break;
        }
    }
    let (f, command, latched) = fault.expect("never reported");
    assert_eq!(f, Fault::Drifted);
    assert_eq!(command, ValveCommand::Safe(c.config().safety.safe_state));
    assert!(latched && c.latched());
    // Latched: good readings do not bring control back.
    for k in 0..1_000 {
        let (s, x) = scaled_muscle(&c, 1.0, k);
        assert!(c.update(&s, x).fault.is_some());
    }
}

#[test]
fn adaptation_is_refused_with_a_feedforward_other_than_the_papers() {
    let memory = ControllerConfig {
        feedforward: Feedforward::HysteresisMemory(NonLocalMemory::with_shape(1.0)),
        ..adapting()
    };
    assert_eq!(
        Controller::new(Coeffs::new(Params::DEFAULT).unwrap(), memory, 200.0).err(),
        Some(ConfigError::Invalid(Setting::Adaptation))
    );
    let bad = ControllerConfig {
        adaptation: Some(AdaptationConfig {
            bound: 0.0,
            ..AdaptationConfig::DEFAULT
        }),
        ..ControllerConfig::DEFAULT
    };
    assert_eq!(
        bad.validate(),
        Err(ConfigError::Invalid(Setting::Adaptation))
    );
}

/// A muscle that is its own rate model: pam-core's `Simulator` of the
/// paper's model with the rate law `rate`, fed `pressures` (one a period),
/// its contraction read `offset` beyond it; the controller of that model
/// holds a set-point while the pressure moves (a disturbance the loop
/// corrects: the desired motion is still). The fault, if any.
fn own_rate_muscle(
    rate: pam_core::effects::RateDependence,
    pressures: &[f32],
    offset: f32,
) -> Option<Fault> {
    use pam_core::effects::Effects;
    use pam_core::{Simulator, TrackerConfig};
    let effects = Effects {
        rate: Some(rate),
        ..Effects::NONE
    };
    let mut cfg = model_only();
    cfg.feedforward = Feedforward::HysteresisEffects(effects);
    let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
    let mut c = Controller::new(coeffs, cfg, 200.0).unwrap();
    let mut muscle =
        Simulator::<16>::new(coeffs, effects, TrackerConfig::DEFAULT_PRESSURE, 200.0).unwrap();
    for (k, &p) in pressures.iter().enumerate() {
        let x = muscle.step(k as f32 * cfg.dt_s, p, 200.0) + offset;
        let d = (k % 2) as f32 * 1e-4;
        if let Some(f) = c.update(&good(p + d, x, 200.0 + d), 0.12).new_fault {
            return Some(f);
        }
    }
    None
}

/// The pressure held at 0.1 MPa for `hold_s`, then triangles between 0.1
/// and 0.45 MPa at `rate_mpa_per_s`, for `cycles`, at the period `dt_s`.
fn pressure_triangles(dt_s: f32, hold_s: f32, rate_mpa_per_s: f32, cycles: usize) -> Vec<f32> {
    let mut p = vec![0.1; (hold_s / dt_s) as usize];
    let per_leg = (0.35 / rate_mpa_per_s / dt_s) as usize;
    for _ in 0..cycles {
        for k in 0..per_leg {
            p.push(0.1 + 0.35 * k as f32 / per_leg as f32);
        }
        for k in 0..per_leg {
            p.push(0.45 - 0.35 * k as f32 / per_leg as f32);
        }
    }
    p
}

#[test]
fn a_muscle_that_is_its_own_rate_model_passes_the_model_check() {
    // The loop a rate law widens is the loop of the pressure the muscle
    // sees, not of the desired motion: with the set-point held, the
    // feedforward's rate is at rest while the measured pressure sweeps at
    // 0.3 MPa/s, where this law's loop is 2.8 times the paper's. Judged by
    // the feedforward's rate alone, the muscle left the band and tripped.
    let law = pam_core::effects::RateDependence::linear(1.0, 6.0);
    let dt = ControllerConfig::DEFAULT.dt_s;
    let sweeps = pressure_triangles(dt, 1.5, 0.3, 3);
    assert_eq!(own_rate_muscle(law, &sweeps, 0.0), None);
    // The check still sees a muscle beyond the widest loop the law allows.
    let s = ControllerConfig::DEFAULT.safety;
    assert_eq!(
        own_rate_muscle(law, &sweeps, 0.1 + s.implausible_contraction),
        Some(Fault::Implausible(Check::Model))
    );
}

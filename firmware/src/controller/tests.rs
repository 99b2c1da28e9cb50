//! Unit tests of the controller: law, monitor, configuration.

use super::*;
use crate::hal::SensorErrorKind;
use pam_core::effects::NonLocalMemory;
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
            Err(ConfigError::Invalid(Setting::MemoryShape))
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

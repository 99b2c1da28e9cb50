//! The run-pass scenario of the QEMU image (and of a host test): the real
//! [`Controller`] drives the simulated muscle of [`crate::plant`] through a
//! triangle trajectory, with one injected sensor fault.
//!
//! * Trajectory: contraction `LOW → HIGH → LOW` ([`LOW`], [`HIGH`]), period
//!   [`PERIOD_S`], [`CYCLES`] cycles, at [`LOAD_N`], sampled every
//!   `ControllerConfig::DEFAULT.dt_s`.
//! * Plant: the controller's parameters with a 25 % higher ellipse (wider
//!   hysteresis loop) and a 10 % faster growth of `c` with load
//!   ([`plant_params`]), inlet/exhaust on/off valves with a 5 % dead duty, a
//!   30 ms lag, and uniform sensor noise of [`NOISE`].
//! * Fault: the pressure sensor times out for [`FAULT_SAMPLES`] samples from
//!   [`FAULT_AT_S`]; the valves must be in the safe state (exhaust) after the
//!   very step that read the first bad sample, and control must resume after
//!   `recovery_samples` good samples.
//! * Pass: the tracking error `|desired − actual contraction|` (the plant's
//!   true contraction, not the noisy sensor) from [`EVAL_FROM_S`] on stays
//!   within [`MAX_ERROR_BOUND`], the fault is caught as above, and no other
//!   fault occurs.

use crate::controller::{
    ConfigError, Controller, ControllerConfig, Feedforward, Io, SensorId, Step,
};
use crate::hal::{PressureCalibration, SensorErrorKind, ValvePair, ValvePairConfig};
use crate::plant::{MusclePlant, Noise, PlantConfig, SimBus};
use crate::sim_io::{SimContraction, SimLoad, SimPressure, SimPwm, PWM_MAX_DUTY};
use core::cell::Cell;
use pam_core::{Coeffs, Params};

pub use crate::exercise::{triangle, HIGH, LOW, PERIOD_S};

/// Number of periods.
pub const CYCLES: u32 = 3;
/// Load on the muscle, N.
pub const LOAD_N: f32 = 200.0;
/// When the pressure sensor starts timing out, s.
pub const FAULT_AT_S: f32 = 1.5;
/// For how many samples it times out.
pub const FAULT_SAMPLES: u32 = 10;
/// Start of the error evaluation (after the first period: start-up from
/// rest and the injected fault are transients), s.
pub const EVAL_FROM_S: f32 = PERIOD_S;
/// Sensor noise amplitudes (uniform): pressure in MPa, contraction, load in N.
pub const NOISE: (f32, f32, f32) = (0.001, 0.0002, 2.0);
/// The stated bound on the tracking error after [`EVAL_FROM_S`], fraction of
/// rest length (0.5 % of the muscle's length; the stroke is 10 %).
pub const MAX_ERROR_BOUND: f32 = 0.005;

/// The plant's parameters: the controller's ([`Params::DEFAULT`]) with a
/// wider hysteresis loop and a stiffer load dependence, so the model is not
/// exact.
pub fn plant_params() -> Params {
    let mut p = Params::DEFAULT;
    p.ellipse_height_mpa *= 1.25;
    p.c_growth_per_step *= 1.1;
    p
}

/// What the run measured.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Report {
    /// Steps run.
    pub steps: u32,
    /// Largest `|desired − actual|` from [`EVAL_FROM_S`] on.
    pub max_error: f32,
    /// RMS of the same.
    pub rms_error: f32,
    /// The injected fault was reported on the step that read it, and the
    /// valves were in the safe state after that step.
    pub fault_caught: bool,
    /// Steps from the end of the injected fault to the recovery.
    pub recovery_steps: Option<u32>,
    /// Faults reported other than the injected one.
    pub other_faults: u32,
    /// The online adaptation's stroke scale at the end (1 without it:
    /// feature `adapt`).
    pub stroke_scale: f32,
}

impl Report {
    /// Whether the run passes (see the module docs).
    pub fn passed(&self) -> bool {
        self.max_error <= MAX_ERROR_BOUND
            && self.fault_caught
            && self.recovery_steps.is_some()
            && self.other_faults == 0
    }
}

/// The hardware of the images: the simulated bus's sensors and valve pair.
pub type SimIo<'a> = Io<
    SimPressure<&'a SimBus>,
    SimContraction<&'a SimBus>,
    SimLoad<&'a SimBus>,
    ValvePair<SimPwm<&'a Cell<u16>>, SimPwm<&'a Cell<u16>>>,
>;

/// One control period of the images: [`Controller::step`] on [`SimIo`].
///
/// Not inlined and exported unmangled as `pam_control_step`, so that
/// `firmware/panic-check.sh` finds it in the LTO image and checks that no
/// panic is reachable from it (the whole read → compute → write path, as the
/// image runs it).
// `no_mangle` is flagged by the `unsafe_code` lint (symbol clashes); the
// name is unique to this crate.
#[allow(unsafe_code)]
#[no_mangle]
#[inline(never)]
pub fn pam_control_step(
    ctl: &mut Controller,
    io: &mut SimIo<'_>,
    desired_contraction: f32,
) -> Step {
    ctl.step(io, desired_contraction)
}

/// The effects of the version-2 blob the `qemu-memory-blob` self-test boots
/// (`firmware/build.rs` writes the same): non-local memory with `shape` 1 and
/// a merge span of 0.02 of contraction, the self-test plant's play-type
/// friction reaching the other branch within a few hundredths.
pub const MEMORY_BLOB_EFFECTS: pam_core::Effects = pam_core::Effects {
    memory: Some(pam_core::effects::NonLocalMemory {
        shape: 1.0,
        merge_span: 0.02,
    }),
    rate: None,
    creep: None,
    width: None,
    shape: None,
    pressure_lag: None,
    pressure_delay: None,
};

/// The effects of the version-2 blob the `qemu-effects-blob` self-test
/// boots (`firmware/build.rs` writes the same): every effect a version-2
/// blob can carry, each small (the self-test plant has none of them: the run checks
/// that a controller inverting all of them boots, runs within its
/// worst-case budget and still tracks within [`MAX_ERROR_BOUND`]).
pub const EFFECTS_BLOB_EFFECTS: pam_core::Effects = pam_core::Effects {
    memory: Some(pam_core::effects::NonLocalMemory {
        shape: 1.0,
        merge_span: 0.02,
    }),
    rate: Some(pam_core::effects::RateDependence::linear(1.0, 0.5)),
    creep: Some(pam_core::effects::Creep {
        gain: 0.05,
        time_constant_s: 0.5,
    }),
    width: Some(pam_core::effects::LoadDependentWidth {
        scale_at_min_load: 1.0,
        scale_per_step: 0.05,
    }),
    shape: Some(pam_core::effects::ConstraintShape {
        bulge: 0.05,
        tilt: 0.0,
        bulge_per_step: 0.0,
        tilt_per_step: 0.0,
        ..pam_core::effects::ConstraintShape::NEUTRAL
    }),
    // Version 4's: not in this version-2 blob.
    pressure_lag: None,
    pressure_delay: None,
};

/// Run the scenario with the controller built from `blob` and the given
/// feedforward; `on_event` sees every step that reports a new fault or a
/// recovery (the firmware logs them).
pub fn run(
    blob: &[u8],
    feedforward: Feedforward,
    on_event: impl FnMut(u32, &Step),
) -> Result<Report, ConfigError> {
    let plant_coeffs = Coeffs::new(plant_params()).map_err(ConfigError::Coefficients)?;
    let plant = MusclePlant::new(
        plant_coeffs.load_model_clamped(LOAD_N),
        PlantConfig::DEFAULT,
    );
    run_on(blob, feedforward, plant, on_event)
}

/// [`run`] on a plant with `effects` (the [`plant_params`] model with
/// them, [`MusclePlant::with_effects`]).
pub fn run_with_plant_effects(
    blob: &[u8],
    feedforward: Feedforward,
    effects: pam_core::Effects,
) -> Result<Report, ConfigError> {
    let plant_coeffs = Coeffs::new(plant_params()).map_err(ConfigError::Coefficients)?;
    let plant = MusclePlant::with_effects(plant_coeffs, effects, LOAD_N, PlantConfig::DEFAULT)
        .map_err(ConfigError::Coefficients)?;
    run_on(blob, feedforward, plant, |_, _| {})
}

/// [`run`] on a given plant.
pub fn run_on(
    blob: &[u8],
    feedforward: Feedforward,
    plant: MusclePlant,
    mut on_event: impl FnMut(u32, &Step),
) -> Result<Report, ConfigError> {
    let mut config = ControllerConfig::DEFAULT;
    config.feedforward = feedforward;
    if cfg!(feature = "adapt")
        && matches!(
            feedforward,
            Feedforward::Hysteresis | Feedforward::Constraint
        )
    {
        config.adaptation = Some(crate::controller::AdaptationConfig::DEFAULT);
    }
    let dt_s = config.dt_s;
    let mut ctl = Controller::from_blob(blob, config, LOAD_N)?;
    // Rounded: 12 s / 1 ms is 11999.999… in f32.
    let steps = (CYCLES as f32 * PERIOD_S / dt_s + 0.5) as u32;
    let fault_from = (FAULT_AT_S / dt_s + 0.5) as u32;
    let fault_to = fault_from + FAULT_SAMPLES;
    let eval_from = (EVAL_FROM_S / dt_s + 0.5) as u32;
    let mut report = Report {
        steps,
        max_error: 0.0,
        rms_error: 0.0,
        fault_caught: false,
        recovery_steps: None,
        other_faults: 0,
        stroke_scale: 1.0,
    };
    let injected = |k: u32| {
        (k >= fault_from && k < fault_to).then_some((SensorId::Pressure, SensorErrorKind::Timeout))
    };
    let (rms_error, max_error) = drive(
        &mut ctl,
        plant,
        LOAD_N,
        (steps, eval_from),
        |k| triangle(k as f32 * dt_s),
        injected,
        |k, step, duties| {
            if step.new_fault.is_some() || step.recovered {
                on_event(k, step);
            }
            if let Some(f) = step.new_fault {
                if k == fault_from {
                    report.fault_caught = duties == (0, PWM_MAX_DUTY)
                        && f == crate::controller::Fault::Read {
                            sensor: SensorId::Pressure,
                            kind: SensorErrorKind::Timeout,
                        };
                } else {
                    report.other_faults += 1;
                }
            }
            if step.recovered && k >= fault_to && report.recovery_steps.is_none() {
                report.recovery_steps = Some(k - fault_to + 1);
            }
        },
    )?;
    report.rms_error = rms_error;
    report.max_error = max_error;
    report.stroke_scale = ctl.adaptation().map_or(1.0, |a| a.scale());
    Ok(report)
}

/// What [`track_on`] measured.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Tracking {
    /// RMS of `|desired − actual|` (the plant's true contraction) from the
    /// evaluation's first step on.
    pub rms_error: f32,
    /// Largest `|desired − actual|` over the same steps.
    pub max_error: f32,
    /// Faults the controller reported (each puts the valves safe).
    pub faults: u32,
    /// The first of them and the step that reported it.
    pub first_fault: Option<(u32, crate::controller::Fault)>,
}

/// The controller booted from `blob` (with [`ControllerConfig::DEFAULT`]
/// and the feedforward the blob's model asks for, as the image boots it)
/// drives `plant` at `load_n` along `desired(t_s)` for `steps` periods,
/// with the self-test's sensor noise ([`NOISE`]) and no injected fault;
/// the error is judged from step `eval_from` on. The closed loop a host
/// tool runs on a model before it is flashed (`pam-lab diagnose`).
pub fn track_on(
    blob: &[u8],
    plant: MusclePlant,
    load_n: f32,
    desired: impl Fn(f32) -> f32,
    steps: u32,
    eval_from: u32,
) -> Result<Tracking, ConfigError> {
    let config = ControllerConfig {
        feedforward: Feedforward::Hysteresis,
        ..ControllerConfig::DEFAULT
    };
    let dt_s = config.dt_s;
    let mut ctl = Controller::from_blob(blob, config, load_n)?;
    let mut faults = 0;
    let mut first_fault = None;
    let (rms_error, max_error) = drive(
        &mut ctl,
        plant,
        load_n,
        (steps, eval_from),
        |k| desired(k as f32 * dt_s),
        |_| None,
        |k, step, _| {
            if let Some(f) = step.new_fault {
                faults += 1;
                if first_fault.is_none() {
                    first_fault = Some((k, f));
                }
            }
        },
    )?;
    Ok(Tracking {
        rms_error,
        max_error,
        faults,
        first_fault,
    })
}

/// The simulated rig of the scenarios: `ctl` drives `plant` at `load_n`
/// through the simulated sensors and valve pair, one control period a
/// step, for `steps` steps (`(steps, eval_from)`). `desired(k)` is step
/// `k`'s set-point, `failing(k)` the sensor fault injected on it, and
/// `after_step(k, step, duties)` sees each step's outcome and the valves'
/// raw duties before the plant moves. Returns the RMS and the largest
/// `|desired − actual|` (the plant's true contraction, not the noisy
/// sensor) from step `eval_from` on (infinite once it is NaN).
fn drive(
    ctl: &mut Controller,
    mut plant: MusclePlant,
    load_n: f32,
    (steps, eval_from): (u32, u32),
    desired: impl Fn(u32) -> f32,
    failing: impl Fn(u32) -> Option<(SensorId, SensorErrorKind)>,
    mut after_step: impl FnMut(u32, &Step, (u16, u16)),
) -> Result<(f32, f32), ConfigError> {
    let dt_s = ctl.config().dt_s;
    let bus = SimBus::new();
    let calibration = PressureCalibration::ADC12_0_1MPA;
    let valve = ValvePair::new(
        SimPwm::new(&bus.inlet_duty),
        SimPwm::new(&bus.exhaust_duty),
        ValvePairConfig::DEFAULT,
    )?;
    let mut io = Io {
        pressure: SimPressure {
            source: &bus,
            calibration,
        },
        contraction: SimContraction(&bus),
        load: SimLoad(&bus),
        valve,
    };
    let mut noise = Noise::new(0x5EED);
    let (mut sum_sq, mut max_error, mut evaluated) = (0.0f64, 0.0f32, 0u32);
    for k in 0..steps {
        let x_ref = desired(k);
        bus.publish(&plant, load_n, &calibration, &mut noise, NOISE);
        bus.failing.set(failing(k));
        let step = pam_control_step(ctl, &mut io, x_ref);
        after_step(k, &step, (bus.inlet_duty.get(), bus.exhaust_duty.get()));
        let (inlet, exhaust) = bus.duties();
        plant.step(inlet, exhaust, dt_s);
        if k >= eval_from {
            let e = (x_ref - plant.contraction()).abs();
            if e > max_error || e.is_nan() {
                max_error = if e.is_nan() { f32::INFINITY } else { e };
            }
            sum_sq += f64::from(e) * f64::from(e);
            evaluated += 1;
        }
    }
    let rms_error = if evaluated > 0 {
        libm_sqrt(sum_sq / f64::from(evaluated)) as f32
    } else {
        0.0
    };
    Ok((rms_error, max_error))
}

/// Square root by Newton's method (the library has no `std`, and this runs
/// once per scenario).
fn libm_sqrt(v: f64) -> f64 {
    if !(v > 0.0) {
        return 0.0;
    }
    let mut x = if v > 1.0 { v } else { 1.0 };
    for _ in 0..64 {
        x = 0.5 * (x + v / x);
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blob() -> [u8; pam_core::blob::BLOB_LEN] {
        pam_core::blob::encode(&Params::DEFAULT)
    }

    #[test]
    fn triangle_shape() {
        assert!((triangle(0.0) - LOW).abs() < 1e-6);
        assert!((triangle(PERIOD_S / 2.0) - HIGH).abs() < 1e-6);
        assert!((triangle(PERIOD_S / 4.0) - 0.5 * (LOW + HIGH)).abs() < 1e-6);
        assert!((triangle(PERIOD_S * 1.25) - 0.5 * (LOW + HIGH)).abs() < 1e-5);
    }

    #[test]
    fn sqrt_is_right() {
        for v in [0.0, 1e-10, 0.25, 2.0, 1e6] {
            assert!((libm_sqrt(v) - v.sqrt()).abs() <= 1e-12 * (1.0 + v.sqrt()));
        }
    }

    #[test]
    fn the_qemu_scenario_passes_on_the_host() {
        let mut events = 0;
        let r = run(&blob(), Feedforward::Hysteresis, |_, _| events += 1).unwrap();
        println!("{r:?}");
        assert!(r.passed(), "{r:?}");
        assert_eq!(events, 2, "one fault, one recovery");
        assert_eq!(
            r.recovery_steps,
            Some(u32::from(ControllerConfig::DEFAULT.safety.recovery_samples))
        );
    }

    #[test]
    fn hysteresis_feedforward_beats_the_alternatives() {
        let with = run(&blob(), Feedforward::Hysteresis, |_, _| {}).unwrap();
        let constraint = run(&blob(), Feedforward::Constraint, |_, _| {}).unwrap();
        let off = run(&blob(), Feedforward::Off, |_, _| {}).unwrap();
        println!("hysteresis {with:?}\nconstraint {constraint:?}\noff {off:?}");
        assert!(
            with.rms_error < constraint.rms_error,
            "{with:?} {constraint:?}"
        );
        assert!(with.rms_error < off.rms_error, "{with:?} {off:?}");
    }

    /// `track_on`, the closed loop a host tool runs on a model: the
    /// controller of the plant's own model tracks it without a fault, its
    /// RMS within the self-test's bound, and better than the controller of another
    /// model (the self-test's plant is the default model with a 25 % wider
    /// loop and a stiffer load dependence).
    #[test]
    fn a_models_own_controller_tracks_its_plant_best() {
        let own = pam_core::blob::encode(&plant_params());
        let other = blob();
        let track = |b: &[u8]| {
            let coeffs = Coeffs::new(plant_params()).unwrap();
            let plant = MusclePlant::with_effects(
                coeffs,
                pam_core::Effects::NONE,
                LOAD_N,
                PlantConfig::DEFAULT,
            )
            .unwrap();
            let steps = (CYCLES as f32 * PERIOD_S / ControllerConfig::DEFAULT.dt_s) as u32;
            track_on(b, plant, LOAD_N, triangle, steps, steps / CYCLES).unwrap()
        };
        let (own, other) = (track(&own), track(&other));
        println!("own {own:?}\nother {other:?}");
        assert_eq!((own.faults, own.first_fault), (0, None), "{own:?}");
        assert!(own.rms_error <= MAX_ERROR_BOUND, "{own:?}");
        assert!(own.rms_error < other.rms_error, "{own:?} vs {other:?}");
    }

    #[test]
    fn a_v2_blob_with_memory_runs_the_memory_feedforward_and_passes() {
        let effects = MEMORY_BLOB_EFFECTS;
        let b = pam_core::blob::encode_v2(&Params::DEFAULT, &effects);
        let (_, ff) = crate::boot::model_from_blob(&b, Feedforward::Hysteresis).unwrap();
        assert_eq!(ff, Feedforward::HysteresisMemory(effects.memory.unwrap()));
        let r = run(&b, Feedforward::Hysteresis, |_, _| {}).unwrap();
        let plain = run(&blob(), Feedforward::Hysteresis, |_, _| {}).unwrap();
        println!("memory {r:?}\nplain {plain:?}");
        assert!(r.passed(), "{r:?}");
        // On this plant (play-type friction that reaches the other branch
        // within a few hundredths of contraction) the short merge span
        // tracks at least as well as the paper's model.
        assert!(r.max_error <= plain.max_error, "{r:?} vs {plain:?}");
    }

    #[test]
    fn a_v2_blob_with_every_effect_runs_their_inverse_and_passes() {
        let effects = EFFECTS_BLOB_EFFECTS;
        let b = pam_core::blob::encode_v2(&Params::DEFAULT, &effects);
        let (_, ff) = crate::boot::model_from_blob(&b, Feedforward::Hysteresis).unwrap();
        assert_eq!(ff, Feedforward::HysteresisEffects(effects));
        let r = run(&b, Feedforward::Hysteresis, |_, _| {}).unwrap();
        let plain = run(&blob(), Feedforward::Hysteresis, |_, _| {}).unwrap();
        println!("effects {r:?}\nplain {plain:?}");
        assert!(r.passed(), "{r:?}");
    }

    /// One plant per effect (and all at once), each an effect a diagnosis
    /// would find: the feedforward that inverts the blob's model with it
    /// tracks that plant at least as well as the paper-only feedforward.
    #[test]
    fn each_effects_feedforward_tracks_its_plant_no_worse_than_the_paper_model() {
        use pam_core::effects::{
            ConstraintShape, Creep, LoadDependentWidth, NonLocalMemory, PressureLag, RateDependence,
        };
        use pam_core::Effects;
        let none = Effects::NONE;
        let cases = [
            (
                "memory",
                Effects {
                    memory: Some(NonLocalMemory::with_shape(1.0)),
                    ..none
                },
            ),
            (
                "rate",
                Effects {
                    rate: Some(RateDependence::linear(1.0, 2.0)),
                    ..none
                },
            ),
            (
                "creep",
                Effects {
                    creep: Some(Creep {
                        gain: 0.3,
                        time_constant_s: 1.0,
                    }),
                    ..none
                },
            ),
            (
                "width",
                Effects {
                    width: Some(LoadDependentWidth {
                        scale_at_min_load: 1.0,
                        scale_per_step: 0.5,
                    }),
                    ..none
                },
            ),
            (
                "shape",
                Effects {
                    shape: Some(ConstraintShape {
                        bulge: 0.3,
                        tilt: 0.1,
                        ..ConstraintShape::NEUTRAL
                    }),
                    ..none
                },
            ),
            (
                "pressure lag",
                Effects {
                    pressure_lag: Some(PressureLag {
                        time_constant_s: 0.02,
                    }),
                    ..none
                },
            ),
        ];
        let all = cases.iter().fold(none, |acc, (_, e)| Effects {
            memory: acc.memory.or(e.memory),
            rate: acc.rate.or(e.rate),
            creep: acc.creep.or(e.creep),
            width: acc.width.or(e.width),
            shape: acc.shape.or(e.shape),
            pressure_lag: acc.pressure_lag.or(e.pressure_lag),
            pressure_delay: acc.pressure_delay.or(e.pressure_delay),
        });
        let paper = blob();
        for (name, effects) in cases.iter().copied().chain([("all", all)]) {
            let (bytes, len) = pam_core::blob::encode_model(&Params::DEFAULT, &effects);
            let diagnosed = &bytes[..len];
            let with = run_with_plant_effects(diagnosed, Feedforward::Hysteresis, effects).unwrap();
            let without = run_with_plant_effects(&paper, Feedforward::Hysteresis, effects).unwrap();
            println!(
                "{name}: rms {:.5} max {:.5} (paper-only rms {:.5} max {:.5})",
                with.rms_error, with.max_error, without.rms_error, without.max_error
            );
            assert!(
                with.rms_error <= without.rms_error,
                "{name}: {with:?} vs paper-only {without:?}"
            );
            assert!(
                with.fault_caught && with.other_faults == 0,
                "{name}: {with:?}"
            );
        }
    }

    #[test]
    fn a_corrupt_blob_is_refused() {
        let mut b = blob();
        b[9] ^= 1;
        assert!(matches!(
            run(&b, Feedforward::Hysteresis, |_, _| {}),
            Err(ConfigError::Coefficients(pam_core::Error::Blob(_)))
        ));
    }
}

//! The Preisach model on the firmware (issue 30): identified on host-sim's
//! characterisation record as `pam-lab compare` identifies it, booted from
//! its `PAMP` blob, tracking the paper's scenarios with the safety
//! behaviour intact. Bounds from measured runs with margin (the measured
//! values are beside each; full-length numbers in host-sim/README.md).

use firmware::controller::{Fault, Feedforward, Sample, SensorId, ValveCommand};
use firmware::hal::SafeState;
use host_sim::bench::{run, run_booted, BenchConfig, Mode};
use host_sim::scenarios::Scenario;

fn blob() -> Vec<u8> {
    host_sim::preisach::identify_blob(&host_sim::characterisation_run(1)).expect("identified")
}

#[test]
fn the_preisach_blob_boots_and_tracks_the_scenarios_without_a_fault() {
    let blob = blob();
    assert_eq!(&blob[..4], b"PAMP");
    let cfg = BenchConfig::default_with_seed(11);
    // (scenario, RMS bound): measured 0.0035 / 0.0036 / 0.0039 at full
    // length (seed 1), PI alone 0.0055 / 0.0056 / 0.0067.
    for (sc, rms_bound) in [
        (Scenario::triangle(3, 4.0), 0.005),
        (Scenario::random_step_load(40.0, 4.0, 7), 0.0055),
        (Scenario::cyclic_load_change(5, 4.0), 0.0055),
    ] {
        let pre = run_booted(&sc, &blob, Mode::PreisachFeedforwardPi, &cfg).expect("boots");
        let pi = run(&sc, Mode::PiOnly, &cfg);
        let (r, p) = (pre.metrics.rms_error, pi.metrics.rms_error);
        eprintln!("{}: FF(Preisach)+PI rms {r:.4}, PI {p:.4}", sc.name);
        assert_eq!(pre.first_fault, None, "{}", sc.name);
        assert_eq!(pre.metrics.fault_samples, 0, "{}", sc.name);
        assert!(r < rms_bound, "{}: rms {r} (bound {rms_bound})", sc.name);
        // The feedforward earns its place: measured 59-64 % of PI's RMS.
        assert!(r < 0.8 * p, "{}: rms {r} against PI {p}", sc.name);
        // Every load step of the scenario followed by a completed switch.
        assert!(
            pre.metrics
                .load_steps
                .iter()
                .all(|l| l.detected_after_samples.is_some()),
            "{}",
            sc.name
        );
    }
}

#[test]
fn the_preisach_blob_runs_the_preisach_feedforward_and_its_faults_leave_the_valves_safe() {
    let blob = blob();
    // The model check from the first period (no pause at the start,
    // `implausible_start_s`): its trip is part of what is checked here.
    let mut config = firmware::ControllerConfig::DEFAULT;
    config.safety.implausible_start_s = 0.0;
    let booted = firmware::boot::boot(&blob, config, |l| {
        // The record's measured loads, 100-600 N with the load cell's noise.
        assert!((l.min_load_n - 100.0).abs() < 10.0 && (l.max_load_n - 600.0).abs() < 10.0);
        200.0
    })
    .expect("boots");
    assert_eq!(
        booted.controller.config().feedforward,
        Feedforward::Preisach
    );
    assert!(booted.controller.preisach().is_some() && booted.controller.coeffs().is_none());
    let mut ctl = booted.controller;
    let good = Sample {
        pressure_mpa: Ok(0.2),
        contraction: Ok(0.10),
        load_n: Ok(200.0),
    };
    let step = ctl.update(&good, 0.12);
    assert!(matches!(step.command, ValveCommand::Flow(_)), "{step:?}");
    assert!(step.feedforward_mpa > 0.0);
    // A bad reading of each kind: valves safe in the step that reads it.
    let safe = ValveCommand::Safe(SafeState::Exhaust);
    for (bad, fault) in [
        (
            Sample {
                contraction: Ok(f32::NAN),
                ..good
            },
            Fault::NonFinite(SensorId::Contraction),
        ),
        (
            Sample {
                load_n: Ok(700.0),
                ..good
            },
            Fault::OutOfRange(SensorId::Load),
        ),
        (
            Sample {
                pressure_mpa: Ok(0.58),
                ..good
            },
            Fault::OverPressure,
        ),
    ] {
        let step = ctl.update(&bad, 0.12);
        assert_eq!(step.fault, Some(fault));
        assert_eq!(step.command, safe);
        // Back to control after the recovery samples.
        for _ in 0..firmware::ControllerConfig::DEFAULT.safety.recovery_samples {
            ctl.update(&good, 0.12);
        }
        assert_eq!(ctl.fault(), None);
    }
    // The model check: a contraction sensor reading far from the model's
    // prediction at the measured pressure trips it, valves safe.
    let decoupled = Sample {
        contraction: Ok(0.35),
        ..good
    };
    let tripped = (0..200).find_map(|k| {
        let s = ctl.update(&decoupled, 0.12);
        (s.new_fault == Some(Fault::Implausible(firmware::controller::Check::Model)))
            .then_some((k, s.command))
    });
    let (k, command) = tripped.expect("the model check trips");
    assert_eq!(command, safe);
    assert!(k < 110, "tripped after {k} periods");
}

#[test]
fn a_corrupt_or_truncated_preisach_blob_is_refused_with_the_valves_safe() {
    let blob = blob();
    let good = host_sim::faults::boot(&blob);
    assert_eq!(good.result, Ok(()));
    let mut flipped = blob.clone();
    flipped[100] ^= 0x04;
    for bad in [&flipped[..], &blob[..blob.len() - 1], &blob[..8]] {
        let o = host_sim::faults::boot(bad);
        assert!(o.result.is_err(), "{o:?}");
        // Inlet closed, exhaust fully open: no step ran.
        assert_eq!(o.duties, (0, firmware::sim_io::PWM_MAX_DUTY), "{o:?}");
    }
    assert_eq!(
        host_sim::faults::boot(&flipped).result,
        Err(firmware::controller::ConfigError::Coefficients(
            pam_core::Error::Blob("CRC mismatch")
        ))
    );
    // The constraint model's comparison mode has no Preisach counterpart.
    let cfg = firmware::ControllerConfig {
        feedforward: Feedforward::Constraint,
        ..firmware::ControllerConfig::DEFAULT
    };
    assert!(firmware::boot::boot(&blob, cfg, |_| 200.0).is_err());
}

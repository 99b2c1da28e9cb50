//! The firmware's online adaptation (`firmware::controller::adapt`) in the
//! closed loop: every fault of the suite caught as without it, a slow
//! sensor drift and a muscle worn past the bound reported, not adapted
//! away, and on the worn muscle tracking within 1.2× of a model freshly
//! identified on it.

use firmware::controller::{AdaptationConfig, Check, Fault};
use firmware::ControllerConfig;
use host_sim::bench::BenchConfig;
use host_sim::faults::{run_case, run_case_with, CASES};
use host_sim::harness::Harness;
use host_sim::plant::MuscleParams;
use host_sim::scenarios::Scenario;
use host_sim::wear::{compare, Wear};

const SEED: u64 = 1;

fn adapted() -> ControllerConfig {
    ControllerConfig {
        adaptation: Some(AdaptationConfig::DEFAULT),
        ..ControllerConfig::DEFAULT
    }
}

#[test]
fn every_fault_is_reported_as_without_adaptation_and_as_fast() {
    for case in CASES {
        let plain = run_case(case, SEED);
        let with = run_case_with(case, SEED, adapted());
        assert_eq!(
            with.faults_before, 0,
            "{case:?}: faults before the injection"
        );
        let (at, fault) = with
            .reported
            .unwrap_or_else(|| panic!("{case:?}: not reported"));
        let (plain_at, plain_fault) = plain.reported.expect("reported without adaptation");
        assert_eq!(fault, plain_fault, "{case:?}");
        assert!(
            at <= plain_at + 5,
            "{case:?}: reported at {at}, without adaptation at {plain_at}"
        );
        assert_eq!(with.latched_at_end, plain.latched_at_end, "{case:?}");
        assert!(with.safe_at.is_some(), "{case:?}: valves never safe");
    }
}

/// The triangle at 200 N with `cfg`, `disturb` applied to the harness
/// before each period; the first fault and its time, and the adapted
/// scale when it was reported.
fn first_fault(
    cfg: ControllerConfig,
    duration_s: f64,
    mut disturb: impl FnMut(&mut Harness, f64),
) -> Option<(f64, Fault, f32, bool)> {
    let sc = Scenario::triangle((duration_s / 4.0) as usize, 4.0);
    let mut h = Harness::new(cfg, 200.0, SEED);
    let dt = f64::from(cfg.dt_s);
    let n = (sc.duration_s / dt) as usize;
    for k in 0..n {
        let t = k as f64 * dt;
        disturb(&mut h, t);
        let step = h.period(sc.reference_at(t) as f32)?;
        if let Some(f) = step.new_fault {
            let scale = h.ctl.adaptation().map_or(1.0, |a| a.scale());
            return Some((t, f, scale, h.valves_commanded_safe()));
        }
    }
    None
}

#[test]
fn a_slow_contraction_sensor_drift_is_reported_not_adapted_away() {
    // 0.5 mm per 300 mm each second from 5 s on: 0.035 (the band) after
    // 21 s, 0.08 after 53 s.
    let drift = |h: &mut Harness, t: f64| {
        h.rig.borrow_mut().contraction_sensor.offset = 0.0015 * (t - 5.0).max(0.0);
    };
    let (t, fault, scale, safe) =
        first_fault(adapted(), 120.0, drift).expect("the drift was never reported");
    eprintln!("reported at {t:.1} s: {fault:?}, scale {scale}");
    assert!(safe, "valves safe in the step that reported it");
    assert!(
        matches!(fault, Fault::Implausible(Check::Model) | Fault::Drifted),
        "{fault:?}"
    );
    // Reported before the offset is twice the model check's band.
    assert!(0.0015 * (t - 5.0) < 0.07, "reported at {t} s");
}

#[test]
fn a_muscle_worn_past_the_bound_is_the_drift_fault_latched() {
    // Stroke −40 % over five minutes: beyond the ±20 % the adaptation may
    // take.
    let wear = Wear {
        stroke: -0.40,
        friction: 0.0,
        stiffness: 0.0,
        duration_s: 300.0,
    };
    let mut h_latched = false;
    let mut reported = None;
    let cfg = adapted();
    let sc = Scenario::triangle(75, 4.0);
    let mut h = Harness::new(cfg, 200.0, SEED);
    let dt = f64::from(cfg.dt_s);
    for k in 0..(sc.duration_s / dt) as usize {
        let t = k as f64 * dt;
        if k % 100 == 0 {
            let m = wear.muscle(&MuscleParams::DEFAULT, wear.fraction_at(t));
            h.rig.borrow_mut().muscle.set_params(m);
        }
        let Some(step) = h.period(sc.reference_at(t) as f32) else {
            continue;
        };
        if reported.is_none() {
            if let Some(f) = step.new_fault {
                reported = Some((t, f, h.valves_commanded_safe()));
            }
        }
        h_latched = step.latched;
    }
    let (t, fault, safe) = reported.expect("the worn muscle was never reported");
    eprintln!("reported at {t:.1} s: {fault:?}");
    assert_eq!(fault, Fault::Drifted);
    assert!(safe, "valves safe in the step that reported it");
    assert!(h_latched, "latched until the operator's reset");
}

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "release only (a quarter of an hour of simulated muscle and a fit): .ci/run runs it with --release"
)]
fn on_the_worn_muscle_adaptation_tracks_as_a_fresh_identification() {
    let cfg = BenchConfig::default_with_seed(SEED);
    let scenarios = [
        Scenario::triangle(8, 4.0),
        Scenario::cyclic_load_change(12, 4.0),
    ];
    let wear = Wear {
        duration_s: 900.0,
        ..Wear::HOUR
    };
    let c = compare(&cfg, &wear, &scenarios, AdaptationConfig::DEFAULT).expect("comparison");
    let adapted = c.adapted.final_rms();
    eprintln!(
        "flashed {:.4} ({:?}), adapted {adapted:.4} ({:?}, scale {:?}), fresh {:.4}",
        c.flashed.final_rms(),
        c.flashed.first_fault,
        c.adapted.first_fault,
        c.adapted.repetitions.last().map(|r| r.stroke_scale),
        c.fresh_rms
    );
    assert_eq!(c.adapted.first_fault, None);
    assert_eq!(c.fresh_fault, None);
    assert!(
        adapted <= 1.2 * c.fresh_rms,
        "{adapted} > 1.2 × {}",
        c.fresh_rms
    );
    // Without adaptation the flashed model's check trips on the worn muscle.
    assert!(c.flashed.first_fault.is_some());
}

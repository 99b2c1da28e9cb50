//! The paper's scenarios (Figs. 6–8), shortened, with the firmware's
//! controller on the simulated rig. Bounds are set from measured runs with
//! margin (see host-sim/README.md for the full-length numbers).

use host_sim::bench::{run, BenchConfig, Mode, Run};
use host_sim::scenarios::Scenario;

/// The tracker's debounce: a load step cannot be detected in fewer samples.
const DEBOUNCE: usize = firmware::ControllerConfig::DEFAULT
    .tracker
    .load_debounce_samples as usize;

/// Stated bound on the feedforward's change across a branch switch with the
/// firmware's non-local memory (`Feedforward::HysteresisMemory`), MPa: 5 %
/// of the plain model's `2·be` = 0.060 MPa. Measured ≤ 0.0003 (README).
const MITIGATED_JUMP_BOUND_MPA: f64 = 0.002;

fn both(sc: &Scenario) -> (Run, Run) {
    let cfg = BenchConfig::default_with_seed(11);
    let (pi, ff) = (
        run(sc, Mode::PiOnly, &cfg),
        run(sc, Mode::FeedforwardPi, &cfg),
    );
    // The same scenario with the minor-loop feedforward: the 2·be jump of
    // the plain model at each switch is gone.
    let mem = run(sc, Mode::FeedforwardMemoryPi, &cfg);
    eprintln!(
        "{}: FF jump at switch plain {:.4} mitigated {:.4} MPa; FF(mem)+PI rms {:.4}",
        sc.name,
        ff.metrics.max_feedforward_jump_mpa(),
        mem.metrics.max_feedforward_jump_mpa(),
        mem.metrics.rms_error
    );
    assert_eq!(mem.metrics.fault_samples, 0);
    assert_eq!(mem.metrics.switches.len(), ff.metrics.switches.len());
    assert!(mem.metrics.switches.len() >= 5);
    assert!(ff.metrics.max_feedforward_jump_mpa() > 0.03);
    assert!(
        mem.metrics.max_feedforward_jump_mpa() <= MITIGATED_JUMP_BOUND_MPA,
        "{:?}",
        mem.metrics.switches
    );
    // It still tracks (measured 0.0027-0.0037 RMS at full length: worse than
    // the plain model's 0.0022-0.0028 on this rig, see README).
    assert!(mem.metrics.rms_error < 0.0065, "{}", mem.metrics.rms_error);
    (pi, ff)
}

fn report(name: &str, pi: &Run, ff: &Run) {
    eprintln!(
        "{name}: PI rms {:.4} max {:.4} | FF+PI rms {:.4} max {:.4} | ratio {:.2}",
        pi.metrics.rms_error,
        pi.metrics.max_error,
        ff.metrics.rms_error,
        ff.metrics.max_error,
        ff.metrics.rms_error / pi.metrics.rms_error
    );
}

#[test]
fn triangle_fig6_tracks_and_feedforward_helps() {
    let sc = Scenario::triangle(3, 4.0);
    let (pi, ff) = both(&sc);
    report("triangle", &pi, &ff);
    for r in [&pi, &ff] {
        assert_eq!(r.metrics.fault_samples, 0, "{:?}", r.mode);
    }
    // Closed-loop tracking bounds (contraction, fraction of rest length).
    assert!(ff.metrics.rms_error < 0.005, "{}", ff.metrics.rms_error);
    assert!(ff.metrics.max_error < 0.02, "{}", ff.metrics.max_error);
    // PI alone is the same controller with `Feedforward::Off`. Measured
    // 0.49 here (0.46 full length) with the default gains and pam-core's
    // default model fitted to this rig: the goal of 0.5 is met.
    assert!(
        ff.metrics.rms_error <= 0.5 * pi.metrics.rms_error,
        "FF+PI {} vs PI {}",
        ff.metrics.rms_error,
        pi.metrics.rms_error
    );
    // Branch switches at each reversal; the paper model's feedforward jumps
    // by up to 2·be there (0.060 MPa with the fitted default), the chamber
    // (valve-flow limited) changes by less within 10 ms.
    let two_be = 2.0 * f64::from(pam_core::Params::DEFAULT.ellipse_height_mpa);
    assert!(
        ff.metrics.switches.len() >= 5,
        "{}",
        ff.metrics.switches.len()
    );
    for s in &ff.metrics.switches {
        assert!(s.feedforward_jump_mpa.abs() <= two_be + 0.001, "{s:?}");
        assert!(s.chamber_jump_mpa <= 0.035, "{s:?}");
    }
}

#[test]
fn random_step_load_fig7_is_detected_and_followed() {
    let sc = Scenario::random_step_load(40.0, 4.0, 7);
    let (pi, ff) = both(&sc);
    report("random_step_load", &pi, &ff);
    assert!(ff.metrics.load_steps.len() >= 6);
    for r in [&pi, &ff] {
        assert_eq!(r.metrics.fault_samples, 0, "{:?}", r.mode);
        for step in &r.metrics.load_steps {
            // Detected within the debounce count of the step.
            let k = step.detected_after_samples.expect("load step not detected");
            assert!(k <= DEBOUNCE, "{step:?}");
        }
    }
    // The active model follows the load (to the load cell's noise).
    assert!(ff.metrics.worst_model_load_error_n < 10.0);
    // The feedforward at least halves the RMS tracking error here (measured 0.38).
    assert!(
        ff.metrics.rms_error <= 0.5 * pi.metrics.rms_error,
        "FF+PI {} vs PI {}",
        ff.metrics.rms_error,
        pi.metrics.rms_error
    );
    assert!(ff.metrics.max_error < 0.035, "{}", ff.metrics.max_error);
}

#[test]
fn cyclic_load_change_fig8_adapts() {
    let sc = Scenario::cyclic_load_change(5, 4.0);
    let (pi, ff) = both(&sc);
    report("cyclic_load_change", &pi, &ff);
    assert_eq!(ff.metrics.fault_samples, 0);
    assert_eq!(ff.metrics.load_steps.len(), 4);
    for step in &ff.metrics.load_steps {
        assert!(step.detected_after_samples.expect("detected") <= DEBOUNCE);
    }
    assert!(ff.metrics.worst_model_load_error_n < 10.0);
    assert!(ff.metrics.rms_error < 0.006, "{}", ff.metrics.rms_error);
    assert!(ff.metrics.max_error < 0.03, "{}", ff.metrics.max_error);
    // Measured 0.43 (0.41 full length): the goal of 0.5 is met.
    assert!(
        ff.metrics.rms_error <= 0.5 * pi.metrics.rms_error,
        "FF+PI {} vs PI {}",
        ff.metrics.rms_error,
        pi.metrics.rms_error
    );
}

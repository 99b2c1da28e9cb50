//! The end-to-end path a user takes, on the rig closest to the paper's model:
//! characterise → `pam-lab fit` and `diagnose` → the blobs they write →
//! the firmware's boot path → tracking on the same rig. The main job runs
//! every effect rig and prints the table (host-sim/README.md).

use host_sim::bench::BenchConfig;
use host_sim::characterisation::IsotonicProtocol;
use host_sim::effect_rigs::effect_rigs;
use host_sim::end_to_end::{boot, characterise, characterise_with, identify, run_rig};
use host_sim::scenarios::Scenario;

/// host-sim's effect rig of that name.
fn rig_named(name: &str) -> host_sim::effect_rigs::EffectRig {
    effect_rigs()
        .into_iter()
        .find(|r| r.name == name)
        .expect("a rig of that name")
}

/// The coulomb rig through fit and diagnose, tracked with each tool's blob.
fn coulomb_run() -> host_sim::end_to_end::RigOutcome {
    let rig = rig_named("coulomb");
    let cfg = BenchConfig::default_with_seed(3);
    run_rig(&rig, &[Scenario::triangle(4, 4.0)], &cfg)
}

#[test]
fn coulomb_rig_end_to_end_names_no_dynamic_effect_and_both_blobs_track() {
    let outcome = coulomb_run();
    let id = outcome
        .identified
        .as_ref()
        .expect("fit and diagnose accept the record");
    // The rig's static curve is outside the cubic family and its friction
    // leaves small minor loops (constraint_shape and non_local_memory are
    // fair names); it has no rate, creep or load-dependent width beyond
    // the reference muscle's.
    for wrong in ["rate_dependence", "creep", "load_dependent_width"] {
        assert!(
            !id.effects_added.contains(&wrong),
            "diagnose added {:?}",
            id.effects_added
        );
    }
    let r = &outcome.runs[0];
    let diagnosed = r
        .diagnosed
        .as_ref()
        .expect("the firmware boots diagnose's blob");
    for run in [&r.pi, &r.paper, diagnosed] {
        assert!(
            run.first_fault.is_none(),
            "{:?}: {:?}",
            run.mode,
            run.first_fault
        );
    }
    let (pi, paper, diag) = (
        r.pi.metrics.rms_error,
        r.paper.metrics.rms_error,
        diagnosed.metrics.rms_error,
    );
    eprintln!(
        "coulomb rig, triangle: PI {pi:.4}, paper FF+PI {paper:.4}, diagnosed FF+PI {diag:.4}"
    );
    assert!(
        paper < 0.6 * pi,
        "the fitted model's feedforward helps: {paper} vs PI {pi}"
    );
    assert!(
        diag < 0.6 * pi,
        "the diagnosed model's feedforward helps: {diag} vs PI {pi}"
    );
    // The rig's static curve is outside the cubic family: fit's blob
    // carries the static shape's stroke table (blob version 3).
    assert_eq!(
        u16::from_le_bytes([id.paper_blob[4], id.paper_blob[5]]),
        pam_core::blob::BLOB_VERSION_V3
    );
}

/// On the coulomb rig the polynomial correction alone earns the static
/// shape's place and fit's static model does not (its regime's cut), a
/// few per cent apart on diagnose's held-out samples: a tie, so diagnose
/// writes fit's static model, with the memory its reversals earn, and its
/// blob tracks no worse than fit's. The correction written instead
/// tracked this triangle at 128 % of fit's (seed 3), and the main job's
/// at 130 % (seed 1). Release only (about ten seconds).
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn where_the_static_shapes_tie_the_diagnosed_blob_tracks_no_worse_than_fits() {
    let outcome = coulomb_run();
    let r = &outcome.runs[0];
    let diag = r.diagnosed.as_ref().expect("boots").metrics.rms_error;
    let paper = r.paper.metrics.rms_error;
    eprintln!("coulomb rig, triangle: fit {paper:.5}, diagnosed {diag:.5}");
    assert!(diag <= paper, "{diag} vs {paper}");
}

/// The rate rig (five times the reference's damping): its record has no
/// hold after a step, so diagnose fits the linear rate law, whose loop at
/// rest is what the slowest ramps show (a sub-linear law fitted there put
/// the factor at rest at 0.00 and tripped at 9.8 s, seed 1, the main
/// job's triangle). diagnose's closed-loop check accepts that model: on a
/// muscle that is that model its own controller never goes to its safe
/// state. (It did, `Implausible(Model)` on steps held, while the
/// firmware's model check judged a rate-law muscle by the loop of the
/// feedforward's rate alone, not of the pressure the muscle sees; the
/// check then refused the model and fit's was written.) The firmware
/// boots diagnose's blob and tracks the rig's triangle without a trip, at
/// 134 % of fit's error on the main job's (the rig's loop at rest is its
/// friction's, not the law's: issue 32). Release only (about half a
/// minute).
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn rate_rig_is_named_rate_and_its_rate_law_runs_without_a_trip() {
    let rig = rig_named("rate");
    let cfg = BenchConfig::default_with_seed(1);
    let outcome = run_rig(&rig, &[Scenario::triangle(8, 4.0)], &cfg);
    let id = outcome
        .identified
        .as_ref()
        .expect("fit and diagnose accept the record");
    assert!(
        id.effects_added.contains(&"rate_dependence"),
        "{:?}",
        id.effects_added
    );
    let check = id.closed_loop.as_ref().expect("diagnose checks its model");
    let rate = check
        .effects
        .rate
        .expect("the model checked has the rate law");
    assert_eq!(rate.exponent, 1.0, "{rate:?}");
    assert!(rate.scale_at_rest > 0.1, "{rate:?}");
    for r in &check.runs {
        assert_eq!(r.diagnosed.faults, 0, "{r:?}");
    }
    assert!(check.accepted, "{check:#?}");
    assert!(!id.refused());
    assert_ne!(id.diagnosed_blob, id.paper_blob, "the rate law is written");
    let diagnosed = outcome.runs[0]
        .diagnosed
        .as_ref()
        .expect("the firmware boots diagnose's blob");
    eprintln!(
        "rate rig, triangle: fit FF+PI {:.4}, diagnosed FF+PI {:.4}; {}",
        outcome.runs[0].paper.metrics.rms_error, diagnosed.metrics.rms_error, check.verdict
    );
    assert!(
        diagnosed.first_fault.is_none(),
        "{:?}",
        diagnosed.first_fault
    );
}

#[test]
fn a_corrupt_blob_from_the_pipeline_is_refused_at_boot_with_its_reason() {
    let rig = effect_rigs()[0];
    let record = characterise(&rig, 1);
    assert_eq!(record.len(), 10_356);
    let cfg = BenchConfig::default_with_seed(1);
    let mut blob = identify(&record).expect("identified").diagnosed_blob;
    let last = blob.len() - 1;
    blob[last] ^= 1;
    let err = boot(&blob, &cfg, 200.0).expect_err("a corrupt blob is refused");
    assert!(err.contains("CRC"), "{err}");
}

/// The creep rig characterised with two steps held 5 s at every load
/// ([`IsotonicProtocol::WITH_STEPS`]): its creep shows after the steps, its
/// friction's minor loops at the inner reversals, and diagnose names both.
/// Fitted creep first, the pair beats the memory alone by the evidence
/// rule; creep fitted on the memory held as fitted alone does not (the
/// memory took up part of the creep): diagnose's pair rule takes the
/// first.
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn creep_rig_with_held_steps_is_named_creep_and_memory() {
    assert_named(
        "creep",
        &IsotonicProtocol::WITH_STEPS,
        12_156,
        &["creep", "non_local_memory"],
    );
}

/// The memory rig (the reference muscle: slip elements breaking away at
/// 0.15–2.5 % of contraction, so a reversal inside the loop draws a minor
/// loop) is named with its memory beside the static shape. Judged on fit's
/// static model as fitted before it, the memory cut 13.9 % of the held-out
/// error at seed 1, under the evidence rule's 15 %: fit's stroke table had
/// taken up the minor loops' mean, and the rig was named
/// `constraint_shape` alone. With the static model refitted under the
/// memory (pam-lab's `diagnose/backfit.rs`) it cuts 26 %. Release only
/// (about ten seconds).
#[test]
#[cfg_attr(debug_assertions, ignore)]
fn memory_rig_is_named_memory_with_the_static_model_refitted_under_it() {
    assert_named(
        "memory",
        &IsotonicProtocol::WITH_FAST_CYCLE,
        10_356,
        &["constraint_shape", "non_local_memory"],
    );
}

/// The rig `rig`, characterised with `protocol` (`samples` long) at seeds
/// 1 and 2, is named with each of `effects` by diagnose.
fn assert_named(rig: &str, protocol: &IsotonicProtocol, samples: usize, effects: &[&str]) {
    let rig = rig_named(rig);
    for seed in [1, 2] {
        let record = characterise_with(&rig, seed, protocol);
        assert_eq!(record.len(), samples);
        let id = identify(&record).expect("fit and diagnose accept the record");
        for effect in effects {
            assert!(
                id.effects_added.contains(effect),
                "seed {seed}: diagnose added {:?}",
                id.effects_added
            );
        }
    }
}

//! `pam-lab diagnose` on rigs with one hidden effect each (see
//! `support/hidden_plants.rs`): the workflow sees only the CSV and must name
//! the rig's effect (or `none`), and should at least halve the held-out RMS
//! where an effect is present.
//!
//! Measured figures (every plant, both protocols, several seeds) are in
//! pam-lab/DIAGNOSE.md; this file checks seed 7 of the examples' protocol.
//!
//! Each plant is diagnosed once (a per-plant `OnceLock`), shared by its
//! naming and halving tests, to keep the suite's debug run short.

mod support;

use pam_lab::identify::diagnose::{diagnose, DiagnoseConfig, DiagnoseReport};
use std::sync::OnceLock;

use support::hidden_plants::{csv, csv_b, csv_below_pmax, Plant};

/// `Pmax` of the rigs run below it ([`csv_below_pmax`]; the protocol's top
/// is 0.5 MPa).
const BELOW_PMAX_MPA: f64 = 0.56;

fn run(plant: Plant, seed: u64) -> DiagnoseReport {
    run_csv(plant, &csv(plant, seed, true))
}

fn run_csv(plant: Plant, text: &str) -> DiagnoseReport {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("{plant:?}.csv"));
    std::fs::write(&path, text).unwrap();
    let record = pam_lab::record::read_csv(&path).unwrap();
    let report = diagnose(&record, &DiagnoseConfig::default()).unwrap();
    eprintln!("{}", pam_lab::identify::diagnose::summary(&report));
    report
}

/// The diagnosis of `plant` (seed 7), computed once per test binary.
fn report(plant: Plant) -> &'static DiagnoseReport {
    static CACHE: [OnceLock<DiagnoseReport>; Plant::ALL.len()] =
        [const { OnceLock::new() }; Plant::ALL.len()];
    let slot = Plant::ALL.iter().position(|p| *p == plant).unwrap_or(0);
    CACHE[slot].get_or_init(|| run(plant, 7))
}

fn names(plant: Plant) -> &'static DiagnoseReport {
    let r = report(plant);
    assert_eq!(r.named, plant.expected_name(), "{plant:?}");
    // Nothing beyond the plant's own effects (the creep plant used to get
    // a false second one: a rescaled ellipse that was the base refit's
    // gain, not the effect's).
    assert_eq!(
        r.effects_added.len(),
        plant.expected_effects().len(),
        "{plant:?}: {:?}",
        r.effects_added
    );
    if plant == Plant::None {
        assert!(r.effects_added.is_empty(), "{:?}", r.effects_added);
        assert_eq!(r.rms_after, r.rms_before);
    } else {
        assert!(r.rms_after < r.rms_before);
    }
    r
}

/// The model error above the noise floor is cut by at least `share`
/// (the held-out RMS itself cannot fall below the noise).
fn cuts_above_noise(plant: Plant, share: f64) {
    let r = names(plant);
    assert!(
        r.share_removed() >= share,
        "{plant:?}: above the noise {} -> {} ({:.0} %)",
        r.above_noise_before,
        r.above_noise_after,
        100.0 * r.share_removed()
    );
}

fn halves(plant: Plant) {
    let r = names(plant);
    assert!(
        r.rms_after <= 0.5 * r.rms_before,
        "{plant:?}: {} -> {}",
        r.rms_before,
        r.rms_after
    );
    cuts_above_noise(plant, 0.5);
}

#[test]
fn no_effect_is_within_one_and_a_half_noise_floors() {
    let r = names(Plant::None);
    assert!(
        r.rms_before <= 1.5 * r.noise.contraction,
        "{} against a noise of {}",
        r.rms_before,
        r.noise.contraction
    );
}

#[test]
fn no_effect_is_named_none() {
    names(Plant::None);
}

#[test]
fn non_local_memory_is_named() {
    names(Plant::NonLocalMemory);
}

#[test]
fn rate_dependence_is_named() {
    names(Plant::Rate);
}

#[test]
fn load_dependent_width_is_named() {
    names(Plant::Width);
}

#[test]
fn creep_is_named() {
    names(Plant::Creep);
}

#[test]
fn creep_halves_the_error() {
    halves(Plant::Creep);
}

#[test]
fn non_local_memory_halves_the_error() {
    halves(Plant::NonLocalMemory);
}

#[test]
fn rate_dependence_halves_the_error() {
    halves(Plant::Rate);
}

#[test]
fn load_dependent_width_halves_the_error() {
    halves(Plant::Width);
}

#[test]
fn a_rig_run_below_its_pmax_has_its_pmax_identified() {
    // The record tops at 0.5 MPa, where this muscle's loop is still open:
    // its top reversal jumps to the other branch (the paper's model, no
    // effect). A Pmax held at the record's top bends the whole curve to
    // close the loop there (measured: 1.42x the noise on seed 1, 0.00079
    // above it); refitted, Pmax lands near the muscle's.
    let r = run_csv(Plant::None, &csv_below_pmax(Plant::None, 7, BELOW_PMAX_MPA));
    assert_eq!(r.named, "none", "{:?}", r.effects_added);
    assert!(!r.pmax_at_ceiling);
    let pmax = f64::from(r.final_params.points.max_pressure_mpa);
    assert!(
        (pmax - BELOW_PMAX_MPA).abs() <= 0.02,
        "Pmax {pmax} MPa, the muscle's {BELOW_PMAX_MPA}"
    );
    assert!(
        r.rms_before <= 1.5 * r.noise.contraction,
        "{} against a noise of {}",
        r.rms_before,
        r.noise.contraction
    );
}

/// Not a check: writes every plant's record under both protocols, for
/// seeds 1–`PAM_HIDDEN_SEEDS` (default 3), into `PAM_HIDDEN_OUT` (default
/// `target/hidden-plants`), named `PROTOCOL_PLANT_SEED.csv`, so that the
/// CLI can be run on them (DIAGNOSE.md gives the command).
#[test]
#[ignore]
fn write_hidden_plant_records() {
    let out = std::env::var("PAM_HIDDEN_OUT").unwrap_or_else(|_| "target/hidden-plants".into());
    let seeds: u64 = std::env::var("PAM_HIDDEN_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    std::fs::create_dir_all(&out).unwrap();
    for seed in 1..=seeds {
        for plant in Plant::ALL {
            let name = plant.expected_name();
            std::fs::write(format!("{out}/a_{name}_{seed}.csv"), csv(plant, seed, true)).unwrap();
            std::fs::write(format!("{out}/b_{name}_{seed}.csv"), csv_b(plant, seed)).unwrap();
        }
        for plant in [Plant::None, Plant::NonLocalMemory] {
            let name = plant.expected_name();
            std::fs::write(
                format!("{out}/top_{name}_{seed}.csv"),
                csv_below_pmax(plant, seed, BELOW_PMAX_MPA),
            )
            .unwrap();
        }
    }
}

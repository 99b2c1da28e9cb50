//! `pam-lab diagnose` on rigs with one hidden effect each (see
//! `support/hidden_plants.rs`): the workflow sees only the CSV, must name the
//! rig's effect (or `none`), and must at least halve the held-out RMS where an
//! effect is present.

mod support;

use pam_lab::diagnose::{diagnose, DiagnoseConfig, DiagnoseReport};
use support::hidden_plants::{csv, Plant};

fn run(plant: Plant, seed: u64) -> DiagnoseReport {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("{plant:?}.csv"));
    std::fs::write(&path, csv(plant, seed, true)).unwrap();
    let record = pam_lab::data::read_csv(&path).unwrap();
    let report = diagnose(&record, &DiagnoseConfig::default()).unwrap();
    eprintln!("{}", pam_lab::diagnose::summary(&report));
    report
}

fn check(plant: Plant) {
    let r = run(plant, 7);
    assert_eq!(r.named, plant.expected_name(), "{plant:?}");
    if plant == Plant::None {
        assert!(r.effects_added.is_empty(), "{:?}", r.effects_added);
    } else {
        assert!(
            r.rms_after <= 0.5 * r.rms_before,
            "{plant:?}: {} -> {}",
            r.rms_before,
            r.rms_after
        );
    }
}

#[test]
fn no_effect_is_named_none() {
    check(Plant::None);
}

#[test]
fn non_local_memory_is_named() {
    check(Plant::NonLocalMemory);
}

#[test]
fn rate_dependence_is_named() {
    check(Plant::Rate);
}

#[test]
fn creep_is_named() {
    check(Plant::Creep);
}

#[test]
fn load_dependent_width_is_named() {
    check(Plant::Width);
}

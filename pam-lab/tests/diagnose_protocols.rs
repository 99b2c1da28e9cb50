//! `pam-lab diagnose` beyond the examples' protocol and beyond one effect
//! at a time (plants in `support/hidden_plants.rs`, seed 1):
//!
//! * the second rig protocol ([`hidden_plants::protocol_b`]: 100 Hz,
//!   sinusoidal cycles, decaying oscillations with nested minor loops,
//!   random reversals, steps, loads 80–480 N) for every single-effect plant;
//! * two effects at once (load-dependent width with creep, memory with
//!   rate dependence), under both protocols;
//! * the Tondu–Lopez muscle (static shape and memory) under both.
//!
//! Each diagnosis takes about 10 s in a release build and over a minute in
//! a debug one, so these run in release builds only
//! (`cargo test --release -p pam-lab --test diagnose_protocols`); the
//! measured figures over several seeds are in pam-lab/DIAGNOSE.md.

mod support;

use std::sync::OnceLock;

use pam_lab::identify::diagnose::{diagnose, DiagnoseConfig, DiagnoseReport};
use support::hidden_plants::{self, Plant};

fn run(name: &str, csv: String) -> DiagnoseReport {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("{name}.csv"));
    std::fs::write(&path, csv).unwrap();
    let record = pam_lab::record::read_csv(&path).unwrap();
    let report = diagnose(&record, &DiagnoseConfig::default()).unwrap();
    eprintln!("{}", pam_lab::identify::diagnose::summary(&report));
    report
}

/// The diagnosis of `plant` under the second protocol, once per binary.
fn protocol_b(plant: Plant) -> &'static DiagnoseReport {
    static CACHE: [OnceLock<DiagnoseReport>; Plant::ALL.len()] =
        [const { OnceLock::new() }; Plant::ALL.len()];
    let slot = Plant::ALL.iter().position(|p| *p == plant).unwrap_or(0);
    CACHE[slot].get_or_init(|| run(&format!("b_{plant:?}"), hidden_plants::csv_b(plant, 1)))
}

fn named_first_under_protocol_b(plant: Plant) -> &'static DiagnoseReport {
    let r = protocol_b(plant);
    assert_eq!(
        r.named,
        plant.expected_name(),
        "{plant:?}: {:?}",
        r.effects_added
    );
    assert_eq!(
        r.effects_added.len(),
        plant.expected_effects().len(),
        "{plant:?}: {:?}",
        r.effects_added
    );
    r
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn second_protocol_no_effect_is_none_within_one_and_a_half_noise_floors() {
    let r = named_first_under_protocol_b(Plant::None);
    assert!(r.effects_added.is_empty(), "{:?}", r.effects_added);
    assert!(
        r.rms_before <= 1.5 * r.noise.contraction,
        "{} against a noise of {}",
        r.rms_before,
        r.noise.contraction
    );
    assert_eq!(r.extrapolated_samples, 0);
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn second_protocol_memory_is_named_and_halves_the_error_above_the_noise() {
    // 26 % while the base refit could not leave the edge of the valid
    // parameters the fit ended on (DIAGNOSE.md).
    let r = named_first_under_protocol_b(Plant::NonLocalMemory);
    assert!(r.share_removed() >= 0.5, "{}", r.share_removed());
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn second_protocol_rate_is_named_and_halves_the_error_above_the_noise() {
    let r = named_first_under_protocol_b(Plant::Rate);
    assert!(r.share_removed() >= 0.5, "{}", r.share_removed());
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn second_protocol_width_is_named_and_halves_the_error_above_the_noise() {
    let r = named_first_under_protocol_b(Plant::Width);
    assert!(r.share_removed() >= 0.5, "{}", r.share_removed());
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn second_protocol_creep_is_named_first_and_cuts_a_fifth_above_the_noise() {
    let r = named_first_under_protocol_b(Plant::Creep);
    assert!(r.share_removed() >= 0.2, "{}", r.share_removed());
}

fn both_named(plant: Plant) {
    both_named_in(
        &run(&format!("a_{plant:?}"), hidden_plants::csv(plant, 1, true)),
        plant,
    );
}

/// Both effects of a compound `plant` named (in either order), nothing
/// else, and the error above the noise at least halved.
fn both_named_in(r: &DiagnoseReport, plant: Plant) {
    let mut got = r.effects_added.clone();
    let mut want = plant.expected_effects().to_vec();
    got.sort_unstable();
    want.sort_unstable();
    assert_eq!(got, want, "{plant:?}");
    assert!(r.share_removed() >= 0.5, "{plant:?}: {}", r.share_removed());
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn width_and_creep_at_once_are_both_named() {
    both_named(Plant::WidthAndCreep);
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn memory_and_rate_at_once_are_both_named() {
    both_named(Plant::MemoryAndRate);
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn memory_and_rate_at_once_are_both_named_under_the_second_protocol() {
    // Greedy, creep (which stands in for part of the rate law's loops) or
    // the rate law came first here, and the memory on top of it did not
    // earn its place or left most of the error; the search over paths
    // (pam-lab/src/identify/diagnose/paths.rs) finds the memory first.
    let r = protocol_b(Plant::MemoryAndRate);
    both_named_in(r, Plant::MemoryAndRate);
    // The report lists every path followed; the one chosen is kept and
    // has the lowest held-out error of those kept.
    assert!(r.paths.len() >= 2, "{:?}", r.paths);
    let chosen = r
        .paths
        .iter()
        .find(|p| p.kept && p.effects == r.effects_added)
        .expect("the chosen path is listed");
    assert!(r
        .paths
        .iter()
        .filter(|p| p.kept)
        .all(|p| p.rms_heldout >= chosen.rms_heldout));
    assert_eq!(chosen.rms_heldout, r.rms_after);
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn width_and_creep_at_once_are_both_named_under_the_second_protocol() {
    both_named_in(protocol_b(Plant::WidthAndCreep), Plant::WidthAndCreep);
}

/// The Tondu–Lopez muscle (a static curve outside the cubic family, with
/// the memory plant's friction): the static shape is named first, then the
/// memory, and the error above the noise is cut by a fifth at least.
fn tondu_lopez(name: &str, csv: String) {
    let r = run(name, csv);
    assert_eq!(
        r.effects_added.first().copied(),
        Some("constraint_shape"),
        "{:?}",
        r.effects_added
    );
    let mut got = r.effects_added.clone();
    let mut want = Plant::TonduLopez.expected_effects().to_vec();
    got.sort_unstable();
    want.sort_unstable();
    assert_eq!(got, want);
    assert!(r.share_removed() >= 0.2, "{}", r.share_removed());
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn tondu_lopez_static_shape_is_named_under_the_first_protocol() {
    tondu_lopez("a_tl", hidden_plants::csv(Plant::TonduLopez, 1, true));
}

#[test]
#[cfg_attr(debug_assertions, ignore)]
fn tondu_lopez_static_shape_is_named_under_the_second_protocol() {
    tondu_lopez("b_tl", hidden_plants::csv_b(Plant::TonduLopez, 1));
}

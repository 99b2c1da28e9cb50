//! The Preisach model on host-sim's rig, as a user gets it onto a chip:
//! identified on the characterisation record by pam-lab's one
//! identification of the family (`pam_lab::identify::preisach`, what
//! `pam-lab compare` runs: [`Grid::for_record`] and [`identify`]), encoded
//! by pam-core into the blob `compare` writes (`preisach.blob`, magic
//! `PAMP`), and booted by the firmware ([`firmware::boot::boot`]).
//!
//! `compare` trains on the record without its held-out cycles, which it
//! scores the model on; the blob for the controller here trains on every
//! sample (nothing is scored on the record: the scenarios are the test).

use crate::rig::Sample;
use firmware::controller::preisach::{PREISACH_BLOB_LEN, PREISACH_LOADS, PREISACH_ROWS};
use pam_lab::identify::preisach::{identify, Grid, Table, LOADS, ROWS};

// The firmware boots the size pam-lab identifies.
const _: () = assert!(ROWS == PREISACH_ROWS && LOADS == PREISACH_LOADS);

/// The Preisach table of `samples` (a characterisation record), every
/// sample training.
pub fn identify_table(samples: &[Sample]) -> Result<Table, String> {
    let record = crate::to_record("characterisation run", samples);
    let grid = Grid::for_record(&record.samples)
        .ok_or("the record has no positive pressure: no Preisach grid")?;
    let training = vec![false; record.samples.len()];
    identify(&record.samples, &training, &grid)
}

/// The blob of [`identify_table`]'s table, as `pam-lab compare` writes it.
pub fn identify_blob(samples: &[Sample]) -> Result<Vec<u8>, String> {
    let table = identify_table(samples)?;
    let mut blob = vec![0u8; PREISACH_BLOB_LEN];
    pam_core::preisach::blob::encode(&table, &mut blob)
        .map_err(|e| format!("the Preisach blob: {e}"))?;
    Ok(blob)
}

//! `pam-lab diagnose` on an arbitrary record, through the entry points the
//! command uses: `commands::parse_record` (`Purpose::Diagnose`), then
//! `commands::diagnose_record` and the summary it prints.
//!
//! Asserts: no panic; a refusal's text is not empty; an accepted diagnosis
//! has finite held-out errors, one prediction per sample, and a report that
//! serialises to JSON.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_lab::commands;
use pam_lab::record::Purpose;
use pam_lab::identify::diagnose::DiagnoseConfig;

fuzz_target!(|data: &[u8]| {
    let record = match commands::parse_record("fuzz.csv", data, Purpose::Diagnose) {
        Ok(r) => r,
        Err(e) => {
            assert!(e.to_string().starts_with("fuzz.csv"), "{e}");
            return;
        }
    };
    match commands::diagnose_record(&record, &DiagnoseConfig::default(), &|_| {}) {
        Ok(r) => {
            assert!(r.rms_before.is_finite() && r.rms_after.is_finite());
            assert_eq!(r.predicted_base.len(), record.len());
            assert_eq!(r.predicted_after.len(), record.len());
            assert!(serde_json::to_string(&r).is_ok());
            let _ = pam_lab::identify::diagnose::summary(&r);
        }
        Err(e) => assert!(!e.to_string().is_empty()),
    }
});

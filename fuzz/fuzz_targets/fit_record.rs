//! `pam-lab fit` on an arbitrary record, through the entry points the
//! command uses: `commands::parse_record` (the reader and the record-level
//! checks of `Purpose::Fit`), then `commands::fit_record` (the fit and the
//! model files) and `commands::fit_text` (the report).
//!
//! Asserts: no panic; a refusal's text names the record; an accepted fit
//! gives a blob that decodes to the same parameters, a JSON model file that
//! parses back to them, and parameters `Coeffs::new` accepts.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_lab::commands;
use pam_lab::record::Purpose;
use pam_lab::identify::fit::FitConfig;

fuzz_target!(|data: &[u8]| {
    let record = match commands::parse_record("fuzz.csv", data, Purpose::Fit) {
        Ok(r) => r,
        Err(e) => {
            assert!(e.to_string().starts_with("fuzz.csv"), "{e}");
            return;
        }
    };
    let cfg = FitConfig::default();
    match commands::fit_record(&record, &cfg, &|_| {}) {
        Ok(outcome) => {
            let params = outcome.report.params;
            assert!(pam_core::Coeffs::new(params).is_ok());
            let blob = &outcome
                .files
                .iter()
                .find(|f| f.0 == "model.blob")
                .unwrap()
                .1;
            let back = pam_core::blob::decode_params(blob).expect("blob decodes");
            assert_eq!(back, params);
            let json = &outcome
                .files
                .iter()
                .find(|f| f.0 == "model.json")
                .unwrap()
                .1;
            let m: pam_lab::export::model_file::ModelFile = serde_json::from_slice(json).expect("json");
            assert_eq!(m.params, params);
            let text = commands::fit_text(&outcome, &record, &cfg);
            assert!(text.contains("fuzz.csv"));
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("fuzz.csv"), "{msg}");
        }
    }
});

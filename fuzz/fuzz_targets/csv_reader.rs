//! pam-lab's measurement CSV reader, `data::parse_csv`, on arbitrary bytes.
//!
//! Asserts: no panic; an accepted record is non-empty, has one line number
//! per sample, strictly increasing line numbers, finite values, time that
//! never goes backwards, and every sample within `check_physical`; an error
//! formats (its `Display` does not panic) and names a line within the input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use pam_lab::record::{check_physical, parse_csv};

fuzz_target!(|data: &[u8]| {
    match parse_csv("fuzz.csv", data) {
        Ok(r) => {
            assert!(!r.samples.is_empty());
            assert_eq!(r.samples.len(), r.lines.len());
            let lines_in_input = data.split(|&b| b == b'\n').count() as u64;
            for w in r.lines.windows(2) {
                assert!(w[0] < w[1], "line numbers not increasing: {:?}", r.lines);
            }
            assert!(r.lines.iter().all(|&l| l >= 2 && l <= lines_in_input));
            for w in r.samples.windows(2) {
                assert!(w[1].t_s >= w[0].t_s, "time backwards");
            }
            for s in &r.samples {
                assert!(s.t_s.is_finite() && s.load_n.is_finite());
                assert!(s.pressure_mpa.is_finite() && s.contraction.is_finite());
                assert!(check_physical(s).is_ok());
            }
        }
        Err(e) => {
            let lines_in_input = data.split(|&b| b == b'\n').count() as u64;
            assert!(
                e.line <= lines_in_input,
                "error line {} of {lines_in_input}",
                e.line
            );
            let _ = e.to_string();
        }
    }
});

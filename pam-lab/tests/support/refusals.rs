//! Running `pam-lab` on bad input in a fresh directory and checking its
//! refusal (the helpers of `cli_refusals*.rs`).

#![allow(dead_code)]

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use pam_core::Params;
use pam_lab::export::model_file::ModelFile;
use pam_lab::synth::{generate, Protocol};

pub const HEADER: &str = "t_s,load_n,pressure_mpa,contraction";

/// A good two-load record as CSV rows (without the header).
pub fn good_rows() -> Vec<String> {
    rows_at(&[100.0, 300.0])
}

/// A good record at `loads` as CSV rows.
pub fn rows_at(loads: &[f64]) -> Vec<String> {
    let rec = generate(&Params::DEFAULT, &Protocol::quick(loads), 0.001, 0.0008, 5);
    rec.samples
        .iter()
        .map(|s| {
            format!(
                "{:.3},{},{:.5},{:.5}",
                s.t_s, s.load_n, s.pressure_mpa, s.contraction
            )
        })
        .collect()
}

pub fn good_csv() -> String {
    format!("{HEADER}\n{}\n", good_rows().join("\n"))
}

/// The rows of the good record with `f` applied to each `(index, fields)`.
pub fn edited(f: impl Fn(usize, &mut Vec<String>)) -> String {
    let mut out = format!("{HEADER}\n");
    for (i, row) in good_rows().iter().enumerate() {
        let mut fields: Vec<String> = row.split(',').map(str::to_string).collect();
        f(i, &mut fields);
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// Every file and directory below `dir`, with its contents.
pub fn snapshot(dir: &Path) -> BTreeMap<String, Option<Vec<u8>>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let key = p.strip_prefix(dir).unwrap().display().to_string();
            if p.is_dir() {
                out.insert(key, None);
                stack.push(p);
            } else if p.metadata().unwrap().len() < (1 << 20) {
                out.insert(key, Some(std::fs::read(&p).unwrap()));
            } else {
                let len = p.metadata().unwrap().len();
                out.insert(key, Some(len.to_le_bytes().to_vec()));
            }
        }
    }
    out
}

/// Set up the directory with `files`, run `pam-lab args`, and check the
/// refusal: exit code 1, one error line containing every `want`, nothing
/// written.
pub fn refused(files: &[(&str, Vec<u8>)], args: &[&str], want: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in files {
        let p = dir.path().join(name);
        if let Some(parent) = p.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        if name.ends_with('/') {
            std::fs::create_dir_all(&p).unwrap();
        } else {
            std::fs::write(&p, bytes).unwrap();
        }
    }
    let before = snapshot(dir.path());
    let out = Command::new(env!("CARGO_BIN_EXE_pam-lab"))
        .args(args)
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert_eq!(
        out.status.code(),
        Some(1),
        "{args:?}: exit code\nstdout: {stdout}\nstderr: {stderr}"
    );
    for w in want {
        assert!(stderr.contains(w), "{args:?}: want `{w}` in:\n{stderr}");
        assert_eq!(
            stderr.matches(w).count(),
            1,
            "{args:?}: `{w}` said more than once:\n{stderr}"
        );
    }
    assert!(
        !stderr.contains("panicked"),
        "{args:?}: a panic, not a refusal:\n{stderr}"
    );
    // (Progress lines, on a redirected stderr, may come before it.)
    if stderr.lines().any(|l| l.starts_with("error: ")) {
        assert_eq!(
            stderr.matches("error:").count(),
            1,
            "{args:?}: the error is printed once:\n{stderr}"
        );
    }
    assert!(stdout.is_empty(), "{args:?}: nothing on stdout: {stdout}");
    assert_eq!(
        snapshot(dir.path()).keys().collect::<Vec<_>>(),
        before.keys().collect::<Vec<_>>(),
        "{args:?}: files written or removed"
    );
    assert!(
        snapshot(dir.path()) == before,
        "{args:?}: a file was changed"
    );
}

pub fn csv(text: impl Into<String>) -> Vec<u8> {
    text.into().into_bytes()
}

pub fn model_json() -> Vec<u8> {
    csv(ModelFile::new(Params::DEFAULT, None).to_json())
}

pub const FIT: [&str; 4] = ["fit", "bad.csv", "-o", "out"];

pub fn fit_refuses(data: Vec<u8>, want: &[&str]) {
    refused(&[("bad.csv", data)], &FIT, want);
}

pub fn simulate_refuses(data: Vec<u8>, want: &[&str]) {
    refused(
        &[("bad.csv", data), ("model.json", model_json())],
        &["simulate", "model.json", "bad.csv", "-o", "sim.csv"],
        want,
    );
}

pub fn diagnose_refuses(data: Vec<u8>, want: &[&str]) {
    refused(
        &[("bad.csv", data)],
        &["diagnose", "bad.csv", "-o", "diag"],
        want,
    );
}

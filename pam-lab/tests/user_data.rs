//! A user's data is safe: no command writes over one of its inputs (by
//! name, through a symbolic link or a hard link), and an interrupted
//! command leaves no staging directory behind.

use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "support/cli.rs"]
mod cli_support;
use cli_support::pam_lab;

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(name)
}

#[test]
fn no_command_writes_over_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.csv");
    std::fs::copy(example("reference.csv"), &rec).unwrap();
    let original = std::fs::read(&rec).unwrap();
    let fit = dir.path().join("fit");
    let (ok, _, stderr) = pam_lab(&[
        "fit",
        rec.to_str().unwrap(),
        "-o",
        fit.to_str().unwrap(),
        "--no-plot",
        "-q",
    ]);
    assert!(ok, "{stderr}");
    let model = fit.join("model.json");
    let model_bytes = std::fs::read(&model).unwrap();
    let link = dir.path().join("link.csv");
    std::os::unix::fs::symlink(&rec, &link).unwrap();
    let hard = dir.path().join("hard.csv");
    std::fs::hard_link(&rec, &hard).unwrap();
    for target in [&rec, &model, &link, &hard] {
        let (ok, stdout, stderr) = pam_lab(&[
            "simulate",
            model.to_str().unwrap(),
            rec.to_str().unwrap(),
            "-o",
            target.to_str().unwrap(),
        ]);
        assert!(
            !ok && stdout.is_empty(),
            "{}: {stdout}{stderr}",
            target.display()
        );
        assert!(
            stderr.contains("cannot write: it is the input"),
            "{}: {stderr}",
            target.display()
        );
    }
    // The plot may not replace it either (here through a hard link named
    // as a plot).
    let as_png = dir.path().join("rec.png");
    std::fs::hard_link(&rec, &as_png).unwrap();
    let (ok, _, stderr) = pam_lab(&[
        "simulate",
        model.to_str().unwrap(),
        rec.to_str().unwrap(),
        "-o",
        dir.path().join("sim.csv").to_str().unwrap(),
        "--plot",
        as_png.to_str().unwrap(),
    ]);
    assert!(!ok && stderr.contains("it is the input"), "{stderr}");
    assert!(!dir.path().join("sim.csv").exists());
    assert_eq!(std::fs::read(&rec).unwrap(), original);
    assert_eq!(std::fs::read(&model).unwrap(), model_bytes);
}

#[test]
fn an_interrupted_diagnose_leaves_nothing_behind() {
    // Ctrl-C (SIGINT) and a service manager's stop (SIGTERM) alike.
    for signal in ["-INT", "-TERM"] {
        interrupted_diagnose_leaves_nothing_behind(signal);
    }
}

fn interrupted_diagnose_leaves_nothing_behind(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("diag");
    let mut child = Command::new(env!("CARGO_BIN_EXE_pam-lab"))
        .args([
            "diagnose",
            example("rate_dependence.csv").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "-q",
        ])
        .spawn()
        .unwrap();
    let staging = || {
        std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(Result::ok)
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with(".pam-lab-staging-")
            })
            .count()
    };
    // The staging directory is made before the work starts.
    let t0 = std::time::Instant::now();
    while staging() == 0 && t0.elapsed().as_secs() < 20 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert_eq!(staging(), 1, "{signal}: no staging directory appeared");
    let killed = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "{signal}: {status:?}");
    assert_eq!(staging(), 0, "{signal}: a staging directory was left");
    assert!(!out.exists(), "{signal}");
}

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
fn fit_diagnose_and_import_never_write_over_their_inputs() {
    // Each command's output directory holds a file the command reads,
    // under the name of one it writes: refused before any work, the input
    // untouched.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let read = |p: &Path| std::fs::read(p).unwrap();
    let refused = |args: &[&str], input: &Path| {
        let before = read(input);
        let (ok, stdout, stderr) = pam_lab(args);
        assert!(!ok && stdout.is_empty(), "{args:?}: {stdout}{stderr}");
        assert!(
            stderr.contains("cannot write: it is the input"),
            "{args:?}: {stderr}"
        );
        assert_eq!(read(input), before, "{args:?}");
    };
    let o = out.to_str().unwrap();
    // fit: the record as the model file, then the validation record as the
    // blob (a hard link under another name).
    let rec = out.join("model.json");
    std::fs::copy(example("reference.csv"), &rec).unwrap();
    refused(
        &["fit", rec.to_str().unwrap(), "-o", o, "--no-plot", "-q"],
        &rec,
    );
    let own = dir.path().join("rec.csv");
    std::fs::copy(example("reference.csv"), &own).unwrap();
    let blob = out.join("model.blob");
    std::fs::hard_link(&own, &blob).unwrap();
    refused(
        &[
            "fit",
            own.to_str().unwrap(),
            "--validate",
            blob.to_str().unwrap(),
            "-o",
            o,
            "--no-plot",
            "-q",
        ],
        &own,
    );
    // diagnose: the record as its report.
    let report = out.join("report.json");
    std::fs::copy(example("reference.csv"), &report).unwrap();
    refused(
        &[
            "diagnose",
            report.to_str().unwrap(),
            "-o",
            o,
            "--no-plot",
            "-q",
        ],
        &report,
    );
    // import: a logger's file named as the record it writes, in the output
    // directory itself; then the mapping through a symbolic link.
    let data = dir.path().join("logger");
    std::fs::create_dir(&data).unwrap();
    std::fs::write(data.join("r.csv"), "0.0,10,100\n0.1,11,120\n0.2,12,140\n").unwrap();
    let map = dir.path().join("map.toml");
    std::fs::write(
        &map,
        "header = false\nlength_unit = \"cm\"\n[columns]\nload = { column = 2, unit = \"N\" }\n\
         pressure = { column = 3, unit = \"kPa\" }\ntime = { column = 1, unit = \"s\" }\n\
         [[record]]\nname = \"r\"\nrest_length = 10\nfiles = [ { path = \"r.csv\", held_length = 9 } ]\n",
    )
    .unwrap();
    let d = data.to_str().unwrap();
    refused(
        &["import", map.to_str().unwrap(), "--data-dir", d, "-o", d],
        &data.join("r.csv"),
    );
    std::os::unix::fs::symlink(&map, data.join("map_link.csv")).unwrap();
    std::fs::write(
        &map,
        std::fs::read_to_string(&map)
            .unwrap()
            .replace("name = \"r\"", "name = \"map_link\""),
    )
    .unwrap();
    refused(
        &["import", map.to_str().unwrap(), "--data-dir", d, "-o", d],
        &map,
    );
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

//! `pam-lab`: identify the PAM hysteresis model from test-rig measurements,
//! simulate it, and export the firmware's coefficients. See the crate docs
//! and `pam-lab/README.md`.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use pam_core::TrackerConfig;
use pam_lab::fit::{FitConfig, Holdout, Progress, TestKind};
use pam_lab::model_file::{FitSummary, ModelFile};
use pam_lab::split::SplitConfig;
use pam_lab::{atomic, data, fit, model_file, plot, simulate};

#[derive(Parser)]
#[command(
    name = "pam-lab",
    version,
    about = "Identify, simulate and export the PAM hysteresis model"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fit the paper's model to a record and write model.json, model.blob,
    /// model_params.rs and fit.png.
    Fit {
        /// Measurement CSV (`t_s,load_n,pressure_mpa,contraction`).
        data: PathBuf,
        /// Output directory (created if missing).
        #[arg(short, long, default_value = "pam-lab-fit")]
        out_dir: PathBuf,
        /// Maximum operating pressure Pmax, MPa (default: measured from the record).
        #[arg(long, value_name = "MPA")]
        pmax: Option<f64>,
        /// Load step of the regression and growth factors, N.
        #[arg(long, default_value_t = 100.0, value_name = "N")]
        load_step: f64,
        /// Held-out part: `every:K` (every K-th cycle), `tail:F` (last fraction F) or `none`.
        #[arg(long, default_value = "every:4")]
        holdout: Holdout,
        /// Branch-split deadband on the pressure, MPa (default: 6 × the estimated pressure noise).
        #[arg(long, value_name = "MPA")]
        deadband: Option<f64>,
        /// Width of the load bins for grouping and reports, N.
        #[arg(long, default_value_t = 25.0, value_name = "N")]
        load_bin: f64,
        /// Fewest training samples per branch in a load bin.
        #[arg(long, default_value_t = 50)]
        min_samples: usize,
        /// Kind of test: `isotonic`, `isometric` or `mixed` (default: detected from the record).
        #[arg(long, value_name = "KIND")]
        test: Option<TestKind>,
        /// Do not draw fit.png.
        #[arg(long)]
        no_plot: bool,
        /// No progress on stderr.
        #[arg(short, long)]
        quiet: bool,
    },
    /// Drive a model with a record's measured pressure and load; write the
    /// predicted and measured contraction and the error.
    Simulate {
        /// Model: a model.json or a model.blob.
        model: PathBuf,
        /// Measurement CSV.
        data: PathBuf,
        /// Output CSV.
        #[arg(short, long, default_value = "simulated.csv")]
        out: PathBuf,
        /// Plot (PNG) of measured and predicted contraction and the error.
        #[arg(long, value_name = "PNG")]
        plot: Option<PathBuf>,
        /// Tracker direction deadband on the pressure, MPa.
        #[arg(long, default_value_t = TrackerConfig::DEFAULT_PRESSURE.direction_deadband, value_name = "MPA")]
        deadband: f32,
        /// Load change that switches the active model, N.
        #[arg(long, default_value_t = TrackerConfig::DEFAULT_PRESSURE.load_threshold_n, value_name = "N")]
        load_threshold: f32,
        /// Samples a load change must persist before the model switches.
        #[arg(long, default_value_t = TrackerConfig::DEFAULT_PRESSURE.load_debounce_samples)]
        debounce: u16,
    },
    /// Find where the model and a record disagree, name the missing effect,
    /// add it, and report the held-out error before and after (report.json,
    /// residual.png, loops.png; see pam-lab/DIAGNOSE.md).
    Diagnose {
        /// Measurement CSV.
        data: PathBuf,
        /// Output directory (created if missing).
        #[arg(long, default_value = "pam-lab-diagnose")]
        out: PathBuf,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Fit {
            data,
            out_dir,
            pmax,
            load_step,
            holdout,
            deadband,
            load_bin,
            min_samples,
            test,
            no_plot,
            quiet,
        } => {
            let cfg = FitConfig {
                max_pressure_mpa: pmax,
                load_step_n: load_step,
                holdout,
                split: SplitConfig {
                    deadband_mpa: deadband,
                    ..SplitConfig::default()
                },
                load_bin_n: load_bin,
                min_samples_per_group: min_samples,
                test,
                ..FitConfig::default()
            };
            run_fit(&data, &out_dir, &cfg, !no_plot, !quiet)
        }
        Command::Simulate {
            model,
            data,
            out,
            plot,
            deadband,
            load_threshold,
            debounce,
        } => {
            let config = TrackerConfig {
                direction_deadband: deadband,
                load_threshold_n: load_threshold,
                load_debounce_samples: debounce,
            };
            run_simulate(&model, &data, &out, plot.as_deref(), config)
        }
        Command::Diagnose { data, out } => pam_lab::diagnose::run_cli(&data, &out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

fn run_fit(
    data_path: &Path,
    out_dir: &Path,
    cfg: &FitConfig,
    draw: bool,
    verbose: bool,
) -> Result<()> {
    // Every setting is checked before the record is read.
    cfg.validate()?;
    let start = Instant::now();
    let tty = std::io::stderr().is_terminal();
    let say = |msg: &str| {
        if verbose {
            eprintln!("[{:6.2} s] {msg}", start.elapsed().as_secs_f64());
        }
    };
    say(&format!("reading {}", data_path.display()));
    let record = data::read_csv(data_path)?;
    say(&format!("{} samples", record.len()));
    let progress = |p: Progress| {
        if !verbose {
            return;
        }
        match p {
            Progress::Stage(s) => {
                if tty {
                    eprint!("\r\x1b[K");
                }
                eprintln!("[{:6.2} s] {s}", start.elapsed().as_secs_f64());
            }
            Progress::Evaluation { count, cost } => {
                if tty {
                    eprint!("\r\x1b[K  evaluation {count}, cost {cost:.6e}");
                    let _ = std::io::stderr().flush();
                }
            }
        }
    };
    let report = fit::fit_with_progress(&record, cfg, &progress)?;
    say(&format!(
        "fit done: {} residual evaluations, {}",
        report.evaluations, report.termination
    ));

    std::fs::create_dir_all(out_dir)
        .with_context(|| format!("cannot create {}", out_dir.display()))?;
    let n_train = (0..record.len())
        .filter(|&i| report.split.branch[i].is_some() && !report.heldout[i])
        .count();
    let any_heldout = report.heldout.iter().any(|h| *h);
    let summary = FitSummary {
        source: record.source.clone(),
        samples: record.len(),
        training_samples: n_train,
        holdout: report.holdout.to_string(),
        max_pressure_source: format!("{:?}", report.pmax_source).to_lowercase(),
        pressure_noise_mpa: report.split.pressure_noise_mpa,
        contraction_noise: report.split.contraction_noise,
        heldout_errors: any_heldout.then(|| report.test.clone()),
    };
    let model = ModelFile::new(report.params, Some(summary));
    let json = out_dir.join("model.json");
    atomic::write_bytes(&json, model.to_json().as_bytes())?;
    let blob = out_dir.join("model.blob");
    atomic::write_bytes(&blob, &pam_core::blob::encode(&report.params))?;
    let rs = out_dir.join("model_params.rs");
    let origin = format!("pam-lab fit {} --holdout {}", record.source, report.holdout);
    atomic::write_bytes(
        &rs,
        model_file::rust_source(&report.params, &origin).as_bytes(),
    )?;
    let mut written = vec![json, blob, rs];
    if draw {
        say("plotting");
        let png = out_dir.join("fit.png");
        plot::fit_plot(
            &png,
            &record,
            &report.split,
            &report.heldout,
            &report.coeffs,
            cfg.load_bin_n,
        )?;
        written.push(png);
    }

    let p = &report.params;
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "model of {} ({} samples, {} for training, held out: {})",
        record.source,
        record.len(),
        n_train,
        report.holdout
    )?;
    writeln!(
        out,
        "  loads {}..{} N, step {} N; Pmax {} MPa ({:?})",
        p.min_load_n, p.max_load_n, p.load_step_n, p.points.max_pressure_mpa, report.pmax_source
    )?;
    writeln!(
        out,
        "  R1 {:.5}  Rx1 {:.5}  tangency ({:.5}, {:.5} MPa)  inflection ({:.5}, {:.5} MPa)",
        p.points.root_contraction,
        p.points.max_contraction,
        p.points.tangency.contraction,
        p.points.tangency.pressure_mpa,
        p.points.inflection.contraction,
        p.points.inflection.pressure_mpa
    )?;
    writeln!(
        out,
        "  RG_L {:.6}  RG_U {:.6}  GR_c {:.5}  be {:.5} MPa",
        p.root_regression_per_step,
        p.max_regression_per_step,
        p.c_growth_per_step,
        p.ellipse_height_mpa
    )?;
    writeln!(
        out,
        "  noise estimate: pressure {:.5} MPa, contraction {:.5}",
        report.split.pressure_noise_mpa, report.split.contraction_noise
    )?;
    writeln!(
        out,
        "  test: {} ({})",
        report.test_kind,
        if cfg.test.is_some() {
            "given"
        } else {
            "detected"
        }
    )?;
    writeln!(out, "  shape: {}", report.shape.statement())?;
    writeln!(
        out,
        "{} errors (model − measured; pressure by the forward model, contraction by the inverse):",
        if any_heldout {
            "held-out"
        } else {
            "training (nothing held out)"
        }
    )?;
    write!(out, "{}", report.test.to_text())?;
    writeln!(
        out,
        "  held-out pressure error RMS {:.5} MPa, contraction error RMS {:.6} ({} error is primary for an {} test)",
        report.test.total.pressure_rms_mpa,
        report.test.total.contraction_rms,
        if report.test_kind == fit::TestKind::Isometric { "the pressure" } else { "the contraction" },
        report.test_kind
    )?;
    for w in &written {
        writeln!(out, "wrote {}", w.display())?;
    }
    Ok(())
}

fn run_simulate(
    model: &Path,
    data_path: &Path,
    out: &Path,
    plot_path: Option<&Path>,
    config: TrackerConfig,
) -> Result<()> {
    let coeffs = model_file::load(model)?;
    config
        .validate()
        .map_err(|e| anyhow::anyhow!("tracker settings: {e}"))?;
    let record = data::read_csv(data_path)?;
    let sim = simulate::simulate(&coeffs, config, &record.samples);
    atomic::write_with(out, |w| simulate::write_csv(w, &sim).map_err(Into::into))?;
    if let Some(p) = plot_path {
        plot::simulate_plot(p, &record.source, &sim)?;
    }
    let sum = simulate::summary(&sim);
    println!(
        "simulated {} samples of {} with {}: contraction error RMS {:.5}, max {:.5}; \
         pressure error RMS {:.5} MPa, max {:.5} MPa",
        sim.len(),
        record.source,
        model.display(),
        sum.contraction_rms,
        sum.contraction_max,
        sum.pressure_rms_mpa,
        sum.pressure_max_mpa
    );
    println!("wrote {}", out.display());
    if let Some(p) = plot_path {
        println!("wrote {}", p.display());
    }
    Ok(())
}

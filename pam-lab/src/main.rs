//! `pam-lab`: identify the PAM hysteresis model from test-rig measurements,
//! simulate it, and export the firmware's coefficients. See the crate docs
//! and `pam-lab/README.md` (its table of options is this file's `Cli`).
//!
//! Every command runs the same way: options checked, the record read and
//! checked, the work, then every output written at once
//! ([`pam_lab::output::OutputSet`]) and the report printed. Any refusal is
//! one `error:` line on stderr and exit code 1; nothing is written.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::Result;
use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use pam_core::TrackerConfig;
use pam_lab::commands;
use pam_lab::identify::diagnose::DiagnoseConfig;
use pam_lab::identify::fit::{FitConfig, Holdout, Progress, TestKind};
use pam_lab::output::OutputSet;
use pam_lab::record::split::SplitConfig;
use pam_lab::record::Purpose;

#[derive(Parser)]
#[command(
    name = "pam-lab",
    version,
    about = "Identify, simulate and export the PAM hysteresis model",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Options every command has.
#[derive(Args, Clone, Copy)]
struct Common {
    /// No progress and no report; only warnings and errors (stderr).
    #[arg(short, long)]
    quiet: bool,
    /// Progress on stderr: `auto` (a bar on a terminal, a plain line per
    /// stage when redirected: a diagnosis prints one per candidate and
    /// round), `always` (plain lines, on a terminal too), `never`.
    #[arg(long, value_enum, default_value_t = ProgressMode::Auto)]
    progress: ProgressMode,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ProgressMode {
    Auto,
    Always,
    Never,
}

/// The fit's options, shared by `fit` and `diagnose` (diagnose's base fit).
#[derive(Args)]
struct FitOptions {
    /// Maximum operating pressure Pmax, where the loop closes, MPa (default:
    /// the record's top; `diagnose` then refits it up to 1.25× the top, and
    /// holds a given one).
    #[arg(long, value_name = "MPA")]
    pmax: Option<f64>,
    /// Load step of the regression and growth factors, N.
    #[arg(long, default_value_t = 100.0, value_name = "N")]
    load_step: f64,
    /// Branch-split deadband on the pressure, MPa (default: 6 × the estimated pressure noise).
    #[arg(long, value_name = "MPA")]
    deadband: Option<f64>,
    /// Width of the load bins for grouping and reports, N.
    #[arg(long, default_value_t = 25.0, value_name = "N")]
    load_bin: f64,
    /// Fewest training samples per branch in a load bin.
    #[arg(long, default_value_t = 50, value_name = "N")]
    min_samples: usize,
    /// Kind of test: `isotonic`, `isometric` or `mixed` (default: detected from the record).
    #[arg(long, value_name = "KIND")]
    test: Option<TestKind>,
    /// Fit the paper's cubic alone: no static shape (stroke table), even
    /// where the cubic leaves a systematic misfit.
    #[arg(long)]
    no_static_shape: bool,
}

impl FitOptions {
    fn config(&self, holdout: Holdout) -> FitConfig {
        FitConfig {
            max_pressure_mpa: self.pmax,
            load_step_n: self.load_step,
            holdout,
            split: SplitConfig {
                deadband_mpa: self.deadband,
                ..SplitConfig::default()
            },
            load_bin_n: self.load_bin,
            min_samples_per_group: self.min_samples,
            test: self.test,
            static_shape: !self.no_static_shape,
            ..FitConfig::default()
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Turn a logger's files into pam's records: the mapping file says
    /// which column holds what, in which unit, and which files (with the
    /// length each was held at) make a record; writes NAME.csv per record.
    Import {
        /// Mapping file (TOML; examples/festo-10mm-isometric.toml is one).
        mapping: PathBuf,
        /// Directory the mapping's file paths are relative to.
        #[arg(long, default_value = ".", value_name = "DIR")]
        data_dir: PathBuf,
        /// Output directory (created if missing).
        #[arg(short, long, default_value = "pam-lab-import", value_name = "DIR")]
        out: PathBuf,
        /// Only this record of the mapping (repeatable; default: all).
        #[arg(long, value_name = "NAME")]
        record: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
    /// Fit the paper's model to a record and write model.json, model.blob,
    /// model_params.rs and fit.png into the output directory.
    #[command(allow_negative_numbers = true)]
    Fit {
        /// Measurement CSV (`t_s,load_n,pressure_mpa,contraction`).
        data: PathBuf,
        /// Output directory (created if missing).
        #[arg(short, long, default_value = "pam-lab-fit", value_name = "DIR")]
        out: PathBuf,
        #[command(flatten)]
        fit: FitOptions,
        /// Held-out part: `every:K` (every K-th cycle), `tail:F` (last fraction F) or `none`.
        #[arg(long, default_value = "every:4")]
        holdout: Holdout,
        /// Also evaluate the model and the reference surface on this
        /// record (another test of the same muscle, e.g. the held-out test).
        #[arg(long, value_name = "DATA.csv")]
        validate: Option<PathBuf>,
        /// Do not draw fit.png.
        #[arg(long)]
        no_plot: bool,
        #[command(flatten)]
        common: Common,
    },
    /// Put a record on the accuracy × instructions plane: the model fit
    /// writes and the Preisach model, each identified on the training
    /// cycles and scored on the held-out ones, beside their instructions
    /// on the chip (bench-m4's counts); says which pam would flash and why.
    /// Writes compare.json, preisach.blob (the Preisach table identified)
    /// and compare.png into the output directory.
    Compare {
        /// Isotonic measurement CSV (`t_s,load_n,pressure_mpa,contraction`).
        data: PathBuf,
        /// Output directory (created if missing).
        #[arg(short, long, default_value = "pam-lab-compare", value_name = "DIR")]
        out: PathBuf,
        /// Held-out part: `every:K` (every K-th cycle) or `tail:F` (last fraction F).
        #[arg(long, default_value = "every:4")]
        holdout: Holdout,
        /// Do not draw compare.png.
        #[arg(long)]
        no_plot: bool,
        #[command(flatten)]
        common: Common,
    },
    /// Drive a model with a record's measured pressure and load; write the
    /// predicted and measured contraction and the error as CSV.
    #[command(allow_negative_numbers = true)]
    Simulate {
        /// Model: a model.json or a model.blob.
        model: PathBuf,
        /// Measurement CSV.
        data: PathBuf,
        /// Output CSV (`-` for stdout).
        #[arg(short, long, default_value = "simulated.csv", value_name = "FILE")]
        out: PathBuf,
        /// Also draw measured and predicted contraction and the error (PNG);
        /// on an isometric record the pressure, its slack samples left out.
        #[arg(long, value_name = "PNG")]
        plot: Option<PathBuf>,
        /// Tracker direction deadband on the pressure, MPa.
        #[arg(long, default_value_t = TrackerConfig::DEFAULT_PRESSURE.direction_deadband, value_name = "MPA")]
        deadband: f32,
        /// Load change that switches the active model, N [default: 20, the
        /// firmware's; on an isometric record twice the load's noise, at
        /// least 0.5, as fit and diagnose evaluate it].
        #[arg(long, value_name = "N")]
        load_threshold: Option<f32>,
        /// Samples a load change must persist before the model switches
        /// [default: 5; 1 on an isometric record].
        #[arg(long, value_name = "N")]
        debounce: Option<u16>,
        #[command(flatten)]
        common: Common,
    },
    /// Turn the stroke scale the firmware adapted online (its defmt line
    /// `adaptation: stroke scale S`) into a model of its own: the flashed
    /// paper model with its stroke scaled, refitted, written as model.json,
    /// model.blob and model_params.rs; with `--record`, compared with the
    /// flashed model and a fresh `fit` of that record of the worn muscle.
    Adapt {
        /// The flashed model: a model.json or a model.blob (the paper's
        /// model; the firmware adapts no other).
        model: PathBuf,
        /// The adapted stroke scale the controller logged (0.5–1.5).
        #[arg(long, value_name = "S")]
        stroke_scale: f64,
        /// A record of the worn muscle: compare the flashed, the adapted and
        /// a freshly fitted model on it (contraction RMS).
        #[arg(long, value_name = "CSV")]
        record: Option<PathBuf>,
        /// Output directory (created if missing).
        #[arg(short, long, default_value = "pam-lab-adapt", value_name = "DIR")]
        out: PathBuf,
        #[command(flatten)]
        common: Common,
    },
    /// Find where the model and a record disagree, name the missing effect,
    /// add it, and report the held-out error before and after (report.json,
    /// residual.png, loops.png; see pam-lab/DIAGNOSE.md).
    #[command(allow_negative_numbers = true)]
    Diagnose {
        /// Measurement CSV.
        data: PathBuf,
        /// Output directory (created if missing).
        #[arg(short, long, default_value = "pam-lab-diagnose", value_name = "DIR")]
        out: PathBuf,
        #[command(flatten)]
        fit: FitOptions,
        /// How the static model diagnose writes is fitted on the whole
        /// record, as `pam-lab fit --holdout` fits it: `every:K`, `tail:F` or
        /// `none` (the diagnosis itself holds out its own segments).
        #[arg(long, default_value = "every:4")]
        holdout: Holdout,
        /// Most effects added, one per round, 0–5 (default 2; each round
        /// fits every remaining candidate, so a round costs about as much
        /// as the first).
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(0..=5))]
        max_effects: Option<u8>,
        /// Also evaluate the base and diagnosed models, in pressure, and the
        /// reference surface on this record (another test of the same
        /// muscle, e.g. the held-out test).
        #[arg(long, value_name = "DATA.csv")]
        validate: Option<PathBuf>,
        /// Do not draw residual.png and loops.png.
        #[arg(long)]
        no_plot: bool,
        #[command(flatten)]
        common: Common,
    },
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
                let _ = e.print();
                return ExitCode::SUCCESS;
            }
            // A usage error is a refusal like any other: exit code 1.
            let _ = e.print();
            return ExitCode::FAILURE;
        }
    };
    if let Err(e) = pam_lab::output::remove_staging_on_interrupt() {
        let _ = writeln!(std::io::stderr(), "error: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Import {
            mapping,
            data_dir,
            out,
            record,
            common,
        } => run_import(&mapping, &data_dir, &out, &record, common),
        Command::Fit {
            data,
            out,
            fit,
            holdout,
            validate,
            no_plot,
            common,
        } => run_fit(
            &data,
            validate.as_deref(),
            &out,
            &fit.config(holdout),
            !no_plot,
            common,
        ),
        Command::Compare {
            data,
            out,
            holdout,
            no_plot,
            common,
        } => run_compare(&data, &out, holdout, !no_plot, common),
        Command::Simulate {
            model,
            data,
            out,
            plot,
            deadband,
            load_threshold,
            debounce,
            common,
        } => {
            let config = TrackerConfig {
                direction_deadband: deadband,
                load_threshold_n: load_threshold
                    .unwrap_or(TrackerConfig::DEFAULT_PRESSURE.load_threshold_n),
                load_debounce_samples: debounce
                    .unwrap_or(TrackerConfig::DEFAULT_PRESSURE.load_debounce_samples),
            };
            let given = (load_threshold.is_some(), debounce.is_some());
            run_simulate(&model, &data, &out, plot.as_deref(), config, given, common)
        }
        Command::Adapt {
            model,
            stroke_scale,
            record,
            out,
            common,
        } => run_adapt(&model, stroke_scale, record.as_deref(), &out, common),
        Command::Diagnose {
            data,
            out,
            fit,
            holdout,
            max_effects,
            validate,
            no_plot,
            common,
        } => {
            let cfg = DiagnoseConfig {
                fit: fit.config(holdout),
                max_effects: max_effects.map_or(DiagnoseConfig::default().max_effects, usize::from),
                ..DiagnoseConfig::default()
            };
            run_diagnose(&data, validate.as_deref(), &out, &cfg, !no_plot, common)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if is_broken_pipe(&err) => ExitCode::SUCCESS,
        Err(err) => {
            let _ = writeln!(std::io::stderr(), "error: {}", message(&err));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes, each said once: a cause whose text its
/// wrapper already contains (`base fit: X` over `X`) is not repeated.
fn message(err: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if !out.contains(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
    }
    out
}

/// Stdout closed early (`pam-lab … | head`): not an error of ours.
fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Print to stdout, returning (not panicking on) a closed pipe.
fn print_out(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()?;
    Ok(())
}

fn warn(text: &str) {
    let _ = writeln!(std::io::stderr(), "warning: {text}");
}

/// Progress on stderr: an `indicatif` spinner on a terminal, plain lines
/// when asked for and redirected, nothing otherwise.
struct Reporter {
    bar: Option<ProgressBar>,
    lines: bool,
    start: Instant,
}

impl Reporter {
    fn new(common: Common) -> Reporter {
        let tty = std::io::stderr().is_terminal();
        let on = !common.quiet && common.progress != ProgressMode::Never;
        let bar = (on && tty && common.progress == ProgressMode::Auto).then(|| {
            let b = ProgressBar::new_spinner();
            b.set_style(
                ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_spinner()),
            );
            b.enable_steady_tick(Duration::from_millis(120));
            b
        });
        Reporter {
            bar,
            lines: on && (!tty || common.progress == ProgressMode::Always),
            start: Instant::now(),
        }
    }

    fn stage(&self, msg: &str) {
        if let Some(b) = &self.bar {
            b.set_message(msg.to_string());
        } else if self.lines {
            let _ = writeln!(
                std::io::stderr(),
                "[{:6.2} s] {msg}",
                self.start.elapsed().as_secs_f64()
            );
        }
    }

    /// A detail that changes often: shown on the bar only.
    fn detail(&self, msg: String) {
        if let Some(b) = &self.bar {
            b.set_message(msg);
        }
    }

    fn done(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

impl Drop for Reporter {
    fn drop(&mut self) {
        self.done();
    }
}

fn wrote(set_targets: &[PathBuf]) -> String {
    set_targets
        .iter()
        .map(|p| format!("wrote {}\n", p.display()))
        .collect()
}

fn run_import(
    mapping: &Path,
    data_dir: &Path,
    out: &Path,
    only: &[String],
    common: Common,
) -> Result<()> {
    let map = pam_lab::record::import::read_mapping(mapping)?;
    let mut set = OutputSet::new();
    set.protect(mapping);
    for r in &map.records {
        for f in &r.files {
            set.protect(&data_dir.join(&f.path));
        }
    }
    set.into_dir(out)?;
    let names: Vec<String> = map
        .records
        .iter()
        .filter(|r| only.is_empty() || only.contains(&r.name))
        .map(|r| format!("{}.csv", r.name))
        .collect();
    set.check_in_dir(out, &names.iter().map(String::as_str).collect::<Vec<_>>())?;
    let rep = Reporter::new(common);
    rep.stage(&format!("reading the files of {}", mapping.display()));
    let records = pam_lab::record::import::import(&map, data_dir, only)?;
    let mut text = String::new();
    for r in &records {
        for w in &r.warnings {
            warn(w);
        }
        set.add_bytes(&out.join(format!("{}.csv", r.name)), r.to_csv().as_bytes())?;
        let (t0, t1) = (
            r.samples.first().map_or(0.0, |s| s.t_s),
            r.samples.last().map_or(0.0, |s| s.t_s),
        );
        text.push_str(&format!(
            "{}: {} samples, {} segments, {:.1} s\n",
            r.name,
            r.samples.len(),
            r.segments.len(),
            t1 - t0
        ));
    }
    let written = set.commit()?;
    rep.done();
    if !common.quiet {
        print_out(&(text + &wrote(&written)))?;
    }
    Ok(())
}

fn run_fit(
    data: &Path,
    validate: Option<&Path>,
    out: &Path,
    cfg: &FitConfig,
    draw: bool,
    common: Common,
) -> Result<()> {
    // Options and the output directory before the record is read.
    cfg.validate()?;
    let mut set = OutputSet::new();
    set.protect(data);
    if let Some(v) = validate {
        set.protect(v);
    }
    set.into_dir(out)?;
    set.check_in_dir(
        out,
        &["model.json", "model.blob", "model_params.rs", "fit.png"][..if draw { 4 } else { 3 }],
    )?;
    let rep = Reporter::new(common);
    rep.stage(&format!("reading {}", data.display()));
    let record = commands::read_record(data, Purpose::Fit)?;
    for w in pam_lab::record::unit_warnings(&record) {
        warn(&w);
    }
    let validation = match validate {
        Some(v) => {
            rep.stage(&format!("reading {}", v.display()));
            Some(commands::read_record(v, Purpose::Simulate)?)
        }
        None => None,
    };
    rep.stage(&format!("{} samples", record.len()));
    let stage = std::sync::Mutex::new("");
    let progress = |p: Progress| match p {
        Progress::Stage(s) => {
            if let Ok(mut g) = stage.lock() {
                *g = s;
            }
            rep.stage(s);
        }
        Progress::Evaluation { count, cost } => {
            let s = stage.lock().map(|g| *g).unwrap_or("");
            rep.detail(format!("{s}: evaluation {count}, cost {cost:.4e}"));
        }
    };
    let outcome = commands::fit_and_validate(&record, validation.as_ref(), cfg, &progress)?;
    if draw {
        rep.stage("plotting");
    }
    commands::stage_fit(&mut set, out, &outcome, &record, cfg, draw)?;
    let written = set.commit()?;
    rep.done();
    if !common.quiet {
        print_out(&(commands::fit_text(&outcome, &record, cfg) + &wrote(&written)))?;
    }
    Ok(())
}

fn run_compare(
    data: &Path,
    out: &Path,
    holdout: Holdout,
    draw: bool,
    common: Common,
) -> Result<()> {
    let mut set = OutputSet::new();
    set.protect(data);
    set.into_dir(out)?;
    set.check_in_dir(
        out,
        &["compare.json", "preisach.blob", "compare.png"][..if draw { 3 } else { 2 }],
    )?;
    let rep = Reporter::new(common);
    rep.stage(&format!("reading {}", data.display()));
    let record = commands::read_record(data, Purpose::Fit)?;
    rep.stage("fitting the paper's model and identifying the Preisach model");
    let cfg = FitConfig {
        holdout,
        ..FitConfig::default()
    };
    let comparison = pam_lab::evaluate::families::compare(&record, &cfg)
        .map_err(|e| anyhow::anyhow!("{}: {e}", data.display()))?;
    let json = serde_json::to_vec_pretty(&comparison)?;
    set.add_bytes(&out.join("compare.json"), &json)?;
    let mut blob = vec![
        0u8;
        pam_core::preisach::blob::blob_len(
            pam_lab::identify::preisach::ROWS,
            pam_lab::identify::preisach::LOADS
        )
    ];
    pam_core::preisach::blob::encode(&comparison.preisach, &mut blob)
        .map_err(|e| anyhow::anyhow!("preisach.blob: {e}"))?;
    set.add_bytes(&out.join("preisach.blob"), &blob)?;
    if draw {
        rep.stage("plotting");
        let source = data.display().to_string();
        set.add_via_path(&out.join("compare.png"), |p| {
            pam_lab::report::compare_plot::compare_plot(p, &source, &comparison)
        })?;
    }
    let written = set.commit()?;
    rep.done();
    if !common.quiet {
        let text = pam_lab::evaluate::families::text(&comparison, &data.display().to_string());
        print_out(&(text + &wrote(&written)))?;
    }
    Ok(())
}

fn run_adapt(
    model: &Path,
    stroke_scale: f64,
    record: Option<&Path>,
    out: &Path,
    common: Common,
) -> Result<()> {
    if !(stroke_scale.is_finite()
        && pam_lab::identify::adapted::STROKE_SCALE_RANGE.contains(&stroke_scale))
    {
        anyhow::bail!("invalid setting `--stroke-scale`: {stroke_scale} is outside 0.5..=1.5");
    }
    let mut set = OutputSet::new();
    set.protect(model);
    if let Some(r) = record {
        set.protect(r);
    }
    set.into_dir(out)?;
    set.check_in_dir(out, &["model.json", "model.blob", "model_params.rs"])?;
    let rep = Reporter::new(common);
    rep.stage(&format!("reading {}", model.display()));
    let loaded = pam_lab::export::model_file::load(model)?;
    let record = match record {
        Some(r) => {
            rep.stage(&format!("reading {}", r.display()));
            Some(commands::read_record(r, Purpose::Fit)?)
        }
        None => None,
    };
    rep.stage("fitting the adapted model");
    let outcome = commands::adapt_model(
        &loaded,
        stroke_scale,
        record.as_ref(),
        &FitConfig::default(),
    )?;
    for (name, bytes) in &outcome.files {
        set.add_bytes(&out.join(name), bytes)?;
    }
    let written = set.commit()?;
    rep.done();
    if !common.quiet {
        print_out(
            &(commands::adapt_text(&outcome, stroke_scale, record.as_ref()) + &wrote(&written)),
        )?;
    }
    Ok(())
}

fn run_simulate(
    model: &Path,
    data: &Path,
    out: &Path,
    plot: Option<&Path>,
    config: TrackerConfig,
    (threshold_given, debounce_given): (bool, bool),
    common: Common,
) -> Result<()> {
    config.validate().map_err(|e| {
        let option = match e {
            pam_core::Error::OutOfRange("direction_deadband", _) => "--deadband",
            pam_core::Error::OutOfRange("load_threshold_n", _) => "--load-threshold",
            pam_core::Error::OutOfRange("load_debounce_samples", _) => "--debounce",
            _ => "tracker settings",
        };
        anyhow::anyhow!("invalid setting `{option}`: {e}")
    })?;
    if let Some(p) = plot {
        let png = p.extension().is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if !png {
            anyhow::bail!(
                "invalid setting `--plot`: {}: the plot is drawn as PNG only (name it .png)",
                p.display()
            );
        }
    }
    let to_stdout = out == Path::new("-");
    let mut set = OutputSet::new();
    set.protect(model);
    set.protect(data);
    if !to_stdout {
        set.check_target(out)?;
    }
    if let Some(p) = plot {
        set.check_target(p)?;
    }
    let rep = Reporter::new(common);
    rep.stage(&format!("reading {}", model.display()));
    let loaded = pam_lab::export::model_file::load(model)?;
    rep.stage(&format!("reading {}", data.display()));
    let record = commands::read_record(data, Purpose::Simulate)?;
    for w in pam_lab::record::unit_warnings(&record) {
        warn(&w);
    }
    // An isometric record's load is a force that moves every sample: the
    // model follows it as fit and diagnose evaluate it, unless told.
    let mut config = config;
    let isometric = pam_lab::identify::fit::detect_test(&record.samples)
        == pam_lab::identify::fit::TestKind::Isometric;
    if isometric {
        let load_noise = pam_lab::record::noise_std(record.samples.iter().map(|s| s.load_n));
        let follow = pam_lab::evaluate::simulate::following_the_force(config, load_noise);
        if !threshold_given {
            config.load_threshold_n = follow.load_threshold_n;
        }
        if !debounce_given {
            config.load_debounce_samples = follow.load_debounce_samples;
        }
    }
    rep.stage("simulating");
    let (sim, warnings) = commands::simulate_record(&loaded, config, &record)
        .map_err(|e| anyhow::anyhow!("tracker settings: {e}"))?;
    for w in &warnings {
        warn(w);
    }
    if !to_stdout {
        set.add_with(out, |w| pam_lab::evaluate::simulate::write_csv(w, &sim))?;
    }
    if let Some(p) = plot {
        rep.stage("plotting");
        // An isometric test's plot is in pressure, its slack samples left
        // out as fit leaves them out.
        let slack = isometric.then(|| {
            pam_lab::identify::fit::slack_mask(
                &record.samples,
                pam_lab::identify::fit::TestKind::Isometric,
            )
        });
        set.add_via_path(p, |tmp| {
            pam_lab::report::plot::simulate_plot(tmp, &record.source, &sim, slack.as_deref())
        })?;
    }
    let written = set.commit()?;
    rep.done();
    let summary = commands::simulate_text(&sim, &record, model, &loaded.effects) + &wrote(&written);
    if to_stdout {
        let mut w = std::io::BufWriter::new(std::io::stdout().lock());
        pam_lab::evaluate::simulate::write_csv(&mut w, &sim)?;
        w.flush()?;
        if !common.quiet {
            let _ = write!(std::io::stderr(), "{summary}");
        }
    } else if !common.quiet {
        print_out(&summary)?;
    }
    Ok(())
}

fn run_diagnose(
    data: &Path,
    validate: Option<&Path>,
    out: &Path,
    cfg: &DiagnoseConfig,
    draw: bool,
    common: Common,
) -> Result<()> {
    cfg.fit.validate()?;
    let mut set = OutputSet::new();
    set.protect(data);
    if let Some(v) = validate {
        set.protect(v);
    }
    set.into_dir(out)?;
    set.check_in_dir(
        out,
        &["report.json", "residual.png", "loops.png"][..if draw { 3 } else { 1 }],
    )?;
    let rep = Reporter::new(common);
    rep.stage(&format!("reading {}", data.display()));
    let record = commands::read_record(data, Purpose::Diagnose)?;
    for w in pam_lab::record::unit_warnings(&record) {
        warn(&w);
    }
    rep.stage(&format!(
        "diagnosing {} samples: base fit, then each candidate effect",
        record.len()
    ));
    let validation = match validate {
        Some(v) => {
            rep.stage(&format!("reading {}", v.display()));
            Some(commands::read_record(v, Purpose::Simulate)?)
        }
        None => None,
    };
    let mut report = commands::diagnose_record(&record, cfg, &|msg| rep.stage(msg))?;
    if let Some(v) = &validation {
        rep.stage(&format!("validating on {}", v.source));
        report.validation = Some(pam_lab::identify::diagnose::validate(
            &report, &record, v, cfg,
        ));
    }
    if draw {
        rep.stage("plotting");
    }
    commands::stage_diagnose(&mut set, out, &report, &record, draw)?;
    let written = set.commit()?;
    rep.done();
    if !common.quiet {
        print_out(&(pam_lab::identify::diagnose::summary(&report) + &wrote(&written)))?;
    }
    Ok(())
}

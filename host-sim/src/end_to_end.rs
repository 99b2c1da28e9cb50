//! End to end, as a user works: characterise a rig, identify the paper's
//! model (`pam-lab fit`) and the diagnosed one (`pam-lab diagnose`), boot
//! the firmware's controller from each model's blob, and track the paper's
//! scenarios (Figs. 6–8) on that same rig.
//!
//! For each rig of [`crate::effect_rigs`]:
//! 1. an isotonic record of [`IsotonicProtocol::WITH_FAST_CYCLE`] on the rig
//!    (100–600 N, slow and fast cycles, reversals inside the loop);
//! 2. `fit` and `diagnose` on it through pam-lab's command layer
//!    ([`pam_lab::commands::fit_record`], [`pam_lab::commands::diagnose_record`])
//!    and the `model.blob` each writes ([`pam_lab::export::model_file::model_files`]);
//! 3. each blob through the firmware's boot path ([`firmware::boot::boot`])
//!    into a [`Controller`];
//! 4. every scenario on a fresh rig of the same muscle: PI alone, the
//!    paper's model as feedforward, the diagnosed model as feedforward.
//!
//! A step the tools or the firmware refuse is reported with its reason, not
//! skipped silently.

use crate::bench::{controller_config, run_controller, BenchConfig, Mode, Run};
use crate::characterisation::{isotonic_run_on, to_record, IsotonicProtocol};
use crate::effect_rigs::EffectRig;
use crate::pneumatics::PneumaticParams;
use crate::rig::Rig;
use crate::scenarios::Scenario;
use firmware::boot::BootError;
use firmware::controller::Controller;
use pam_lab::commands::{diagnose_record, fit_record};
use pam_lab::identify::diagnose::DiagnoseConfig;
use pam_lab::identify::fit::FitConfig;
use pam_lab::record::Record;

/// What the host tools made of one rig's record.
#[derive(Clone, Debug)]
pub struct Identified {
    /// Samples in the record.
    pub samples: usize,
    /// Effects `diagnose` added, in order (empty: `none`).
    pub effects_added: Vec<&'static str>,
    /// Held-out contraction RMS of diagnose's base model and final model.
    pub rms_before: f64,
    /// See [`Identified::rms_before`].
    pub rms_after: f64,
    /// Contraction noise estimated from the record.
    pub noise: f64,
    /// `model.blob` of `fit`.
    pub paper_blob: Vec<u8>,
    /// `model.blob` of `diagnose`.
    pub diagnosed_blob: Vec<u8>,
    /// diagnose's closed-loop check of its model (refused: the blob
    /// written is fit's model).
    pub closed_loop: Option<pam_lab::identify::diagnose::closed_loop::ClosedLoopCheck>,
}

impl Identified {
    /// What diagnose named, `+`-joined (`none` for nothing).
    pub fn named(&self) -> String {
        if self.effects_added.is_empty() {
            "none".to_string()
        } else {
            self.effects_added.join("+")
        }
    }

    /// Whether diagnose's closed-loop check refused its model (then the
    /// blob it wrote is fit's model).
    pub fn refused(&self) -> bool {
        self.closed_loop.as_ref().is_some_and(|c| !c.accepted)
    }
}

/// The tracking of one scenario on one rig.
#[derive(Clone, Debug)]
pub struct ScenarioRuns {
    /// The scenario.
    pub scenario: &'static str,
    /// PI alone.
    pub pi: Run,
    /// The paper's model (the `fit` blob) as feedforward.
    pub paper: Run,
    /// The diagnosed model (the `diagnose` blob) as feedforward, or why the
    /// firmware refused to boot it.
    pub diagnosed: Result<Run, String>,
}

/// One rig, end to end.
#[derive(Clone, Debug)]
pub struct RigOutcome {
    /// The rig.
    pub rig: EffectRig,
    /// The identification, or why a tool refused the record.
    pub identified: Result<Identified, String>,
    /// The scenarios (empty when the identification failed).
    pub runs: Vec<ScenarioRuns>,
}

/// The record a user's rig would log: [`IsotonicProtocol::WITH_FAST_CYCLE`]
/// on `rig`'s muscle with the reference valves and sensors.
pub fn characterise(rig: &EffectRig, seed: u64) -> Record {
    characterise_with(rig, seed, &IsotonicProtocol::WITH_FAST_CYCLE)
}

/// [`characterise`] with another `protocol`.
pub fn characterise_with(rig: &EffectRig, seed: u64, protocol: &IsotonicProtocol) -> Record {
    let sim = Rig::new(
        rig.muscle,
        PneumaticParams::DEFAULT,
        protocol.loads_n[0],
        seed,
    );
    let samples = isotonic_run_on(sim, protocol);
    to_record(format!("{} rig (seed {seed})", rig.name), &samples)
}

/// `fit` and `diagnose` on `record` with their default settings, as the
/// CLI runs them, and the blob each writes.
pub fn identify(record: &Record) -> Result<Identified, String> {
    let fit = fit_record(record, &FitConfig::default(), &|_| {})
        .map_err(|e| format!("fit refused the record: {e}"))?;
    let paper_blob = blob_of(&fit.files).ok_or("fit wrote no model.blob")?;
    let report = diagnose_record(record, &DiagnoseConfig::default(), &|_| {})
        .map_err(|e| format!("diagnose refused the record: {e}"))?;
    let files = pam_lab::export::model_file::model_files(
        &report.final_params,
        &report.effects,
        None,
        &report.source,
    )
    .map_err(|e| format!("diagnose's model files: {e}"))?;
    let diagnosed_blob = blob_of(&files).ok_or("diagnose wrote no model.blob")?;
    Ok(Identified {
        samples: record.len(),
        effects_added: report.effects_added.clone(),
        rms_before: report.rms_before,
        rms_after: report.rms_after,
        noise: report.noise.contraction,
        paper_blob,
        diagnosed_blob,
        closed_loop: report.closed_loop.clone(),
    })
}

/// A table cell: the RMS error, and the fault the run went to its safe
/// state for (then the RMS is not a tracking error).
fn cell(run: &Run) -> String {
    match run.first_fault {
        Some((t, fault)) => format!(
            "{:.4} (safe state at {t:.1} s: {fault:?})",
            run.metrics.rms_error
        ),
        None => format!("{:.4}", run.metrics.rms_error),
    }
}

fn blob_of(files: &[(&'static str, Vec<u8>)]) -> Option<Vec<u8>> {
    files
        .iter()
        .find(|(name, _)| *name == "model.blob")
        .map(|(_, bytes)| bytes.clone())
}

/// The firmware's controller booted from `blob` the way the image boots:
/// [`firmware::boot::boot`] with the configured `Feedforward::Hysteresis`,
/// which runs whatever effects the blob carries (or refuses it).
pub fn boot(blob: &[u8], cfg: &BenchConfig, load_n: f64) -> Result<Controller, String> {
    boot_with(blob, Mode::FeedforwardPi, cfg, load_n)
}

/// [`boot`] with `mode`'s configuration ([`controller_config`]); the
/// blob's feedforward replaces the configured one where `mode` has a
/// model feedforward.
fn boot_with(
    blob: &[u8],
    mode: Mode,
    cfg: &BenchConfig,
    load_n: f64,
) -> Result<Controller, String> {
    match firmware::boot::boot(blob, controller_config(mode, cfg), |_| load_n as f32) {
        Ok(b) => Ok(b.controller),
        Err(BootError::Blob(e)) => Err(format!("firmware refuses the blob: {e:?}")),
        Err(BootError::Controller(e)) => Err(format!("firmware refuses the configuration: {e:?}")),
    }
}

/// Characterise, identify and track every scenario on `rig`.
pub fn run_rig(rig: &EffectRig, scenarios: &[Scenario], cfg: &BenchConfig) -> RigOutcome {
    let record = characterise(rig, cfg.seed);
    let identified = identify(&record);
    let runs = match &identified {
        Ok(id) => scenarios.iter().map(|sc| track(rig, sc, id, cfg)).collect(),
        Err(_) => Vec::new(),
    };
    RigOutcome {
        rig: *rig,
        identified,
        runs,
    }
}

/// [`run_rig`] for every rig, spread over the machine's cores.
pub fn run_all(rigs: &[EffectRig], scenarios: &[Scenario], cfg: &BenchConfig) -> Vec<RigOutcome> {
    let threads = std::thread::available_parallelism()
        .map_or(1, usize::from)
        .clamp(1, rigs.len().max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut done: Vec<(usize, RigOutcome)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(rig) = rigs.get(i) else { break };
                        mine.push((i, run_rig(rig, scenarios, cfg)));
                    }
                    mine
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("an end-to-end worker panicked"))
            .collect()
    });
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, o)| o).collect()
}

fn track(rig: &EffectRig, sc: &Scenario, id: &Identified, cfg: &BenchConfig) -> ScenarioRuns {
    let load0 = sc.load_at(0.0);
    let fresh = || Rig::new(rig.muscle, PneumaticParams::DEFAULT, load0, cfg.seed);
    // PI alone runs on the same booted model (its safety monitor checks
    // the contraction against this rig's identified model), without the
    // feedforward.
    let pi = boot_with(&id.paper_blob, Mode::PiOnly, cfg, load0)
        .map(|ctl| run_controller(sc, fresh(), ctl, Mode::PiOnly, cfg.warmup_s))
        .expect("the firmware boots the paper model's blob");
    let paper = boot(&id.paper_blob, cfg, load0)
        .map(|ctl| run_controller(sc, fresh(), ctl, Mode::FeedforwardPi, cfg.warmup_s))
        // The paper's blob carries no effect: the firmware always boots it.
        .expect("the firmware boots the paper model's blob");
    let diagnosed = boot(&id.diagnosed_blob, cfg, load0)
        .map(|ctl| run_controller(sc, fresh(), ctl, Mode::DiagnosedFeedforwardPi, cfg.warmup_s));
    ScenarioRuns {
        scenario: sc.name,
        pi,
        paper,
        diagnosed,
    }
}

/// The end-to-end table, Markdown.
pub fn table(outcomes: &[RigOutcome]) -> String {
    let mut s = String::new();
    s.push_str("| rig (effect turned up) | diagnose named | held-out RMS before -> after (noise) | scenario | PI | fit FF+PI | diagnosed FF+PI | diagnosed / fit |\n");
    s.push_str("|---|---|---|---|---|---|---|---|\n");
    for o in outcomes {
        let rig = format!("{} ({})", o.rig.name, o.rig.effect);
        let id = match &o.identified {
            Ok(id) => id,
            Err(why) => {
                s.push_str(&format!("| {rig} | {why} | | | | | | |\n"));
                continue;
            }
        };
        for (i, r) in o.runs.iter().enumerate() {
            let (named, rms) = if i == 0 {
                (
                    if id.refused() {
                        format!(
                            "{} (closed loop refused it: fit's model written)",
                            id.named()
                        )
                    } else {
                        id.named()
                    },
                    format!(
                        "{:.4} -> {:.4} ({:.4})",
                        id.rms_before, id.rms_after, id.noise
                    ),
                )
            } else {
                (String::new(), String::new())
            };
            let rig = if i == 0 { rig.as_str() } else { "" };
            let (diag, ratio) = match &r.diagnosed {
                Ok(d) => (
                    cell(d),
                    format!(
                        "{:.0} %",
                        100.0 * d.metrics.rms_error / r.paper.metrics.rms_error
                    ),
                ),
                Err(why) => (why.clone(), String::new()),
            };
            s.push_str(&format!(
                "| {rig} | {named} | {rms} | {} | {} | {} | {diag} | {ratio} |\n",
                r.scenario,
                cell(&r.pi),
                cell(&r.paper)
            ));
        }
    }
    s
}

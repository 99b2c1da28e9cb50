//! The diagnosis' report: its structure, the summary on stdout and the one
//! function that writes files.

use pam_core::{Effects, Params};
use serde::Serialize;

use super::candidates::CandidateResult;
use super::evaluate::ModelErrors;
use super::regimes::Regimes;

/// One round of candidate selection.
#[derive(Clone, Debug, Serialize)]
pub struct Round {
    /// Held-out RMS of the model the round started from.
    pub rms_start: f64,
    /// Every candidate tried.
    pub candidates: Vec<CandidateResult>,
    /// The effect added, if any earned it.
    pub added: Option<&'static str>,
}

/// One path followed: its effects in order, its held-out error, and
/// whether it was kept.
#[derive(Clone, Debug, Serialize)]
pub struct PathSummary {
    /// Effects in the order added.
    pub effects: Vec<&'static str>,
    /// Held-out RMS contraction error at its end.
    pub rms_heldout: f64,
    /// Whether each of its effects earns its place on top of the others.
    pub kept: bool,
    /// Why not, when not.
    pub why_not: Option<String>,
}

/// One model's errors on the validation record.
#[derive(Clone, Debug, Serialize)]
pub struct ValidationErrors {
    /// RMS of the pressure the model needs to reach each sample's
    /// contraction, minus the measured pressure, MPa.
    pub pressure_rms_mpa: f64,
    /// RMS of the simulated contraction (driven by the measured pressure
    /// and load) minus the measured one.
    pub contraction_rms: f64,
}

/// The diagnosis on a record it was not fitted to.
#[derive(Clone, Debug, Serialize)]
pub struct DiagnoseValidation {
    /// The record.
    pub source: String,
    /// Samples judged: those `fit --validate` judges (on a branch, not
    /// slack).
    pub samples: usize,
    /// The base model (the paper's, refitted).
    pub base: ValidationErrors,
    /// The diagnosed model, its effects in.
    pub model: ValidationErrors,
    /// The diagnosed model's errors per part of the record (its `#
    /// segment` seams: the tests `pam-lab import` joined); empty for a
    /// record of one run.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub segments: Vec<crate::evaluate::segments::SegmentErrors>,
    /// The reference surface ([`crate::identify::reference::ReferenceSurface`]) fitted to every
    /// labelled, loaded sample of the diagnosed record: RMS pressure error
    /// on the same samples, MPa.
    pub reference_rms_mpa: Option<f64>,
    /// Where the diagnosed model has a pressure delay: the reference
    /// surface fitted and judged with each pressure taken that delay
    /// earlier (the same samples), MPa: how much of the model's lead over
    /// the reference is the delay's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_delayed_rms_mpa: Option<f64>,
}

/// What the hold-out's regime cover did for one regime.
#[derive(Clone, Debug, Serialize)]
pub struct HoldoutCover {
    /// The regime (`fast_ramp`, `hold_after_step`).
    pub regime: &'static str,
    /// Training segments moved to the held-out part for it.
    pub segments_moved: usize,
}

/// The outcome of a diagnosis.
#[derive(Clone, Debug, Serialize)]
pub struct DiagnoseReport {
    /// The record diagnosed.
    pub source: String,
    /// The kind of test it is: an isometric record's holds are its
    /// segments, its slack samples judged on nothing.
    pub test_kind: crate::identify::fit::TestKind,
    /// What every RMS of the diagnosis measures: `contraction` (fraction of
    /// rest length), or on an isometric record `pressure (MPa)` (the
    /// pressure the model needs at each held length minus the measured
    /// one).
    pub residual: &'static str,
    /// The noise floor of that residual: `noise.contraction`, or on an
    /// isometric record `noise.pressure_mpa`.
    pub residual_noise: f64,
    /// Effects added, in order (empty: `none`).
    pub effects_added: Vec<&'static str>,
    /// What was named: the first effect added, or `none`.
    pub named: &'static str,
    /// Held-out RMS contraction error of the base model.
    pub rms_before: f64,
    /// The same after the additions.
    pub rms_after: f64,
    /// Measurement noise estimated from the record
    /// ([`crate::evaluate::errors::noise_floor`]); `contraction` is the floor no model
    /// can go below on held-out data.
    pub noise: crate::evaluate::errors::NoiseFloor,
    /// Held-out samples at loads beyond the training loads (their error is
    /// partly the load family's extrapolation).
    pub extrapolated_samples: usize,
    /// Model error above the noise before: `sqrt(rms_before² − noise²)`.
    pub above_noise_before: f64,
    /// The same after the additions.
    pub above_noise_after: f64,
    /// Share of the error above the noise the added effects removed
    /// ([`DiagnoseReport::share_removed`]).
    pub above_noise_removed: f64,
    /// First round's candidates against the base model: name and held-out RMS.
    pub candidates: Vec<CandidateSummary>,
    /// Every round in full, of the path chosen.
    pub rounds: Vec<Round>,
    /// Every path followed (one from each first-round earner, when more
    /// than one earned): its effects, held-out error, and whether it was
    /// kept (`paths.rs`).
    pub paths: Vec<PathSummary>,
    /// The base model's errors.
    pub base: ModelErrors,
    /// The final model's errors.
    pub after: ModelErrors,
    /// Held-out RMS of the paper's model as `fit::fit` gives it, before the
    /// base refit on the simulated record.
    pub rms_paper_fit: f64,
    /// The base model's parameters (after its refit).
    pub base_params: Params,
    /// The final model's base parameters (refitted jointly with its effects).
    pub final_params: Params,
    /// How the model written differs from the path's, when it does: the
    /// path's effects on fit's static model held, and the static model as
    /// `pam-lab fit` writes it for the record (see `static_kept.rs`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_refit: Option<String>,
    /// The closed-loop check of the model written ([`super::closed_loop`]);
    /// `None` where fit refuses the record.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub closed_loop: Option<super::closed_loop::ClosedLoopCheck>,
    /// On an isometric record: how much later the final model's pressure
    /// follows the measured pressure best ([`super::lag`]), over every
    /// sample judged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pressure_lag: Option<super::lag::PressureLag>,
    /// The final model's effects.
    pub effects: Effects,
    /// The effects the base model carries (none: the static shape is a
    /// candidate like the others).
    #[serde(skip)]
    pub base_effects: Effects,
    /// The base and final models on another record of the muscle
    /// (`--validate`), in pressure, beside the reference surface.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation: Option<DiagnoseValidation>,
    /// The record's top pressure, MPa (the training part's, through a
    /// 9-sample average, as `fit` measures `Pmax`), where `Pmax` started
    /// when it was measured (the joint refit may raise it: a loop still
    /// open at the record's top closes above it); `None` when `--pmax` gave
    /// it (held).
    pub pmax_record_top_mpa: Option<f64>,
    /// `Pmax` refitted went to its ceiling ([`super::refit::PMAX_CEILING_OF_TOP`]
    /// times the record's top): the record does not say where the loop
    /// closes, and the diagnosis was made again with `Pmax` at the top.
    pub pmax_at_ceiling: bool,
    /// Samples held out and trained on.
    pub heldout_samples: usize,
    /// Training samples.
    pub train_samples: usize,
    /// Correlation length of the base residual, samples.
    pub correlation_length: f64,
    /// The evidence rule's thresholds.
    pub min_improvement: f64,
    /// BIC threshold.
    pub min_bic_drop: f64,
    /// What the record leaves open about the model it ends with
    /// ([`super::warnings::model_warnings`]), one sentence each.
    pub warnings: Vec<String>,
    /// Segments the hold-out moved to the held-out part so that a regime
    /// the pressure decides is held out too ([`crate::record::split::cover_regime`]).
    pub holdout_cover: Vec<HoldoutCover>,
    /// The base model's prediction of the quantity the residual measures
    /// (`residual`): the contraction, or on an isometric record the
    /// pressure each held length takes (not serialised).
    #[serde(skip)]
    pub predicted_base: Vec<f64>,
    /// The final model's (not serialised).
    #[serde(skip)]
    pub predicted_after: Vec<f64>,
    /// Held-out mask (not serialised).
    #[serde(skip)]
    pub heldout: Vec<bool>,
    /// Regimes (not serialised).
    #[serde(skip)]
    pub regimes: Regimes,
}

impl DiagnoseReport {
    /// Share of the model error above the noise that the added effects
    /// removed: `1 − above_noise_after / above_noise_before` (0 when the
    /// base is already at the noise).
    pub fn share_removed(&self) -> f64 {
        self.above_noise_removed
    }
}

/// A candidate's name and held-out RMS (first round).
#[derive(Clone, Debug, Serialize)]
pub struct CandidateSummary {
    /// Effect name.
    pub name: &'static str,
    /// Held-out RMS contraction error with it added to the base model.
    pub rms: f64,
}

/// Relative rise of `Pmax` over the record's top that the summary reports
/// (a smaller one is within what the refit moves it on a loop that does
/// close at the top: up to 0.3 % on the no-effect plants and example_1).
const PMAX_MOVED: f64 = 0.01;

/// A short summary a person can read.
pub fn summary(r: &DiagnoseReport) -> String {
    let mut s = String::new();
    let pct = |x: f64| 100.0 * x;
    s.push_str(&format!(
        "diagnose {}: {} training / {} held-out samples (one segment in 3 held out: cycles cut at {}, drawn)\n",
        r.source,
        r.train_samples,
        r.heldout_samples,
        match r.test_kind {
            crate::identify::fit::TestKind::Isometric =>
                "changes of the held length; slack samples in neither part",
            _ => "load changes",
        }
    ));
    for c in r.holdout_cover.iter().filter(|c| c.segments_moved > 0) {
        s.push_str(&format!(
            "  {} more segment(s) held out so that the {} regime is held out too\n",
            c.segments_moved, c.regime
        ));
    }
    s.push_str(&format!(
        "base model (paper): held-out RMS {} error {:.5}\n",
        r.residual, r.rms_before
    ));
    if r.extrapolated_samples > 0 {
        s.push_str(&format!(
            "  {} held-out samples lie beyond the training loads: their error includes the load family's extrapolation\n",
            r.extrapolated_samples
        ));
    }
    let worst = r
        .base
        .regimes
        .iter()
        .filter(|g| g.samples > 0)
        .max_by(|a, b| a.rms.total_cmp(&b.rms));
    if let Some(w) = worst {
        s.push_str(&format!(
            "  largest disagreement: {} (RMS {:.5} over {} held-out samples)\n",
            w.regime, w.rms, w.samples
        ));
    }
    for (k, round) in r.rounds.iter().enumerate() {
        s.push_str(&format!(
            "round {}: candidates against RMS {:.5}\n",
            k + 1,
            round.rms_start
        ));
        for c in &round.candidates {
            s.push_str(&format!(
                "  {:<22} RMS {:.5}  ({:+.1} %, BIC drop {:>8.1}, {} in {}: {}){}\n",
                c.name,
                c.rms,
                -pct(c.improvement),
                c.bic_drop,
                c.parameters,
                c.signature.regime,
                if c.signature.rms_before.is_finite() && c.signature.rms_after.is_finite() {
                    format!(
                        "{:.5} -> {:.5}",
                        c.signature.rms_before, c.signature.rms_after
                    )
                } else {
                    "no held-out samples there".to_string()
                },
                if c.earned { "  earns it" } else { "" }
            ));
            s.push_str(&format!("      {}\n", c.verdict));
            if let Some(v) = &c.variants {
                s.push_str(&format!("      {v}\n"));
            }
        }
        match round.added {
            Some(n) => s.push_str(&format!("  -> added {n}\n")),
            None => s.push_str("  -> no candidate earns its parameters\n"),
        }
    }
    if !r.paths.is_empty() {
        s.push_str("paths followed (one from each first-round earner):\n");
        for p in &r.paths {
            let name = if p.effects.is_empty() {
                "none".to_string()
            } else {
                p.effects.join(" then ")
            };
            s.push_str(&format!("  {:<46} RMS {:.5}", name, p.rms_heldout));
            match &p.why_not {
                Some(why) => s.push_str(&format!("  not kept: {why}\n")),
                None if p.effects == r.effects_added => s.push_str("  <- chosen\n"),
                None => s.push('\n'),
            }
        }
    }
    s.push_str(&format!(
        "named first: {}; effects added, in order: [{}]\nheld-out RMS {:.5} -> {:.5} ({:.1} % lower)\n",
        r.named,
        r.effects_added.join(", "),
        r.rms_before,
        r.rms_after,
        pct(1.0 - r.rms_after / r.rms_before)
    ));
    s.push_str(&format!(
        "noise floor {:.5} (from {} slow samples); error above it {:.5} -> {:.5} ({:.1} % removed)\n",
        r.residual_noise,
        r.noise.samples,
        r.above_noise_before,
        r.above_noise_after,
        pct(r.share_removed())
    ));
    if let Some(note) = &r.final_refit {
        s.push_str(note);
        s.push('\n');
    }
    if let Some(c) = &r.closed_loop {
        s.push_str(&closed_loop_lines(c));
    }
    if let Some(lag) = &r.pressure_lag {
        s.push_str(&lag_line(
            lag,
            r.min_improvement,
            r.effects.pressure_lag.is_some(),
        ));
    }
    if r.pmax_at_ceiling {
        s.push_str(&format!(
            "Pmax held at the record's top: refitted, it went to its ceiling ({:.2}x the top), so the record does not say where the loop closes\n",
            super::refit::PMAX_CEILING_OF_TOP
        ));
    }
    if let Some(top) = r.pmax_record_top_mpa {
        let pmax = f64::from(r.final_params.points.max_pressure_mpa);
        if pmax > top * (1.0 + PMAX_MOVED) {
            s.push_str(&format!(
                "Pmax refitted {top:.4} -> {pmax:.4} MPa: the loop is still open at the record's top pressure and closes above it (the model extrapolates there; the firmware commands no more than its `max_command_mpa`)\n"
            ));
        }
    }
    if let Some(v) = &r.validation {
        let kpa = |mpa: f64| 1000.0 * mpa;
        s.push_str(&format!(
            "validation on {} ({} samples), pressure RMS: base model {:.1} kPa, diagnosed model {:.1} kPa",
            v.source,
            v.samples,
            kpa(v.base.pressure_rms_mpa),
            kpa(v.model.pressure_rms_mpa)
        ));
        if let Some(r) = v.reference_rms_mpa {
            s.push_str(&format!(
                ", reference surface {:.1} kPa ({:.2}x)",
                kpa(r),
                v.model.pressure_rms_mpa / r
            ));
        }
        match v.reference_delayed_rms_mpa {
            Some(r) => s.push_str(&format!(
                "; the reference surface with the model's pressure delay {:.1} kPa ({:.2}x)\n",
                kpa(r),
                v.model.pressure_rms_mpa / r
            )),
            None => s.push('\n'),
        }
        s.push_str(&crate::evaluate::segments::segments_report(
            &v.segments,
            r.test_kind == crate::identify::fit::TestKind::Isometric,
        ));
    }
    for w in &r.warnings {
        s.push_str(&format!("warning: {w}\n"));
    }
    s
}

/// The summary's lines on the closed-loop check: each run and the
/// verdict.
fn closed_loop_lines(c: &super::closed_loop::ClosedLoopCheck) -> String {
    let run = |t: &super::closed_loop::LoopTracking| match &t.first_fault {
        Some(f) => format!("{:.5} (safe state: {f})", t.rms_error),
        None => format!("{:.5}", t.rms_error),
    };
    let mut s = String::from(
        "closed loop: the firmware's controller on a simulated muscle that is the diagnosed model, \
         over the middle of its stroke (RMS error after the start)\n",
    );
    for r in &c.runs {
        s.push_str(&format!(
            "  {:>5.0} N, {:<15} {:.3}-{:.3}: diagnosed model {}, fit's model {}\n",
            r.load_n,
            r.setpoint,
            r.low,
            r.high,
            run(&r.diagnosed),
            run(&r.fit)
        ));
    }
    for why in &c.skipped {
        s.push_str(&format!("  {why}\n"));
    }
    s.push_str(&format!(
        "  -> {}: {}\n",
        if c.accepted { "accepted" } else { "refused" },
        c.verdict
    ));
    s
}

/// The summary's line on the lag between the measured pressure and the
/// model's ([`super::lag`]); a hint when shifting removes at least
/// `min_cut` of the RMS and the model has no pressure lag.
fn lag_line(lag: &super::lag::PressureLag, min_cut: f64, modelled: bool) -> String {
    let ms = 1000.0 * lag.lag_s;
    let mut line = format!(
        "timing: the model's pressure matches the pressure measured {ms:.0} ms earlier best \
         (RMS {:.5} -> {:.5} MPa, {:.1} % lower, over {} samples)",
        lag.rms_unshifted_mpa,
        lag.rms_at_lag_mpa,
        100.0 * lag.cut(),
        lag.samples
    );
    if !modelled && lag.lag_s > 0.0 && lag.cut() >= min_cut {
        line.push_str(
            ": the muscle answers its pressure late (a tube, the bladder's volume, a sensor's \
             filter), which the model written leaves out",
        );
    }
    line.push('\n');
    line
}

//! A user's record on the accuracy × instructions plane: the model `fit`
//! writes and the Preisach model, each identified on the record's training
//! cycles and scored on its held-out ones, beside the instructions each
//! costs on the chip (bench-m4's measured counts), and which one pam would
//! flash and why (`pam-lab compare`).

use pam_core::effects::memory::MEMORY_DEPTH;
use pam_core::{Effects, Simulator, TrackerConfig};
use serde::Serialize;

use crate::identify::fit::{self, FitConfig, FitReport, TestKind};
use crate::identify::preisach;
use crate::record::{Record, Sample};

/// bench-m4's measured instruction counts (`bench-m4/run.sh --update`
/// writes them; its README has how they are counted).
const BENCH_COUNTS: &str = include_str!("../../../bench-m4/baseline.tsv");

/// Most instructions one controller period may take on its slowest path
/// (bench-m4's check, issue 30).
const BUDGET: u32 = 2000;

/// One model on the plane.
#[derive(Clone, Debug, Serialize)]
pub struct Entry {
    /// What it is.
    pub model: String,
    /// Held-out RMS contraction error (fraction of rest length).
    pub heldout_rms: f64,
    /// Training RMS contraction error.
    pub training_rms: f64,
    /// bench-m4's call measured for its per-sample forward step.
    pub bench_call: &'static str,
    /// Instructions of that call on the Cortex-M4F: mean and worst.
    pub instructions_mean: f64,
    /// Worst count of the call.
    pub instructions_max: u32,
    /// Whether pam can flash it today (a blob the firmware boots and
    /// runs as its feedforward).
    pub flashable: bool,
}

/// The comparison on one record.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Training samples (outside the held-out cycles).
    pub training_samples: usize,
    /// Held-out samples.
    pub heldout_samples: usize,
    /// The models, fit's first.
    pub entries: Vec<Entry>,
    /// Index into `entries` of the model pam would flash.
    pub chosen: usize,
    /// Why.
    pub why: String,
}

/// `(mean, max)` of a bench-m4 call.
fn counts(call: &str) -> Option<(f64, u32)> {
    BENCH_COUNTS.lines().find_map(|l| {
        let mut f = l.split('\t');
        (f.next()? == call).then_some(())?;
        Some((f.next()?.parse().ok()?, f.next()?.parse().ok()?))
    })
}

/// RMS of `predicted − measured` over the samples `keep` selects.
fn rms(samples: &[Sample], predicted: &[f64], keep: impl Fn(usize) -> bool) -> f64 {
    let (sq, n) = samples
        .iter()
        .zip(predicted)
        .enumerate()
        .filter(|(i, (s, x))| keep(*i) && s.contraction.is_finite() && x.is_finite())
        .fold((0.0, 0usize), |(sq, n), (_, (s, x))| {
            (sq + (x - s.contraction).powi(2), n + 1)
        });
    (sq / n.max(1) as f64).sqrt()
}

/// fit's model driven by the measured pressure and load, as the chip
/// would run it forward (pam-core's `Simulator` with fit's static shape).
fn fit_predictions(rep: &FitReport, samples: &[Sample]) -> Result<Vec<f64>, String> {
    let effects = Effects {
        shape: rep.constraint_shape,
        ..Effects::NONE
    };
    let first = samples.first().ok_or("the record has no samples")?;
    let mut sim = Simulator::<MEMORY_DEPTH>::new(
        rep.coeffs,
        effects,
        TrackerConfig::DEFAULT_PRESSURE,
        first.load_n as f32,
    )
    .map_err(|e| format!("pam-core refuses fit's model: {e}"))?;
    Ok(samples
        .iter()
        .map(|s| f64::from(sim.step(s.t_s as f32, s.pressure_mpa as f32, s.load_n as f32)))
        .collect())
}

/// Fit's model and the Preisach model on `record`, split as `cfg.holdout`
/// says (fit's split: whole pressure cycles held out), and the choice.
/// Refused for an isometric record (both predict contraction from pressure
/// at a hung load) and where either identification fails.
pub fn compare(record: &Record, cfg: &FitConfig) -> Result<Comparison, String> {
    let rep = fit::fit(record, cfg).map_err(|e| format!("fit: {e}"))?;
    if rep.test_kind == TestKind::Isometric {
        return Err(
            "compare needs an isotonic record (a hung load, the contraction \
                    measured): both models predict contraction from pressure"
                .into(),
        );
    }
    let samples = &record.samples;
    let heldout = &rep.heldout;
    if !heldout.iter().any(|h| *h) {
        return Err(
            "no held-out cycle: compare scores each model on held-out cycles \
                    (use --holdout every:K or tail:F)"
                .into(),
        );
    }
    let grid = preisach::Grid::for_record(samples)
        .ok_or("the record has no positive pressure: no Preisach grid")?;
    let table = preisach::identify(samples, heldout, &grid)?;
    let predictions = [
        fit_predictions(&rep, samples)?,
        preisach::predict(&table, samples),
    ];
    let bench_calls = ["fit_model_step", "preisach16_step"];
    let names = [
        "fit's model (the paper's, its static shape)".to_string(),
        format!(
            "Preisach {r} x {r} ({} relays), {} loads",
            preisach::ROWS * (preisach::ROWS + 1) / 2,
            preisach::LOADS,
            r = preisach::ROWS
        ),
    ];
    let mut entries = Vec::new();
    for ((model, predicted), (call, flashable)) in names
        .into_iter()
        .zip(&predictions)
        .zip(bench_calls.into_iter().zip([true, false]))
    {
        let (mean, max) =
            counts(call).ok_or_else(|| format!("bench-m4/baseline.tsv has no `{call}`"))?;
        entries.push(Entry {
            model,
            heldout_rms: rms(samples, predicted, |i| heldout[i]),
            training_rms: rms(samples, predicted, |i| !heldout[i]),
            bench_call: call,
            instructions_mean: mean,
            instructions_max: max,
            flashable,
        });
    }
    let (fit_e, pr) = (&entries[0], &entries[1]);
    let ratio = pr.heldout_rms / fit_e.heldout_rms;
    let far = counts("preisach16_feedforward_far").map_or(0, |c| c.1);
    let why = if ratio < 1.0 {
        format!(
            "fit's model is the most accurate model pam can flash. The Preisach model \
             predicts this record's held-out cycles {:.0} % better ({:.5} against {:.5}) at \
             {:.0} instructions a sample against {:.0} (its feedforward's slowest period, a \
             move across the whole range: {far}, {} the controller's budget of {BUDGET}), \
             but no blob or firmware path carries it yet",
            100.0 * (1.0 - ratio),
            pr.heldout_rms,
            fit_e.heldout_rms,
            pr.instructions_mean,
            fit_e.instructions_mean,
            if far <= BUDGET { "within" } else { "over" },
        )
    } else {
        format!(
            "fit's model is the most accurate model on this record's held-out cycles \
             ({:.5} against the Preisach model's {:.5}), and pam can flash it",
            fit_e.heldout_rms, pr.heldout_rms
        )
    };
    Ok(Comparison {
        training_samples: heldout.iter().filter(|h| !**h).count(),
        heldout_samples: heldout.iter().filter(|h| **h).count(),
        entries,
        chosen: 0,
        why,
    })
}

/// The comparison as the command prints it.
pub fn text(c: &Comparison, source: &str) -> String {
    let mut s = format!(
        "compare {source}: {} training / {} held-out samples (whole pressure cycles held out)\n",
        c.training_samples, c.heldout_samples
    );
    s += &format!(
        "  {:<44} {:>12} {:>13}  instructions mean / max (bench-m4 call)  flashable\n",
        "model", "held-out RMS", "training RMS"
    );
    for e in &c.entries {
        s += &format!(
            "  {:<44} {:>12.5} {:>13.5}  {:>5.0} / {:<5} ({})  {}\n",
            e.model,
            e.heldout_rms,
            e.training_rms,
            e.instructions_mean,
            e.instructions_max,
            e.bench_call,
            if e.flashable { "yes" } else { "not yet" }
        );
    }
    s += &format!(
        "pam would flash: {}. {}.\n",
        c.entries.get(c.chosen).map_or("", |e| e.model.as_str()),
        c.why
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bench_counts_name_both_models() {
        for call in [
            "fit_model_step",
            "preisach16_step",
            "preisach16_feedforward_far",
        ] {
            let (mean, max) = counts(call).unwrap();
            assert!(mean > 0.0 && f64::from(max) >= mean, "{call}");
        }
        assert!(counts("no_such_call").is_none());
    }
}

//! A user's record on the accuracy × instructions plane: the model `fit`
//! writes and the Preisach model, each identified on the record's training
//! cycles and scored on its held-out ones, beside the instructions each
//! costs on the chip (bench-m4's measured counts), and which one pam would
//! flash and why (`pam-lab compare`).

use pam_core::{Effects, TrackerConfig};
use serde::Serialize;

use crate::evaluate::simulate::{run_record, InverseTables};
use crate::identify::fit::{self, FitConfig, FitReport, Holdout, TestKind};
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
    /// Held-out RMS at the loads left out of a second training (`None`
    /// when the record has too few loads to leave one out).
    pub heldout_loads_rms: Option<f64>,
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
    /// The loads left out of the second training, N (the interior loads
    /// at every other place, as bench-m4 leaves out 300 and 500 N of
    /// 100–600 N); empty when the record has fewer than three loads.
    pub heldout_loads_n: Vec<f64>,
    /// The models, fit's first.
    pub entries: Vec<Entry>,
    /// Index into `entries` of the model pam would flash.
    pub chosen: usize,
    /// The Preisach table identified on the training cycles (written as
    /// `preisach.blob`, not into the JSON).
    #[serde(skip)]
    pub preisach: preisach::Table,
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
/// would run it forward: pam-lab's one record simulator ([`run_record`],
/// pam-core's `Simulator` with fit's static shape).
fn fit_predictions(rep: &FitReport, samples: &[Sample]) -> Result<Vec<f64>, String> {
    let effects = Effects {
        shape: rep.constraint_shape,
        ..Effects::NONE
    };
    let mut out = vec![f64::NAN; samples.len()];
    let ran = run_record(
        &rep.coeffs,
        &effects,
        TrackerConfig::DEFAULT_PRESSURE,
        samples,
        None,
        InverseTables::AtEachSwitch,
        |i, _, x| out[i] = f64::from(x),
    );
    if !ran {
        return Err("pam-core refuses fit's model".into());
    }
    Ok(out)
}

/// Loads closer than this (N) are one load of the record (its noise and
/// drift; a characterisation steps its loads by tens of newtons at least).
const LOAD_LEVEL_GAP_N: f64 = 10.0;

/// The record's loads (the means of its load levels, sorted) and each
/// sample's level.
fn load_levels(samples: &[Sample]) -> (Vec<f64>, Vec<Option<usize>>) {
    let mut sorted: Vec<f64> = samples
        .iter()
        .map(|s| s.load_n)
        .filter(|l| l.is_finite())
        .collect();
    sorted.sort_by(f64::total_cmp);
    let mut groups: Vec<(f64, usize)> = Vec::new();
    let mut last = f64::NEG_INFINITY;
    for l in sorted {
        match groups.last_mut() {
            Some((sum, n)) if l - last <= LOAD_LEVEL_GAP_N => {
                *sum += l;
                *n += 1;
            }
            _ => groups.push((l, 1)),
        }
        last = l;
    }
    let levels: Vec<f64> = groups.iter().map(|(sum, n)| sum / *n as f64).collect();
    let level_of = samples
        .iter()
        .map(|s| {
            levels
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1 - s.load_n).abs().total_cmp(&(b.1 - s.load_n).abs()))
                .map(|(i, _)| i)
                .filter(|_| s.load_n.is_finite())
        })
        .collect();
    (levels, level_of)
}

/// The loads left out (every other interior load: places 2, 4, … short of
/// the last, or the middle of three) and the mask of their samples; `None`
/// with fewer than three loads.
fn left_out_loads(samples: &[Sample]) -> Option<(Vec<f64>, Vec<bool>)> {
    let (levels, level_of) = load_levels(samples);
    let l = levels.len();
    let out: Vec<usize> = match l {
        0..=2 => return None,
        3 => vec![1],
        _ => (2..l - 1).step_by(2).collect(),
    };
    let mask = level_of
        .iter()
        .map(|lv| lv.is_some_and(|i| out.contains(&i)))
        .collect();
    Some((out.iter().map(|&i| levels[i]).collect(), mask))
}

/// Fit's model and the Preisach model trained without the samples of
/// `mask`, their contraction predicted over the whole record.
fn predictions_without(
    record: &Record,
    mask: &[bool],
    cfg: &FitConfig,
    grid: &preisach::Grid,
) -> Result<[Vec<f64>; 2], String> {
    let samples = &record.samples;
    let kept: Vec<Sample> = samples
        .iter()
        .zip(mask)
        .filter(|(_, &m)| !m)
        .map(|(s, _)| *s)
        .collect();
    let training = Record::from_samples(
        format!("{} without its left-out loads", record.source),
        kept,
    );
    let cfg = FitConfig {
        holdout: Holdout::None,
        ..cfg.clone()
    };
    let rep =
        fit::fit(&training, &cfg).map_err(|e| format!("fit without the left-out loads: {e}"))?;
    let table = preisach::identify(samples, mask, grid)?;
    Ok([
        fit_predictions(&rep, samples)?,
        preisach::predict(&table, samples),
    ])
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
    // The second comparison: loads the models were not trained at.
    let left_out = left_out_loads(samples);
    let without = match &left_out {
        Some((_, mask)) => Some((mask, predictions_without(record, mask, cfg, &grid)?)),
        None => None,
    };
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
    for (k, ((model, predicted), (call, flashable))) in names
        .into_iter()
        .zip(&predictions)
        .zip(bench_calls.into_iter().zip([true, true]))
        .enumerate()
    {
        let (mean, max) =
            counts(call).ok_or_else(|| format!("bench-m4/baseline.tsv has no `{call}`"))?;
        entries.push(Entry {
            model,
            heldout_rms: rms(samples, predicted, |i| heldout[i]),
            training_rms: rms(samples, predicted, |i| !heldout[i]),
            heldout_loads_rms: without
                .as_ref()
                .map(|(mask, p)| rms(samples, &p[k], |i| mask[i])),
            bench_call: call,
            instructions_mean: mean,
            instructions_max: max,
            flashable,
        });
    }
    let (fit_e, pr) = (&entries[0], &entries[1]);
    let far = counts("preisach16_feedforward_far").map_or(0, |c| c.1);
    // The Preisach model is flashed where it is the more accurate on both
    // held-out sets: a table per load interpolates between its loads,
    // where the paper's load family was made to (a record with too few
    // loads to leave one out is judged on its cycles alone), and its
    // slowest feedforward period is within the controller's budget.
    let better_cycles = pr.heldout_rms < fit_e.heldout_rms;
    let better_loads = match (pr.heldout_loads_rms, fit_e.heldout_loads_rms) {
        (Some(p), Some(f)) => p < f,
        _ => true,
    };
    let loads_text = |e: &Entry| {
        e.heldout_loads_rms
            .map_or_else(String::new, |v| format!(", {v:.5} at the held-out loads"))
    };
    let chosen = usize::from(better_cycles && better_loads && far <= BUDGET);
    let why = if chosen == 1 {
        format!(
            "The Preisach model predicts this record's held-out cycles {:.0} % better \
             ({:.5} against {:.5}{}{}) at {:.0} instructions a sample against {:.0} (its \
             feedforward's slowest period, a move across the whole range: {far}, within the \
             controller's budget of {BUDGET}); flash its blob, preisach.blob, as \
             PAM_COEFFS_BLOB (firmware/README.md). This compares predictions; how each \
             tracks in a closed loop is host-sim's (host-sim/README.md)",
            100.0 * (1.0 - pr.heldout_rms / fit_e.heldout_rms),
            pr.heldout_rms,
            fit_e.heldout_rms,
            loads_text(pr),
            fit_e
                .heldout_loads_rms
                .map_or_else(String::new, |v| format!(" against {v:.5}")),
            pr.instructions_mean,
            fit_e.instructions_mean,
        )
    } else {
        format!(
            "fit's model is the more accurate on this record's held-out {} ({:.5}{} against \
             the Preisach model's {:.5}{}), with fewer parameters; flash its model.blob",
            if better_cycles { "loads" } else { "cycles" },
            fit_e.heldout_rms,
            loads_text(fit_e),
            pr.heldout_rms,
            loads_text(pr),
        )
    };
    Ok(Comparison {
        training_samples: heldout.iter().filter(|h| !**h).count(),
        heldout_samples: heldout.iter().filter(|h| **h).count(),
        heldout_loads_n: left_out.map_or_else(Vec::new, |(l, _)| l),
        entries,
        chosen,
        preisach: table,
        why,
    })
}

/// The comparison as the command prints it.
pub fn text(c: &Comparison, source: &str) -> String {
    let mut s = format!(
        "compare {source}: {} training / {} held-out samples (whole pressure cycles held out)\n",
        c.training_samples, c.heldout_samples
    );
    if !c.heldout_loads_n.is_empty() {
        let loads: Vec<String> = c
            .heldout_loads_n
            .iter()
            .map(|l| format!("{l:.0}"))
            .collect();
        s += &format!(
            "  and trained again without the loads {} N, scored there (held-out loads)\n",
            loads.join(", ")
        );
    }
    s += &format!(
        "  {:<44} {:>12} {:>14} {:>13}  instructions mean / max (bench-m4 call)  flashable\n",
        "model", "held-out RMS", "held-out loads", "training RMS"
    );
    for e in &c.entries {
        let loads = e
            .heldout_loads_rms
            .map_or_else(|| "-".to_string(), |v| format!("{v:.5}"));
        s += &format!(
            "  {:<44} {:>12.5} {:>14} {:>13.5}  {:>5.0} / {:<5} ({})  {}\n",
            e.model,
            e.heldout_rms,
            loads,
            e.training_rms,
            e.instructions_mean,
            e.instructions_max,
            e.bench_call,
            if e.flashable { "yes" } else { "no" }
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

    fn at(load_n: f64) -> Sample {
        Sample {
            t_s: 0.0,
            load_n,
            pressure_mpa: 0.1,
            contraction: 0.05,
        }
    }

    #[test]
    fn every_other_interior_load_is_left_out() {
        let loads = |ls: &[f64]| -> Vec<Sample> {
            ls.iter()
                .flat_map(|&l| [at(l - 2.0), at(l), at(l + 3.0)])
                .collect()
        };
        let six = loads(&[100.0, 200.0, 300.0, 400.0, 500.0, 600.0]);
        let (out, mask) = left_out_loads(&six).unwrap();
        let rounded: Vec<f64> = out.iter().map(|l| l.round()).collect();
        assert_eq!(rounded, [300.0, 500.0]);
        assert_eq!(mask.iter().filter(|m| **m).count(), 6);
        let (out, _) = left_out_loads(&loads(&[100.0, 250.0, 400.0])).unwrap();
        assert_eq!(out.len(), 1);
        assert!((out[0] - 250.0).abs() < 2.0);
        assert!(left_out_loads(&loads(&[100.0, 300.0])).is_none());
        assert!(left_out_loads(&[at(f64::NAN)]).is_none());
    }

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

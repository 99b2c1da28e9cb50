//! The commands of `pam-lab` as library functions: what the binary
//! runs, and what the fuzz targets (`fuzz/fuzz_targets/fit_record.rs`,
//! `diagnose_record.rs`) run, so both reach the same code.
//!
//! Each command is split the same way:
//! 1. options validated ([`fit::FitConfig::validate`],
//!    [`TrackerConfig::validate`]) before anything is read;
//! 2. the record read and checked for the command ([`read_record`]:
//!    located errors, record-level checks);
//! 3. the work ([`fit_record`], [`diagnose_record`], [`simulate_record`],
//!    [`adapt_model`]),
//!    whose outputs are bytes in memory;
//! 4. the outputs staged into one [`OutputSet`] ([`stage_fit`],
//!    [`stage_diagnose`]) and committed together by the caller.

use std::fmt::Write as _;
use std::io::Read;
use std::path::Path;

use pam_core::{Coeffs, TrackerConfig};

use crate::evaluate::simulate::{self, SimSample};
use crate::export::model_file::{self, FitSummary, LoadedModel};
use crate::identify::diagnose::{self, DiagnoseConfig, DiagnoseError, DiagnoseReport};
use crate::identify::fit::{self, FitConfig, FitError, FitReport, Progress};
use crate::output::OutputSet;
use crate::record::{self, num, num32, DataError, Purpose, Record};

/// Read `path` and check it for `purpose` ([`record::read_csv`], then
/// [`record::check_record`], and for `diagnose` [`check_load_blocks`]).
pub fn read_record(path: &Path, purpose: Purpose) -> Result<Record, DataError> {
    let record = record::read_csv(path)?;
    check(&record, purpose)?;
    Ok(record)
}

/// [`read_record`] from any reader; `source` names it in errors.
pub fn parse_record<R: Read>(
    source: &str,
    reader: R,
    purpose: Purpose,
) -> Result<Record, DataError> {
    let record = record::parse_csv(source, reader)?;
    check(&record, purpose)?;
    Ok(record)
}

fn check(record: &Record, purpose: Purpose) -> Result<(), DataError> {
    record::check_record(record, purpose)?;
    if purpose == Purpose::Diagnose {
        check_load_blocks(record)?;
    }
    Ok(())
}

/// `diagnose` cuts its hold-out at load changes
/// ([`crate::record::split::holdout_by_load_block`]), or on an isometric
/// record at changes of the held length; a record whose load changes
/// between most samples and whose length is not held (a noisy load cell on
/// an isotonic rig) has no such blocks: refused before the work, with the
/// reason.
pub fn check_load_blocks(record: &Record) -> Result<(), DataError> {
    if fit::detect_test(&record.samples) == fit::TestKind::Isometric {
        return Ok(());
    }
    let loads: Vec<f64> = record.samples.iter().map(|s| s.load_n).collect();
    let mask = crate::record::split::holdout_by_load_block(&loads);
    let blocks = 1 + mask.windows(2).filter(|w| w[0] != w[1]).count();
    let mean_len = record.len() as f64 / blocks as f64;
    if blocks > 1 && mean_len < 50.0 {
        return Err(DataError {
            file: record.source.clone(),
            line: 0,
            column: Some("load_n".into()),
            kind: record::DataErrorKind::TooFewSamples(format!(
                "diagnose holds out whole stretches of one load (within 1 N), but the load \
                 changes so often that the {} samples make {blocks} stretches of {:.1} samples \
                 on average: it needs a record that holds its load (isotonic, the hung load \
                 logged) or its length (isometric); a noisy load cell cannot be split so",
                record.len(),
                mean_len
            )),
        });
    }
    Ok(())
}

/// A finished fit and the files it makes.
#[derive(Debug)]
pub struct FitOutcome {
    /// The fit.
    pub report: FitReport,
    /// `model.json`, `model.blob`, `model_params.rs`: `(file name, bytes)`.
    pub files: Vec<(&'static str, Vec<u8>)>,
    /// Training samples used.
    pub training_samples: usize,
    /// The model and its reference surface on the `--validate` record.
    pub validation: Option<fit::Validation>,
}

/// `pam-lab fit`'s work: fit `record` (checked by [`read_record`]) with
/// `cfg` (validated) and make the model files. Every file is checked to read
/// back: the blob decodes, the JSON parses to the same parameters.
pub fn fit_record(
    record: &Record,
    cfg: &FitConfig,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<FitOutcome, FitError> {
    fit_and_validate(record, None, cfg, progress)
}

/// [`fit_record`], and the model and its reference surface evaluated on
/// `validation`, a record of the same muscle neither was fitted to (its
/// figures in the report and in `model.json`).
pub fn fit_and_validate(
    record: &Record,
    validation: Option<&Record>,
    cfg: &FitConfig,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<FitOutcome, FitError> {
    cfg.validate()?;
    let report = fit::fit_with_progress(record, cfg, progress)?;
    let training_samples = report.training_samples(&record.samples);
    let any_heldout = report.heldout.iter().any(|h| *h);
    let validated = validation.map(|v| fit::validate(&report, v, cfg));
    let summary = FitSummary {
        source: record.source.clone(),
        samples: record.len(),
        training_samples,
        holdout: report.holdout.to_string(),
        max_pressure_source: format!("{:?}", report.pmax_source).to_lowercase(),
        pressure_noise_mpa: report.split.pressure_noise_mpa,
        contraction_noise: report.split.contraction_noise,
        heldout_errors: any_heldout.then(|| report.test.clone()),
        reference_heldout_rms_mpa: report.reference_test_rms_mpa.filter(|_| any_heldout),
        validation: validated.clone(),
        segments: report.segments.clone(),
    };
    let origin = format!("pam-lab fit {} --holdout {}", record.source, report.holdout);
    let files = model_file::model_files(&report.params, &report.effects(), Some(summary), &origin)
        .map_err(|e| FitError::Export {
            source_name: record.source.clone(),
            why: e.to_string(),
        })?;
    Ok(FitOutcome {
        report,
        files,
        training_samples,
        validation: validated,
    })
}

/// Stage `fit`'s files in `dir`; `fit.png` too when `draw`.
pub fn stage_fit(
    set: &mut OutputSet,
    dir: &Path,
    outcome: &FitOutcome,
    record: &Record,
    cfg: &FitConfig,
    draw: bool,
) -> anyhow::Result<()> {
    set.into_dir(dir)?;
    for (name, bytes) in &outcome.files {
        set.add_bytes(&dir.join(name), bytes)?;
    }
    if draw {
        let r = &outcome.report;
        set.add_via_path(&dir.join("fit.png"), |p| {
            let slack = fit::slack_mask(&record.samples, r.test_kind);
            crate::report::plot::fit_plot(
                p,
                &crate::report::plot::FitPlot {
                    record,
                    split: &r.split,
                    heldout: &r.heldout,
                    slack: &slack,
                    coeffs: &r.coeffs,
                    shape: r.constraint_shape.as_ref(),
                    test: r.test_kind,
                    load_bin_n: cfg.load_bin_n,
                },
            )
        })?;
    }
    Ok(())
}

/// The report `pam-lab fit` prints.
pub fn fit_text(outcome: &FitOutcome, record: &Record, cfg: &FitConfig) -> String {
    let report = &outcome.report;
    let p = &report.params;
    let any_heldout = report.heldout.iter().any(|h| *h);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "model of {} ({} samples, {} for training, held out: {})",
        record.source,
        record.len(),
        outcome.training_samples,
        report.holdout
    );
    let _ = writeln!(
        out,
        "  loads {}..{} N, step {} N; Pmax {} MPa ({:?})",
        num32(p.min_load_n),
        num32(p.max_load_n),
        num32(p.load_step_n),
        num32(p.points.max_pressure_mpa),
        report.pmax_source
    );
    let _ = writeln!(
        out,
        "  R1 {:.5}  Rx1 {:.5}  tangency ({:.5}, {:.5} MPa)  inflection ({:.5}, {:.5} MPa)",
        p.points.root_contraction,
        p.points.max_contraction,
        p.points.tangency.contraction,
        p.points.tangency.pressure_mpa,
        p.points.inflection.contraction,
        p.points.inflection.pressure_mpa
    );
    let _ = writeln!(
        out,
        "  RG_L {:.6}  RG_U {:.6}  GR_c {:.5}  be {:.5} MPa",
        p.root_regression_per_step,
        p.max_regression_per_step,
        p.c_growth_per_step,
        p.ellipse_height_mpa
    );
    let _ = writeln!(
        out,
        "  noise estimate: pressure {:.5} MPa, contraction {:.5}",
        report.split.pressure_noise_mpa, report.split.contraction_noise
    );
    let _ = writeln!(
        out,
        "  test: {} ({})",
        report.test_kind,
        if cfg.test.is_some() {
            "given"
        } else {
            "detected"
        }
    );
    let _ = writeln!(out, "  shape: {}", report.shape.statement());
    let _ = writeln!(
        out,
        "{} errors (model − measured; pressure by the forward model, contraction by the inverse):",
        if any_heldout {
            "held-out"
        } else {
            "training (nothing held out)"
        }
    );
    out.push_str(&report.test.to_text());
    let _ = writeln!(
        out,
        "  {} pressure error RMS {:.5} MPa, contraction error RMS {:.6} ({} error is primary for an {} test)",
        if any_heldout { "held-out" } else { "training" },
        report.test.total.pressure_rms_mpa,
        report.test.total.contraction_rms,
        if report.test_kind == fit::TestKind::Isometric {
            "the pressure"
        } else {
            "the contraction"
        },
        report.test_kind
    );
    if let Some(r) = report.reference_test_rms_mpa {
        let _ = writeln!(
            out,
            "  reference (a smooth static surface pressure(contraction, load), 30 coefficients, \
             least squares on the same training samples): pressure RMS {r:.5} MPa; the model's is {:.2}x it",
            report.test.total.pressure_rms_mpa / r
        );
    }
    let isometric = report.test_kind == fit::TestKind::Isometric;
    out.push_str(&crate::evaluate::segments::segments_report(
        &report.segments,
        isometric,
    ));
    if let Some(v) = &outcome.validation {
        let _ = writeln!(
            out,
            "validation on {} ({} samples; errors model − measured):",
            v.source, v.model.total.samples
        );
        out.push_str(&v.model.to_text());
        let _ = write!(
            out,
            "  validation pressure error RMS {:.5} MPa, contraction error RMS {:.6}",
            v.model.total.pressure_rms_mpa, v.model.total.contraction_rms
        );
        match v.reference_rms_mpa {
            Some(r) => {
                let _ = writeln!(
                    out,
                    "; reference surface {r:.5} MPa (the model is {:.2}x it)",
                    v.model.total.pressure_rms_mpa / r
                );
            }
            None => out.push('\n'),
        }
        out.push_str(&crate::evaluate::segments::segments_report(
            &v.segments,
            isometric,
        ));
    }
    out
}

/// `pam-lab diagnose`'s work on a record checked by [`read_record`].
pub fn diagnose_record(
    record: &Record,
    cfg: &DiagnoseConfig,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<DiagnoseReport, DiagnoseError> {
    cfg.fit.validate()?;
    diagnose::diagnose_with_progress(record, cfg, progress)
}

/// Stage `report.json` and, when `draw`, `residual.png` and `loops.png` in
/// `dir`.
pub fn stage_diagnose(
    set: &mut OutputSet,
    dir: &Path,
    report: &DiagnoseReport,
    record: &Record,
    draw: bool,
) -> anyhow::Result<()> {
    set.into_dir(dir)?;
    let mut json = serde_json::to_string_pretty(report).map_err(|e| {
        anyhow::anyhow!(
            "{}: cannot encode the report: {e}",
            dir.join("report.json").display()
        )
    })?;
    json.push('\n');
    set.add_bytes(&dir.join("report.json"), json.as_bytes())?;
    // The model diagnose ends with, effects included, as `fit` writes it:
    // what the firmware boots from (blob version 2 when it has effects).
    let origin = format!("pam-lab diagnose {}", report.source);
    for (name, bytes) in
        model_file::model_files(&report.final_params, &report.effects, None, &origin)?
    {
        set.add_bytes(&dir.join(name), &bytes)?;
    }
    if draw {
        set.add_via_path(&dir.join("residual.png"), |p| {
            crate::report::diagnose_plot::residual_plot(report, record, p)
        })?;
        set.add_via_path(&dir.join("loops.png"), |p| {
            crate::report::diagnose_plot::loops_plot(report, record, p)
        })?;
    }
    Ok(())
}

/// `pam-lab simulate`'s work: the simulation and the warnings about data
/// outside the model's calibrated range.
pub fn simulate_record(
    model: &LoadedModel,
    config: TrackerConfig,
    record: &Record,
) -> Result<(Vec<SimSample>, Vec<String>), pam_core::Error> {
    config.validate()?;
    model.effects.validate()?;
    let warnings = range_warnings(&model.coeffs, record);
    Ok((
        simulate::simulate(&model.coeffs, &model.effects, config, &record.samples),
        warnings,
    ))
}

/// Warnings for samples outside what the model was calibrated for: loads
/// outside `[min_load_n, max_load_n]` (by more than 2 % of the range or
/// 5 N; the tracker clamps them to the range) and pressures above `Pmax`
/// (the inverse clamps them to the end of the stroke).
pub fn range_warnings(coeffs: &Coeffs, record: &Record) -> Vec<String> {
    let p = coeffs.params();
    let (lo, hi) = (f64::from(p.min_load_n), f64::from(p.max_load_n));
    let tol = (0.02 * (hi - lo)).max(5.0);
    let pmax = f64::from(p.points.max_pressure_mpa);
    let mut out = Vec::new();
    let mut describe = |what: &str,
                        outside: &dyn Fn(f64) -> bool,
                        get: fn(&record::Sample) -> f64,
                        range: String,
                        effect: &str| {
        let idx: Vec<usize> = (0..record.len())
            .filter(|&i| outside(get(&record.samples[i])))
            .collect();
        let (Some(&first), false) = (idx.first(), idx.is_empty()) else {
            return;
        };
        let (vmin, vmax) = idx.iter().fold((f64::MAX, f64::MIN), |(a, b), &i| {
            let v = get(&record.samples[i]);
            (a.min(v), b.max(v))
        });
        out.push(format!(
            "{}:{}: {what} outside the model's calibrated range {range} on {} of {} samples \
             ({}..{}): {effect}",
            record.source,
            record.line(first),
            idx.len(),
            record.len(),
            num(vmin),
            num(vmax),
        ));
    };
    describe(
        "load",
        &|v| v < lo - tol || v > hi + tol,
        |s| s.load_n,
        format!("{}..{} N", num(lo), num(hi)),
        "the model holds the nearest calibrated load there, so its prediction is a guess",
    );
    describe(
        "pressure",
        &|v| v > pmax * 1.02,
        |s| s.pressure_mpa,
        format!("0..{} MPa", num(pmax)),
        "the model holds its end of stroke there",
    );
    out
}

/// The line `simulate` prints.
pub fn simulate_text(
    sim: &[SimSample],
    record: &Record,
    model: &Path,
    effects: &pam_core::Effects,
) -> String {
    let sum = simulate::summary(sim);
    let named: Vec<&str> = diagnose::EffectKind::ALL
        .into_iter()
        .filter(|k| k.is_on(effects))
        .map(diagnose::EffectKind::name)
        .collect();
    let dynamic: Vec<&str> = named
        .iter()
        .copied()
        .filter(|n| *n != diagnose::EffectKind::ConstraintShape.name())
        .collect();
    let with = if named.is_empty() {
        String::from("the paper's model")
    } else if dynamic.is_empty() {
        format!("the paper's model + {}", named.join(" + "))
    } else {
        format!(
            "the paper's model + {} (the pressure error is the static model's, its shape in, {} left out)",
            named.join(" + "),
            dynamic.join(" + ")
        )
    };
    let mut text = format!(
        "simulated {} samples of {} with {} ({with}): contraction error RMS {:.5}, max {:.5}; \
         pressure error RMS {:.5} MPa, max {:.5} MPa\n",
        sim.len(),
        record.source,
        model.display(),
        sum.contraction_rms,
        sum.contraction_max,
        sum.pressure_rms_mpa,
        sum.pressure_max_mpa
    );
    // An isometric test's slack samples (force at the load cell's floor)
    // are no samples of the model: its errors without them, as fit's.
    if fit::detect_test(&record.samples) == fit::TestKind::Isometric {
        let slack = fit::slack_mask(&record.samples, fit::TestKind::Isometric);
        let loaded: Vec<SimSample> = sim
            .iter()
            .zip(&slack)
            .filter(|(_, s)| !**s)
            .map(|(x, _)| *x)
            .collect();
        if !loaded.is_empty() && loaded.len() < sim.len() {
            let l = simulate::summary(&loaded);
            text.push_str(&format!(
                "  isometric test, the {} samples under load (the {} slack ones left out, as fit \
                 leaves them out): pressure error RMS {:.5} MPa, max {:.5} MPa; contraction error \
                 RMS {:.5}\n",
                loaded.len(),
                sim.len() - loaded.len(),
                l.pressure_rms_mpa,
                l.pressure_max_mpa,
                l.contraction_rms
            ));
        }
    }
    text
}

/// What `pam-lab adapt` made: the adapted model's files, how far the
/// adapted model is from the scaled flashed one, and (with a record of the
/// worn muscle) each model's contraction error on it.
pub struct AdaptOutcome {
    /// The adapted model and its fit to the scaled samples.
    pub adapted: crate::identify::adapted::AdaptedModel,
    /// model.json, model.blob, model_params.rs.
    pub files: Vec<(&'static str, Vec<u8>)>,
    /// `(model, contraction RMS)` on the record: the flashed model, the
    /// adapted one, and `pam-lab fit`'s fresh identification of the record.
    pub comparison: Option<Vec<(&'static str, f64)>>,
}

/// `pam-lab adapt`'s work: the flashed `model` (the paper's model) with the
/// stroke scale the firmware logged, refitted as a model of its own; with
/// `record`, compared with the flashed model and a fresh `pam-lab fit` of
/// that record (`fit_cfg`), in contraction RMS over the record.
pub fn adapt_model(
    model: &LoadedModel,
    stroke_scale: f64,
    record: Option<&Record>,
    fit_cfg: &FitConfig,
) -> anyhow::Result<AdaptOutcome> {
    use crate::identify::adapted::{adapted_model, AdaptError};
    if model.effects != pam_core::Effects::NONE {
        let e = &model.effects;
        let names: Vec<&str> = [
            (e.memory.is_some(), "non-local memory"),
            (e.rate.is_some(), "rate dependence"),
            (e.creep.is_some(), "creep"),
            (e.width.is_some(), "load-dependent width"),
            (e.shape.is_some(), "constraint shape"),
            (e.pressure_lag.is_some(), "pressure lag"),
            (e.pressure_delay.is_some(), "pressure delay"),
        ]
        .into_iter()
        .filter_map(|(on, name)| on.then_some(name))
        .collect();
        return Err(AdaptError::Effects(names.join(", ")).into());
    }
    let adapted = adapted_model(model.coeffs.params(), stroke_scale)?;
    let origin = format!("pam-lab adapt (stroke scale {stroke_scale})");
    let files = model_file::model_files(&adapted.params, &pam_core::Effects::NONE, None, &origin)
        .map_err(|e| anyhow::anyhow!("the adapted model's files: {e}"))?;
    let comparison = match record {
        None => None,
        Some(r) => {
            let fresh = fit_record(r, fit_cfg, &|_| {})
                .map_err(|e| anyhow::anyhow!("fit refused the record: {e}"))?;
            let adapted_coeffs = Coeffs::new(adapted.params)?;
            let rms = |coeffs: &Coeffs, effects: &pam_core::Effects| {
                let sim = simulate::simulate(
                    coeffs,
                    effects,
                    TrackerConfig::DEFAULT_PRESSURE,
                    &r.samples,
                );
                let e: Vec<f64> = sim
                    .iter()
                    .map(|s| s.error())
                    .filter(|e| e.is_finite())
                    .collect();
                (e.iter().map(|v| v * v).sum::<f64>() / e.len().max(1) as f64).sqrt()
            };
            Some(vec![
                ("flashed", rms(&model.coeffs, &model.effects)),
                ("adapted", rms(&adapted_coeffs, &pam_core::Effects::NONE)),
                (
                    "fresh fit",
                    rms(&fresh.report.coeffs, &fresh.report.effects()),
                ),
            ])
        }
    };
    Ok(AdaptOutcome {
        adapted,
        files,
        comparison,
    })
}

/// `pam-lab adapt`'s report.
pub fn adapt_text(outcome: &AdaptOutcome, stroke_scale: f64, record: Option<&Record>) -> String {
    let a = &outcome.adapted;
    let mut s = format!(
        "adapted model: the flashed model with its stroke scaled by {stroke_scale} about each load's root, \
         refitted as the paper's model: contraction RMS {:.5} (largest {:.5}) from the scaled model over {} samples\n",
        a.rms_contraction,
        a.max_contraction,
        a.record.len()
    );
    if let (Some(rows), Some(r)) = (&outcome.comparison, record) {
        s.push_str(&format!(
            "contraction RMS on {} ({} samples):\n",
            r.source,
            r.len()
        ));
        for (name, rms) in rows {
            s.push_str(&format!("  {name:<10} {rms:.5}\n"));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use pam_core::Params;

    #[test]
    fn loads_outside_the_calibrated_range_are_warned_with_their_first_line() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let p = coeffs.params();
        let mid = f64::from(p.min_load_n + p.max_load_n) / 2.0;
        let s = |load| record::Sample {
            t_s: 0.0,
            load_n: load,
            pressure_mpa: 0.1,
            contraction: 0.05,
        };
        let rec = Record::from_samples("r.csv", vec![s(mid), s(mid), s(5000.0), s(0.0)]);
        let w = range_warnings(&coeffs, &rec);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].starts_with("r.csv:4: load outside"), "{}", w[0]);
        assert!(w[0].contains("on 2 of 4 samples (0..5000)"), "{}", w[0]);
        let ok = Record::from_samples("r.csv", vec![s(mid); 3]);
        assert!(range_warnings(&coeffs, &ok).is_empty());
    }
}

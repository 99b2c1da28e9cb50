//! The diagnosed model on another record of the same muscle, in the
//! pressure a user commands: the pressure each sample's contraction takes
//! ([`crate::evaluate::simulate::pressure_to_reach`], every effect in),
//! beside the reference surface fitted to the diagnosed record.

use pam_core::{Coeffs, Effects, Params};

use super::config::{DiagnoseConfig, PRESSURE_MEDIAN_HALF_WIDTH};
use super::evaluate::simulate;
use super::prepare::{denoise_pressure, inverse_tables, record_branches, tracker_config};
use super::report::{DiagnoseReport, DiagnoseValidation, ValidationErrors};
use crate::evaluate::errors::rms_where;
use crate::evaluate::segments::{segment_errors_of, with_reference};
use crate::identify::fit::{detect_test, slack_mask, TestKind};
use crate::identify::reference::ReferenceSurface;
use crate::record::split::split_branches;
use crate::record::Record;

/// Evaluate `report`'s base and final models on `validation`, and the
/// reference surface fitted to `record` (the record diagnosed).
pub fn validate(
    report: &DiagnoseReport,
    record: &Record,
    validation: &Record,
    cfg: &DiagnoseConfig,
) -> DiagnoseValidation {
    let raw = &validation.samples;
    let test = detect_test(raw);
    let slack = slack_mask(raw, test);
    let split = split_branches(raw, &cfg.fit.split);
    let include = |i: usize| split.branch[i].is_some() && !slack[i];
    let samples = denoise_pressure(raw, PRESSURE_MEDIAN_HALF_WIDTH);
    let tracker = tracker_config(
        crate::record::noise_std(raw.iter().map(|s| s.pressure_mpa)),
        crate::record::noise_std(raw.iter().map(|s| s.load_n)),
        test == TestKind::Isometric,
    );
    let noise = crate::evaluate::errors::noise_floor(raw);
    let tables = inverse_tables(test == TestKind::Isometric);
    // A model's residuals, predicted − measured, in pressure and in
    // contraction per sample; `None` for parameters pam-core refuses.
    let residuals = |params: &Params, effects: &Effects| {
        let coeffs = Coeffs::new(*params).ok()?;
        // Up to the model's `Pmax`, where its stroke ends: a contraction
        // beyond what the model reaches is predicted at `Pmax`, as the
        // static inverse clamps it to the stroke.
        let limit = params.points.max_pressure_mpa;
        let branches = record_branches(
            &samples,
            &split.branch,
            &coeffs,
            tracker,
            noise.contraction,
            test == TestKind::Isometric,
        );
        let p = crate::evaluate::simulate::pressure_to_reach(
            &coeffs,
            effects,
            tracker,
            &samples,
            Some(&branches),
            tables,
            limit,
        );
        let p_res: Vec<f64> = p.iter().zip(raw).map(|(p, s)| p - s.pressure_mpa).collect();
        let x = simulate(&coeffs, *effects, tracker, &samples, &branches, tables);
        let x_res: Vec<f64> = x.iter().zip(raw).map(|(x, s)| x - s.contraction).collect();
        Some((p_res, x_res))
    };
    let errors = |res: &Option<(Vec<f64>, Vec<f64>)>| match res {
        Some((p_res, x_res)) => ValidationErrors {
            pressure_rms_mpa: rms_where(p_res, include).0,
            contraction_rms: rms_where(x_res, include).0,
        },
        None => ValidationErrors {
            pressure_rms_mpa: f64::NAN,
            contraction_rms: f64::NAN,
        },
    };
    let own = &record.samples;
    let own_test = detect_test(own);
    let own_slack = slack_mask(own, own_test);
    let own_split = split_branches(own, &cfg.fit.split);
    let own_include = |i: usize| own_split.branch[i].is_some() && !own_slack[i];
    let reference = ReferenceSurface::fit(own, own_include);
    let reference_delayed_rms_mpa = report.effects.pressure_delay.and_then(|d| {
        let delayed = |s: &[crate::record::Sample]| {
            crate::evaluate::retime::with_delayed_pressure(s, f64::from(d.delay_s))
        };
        ReferenceSurface::fit(&delayed(own), own_include)?
            .rms_mpa(&delayed(raw), include)
            .map(|(rms, _)| rms)
    });
    // The diagnosed model's errors, and its errors per part of the record.
    let final_res = residuals(&report.final_params, &report.effects);
    let segments = match &final_res {
        Some((p_res, x_res)) => {
            segment_errors_of(validation, |i| include(i).then(|| (p_res[i], x_res[i])))
        }
        None => Vec::new(),
    };
    DiagnoseValidation {
        source: validation.source.clone(),
        samples: (0..raw.len()).filter(|&i| include(i)).count(),
        base: errors(&residuals(&report.base_params, &report.base_effects)),
        model: errors(&final_res),
        segments: with_reference(segments, validation, reference.as_ref(), include),
        reference_rms_mpa: reference
            .and_then(|r| r.rms_mpa(raw, include))
            .map(|(rms, _)| rms),
        reference_delayed_rms_mpa,
    }
}

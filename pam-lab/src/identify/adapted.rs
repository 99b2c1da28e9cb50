//! The model the firmware adapted online, as a model of its own: the
//! flashed paper model with the stroke scale the controller logged
//! (`firmware::controller::adapt`, the defmt line `adaptation: stroke scale
//! S`), refitted as the paper's model so that a blob carries it.
//!
//! The adapted muscle contracts `R + s·(x − R)` where the flashed model
//! says `x` (`R` its root at the load). That is not exactly a member of the
//! paper's family (its critical points move with the load's own root), so
//! it is sampled from pam-core's model, scaled, and fitted by `pam-lab
//! fit` as a record: the samples follow [`crate::synth::Protocol::standard`]
//! at every calibrated load step, noise-free. The fit's residual against
//! the scaled model is reported: that is how far the blob is from what the
//! controller ran.

use pam_core::{Coeffs, Params};

use crate::identify::fit::{self, FitConfig, Holdout};
use crate::record::Record;
use crate::synth::{generate, Protocol};

/// Stroke scales accepted: the adaptation's bound is at most ±50 %.
pub const STROKE_SCALE_RANGE: std::ops::RangeInclusive<f64> = 0.5..=1.5;

/// The adapted model and how far it is from the scaled flashed model.
#[derive(Clone, Debug)]
pub struct AdaptedModel {
    /// The paper's model fitted to the scaled samples (pam-core accepts it).
    pub params: Params,
    /// The scaled samples it was fitted to.
    pub record: Record,
    /// RMS and largest contraction difference, fitted − scaled, over them.
    pub rms_contraction: f64,
    /// Largest of the same.
    pub max_contraction: f64,
}

/// Why the adapted model could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AdaptError {
    /// The stroke scale is not finite or outside [`STROKE_SCALE_RANGE`].
    #[error("stroke scale {0} is outside 0.5..=1.5 (the adaptation's bound is at most ±50 %)")]
    Scale(f64),
    /// The flashed model carries effects: the adaptation runs on the
    /// paper's model only.
    #[error("the model carries effects ({0}); the firmware adapts the paper's model only")]
    Effects(String),
    /// The flashed parameters do not validate.
    #[error("the flashed model is refused by pam-core: {0}")]
    Flashed(pam_core::Error),
    /// The fit refused the scaled samples.
    #[error("fit refused the adapted model's samples: {0}")]
    Fit(String),
}

/// The flashed model `params` with its stroke scaled by `stroke_scale`
/// about each load's root, as the paper's model.
pub fn adapted_model(params: &Params, stroke_scale: f64) -> Result<AdaptedModel, AdaptError> {
    if !(stroke_scale.is_finite() && STROKE_SCALE_RANGE.contains(&stroke_scale)) {
        return Err(AdaptError::Scale(stroke_scale));
    }
    let coeffs = Coeffs::new(*params).map_err(AdaptError::Flashed)?;
    let p = coeffs.params();
    let step = p.load_step_n.max(1.0);
    let mut loads = Vec::new();
    let mut load = f64::from(p.min_load_n);
    while load <= f64::from(p.max_load_n) + 1e-6 {
        loads.push(load);
        load += f64::from(step);
    }
    let pmax = f64::from(p.points.max_pressure_mpa);
    let mut record = generate(params, &Protocol::standard(&loads, pmax, 10.0), 0.0, 0.0, 1);
    for s in &mut record.samples {
        let root = f64::from(
            coeffs
                .load_model_clamped(s.load_n as f32)
                .root_contraction(),
        );
        s.contraction = root + stroke_scale * (s.contraction - root);
    }
    record.source = format!("the flashed model, stroke scale {stroke_scale}");
    let config = FitConfig {
        holdout: Holdout::None,
        static_shape: false,
        ..FitConfig::default()
    };
    let report = fit::fit(&record, &config).map_err(|e| AdaptError::Fit(e.to_string()))?;
    let fitted = report.coeffs;
    let mut cache = crate::evaluate::errors::ModelCache::new(&fitted, None);
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    let drive = Protocol::standard(&loads, pmax, 10.0).drive();
    for ((_, load_n, pressure, branch), s) in drive.into_iter().zip(&record.samples) {
        let x = f64::from(cache.contraction(pressure as f32, load_n as f32, branch));
        let d = x - s.contraction;
        sum += d * d;
        max = max.max(d.abs());
        n += 1;
    }
    Ok(AdaptedModel {
        params: report.params,
        record,
        rms_contraction: (sum / n.max(1) as f64).sqrt(),
        max_contraction: max,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scale_of_one_gives_the_flashed_model_back() {
        let a = adapted_model(&Params::DEFAULT, 1.0).unwrap();
        // The refit of the flashed model's own samples: within a tenth of
        // the contraction sensor's noise in RMS (the largest difference
        // where the stroke's top is steep in pressure).
        assert!(a.rms_contraction < 5e-4, "{}", a.rms_contraction);
        assert!(a.max_contraction < 1e-2, "{}", a.max_contraction);
    }

    #[test]
    fn a_shrunk_stroke_is_a_paper_model_close_to_the_scaled_one() {
        let a = adapted_model(&Params::DEFAULT, 0.9).unwrap();
        eprintln!("rms {} max {}", a.rms_contraction, a.max_contraction);
        assert!(a.rms_contraction < 2e-3, "{}", a.rms_contraction);
        let flashed = Coeffs::new(Params::DEFAULT).unwrap();
        let adapted = Coeffs::new(a.params).unwrap();
        for load in [100.0f32, 350.0, 600.0] {
            let (f, g) = (
                flashed.load_model_clamped(load),
                adapted.load_model_clamped(load),
            );
            let stroke = |m: &pam_core::LoadModel| m.max_contraction() - m.root_contraction();
            let ratio = stroke(&g) / stroke(&f);
            assert!((ratio - 0.9).abs() < 0.03, "{load} N: stroke ratio {ratio}");
        }
    }

    #[test]
    fn scales_outside_the_range_and_models_with_effects_are_refused() {
        for s in [0.4, 1.6, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                adapted_model(&Params::DEFAULT, s),
                Err(AdaptError::Scale(_))
            ));
        }
    }
}

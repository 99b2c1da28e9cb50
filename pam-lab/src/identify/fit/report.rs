//! What a fit reports: the model, its errors, how well the cubic follows
//! the static curve, the reference beside it; and the evaluation on
//! another record.

use super::*;

/// How well the paper's cubic family can follow the record's static curve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ShapeFit {
    /// Systematic pressure misfit on the training samples, MPa: the RMS of
    /// the mean residual per (load bin, branch, 1/20 of the stroke) cell,
    /// weighted by samples. Noise averages out of it; shape error does not.
    pub systematic_pressure_rms_mpa: f64,
    /// The record's pressure noise, MPa (standard deviation).
    pub pressure_noise_mpa: f64,
    /// The fitted model lies at the edge of the shapes the paper allows
    /// (the optimiser pressed against the one-real-root or monotone
    /// condition at some load): the data would pull it outside.
    pub at_shape_limit: bool,
    /// Smallest shape margin over the calibrated loads, relative to the mean
    /// slope (see `pam_core::ShapeMargins::relative`).
    pub worst_shape_margin: f64,
    /// With the static shape: the cubic alone's systematic misfit, MPa
    /// (the first stage's, before the shape was added).
    pub cubic_only_systematic_pressure_rms_mpa: Option<f64>,
}

impl ShapeFit {
    /// Whether the static curve is beyond what the cubic family can follow:
    /// pressed against the shape limits with a systematic misfit above
    /// twice the noise.
    pub fn cubic_cannot_follow(&self) -> bool {
        self.at_shape_limit && self.systematic_pressure_rms_mpa > 2.0 * self.pressure_noise_mpa
    }

    /// One sentence for a report.
    pub fn statement(&self) -> String {
        let noise = self.pressure_noise_mpa.max(1e-12);
        let ratio = self.systematic_pressure_rms_mpa / noise;
        if let Some(cubic) = self.cubic_only_systematic_pressure_rms_mpa {
            return format!(
                "the paper's cubic alone left a systematic pressure misfit of {cubic:.4} MPa RMS \
                 ({:.1}x the {:.4} MPa noise); with the static shape's stroke table {:.4} MPa \
                 ({ratio:.1}x)",
                cubic / noise,
                self.pressure_noise_mpa,
                self.systematic_pressure_rms_mpa
            );
        }
        if self.cubic_cannot_follow() {
            format!(
                "the paper's cubic cannot follow this muscle's static curve: the fit is the closest \
                 valid model, pressed against the paper's shape conditions, with a systematic \
                 pressure misfit of {:.4} MPa RMS ({ratio:.1}x the {:.4} MPa noise)",
                self.systematic_pressure_rms_mpa, self.pressure_noise_mpa
            )
        } else {
            format!(
                "systematic pressure misfit {:.4} MPa RMS ({ratio:.1}x the {:.4} MPa noise){}",
                self.systematic_pressure_rms_mpa,
                self.pressure_noise_mpa,
                if self.at_shape_limit {
                    "; the fit touches the paper's shape conditions"
                } else {
                    ""
                }
            )
        }
    }
}

/// Where `Pmax` came from.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PmaxSource {
    /// Given by the user.
    Given,
    /// Measured from the record.
    Measured,
}

/// The outcome of [`fit`].
#[derive(Clone, Debug)]
pub struct FitReport {
    /// The identified parameters (`Coeffs::new` accepts them, always).
    pub params: Params,
    /// `Coeffs::new(params)`.
    pub coeffs: Coeffs,
    /// The static-shape correction fitted with the paper's parameters, when
    /// the cubic alone left a systematic misfit and the shape earned its
    /// parameters (`FitConfig::static_shape`).
    pub constraint_shape: Option<pam_core::effects::ConstraintShape>,
    /// The branch split of the whole record.
    pub split: Split,
    /// Which samples were held out.
    pub heldout: Vec<bool>,
    /// Errors on the training samples.
    pub train: ErrorTable,
    /// Errors on the held-out samples (the training samples when nothing is
    /// held out).
    pub test: ErrorTable,
    /// Where `Pmax` came from.
    pub pmax_source: PmaxSource,
    /// The hold-out rule used.
    pub holdout: Holdout,
    /// Residual evaluations of the optimiser.
    pub evaluations: usize,
    /// The optimiser's termination reason.
    pub termination: String,
    /// Final cost `½·Σr²` (weighted residuals).
    pub cost: f64,
    /// The starting point derived from the data.
    pub initial: Params,
    /// The kind of test (given or detected).
    pub test_kind: TestKind,
    /// How well the cubic family follows the record's static curve.
    pub shape: ShapeFit,
    /// The best smooth static surface on the same training samples
    /// ([`ReferenceSurface`]), when there are enough of them.
    pub reference: Option<ReferenceSurface>,
    /// The reference's RMS pressure error on the samples of `test`, MPa.
    pub reference_test_rms_mpa: Option<f64>,
    /// Errors per part of the record fitted (its `# segment` seams), on its
    /// samples on a branch and under load, training and held-out; empty
    /// for a record of one run.
    pub segments: Vec<SegmentErrors>,
}

impl FitReport {
    /// The effects the fitted model carries: the static shape, when fitted.
    pub fn effects(&self) -> pam_core::Effects {
        pam_core::Effects {
            shape: self.constraint_shape,
            ..pam_core::Effects::NONE
        }
    }

    /// The samples of `samples` (the record fitted) the fit trained on: on
    /// a branch, not held out, not slack.
    pub fn training_samples(&self, samples: &[crate::record::Sample]) -> usize {
        let slack = slack_mask(samples, self.test_kind);
        (0..samples.len())
            .filter(|&i| {
                self.split.branch.get(i).is_some_and(Option::is_some)
                    && !self.heldout.get(i).copied().unwrap_or(false)
                    && !slack[i]
            })
            .count()
    }
}

/// A fitted model and its reference surface on a record neither was
/// fitted to (`pam-lab fit --validate`).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Validation {
    /// The record.
    pub source: String,
    /// The model's errors per load bin and branch.
    pub model: ErrorTable,
    /// The reference surface's RMS pressure error on the same samples, MPa.
    pub reference_rms_mpa: Option<f64>,
    /// The model's errors per part of the record (its `# segment` seams:
    /// the tests `pam-lab import` joined); empty for a record of one run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub segments: Vec<SegmentErrors>,
}

/// Evaluate a fit on another record: its branches split as the fit split
/// its own, slack samples of an isometric test left out as the fit leaves
/// them out.
pub fn validate(report: &FitReport, record: &Record, cfg: &FitConfig) -> Validation {
    let samples = &record.samples;
    let split = split_branches(samples, &cfg.split);
    let slack = slack_mask(samples, report.test_kind);
    let include = |i: usize| split.branch[i].is_some() && !slack[i];
    let model = error_table(
        &report.coeffs,
        report.constraint_shape.as_ref(),
        samples,
        &split.branch,
        |i| !slack[i],
        cfg.load_bin_n,
    );
    let segments = segment_errors(
        &report.coeffs,
        report.constraint_shape.as_ref(),
        record,
        &split.branch,
        |i| !slack[i],
    );
    Validation {
        source: record.source.clone(),
        segments: with_reference(segments, record, report.reference.as_ref(), include),
        model,
        reference_rms_mpa: report
            .reference
            .as_ref()
            .and_then(|r| r.rms_mpa(samples, include))
            .map(|(rms, _)| rms),
    }
}

/// RMS of the mean pressure residual per (load bin, branch, 1/20 of the
/// stroke) cell, weighted by the cell's samples.
pub(super) fn systematic_misfit(
    train: &TrainSet,
    fam: &LoadFamily,
    shape: Option<&pam_core::effects::ConstraintShape>,
    bin: f64,
) -> f64 {
    use pam_core::effects::shape::table::{at_fraction_f64, TABLE_KNOTS};
    use pam_core::effects::ConstraintShape;
    let nodes = shape.map(|s| s.table.knots.map(|k| k.map(f64::from)));
    let coefficients = shape.map(ConstraintShape::coefficients_f64);
    let span = (fam.max_load_n - fam.min_load_n).max(1e-9);
    let mut cells: std::collections::HashMap<(i64, bool, i64), (f64, usize)> = Default::default();
    for &(load, start, end) in &train.runs {
        let m = fam.at_load(load);
        let stroke = (m.max_contraction - m.cubic.root).max(1e-6);
        let steps = (load.clamp(fam.min_load_n, fam.max_load_n) - fam.min_load_n) / fam.load_step_n;
        let at = coefficients.map(|c| ConstraintShape::at_steps_f64(c, steps).0);
        let k: Option<[f64; TABLE_KNOTS]> =
            nodes.map(|n| at_fraction_f64(&n, (load - fam.min_load_n) / span));
        for i in start..end {
            let (x, br) = (train.x[i], train.branch[i]);
            let p = match at {
                Some(at) => ConstraintShape::pressure_and_slope_f64(at, k.as_ref(), &m, x, br).0,
                None => m.pressure_mpa(x, br),
            };
            let r = p - train.p[i];
            let key = (
                (load / bin).round() as i64,
                br == Branch::Expansion,
                ((x - m.cubic.root) / stroke * 20.0).floor() as i64,
            );
            let c = cells.entry(key).or_default();
            c.0 += r;
            c.1 += 1;
        }
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for (s, k) in cells.values() {
        // Cells of a few samples carry their noise: they are left out.
        if *k >= 5 {
            let mean = s / *k as f64;
            sum += mean * mean * *k as f64;
            n += k;
        }
    }
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

//! A model's errors per part of a record: the tests, files or runs after
//! a clock reset that `pam-lab import` joined, marked by `# segment`
//! seams ([`crate::record::Segment`]). How far each part sits from the
//! model, and how much of the error is the parts' offsets from one another
//! (a drift between tests) rather than error within each.

use pam_core::effects::ConstraintShape;
use pam_core::{Branch, Coeffs};
use serde::{Deserialize, Serialize};

use super::errors::{Acc, ErrorStats, ModelCache};
use crate::identify::reference::ReferenceSurface;
use crate::record::Record;

/// Errors of one part of a record ([`crate::record::Segment`]): a test, a
/// file, a run after a clock reset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmentErrors {
    /// The part's label.
    pub label: String,
    /// Its errors.
    pub stats: ErrorStats,
    /// Mean predicted − measured pressure, MPa: how far the part as a whole
    /// sits from the model.
    pub pressure_mean_mpa: f64,
    /// Mean predicted − measured contraction.
    pub contraction_mean: f64,
    /// The reference surface's pressure RMS on the part's same samples,
    /// MPa ([`with_reference`]): where the model loses to a smooth static
    /// surface, part by part; `None` without one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_pressure_rms_mpa: Option<f64>,
}

/// [`super::errors::error_table`]'s errors per part of `record` (its `# segment` seams),
/// on the samples with `branch[i]` labelled and `include(i)` true; a part
/// without such samples is left out. Empty for a record without seams.
pub fn segment_errors(
    coeffs: &Coeffs,
    shape: Option<&ConstraintShape>,
    record: &Record,
    branch: &[Option<Branch>],
    include: impl Fn(usize) -> bool,
) -> Vec<SegmentErrors> {
    let mut cache = ModelCache::new(coeffs, shape);
    segment_errors_of(record, |i| {
        let br = branch.get(i).copied().flatten()?;
        include(i).then(|| cache.errors(&record.samples[i], br))
    })
}

/// Errors per part of `record` (its `# segment` seams) from each sample's
/// residuals, `residual(i)` = (pressure, contraction), predicted −
/// measured, or `None` for a sample not judged; a sample with a residual
/// that is not finite is left out, and so is a part without samples.
/// Empty for a record without seams.
pub fn segment_errors_of(
    record: &Record,
    mut residual: impl FnMut(usize) -> Option<(f64, f64)>,
) -> Vec<SegmentErrors> {
    let mut out = Vec::new();
    for (label, range) in record.segment_ranges() {
        let mut acc = Acc::default();
        for i in range {
            if let Some((ep, ex)) = residual(i).filter(|(p, x)| p.is_finite() && x.is_finite()) {
                acc.add(ep, ex);
            }
        }
        let stats = acc.stats();
        if stats.samples > 0 {
            let (pressure_mean_mpa, contraction_mean) = acc.means();
            out.push(SegmentErrors {
                label: label.to_string(),
                stats,
                pressure_mean_mpa,
                contraction_mean,
                reference_pressure_rms_mpa: None,
            });
        }
    }
    out
}

/// `parts` (of `record`, from [`segment_errors_of`]) with the pressure RMS
/// of `reference` beside each: on the samples `judged(i)` selects, which
/// must be those the parts' own residuals came from (a sample the part
/// left out for a residual that was not finite is still judged here).
/// `parts` as they are without a reference.
pub fn with_reference(
    mut parts: Vec<SegmentErrors>,
    record: &Record,
    reference: Option<&ReferenceSurface>,
    judged: impl Fn(usize) -> bool,
) -> Vec<SegmentErrors> {
    let Some(reference) = reference else {
        return parts;
    };
    let of_reference = segment_errors_of(record, |i| {
        let s = record.samples.get(i)?;
        judged(i).then(|| {
            (
                reference.pressure_mpa(s.contraction, s.load_n) - s.pressure_mpa,
                0.0,
            )
        })
    });
    for part in &mut parts {
        part.reference_pressure_rms_mpa = of_reference
            .iter()
            .find(|r| r.label == part.label)
            .map(|r| r.stats.pressure_rms_mpa);
    }
    parts
}

/// The share of the errors' mean square that is each part's mean error
/// (the parts' offsets from one another and from the model), in
/// pressure or in contraction: `Σ n·mean² / Σ n·rms²`; `NaN` without
/// samples. A share near 1 says the parts disagree as wholes (a drift
/// between tests, a rig reset); near 0, that the error lies within each.
pub fn between_segments_share(parts: &[SegmentErrors], pressure: bool) -> f64 {
    let (mut between, mut all) = (0.0, 0.0);
    for p in parts {
        let n = p.stats.samples as f64;
        let (mean, rms) = if pressure {
            (p.pressure_mean_mpa, p.stats.pressure_rms_mpa)
        } else {
            (p.contraction_mean, p.stats.contraction_rms)
        };
        between += n * mean * mean;
        all += n * rms * rms;
    }
    if all > 0.0 {
        between / all
    } else {
        f64::NAN
    }
}

/// The report's lines for a record of two parts or more (nothing for
/// fewer): how much of the error's mean square is the parts' offsets from
/// one another (in pressure for an isometric test, else in contraction),
/// and [`segments_to_text`]'s table.
pub fn segments_report(parts: &[SegmentErrors], isometric: bool) -> String {
    if parts.len() < 2 {
        return String::new();
    }
    format!(
        "  per part of the record (model − measured, samples on a branch and under load): \
         the parts' mean errors are {:.0} % of the {} error's mean square\n{}",
        100.0 * between_segments_share(parts, isometric),
        if isometric { "pressure" } else { "contraction" },
        segments_to_text(parts)
    )
}

/// A plain-text table of [`SegmentErrors`], one line a part.
pub fn segments_to_text(parts: &[SegmentErrors]) -> String {
    let width = parts
        .iter()
        .map(|p| p.label.chars().count())
        .max()
        .unwrap_or(4)
        .max(4);
    let reference = parts.iter().any(|p| p.reference_pressure_rms_mpa.is_some());
    let mut s = format!(
        "  {:<width$}  samples  p_mean_mpa  p_rms_mpa  x_mean     x_rms{}\n",
        "part",
        if reference {
            "     reference_p_rms_mpa"
        } else {
            ""
        }
    );
    for p in parts {
        s.push_str(&format!(
            "  {:<width$}  {:>7}  {:>+10.5}  {:>9.5}  {:>+9.6}  {:>8.6}",
            p.label,
            p.stats.samples,
            p.pressure_mean_mpa,
            p.stats.pressure_rms_mpa,
            p.contraction_mean,
            p.stats.contraction_rms
        ));
        if reference {
            match p.reference_pressure_rms_mpa {
                Some(r) => s.push_str(&format!("  {r:>22.5}")),
                None => s.push_str(&format!("  {:>22}", "-")),
            }
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Sample;
    use pam_core::Params;

    #[test]
    fn parts_offset_from_one_another_show_in_their_means_and_share() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let m = coeffs.load_model(200.0).unwrap();
        let mut samples = Vec::new();
        let mut branch = Vec::new();
        // Two tests of the same loop, the second needing 0.01 MPa less
        // pressure for every contraction, the first 0.01 MPa more.
        for offset in [0.01, -0.01] {
            for k in 1..40 {
                let p = 0.01 * k as f32;
                let x = f64::from(m.contraction(p, Branch::Contraction));
                samples.push(Sample {
                    t_s: samples.len() as f64,
                    load_n: 200.0,
                    pressure_mpa: f64::from(p) + offset,
                    contraction: x,
                });
                branch.push(Some(Branch::Contraction));
            }
        }
        let mut record = Record::from_samples("two tests", samples);
        record.segments = vec![
            crate::record::Segment {
                start: 0,
                label: "test 8".into(),
            },
            crate::record::Segment {
                start: 39,
                label: "test 9".into(),
            },
        ];
        let parts = segment_errors(&coeffs, None, &record, &branch, |_| true);
        assert_eq!(parts.len(), 2);
        assert_eq!(parts[0].stats.samples, 39);
        assert!(
            (parts[0].pressure_mean_mpa + 0.01).abs() < 5e-4,
            "{parts:?}"
        );
        assert!(
            (parts[1].pressure_mean_mpa - 0.01).abs() < 5e-4,
            "{parts:?}"
        );
        let share = between_segments_share(&parts, true);
        assert!(share > 0.95 && share <= 1.0, "{share}");
        assert!(segments_to_text(&parts).contains("test 9"));
        // Within each test the same error with alternating signs: no offset.
        for (i, s) in record.samples.iter_mut().enumerate() {
            s.pressure_mpa -= if i < 39 { 0.01 } else { -0.01 };
            s.pressure_mpa += if i % 2 == 0 { 0.01 } else { -0.01 };
        }
        let parts = segment_errors(&coeffs, None, &record, &branch, |_| true);
        assert!(between_segments_share(&parts, true) < 0.01);
        // A record without seams has no parts.
        record.segments.clear();
        assert!(segment_errors(&coeffs, None, &record, &branch, |_| true).is_empty());
    }
}

//! Prediction errors of a model on labelled samples, per load and branch.
//!
//! Errors are measured with pam-core's own `f32` evaluation (the code the
//! firmware runs): in pressure with the forward model (`pressure_mpa` at the
//! measured contraction), and in contraction with the inverse model
//! (`contraction` at the measured pressure), each on the sample's own load
//! (clamped to the calibrated range) and labelled branch.

use std::collections::{BTreeMap, HashMap};

use pam_core::{Branch, Coeffs, LoadModel};
use serde::{Deserialize, Serialize};

use crate::data::Sample;

/// Error statistics of one group of samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Number of samples.
    pub samples: usize,
    /// RMS of predicted − measured pressure, MPa.
    pub pressure_rms_mpa: f64,
    /// Largest |predicted − measured| pressure, MPa.
    pub pressure_max_mpa: f64,
    /// RMS of predicted − measured contraction (fraction of rest length).
    pub contraction_rms: f64,
    /// Largest |predicted − measured| contraction.
    pub contraction_max: f64,
}

#[derive(Clone, Copy, Default)]
struct Acc {
    n: usize,
    sp: f64,
    mp: f64,
    sx: f64,
    mx: f64,
}

impl Acc {
    fn add(&mut self, ep: f64, ex: f64) {
        self.n += 1;
        self.sp += ep * ep;
        self.mp = self.mp.max(ep.abs());
        self.sx += ex * ex;
        self.mx = self.mx.max(ex.abs());
    }
    fn stats(&self) -> ErrorStats {
        let n = self.n.max(1) as f64;
        ErrorStats {
            samples: self.n,
            pressure_rms_mpa: (self.sp / n).sqrt(),
            pressure_max_mpa: self.mp,
            contraction_rms: (self.sx / n).sqrt(),
            contraction_max: self.mx,
        }
    }
}

/// One row of an [`ErrorTable`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroupStats {
    /// Centre of the load bin, N.
    pub load_n: f64,
    /// The branch.
    pub branch: Branch,
    /// The errors.
    #[serde(flatten)]
    pub stats: ErrorStats,
}

/// Errors per load bin and branch, plus the total.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ErrorTable {
    /// Width of the load bins, N.
    pub load_bin_n: f64,
    /// Per load bin and branch, by load then branch (contraction first).
    pub groups: Vec<GroupStats>,
    /// All samples together.
    pub total: ErrorStats,
}

/// Centre of the load bin of `load_n`.
pub fn load_bin(load_n: f64, bin_n: f64) -> f64 {
    (load_n / bin_n).round() * bin_n
}

/// A cache of pam-core load models by exact load value (isotonic records have
/// few distinct loads; building a model costs 66 forward evaluations).
pub struct ModelCache<'c> {
    coeffs: &'c Coeffs,
    models: HashMap<u32, LoadModel>,
}

impl<'c> ModelCache<'c> {
    /// An empty cache for `coeffs`.
    pub fn new(coeffs: &'c Coeffs) -> Self {
        ModelCache {
            coeffs,
            models: HashMap::new(),
        }
    }

    /// The model at `load_n` (clamped to the calibrated range).
    pub fn get(&mut self, load_n: f32) -> &LoadModel {
        let coeffs = self.coeffs;
        self.models
            .entry(load_n.to_bits())
            .or_insert_with(|| coeffs.load_model_clamped(load_n))
    }
}

/// Errors of `coeffs` on the samples `i` with `branch[i]` labelled and
/// `include(i)` true.
pub fn error_table(
    coeffs: &Coeffs,
    samples: &[Sample],
    branch: &[Option<Branch>],
    include: impl Fn(usize) -> bool,
    load_bin_n: f64,
) -> ErrorTable {
    let mut cache = ModelCache::new(coeffs);
    let mut groups: BTreeMap<(i64, u8), Acc> = BTreeMap::new();
    let mut total = Acc::default();
    for (i, s) in samples.iter().enumerate() {
        let Some(br) = branch.get(i).copied().flatten() else {
            continue;
        };
        if !include(i) {
            continue;
        }
        let m = cache.get(s.load_n as f32);
        let ep = f64::from(m.pressure_mpa(s.contraction as f32, br)) - s.pressure_mpa;
        let ex = f64::from(m.contraction(s.pressure_mpa as f32, br)) - s.contraction;
        let key = (
            (s.load_n / load_bin_n).round() as i64,
            u8::from(br == Branch::Expansion),
        );
        groups.entry(key).or_default().add(ep, ex);
        total.add(ep, ex);
    }
    ErrorTable {
        load_bin_n,
        groups: groups
            .into_iter()
            .map(|((k, b), acc)| GroupStats {
                load_n: k as f64 * load_bin_n,
                branch: if b == 0 {
                    Branch::Contraction
                } else {
                    Branch::Expansion
                },
                stats: acc.stats(),
            })
            .collect(),
        total: total.stats(),
    }
}

impl ErrorTable {
    /// A plain-text table: one line per group and a total line.
    pub fn to_text(&self) -> String {
        let mut s = String::from(
            "  load_n  branch       samples  p_rms_mpa  p_max_mpa  x_rms      x_max\n",
        );
        let line = |s: &mut String, load: &str, br: &str, e: &ErrorStats| {
            s.push_str(&format!(
                "  {load:>6}  {br:<11}  {:>7}  {:>9.5}  {:>9.5}  {:>9.6}  {:>9.6}\n",
                e.samples,
                e.pressure_rms_mpa,
                e.pressure_max_mpa,
                e.contraction_rms,
                e.contraction_max
            ));
        };
        for g in &self.groups {
            let br = match g.branch {
                Branch::Contraction => "contraction",
                Branch::Expansion => "expansion",
            };
            line(&mut s, &format!("{:.0}", g.load_n), br, &g.stats);
        }
        line(&mut s, "all", "both", &self.total);
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pam_core::Params;

    #[test]
    fn samples_on_the_model_have_zero_error_and_offsets_show() {
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let m = coeffs.load_model(200.0).unwrap();
        let mut samples = Vec::new();
        let mut branch = Vec::new();
        for k in 1..20 {
            let p = 0.02 * k as f32;
            for br in [Branch::Contraction, Branch::Expansion] {
                let x = m.contraction(p, br);
                samples.push(Sample {
                    t_s: 0.0,
                    load_n: 200.0,
                    pressure_mpa: f64::from(p),
                    contraction: f64::from(x),
                });
                branch.push(Some(br));
            }
        }
        let t = error_table(&coeffs, &samples, &branch, |_| true, 25.0);
        assert_eq!(t.groups.len(), 2);
        assert_eq!(t.total.samples, 38);
        assert!(t.total.pressure_max_mpa < 3e-4, "{:?}", t.total);
        assert!(t.total.contraction_max < 1e-5, "{:?}", t.total);
        // Shift every measured pressure by 0.01 MPa: the pressure RMS shows it.
        for s in &mut samples {
            s.pressure_mpa += 0.01;
        }
        let t = error_table(&coeffs, &samples, &branch, |i| i % 2 == 0, 25.0);
        assert_eq!(t.groups.len(), 1);
        assert!((t.total.pressure_rms_mpa - 0.01).abs() < 1e-3);
        assert!(t.to_text().contains("contraction"));
    }
}

//! Prediction errors of a model on labelled samples, per load and branch.
//!
//! Errors are measured with pam-core's own `f32` evaluation (the code the
//! firmware runs): in pressure with the forward model (`pressure_mpa` at the
//! measured contraction), and in contraction with the inverse model
//! (`contraction` at the measured pressure), each on the sample's own load
//! (clamped to the calibrated range) and labelled branch.

use std::collections::{BTreeMap, HashMap};

use pam_core::effects::{ConstraintShape, ShapeInverse};
use pam_core::{Branch, Coeffs, LoadModel};
use serde::{Deserialize, Serialize};

use crate::record::Sample;

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
pub(super) struct Acc {
    n: usize,
    sp: f64,
    mp: f64,
    sx: f64,
    mx: f64,
    // Sums of the signed errors.
    bp: f64,
    bx: f64,
}

impl Acc {
    pub(super) fn add(&mut self, ep: f64, ex: f64) {
        self.n += 1;
        self.bp += ep;
        self.bx += ex;
        self.sp += ep * ep;
        self.mp = self.mp.max(ep.abs());
        self.sx += ex * ex;
        self.mx = self.mx.max(ex.abs());
    }
    /// The mean signed errors, (pressure, contraction); `NaN` without
    /// samples.
    pub(super) fn means(&self) -> (f64, f64) {
        if self.n == 0 {
            return (f64::NAN, f64::NAN);
        }
        let n = self.n as f64;
        (self.bp / n, self.bx / n)
    }

    pub(super) fn stats(&self) -> ErrorStats {
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

/// The static model (the paper's, with the static shape when it has one)
/// evaluated as the chip evaluates it, with pam-core's load models and
/// shape inverses cached by exact load value (isotonic records have few
/// distinct loads; building a model costs 66 forward evaluations).
pub struct ModelCache<'c> {
    coeffs: &'c Coeffs,
    shape: Option<&'c ConstraintShape>,
    models: HashMap<u32, (LoadModel, Option<ShapeInverse>)>,
}

impl<'c> ModelCache<'c> {
    /// An empty cache for `coeffs` and `shape`.
    pub fn new(coeffs: &'c Coeffs, shape: Option<&'c ConstraintShape>) -> Self {
        ModelCache {
            coeffs,
            shape,
            models: HashMap::new(),
        }
    }

    /// The model at `load_n` (clamped to the calibrated range) and the
    /// shape's inverse there.
    pub fn get(&mut self, load_n: f32) -> &(LoadModel, Option<ShapeInverse>) {
        let (coeffs, shape) = (self.coeffs, self.shape);
        self.models.entry(load_n.to_bits()).or_insert_with(|| {
            let params = coeffs.params();
            let load = load_n.clamp(params.min_load_n, params.max_load_n);
            let load = if load.is_finite() {
                load
            } else {
                params.min_load_n
            };
            (
                coeffs.load_model_clamped(load_n),
                shape.map(|s| s.inverse_at_load(params, load)),
            )
        })
    }

    /// The pressure at the muscle's `contraction` under `load_n` on
    /// `branch`, MPa: as the feedforward computes it (the contraction held
    /// to the model's stroke, the shape's inverse, the branch, eqs. 25–26).
    pub fn pressure_mpa(&mut self, contraction: f32, load_n: f32, branch: Branch) -> f32 {
        let (m, inverse) = self.get(load_n);
        let x_model = match inverse {
            Some(inverse) => {
                let x = contraction.clamp(m.root_contraction(), m.max_contraction());
                inverse.model_contraction(m, x)
            }
            None => contraction,
        };
        m.pressure_mpa(x_model, branch)
    }

    /// A sample's errors, predicted − measured: the pressure at its
    /// contraction, MPa, and the contraction at its pressure, on `branch`.
    pub fn errors(&mut self, s: &Sample, branch: Branch) -> (f64, f64) {
        let load = s.load_n as f32;
        let ep = f64::from(self.pressure_mpa(s.contraction as f32, load, branch)) - s.pressure_mpa;
        let ex = f64::from(self.contraction(s.pressure_mpa as f32, load, branch)) - s.contraction;
        (ep, ex)
    }

    /// The muscle's contraction at `pressure_mpa` under `load_n` on
    /// `branch`: the model's inverse, then the shape's map.
    pub fn contraction(&mut self, pressure_mpa: f32, load_n: f32, branch: Branch) -> f32 {
        let (m, inverse) = self.get(load_n);
        let x = m.contraction(pressure_mpa, branch);
        match inverse {
            Some(inverse) => inverse.apply(m, x),
            None => x,
        }
    }
}

/// Errors of `coeffs` (with the static `shape` correction, when given) on
/// the samples `i` with `branch[i]` labelled and `include(i)` true,
/// evaluated as the chip evaluates them ([`ModelCache`]): the pressure at
/// the measured contraction (the feedforward's direction) and the
/// contraction at the measured pressure.
pub fn error_table(
    coeffs: &Coeffs,
    shape: Option<&ConstraintShape>,
    samples: &[Sample],
    branch: &[Option<Branch>],
    include: impl Fn(usize) -> bool,
    load_bin_n: f64,
) -> ErrorTable {
    let mut cache = ModelCache::new(coeffs, shape);
    let mut groups: BTreeMap<(i64, u8), Acc> = BTreeMap::new();
    let mut total = Acc::default();
    for (i, s) in samples.iter().enumerate() {
        let Some(br) = branch.get(i).copied().flatten() else {
            continue;
        };
        if !include(i) {
            continue;
        }
        let (ep, ex) = cache.errors(s, br);
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
        let t = error_table(&coeffs, None, &samples, &branch, |_| true, 25.0);
        assert_eq!(t.groups.len(), 2);
        assert_eq!(t.total.samples, 38);
        assert!(t.total.pressure_max_mpa < 3e-4, "{:?}", t.total);
        assert!(t.total.contraction_max < 1e-5, "{:?}", t.total);
        // Shift every measured pressure by 0.01 MPa: the pressure RMS shows it.
        for s in &mut samples {
            s.pressure_mpa += 0.01;
        }
        let t = error_table(&coeffs, None, &samples, &branch, |i| i % 2 == 0, 25.0);
        assert_eq!(t.groups.len(), 1);
        assert!((t.total.pressure_rms_mpa - 0.01).abs() < 1e-3);
        assert!(t.to_text().contains("contraction"));
    }
}

/// RMS of the finite `res[i]` where `mask(i)`, and how many there were
/// (`NaN`, 0 when none).
pub fn rms_where(res: &[f64], mask: impl Fn(usize) -> bool) -> (f64, usize) {
    let (mut s, mut k) = (0.0, 0usize);
    for (i, r) in res.iter().enumerate() {
        if mask(i) && r.is_finite() {
            s += r * r;
            k += 1;
        }
    }
    if k == 0 {
        (f64::NAN, 0)
    } else {
        ((s / k as f64).sqrt(), k)
    }
}

/// Longest correlation length [`correlation_length`] reports, samples.
pub const MAX_CORRELATION_LAG: usize = 500;

/// Correlation length of a residual series, samples: the first lag at which
/// its autocorrelation falls below `1/e` (at least 1, at most
/// [`MAX_CORRELATION_LAG`]).
///
/// `noise` is the white measurement noise in the series (standard
/// deviation; 0 if unknown) and `short_lag` the longest lag over which
/// noise stays correlated (1 for white noise; the width of a filter the
/// input went through). The noise's variance is taken off, so the length is
/// that of the systematic part, the model error: on a
/// residual that is mostly noise the plain autocorrelation drops below
/// `1/e` at lag 1, which would count every sample as an independent piece
/// of evidence and make any small change of the RMS look decisive in a BIC.
/// A residual with no variance above the noise has no systematic part to
/// measure: the length is then the maximum (little evidence).
pub fn correlation_length(res: &[f64], noise: f64, short_lag: usize) -> f64 {
    let v: Vec<f64> = res.iter().copied().filter(|r| r.is_finite()).collect();
    let n = v.len();
    if n < 4 {
        return 1.0;
    }
    let mean = v.iter().sum::<f64>() / n as f64;
    let var = v.iter().map(|r| (r - mean) * (r - mean)).sum::<f64>() / n as f64;
    if var.is_nan() || var <= 0.0 {
        return 1.0;
    }
    let max_lag = MAX_CORRELATION_LAG.min(n - 1);
    let cov = |lag: usize| {
        (0..n - lag)
            .map(|i| (v[i] - mean) * (v[i + lag] - mean))
            .sum::<f64>()
            / (n - lag) as f64
    };
    // The systematic variance: the lag-0 variance less the noise's, and at
    // most the covariance at `short_lag` (white parts — the noise,
    // single-sample spikes at reversals — add to lag 0 only, and noise
    // filtered over fewer than `short_lag` samples, such as the input's
    // noise through a running median, is gone by then).
    let short_lag = short_lag.clamp(1, max_lag.saturating_sub(1).max(1));
    let systematic = (var - noise * noise).min(cov(short_lag));
    if systematic <= 0.05 * var {
        return max_lag as f64;
    }
    for lag in short_lag..max_lag {
        if cov(lag) / systematic < (-1.0f64).exp() {
            return lag as f64;
        }
    }
    max_lag as f64
}

/// Measurement noise of a record, estimated from the record itself.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct NoiseFloor {
    /// Contraction noise (standard deviation, fraction of rest length).
    pub contraction: f64,
    /// Pressure noise (standard deviation), MPa.
    pub pressure_mpa: f64,
    /// Samples the estimate is taken from.
    pub samples: usize,
}

/// Estimate the white measurement noise of contraction and pressure from
/// short-lag (second) differences where the pressure moves slowest: the
/// quarter of the samples with the lowest pressure rate (holds, slow ramps,
/// the turns of smooth cycles), whatever the protocol. There the muscle's
/// own motion adds almost nothing to a second difference, so
/// `var(x[i+1] − 2x[i] + x[i−1]) = 6σ²`; the median absolute value makes it
/// robust to the few steps and spikes left (`σ ≈ 1.4826·MAD`). A channel
/// a logger quantises (the Festo records' pressure, in steps of 0.77 kPa)
/// holds one value over a still stretch: its second differences there are
/// exactly zero in a share no continuous noise gives, and their median is
/// 0 or one quantisation step depending on whether that share is just over
/// or under a half (Festo 15 cm: 0; 20 cm: 0.46 kPa). Where at least
/// `QUANTISED_SHARE` (a quarter) are exactly zero the mean absolute value is taken
/// instead (`E|d| = √(2/π)·√6·σ`: 0.23–0.29 kPa on the six Festo lengths,
/// about the step's rounding, `0.77/√12` = 0.22 kPa). Falls back to the
/// whole record when fewer than 30 such triples exist.
pub fn noise_floor(samples: &[Sample]) -> NoiseFloor {
    let n = samples.len();
    let whole = || NoiseFloor {
        contraction: crate::record::noise_std(samples.iter().map(|s| s.contraction)),
        pressure_mpa: crate::record::noise_std(samples.iter().map(|s| s.pressure_mpa)),
        samples: n,
    };
    if n < 40 {
        return whole();
    }
    let p: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
    let ps = crate::record::split::running_median(&p, 4);
    let dt = median_step_s(samples);
    // Rate over ±0.2 s (at least ±2 samples).
    let w = ((0.2 / dt).round() as usize).max(2);
    let rate: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(w), (i + w).min(n - 1));
            (ps[b] - ps[a]).abs() / ((b - a) as f64 * dt)
        })
        .collect();
    let mut sorted = rate.clone();
    let k = n / 4;
    let (_, q, _) = sorted.select_nth_unstable_by(k, f64::total_cmp);
    let q = *q;
    let slow: Vec<bool> = rate.iter().map(|r| *r <= q).collect();
    let second = |v: &dyn Fn(usize) -> f64| -> Vec<f64> {
        (1..n - 1)
            .filter(|&i| slow[i - 1] && slow[i] && slow[i + 1])
            .map(|i| (v(i + 1) - 2.0 * v(i) + v(i - 1)).abs())
            .collect()
    };
    let dx = second(&|i| samples[i].contraction);
    let dp = second(&|i| samples[i].pressure_mpa);
    if dx.len() < 30 {
        return whole();
    }
    NoiseFloor {
        samples: dx.len(),
        contraction: second_difference_sigma(dx),
        pressure_mpa: second_difference_sigma(dp),
    }
}

/// The share of exactly zero second differences at and above which
/// [`noise_floor`] reads a channel as quantised: continuous noise gives
/// none, a quantised channel that holds still about half (0.46–0.59 on the
/// Festo records' pressure).
const QUANTISED_SHARE: f64 = 0.25;

/// White noise's σ from the absolute second differences `d` of a channel
/// (each `√6·σ` in RMS): the median's, or for a quantised channel
/// ([`QUANTISED_SHARE`]) the mean's. 0 without differences.
fn second_difference_sigma(mut d: Vec<f64>) -> f64 {
    if d.is_empty() {
        return 0.0;
    }
    let zeros = d.iter().filter(|v| **v == 0.0).count();
    if zeros as f64 >= QUANTISED_SHARE * d.len() as f64 {
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        return mean / (6.0 * 2.0 / std::f64::consts::PI).sqrt();
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *m / 6f64.sqrt()
}

/// Median sample interval of a record, s (0.02 if it has under 2 samples
/// or no positive interval).
pub fn median_step_s(samples: &[Sample]) -> f64 {
    let mut d: Vec<f64> = samples
        .windows(2)
        .map(|w| w[1].t_s - w[0].t_s)
        .filter(|d| *d > 0.0 && d.is_finite())
        .collect();
    if d.is_empty() {
        return 0.02;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// The model error above the measurement noise: `sqrt(rms² − noise²)`
/// (0 when the RMS is at or below the noise).
pub fn above_noise(rms: f64, noise: f64) -> f64 {
    (rms * rms - noise * noise).max(0.0).sqrt()
}

#[cfg(test)]
mod noise_tests {
    use super::*;

    /// Deterministic Gaussian-ish noise (sum of 12 uniforms − 6).
    fn gauss(i: usize) -> f64 {
        let mut rng = crate::rng::Rng::new(i as u64 * 7 + 3);
        (0..12).map(|_| rng.uniform()).sum::<f64>() - 6.0
    }

    #[test]
    fn correlation_length_of_a_slow_signal_is_long_and_white_noise_has_no_length() {
        let slow: Vec<f64> = (0..2000).map(|i| (i as f64 / 200.0).sin()).collect();
        assert!(correlation_length(&slow, 0.0, 1) > 50.0);
        // White noise has no systematic part: the maximum (little evidence),
        // not one sample (every sample independent evidence).
        let white: Vec<f64> = (0..1000).map(|i| 0.0008 * gauss(i)).collect();
        for (noise, short) in [(0.0, 1), (0.0008, 1), (0.0008, 9)] {
            assert_eq!(
                correlation_length(&white, noise, short),
                MAX_CORRELATION_LAG as f64
            );
        }
    }

    #[test]
    fn correlation_length_sees_a_slow_error_under_white_noise() {
        // A slow error of 0.0005 under 0.0008 of white noise: normalised by
        // the lag-0 variance the autocorrelation falls below 1/e at once;
        // the systematic part's length is about 200·acos(1/e) ≈ 240 samples.
        let r: Vec<f64> = (0..6000)
            .map(|i| 0.0005 * (i as f64 / 200.0).sin() + 0.0008 * gauss(i))
            .collect();
        for (noise, short) in [(0.0, 1), (0.0008, 1), (0.0008, 9)] {
            let len = correlation_length(&r, noise, short);
            assert!((150.0..=350.0).contains(&len), "{noise} {short}: {len}");
        }
    }

    #[test]
    fn a_quantised_channel_has_the_noise_of_its_rounding() {
        // Pressure ramps and holds with 0.0002 MPa of noise, rounded to
        // steps of 0.00077 MPa as the Festo logger's (over half of the slow
        // second differences exactly zero): the floor is the rounded
        // signal's noise, about the step's `q/√12` with the noise beside
        // it, not the median's 0 (or one step, 0.00047, where the share of
        // zeros is just under a half).
        let q = 0.00077;
        let s: Vec<Sample> = (0..20_000)
            .map(|i| {
                let t = i as f64 * 0.01;
                let phase = (t / 10.0).fract();
                let p = 0.3 * (4.0 * phase).min(1.0) * (4.0 - 4.0 * phase).min(1.0);
                Sample {
                    t_s: t,
                    load_n: 200.0,
                    pressure_mpa: ((p + 0.0002 * gauss(2 * i)) / q).round() * q,
                    contraction: 0.3 * p + 0.0008 * gauss(2 * i + 1),
                }
            })
            .collect();
        let f = noise_floor(&s);
        let rounded = (q * q / 12.0 + 0.0002f64.powi(2)).sqrt();
        assert!(
            f.pressure_mpa > 0.5 * rounded && f.pressure_mpa < 1.5 * rounded,
            "{f:?} against {rounded}"
        );
        assert!((f.contraction - 0.0008).abs() < 0.1 * 0.0008, "{f:?}");
    }

    #[test]
    fn noise_floor_is_found_on_ramps_and_holds_of_any_rate() {
        // Sinusoidal pressure at 100 Hz (no holds at all), a steep static
        // curve, 0.0008 contraction and 0.001 MPa pressure noise.
        let s: Vec<Sample> = (0..20_000)
            .map(|i| {
                let t = i as f64 * 0.01;
                let p = 0.25 - 0.25 * (2.0 * std::f64::consts::PI * t / 8.0).cos();
                Sample {
                    t_s: t,
                    load_n: 200.0,
                    pressure_mpa: p + 0.001 * gauss(2 * i),
                    contraction: 0.3 * p + 0.0008 * gauss(2 * i + 1),
                }
            })
            .collect();
        let f = noise_floor(&s);
        assert!((f.contraction - 0.0008).abs() < 0.1 * 0.0008, "{f:?}");
        assert!((f.pressure_mpa - 0.001).abs() < 0.1 * 0.001, "{f:?}");
        assert!(f.samples > 3000, "{f:?}");
        assert!((above_noise(0.001, 0.0008) - 0.0006).abs() < 1e-12);
        assert_eq!(above_noise(0.0007, 0.0008), 0.0);
    }
}

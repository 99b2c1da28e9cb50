//! Statistics of a record's channels: noise, correlation, quantiles.

use super::*;

/// Pearson correlation of two channels over a record (0 when one holds).
pub fn correlation(samples: &[Sample], f: fn(&Sample) -> f64, g: fn(&Sample) -> f64) -> f64 {
    let n = samples.len().max(1) as f64;
    let (mf, mg) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), s| (a + f(s) / n, b + g(s) / n));
    let (mut sfg, mut sff, mut sgg) = (0.0, 0.0, 0.0);
    for s in samples {
        let (df, dg) = (f(s) - mf, g(s) - mg);
        sfg += df * dg;
        sff += df * df;
        sgg += dg * dg;
    }
    if sff > 0.0 && sgg > 0.0 {
        sfg / (sff * sgg).sqrt()
    } else {
        0.0
    }
}

/// Robust standard deviation of white noise on a smooth signal, from the
/// median absolute second difference: `var(x[i+1] − 2x[i] + x[i−1]) = 6σ²`,
/// and `σ ≈ 1.4826 · MAD` for Gaussian noise.
pub fn noise_std(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let v: Vec<f64> = values.collect();
    if v.len() < 3 {
        return 0.0;
    }
    let mut d2: Vec<f64> = v
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    let mid = d2.len() / 2;
    let (_, m, _) = d2.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *m / 6f64.sqrt()
}

/// The `q`-quantile of `v` (`q` in `0..=1`, the nearest rank); `None`
/// for no values.
pub fn quantile(mut v: Vec<f64>, q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    let (_, m, _) = v.select_nth_unstable_by(k, f64::total_cmp);
    Some(*m)
}

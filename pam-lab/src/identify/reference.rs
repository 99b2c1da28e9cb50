//! The reference a model is measured against: the best smooth *static*
//! surface `pressure(contraction, load)` a plain least-squares fit finds in
//! the same training samples.
//!
//! A tensor Chebyshev polynomial of degree [`DEGREE_CONTRACTION`] in
//! contraction and [`DEGREE_LOAD`] in load (30 coefficients), each
//! coordinate scaled to `[−1, 1]` over the training range (clamped there
//! outside it), solved by SVD (a record with fewer distinct contractions
//! or loads than the degree gets the minimum-norm solution). It knows no
//! hysteresis: one surface for both branches. A hysteresis model with
//! about ten parameters that predicts held-out pressure worse than this
//! misses static shape, not dynamics.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::record::Sample;

/// Polynomial degree in contraction.
pub const DEGREE_CONTRACTION: usize = 4;
/// Polynomial degree in load.
pub const DEGREE_LOAD: usize = 5;

/// One training point of a surface: a sample's contraction, load and
/// pressure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Contraction.
    pub contraction: f64,
    /// Load, N.
    pub load_n: f64,
    /// Pressure, MPa.
    pub pressure_mpa: f64,
}

/// A fitted reference surface.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceSurface {
    /// Contraction range of the training samples (the scaling's `[−1, 1]`).
    pub contraction_range: (f64, f64),
    /// Load range of the training samples, N.
    pub load_range_n: (f64, f64),
    /// Coefficients, contraction degree major: `c[i·(DEGREE_LOAD+1) + j]`
    /// multiplies `T_i(x̂)·T_j(L̂)`, MPa.
    pub coefficients_mpa: Vec<f64>,
    /// Training samples.
    pub training_samples: usize,
    /// RMS pressure error on the training samples, MPa.
    pub training_rms_mpa: f64,
}

/// `T_0..=T_n` at `t`.
fn chebyshev(t: f64, n: usize, out: &mut [f64]) {
    out[0] = 1.0;
    if n >= 1 {
        out[1] = t;
    }
    for k in 2..=n {
        out[k] = 2.0 * t * out[k - 1] - out[k - 2];
    }
}

fn scaled(v: f64, (lo, hi): (f64, f64)) -> f64 {
    if hi > lo {
        (2.0 * (v - lo) / (hi - lo) - 1.0).clamp(-1.0, 1.0)
    } else {
        0.0
    }
}

const NX: usize = DEGREE_CONTRACTION + 1;
const NL: usize = DEGREE_LOAD + 1;

impl ReferenceSurface {
    fn row(&self, contraction: f64, load_n: f64, out: &mut [f64; NX * NL]) {
        row(
            self.contraction_range,
            self.load_range_n,
            contraction,
            load_n,
            out,
        );
    }

    /// The surface's pressure, MPa.
    pub fn pressure_mpa(&self, contraction: f64, load_n: f64) -> f64 {
        let mut r = [0.0; NX * NL];
        self.row(contraction, load_n, &mut r);
        r.iter()
            .zip(&self.coefficients_mpa)
            .map(|(a, b)| a * b)
            .sum()
    }

    /// Fit to the samples `include` selects; `None` with fewer samples than
    /// coefficients.
    pub fn fit(samples: &[Sample], include: impl Fn(usize) -> bool) -> Option<ReferenceSurface> {
        let used: Vec<Point> = samples
            .iter()
            .enumerate()
            .filter(|(i, _)| include(*i))
            .map(|(_, s)| Point {
                contraction: s.contraction,
                load_n: s.load_n,
                pressure_mpa: s.pressure_mpa,
            })
            .collect();
        Self::fit_points(&used)
    }

    /// [`Self::fit`] to `points`.
    pub fn fit_points(used: &[Point]) -> Option<ReferenceSurface> {
        if used.len() < 2 * NX * NL {
            return None;
        }
        let range = |f: fn(&Point) -> f64| {
            used.iter()
                .map(f)
                .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)))
        };
        let xr = range(|s| s.contraction);
        let lr = range(|s| s.load_n);
        // Normal equations, accumulated row by row (memory independent of
        // the record's length), solved by SVD: the scaled Chebyshev basis
        // keeps them well conditioned, and a record with fewer distinct
        // contractions or loads than the degree gets the minimum-norm
        // solution.
        let m = NX * NL;
        let mut ata = DMatrix::<f64>::zeros(m, m);
        let mut atb = DVector::<f64>::zeros(m);
        let mut r = [0.0; NX * NL];
        for s in used {
            row(xr, lr, s.contraction, s.load_n, &mut r);
            for j in 0..m {
                atb[j] += r[j] * s.pressure_mpa;
                for k in 0..m {
                    ata[(j, k)] += r[j] * r[k];
                }
            }
        }
        let svd = ata.svd(true, true);
        let tol = svd.singular_values.max() * 1e-12;
        let c = svd.solve(&atb, tol).ok()?;
        let mut surface = ReferenceSurface {
            contraction_range: xr,
            load_range_n: lr,
            coefficients_mpa: c.iter().copied().collect(),
            training_samples: used.len(),
            training_rms_mpa: 0.0,
        };
        let sq: f64 = used
            .iter()
            .map(|s| (surface.pressure_mpa(s.contraction, s.load_n) - s.pressure_mpa).powi(2))
            .sum();
        surface.training_rms_mpa = (sq / used.len() as f64).sqrt();
        Some(surface)
    }

    /// The training RMS pressure error, MPa, of the surface fitted with a
    /// second surface beside it that changes sign with the branch
    /// (`branch[i]`: +1 filling, −1 venting; degree 2 in load): the best
    /// smooth static curve with a hysteresis that does not depend on the
    /// rate. `None` with fewer samples than twice its coefficients.
    pub fn training_rms_with_branch_mpa(
        samples: &[Sample],
        branch: &[f64],
        include: impl Fn(usize) -> bool,
    ) -> Option<f64> {
        const NB: usize = 3;
        let m = NX * NL + NX * NB;
        let used: Vec<usize> = (0..samples.len().min(branch.len()))
            .filter(|&i| include(i))
            .collect();
        if used.len() < 2 * m {
            return None;
        }
        let range = |f: fn(&Sample) -> f64| {
            used.iter()
                .map(|&i| f(&samples[i]))
                .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)))
        };
        let (xr, lr) = (range(|s| s.contraction), range(|s| s.load_n));
        let row_of = |i: usize, out: &mut Vec<f64>| {
            let s = &samples[i];
            let mut r = [0.0; NX * NL];
            row(xr, lr, s.contraction, s.load_n, &mut r);
            out.clear();
            out.extend_from_slice(&r);
            for i_x in 0..NX {
                for j in 0..NB {
                    out.push(branch[i] * r[i_x * NL + j]);
                }
            }
        };
        let mut ata = DMatrix::<f64>::zeros(m, m);
        let mut atb = DVector::<f64>::zeros(m);
        let mut r = Vec::with_capacity(m);
        for &i in &used {
            row_of(i, &mut r);
            for j in 0..m {
                atb[j] += r[j] * samples[i].pressure_mpa;
                for k in 0..m {
                    ata[(j, k)] += r[j] * r[k];
                }
            }
        }
        let svd = ata.svd(true, true);
        let tol = svd.singular_values.max() * 1e-12;
        let c = svd.solve(&atb, tol).ok()?;
        let mut sq = 0.0;
        for &i in &used {
            row_of(i, &mut r);
            let p: f64 = r.iter().zip(c.iter()).map(|(a, b)| a * b).sum();
            sq += (p - samples[i].pressure_mpa).powi(2);
        }
        Some((sq / used.len() as f64).sqrt())
    }

    /// RMS pressure error (surface − measured) on the samples `include`
    /// selects, and their number; `None` when it selects none.
    pub fn rms_mpa(
        &self,
        samples: &[Sample],
        include: impl Fn(usize) -> bool,
    ) -> Option<(f64, usize)> {
        let (mut sum, mut n) = (0.0, 0usize);
        for (i, s) in samples.iter().enumerate() {
            if include(i) {
                sum += (self.pressure_mpa(s.contraction, s.load_n) - s.pressure_mpa).powi(2);
                n += 1;
            }
        }
        (n > 0).then(|| ((sum / n as f64).sqrt(), n))
    }
}

fn row(xr: (f64, f64), lr: (f64, f64), x: f64, l: f64, out: &mut [f64; NX * NL]) {
    let (mut tx, mut tl) = ([0.0; NX], [0.0; NL]);
    chebyshev(scaled(x, xr), DEGREE_CONTRACTION, &mut tx);
    chebyshev(scaled(l, lr), DEGREE_LOAD, &mut tl);
    for i in 0..NX {
        for j in 0..NL {
            out[i * NL + j] = tx[i] * tl[j];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polynomial_surface_is_recovered_and_clamped_outside() {
        let truth = |x: f64, l: f64| 0.1 + 2.0 * x * x + 0.001 * l - 1e-6 * l * l * x;
        let samples: Vec<Sample> = (0..2000)
            .map(|i| {
                let x = 0.02 * f64::from(i % 10);
                let l = f64::from(i / 10) * 2.0;
                Sample {
                    t_s: f64::from(i),
                    load_n: l,
                    pressure_mpa: truth(x, l),
                    contraction: x,
                }
            })
            .collect();
        let s = ReferenceSurface::fit(&samples, |i| (i / 10) % 2 == 0).unwrap();
        assert!(s.training_rms_mpa < 1e-9, "{}", s.training_rms_mpa);
        let (rms, n) = s
            .rms_mpa(&samples, |i| (i / 10) % 2 == 1 && i < 1990)
            .unwrap();
        assert!(s.rms_mpa(&samples, |_| false).is_none());
        assert_eq!(n, 990);
        assert!(rms < 1e-9, "{rms}");
        // Beyond the training range the surface holds its edge.
        assert_eq!(s.pressure_mpa(0.18, 1e4), s.pressure_mpa(0.18, 398.0));
        assert!(ReferenceSurface::fit(&samples[..10], |_| true).is_none());
    }
}

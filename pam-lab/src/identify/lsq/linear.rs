//! Linear least squares from accumulated normal equations, with a small
//! ridge: the models that are linear in their coefficients (the Preisach
//! model's relay weights; bench-m4's play-operator baselines).

use nalgebra::{DMatrix, DVector};

/// The normal equations `AᵀA·x = Aᵀy` of one problem, accumulated a row
/// at a time (the upper triangle of `AᵀA` only).
#[derive(Clone, Debug)]
pub struct NormalEquations {
    ata: DMatrix<f64>,
    aty: DVector<f64>,
    rows: usize,
}

impl NormalEquations {
    /// For `m` coefficients.
    pub fn new(m: usize) -> NormalEquations {
        NormalEquations {
            ata: DMatrix::zeros(m, m),
            aty: DVector::zeros(m),
            rows: 0,
        }
    }

    /// Add the row `row` with its target `y` (its zero entries cost
    /// nothing).
    pub fn add(&mut self, row: &[f64], y: f64) {
        let m = row.len().min(self.aty.len());
        for (i, &ri) in row.iter().enumerate().take(m) {
            if ri == 0.0 {
                continue;
            }
            for (j, &rj) in row.iter().enumerate().take(m).skip(i) {
                self.ata[(i, j)] += ri * rj;
            }
            self.aty[i] += ri * y;
        }
        self.rows += 1;
    }

    /// Rows added.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The least-squares coefficients with a ridge of `ridge` times the
    /// mean of the diagonal on every coefficient but the first (the
    /// bias): a coefficient no row moves gets 0 instead of an arbitrary
    /// value. Cholesky, or an SVD where that fails.
    pub fn solve(&self, ridge: f64) -> Result<Vec<f64>, String> {
        let mut a = self.ata.clone();
        let m = a.nrows();
        for i in 0..m {
            for j in 0..i {
                a[(i, j)] = a[(j, i)];
            }
        }
        let mean_diag = (0..m).map(|i| a[(i, i)]).sum::<f64>() / m.max(1) as f64;
        for i in 1..m {
            a[(i, i)] += ridge * mean_diag;
        }
        let x = match a.clone().cholesky() {
            Some(c) => c.solve(&self.aty),
            None => a
                .svd(true, true)
                .solve(&self.aty, 1e-12)
                .map_err(|e| format!("least squares failed: {e}"))?,
        };
        Ok(x.iter().copied().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_is_recovered_and_an_unused_coefficient_is_zero() {
        let mut ne = NormalEquations::new(3);
        for k in 0..50 {
            let x = k as f64 / 10.0;
            ne.add(&[1.0, x, 0.0], 0.5 + 2.0 * x);
        }
        assert_eq!(ne.rows(), 50);
        let c = ne.solve(1e-9).unwrap();
        assert!(
            (c[0] - 0.5).abs() < 1e-6 && (c[1] - 2.0).abs() < 1e-6,
            "{c:?}"
        );
        assert_eq!(c[2], 0.0);
    }
}

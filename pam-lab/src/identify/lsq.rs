//! Least-squares plumbing shared by the fits: the forward-difference
//! Jacobian, its columns shared between two threads (the machines this
//! runs on have at least two cores).

use nalgebra::DMatrix;

/// Forward-difference Jacobian of `residuals` (which writes `m` residuals
/// for a parameter vector) at `theta`, with step `steps[j]` for parameter
/// `j`: one residual evaluation per parameter plus the base point.
pub fn forward_difference_jacobian(
    theta: &[f64],
    steps: &[f64],
    m: usize,
    residuals: &(dyn Fn(&[f64], &mut [f64]) + Sync),
) -> DMatrix<f64> {
    let n = theta.len();
    let mut base = vec![0.0; m];
    residuals(theta, &mut base);
    let mut jac = DMatrix::zeros(m, n);
    let (left, right): (Vec<_>, Vec<_>) = jac
        .as_mut_slice()
        .chunks_mut(m)
        .enumerate()
        .partition(|(j, _)| j % 2 == 0);
    let work = |list: Vec<(usize, &mut [f64])>| {
        let mut t = theta.to_vec();
        for (j, col) in list {
            let step = steps.get(j).copied().unwrap_or(1e-7);
            t[j] = theta[j] + step;
            residuals(&t, col);
            t[j] = theta[j];
            for (c, b) in col.iter_mut().zip(&base) {
                *c = (*c - b) / step;
            }
        }
    };
    std::thread::scope(|s| {
        s.spawn(|| work(right));
        work(left);
    });
    jac
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_of_a_known_function() {
        // r(θ) = [θ0², θ0·θ1, sin θ1]
        let f = |t: &[f64], out: &mut [f64]| {
            out[0] = t[0] * t[0];
            out[1] = t[0] * t[1];
            out[2] = t[1].sin();
        };
        let j = forward_difference_jacobian(&[2.0, 0.5], &[1e-7, 1e-7], 3, &f);
        let want = [[4.0, 0.0], [0.5, 2.0], [0.0, 0.5f64.cos()]];
        for r in 0..3 {
            for c in 0..2 {
                assert!(
                    (j[(r, c)] - want[r][c]).abs() < 1e-5,
                    "{r},{c}: {}",
                    j[(r, c)]
                );
            }
        }
    }
}

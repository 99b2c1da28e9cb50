//! Least-squares plumbing shared by the fits: one adapter from a residual
//! function to the `levenberg-marquardt` crate ([`minimize`]), and the
//! forward-difference Jacobian, its columns shared between two threads
//! (the machines this runs on have at least two cores).

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A least-squares problem as the fits state it: `m` residuals of a
/// parameter vector, written by `residuals`, and the finite-difference step
/// of each parameter at a point.
pub struct Residuals<'a> {
    /// Number of residuals.
    pub m: usize,
    /// Writes the residuals at a parameter vector into its `m`-slice.
    pub residuals: &'a (dyn Fn(&[f64], &mut [f64]) + Sync),
    /// The forward-difference step of parameter `j` at value `v`.
    pub step: &'a (dyn Fn(usize, f64) -> f64 + Sync),
    /// Hears every evaluation: its count and cost `½·Σr²`.
    pub on_evaluation: &'a (dyn Fn(usize, f64) + Sync),
    /// What a non-finite residual means.
    pub non_finite: NonFinite,
}

/// What a non-finite residual (a point where the model breaks) means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NonFinite {
    /// A bad point: the residual is 10⁶ and the optimiser moves on.
    Penalise,
    /// No point: the optimiser's step there fails (the crate shrinks it).
    Refuse,
}

impl Residuals<'_> {
    /// The residuals at `theta`; `false` when they are not usable.
    fn eval(&self, theta: &[f64], out: &mut [f64]) -> bool {
        (self.residuals)(theta, out);
        match self.non_finite {
            NonFinite::Penalise => {
                for v in out.iter_mut() {
                    if !v.is_finite() {
                        *v = 1e6;
                    }
                }
                true
            }
            NonFinite::Refuse => out.iter().all(|v| v.is_finite()),
        }
    }
}

/// What [`minimize`] found.
#[derive(Debug)]
pub struct Minimum {
    /// The best point.
    pub theta: Vec<f64>,
    /// `½·Σr²` there.
    pub cost: f64,
    /// Residual evaluations spent.
    pub evaluations: usize,
    /// The optimiser's termination reason.
    pub termination: TerminationReason,
}

impl Minimum {
    /// Whether the result is usable: converged, or out of patience (the
    /// best point found is still the best point); other terminations are
    /// numerical failures.
    pub fn usable(&self) -> bool {
        self.termination.was_successful()
            || matches!(self.termination, TerminationReason::LostPatience)
    }
}

struct Adapter<'a, 'b> {
    theta: DVector<f64>,
    problem: &'b Residuals<'a>,
    evaluations: AtomicUsize,
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Adapter<'_, '_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.theta.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let mut r = DVector::zeros(self.problem.m);
        let usable = self.problem.eval(self.theta.as_slice(), r.as_mut_slice());
        let count = 1 + self.evaluations.fetch_add(1, Ordering::Relaxed);
        (self.problem.on_evaluation)(count, 0.5 * r.norm_squared());
        usable.then_some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let theta: Vec<f64> = self.theta.iter().copied().collect();
        let steps: Vec<f64> = theta
            .iter()
            .enumerate()
            .map(|(j, &v)| (self.problem.step)(j, v))
            .collect();
        let jac = forward_difference_jacobian(&theta, &steps, self.problem.m, &|t, out| {
            self.problem.eval(t, out);
        });
        jac.iter().all(|v| v.is_finite()).then_some(jac)
    }
}

/// Levenberg–Marquardt from `theta0` with the given patience (the crate's
/// limit on evaluations, a multiple of the parameter count).
pub fn minimize(problem: &Residuals<'_>, theta0: &[f64], patience: usize) -> Minimum {
    let adapter = Adapter {
        theta: DVector::from_column_slice(theta0),
        problem,
        evaluations: AtomicUsize::new(0),
    };
    let (adapter, report) = LevenbergMarquardt::new()
        .with_patience(patience)
        .minimize(adapter);
    Minimum {
        theta: adapter.theta.iter().copied().collect(),
        cost: report.objective_function,
        evaluations: adapter.evaluations.load(Ordering::Relaxed),
        termination: report.termination,
    }
}

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

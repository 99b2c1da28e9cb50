//! Levenberg–Marquardt on the normal equations, for tall problems whose
//! parameters each move a block of the rows ([`super::Blocks`]): the stroke
//! table's 66 variables over tens of thousands of samples.
//!
//! The crate's MINPACK algorithm ([`super::minimize`]) factors the whole
//! `m × n` Jacobian by a pivoted QR at every iteration: `2·m·n²` operations,
//! 78 % of `pam-lab fit`'s time on a 100 000-row record (perf). Here the
//! step comes from the `n × n` normal equations `(JᵀJ + λ·D²)·δ = −Jᵀr`,
//! formed over each column pair's shared rows only (a table load's columns
//! meet its neighbours' only), and solved by Cholesky: about
//! `m·n²/(2·blocks)` operations. The squared condition number is harmless
//! where the damping `λ·D²` (`D` the running largest column norms, as
//! MINPACK scales) keeps the system positive definite.
//!
//! The damping follows Nielsen's rule: after a step the gain ratio `ρ`
//! (actual over predicted reduction) shrinks `λ` by `max(1/3, 1 − (2ρ −
//! 1)³)`; a step that does not lower the cost is refused and `λ` grows by
//! a factor that doubles with each refusal. It stops as MINPACK's `ftol`
//! and `xtol` do (relative reductions, actual and predicted, both below
//! `√ε`; a step below `√ε` of the scaled parameters), where the cost has
//! stalled as [`super::minimize`] judges it ([`super::STALL_JACOBIANS`]),
//! or at the limits' evaluations and Jacobians. Without the stall rule a
//! heavily damped search crept on with each step's predicted reduction
//! just above `√ε`: fit's stroke table on diagnose's training part of
//! Festo 40 cm took 1 211 Jacobians (19 s) to lower its cost by 1.8 %, a
//! Jacobian each step (the patience counts the trial evaluations only).

use super::{jacobian, stalled, Limits, Minimum, Residuals};
use levenberg_marquardt::TerminationReason;
use nalgebra::{DMatrix, DVector};

/// Converged as MINPACK's `ftol` judges it: the cost cannot fall by more
/// than the tolerance (a refused step the model itself predicted within
/// it), or has stalled.
const COST_CONVERGED: TerminationReason = TerminationReason::Converged {
    ftol: true,
    xtol: false,
};

/// MINPACK's default `ftol` and `xtol`, `√ε`.
const TOLERANCE: f64 = 1.490_116_119_384_765_6e-8;

/// The first damping, relative to each column's own `JᵀJ` diagonal (the
/// damping term is `λ·D²`, `D` the columns' norms): Marquardt's `10⁻³`.
/// A damping in the units of `JᵀJ` (`10⁻³` of its largest diagonal entry,
/// as this was) holds every column back by the largest one's scale: with
/// the stroke ends' shifts, whose columns near the stroke's end are 10⁶
/// times the table's, the first step moved nothing, and the search stopped
/// there as converged.
const FIRST_DAMPING: f64 = 1e-3;

/// Largest damping before the step is given up (the cost cannot be lowered
/// along any direction the Jacobian sees).
const MAX_DAMPING: f64 = 1e16;

/// Levenberg–Marquardt from `theta0` (projected onto the bounds first)
/// within `limits`, each step from the normal equations. A trial point
/// whose residuals are not all finite is a refused step (with
/// [`super::NonFinite::Refuse`] too). `limits.first_step` is not used: the
/// first damping is `FIRST_DAMPING`, `10⁻³` of each column's own scale.
pub fn minimize_normal(
    problem: &Residuals<'_>,
    theta0: &[f64],
    limits: impl Into<Limits>,
) -> Minimum {
    let limits = limits.into();
    let n = theta0.len();
    let mut theta = theta0.to_vec();
    problem.project(&mut theta);
    let count = std::cell::Cell::new(0usize);
    let evaluate = |t: &[f64], out: &mut [f64]| -> Option<f64> {
        let finite = problem.eval(t, out);
        count.set(count.get() + 1);
        let cost = 0.5 * out.iter().map(|v| v * v).sum::<f64>();
        (problem.on_evaluation)(count.get(), cost);
        (finite || problem.non_finite != super::NonFinite::Refuse).then_some(cost)
    };
    let mut r = vec![0.0; problem.m];
    let first = evaluate(&theta, &mut r);
    let done = |theta: Vec<f64>, cost: f64, termination| Minimum {
        theta,
        cost,
        evaluations: count.get(),
        termination,
    };
    let Some(mut cost) = first else {
        return done(theta, f64::NAN, TerminationReason::User("residuals"));
    };
    if limits.patience == 0 || limits.iterations == Some(0) {
        return done(theta, cost, TerminationReason::LostPatience);
    }
    if n == 0 {
        return done(theta, cost, TerminationReason::NoParameters);
    }
    if problem.m == 0 {
        return done(theta, cost, TerminationReason::NoResiduals);
    }
    let max_evaluations = limits.patience.saturating_mul(n + 1);
    let mut scale = vec![0.0f64; n];
    let mut damping: Option<f64> = None;
    let mut growth = 2.0;
    let mut jacobians = 0usize;
    // The cost at each Jacobian: a stall ends the search as it ends
    // [`super::minimize`]'s ([`super::STALL_JACOBIANS`]).
    let mut history = Vec::new();
    let mut trial = vec![0.0; n];
    let mut r_trial = vec![0.0; problem.m];
    loop {
        if cost == 0.0 {
            return done(theta, cost, TerminationReason::ResidualsZero);
        }
        if limits.iterations.is_some_and(|k| jacobians >= k) {
            return done(theta, cost, TerminationReason::LostPatience);
        }
        if stalled(&history, cost) {
            return done(theta, cost, COST_CONVERGED);
        }
        history.push(cost);
        jacobians += 1;
        let (jac, held) = jacobian(problem, &theta);
        if !jac.iter().all(|v| v.is_finite()) {
            return done(theta, cost, TerminationReason::User("jacobian"));
        }
        let (a, g) = normal_equations(problem, &jac, &r);
        for (j, s) in scale.iter_mut().enumerate() {
            *s = s.max(a[(j, j)].max(0.0).sqrt());
        }
        if g.iter().all(|v| *v == 0.0) {
            return done(theta, cost, TerminationReason::Orthogonal);
        }
        let lambda = damping.get_or_insert(FIRST_DAMPING);
        loop {
            if count.get() >= max_evaluations {
                return done(theta, cost, TerminationReason::LostPatience);
            }
            let Some(step) = damped_step(&a, &g, &scale, &held, *lambda) else {
                *lambda *= growth;
                growth *= 2.0;
                if *lambda > MAX_DAMPING {
                    return done(
                        theta,
                        cost,
                        TerminationReason::NoImprovementPossible("damping"),
                    );
                }
                continue;
            };
            for ((t, v), s) in trial.iter_mut().zip(&theta).zip(step.iter()) {
                *t = v + s;
            }
            problem.project(&mut trial);
            // The step as taken (the bounds may have shortened it).
            let taken = DVector::from_iterator(n, trial.iter().zip(&theta).map(|(t, v)| t - v));
            let predicted = -(g.dot(&taken) + 0.5 * taken.dot(&(&a * &taken)));
            let new_cost = evaluate(&trial, &mut r_trial);
            let step_norm = scaled_norm(&scale, taken.iter().copied());
            let theta_norm = scaled_norm(&scale, theta.iter().copied());
            match new_cost {
                Some(c) if c < cost => {
                    let rho = if predicted > 0.0 {
                        (cost - c) / predicted
                    } else {
                        1.0
                    };
                    *lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                    growth = 2.0;
                    let ftol = (cost - c) / cost <= TOLERANCE && predicted / cost <= TOLERANCE;
                    let xtol = step_norm <= TOLERANCE * theta_norm;
                    std::mem::swap(&mut theta, &mut trial);
                    std::mem::swap(&mut r, &mut r_trial);
                    cost = c;
                    if ftol || xtol {
                        return done(theta, cost, TerminationReason::Converged { ftol, xtol });
                    }
                    break;
                }
                _ => {
                    // Refused: the cost did not fall. Where even the
                    // model's own prediction is within the tolerance, the
                    // point is converged.
                    if predicted >= 0.0 && predicted / cost <= TOLERANCE {
                        return done(theta, cost, COST_CONVERGED);
                    }
                    if step_norm <= TOLERANCE * theta_norm {
                        return done(
                            theta,
                            cost,
                            TerminationReason::Converged {
                                ftol: false,
                                xtol: true,
                            },
                        );
                    }
                    *lambda *= growth;
                    growth *= 2.0;
                }
            }
        }
    }
}

/// `‖D·v‖`.
fn scaled_norm(scale: &[f64], v: impl Iterator<Item = f64>) -> f64 {
    scale
        .iter()
        .zip(v)
        .map(|(s, x)| (s * x) * (s * x))
        .sum::<f64>()
        .sqrt()
}

/// `JᵀJ` and `Jᵀr`, each column pair over the rows both move (all rows
/// without [`super::Blocks`]).
fn normal_equations(
    problem: &Residuals<'_>,
    jac: &DMatrix<f64>,
    r: &[f64],
) -> (DMatrix<f64>, DVector<f64>) {
    let (m, n) = jac.shape();
    let rows = |j: usize| match &problem.blocks {
        Some(b) => {
            let k = (b.of)(j);
            k.start.min(m)..k.end.min(m)
        }
        None => 0..m,
    };
    let ranges: Vec<_> = (0..n).map(rows).collect();
    let mut a = DMatrix::zeros(n, n);
    let mut g = DVector::zeros(n);
    for p in 0..n {
        let cp = jac.column(p);
        let cp = cp.as_slice();
        let rp = ranges[p].clone();
        g[p] = cp[rp.clone()]
            .iter()
            .zip(&r[rp.clone()])
            .map(|(x, y)| x * y)
            .sum();
        for q in p..n {
            let rq = &ranges[q];
            let (lo, hi) = (rp.start.max(rq.start), rp.end.min(rq.end));
            if lo >= hi {
                continue;
            }
            let cq = jac.column(q);
            let v: f64 = cp[lo..hi]
                .iter()
                .zip(&cq.as_slice()[lo..hi])
                .map(|(x, y)| x * y)
                .sum();
            a[(p, q)] = v;
            a[(q, p)] = v;
        }
    }
    (a, g)
}

/// The damped step `−(A + λ·D²)⁻¹·g`, held parameters fixed (their rows and
/// columns the identity, their step zero); `None` when the damped system is
/// not positive definite.
fn damped_step(
    a: &DMatrix<f64>,
    g: &DVector<f64>,
    scale: &[f64],
    held: &[bool],
    lambda: f64,
) -> Option<DVector<f64>> {
    let n = g.len();
    let mut m = a.clone();
    let mut rhs = -g.clone();
    for j in 0..n {
        if held.get(j).copied().unwrap_or(false) || scale[j] == 0.0 {
            m.row_mut(j).fill(0.0);
            m.column_mut(j).fill(0.0);
            m[(j, j)] = 1.0;
            rhs[j] = 0.0;
        } else {
            m[(j, j)] += lambda * scale[j] * scale[j];
        }
    }
    let step = m.cholesky()?.solve(&rhs);
    step.iter().all(|v| v.is_finite()).then_some(step)
}

#[cfg(test)]
mod tests {
    use super::super::{NonFinite, Residuals};
    use super::*;

    /// The Rosenbrock valley as residuals `(10·(y − x²), 1 − x)`.
    fn rosenbrock(t: &[f64], out: &mut [f64]) {
        out[0] = 10.0 * (t[1] - t[0] * t[0]);
        out[1] = 1.0 - t[0];
    }

    fn problem<'a>(m: usize, f: &'a (dyn Fn(&[f64], &mut [f64]) + Sync)) -> Residuals<'a> {
        Residuals {
            m,
            residuals: f,
            step: &|_, v| 1e-7 * v.abs().max(1.0),
            on_evaluation: &|_, _| {},
            non_finite: NonFinite::Penalise,
            bounds: None,
            blocks: None,
        }
    }

    #[test]
    fn it_finds_the_bottom_of_rosenbrocks_valley() {
        let m = minimize_normal(&problem(2, &rosenbrock), &[-1.2, 1.0], 100);
        assert!(m.usable(), "{:?}", m.termination);
        assert!(
            (m.theta[0] - 1.0).abs() < 1e-5 && (m.theta[1] - 1.0).abs() < 1e-5,
            "{:?}",
            m.theta
        );
        assert!(m.cost < 1e-12, "{}", m.cost);
    }

    #[test]
    fn a_search_that_only_creeps_stops_at_a_stall() {
        // Each evaluation lowers the cost by 2·10⁻⁸ of itself wherever it
        // is (the creep of a heavily damped search, fit's stroke table on
        // Festo 40 cm's training part, whose steps lowered the cost by
        // 10⁻⁸ of itself for 1 211 Jacobians): above `√ε`, so MINPACK's
        // `ftol` never ends it, and the patience counts only the trial
        // evaluations. The stall rule ends it after `STALL_JACOBIANS`.
        let evaluations = std::sync::atomic::AtomicUsize::new(0);
        let f = |t: &[f64], out: &mut [f64]| {
            let k = evaluations.fetch_add(1, std::sync::atomic::Ordering::Relaxed) as f64;
            out[0] = 1e3 * (1.0 - 1e-8 * k);
            out[1] = 1e-3 * t[0];
        };
        let m = minimize_normal(&problem(2, &f), &[1.0], 1000);
        assert!(
            matches!(
                m.termination,
                TerminationReason::Converged {
                    ftol: true,
                    xtol: false
                }
            ),
            "{:?} after {} evaluations",
            m.termination,
            m.evaluations
        );
        assert!(m.evaluations < 100, "{}", m.evaluations);
    }

    #[test]
    fn it_agrees_with_the_crate_on_a_tall_blocked_fit() {
        // Two exponentials, each over its half of 2 000 samples (the
        // blocks), and a shared offset over all.
        let xs: Vec<f64> = (0..2000).map(|i| (i % 1000) as f64 / 1000.0).collect();
        let f = |t: &[f64], out: &mut [f64]| {
            for (i, (o, x)) in out.iter_mut().zip(&xs).enumerate() {
                let (a, b) = if i < 1000 { (t[0], t[1]) } else { (t[2], t[3]) };
                let truth = if i < 1000 {
                    2.0 * (-1.5 * x).exp()
                } else {
                    0.5 * (0.7 * x).exp()
                };
                *o = a * (b * x).exp() + t[4] - truth - 0.3 - 0.01 * ((i * 7919) % 13) as f64;
            }
        };
        let rows = |i: usize, range: std::ops::Range<usize>, t: &[f64], out: &mut [f64]| {
            let mut all = vec![0.0; 2000];
            f(t, &mut all);
            out.copy_from_slice(&all[range]);
            let _ = i;
        };
        let of = |j: usize| match j {
            0 | 1 => 0..1000,
            2 | 3 => 1000..2000,
            _ => 0..2000,
        };
        let row_residuals =
            |t: &[f64], range: std::ops::Range<usize>, out: &mut [f64]| rows(0, range, t, out);
        let mut p = problem(2000, &f);
        p.blocks = Some(super::super::Blocks {
            of: &of,
            residuals: &row_residuals,
        });
        let start = [1.0, -1.0, 1.0, 1.0, 0.0];
        let ours = minimize_normal(&p, &start, 100);
        let crate_ = super::super::minimize(&p, &start, 100);
        assert!(ours.usable() && crate_.usable());
        assert!(
            (ours.cost - crate_.cost).abs() <= 1e-9 * crate_.cost.max(1e-12),
            "{} {}",
            ours.cost,
            crate_.cost
        );
        for (a, b) in ours.theta.iter().zip(&crate_.theta) {
            assert!((a - b).abs() < 1e-5, "{:?} {:?}", ours.theta, crate_.theta);
        }
    }
}

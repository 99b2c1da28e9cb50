//! Least-squares plumbing shared by the fits: one adapter from a residual
//! function to the `levenberg-marquardt` crate ([`minimize`]), with
//! optional bounds on the parameters, limits on its iterations and first
//! step, and a choice of what a point where the model breaks means, and the
//! finite-difference
//! Jacobian, its columns shared between two threads (the machines this
//! runs on have at least two cores), each column evaluated on the rows its
//! parameter moves where the problem says which ([`Blocks`]: the stroke
//! table's loads). [`minimize_normal`] takes its steps from the normal
//! equations instead, for the tall blocked problem of the stroke table;
//! [`linear`] solves the models linear in their coefficients.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt, TerminationReason};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use std::cell::{Cell, RefCell};
use std::ops::Range;
use std::sync::atomic::{AtomicUsize, Ordering};

pub mod linear;
mod normal_equations;
pub use normal_equations::minimize_normal;

/// A least-squares problem as the fits state it: `m` residuals of a
/// parameter vector, written by `residuals`, and the finite-difference step
/// of each parameter at a point.
pub struct Residuals<'a> {
    /// Number of residuals.
    pub m: usize,
    /// Writes the residuals at a parameter vector into its `m`-slice.
    pub residuals: &'a (dyn Fn(&[f64], &mut [f64]) + Sync),
    /// The forward-difference step of parameter `j` at value `v` (taken
    /// backwards where a forward step would pass the parameter's upper
    /// bound, or, with [`NonFinite::Edge`], leave the valid points).
    pub step: &'a (dyn Fn(usize, f64) -> f64 + Sync),
    /// Hears every evaluation: its count and cost `½·Σr²`.
    pub on_evaluation: &'a (dyn Fn(usize, f64) + Sync),
    /// What a non-finite residual means.
    pub non_finite: NonFinite,
    /// Bounds `(lo, hi)` on each parameter (infinite for none), or `None`
    /// when no parameter has any. The start and every trial point are
    /// projected onto them (each parameter clamped), so that the point
    /// found lies within them; a parameter with `lo == hi` is held there
    /// (its Jacobian column is zero and not simulated), and one on a bound
    /// whose descent direction points out of its range is held for the
    /// iteration (the bound is active: solved free, the other parameters'
    /// step would count on a move of it that the projection takes back).
    pub bounds: Option<&'a [(f64, f64)]>,
    /// For a problem whose parameters each move a block of the residuals
    /// only: the finite-difference Jacobian evaluates each column on its
    /// block (the same derivatives: the other rows' differences are exactly
    /// zero). `None`: every column evaluates every residual.
    pub blocks: Option<Blocks<'a>>,
}

/// Writes the residuals of a range of rows at a parameter vector into the
/// range's slice.
pub type RowResiduals<'a> = &'a (dyn Fn(&[f64], Range<usize>, &mut [f64]) + Sync);

/// The residual rows each parameter moves ([`Residuals::blocks`]).
pub struct Blocks<'a> {
    /// The rows parameter `j` can move; every other row's derivative is
    /// exactly zero.
    pub of: &'a (dyn Fn(usize) -> Range<usize> + Sync),
    /// Writes the residuals of `rows` at a parameter vector into its
    /// `rows.len()`-slice, as `Residuals::residuals` writes them there.
    pub residuals: RowResiduals<'a>,
}

/// What a non-finite residual (a point where the model breaks) means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NonFinite {
    /// A bad point: the residual is 10⁶ and the optimiser moves on.
    Penalise,
    /// No point: a trial step there ends the minimisation (the crate's
    /// `User("residuals")`: the point returned is then that trial point,
    /// the cost the last accepted one's), and a Jacobian column there fails
    /// it (`User("jacobian")`, at the last accepted point).
    Refuse,
    /// The edge of the valid points: a trial step past it is a bad point
    /// to the optimiser (its residuals 10⁶: the crate shrinks the step, and
    /// never accepts it from a valid point), a parameter whose forward step
    /// leaves the valid points is differenced backwards, and one that can
    /// move neither way is held for the iteration (its Jacobian column
    /// zero).
    Edge,
}

impl Residuals<'_> {
    /// The residuals at `theta`; `false` when they are not all finite
    /// (with [`NonFinite::Penalise`] and [`NonFinite::Edge`] the non-finite
    /// ones are then 10⁶).
    fn eval(&self, theta: &[f64], out: &mut [f64]) -> bool {
        (self.residuals)(theta, out);
        self.mark_non_finite(out)
    }

    /// [`Self::eval`] on `rows` only, into their slice `out`.
    fn eval_rows(&self, theta: &[f64], rows: Range<usize>, out: &mut [f64]) -> bool {
        match &self.blocks {
            Some(b) => (b.residuals)(theta, rows, out),
            None => return self.eval(theta, out),
        }
        self.mark_non_finite(out)
    }

    /// Non-finite residuals in `out` made 10⁶ (unless they are refused);
    /// `false` when there were any.
    fn mark_non_finite(&self, out: &mut [f64]) -> bool {
        let mut finite = true;
        for v in out.iter_mut() {
            if !v.is_finite() {
                finite = false;
                if self.non_finite != NonFinite::Refuse {
                    *v = 1e6;
                }
            }
        }
        finite
    }

    /// Whether the residuals are usable when not all finite.
    fn usable(&self, finite: bool) -> bool {
        finite || self.non_finite != NonFinite::Refuse
    }

    /// The bounds of parameter `j`.
    fn bound(&self, j: usize) -> (f64, f64) {
        self.bounds
            .and_then(|b| b.get(j).copied())
            .unwrap_or((f64::NEG_INFINITY, f64::INFINITY))
    }

    /// `theta` clamped onto the bounds.
    fn project(&self, theta: &mut [f64]) {
        if self.bounds.is_none() {
            return;
        }
        for (j, v) in theta.iter_mut().enumerate() {
            let (lo, hi) = self.bound(j);
            if *v < lo {
                *v = lo;
            } else if *v > hi {
                *v = hi;
            }
        }
    }
}

/// Jacobians over which [`minimize`] judges a stall: when the best cost
/// found has fallen by less than [`STALL_TOLERANCE`] of itself over this
/// many, it stops (converged as MINPACK's `ftol` judges one step). The
/// paper's model fitted on a whole 103 500-row record crawled along its
/// feasible set's edge for 885 Jacobians, 28 s, the cost falling by
/// 1.7·10⁻⁶ of itself after the first 25.
pub const STALL_JACOBIANS: usize = 10;

/// The relative fall of the cost over [`STALL_JACOBIANS`] below which the
/// minimisation has stalled.
pub const STALL_TOLERANCE: f64 = 1e-6;

/// How long [`minimize`] may run, and how far its first step may go.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// The crate's patience: its limit on evaluations at trial points,
    /// this times the parameter count plus one. Zero runs nothing (the
    /// start is the point found).
    pub patience: usize,
    /// Most Jacobians computed (the iterations: each is followed by the
    /// trial steps to one accepted step), or `None` for no limit.
    pub iterations: Option<usize>,
    /// The first trust region's radius, as a multiple of the norm of the
    /// parameters scaled by their Jacobian columns (the crate's
    /// `stepbound`), or `None` for the crate's 100. A refinement of a
    /// fitted point on an ill-conditioned Jacobian wants a few: its first
    /// Gauss–Newton step is otherwise tried whole, wild, and shrunk back
    /// only after failing.
    pub first_step: Option<f64>,
}

impl From<usize> for Limits {
    /// The given patience, iterations and first step the crate's.
    fn from(patience: usize) -> Self {
        Limits {
            patience,
            iterations: None,
            first_step: None,
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
    /// The optimiser's termination reason (`LostPatience` too when the
    /// [`Limits`]'s iterations ran out).
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
    /// The point of the last Jacobian (the crate's current point), and the
    /// parameters held there (see [`Residuals::bounds`], [`NonFinite::Edge`]).
    last: RefCell<(Vec<f64>, Vec<bool>)>,
    /// Jacobians computed, the most allowed, and whether one more was
    /// refused for that.
    jacobians: Cell<usize>,
    max_jacobians: Option<usize>,
    out_of_iterations: Cell<bool>,
    /// The lowest cost evaluated, the lowest at each Jacobian, and whether
    /// a Jacobian was refused for a stall ([`STALL_JACOBIANS`]).
    best: Cell<f64>,
    best_at_jacobian: RefCell<Vec<f64>>,
    stalled: Cell<bool>,
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Adapter<'_, '_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.theta.copy_from(x);
        let (at, held) = &*self.last.borrow();
        for (j, v) in self.theta.iter_mut().enumerate() {
            if let (true, Some(&a)) = (held.get(j).copied().unwrap_or(false), at.get(j)) {
                *v = a;
            }
        }
        self.problem.project(self.theta.as_mut_slice());
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let mut r = DVector::zeros(self.problem.m);
        let finite = self.problem.eval(self.theta.as_slice(), r.as_mut_slice());
        let count = 1 + self.evaluations.fetch_add(1, Ordering::Relaxed);
        let cost = 0.5 * r.norm_squared();
        (self.problem.on_evaluation)(count, cost);
        if finite && cost < self.best.get() {
            self.best.set(cost);
        }
        self.problem.usable(finite).then_some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let count = self.jacobians.get() + 1;
        if self.max_jacobians.is_some_and(|max| count > max) {
            self.out_of_iterations.set(true);
            return None;
        }
        let best = self.best.get();
        {
            let mut history = self.best_at_jacobian.borrow_mut();
            if stalled(&history, best) {
                self.stalled.set(true);
                return None;
            }
            history.push(best);
        }
        self.jacobians.set(count);
        let theta: Vec<f64> = self.theta.iter().copied().collect();
        let (jac, held) = jacobian(self.problem, &theta);
        *self.last.borrow_mut() = (theta, held);
        jac.iter().all(|v| v.is_finite()).then_some(jac)
    }
}

/// Whether the best cost `best` has fallen by at most [`STALL_TOLERANCE`]
/// of itself since the best at the Jacobian [`STALL_JACOBIANS`] back in
/// `history` (the best cost at each Jacobian so far).
fn stalled(history: &[f64], best: f64) -> bool {
    history
        .len()
        .checked_sub(STALL_JACOBIANS)
        .and_then(|k| history.get(k))
        .is_some_and(|&then| best.is_finite() && then - best <= STALL_TOLERANCE * then.abs())
}

/// Levenberg–Marquardt from `theta0` (projected onto the bounds first)
/// within `limits` (a patience alone, or [`Limits`]).
pub fn minimize(problem: &Residuals<'_>, theta0: &[f64], limits: impl Into<Limits>) -> Minimum {
    let limits = limits.into();
    let mut start = theta0.to_vec();
    problem.project(&mut start);
    let adapter = Adapter {
        theta: DVector::from_column_slice(&start),
        problem,
        evaluations: AtomicUsize::new(0),
        last: RefCell::new((Vec::new(), Vec::new())),
        jacobians: Cell::new(0),
        max_jacobians: limits.iterations,
        out_of_iterations: Cell::new(false),
        best: Cell::new(f64::INFINITY),
        best_at_jacobian: RefCell::new(Vec::new()),
        stalled: Cell::new(false),
    };
    if limits.patience == 0 || limits.iterations == Some(0) {
        let r = adapter.residuals();
        return Minimum {
            theta: start,
            cost: r.map_or(f64::NAN, |r| 0.5 * r.norm_squared()),
            evaluations: adapter.evaluations.load(Ordering::Relaxed),
            termination: TerminationReason::LostPatience,
        };
    }
    let mut lm = LevenbergMarquardt::new().with_patience(limits.patience);
    if let Some(first_step) = limits.first_step {
        lm = lm.with_stepbound(first_step);
    }
    let (adapter, report) = lm.minimize(adapter);
    Minimum {
        theta: adapter.theta.iter().copied().collect(),
        cost: report.objective_function,
        evaluations: adapter.evaluations.load(Ordering::Relaxed),
        termination: if adapter.out_of_iterations.get() {
            TerminationReason::LostPatience
        } else if adapter.stalled.get() {
            TerminationReason::Converged {
                ftol: true,
                xtol: false,
            }
        } else {
            report.termination
        },
    }
}

/// The Jacobian of `problem` at `theta` by finite differences (one residual
/// evaluation per parameter not held, plus the base point), and the
/// parameters held there, whose columns are zero: those a bound fixes, those
/// on an active bound, and with [`NonFinite::Edge`] those that can move
/// neither way (see [`Residuals::bounds`]).
fn jacobian(problem: &Residuals<'_>, theta: &[f64]) -> (DMatrix<f64>, Vec<bool>) {
    let (m, n) = (problem.m, theta.len());
    let mut jac = DMatrix::zeros(m, n);
    let mut held = vec![false; n];
    if m == 0 || n == 0 {
        return (jac, held);
    }
    let mut base = vec![0.0; m];
    problem.eval(theta, &mut base);
    let (left, right): (Vec<_>, Vec<_>) = jac
        .as_mut_slice()
        .chunks_mut(m)
        .zip(held.iter_mut())
        .enumerate()
        .partition(|(j, _)| j % 2 == 0);
    let work = |list: Vec<(usize, (&mut [f64], &mut bool))>| {
        let mut t = theta.to_vec();
        for (j, (col, held)) in list {
            *held = !difference(problem, theta, &base, j, &mut t, col);
        }
    };
    std::thread::scope(|s| {
        s.spawn(|| work(right));
        work(left);
    });
    for (j, held) in held.iter_mut().enumerate() {
        let (lo, hi) = problem.bound(j);
        let descent = -jac
            .column(j)
            .iter()
            .zip(&base)
            .map(|(a, b)| a * b)
            .sum::<f64>();
        if !*held && ((theta[j] <= lo && descent < 0.0) || (theta[j] >= hi && descent > 0.0)) {
            *held = true;
            jac.column_mut(j).fill(0.0);
        }
    }
    (jac, held)
}

/// Column `j` of the Jacobian at `theta`, whose residuals are `base`, into
/// `col` (`t` a copy of `theta`, returned as it was); `false` when the
/// parameter is held (the column zero): fixed by its bounds, or, with
/// [`NonFinite::Edge`], no step either way keeps the residuals finite.
fn difference(
    problem: &Residuals<'_>,
    theta: &[f64],
    base: &[f64],
    j: usize,
    t: &mut [f64],
    col: &mut [f64],
) -> bool {
    let v = theta[j];
    let (lo, hi) = problem.bound(j);
    if lo >= hi {
        col.fill(0.0);
        return false;
    }
    let h = (problem.step)(j, v);
    let forward = if v + h > hi { -h } else { h };
    let edge = problem.non_finite == NonFinite::Edge;
    // The rows the parameter moves; the column is zero elsewhere.
    let rows = match &problem.blocks {
        Some(b) => {
            let r = (b.of)(j);
            r.start.min(col.len())..r.end.min(col.len())
        }
        None => 0..col.len(),
    };
    col.fill(0.0);
    for (k, step) in [forward, -forward].into_iter().enumerate() {
        if k > 0 && (!edge || v + step < lo || v + step > hi) {
            break;
        }
        t[j] = v + step;
        let finite = problem.eval_rows(t, rows.clone(), &mut col[rows.clone()]);
        t[j] = v;
        if finite || !edge {
            for (c, b) in col[rows.clone()].iter_mut().zip(&base[rows.clone()]) {
                *c = (*c - b) / step;
            }
            return true;
        }
    }
    col.fill(0.0);
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    fn problem<'a>(
        m: usize,
        residuals: &'a (dyn Fn(&[f64], &mut [f64]) + Sync),
        non_finite: NonFinite,
        bounds: Option<&'a [(f64, f64)]>,
    ) -> Residuals<'a> {
        Residuals {
            m,
            residuals,
            step: &|_, _| 1e-7,
            on_evaluation: &|_, _| {},
            non_finite,
            bounds,
            blocks: None,
        }
    }

    #[test]
    fn a_stall_is_a_fall_below_the_tolerance_over_the_last_jacobians() {
        let mut history: Vec<f64> = (0..STALL_JACOBIANS).map(|k| 100.0 - k as f64).collect();
        // Ten Jacobians back the best was 100: a fall of 1e-5 of it is not
        // a stall, 1e-7 is.
        assert!(!stalled(&history, 100.0 * (1.0 - 1e-5)));
        assert!(stalled(&history, 100.0 * (1.0 - 1e-7)));
        // Fewer Jacobians than the window: never.
        history.pop();
        assert!(!stalled(&history, 100.0));
        // No finite cost yet: never.
        assert!(!stalled(&[f64::INFINITY; STALL_JACOBIANS], f64::INFINITY));
    }

    #[test]
    fn jacobian_of_a_known_function() {
        // r(θ) = [θ0², θ0·θ1, sin θ1]
        let f = |t: &[f64], out: &mut [f64]| {
            out[0] = t[0] * t[0];
            out[1] = t[0] * t[1];
            out[2] = t[1].sin();
        };
        let (j, held) = jacobian(&problem(3, &f, NonFinite::Penalise, None), &[2.0, 0.5]);
        assert_eq!(held, [false, false]);
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

    #[test]
    fn a_blocked_jacobian_is_the_full_one() {
        // Two parameters each moving its own half of four residuals, the
        // middle two moved by both: evaluated on their blocks, the columns
        // are bit for bit the full differences.
        let row = |t: &[f64], i: usize| match i {
            0 => t[0].sin(),
            1 => t[0] * t[1],
            2 => t[1] * t[1] + t[0],
            _ => t[1].exp(),
        };
        let f = |t: &[f64], out: &mut [f64]| {
            for (i, o) in out.iter_mut().enumerate() {
                *o = row(t, i);
            }
        };
        let of = |j: usize| if j == 0 { 0..3 } else { 1..4 };
        let rows = |t: &[f64], r: Range<usize>, out: &mut [f64]| {
            for (i, o) in r.zip(out.iter_mut()) {
                *o = row(t, i);
            }
        };
        let full = problem(4, &f, NonFinite::Penalise, None);
        let blocked = Residuals {
            blocks: Some(Blocks {
                of: &of,
                residuals: &rows,
            }),
            ..problem(4, &f, NonFinite::Penalise, None)
        };
        let theta = [0.7, -0.3];
        assert_eq!(jacobian(&full, &theta), jacobian(&blocked, &theta));
        assert_eq!(
            minimize(&full, &theta, 50).theta,
            minimize(&blocked, &theta, 50).theta
        );
    }

    #[test]
    fn at_the_edge_a_column_is_differenced_backwards_or_held() {
        // Valid only at θ0 = 1 and θ1 ≤ 1: at (1, 1) θ1 is differenced
        // backwards, and θ0, which can move neither way, is held.
        let f = |t: &[f64], out: &mut [f64]| {
            let valid = t[0] == 1.0 && t[1] <= 1.0;
            out[0] = if valid { t[0] + 2.0 * t[1] } else { f64::NAN };
            out[1] = if valid { t[1] } else { f64::NAN };
        };
        let (j, held) = jacobian(&problem(2, &f, NonFinite::Edge, None), &[1.0, 1.0]);
        assert_eq!(held, [true, false]);
        assert_eq!((j[(0, 0)], j[(1, 0)]), (0.0, 0.0));
        assert!((j[(0, 1)] - 2.0).abs() < 1e-6 && (j[(1, 1)] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_bound_clamps_holds_and_stops_the_step_it_meets() {
        // r = (θ0 - 3, θ1 - 5, θ2 - 7) with θ0 ≤ 2 and θ1 fixed at 1: the
        // minimum within the bounds is (2, 1, 7).
        let f = |t: &[f64], out: &mut [f64]| {
            out[0] = t[0] - 3.0;
            out[1] = t[1] - 5.0;
            out[2] = t[2] - 7.0;
        };
        let bounds = [
            (f64::NEG_INFINITY, 2.0),
            (1.0, 1.0),
            (f64::NEG_INFINITY, f64::INFINITY),
        ];
        let p = problem(3, &f, NonFinite::Penalise, Some(&bounds));
        let min = minimize(&p, &[0.0, 1.0, 0.0], 10);
        assert!(min.usable(), "{:?}", min.termination);
        assert_eq!(min.theta[..2], [2.0, 1.0]);
        assert!((min.theta[2] - 7.0).abs() < 1e-6, "{:?}", min.theta);
        // On its bound with the descent pointing out, θ0 is held.
        let (_, held) = jacobian(&p, &[2.0, 1.0, 0.0]);
        assert_eq!(held, [true, true, false]);
    }

    #[test]
    fn the_iterations_limit_stops_after_that_many_jacobians() {
        // Rosenbrock's valley: far more than two steps from (-1.2, 1).
        let f = |t: &[f64], out: &mut [f64]| {
            out[0] = 10.0 * (t[1] - t[0] * t[0]);
            out[1] = 1.0 - t[0];
        };
        let p = problem(2, &f, NonFinite::Penalise, None);
        let start = [-1.2, 1.0];
        let limits = Limits {
            patience: 100,
            iterations: Some(2),
            first_step: None,
        };
        let two = minimize(&p, &start, limits);
        assert_eq!(two.termination, TerminationReason::LostPatience);
        assert!(two.usable());
        let full = minimize(&p, &start, 100);
        assert!(full.cost < two.cost, "{} vs {}", full.cost, two.cost);
        let none = minimize(
            &p,
            &start,
            Limits {
                iterations: Some(0),
                ..limits
            },
        );
        assert_eq!(none.theta, start);
    }

    #[test]
    fn an_edge_step_is_shrunk_not_taken() {
        // r = θ - 3, valid only below 1: from 0 the point found is valid
        // and close to the edge.
        let f = |t: &[f64], out: &mut [f64]| {
            out[0] = if t[0] < 1.0 { t[0] - 3.0 } else { f64::NAN };
        };
        let p = problem(1, &f, NonFinite::Edge, None);
        let min = minimize(&p, &[0.0], 20);
        assert!(min.theta[0] < 1.0 && min.theta[0] > 0.5, "{:?}", min.theta);
        assert!(min.cost.is_finite() && min.cost < 0.5 * 9.0);
    }
}

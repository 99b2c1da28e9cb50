//! How a minor loop's ends `B(p_r)`, `B(p_t)` are solved for on the
//! branch with the scaled offset (eqs. 25/26): exactly, by Newton steps
//! from where they were, or, for a reversal's new loop, searched for over
//! periods from the tables' starts.

use crate::branch::Branch;
use crate::load_model::LoadModel;
use crate::math::clamp;

#[cfg(doc)]
use crate::effects::offset::branch_contraction_near;
use crate::effects::offset::{
    branch_contraction, inverse_resolution, MAX_OFFSET_SCALE, SCALED_INVERSE_ROUNDING,
};

use super::Reversal;
#[cfg(doc)]
use super::ReversalStack;

/// How a minor loop's ends are solved for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Ends {
    /// [`branch_contraction`] (its Newton iteration at a scale other than
    /// 1): what the forward model computes.
    Exact,
    /// Newton steps on the same equation (the feedforward's bounded path).
    Newton,
}

impl Ends {
    /// The branch contraction at `pressure_mpa`; `x0` a starting point
    /// for [`Ends::Newton`] (one step from it; without one, exact).
    pub(super) fn solve(
        self,
        model: &LoadModel,
        pressure_mpa: f32,
        branch: Branch,
        offset_scale: f32,
        x0: Option<f32>,
    ) -> f32 {
        if self == Ends::Exact || offset_scale == 1.0 {
            return branch_contraction(model, pressure_mpa, branch, offset_scale);
        }
        match x0 {
            Some(x0) => newton_branch(model, pressure_mpa, branch, offset_scale, x0, 1),
            None => branch_contraction(model, pressure_mpa, branch, offset_scale),
        }
    }
}

/// `steps` Newton steps from `x0` on `CM(x) ± offset_scale·y_hys(x) = p`
/// (the equation [`branch_contraction`] solves), with its exact slope
/// (`LoadModel::branch_and_slope`, the one [`branch_contraction`]'s
/// iteration takes); each step clamped to the stroke, and none taken where
/// the slope is not positive (the curve is not increasing there). Pressure
/// clamped to `[0, Pmax]`, the scale as in [`branch_contraction`].
pub(super) fn newton_branch(
    model: &LoadModel,
    pressure_mpa: f32,
    branch: Branch,
    offset_scale: f32,
    x0: f32,
    steps: usize,
) -> f32 {
    let p = clamp(pressure_mpa, 0.0, model.max_pressure_mpa());
    let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    let (lo, hi) = (model.root_contraction(), model.max_contraction());
    let mut x = clamp(x0, lo, hi);
    for _ in 0..steps {
        let (g, slope) = model.branch_and_slope(x, k);
        if !(slope > 0.0) {
            break;
        }
        x = clamp(x - (g - p) / slope, lo, hi);
    }
    x
}

/// [`newton_branch`] with one step from each of `x0` at each of
/// `pressures_mpa`, bit for bit: the pressure clamp's bound, the factor on
/// the offset and the stroke computed once for both.
#[inline(always)]
pub(super) fn newton_ends(
    model: &LoadModel,
    pressures_mpa: [f32; 2],
    branch: Branch,
    offset_scale: f32,
    x0: [f32; 2],
) -> (f32, f32) {
    let pmax = model.max_pressure_mpa();
    let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    let (lo, hi) = (model.root_contraction(), model.max_contraction());
    let step = |p: f32, x0: f32| {
        let p = clamp(p, 0.0, pmax);
        let x = clamp(x0, lo, hi);
        let (g, slope) = model.branch_and_slope(x, k);
        if slope > 0.0 {
            clamp(x - (g - p) / slope, lo, hi)
        } else {
            x
        }
    };
    let [p_r, p_t] = pressures_mpa;
    let [x_r, x_t] = x0;
    (step(p_r, x_r), step(p_t, x_t))
}

/// The pressure of a minor loop's far end: the target's, or for the first
/// reversal's curve, which closes on the end of the major loop, `Pmax`
/// rising and 0 falling.
#[inline(always)]
pub(super) fn end_pressure(model: &LoadModel, target: Option<Reversal>, branch: Branch) -> f32 {
    match target {
        Some(t) => t.pressure_mpa,
        None => match branch {
            Branch::Contraction => model.max_pressure_mpa(),
            Branch::Expansion => 0.0,
        },
    }
}

/// One step of [`ReversalStack::search_ends`] for the loop's end at
/// `pressure_mpa` from `x`, kept in `bracket` (`[lo, hi]`, the stroke for
/// a new loop's first step): the step [`branch_contraction`]'s iteration
/// takes, with its bracket carried from period to period instead of
/// iterated at once. The branch at `x` narrows the bracket to the side the
/// crossing is on; the Newton step is taken where the slope is positive
/// and it stays inside, else the bracket is bisected (near the stroke's
/// ends, where the ellipse's vertical tangent meets them, plain Newton
/// steps do not go on: the end of the major loop at 0 MPa falling starts
/// there). Returns the next `x`, the bracket, and whether the end is done:
/// the Newton step from where the pressure misses by no more than its
/// rounding ([`SCALED_INVERSE_ROUNDING`], as [`branch_contraction_near`]
/// stops), or a bracket within the iteration's resolution. At `Pmax` the
/// end is `Rx_i` at once (its inverse without a step). One branch
/// evaluation, bounded work, whatever the start: where the step could not
/// go on, this took the exact iteration (up to 499 instructions on the
/// M4F in one period).
#[inline(always)]
pub(super) fn search_step(
    model: &LoadModel,
    pressure_mpa: f32,
    branch: Branch,
    offset_scale: f32,
    x: f32,
    bracket: [f32; 2],
) -> (f32, [f32; 2], bool) {
    let pmax = model.max_pressure_mpa();
    let p = clamp(pressure_mpa, 0.0, pmax);
    if !(p < pmax) {
        let max = model.max_contraction();
        return (max, [max, max], true);
    }
    // The bracket is the stroke or a previous step's, and `x` inside it
    // (the clamp maps a NaN start to its low end).
    let [lo, hi] = bracket;
    let x = clamp(x, lo, hi);
    let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    let (g, slope) = model.branch_and_slope(x, k);
    let miss = g - p;
    let (lo, hi) = if miss <= 0.0 { (x, hi) } else { (lo, x) };
    let next = x - miss / slope;
    if slope > 0.0 && next >= lo && next <= hi {
        // Also done where the pressure misses by no more than its own
        // rounding: Newton steps from there alternate about the answer
        // just over the resolution and would not end.
        return (next, [lo, hi], miss.abs() <= SCALED_INVERSE_ROUNDING * pmax);
    }
    // `!(a && b)` is also true for a NaN step (a zero or infinite slope).
    (
        0.5 * (lo + hi),
        [lo, hi],
        hi - lo <= inverse_resolution(model),
    )
}

/// Where a reversal's new loop's ends start ([`ReversalStack::search_ends`]),
/// from `origin` towards `target` on `branch` at `offset_scale`.
///
/// The origin's end, where the set-point is in the loop's first periods,
/// between the two branches' table interpolations at its pressure, linear
/// in the factor on the offset: `B(k) ≈ ((1 + k)·B₊ + (1 − k)·B₋)/2` for
/// the factor `k` (the branch's sign times the scale), exact at the
/// unscaled branches (`k` = ±1), off by `B`'s curvature in `k` elsewhere:
/// at a scale away from 1 much nearer than the unscaled branch (where
/// [`branch_contraction`]'s iteration starts), which is off by
/// `|scale − 1|` times the offset's effect (on random models with the
/// width, the round trip's worst error in the loop's first period
/// 6·10⁻² → 2.9·10⁻², its median 3.1·10⁻⁴ → 5.9·10⁻⁵). The far end at
/// the unscaled branch's interpolation. But the end of the major loop
/// falling, the scaled expansion branch's crossing of 0 MPa, lies near
/// `R_i`, where below the crossing the branch's slope is not positive and
/// a Newton step does not go: there `CM` is nearly linear and `y_hys` a
/// square root in `x − R_i`, so `CM(x) = scale·y_hys(x)` puts the crossing
/// at about `scale²` times the unscaled one's distance from `R_i`; rising,
/// `Rx_i` (`Pmax`'s inverse).
///
/// While a load switch's tables are being built there are no
/// interpolations (the iteration's start is the stroke's middle, far from
/// most crossings for one Newton step): each end starts at its own point
/// (moved to the scale: between the branches at its pressure, within the
/// loop's width of the crossing), the end of the major loop falling at the
/// crossing estimated from the model's coefficients
/// ([`LoadModel::zero_pressure_expansion_estimate`]).
#[inline(always)]
pub(super) fn new_loop_starts(
    model: &LoadModel,
    origin: Reversal,
    target: Option<Reversal>,
    branch: Branch,
    offset_scale: f32,
) -> (f32, f32) {
    let (lo, hi) = (model.root_contraction(), model.max_contraction());
    if model.inverse_ready() {
        let p_r = origin.pressure_mpa;
        let up = model.contraction_interpolated(p_r, Branch::Contraction);
        let down = model.contraction_interpolated(p_r, Branch::Expansion);
        let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
        let start_r = clamp(0.5 * (up + down) + 0.5 * k * (up - down), lo, hi);
        let start_t = match (target, branch) {
            (Some(t), _) => model.contraction_interpolated(t.pressure_mpa, branch),
            (None, Branch::Contraction) => hi,
            (None, Branch::Expansion) => {
                let scale = clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
                let unscaled = model.contraction_interpolated(0.0, branch) - lo;
                lo + scale * scale * unscaled
            }
        };
        return (start_r, start_t);
    }
    let end = match (target, branch) {
        (Some(t), _) => t.contraction,
        (None, Branch::Contraction) => hi,
        (None, Branch::Expansion) => model.zero_pressure_expansion_estimate(offset_scale),
    };
    (origin.contraction, end)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Coeffs, Params};

    #[test]
    fn newton_ends_match_the_bisection() {
        let c = Coeffs::new(Params::DEFAULT).unwrap();
        let mut worst = [0.0f32; 2];
        for load in [100.0f32, 250.0, 400.0, 600.0] {
            let m = c.load_model(load).unwrap();
            let pmax = m.max_pressure_mpa();
            for br in [Branch::Contraction, Branch::Expansion] {
                for i in 1..40 {
                    let p = pmax * i as f32 / 40.0;
                    for scale in [0.1f32, 0.5, 0.9, 1.1, 1.5, 2.0, 3.0, 4.0] {
                        let exact = branch_contraction(&m, p, br, scale);
                        // The scale moved by 1 % (5 %) since the last period.
                        for (w, step) in worst.iter_mut().zip([0.99f32, 0.95]) {
                            let before = branch_contraction(&m, p, br, scale * step);
                            let warm = Ends::Newton.solve(&m, p, br, scale, Some(before));
                            *w = w.max((warm - exact).abs());
                        }
                        assert_eq!(Ends::Newton.solve(&m, p, br, scale, None), exact);
                    }
                }
            }
        }
        assert!(worst[0] < 1e-4, "{worst:?}");
        assert!(worst[1] < 2e-3, "{worst:?}");
    }

    #[test]
    fn the_search_steps_reach_the_exact_end_from_where_newton_cannot_go() {
        // From near either end of the stroke, where the branch's slope is
        // not positive or a Newton step leaves the stroke (the exact
        // iteration ran in one period there), one bracketed step a period
        // reaches `branch_contraction`'s end within its own tolerance.
        let c = Coeffs::new(Params::DEFAULT).unwrap();
        let (mut bisected, mut cases, mut periods_worst) = (0, 0, 0);
        for load in [100.0f32, 250.0, 450.0, 600.0] {
            let m = c.load_model(load).unwrap();
            let (root, max) = (m.root_contraction(), m.max_contraction());
            let pmax = m.max_pressure_mpa();
            for scale in [0.3f32, 1.3, 1.7, MAX_OFFSET_SCALE] {
                for br in [Branch::Contraction, Branch::Expansion] {
                    for i in 1..10 {
                        let p = pmax * i as f32 / 10.0;
                        let exact = branch_contraction(&m, p, br, scale);
                        for start in [root + 0.01 * (max - root), max - 0.01 * (max - root)] {
                            let (mut x, mut bracket, mut done) = (start, [root, max], false);
                            let mut periods = 0;
                            while !done && periods < 40 {
                                let k = br.offset_sign() * scale;
                                let (g, slope) = m.branch_and_slope(x, k);
                                let next = x - (g - p) / slope;
                                if !(slope > 0.0 && next >= bracket[0] && next <= bracket[1]) {
                                    bisected += 1;
                                }
                                (x, bracket, done) = search_step(&m, p, br, scale, x, bracket);
                                periods += 1;
                            }
                            cases += 1;
                            periods_worst = periods_worst.max(periods);
                            assert!(
                                done && (x - exact).abs() <= 2e-6,
                                "{load} N, {scale}, {br:?}, {p} MPa from {start}: \
                                 {x} vs {exact} after {periods} periods"
                            );
                        }
                    }
                }
            }
        }
        eprintln!("{cases} searches, {bisected} bisections, {periods_worst} periods at most");
        assert!(bisected >= 50, "{bisected} bisections in {cases} searches");
        assert!(periods_worst <= 12, "{periods_worst} periods");
    }

    #[test]
    fn the_zero_pressure_estimate_starts_a_newton_step_towards_the_crossing() {
        // The end of the major loop falling without the tables
        // (`LoadModel::zero_pressure_expansion_estimate`): the branch rises
        // at the estimate (a Newton step goes, where from the stroke's
        // middle it left the stroke and the bracket had to be bisected),
        // and one step lands near the exact crossing.
        let family = crate::load_model::FamilyF32::new(
            &crate::LoadFamily::from_params(&Params::DEFAULT).unwrap(),
        );
        let mut worst = 0.0f32;
        for load in [100.0f32, 250.0, 450.0, 600.0] {
            let m = family.model_without_tables(load);
            for scale in [0.2f32, 0.8, 1.0, 1.5, 2.5, MAX_OFFSET_SCALE] {
                let exact = branch_contraction(&m, 0.0, Branch::Expansion, scale);
                let start = m.zero_pressure_expansion_estimate(scale);
                // The branch rises there: the step is a Newton step, not a
                // bisection.
                let (_, slope) = m.branch_and_slope(start, -scale);
                assert!(slope > 0.0, "{load} N, {scale}: slope {slope} at {start}");
                let stroke_ends = [m.root_contraction(), m.max_contraction()];
                let (x, _, _) = search_step(&m, 0.0, Branch::Expansion, scale, start, stroke_ends);
                let stroke = m.max_contraction() - m.root_contraction();
                worst = worst.max((x - exact).abs() / stroke);
            }
        }
        // (Measured: 1e-4 of the stroke at the scale bound, 600 N.)
        assert!(worst < 5e-4, "{worst} of the stroke");
    }
}

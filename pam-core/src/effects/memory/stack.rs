//! The stack of reversal points with its wiping-out rules, and the
//! memory's curve on the minor loop from its top point: forward
//! ([`ReversalStack::contraction`], the [`Simulator`](crate::Simulator)'s
//! per-sample path) and inverse ([`ReversalStack::inverse_pressure_mpa`],
//! the feedforward's).

use crate::branch::Branch;
use crate::effects::offset::{branch_contraction, inverse_resolution};
use crate::load_model::LoadModel;
use crate::math::clamp;

use super::ends::{end_pressure, new_loop_starts, search_step, Ends};
#[cfg(doc)]
use super::moved::Moved;
use super::moved::{moved_newton, rescaled, MovedPoints};
use super::segment::Segment;
use super::{branch_pressure_mpa, Blend, NonLocalMemory, Reversal, MEMORY_INVERSE_STEPS};

/// Fixed-capacity stack of reversal points with wiping-out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReversalStack<const N: usize> {
    points: [Reversal; N],
    /// The offset scale each point was recorded at (NaN: not known, the
    /// point is never rescaled; see [`ReversalStack::push_at_scale`]).
    scales: [f32; N],
    len: usize,
    segment: Option<Segment>,
    /// The brackets `[lo, hi]` of the cached loop's two ends while they are
    /// searched for ([`ReversalStack::search_ends`]).
    brackets: [[f32; 2]; 2],
}

impl<const N: usize> Default for ReversalStack<N> {
    fn default() -> Self {
        ReversalStack {
            points: [Reversal::default(); N],
            scales: [f32::NAN; N],
            len: 0,
            segment: None,
            brackets: [[0.0; 2]; 2],
        }
    }
}

impl<const N: usize> ReversalStack<N> {
    /// Remembered reversal points, oldest first.
    pub fn points(&self) -> &[Reversal] {
        self.points.get(..self.len).unwrap_or(&[])
    }

    /// Forget everything (back on the major loop).
    pub fn clear(&mut self) {
        self.len = 0;
        self.segment = None;
    }

    /// Push a reversal; non-finite points are refused; when full the oldest
    /// point is dropped. `N = 0` remembers nothing.
    pub fn push(&mut self, r: Reversal) {
        self.push_at_scale(r, f32::NAN);
    }

    /// [`Self::push`] a point recorded where the ellipse offset was scaled by
    /// `offset_scale` (a rate law's factor at that moment). A minor loop at
    /// another scale starts from (or heads for) the point moved with its
    /// loop: at the same pressure, the same fraction of the way between the
    /// two branches (`φ = (p − CM(x))/(scale·y_hys(x))`, eqs. 25/26 with the
    /// offset scaled). Without this a turning point recorded slowly (a
    /// reversal is where the pressure rate passes through zero) kept its
    /// contraction while the rate law widened the loop around it, and the
    /// memory drove the curve up to 0.03 off the rate law's branches.
    pub fn push_at_scale(&mut self, r: Reversal, offset_scale: f32) {
        self.push_impl(r, offset_scale, None);
    }

    /// [`Self::push_at_scale`], keeping `moved` (the [`Moved`] of each
    /// position) in step.
    pub(crate) fn push_at_scale_moved(
        &mut self,
        r: Reversal,
        offset_scale: f32,
        moved: &mut MovedPoints<N>,
    ) {
        self.push_impl(r, offset_scale, Some(moved));
    }

    #[inline(always)]
    fn push_impl(
        &mut self,
        r: Reversal,
        offset_scale: f32,
        mut moved: Option<&mut MovedPoints<N>>,
    ) {
        if !(r.pressure_mpa.is_finite() && r.contraction.is_finite()) || N == 0 {
            return;
        }
        if self.len >= N {
            self.points.copy_within(1.., 0);
            self.scales.copy_within(1.., 0);
            if let Some(m) = moved.as_deref_mut() {
                m.shift();
            }
            self.len = N - 1;
        }
        if let Some(m) = moved {
            m.pushed(self.len);
        }
        if let (Some(slot), Some(scale)) =
            (self.points.get_mut(self.len), self.scales.get_mut(self.len))
        {
            *slot = r;
            *scale = offset_scale;
            self.len += 1;
        }
        self.segment = None;
    }

    /// Point `i` as it lies at `offset_scale` ([`Self::push_at_scale`]):
    /// unchanged when recorded at that scale or without one (the path
    /// without a rate law: two loads and a compare). `on` is the branch it
    /// was recorded on, which places it when its own scale was too small to
    /// tell the branches apart.
    /// `moved`: the feedforward's [`Moved`] per position (with
    /// [`Ends::Newton`]).
    #[inline(always)]
    fn point_at_scale(
        &self,
        i: usize,
        model: &LoadModel,
        on: Branch,
        offset_scale: f32,
        ends: Ends,
        moved: Option<&mut MovedPoints<N>>,
    ) -> Option<Reversal> {
        let r = *self.points.get(i)?;
        let recorded = *self.scales.get(i)?;
        if !recorded.is_finite() || recorded.to_bits() == offset_scale.to_bits() {
            return Some(r);
        }
        match moved.and_then(|m| m.0.get_mut(i)) {
            Some(m) if ends == Ends::Newton => {
                Some(moved_newton(m, r, recorded, model, on, offset_scale))
            }
            _ => Some(rescaled(r, recorded, model, on, offset_scale, ends)),
        }
    }

    /// The top point and the one below, as they lie at `offset_scale` for
    /// a minor loop on `branch` ([`Self::point_at_scale`]): the top one was
    /// recorded on the other branch, the one below on this one. When both
    /// were recorded at this scale (or without one), [`Self::top2`] as it
    /// is: the path without a rate law costs two compares.
    #[inline(always)]
    fn top2_at_scale(
        &self,
        model: &LoadModel,
        branch: Branch,
        offset_scale: f32,
        ends: Ends,
        moved: Option<&mut MovedPoints<N>>,
    ) -> (Option<Reversal>, Option<Reversal>) {
        let same = |i: Option<usize>| {
            i.and_then(|i| self.scales.get(i))
                .is_none_or(|s| !s.is_finite() || s.to_bits() == offset_scale.to_bits())
        };
        if same(self.len.checked_sub(1)) && same(self.len.checked_sub(2)) {
            return self.top2();
        }
        self.top2_rescaled(model, branch, offset_scale, ends, moved)
    }

    /// [`Self::top2_at_scale`]'s path where a point moves.
    #[inline(never)]
    fn top2_rescaled(
        &self,
        model: &LoadModel,
        branch: Branch,
        offset_scale: f32,
        ends: Ends,
        mut moved: Option<&mut MovedPoints<N>>,
    ) -> (Option<Reversal>, Option<Reversal>) {
        let top = self.len.checked_sub(1).and_then(|i| {
            let on = branch.opposite();
            self.point_at_scale(i, model, on, offset_scale, ends, moved.as_deref_mut())
        });
        let below = self
            .len
            .checked_sub(2)
            .and_then(|i| self.point_at_scale(i, model, branch, offset_scale, ends, moved));
        (top, below)
    }

    /// `self` becomes `other` with `r` pushed at `offset_scale`
    /// ([`Self::push_at_scale`] on a copy), copying only `other`'s
    /// remembered points: not the whole capacity, nor its cached loop,
    /// which the push forgets.
    /// `moved` is this stack's [`Moved`] per position, `other_moved`
    /// `other`'s: valid for the top two positions only (the two a minor
    /// loop moves; the caller forgets the two a wipe-out exposes, and the
    /// inverse's look past closed loops does not use them). The point below
    /// `r`, `other`'s top, brings its own along; `r`'s position is
    /// forgotten.
    pub(crate) fn set_pushed_moved(
        &mut self,
        other: &Self,
        r: Reversal,
        offset_scale: f32,
        moved: &mut MovedPoints<N>,
        other_moved: &MovedPoints<N>,
    ) {
        let len = other.len.min(N);
        for ((to, to_scale), (from, from_scale)) in self
            .points
            .iter_mut()
            .zip(self.scales.iter_mut())
            .zip(other.points.iter().zip(&other.scales))
            .take(len)
        {
            *to = *from;
            *to_scale = *from_scale;
        }
        if let Some(top) = len.checked_sub(1) {
            if let (Some(to), Some(from)) = (moved.0.get_mut(top), other_moved.0.get(top)) {
                *to = *from;
            }
        }
        self.len = len;
        self.push_impl(r, offset_scale, Some(moved));
    }

    /// Whether the top minor loop is cached (then [`Self::contraction`] and
    /// [`Self::inverse_pressure_mpa`] on it skip the two branch inverses of
    /// its ends, as long as branch, model and offset scale stay the same).
    /// A new loop of the feedforward ([`crate::ModelInverse`]) whose ends
    /// are still searched for is not: the next call takes their next Newton
    /// steps (and moves the loop's new point for the first time).
    pub fn has_cached_loop(&self) -> bool {
        self.segment.as_ref().is_some_and(|s| !s.searching)
    }

    /// The cached loop's ends are still searched for
    /// ([`Self::search_ends`]): the next call at the same scale takes their
    /// next steps.
    pub(crate) fn searching(&self) -> bool {
        self.segment.as_ref().is_some_and(|s| s.searching)
    }

    /// [`Self::has_cached_loop`] at `offset_scale` (bit for bit): the next
    /// call at that scale uses the cached loop without moving its ends.
    pub(crate) fn has_cached_loop_at(&self, offset_scale: f32) -> bool {
        self.segment
            .as_ref()
            .is_some_and(|s| !s.searching && s.scale_bits == offset_scale.to_bits())
    }

    /// Forget the cached minor loop (the [`Simulator`](crate::Simulator)
    /// calls this where the branch changes; its model and offset scale change
    /// only with a load switch, which clears the stack, or are compared).
    #[inline]
    pub(crate) fn invalidate(&mut self) {
        self.segment = None;
    }

    fn top2(&self) -> (Option<Reversal>, Option<Reversal>) {
        let top = self.len.checked_sub(1).and_then(|i| self.points.get(i));
        let below = self.len.checked_sub(2).and_then(|i| self.points.get(i));
        (top.copied(), below.copied())
    }

    /// Apply the wiping-out rule for `pressure_mpa` moving on `branch`:
    /// pop every closed minor loop.
    pub fn wipe_out(&mut self, pressure_mpa: f32, branch: Branch) {
        // Each pass pops two points, so N/2 + 1 passes bound the loop.
        for _ in 0..N / 2 + 1 {
            let (_, Some(target)) = self.top2() else {
                return;
            };
            let passed = match branch {
                Branch::Contraction => pressure_mpa > target.pressure_mpa,
                Branch::Expansion => pressure_mpa < target.pressure_mpa,
            };
            if !passed {
                return;
            }
            self.len -= 2;
            self.segment = None;
        }
    }

    /// The minor loop from the top point, for `branch`, `model` and
    /// `offset_scale` (cached; two branch inverses on a miss).
    fn segment(
        &mut self,
        blend: Blend,
        model: &LoadModel,
        branch: Branch,
        offset_scale: f32,
    ) -> Option<&Segment> {
        self.segment_with(blend, model, branch, offset_scale, Ends::Exact, None)
    }

    /// [`Self::segment`] with the loop's ends solved as `ends` says; with
    /// [`Ends::Newton`] a cached loop that differs only in the offset scale
    /// moves its ends by one Newton step each.
    ///
    /// With [`Ends::Newton`] and the feedforward's `moved`, the ends of a
    /// loop that starts at a reversal (its turning point the feedforward's
    /// previous extreme, just pushed: [`Moved::fresh`]) at a scale other
    /// than 1, or at any scale while a load switch's inverse tables are
    /// being built (where the exact ends are two table-free bisections,
    /// 588 instructions on the M4F), are searched for over periods instead
    /// of solved at once
    /// ([`Self::search_ends`]): the loop's first period takes one Newton
    /// step for each end from a start the tables give
    /// ([`new_loop_starts`]), about 250 instructions on the M4F for the two
    /// where [`branch_contraction`]'s iterations took about 720, in a period
    /// that already makes the feedforward's trial stack; each later period
    /// at the same scale takes one more, until both are within the
    /// iteration's resolution ([`inverse_resolution`]) or the pressure's
    /// rounding, and the loop is cached (2–6 periods, within 2·10⁻⁶ of
    /// [`branch_contraction`]'s ends:
    /// `a_reversals_new_loop_searches_for_its_ends_over_periods`); a period
    /// at another scale moves them as any cached loop's (a rate law changes
    /// the scale every period) and ends the search. In a reversal's first
    /// period the set-point is a period from the turning point, where the
    /// curve passes through the turning point whatever its ends, so their
    /// first steps' error weighs little there (on random models with the
    /// width, the round trip's error in that period a median 6·10⁻⁵ of
    /// contraction, `measure_the_new_loops_first_periods` in
    /// `tests/feedforward.rs`). A loop a wipe-out exposes is used mid-sweep
    /// at once, and its ends are exact as before.
    ///
    /// The loop is made in its cache and lent from there (a [`Segment`] is
    /// a dozen words: copies of it in and out cost as much as a Newton
    /// step).
    #[inline(always)]
    fn segment_with(
        &mut self,
        blend: Blend,
        model: &LoadModel,
        branch: Branch,
        offset_scale: f32,
        ends: Ends,
        moved: Option<&mut MovedPoints<N>>,
    ) -> Option<&Segment> {
        let origin_recorded = self.top2().0?;
        let scale_bits = offset_scale.to_bits();
        let load_bits = model.load_n().to_bits();
        let max_contraction_bits = model.max_contraction().to_bits();
        let merge_bits = blend.merge_span.to_bits();
        let shape_bits = blend.k.to_bits();
        let mut warm = None;
        if let Some(s) = &self.segment {
            let same_loop = s.branch == branch
                && s.load_bits == load_bits
                && s.max_contraction_bits == max_contraction_bits
                && s.merge_bits == merge_bits
                && s.shape_bits == shape_bits;
            let same_scale = s.scale_bits == scale_bits;
            // A loop still searching is not done at this scale.
            if same_loop && same_scale && !s.searching {
                return self.segment.as_ref();
            }
            if same_loop && ends == Ends::Newton {
                if same_scale {
                    // (Searching: its next steps.)
                    self.search_ends(blend, model, branch, offset_scale, moved, origin_recorded);
                    return self.segment.as_ref();
                }
                // At another scale a search ends: the ends follow the
                // scale by the Newton step every cached loop takes.
                warm = Some((s.b_r, s.b_t));
            }
        }
        // A new loop whose turning point the feedforward has just pushed
        // (a reversal: the set-point is a period from it), not one a
        // wipe-out exposes mid-sweep, where the whole curve is in use at
        // once: its ends are exact as before.
        if warm.is_none()
            && ends == Ends::Newton
            && (offset_scale != 1.0 || !model.inverse_ready())
            && moved.as_deref().is_some_and(|m| m.top_fresh(self.len))
        {
            self.segment = None;
            self.search_ends(blend, model, branch, offset_scale, moved, origin_recorded);
            return self.segment.as_ref();
        }
        let (origin, target) = self.top2_at_scale(model, branch, offset_scale, ends, moved);
        let origin = origin.unwrap_or(origin_recorded);
        self.segment = Some(Segment::new(
            blend,
            model,
            origin,
            target,
            branch,
            offset_scale,
            ends,
            warm,
        ));
        self.segment.as_ref()
    }

    /// [`Self::segment_with`]'s search for a reversal's loop's ends: one
    /// bracketed Newton step for each end ([`search_step`]), from
    /// [`new_loop_starts`] in the stroke for a new loop (the caller cleared
    /// the cache) and from the cached ends in their brackets for one still
    /// searching at the same scale. The search ends where both ends are
    /// done (within the resolution, or at the pressure's rounding). Out of line:
    /// the path of every period with a rate law, a cached loop's ends moved
    /// to a new scale, stays as it was (inlined, this cost it up to 49
    /// instructions on the M4F).
    #[inline(never)]
    fn search_ends(
        &mut self,
        blend: Blend,
        model: &LoadModel,
        branch: Branch,
        offset_scale: f32,
        moved: Option<&mut MovedPoints<N>>,
        origin_recorded: Reversal,
    ) {
        let (origin, target) = self.top2_at_scale(model, branch, offset_scale, Ends::Newton, moved);
        let origin = origin.unwrap_or(origin_recorded);
        let p_t = end_pressure(model, target, branch);
        // A new loop starts from the tables; one still searching goes on
        // from its ends.
        let (from, new) = match &self.segment {
            Some(s) => ((s.b_r, s.b_t), false),
            None => (
                new_loop_starts(model, origin, target, branch, offset_scale),
                true,
            ),
        };
        let [bracket_r, bracket_t] = if new {
            let stroke = [model.root_contraction(), model.max_contraction()];
            [stroke, stroke]
        } else {
            self.brackets
        };
        let (b_r, bracket_r, done_r) = search_step(
            model,
            origin.pressure_mpa,
            branch,
            offset_scale,
            from.0,
            bracket_r,
        );
        let (b_t, bracket_t, done_t) =
            search_step(model, p_t, branch, offset_scale, from.1, bracket_t);
        self.brackets = [bracket_r, bracket_t];
        // The search ends where both steps at this scale are within the
        // resolution (not tested in a new loop's first period: from the
        // unscaled branch its steps are not, and the test cost that period
        // 30 instructions on the M4F).
        let resolution = inverse_resolution(model);
        let settled = |b: f32, x: f32, done: bool| done || (!new && (b - x).abs() <= resolution);
        let searching = (offset_scale != 1.0 || !model.inverse_ready())
            && !(settled(b_r, from.0, done_r) && settled(b_t, from.1, done_t));
        self.segment = Some(Segment::with_ends(
            blend,
            model,
            origin,
            target,
            branch,
            offset_scale,
            (b_r, b_t),
            searching,
        ));
    }

    /// Contraction at `pressure_mpa` on `branch` with the memory, after
    /// [`Self::wipe_out`]; `offset_scale` is the factor on the ellipse offset
    /// (1 for the paper's model). Within the stroke, never NaN.
    pub fn contraction(
        &mut self,
        params: &NonLocalMemory,
        model: &LoadModel,
        pressure_mpa: f32,
        branch: Branch,
        offset_scale: f32,
    ) -> f32 {
        let p = clamp(pressure_mpa, 0.0, model.max_pressure_mpa());
        self.wipe_out(p, branch);
        let x_branch = branch_contraction(model, p, branch, offset_scale);
        let blend = params.blend_coeffs();
        let Some(seg) = self.segment(blend, model, branch, offset_scale) else {
            return x_branch;
        };
        seg.eval(model, x_branch)
    }

    /// The inverse of [`Self::contraction`]: the pressure in `[0, Pmax]` at
    /// which the memory's curve for `branch` reaches `contraction` (the
    /// feedforward of a controller that follows the memory). The points are
    /// not changed (only the cached minor loop); apply [`Self::wipe_out`]
    /// with the result to move on.
    ///
    /// Minor loops that `contraction` lies beyond (past the contraction of
    /// the point below the top, in the direction of `branch`) close first,
    /// as [`Self::wipe_out`] closes them for a pressure past that point's.
    /// On the remaining loop the curve is `x = B + d_t + (d_r − d_t)·w(s(B))`
    /// in the branch contraction `B`, which is solved for `B` in closed form
    /// (one square root; see `Segment::solve`), or where that finds no
    /// candidate (a contraction beyond the curve's reach) by
    /// [`MEMORY_INVERSE_STEPS`] bisection steps (no table inverse in them:
    /// a few `f32` operations and one division each); the pressure is then
    /// the forward model at `B`, eqs. (25)/(26). With no reversal left it is
    /// the forward model at `contraction`. Assumes, as the wiping-out rules
    /// do, that the curve rises with pressure on the contraction branch and
    /// falls with it on the expansion branch. Never NaN (NaN `contraction`
    /// maps to `R_i`).
    ///
    /// Bounded work: at most `N/2 + 1` comparisons, two branch inverses (the
    /// loop's ends; cached for the top loop, see [`Self::has_cached_loop`]),
    /// the closed form (and at most the bisection) and one forward
    /// evaluation.
    ///
    /// ```
    /// use pam_core::effects::{NonLocalMemory, Reversal, ReversalStack};
    /// use pam_core::{Branch, Coeffs, Params};
    ///
    /// let m = Coeffs::new(Params::DEFAULT).unwrap().load_model(200.0).unwrap();
    /// let mem = NonLocalMemory::with_shape(1.0);
    /// let mut stack = ReversalStack::<8>::default();
    /// // Up to 0.3 MPa, reversed there: the curve back down is a minor loop.
    /// let x_top = m.contraction(0.3, Branch::Contraction);
    /// stack.push(Reversal { pressure_mpa: 0.3, contraction: x_top });
    /// let x_ref = x_top - 0.02;
    /// let p = stack.inverse_pressure_mpa(&mem, &m, x_ref, Branch::Expansion, 1.0);
    /// let mut trial = stack;
    /// let x = trial.contraction(&mem, &m, p, Branch::Expansion, 1.0);
    /// assert!((x - x_ref).abs() < 1e-4);
    /// // Between the branches: above the expansion branch's pressure there.
    /// assert!(p > m.pressure_mpa(x_ref, Branch::Expansion));
    /// ```
    pub fn inverse_pressure_mpa(
        &mut self,
        params: &NonLocalMemory,
        model: &LoadModel,
        contraction: f32,
        branch: Branch,
        offset_scale: f32,
    ) -> f32 {
        self.inverse_impl(
            params,
            model,
            contraction,
            branch,
            offset_scale,
            Ends::Exact,
            None,
        )
    }

    /// [`Self::inverse_pressure_mpa`] for a feedforward called every period
    /// while the offset scale changes (the rate effect): when only the scale
    /// changed since the cached loop, its ends follow it by one Newton step
    /// each on the same equation (eqs. 25/26 with the scaled offset), from
    /// the cached ends, instead of two full inverses ([`branch_contraction`],
    /// up to [`SCALED_INVERSE_STEPS`](crate::effects::offset::SCALED_INVERSE_STEPS) steps each); a
    /// new loop's ends are exact. So the ends follow the scale over the
    /// periods with bounded work. The same as [`Self::inverse_pressure_mpa`]
    /// while the scale holds; after a change of 1 % in one period, within
    /// 10⁻⁴ of contraction (`newton_ends_match_the_bisection`).
    pub fn feedforward_pressure_mpa(
        &mut self,
        params: &NonLocalMemory,
        model: &LoadModel,
        contraction: f32,
        branch: Branch,
        offset_scale: f32,
    ) -> f32 {
        self.inverse_impl(
            params,
            model,
            contraction,
            branch,
            offset_scale,
            Ends::Newton,
            None,
        )
    }

    /// [`Self::feedforward_pressure_mpa`] with the [`Moved`] of each
    /// position kept in `moved` between calls (the same points, bit for
    /// bit; the feedforward's per-period path with a rate law), and its
    /// pushes marked: a reversal's new loop searches for its ends over
    /// periods instead of solving them at once, and its turning point's
    /// first move is skipped where the scale changed little since it was
    /// recorded ([`Self::segment_with`], [`Moved::fresh`]).
    pub(crate) fn feedforward_pressure_mpa_moved(
        &mut self,
        moved: &mut MovedPoints<N>,
        params: &NonLocalMemory,
        model: &LoadModel,
        contraction: f32,
        branch: Branch,
        offset_scale: f32,
    ) -> f32 {
        self.inverse_impl(
            params,
            model,
            contraction,
            branch,
            offset_scale,
            Ends::Newton,
            Some(moved),
        )
    }

    // Inlined into its callers, so each is specialised for its `ends`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn inverse_impl(
        &mut self,
        params: &NonLocalMemory,
        model: &LoadModel,
        contraction: f32,
        branch: Branch,
        offset_scale: f32,
        ends: Ends,
        moved: Option<&mut MovedPoints<N>>,
    ) -> f32 {
        let (lo_x, hi_x) = (model.root_contraction(), model.max_contraction());
        let x_ref = clamp(contraction, lo_x, hi_x);
        let mut len = self.len.min(N);
        for _ in 0..N / 2 + 1 {
            let Some(target) = len.checked_sub(2).and_then(|i| self.points.get(i)) else {
                break;
            };
            let passed = match branch {
                Branch::Contraction => x_ref > target.contraction,
                Branch::Expansion => x_ref < target.contraction,
            };
            if !passed {
                break;
            }
            len -= 2;
        }
        if len == 0 {
            return branch_pressure_mpa(model, x_ref, branch, offset_scale);
        }
        let blend = params.blend_coeffs();
        let inner;
        let seg = if len == self.len {
            // The top loop: cached between calls, as for `contraction`.
            match self.segment_with(blend, model, branch, offset_scale, ends, moved) {
                Some(seg) => seg,
                None => return branch_pressure_mpa(model, x_ref, branch, offset_scale),
            }
        } else {
            // An inner loop of the stack (the top one closed here).
            // (Not with `moved`: valid for the top two positions only.)
            let origin = len.checked_sub(1).and_then(|i| {
                let on = branch.opposite();
                self.point_at_scale(i, model, on, offset_scale, ends, None)
            });
            let Some(origin) = origin else {
                return branch_pressure_mpa(model, x_ref, branch, offset_scale);
            };
            let target = len
                .checked_sub(2)
                .and_then(|i| self.point_at_scale(i, model, branch, offset_scale, ends, None));
            inner = Segment::new(
                blend,
                model,
                origin,
                target,
                branch,
                offset_scale,
                ends,
                None,
            );
            &inner
        };
        if let Some(b) = seg.solve(x_ref) {
            return branch_pressure_mpa(model, clamp(b, lo_x, hi_x), branch, offset_scale);
        }
        // No closed-form candidate (x_ref beyond the curve's reach, or
        // rounding at a region boundary): x(B) is non-decreasing in B, so
        // bisect for the largest B with x(B) <= x_ref.
        let (mut lo, mut hi) = (lo_x, hi_x);
        for _ in 0..MEMORY_INVERSE_STEPS {
            let mid = 0.5 * (lo + hi);
            if seg.eval(model, mid) <= x_ref {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        branch_pressure_mpa(model, 0.5 * (lo + hi), branch, offset_scale)
    }

    /// [`Self::contraction`] for the [`Simulator`](crate::Simulator), given
    /// `x_branch = branch_contraction(model, pressure_mpa, branch,
    /// offset_scale)`: `Some(x)` on a minor loop (then `x` is
    /// [`Self::contraction`]'s result, within the stroke), `None` with no
    /// reversal remembered (then [`Self::contraction`] returns `x_branch`).
    /// `pressure_mpa` must be finite.
    ///
    /// The per-sample path tests only what changes between samples in the
    /// simulator: the wiping-out threshold and the offset scale. The caller
    /// keeps the rest of the cache key: it calls [`Self::invalidate`] when
    /// `branch` changes and [`Self::clear`] when `model` does (`blend` is
    /// fixed).
    #[inline]
    pub(crate) fn follow(
        &mut self,
        blend: Blend,
        model: &LoadModel,
        pressure_mpa: f32,
        x_branch: f32,
        branch: Branch,
        offset_scale: f32,
    ) -> Option<f32> {
        if let Some(seg) = &self.segment {
            // Negation is exact: `−p > −θ` is `p < θ`, infinities included.
            let wiped = seg.wipe_sign * pressure_mpa > seg.wipe_mpa;
            if !wiped && seg.scale_bits == offset_scale.to_bits() {
                return Some(seg.eval(model, x_branch));
            }
        } else if self.len == 0 {
            return None;
        }
        self.follow_slow(blend, model, pressure_mpa, x_branch, branch, offset_scale)
    }

    /// The rare path of [`Self::follow`]: a wipe-out, or a new minor loop.
    #[inline(never)]
    fn follow_slow(
        &mut self,
        blend: Blend,
        model: &LoadModel,
        pressure_mpa: f32,
        x_branch: f32,
        branch: Branch,
        offset_scale: f32,
    ) -> Option<f32> {
        let p = clamp(pressure_mpa, 0.0, model.max_pressure_mpa());
        self.wipe_out(p, branch);
        let seg = self.segment(blend, model, branch, offset_scale)?;
        Some(seg.eval(model, x_branch))
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{model, MEM};
    use super::*;
    use crate::{Coeffs, Params};

    #[test]
    fn the_feedforward_with_moved_points_is_the_one_without_bit_for_bit() {
        // A random walk of the feedforward's stack operations (pushes, a
        // trial made from the memory and flipped in, wipe-outs) at offset
        // scales that change every call, by little at times (a pushed
        // point's first move is skipped then, `Moved::fresh`): the inverse
        // with `MovedPoints` kept between calls against the one that makes
        // every point's `Moved` afresh on each call (keeping only which
        // positions hold a point pushed and not moved since).
        let m = model();
        let mem = NonLocalMemory::with_shape(0.7);
        let mut seed = 12345u32;
        let mut next = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let (lo, hi) = (m.root_contraction(), m.max_contraction());
        let mut stacks = [ReversalStack::<4>::default(); 2];
        let mut moved = [MovedPoints::<4>::default(); 2];
        let mut plain = ReversalStack::<4>::default();
        let mut plain_moved = MovedPoints::<4>::default();
        let mut current = 0;
        let mut branch = Branch::Contraction;
        let mut scale = 1.3f32;
        for k in 0..20_000 {
            // Half the calls move the scale by a rate law's change over a
            // period or so (below `FRESH_SCALE_CHANGE`), half anywhere.
            scale = if next() < 0.5 {
                (scale + 0.02 * (next() - 0.5)).clamp(0.6, 2.1)
            } else {
                0.6 + 1.5 * next()
            };
            let x = lo + (hi - lo) * next();
            let r = Reversal {
                pressure_mpa: m.max_pressure_mpa() * next(),
                contraction: x,
            };
            match (next() * 8.0) as u32 {
                0 => {
                    stacks[current].push_at_scale_moved(r, scale, &mut moved[current]);
                    plain.push_at_scale_moved(r, scale, &mut plain_moved);
                    branch = branch.opposite();
                }
                1 => {
                    // The trial: the memory with `r` pushed, then flipped in.
                    let (a, b) = stacks.split_at_mut(1);
                    let (ma, mb) = moved.split_at_mut(1);
                    if current == 0 {
                        b[0].set_pushed_moved(&a[0], r, scale, &mut mb[0], &ma[0]);
                    } else {
                        a[0].set_pushed_moved(&b[0], r, scale, &mut ma[0], &mb[0]);
                    }
                    current = 1 - current;
                    plain.push_at_scale_moved(r, scale, &mut plain_moved);
                    branch = branch.opposite();
                }
                2 => {
                    let before = stacks[current].points().len();
                    stacks[current].wipe_out(r.pressure_mpa, branch);
                    plain.wipe_out(r.pressure_mpa, branch);
                    let after = stacks[current].points().len();
                    if after < before {
                        for m in [&mut moved[current], &mut plain_moved] {
                            if let Some(i) = after.checked_sub(1) {
                                m.forget(i);
                            }
                            if let Some(i) = after.checked_sub(2) {
                                m.forget(i);
                            }
                        }
                    }
                }
                _ => {}
            }
            assert_eq!(stacks[current].points(), plain.points(), "{k}");
            let mut afresh = plain_moved.afresh();
            let want =
                plain.feedforward_pressure_mpa_moved(&mut afresh, &mem, &m, x, branch, scale);
            plain_moved = afresh;
            let got = stacks[current].feedforward_pressure_mpa_moved(
                &mut moved[current],
                &mem,
                &m,
                x,
                branch,
                scale,
            );
            assert_eq!(got.to_bits(), want.to_bits(), "{k}");
        }
    }

    /// The turns of the new-loop tests on `branch` of a model whose loop
    /// closes at `pmax`: the turning pressure (on the other branch), with
    /// and without a point below on this one (further along `branch`).
    fn turns(pmax: f32, branch: Branch) -> impl Iterator<Item = (f32, Option<f32>)> {
        [(2, 5), (3, 7), (5, 8), (1, 4)]
            .into_iter()
            .flat_map(move |(i, j)| {
                let (a, b) = (pmax * i as f32 / 10.0, pmax * j as f32 / 10.0);
                let (p_r, p_t) = match branch {
                    Branch::Contraction => (a, b),
                    Branch::Expansion => (b, a),
                };
                [(p_r, Some(p_t)), (p_r, None)]
            })
    }

    /// A reversal's loop as the feedforward makes it: the point below (a
    /// turning point on `branch`, or none) and the turn on the other branch
    /// pushed at `scale`, the set-point a period back from the turn.
    fn reversal_loop(
        m: &LoadModel,
        below: Option<f32>,
        p_r: f32,
        branch: Branch,
        scale: f32,
    ) -> (ReversalStack<4>, MovedPoints<4>, f32) {
        let mut s = ReversalStack::<4>::default();
        let mut moved = MovedPoints::<4>::default();
        if let Some(p) = below {
            let x = branch_contraction(m, p, branch, scale);
            s.push_at_scale_moved(
                Reversal {
                    pressure_mpa: p,
                    contraction: x,
                },
                scale,
                &mut moved,
            );
        }
        let x_r = branch_contraction(m, p_r, branch.opposite(), scale);
        s.push_at_scale_moved(
            Reversal {
                pressure_mpa: p_r,
                contraction: x_r,
            },
            scale,
            &mut moved,
        );
        let back = match branch {
            Branch::Contraction => 1e-4,
            Branch::Expansion => -1e-4,
        };
        (s, moved, x_r + back)
    }

    #[test]
    fn a_reversals_new_loop_searches_for_its_ends_over_periods() {
        // The first period of a reversal's loop at a scale other than 1
        // takes one Newton step for each end from its start (the exact
        // iteration took 8–10 branch evaluations for the two), and the loop
        // is not served from the cache; at a scale that holds, the ends
        // are `branch_contraction`'s within its own tolerance (2e-6 of the
        // bisection, `the_scaled_branch_inverse_finds_the_bisections_crossing`)
        // after a few periods, and the loop is cached from then on. Every
        // load, scale from 0 to the bound, both branches, turns across the
        // loop, with a point below and without (the major loop's end).
        let c = Coeffs::new(Params::DEFAULT).unwrap();
        let (mut loops, mut periods_worst) = (0, 0);
        for load in [100.0f32, 250.0, 450.0, 600.0] {
            let m = c.load_model(load).unwrap();
            let pmax = m.max_pressure_mpa();
            for scale in [0.0f32, 0.4, 0.8, 1.2, 1.6, 2.5] {
                for branch in [Branch::Contraction, Branch::Expansion] {
                    for (p_r, below) in turns(pmax, branch) {
                        let (mut s, mut moved, x) = reversal_loop(&m, below, p_r, branch, scale);
                        let (origin, target) = s.top2();
                        let origin = origin.unwrap();
                        let starts = new_loop_starts(&m, origin, target, branch, scale);
                        let p_end = end_pressure(&m, target, branch);
                        s.feedforward_pressure_mpa_moved(&mut moved, &MEM, &m, x, branch, scale);
                        // (No loop where the set-point is already past
                        // the point below: the loop closes at once.)
                        let Some(seg) = s.segment else {
                            continue;
                        };
                        let stroke = [m.root_contraction(), m.max_contraction()];
                        let first = (
                            search_step(&m, origin.pressure_mpa, branch, scale, starts.0, stroke).0,
                            search_step(&m, p_end, branch, scale, starts.1, stroke).0,
                        );
                        assert_eq!(
                            (seg.b_r.to_bits(), seg.b_t.to_bits()),
                            (first.0.to_bits(), first.1.to_bits()),
                            "{load} N, {scale}, {branch:?}, {p_r} MPa, {below:?}"
                        );
                        let exact = (
                            branch_contraction(&m, origin.pressure_mpa, branch, scale),
                            branch_contraction(&m, p_end, branch, scale),
                        );
                        if seg.b_r == exact.0 && seg.b_t == exact.1 {
                            // (Both ends at `Pmax`, or exact at once.)
                            continue;
                        }
                        assert!(!s.has_cached_loop(), "{load} N, {scale}, {branch:?}");
                        loops += 1;
                        let mut periods = 1;
                        while !s.has_cached_loop() && periods < 10 {
                            s.feedforward_pressure_mpa_moved(
                                &mut moved, &MEM, &m, x, branch, scale,
                            );
                            periods += 1;
                        }
                        periods_worst = periods_worst.max(periods);
                        let seg = s.segment.unwrap();
                        assert!(
                            (seg.b_r - exact.0).abs() <= 2e-6 && (seg.b_t - exact.1).abs() <= 2e-6,
                            "{load} N, {scale}, {branch:?}, {p_r} MPa, {below:?}: \
                                 {periods} periods, {:?} vs {exact:?}",
                            (seg.b_r, seg.b_t)
                        );
                    }
                }
            }
        }
        assert!(loops > 300, "{loops} loops searched");
        assert!(periods_worst <= 6, "{periods_worst} periods");
    }

    #[test]
    fn a_reversals_new_loop_without_tables_searches_for_its_ends_at_scale_one() {
        // While a load switch's tables are built, a reversal's new loop at
        // the paper's scale takes a Newton step for each end in its first
        // period (where two table-free bisections took 588 instructions on
        // the M4F, bench-m4's `shape_memory`), then one more each period
        // until both are done (at most 6 periods), and the loop is cached.
        // Its ends' branch pressures miss the ends' by at most 1e-6 MPa
        // (measured: 1.2e-7, the f32 rounding), where the table-free
        // bisection resolves 2^-12 of the stroke.
        let family = crate::load_model::FamilyF32::new(
            &crate::LoadFamily::from_params(&Params::DEFAULT).unwrap(),
        );
        let (mut loops, mut periods_worst, mut worst_miss) = (0, 0, 0.0f32);
        for load in [100.0f32, 250.0, 450.0, 600.0] {
            let m = family.model_without_tables(load);
            assert!(!m.inverse_ready());
            let pmax = m.max_pressure_mpa();
            for branch in [Branch::Contraction, Branch::Expansion] {
                for (p_r, below) in turns(pmax, branch) {
                    let (mut s, mut moved, x) = reversal_loop(&m, below, p_r, branch, 1.0);
                    let (origin, target) = s.top2();
                    let origin = origin.unwrap();
                    let starts = new_loop_starts(&m, origin, target, branch, 1.0);
                    let p_end = end_pressure(&m, target, branch);
                    s.feedforward_pressure_mpa_moved(&mut moved, &MEM, &m, x, branch, 1.0);
                    let Some(seg) = s.segment else {
                        continue;
                    };
                    let stroke = [m.root_contraction(), m.max_contraction()];
                    let first = (
                        search_step(&m, origin.pressure_mpa, branch, 1.0, starts.0, stroke).0,
                        search_step(&m, p_end, branch, 1.0, starts.1, stroke).0,
                    );
                    assert_eq!(
                        (seg.b_r.to_bits(), seg.b_t.to_bits()),
                        (first.0.to_bits(), first.1.to_bits()),
                        "{load} N, {branch:?}, {p_r} MPa, {below:?}"
                    );
                    loops += 1;
                    let mut periods = 1;
                    while !s.has_cached_loop() && periods < 10 {
                        s.feedforward_pressure_mpa_moved(&mut moved, &MEM, &m, x, branch, 1.0);
                        periods += 1;
                    }
                    periods_worst = periods_worst.max(periods);
                    assert!(s.has_cached_loop(), "{load} N, {branch:?}, {p_r} MPa");
                    let seg = s.segment.unwrap();
                    for (b, p) in [(seg.b_r, origin.pressure_mpa), (seg.b_t, p_end)] {
                        if p >= pmax {
                            assert_eq!(b, m.max_contraction());
                            continue;
                        }
                        let miss = (m.pressure_mpa(b, branch) - p).abs();
                        worst_miss = worst_miss.max(miss);
                        assert!(
                            miss <= 1e-6,
                            "{load} N, {branch:?}, {p_r} MPa, {below:?}: {periods} periods, \
                                 end {b} misses {p} MPa by {miss}"
                        );
                    }
                }
            }
        }
        eprintln!("{loops} loops, {periods_worst} periods at most, pressure missed by {worst_miss} MPa at most");
        assert!(loops >= 40, "{loops} loops searched");
        assert!(periods_worst <= 6, "{periods_worst} periods");
    }

    #[test]
    fn a_loop_a_wipe_out_exposes_has_its_exact_ends_at_once() {
        // Its turning point was not pushed in this period (a wipe-out
        // exposed it, mid-sweep, where the whole curve is in use at once):
        // the ends are `branch_contraction`'s in its first period, as
        // before the search, and the loop is cached.
        let m = model();
        let pmax = m.max_pressure_mpa();
        for scale in [0.4f32, 1.3, 2.5] {
            let mut s = ReversalStack::<4>::default();
            let mut moved = MovedPoints::<4>::default();
            let (p_t, p_r) = (0.2 * pmax, 0.7 * pmax);
            for (p, on) in [(p_t, Branch::Expansion), (p_r, Branch::Contraction)] {
                let x = branch_contraction(&m, p, on, scale);
                s.push_at_scale(
                    Reversal {
                        pressure_mpa: p,
                        contraction: x,
                    },
                    scale,
                );
            }
            let x = branch_contraction(&m, p_r, Branch::Contraction, scale) - 1e-4;
            s.feedforward_pressure_mpa_moved(&mut moved, &MEM, &m, x, Branch::Expansion, scale);
            assert!(s.has_cached_loop());
            let seg = s.segment.unwrap();
            assert_eq!(
                seg.b_r,
                branch_contraction(&m, p_r, Branch::Expansion, scale)
            );
            assert_eq!(
                seg.b_t,
                branch_contraction(&m, p_t, Branch::Expansion, scale)
            );
        }
    }

    #[test]
    fn empty_stack_is_the_paper_model() {
        let m = model();
        let mut s = ReversalStack::<8>::default();
        for p in [0.0, 0.1, 0.3, 0.5] {
            for br in [Branch::Contraction, Branch::Expansion] {
                assert_eq!(s.contraction(&MEM, &m, p, br, 1.0), m.contraction(p, br));
            }
        }
    }

    #[test]
    fn reversal_inside_the_loop_starts_where_it_turned_and_closes_on_the_previous_point() {
        let m = model();
        let mut s = ReversalStack::<8>::default();
        // Up the major branch to 0.2 MPa, then back down.
        let bottom = Reversal {
            pressure_mpa: 0.05,
            contraction: m.contraction(0.05, Branch::Contraction),
        };
        s.push(bottom);
        let top = Reversal {
            pressure_mpa: 0.3,
            contraction: m.contraction(0.3, Branch::Contraction),
        };
        s.push(top);
        // No jump: at the turning point the contraction is where it was.
        let at_top = s.contraction(&MEM, &m, 0.3, Branch::Expansion, 1.0);
        assert!((at_top - top.contraction).abs() < 1e-5);
        // The paper's model would jump to the expansion branch here.
        assert!(m.contraction(0.3, Branch::Expansion) - top.contraction > 0.01);
        // It closes on the previous reversal point.
        let at_bottom = s.contraction(&MEM, &m, 0.05, Branch::Expansion, 1.0);
        assert!((at_bottom - bottom.contraction).abs() < 1e-5);
        // Passing it wipes both points out: back on the major branch.
        let below = s.contraction(&MEM, &m, 0.04, Branch::Expansion, 1.0);
        assert!(s.points().is_empty());
        assert_eq!(below, m.contraction(0.04, Branch::Expansion));
    }

    #[test]
    fn a_merge_span_ends_the_blend_early_and_still_closes_on_the_target() {
        let m = model();
        let bottom = Reversal {
            pressure_mpa: 0.05,
            contraction: m.contraction(0.05, Branch::Contraction),
        };
        let top = Reversal {
            pressure_mpa: 0.4,
            contraction: m.contraction(0.4, Branch::Contraction),
        };
        let quick = NonLocalMemory {
            shape: 1.0,
            merge_span: 0.02,
        };
        let run = |mem: &NonLocalMemory, p: f32| {
            let mut s = ReversalStack::<8>::default();
            s.push(bottom);
            s.push(top);
            s.contraction(mem, &m, p, Branch::Expansion, 1.0)
        };
        // No jump at the turn, either way.
        assert!((run(&quick, 0.4) - top.contraction).abs() < 1e-5);
        // Halfway down, the limited blend has already merged: the curve runs
        // at the target's offset from the branch, away from the unlimited one.
        let d_t = bottom.contraction - m.contraction(0.05, Branch::Expansion);
        let mid = run(&quick, 0.2);
        assert!((mid - (m.contraction(0.2, Branch::Expansion) + d_t)).abs() < 1e-5);
        assert!(
            (run(&MEM, 0.2) - mid).abs() > 1e-3,
            "{} vs {mid}",
            run(&MEM, 0.2)
        );
        // Both close exactly on the previous reversal.
        assert!((run(&quick, 0.05) - bottom.contraction).abs() < 1e-5);
        // The unlimited span is the plain blend of the branch's progress.
        let b_r = m.contraction(0.4, Branch::Expansion);
        let b_t = m.contraction(0.05, Branch::Expansion);
        let b = m.contraction(0.2, Branch::Expansion);
        let w = MEM.blend((b - b_t) / (b_r - b_t));
        let want = b + d_t + ((top.contraction - b_r) - d_t) * w;
        assert!((run(&MEM, 0.2) - want).abs() < 1e-5);
    }

    #[test]
    fn full_stack_drops_the_oldest() {
        let mut s = ReversalStack::<3>::default();
        for k in 0..5 {
            s.push(Reversal {
                pressure_mpa: k as f32,
                contraction: 0.0,
            });
        }
        let p: [f32; 3] = core::array::from_fn(|i| s.points()[i].pressure_mpa);
        assert_eq!(p, [2.0, 3.0, 4.0]);
        s.push(Reversal {
            pressure_mpa: f32::NAN,
            contraction: 0.0,
        });
        assert_eq!(s.points().len(), 3);
        let mut none = ReversalStack::<0>::default();
        none.push(Reversal::default());
        assert!(none.points().is_empty());
    }
}

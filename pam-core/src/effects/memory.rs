//! Non-local memory: a reversal inside the loop follows a minor loop back to
//! where the previous reversal was, instead of jumping to the other branch
//! (the paper's conclusion names this as its missing effect).
//!
//! The memory is a stack of reversal points `(pressure, contraction)` of fixed
//! capacity `N`, with the wiping-out (Madelung) rules:
//!
//! 1. at a reversal the turning point is pushed;
//! 2. the curve from the top point `r` heads for the point below it `t` (or,
//!    for the first point, for the end of the major loop: 0 MPa falling,
//!    `Pmax` rising) and reaches it exactly;
//! 3. when the pressure passes `t` the minor loop has closed: `r` and `t` are
//!    wiped out and the curve from before the minor loop continues.
//!
//! The curve between `r` and `t` is the branch `B(p)` of the current
//! direction plus an offset in contraction that moves from `d_r = x_r − B(p_r)`
//! (the offset of `r` from the branch) to `d_t = x_t − B(p_t)` (that of `t`),
//! as the branch itself moves from `B(p_r)` to `B(p_t)`:
//!
//! `x = B(p) + d_t + (d_r − d_t)·w(s)`, `s = (B(p) − B(p_t))/(B(p_r) − B(p_t))`,
//! `w(s) = s / (s + k·(1 − s))`, `k` = [`NonLocalMemory::shape`].
//!
//! A real muscle forgets a reversal within a finite excursion: once the
//! pressure has moved far enough from the turning point it is back on a
//! branch (a Masing-type transition), however far away the target is. The
//! merge span `m` ([`NonLocalMemory::merge_span`], in contraction) bounds the
//! blend: `s = max(0, 1 − |B(p) − B(p_r)|/min(m, |B(p_r) − B(p_t)|))`. A loop
//! longer than `m` has merged at the target's offset `d_t` after `m` of
//! branch progress and runs parallel to the branch until it reaches `t`
//! (so it still closes there); a shorter one is the plain blend above.
//!
//! `w` is a rational blend (one division, no `powf`) with `w(0) = 0`,
//! `w(1) = 1`: `k = 1` moves the offset in proportion to the branch's own
//! progress (the minor loop is the branch affinely rescaled through its two
//! turning points); `k → ∞` leaves the reversal at once, which is the
//! paper's jump to the branch; `k → 0` holds the reversal's offset long.
//! Measuring progress along the branch (not in pressure) makes a reversal
//! near a stroke end, where the two branches meet, join the new branch
//! quickly, as a full-cycle reversal does.
//!
//! Cost: the branch inverse `B(p)` (the fast table inverse when the offset
//! is not scaled) once per sample; `B(p_r)`, `B(p_t)` are cached per minor
//! loop (recomputed after a push, a wipe-out, a change of branch, load
//! model or offset scale). The [`Simulator`](crate::Simulator)'s per-sample
//! path on a cached minor loop is one comparison for the wiping-out test, one
//! for the offset scale, the blend (one division) and the clamp to the
//! stroke: about 40 instructions on a Cortex-M4F besides the branch inverse
//! (bench-m4).
//!
//! When the stack is full the oldest point is dropped (its loop then closes
//! on the major loop instead): memory of at most `N` nested reversals.
//!
//! With a rate law the offset scale changes from sample to sample, and a
//! turning point is recorded with the scale of its moment
//! ([`ReversalStack::push_at_scale`]). A minor loop at another scale starts
//! from (and heads for) the point moved with the loop: at the same
//! pressure, the same fraction `φ = (p − CM(x))/(scale·y_hys(x))` of the
//! way between the two branches (eqs. 25/26 with the offset scaled), so a
//! point on a branch stays on it, and the loop widens and narrows with the
//! rate as the major loop does. Two more branch inverses per new loop, only
//! where the scale differs from the points' own.

use crate::branch::Branch;
use crate::error::Error;
use crate::load_model::{BranchParts, LoadModel};
use crate::math::clamp;

#[cfg(doc)]
use super::offset::branch_contraction_near;
use super::offset::{
    branch_contraction, inverse_resolution, MAX_OFFSET_SCALE, SCALED_INVERSE_ROUNDING,
};

/// Bisection steps of [`ReversalStack::inverse_pressure_mpa`] in branch
/// contraction: a stroke below 1 over 2²⁴ is 6·10⁻⁸ of contraction, the
/// resolution of an `f32` contraction near 0.1.
pub const MEMORY_INVERSE_STEPS: usize = 24;

/// Reversal points a model with memory remembers (nested minor loops);
/// older ones are dropped. The one depth of the workspace: the firmware's
/// feedforward runs it, and every host tool that simulates a model
/// (pam-lab's `simulate` and `diagnose`) evaluates with it, so the model a
/// diagnosis judges is the model the chip runs.
pub const MEMORY_DEPTH: usize = 8;

/// The pressure on `branch` at branch contraction `x` with the ellipse
/// offset scaled by `offset_scale` (eqs. 25/26; 1: the paper's model), in
/// `[0, Pmax]`: the forward counterpart of [`branch_contraction`] (the
/// model's closed-form direction: constraint pressure plus the scaled
/// offset).
#[inline]
pub fn branch_pressure_mpa(model: &LoadModel, x: f32, branch: Branch, offset_scale: f32) -> f32 {
    if offset_scale == 1.0 {
        return model.pressure_mpa(x, branch);
    }
    let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    clamp(
        model.constraint_pressure_mpa(x) + k * model.offset_mpa(x),
        0.0,
        model.max_pressure_mpa(),
    )
}

/// Parameters of the non-local memory.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NonLocalMemory {
    /// `k` of the minor-loop blend `w(s) = s/(s + k(1 − s))`, in
    /// `[0.05, 50]`: small values hold the reversal's offset long (a flat
    /// start), 1 rescales the branch, large values approach the paper's jump
    /// to the branch.
    pub shape: f32,
    /// Branch progress, in contraction, over which a reversal's offset
    /// decays, in `[MIN_MERGE_SPAN, 1]`: once the branch has moved this far
    /// from the turning point the curve runs parallel to the branch (at the
    /// target's offset) until it reaches the target. A minor loop shorter
    /// than this is the plain blend; 1 (longer than any stroke, and what a
    /// model file without the field means) never limits it.
    #[cfg_attr(feature = "serde", serde(default = "unlimited_merge_span"))]
    pub merge_span: f32,
}

/// Smallest [`NonLocalMemory::merge_span`].
pub const MIN_MERGE_SPAN: f32 = 0.002;

/// A [`NonLocalMemory::merge_span`] that never limits the blend.
pub const UNLIMITED_MERGE_SPAN: f32 = 1.0;

#[cfg(feature = "serde")]
fn unlimited_merge_span() -> f32 {
    UNLIMITED_MERGE_SPAN
}

impl NonLocalMemory {
    /// The blend of `shape` alone (no limit on the merge span).
    pub const fn with_shape(shape: f32) -> NonLocalMemory {
        NonLocalMemory {
            shape,
            merge_span: UNLIMITED_MERGE_SPAN,
        }
    }

    /// Finite, shape in `[0.05, 50]`, merge span in `[MIN_MERGE_SPAN, 1]`.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.shape.is_finite() {
            return Err(Error::NonFinite("memory.shape"));
        }
        if !self.merge_span.is_finite() {
            return Err(Error::NonFinite("memory.merge_span"));
        }
        if !(self.shape >= 0.05 && self.shape <= 50.0) {
            return Err(Error::OutOfRange("memory.shape", "must be in [0.05, 50]"));
        }
        if !(self.merge_span >= MIN_MERGE_SPAN && self.merge_span <= UNLIMITED_MERGE_SPAN) {
            return Err(Error::OutOfRange(
                "memory.merge_span",
                "must be in [MIN_MERGE_SPAN, 1]",
            ));
        }
        Ok(())
    }

    /// The blend `w(s) = s/(s + k(1 − s))` for `s` clamped to `[0, 1]` and
    /// `k` to `[0.05, 50]` (NaN `s` → 0): in `[0, 1]`, monotone, never NaN.
    #[inline]
    pub fn blend(&self, s: f32) -> f32 {
        self.blend_coeffs().apply(s)
    }

    /// `k` clamped to `[0.05, 50]` and `1 − k`, the per-sample constants of
    /// [`Self::blend`] (the [`Simulator`](crate::Simulator) computes them once).
    #[inline]
    pub(crate) fn blend_coeffs(&self) -> Blend {
        let k = clamp(self.shape, 0.05, 50.0);
        Blend {
            k,
            one_minus_k: 1.0 - k,
            inv_merge: 1.0 / clamp(self.merge_span, MIN_MERGE_SPAN, UNLIMITED_MERGE_SPAN),
        }
    }
}

/// [`NonLocalMemory::blend`] with its constants computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Blend {
    /// `k` in `[0.05, 50]`.
    k: f32,
    /// `1 − k`.
    one_minus_k: f32,
    /// `1/merge_span`, merge span clamped to `[MIN_MERGE_SPAN, 1]`.
    inv_merge: f32,
}

impl Blend {
    /// `w(s)`, the same operations as [`NonLocalMemory::blend`].
    #[inline]
    fn apply(self, s: f32) -> f32 {
        let s = clamp(s, 0.0, 1.0);
        // The denominator is k + s(1 − k) >= min(k, 1) >= 0.05.
        s / (self.k + s * self.one_minus_k)
    }
}

/// A reversal point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reversal {
    /// Pressure at the turning point, MPa.
    pub pressure_mpa: f32,
    /// Contraction at the turning point.
    pub contraction: f32,
}

/// The minor loop being followed, in branch coordinates, with what it was
/// computed for.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Segment {
    branch: Branch,
    scale_bits: u32,
    load_bits: u32,
    max_contraction_bits: u32,
    /// The wiping-out test of [`ReversalStack::wipe_out`] on an unclamped
    /// finite pressure `p`, as one comparison: the top pair is wiped out when
    /// `wipe_sign·p > wipe_mpa` (`wipe_sign` is +1 rising, −1 falling; see
    /// [`wipe_threshold`]).
    wipe_sign: f32,
    /// `wipe_sign` times the threshold of [`wipe_threshold`].
    wipe_mpa: f32,
    /// Bits of the [`Blend`]'s `inv_merge` it was computed with.
    merge_bits: u32,
    /// `B(p_r)`.
    b_r: f32,
    /// `B(p_t)` (or of the major loop's end).
    b_t: f32,
    /// `1/(B(p_r) − B(p_t))`, raised in magnitude to `1/merge_span` when the
    /// loop is longer than the merge span; 0 for a degenerate loop.
    inv_progress: f32,
    /// `d_t`.
    d_t: f32,
    /// `d_r − d_t`.
    d_rt: f32,
    /// The ends are not yet solved to the scaled inverse's resolution (a
    /// new loop of the feedforward at a reversal, see
    /// [`ReversalStack::segment_with`]): a period at the same scale takes
    /// their next Newton steps instead of serving the loop as it is. (In
    /// the padding after `branch`: the per-sample
    /// [`Simulator`](crate::Simulator)'s stack, which never sets it, is no
    /// larger.)
    searching: bool,
}

/// Fixed-capacity stack of reversal points with wiping-out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReversalStack<const N: usize> {
    points: [Reversal; N],
    /// The offset scale each point was recorded at (NaN: not known, the
    /// point is never rescaled; see [`ReversalStack::push_at_scale`]).
    scales: [f32; N],
    len: usize,
    segment: Option<Segment>,
}

impl<const N: usize> Default for ReversalStack<N> {
    fn default() -> Self {
        ReversalStack {
            points: [Reversal::default(); N],
            scales: [f32::NAN; N],
            len: 0,
            segment: None,
        }
    }
}

/// The part of [`rescaled`] with [`Ends::Newton`] that does not depend on
/// the offset scale the point moves to: its fraction `φ` of the way between
/// the branches, and the constraint model and the offset with their slopes
/// at its contraction, where the Newton step starts. With a rate law the
/// scale changes every period, and the points of the loop being followed
/// move every period: from these, one move is a few products and the
/// step's division instead of two evaluations of the model with their
/// square roots and divisions (bit for bit the same point).
///
/// The feedforward keeps one per position of each of its stacks
/// ([`MovedPoints`], passed to the stack's `*_moved` methods), valid for
/// the stack's top two positions, the two a minor loop moves: a push
/// forgets the new top's, a trial made from the memory takes the memory's
/// top's along, and the feedforward forgets the two a wipe-out exposes.
/// The stack itself stays as small as the per-sample
/// [`Simulator`](crate::Simulator) needs (kept in the stack, they cost its
/// step up to 10 instructions and 640 bytes of RAM at a depth of 16).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Moved {
    /// The branch the point was recorded on; `None`: not computed (or the
    /// position's point changed since).
    on: Option<Branch>,
    /// The point was pushed by the feedforward and has not moved since:
    /// its first move is skipped ([`moved_newton`]). (In the padding after
    /// `on`: no larger.)
    fresh: bool,
    /// Bits of the load and `Rx_i` of the model they were computed on.
    load_bits: u32,
    max_contraction_bits: u32,
    fraction: f32,
    /// The point's pressure clamped to `[0, Pmax]` and contraction clamped
    /// to the stroke (where the Newton step starts).
    pressure_mpa: f32,
    contraction: f32,
    parts: BranchParts,
}

impl Moved {
    pub(crate) const NONE: Moved = Moved {
        on: None,
        fresh: false,
        load_bits: 0,
        max_contraction_bits: 0,
        fraction: 0.0,
        pressure_mpa: 0.0,
        contraction: 0.0,
        parts: BranchParts {
            cubic: 0.0,
            offset: 0.0,
            cubic_slope: 0.0,
            offset_slope: 0.0,
        },
    };
}

/// The largest change of the offset scale since a point was recorded by
/// which its first move after the feedforward pushed it is skipped
/// ([`moved_newton`]): a point `φ` of the way between the branches moves by
/// about `φ·Δscale·y_hys/slope` of contraction, at most about `be/64` of
/// pressure (5·10⁻⁴ MPa for the default model).
const FRESH_SCALE_CHANGE: f32 = 1.0 / 64.0;

/// One [`Moved`] per stack position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MovedPoints<const N: usize>([Moved; N]);

impl<const N: usize> Default for MovedPoints<N> {
    fn default() -> Self {
        MovedPoints([Moved::NONE; N])
    }
}

impl<const N: usize> MovedPoints<N> {
    /// Position `i` holds another point now.
    #[inline(always)]
    pub(crate) fn forget(&mut self, i: usize) {
        if let Some(m) = self.0.get_mut(i) {
            m.on = None;
            m.fresh = false;
        }
    }

    /// Whether the top of a stack of `len` points was pushed by the
    /// feedforward and has not moved since ([`Moved::fresh`]).
    #[inline(always)]
    fn top_fresh(&self, len: usize) -> bool {
        len.checked_sub(1)
            .and_then(|i| self.0.get(i))
            .is_some_and(|m| m.fresh)
    }

    /// Position `i` holds a point pushed now ([`Moved::fresh`]).
    #[inline(always)]
    fn pushed(&mut self, i: usize) {
        if let Some(m) = self.0.get_mut(i) {
            m.on = None;
            m.fresh = true;
        }
    }

    /// Every position's [`Moved`] to be made again, each keeping whether it
    /// holds a point pushed and not moved since (the reference of
    /// `the_feedforward_with_moved_points_is_the_one_without_bit_for_bit`).
    #[cfg(test)]
    fn afresh(&self) -> Self {
        let mut out = MovedPoints::default();
        for (to, from) in out.0.iter_mut().zip(&self.0) {
            to.fresh = from.fresh;
        }
        out
    }

    /// The stack dropped its oldest point (every point moved down one).
    #[inline(always)]
    fn shift(&mut self) {
        if N > 1 {
            self.0.copy_within(1.., 0);
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
    /// than 1 are searched for over periods instead of solved at once
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
        let merge_bits = blend.inv_merge.to_bits();
        let mut warm = None;
        if let Some(s) = &self.segment {
            let same_loop = s.branch == branch
                && s.load_bits == load_bits
                && s.max_contraction_bits == max_contraction_bits
                && s.merge_bits == merge_bits;
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
            && offset_scale != 1.0
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
    /// Newton step for each end ([`search_step`]), from [`new_loop_starts`]
    /// for a new loop (the caller cleared the cache) and from the cached
    /// ends for one still searching at the same scale. The search ends
    /// where both ends are done (within the resolution, or at the pressure's
    /// rounding, or solved exactly where a step cannot go on). Out of line:
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
        let (b_r, done_r) = search_step(model, origin.pressure_mpa, branch, offset_scale, from.0);
        let (b_t, done_t) = search_step(model, p_t, branch, offset_scale, from.1);
        // The search ends where both steps at this scale are within the
        // resolution (not tested in a new loop's first period: from the
        // unscaled branch its steps are not, and the test cost that period
        // 30 instructions on the M4F).
        let resolution = inverse_resolution(model);
        let settled = |b: f32, x: f32, done: bool| done || (!new && (b - x).abs() <= resolution);
        let searching =
            offset_scale != 1.0 && !(settled(b_r, from.0, done_r) && settled(b_t, from.1, done_t));
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
        seg.eval(blend, model, x_branch)
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
    /// up to [`SCALED_INVERSE_STEPS`](super::offset::SCALED_INVERSE_STEPS) steps each); a
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
        if let Some(b) = seg.solve(blend, x_ref) {
            return branch_pressure_mpa(model, clamp(b, lo_x, hi_x), branch, offset_scale);
        }
        // No closed-form candidate (x_ref beyond the curve's reach, or
        // rounding at a region boundary): x(B) is non-decreasing in B, so
        // bisect for the largest B with x(B) <= x_ref.
        let (mut lo, mut hi) = (lo_x, hi_x);
        for _ in 0..MEMORY_INVERSE_STEPS {
            let mid = 0.5 * (lo + hi);
            if seg.eval(blend, model, mid) <= x_ref {
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
                return Some(seg.eval(blend, model, x_branch));
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
        Some(seg.eval(blend, model, x_branch))
    }
}

/// `r`, recorded at offset scale `recorded`, moved to `offset_scale`: at its
/// pressure, the same fraction of the way between the branches
/// ([`ReversalStack::push_at_scale`]); `on` places it when `recorded` is too
/// small to tell the branches apart. One branch inverse, as `ends` solves.
#[inline(never)]
fn rescaled(
    r: Reversal,
    recorded: f32,
    model: &LoadModel,
    on: Branch,
    offset_scale: f32,
    ends: Ends,
) -> Reversal {
    let fraction = fraction_between_branches(r, recorded, model, on);
    let k = fraction * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    let branch = if k >= 0.0 {
        Branch::Contraction
    } else {
        Branch::Expansion
    };
    let x = ends.solve(model, r.pressure_mpa, branch, k.abs(), Some(r.contraction));
    Reversal {
        pressure_mpa: r.pressure_mpa,
        contraction: if x.is_finite() { x } else { r.contraction },
    }
}

/// The fraction `φ = (p − CM(x))/(scale·y_hys(x))` of the way between the
/// branches at which `r` lies, recorded at offset scale `recorded`, in
/// `[−1, 1]`; `on`'s sign where the offset is too small to tell
/// ([`rescaled`]).
#[inline(always)]
fn fraction_between_branches(r: Reversal, recorded: f32, model: &LoadModel, on: Branch) -> f32 {
    let (cm, y) = (
        model.constraint_pressure_mpa(r.contraction),
        model.offset_mpa(r.contraction),
    );
    fraction_from(r, recorded, cm, y, on)
}

/// [`fraction_between_branches`] given `CM(x)` and `y_hys(x)` at the
/// point's contraction.
#[inline(always)]
fn fraction_from(r: Reversal, recorded: f32, cm: f32, y: f32, on: Branch) -> f32 {
    let recorded = clamp(recorded, 0.0, MAX_OFFSET_SCALE);
    let offset = recorded * y;
    if offset.abs() > 1e-9 {
        clamp((r.pressure_mpa - cm) / offset, -1.0, 1.0)
    } else {
        on.offset_sign()
    }
}

/// [`rescaled`] with [`Ends::Newton`], bit for bit, from the point's
/// [`Moved`] (made here when it was not, or was made on another model):
/// the one Newton step of [`newton_branch`] from the recorded contraction,
/// with the model's parts there computed once per point instead of once
/// per move. Inlined where points move (the per-period path with a rate
/// law); making `moved` is out of line.
#[inline(always)]
fn moved_newton(
    moved: &mut Moved,
    r: Reversal,
    recorded: f32,
    model: &LoadModel,
    on: Branch,
    offset_scale: f32,
) -> Reversal {
    let (lo, hi) = (model.root_contraction(), model.max_contraction());
    let (load_bits, max_contraction_bits) =
        (model.load_n().to_bits(), model.max_contraction().to_bits());
    // Field by field: `==` on an `Option` of a tuple is a library call.
    let made = matches!(moved.on, Some(b) if b == on)
        && moved.load_bits == load_bits
        && moved.max_contraction_bits == max_contraction_bits;
    if !made {
        let near = (offset_scale - recorded).abs() <= FRESH_SCALE_CHANGE;
        if moved.fresh && near {
            // Its first move since it was pushed, by a small change of the
            // scale: the feedforward pushes the extreme of its previous
            // period, recorded at that period's scale, and a rate law's
            // filter moves the scale little in a period. The new loop's
            // first period takes the point as recorded, and the next makes
            // its `Moved` (91 instructions on the M4F, about 140 with the
            // move: the reversal's period could not afford them, bench-m4's
            // `memory_rate` 2 065). A larger change (a step of the pressure
            // saturates the filter at once, as at a load switch) moves it.
            moved.fresh = false;
            return r;
        }
        make_moved(moved, r, recorded, model, on);
    }
    let k = moved.fraction * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    if k.abs() == 1.0 {
        // `Ends::solve` inverts a scale of exactly 1 exactly (rare).
        return rescaled(r, recorded, model, on, offset_scale, Ends::Newton);
    }
    // `newton_branch(model, p, branch, |k|, x0, 1)` for the branch of
    // `k`'s sign, with its evaluation at `x0` from `moved`. Its factor
    // `sign·clamp(|k|, 0, MAX_OFFSET_SCALE)` is `k` itself (`|φ| <= 1`, the
    // scale clamped to `[0, MAX_OFFSET_SCALE]`), but +0 for −0.
    let k = if k == 0.0 { 0.0 } else { k };
    let (g, slope) = moved.parts.at(k);
    let x = if slope > 0.0 {
        clamp(moved.contraction - (g - moved.pressure_mpa) / slope, lo, hi)
    } else {
        moved.contraction
    };
    Reversal {
        pressure_mpa: r.pressure_mpa,
        contraction: if x.is_finite() { x } else { r.contraction },
    }
}

/// [`Moved`] for `r`, recorded at `recorded` on `on`, on `model`.
#[inline(never)]
fn make_moved(moved: &mut Moved, r: Reversal, recorded: f32, model: &LoadModel, on: Branch) {
    let x = clamp(
        r.contraction,
        model.root_contraction(),
        model.max_contraction(),
    );
    // `CM` and `y_hys` at the contraction clamped to the stroke are the
    // fraction's at the point's own, bit for bit: `constraint_pressure_mpa`
    // clamps the same way, and `offset_mpa` is 0 outside the stroke as at
    // its ends (NaN → `R_i`: 0 there too).
    let parts = model.branch_parts(x);
    *moved = Moved {
        on: Some(on),
        fresh: false,
        load_bits: model.load_n().to_bits(),
        max_contraction_bits: model.max_contraction().to_bits(),
        fraction: fraction_from(r, recorded, parts.cubic, parts.offset, on),
        pressure_mpa: clamp(r.pressure_mpa, 0.0, model.max_pressure_mpa()),
        contraction: x,
        parts,
    };
}

impl Segment {
    /// The minor loop from `origin` towards `target` (the end of the major
    /// loop when `None`): two branch inverses, solved as `ends` says
    /// (`warm`: the ends of the same loop at another offset scale).
    #[allow(clippy::too_many_arguments)]
    fn new(
        blend: Blend,
        model: &LoadModel,
        origin: Reversal,
        target: Option<Reversal>,
        branch: Branch,
        offset_scale: f32,
        ends: Ends,
        warm: Option<(f32, f32)>,
    ) -> Segment {
        let p_t = end_pressure(model, target, branch);
        let (b_r, b_t) = match warm {
            // The cached loop at another scale (the per-period path with a
            // rate law): one Newton step for each end, `Ends::solve`'s
            // `newton_branch(.., 1)` with what the two share computed once.
            Some((w_r, w_t)) if ends == Ends::Newton && offset_scale != 1.0 => newton_ends(
                model,
                [origin.pressure_mpa, p_t],
                branch,
                offset_scale,
                [w_r, w_t],
            ),
            _ => {
                let end = |p: f32, x0: Option<f32>| ends.solve(model, p, branch, offset_scale, x0);
                (
                    end(origin.pressure_mpa, warm.map(|w| w.0)),
                    end(p_t, warm.map(|w| w.1)),
                )
            }
        };
        Segment::with_ends(
            blend,
            model,
            origin,
            target,
            branch,
            offset_scale,
            (b_r, b_t),
            false,
        )
    }

    /// The minor loop from `origin` towards `target` with its ends
    /// `(B(p_r), B(p_t))` given; `searching`: they are not yet solved to
    /// the resolution ([`ReversalStack::search_ends`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn with_ends(
        blend: Blend,
        model: &LoadModel,
        origin: Reversal,
        target: Option<Reversal>,
        branch: Branch,
        offset_scale: f32,
        (b_r, b_t): (f32, f32),
        searching: bool,
    ) -> Segment {
        let scale_bits = offset_scale.to_bits();
        let load_bits = model.load_n().to_bits();
        let max_contraction_bits = model.max_contraction().to_bits();
        let merge_bits = blend.inv_merge.to_bits();
        let d_t = match target {
            Some(t) => t.contraction - b_t,
            None => 0.0,
        };
        let span = b_r - b_t;
        let degenerate = !(span.abs() > 1e-6);
        let inv_progress = if degenerate {
            0.0
        } else if span > 0.0 {
            // `f32::max`/`min` without their NaN handling (a library call
            // on the M4F): `1/span` is not NaN here, `inv_merge` finite.
            let inv = 1.0 / span;
            if inv >= blend.inv_merge {
                inv
            } else {
                blend.inv_merge
            }
        } else {
            let inv = 1.0 / span;
            if inv <= -blend.inv_merge {
                inv
            } else {
                -blend.inv_merge
            }
        };
        let wipe_sign = match branch {
            Branch::Contraction => 1.0,
            Branch::Expansion => -1.0,
        };
        Segment {
            branch,
            scale_bits,
            load_bits,
            max_contraction_bits,
            merge_bits,
            wipe_sign,
            wipe_mpa: wipe_sign * wipe_threshold(target, branch, model.max_pressure_mpa()),
            b_r,
            b_t,
            inv_progress,
            d_t,
            // A degenerate loop sits at the target's offset (s is 1 there).
            d_rt: if degenerate {
                0.0
            } else {
                (origin.contraction - b_r) - d_t
            },
            searching,
        }
    }

    /// `B(p) + d_t + (d_r − d_t)·w(s)` for `B(p) = x_branch`, within the
    /// stroke; `s = 1 + (B(p) − B(p_r))·inv_progress` (clamped to `[0, 1]`
    /// by the blend).
    #[inline]
    fn eval(&self, blend: Blend, model: &LoadModel, x_branch: f32) -> f32 {
        let w = blend.apply(1.0 + (x_branch - self.b_r) * self.inv_progress);
        let x = x_branch + self.d_t + self.d_rt * w;
        clamp(x, model.root_contraction(), model.max_contraction())
    }

    /// The branch contraction `B` at which the loop's curve (unclamped) is
    /// at `x_ref`, in closed form, or `None` when no candidate checks out.
    ///
    /// With `s = 1 + (B − B_r)·i` (`i` = `inv_progress`) the curve is
    /// `B + d_t + d_rt·w(s)`. Where `s ≥ 1` (`w = 1`) it is
    /// `B = x_ref − d_t − d_rt`; where `s ≤ 0` (`w = 0`), `B = x_ref − d_t`;
    /// in between, `B = B_r + (s − 1)/i` and
    /// `(s − 1)(k + (1 − k)s) + i·d_rt·s − i·c·(k + (1 − k)s) = 0`,
    /// `c = x_ref − d_t − B_r`: a quadratic in `s`. Each candidate is
    /// checked against its region and the curve.
    fn solve(&self, blend: Blend, x_ref: f32) -> Option<f32> {
        let big_x = x_ref - self.d_t;
        let i = self.inv_progress;
        let s_of = |b: f32| 1.0 + (b - self.b_r) * i;
        let fits = |b: f32| {
            let w = blend.apply(s_of(b));
            let x = b + self.d_t + self.d_rt * w;
            (x - x_ref).abs() <= 1e-6 + 1e-5 * x_ref.abs()
        };
        // w = 1 (at or behind the turning point, or a degenerate loop).
        let b1 = big_x - self.d_rt;
        if !(s_of(b1) < 1.0) && fits(b1) {
            return Some(b1);
        }
        // w = 0 (merged: parallel to the branch at the target's offset).
        if !(s_of(big_x) > 0.0) && fits(big_x) {
            return Some(big_x);
        }
        if i == 0.0 {
            return None;
        }
        let (k, m) = (blend.k, blend.one_minus_k);
        let c = big_x - self.b_r;
        let qa = m;
        let qb = k - m + i * self.d_rt - i * c * m;
        let qc = -k * (1.0 + i * c);
        let (first, second) = if qa.abs() < 1e-6 {
            (-qc / qb, f32::NAN)
        } else {
            let disc = qb * qb - 4.0 * qa * qc;
            if !(disc >= 0.0) {
                return None;
            }
            let root = crate::math::sqrt(disc);
            let q = -0.5 * (qb + if qb >= 0.0 { root } else { -root });
            (q / qa, qc / q)
        };
        // The first root in `[0, 1]` (a NaN one is not) whose `B` checks
        // out, in that order (two candidates written out: an iterator over
        // them costs a few dozen instructions more on the M4F).
        let candidate = |s: f32| {
            let b = self.b_r + (s - 1.0) / i;
            ((-1e-6..=1.0 + 1e-6).contains(&s) && fits(b)).then_some(b)
        };
        candidate(first).or_else(|| candidate(second))
    }
}

/// The pressure of a minor loop's far end: the target's, or for the first
/// reversal's curve, which closes on the end of the major loop, `Pmax`
/// rising and 0 falling.
#[inline(always)]
fn end_pressure(model: &LoadModel, target: Option<Reversal>, branch: Branch) -> f32 {
    match target {
        Some(t) => t.pressure_mpa,
        None => match branch {
            Branch::Contraction => model.max_pressure_mpa(),
            Branch::Expansion => 0.0,
        },
    }
}

/// One step of [`ReversalStack::search_ends`] for the loop's end at
/// `pressure_mpa` from `x`: [`newton_branch`]'s step, and whether the end
/// is done (the step from where the pressure misses by no more than its
/// rounding, [`SCALED_INVERSE_ROUNDING`], as [`branch_contraction_near`]
/// stops). Where the step cannot go on, the end is [`branch_contraction`]'s
/// at once (done): at `Pmax` (whose inverse is `Rx_i` without a step), and
/// where the branch's slope is not positive or the step leaves the stroke,
/// which plain Newton steps do not recover from (near the stroke's ends,
/// where the ellipse's vertical tangent meets them: the end of the major
/// loop at 0 MPa falling starts there), but the exact iteration's
/// bisection does (a few such periods cost it, rarely).
#[inline(always)]
fn search_step(
    model: &LoadModel,
    pressure_mpa: f32,
    branch: Branch,
    offset_scale: f32,
    x: f32,
) -> (f32, bool) {
    let pmax = model.max_pressure_mpa();
    let p = clamp(pressure_mpa, 0.0, pmax);
    let (lo, hi) = (model.root_contraction(), model.max_contraction());
    let x = clamp(x, lo, hi);
    if p < pmax {
        let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
        let (g, slope) = model.branch_and_slope(x, k);
        let next = x - (g - p) / slope;
        if slope > 0.0 && next >= lo && next <= hi {
            // Also done where the pressure misses by no more than its own
            // rounding: Newton steps from there alternate about the answer
            // just over the resolution and would not end.
            return (next, (g - p).abs() <= SCALED_INVERSE_ROUNDING * pmax);
        }
    }
    (
        branch_contraction(model, pressure_mpa, branch, offset_scale),
        true,
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
fn new_loop_starts(
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

/// How a minor loop's ends are solved for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Ends {
    /// [`branch_contraction`] (its Newton iteration at a scale other than
    /// 1): what the forward model computes.
    Exact,
    /// Newton steps on the same equation (the feedforward's bounded path).
    Newton,
}

impl Ends {
    /// The branch contraction at `pressure_mpa`; `x0` a starting point
    /// for [`Ends::Newton`] (one step from it; without one, exact).
    fn solve(
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
fn newton_branch(
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
fn newton_ends(
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

/// The threshold `θ` of the wiping-out test for the point `target` below the
/// top on `branch`: wiped out when `p > θ` rising, `p < θ` falling, for a
/// finite unclamped `p`.
///
/// [`ReversalStack::wipe_out`] tests `c = clamp(p, 0, Pmax)` against `p_t`.
/// Rising, `c > p_t` is `p > p_t` for `p_t` in `[0, Pmax)`, always true for
/// `p_t < 0` (`c >= 0`) and never for `p_t >= Pmax` (`c <= Pmax`); falling,
/// `c < p_t` is `p < p_t` for `p_t` in `(0, Pmax]`, never for `p_t <= 0` and
/// always for `p_t > Pmax`.
fn wipe_threshold(target: Option<Reversal>, branch: Branch, max_pressure_mpa: f32) -> f32 {
    let (never, always) = match branch {
        Branch::Contraction => (f32::INFINITY, f32::NEG_INFINITY),
        Branch::Expansion => (f32::NEG_INFINITY, f32::INFINITY),
    };
    let Some(t) = target else {
        return never;
    };
    let tp = t.pressure_mpa;
    match branch {
        Branch::Contraction if tp < 0.0 => always,
        Branch::Contraction if tp >= max_pressure_mpa => never,
        Branch::Expansion if tp <= 0.0 => never,
        Branch::Expansion if tp > max_pressure_mpa => always,
        _ => tp,
    }
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
    fn a_moved_point_is_the_rescaled_one_bit_for_bit() {
        let c = Coeffs::new(Params::DEFAULT).unwrap();
        for load in [100.0f32, 250.0, 600.0] {
            let m = c.load_model(load).unwrap();
            let pmax = m.max_pressure_mpa();
            for br in [Branch::Contraction, Branch::Expansion] {
                for i in 0..=40 {
                    let p = pmax * (i as f32 / 40.0) - 0.01;
                    for recorded in [0.0f32, 0.5, 1.0, 1.7, 4.0] {
                        let x_branch = branch_contraction(&m, p, br, recorded.max(0.1));
                        for dx in [-0.02f32, 0.0, 0.003, 0.05] {
                            let r = Reversal {
                                pressure_mpa: p,
                                contraction: x_branch + dx,
                            };
                            let mut moved = Moved::NONE;
                            for scale in [0.0f32, 0.3, 0.99, 1.0, 1.01, 2.5, 4.0, 7.0] {
                                for on in [Branch::Contraction, Branch::Expansion] {
                                    let want = rescaled(r, recorded, &m, on, scale, Ends::Newton);
                                    let got = moved_newton(&mut moved, r, recorded, &m, on, scale);
                                    assert_eq!(
                                        (got.pressure_mpa.to_bits(), got.contraction.to_bits()),
                                        (want.pressure_mpa.to_bits(), want.contraction.to_bits()),
                                        "{load} {br:?} {p} {recorded} {dx} {scale} {on:?}"
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
    }

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
                    for (i, j) in [(2, 5), (3, 7), (5, 8), (1, 4)] {
                        // The turn on the other branch, the point below on
                        // this one (further along `branch` than the turn).
                        let (a, b) = (pmax * i as f32 / 10.0, pmax * j as f32 / 10.0);
                        let (p_r, p_t) = match branch {
                            Branch::Contraction => (a, b),
                            Branch::Expansion => (b, a),
                        };
                        for below in [Some(p_t), None] {
                            let (mut s, mut moved, x) =
                                reversal_loop(&m, below, p_r, branch, scale);
                            let (origin, target) = s.top2();
                            let origin = origin.unwrap();
                            let starts = new_loop_starts(&m, origin, target, branch, scale);
                            let p_end = end_pressure(&m, target, branch);
                            s.feedforward_pressure_mpa_moved(
                                &mut moved, &MEM, &m, x, branch, scale,
                            );
                            // (No loop where the set-point is already past
                            // the point below: the loop closes at once.)
                            let Some(seg) = s.segment else {
                                continue;
                            };
                            let first = (
                                search_step(&m, origin.pressure_mpa, branch, scale, starts.0).0,
                                search_step(&m, p_end, branch, scale, starts.1).0,
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
                                // (An end at `Pmax`, or both fell back.)
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
                                (seg.b_r - exact.0).abs() <= 2e-6
                                    && (seg.b_t - exact.1).abs() <= 2e-6,
                                "{load} N, {scale}, {branch:?}, {p_r} MPa, {below:?}: \
                                 {periods} periods, {:?} vs {exact:?}",
                                (seg.b_r, seg.b_t)
                            );
                        }
                    }
                }
            }
        }
        assert!(loops > 300, "{loops} loops searched");
        assert!(periods_worst <= 6, "{periods_worst} periods");
    }

    #[test]
    fn the_zero_pressure_estimate_starts_a_newton_step_towards_the_crossing() {
        // The end of the major loop falling without the tables
        // (`LoadModel::zero_pressure_expansion_estimate`): the branch rises
        // at the estimate (a Newton step goes, where from the stroke's
        // middle it left the stroke and the exact iteration had to run),
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
                // The branch rises there: the step is a Newton step, not the
                // exact iteration's fallback.
                let (_, slope) = m.branch_and_slope(start, -scale);
                assert!(slope > 0.0, "{load} N, {scale}: slope {slope} at {start}");
                let (x, _) = search_step(&m, 0.0, Branch::Expansion, scale, start);
                let stroke = m.max_contraction() - m.root_contraction();
                worst = worst.max((x - exact).abs() / stroke);
            }
        }
        // (Measured: 1e-4 of the stroke at the scale bound, 600 N.)
        assert!(worst < 5e-4, "{worst} of the stroke");
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

    fn model() -> LoadModel {
        Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model(200.0)
            .unwrap()
    }

    const MEM: NonLocalMemory = NonLocalMemory::with_shape(1.0);

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

    #[test]
    fn validation() {
        assert_eq!(MEM.validate(), Ok(()));
        for bad in [0.0, 0.001, 1.5] {
            let m = NonLocalMemory {
                shape: 1.0,
                merge_span: bad,
            };
            assert!(m.validate().is_err(), "{bad}");
        }
        assert!(NonLocalMemory::with_shape(0.0).validate().is_err());
        assert_eq!(
            NonLocalMemory::with_shape(f32::NAN).validate(),
            Err(Error::NonFinite("memory.shape"))
        );
    }
}

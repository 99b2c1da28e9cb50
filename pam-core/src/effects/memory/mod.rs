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
//! blend: `s = max(0, 1 − |B(p) − B(p_r)|/min(m, |B(p_r) − B(p_t)|))` (`m`
//! raised where the curve would run backwards, below). A loop
//! longer than `m` has merged at the target's offset `d_t` after `m` of
//! branch progress and runs parallel to the branch until it reaches `t`
//! (so it still closes there); a shorter one is the plain blend above.
//!
//! `w` is a rational blend (one division, no `powf`) with `w(0) = 0`,
//! `w(1) = 1`: `k = 1` moves the offset in proportion to the branch's own
//! progress (the minor loop is the branch affinely rescaled through its two
//! turning points); a large `k` leaves the reversal quickly, a small one
//! holds the reversal's offset long.
//! Measuring progress along the branch (not in pressure) makes a reversal
//! near a stroke end, where the two branches meet, join the new branch
//! quickly, as a full-cycle reversal does.
//!
//! A curve never runs backwards (contraction against the pressure's
//! direction between two reversals): a friction's loop does not, and the
//! feedforward inverts the curve. Along the loop the curve's slope in the
//! branch's progress `u` is `1 − b·w′(s)/D`, `D` the span over which the
//! offset decays, `b` the part of the offset's change `d_r − d_t` that
//! runs against the branch's progress, and `w′` at most `max(k, 1/k)`. So
//! the decay span is `D = min(|B(p_r) − B(p_t)|, max(m, b·max(k, 1/k)))`,
//! and where the loop is shorter than `b·max(k, 1/k)` its blend takes
//! `k` nearer 1, `max(k, 1/k) = D/b` (at least 1: where the target lies
//! beyond the curve's monotone reach, `b > |B(p_r) − B(p_t)|`, `k = 1` is
//! the least backwards). With `k = 1` and `D = b` the curve holds the
//! turning point's contraction until the branch comes to it, then follows
//! it: a Coulomb friction's reversal. (Before, a large `k` with a short
//! merge span jumped to the other branch at the reversal, the paper's
//! model's jump, which runs backwards: on host-sim's memory rig
//! `diagnose` fitted `k` 6.9 and a merge span of 0.12, whose falling
//! curves first went towards more contraction; with the decay span bound
//! it fits `k` 1.4 at the least merge span, and the memory cuts 35 % of
//! the held-out error on fit's static model instead of 26 %.)
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

mod ends;
mod moved;
mod segment;
mod stack;

pub(crate) use moved::MovedPoints;
pub use stack::ReversalStack;

use crate::branch::Branch;
use crate::error::Error;
use crate::load_model::LoadModel;
use crate::math::clamp;

#[cfg(doc)]
use super::offset::branch_contraction;
use super::offset::MAX_OFFSET_SCALE;

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
    /// start), 1 rescales the branch, large values leave the reversal
    /// quickly (within what keeps the curve from running backwards, see
    /// the module docs).
    pub shape: f32,
    /// Branch progress, in contraction, over which a reversal's offset
    /// decays, in `[MIN_MERGE_SPAN, 1]`, at least the span that keeps the
    /// curve from running backwards (module docs): once the branch has
    /// moved this far from the turning point the curve runs parallel to the
    /// branch (at the target's offset) until it reaches the target. A minor
    /// loop shorter than this is the plain blend; 1 (longer than any
    /// stroke, and what a model file without the field means) never limits
    /// it.
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
        rational_blend(self.blend_coeffs().k, s)
    }

    /// `k` clamped to `[0.05, 50]`, the merge span clamped and `max(k, 1/k)`:
    /// the per-loop constants of the blend (the [`Simulator`](crate::Simulator)
    /// computes them once).
    #[inline]
    pub(crate) fn blend_coeffs(&self) -> Blend {
        let k = clamp(self.shape, 0.05, 50.0);
        let merge_span = clamp(self.merge_span, MIN_MERGE_SPAN, UNLIMITED_MERGE_SPAN);
        Blend {
            k,
            merge_span,
            steepest: if k >= 1.0 { k } else { 1.0 / k },
        }
    }
}

/// [`NonLocalMemory::blend`] with its constants computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Blend {
    /// `k` in `[0.05, 50]`.
    k: f32,
    /// The merge span clamped to `[MIN_MERGE_SPAN, 1]`.
    merge_span: f32,
    /// `max(k, 1/k)`: the blend's steepest slope `w′`.
    steepest: f32,
}

/// `w(s) = s/(k + s(1 − k))` for `s` clamped to `[0, 1]` and `k` in
/// `[0.05, 50]`: [`NonLocalMemory::blend`] and each minor loop's blend.
#[inline(always)]
fn rational_blend(k: f32, s: f32) -> f32 {
    let s = clamp(s, 0.0, 1.0);
    // The denominator is k + s(1 − k) >= min(k, 1) >= 0.05.
    s / (k + s * (1.0 - k))
}

/// A reversal point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reversal {
    /// Pressure at the turning point, MPa.
    pub pressure_mpa: f32,
    /// Contraction at the turning point.
    pub contraction: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Coeffs, Params};

    pub(super) fn model() -> LoadModel {
        Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model(200.0)
            .unwrap()
    }

    pub(super) const MEM: NonLocalMemory = NonLocalMemory::with_shape(1.0);

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

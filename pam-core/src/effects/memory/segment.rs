//! The minor loop being followed between two turning points, in branch
//! coordinates: the blend of the offset from the branch
//! `x = B(p) + d_t + (d_r − d_t)·w(s)`, its wiping-out threshold, and its
//! inverse in closed form.

use crate::branch::Branch;
use crate::load_model::LoadModel;
use crate::math::clamp;

use super::ends::{end_pressure, newton_ends, Ends};
#[cfg(doc)]
use super::ReversalStack;
use super::{rational_blend, Blend, Reversal};

/// The minor loop being followed, in branch coordinates, with what it was
/// computed for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Segment {
    pub(super) branch: Branch,
    pub(super) scale_bits: u32,
    pub(super) load_bits: u32,
    pub(super) max_contraction_bits: u32,
    /// The wiping-out test of [`ReversalStack::wipe_out`] on an unclamped
    /// finite pressure `p`, as one comparison: the top pair is wiped out when
    /// `wipe_sign·p > wipe_mpa` (`wipe_sign` is +1 rising, −1 falling; see
    /// [`wipe_threshold`]).
    pub(super) wipe_sign: f32,
    /// `wipe_sign` times the threshold of [`wipe_threshold`].
    pub(super) wipe_mpa: f32,
    /// Bits of the [`Blend`]'s merge span it was computed with.
    pub(super) merge_bits: u32,
    /// Bits of the [`Blend`]'s `k` it was computed with (this loop's own
    /// `k`, below, may differ).
    pub(super) shape_bits: u32,
    /// `B(p_r)`.
    pub(super) b_r: f32,
    /// `B(p_t)` (or of the major loop's end).
    pub(super) b_t: f32,
    /// `1/(B(p_r) − B(p_t))`, raised in magnitude to `1/span` when the
    /// loop is longer than its decay span (the merge span, or the span that
    /// keeps the curve monotone, see [`Segment::with_ends`]); 0 for a
    /// degenerate loop.
    inv_progress: f32,
    /// `k` of this loop's blend: the model's, or nearer 1 where a loop
    /// shorter than its offset's change needs it to stay monotone.
    k: f32,
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
    pub(super) searching: bool,
}

impl Segment {
    /// The minor loop from `origin` towards `target` (the end of the major
    /// loop when `None`): two branch inverses, solved as `ends` says
    /// (`warm`: the ends of the same loop at another offset scale).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
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
    pub(super) fn with_ends(
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
        let merge_bits = blend.merge_span.to_bits();
        let shape_bits = blend.k.to_bits();
        let d_t = match target {
            Some(t) => t.contraction - b_t,
            None => 0.0,
        };
        let span = b_r - b_t;
        let degenerate = !(span.abs() > 1e-6);
        let d_rt = (origin.contraction - b_r) - d_t;
        let (inv_progress, k) = if degenerate {
            (0.0, blend.k)
        } else {
            let length = span.abs();
            // The offset's change against the branch's progress `back`:
            // the curve's slope in branch progress is `1 − back·w′(s)/decay`,
            // `w′` at most `max(k, 1/k)`, so the decay span is at least
            // `back·max(k, 1/k)` (the module docs). `f32::max`/`min`
            // without their NaN handling (a library call on the M4F): every
            // value here is finite; a `back` at or below 0 asks for nothing.
            let back = if span > 0.0 { -d_rt } else { d_rt };
            let monotone = back * blend.steepest;
            let wanted = if monotone > blend.merge_span {
                monotone
            } else {
                blend.merge_span
            };
            let decay = if wanted < length { wanted } else { length };
            let k = if monotone <= decay {
                blend.k
            } else if decay <= back {
                // Beyond the curve's monotone reach: `k = 1` is the least
                // backwards the blend gets.
                1.0
            } else if blend.k >= 1.0 {
                // A loop shorter than its monotone decay span:
                // `max(k, 1/k) = decay/back`.
                decay / back
            } else {
                back / decay
            };
            let inv = if span > 0.0 {
                1.0 / decay
            } else {
                -1.0 / decay
            };
            (inv, k)
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
            shape_bits,
            wipe_sign,
            wipe_mpa: wipe_sign * wipe_threshold(target, branch, model.max_pressure_mpa()),
            b_r,
            b_t,
            inv_progress,
            k,
            d_t,
            // A degenerate loop sits at the target's offset (s is 1 there).
            d_rt: if degenerate { 0.0 } else { d_rt },
            searching,
        }
    }

    /// `B(p) + d_t + (d_r − d_t)·w(s)` for `B(p) = x_branch`, within the
    /// stroke; `s = 1 + (B(p) − B(p_r))·inv_progress` (clamped to `[0, 1]`
    /// by the blend).
    #[inline]
    pub(super) fn eval(&self, model: &LoadModel, x_branch: f32) -> f32 {
        let w = self.blend(1.0 + (x_branch - self.b_r) * self.inv_progress);
        let x = x_branch + self.d_t + self.d_rt * w;
        clamp(x, model.root_contraction(), model.max_contraction())
    }

    /// `w(s)` with this loop's `k`.
    #[inline(always)]
    fn blend(&self, s: f32) -> f32 {
        rational_blend(self.k, s)
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
    pub(super) fn solve(&self, x_ref: f32) -> Option<f32> {
        let big_x = x_ref - self.d_t;
        let i = self.inv_progress;
        let s_of = |b: f32| 1.0 + (b - self.b_r) * i;
        let fits = |b: f32| {
            let w = self.blend(s_of(b));
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
        let (k, m) = (self.k, 1.0 - self.k);
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

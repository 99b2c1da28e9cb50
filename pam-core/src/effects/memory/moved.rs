//! A turning point moved with its loop to another offset scale: at its
//! pressure, the same fraction of the way between the branches (eqs. 25/26
//! with the offset scaled), and the feedforward's cache of what a move
//! needs per point.

use crate::branch::Branch;
use crate::effects::offset::MAX_OFFSET_SCALE;
use crate::load_model::{BranchParts, LoadModel};
use crate::math::clamp;

#[cfg(doc)]
use super::ends::newton_branch;
use super::ends::Ends;
use super::Reversal;
#[cfg(doc)]
use super::ReversalStack;

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
pub(crate) struct MovedPoints<const N: usize>(pub(super) [Moved; N]);

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
    pub(super) fn top_fresh(&self, len: usize) -> bool {
        len.checked_sub(1)
            .and_then(|i| self.0.get(i))
            .is_some_and(|m| m.fresh)
    }

    /// Position `i` holds a point pushed now ([`Moved::fresh`]).
    #[inline(always)]
    pub(super) fn pushed(&mut self, i: usize) {
        if let Some(m) = self.0.get_mut(i) {
            m.on = None;
            m.fresh = true;
        }
    }

    /// Every position's [`Moved`] to be made again, each keeping whether it
    /// holds a point pushed and not moved since (the reference of
    /// `the_feedforward_with_moved_points_is_the_one_without_bit_for_bit`).
    #[cfg(test)]
    pub(super) fn afresh(&self) -> Self {
        let mut out = MovedPoints::default();
        for (to, from) in out.0.iter_mut().zip(&self.0) {
            to.fresh = from.fresh;
        }
        out
    }

    /// The stack dropped its oldest point (every point moved down one).
    #[inline(always)]
    pub(super) fn shift(&mut self) {
        if N > 1 {
            self.0.copy_within(1.., 0);
        }
    }
}

/// `r`, recorded at offset scale `recorded`, moved to `offset_scale`: at its
/// pressure, the same fraction of the way between the branches
/// ([`ReversalStack::push_at_scale`]); `on` places it when `recorded` is too
/// small to tell the branches apart. One branch inverse, as `ends` solves.
#[inline(never)]
pub(super) fn rescaled(
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
pub(super) fn moved_newton(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::offset::branch_contraction;
    use crate::{Coeffs, Params};

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
}

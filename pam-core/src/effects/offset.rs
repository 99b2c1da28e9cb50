//! The ellipse offset `be` of eq. (24) scaled by an effect: its bound
//! ([`MAX_OFFSET_SCALE`]) and the inverse model of a branch with the scaled
//! offset ([`branch_contraction`]), shared by the effects that scale it
//! (memory, rate, width) and the simulator.

use crate::branch::Branch;
use crate::load_model::LoadModel;
use crate::math::clamp;

/// Largest factor any effect may put on the ellipse offset `be` of eq. (24).
pub const MAX_OFFSET_SCALE: f32 = 4.0;

/// Bisection steps of [`branch_contraction`] when the offset is scaled:
/// the stroke (about 0.25) over 2²⁴ is below 2·10⁻⁸ of contraction.
pub const SCALED_INVERSE_STEPS: usize = 24;

/// Inverse model of one branch with the ellipse offset scaled by
/// `offset_scale`: the contraction `x` in `[R_i, Rx_i]` where
/// `CM(x) ± offset_scale·y_hys(x) = pressure_mpa` (eqs. 25–26 with the
/// height `offset_scale·be`).
///
/// A scale of exactly 1 is [`LoadModel::contraction`]; otherwise a bisection
/// of [`SCALED_INVERSE_STEPS`] steps (bounded work). Pressure is clamped to
/// `[0, Pmax]` (NaN → 0); the scale to `[0, MAX_OFFSET_SCALE]` (NaN → 0).
#[inline]
pub fn branch_contraction(
    model: &LoadModel,
    pressure_mpa: f32,
    branch: Branch,
    offset_scale: f32,
) -> f32 {
    if offset_scale == 1.0 {
        return model.contraction(pressure_mpa, branch);
    }
    scaled_branch_contraction(model, pressure_mpa, branch, offset_scale)
}

/// [`branch_contraction`]'s bisection (out of line: the scale of 1, the
/// table inverse, is the common path of its callers).
#[inline(never)]
fn scaled_branch_contraction(
    model: &LoadModel,
    pressure_mpa: f32,
    branch: Branch,
    offset_scale: f32,
) -> f32 {
    let p = clamp(pressure_mpa, 0.0, model.max_pressure_mpa());
    let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    let (mut lo, mut hi) = (model.root_contraction(), model.max_contraction());
    let mut step = || {
        let mid = 0.5 * (lo + hi);
        // `constraint_pressure_mpa(mid) + k·offset_mpa(mid)` bit for bit
        // (`mid` is inside the stroke), without their clamps.
        if model.branch_in_stroke(mid, k) <= p {
            lo = mid;
        } else {
            hi = mid;
        }
    };
    // Four steps per pass: the loop's own overhead is a fifth of a step.
    const _: () = assert!(SCALED_INVERSE_STEPS % 4 == 0);
    for _ in 0..SCALED_INVERSE_STEPS / 4 {
        step();
        step();
        step();
        step();
    }
    clamp(
        0.5 * (lo + hi),
        model.root_contraction(),
        model.max_contraction(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Coeffs, Params};

    #[test]
    fn the_scaled_branch_inverse_is_the_bisection_on_the_forward_model() {
        // `branch_contraction`'s loop through `branch_in_stroke`: the
        // documented bisection bit for bit.
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        for load in [100.0, 333.0, 600.0] {
            let m = coeffs.load_model(load).unwrap();
            for scale in [0.0, 0.5, 0.97, 1.3, 2.0, MAX_OFFSET_SCALE, 9.0] {
                for br in [Branch::Contraction, Branch::Expansion] {
                    let reference = |p: f32| {
                        let p = clamp(p, 0.0, m.max_pressure_mpa());
                        let k = br.offset_sign() * clamp(scale, 0.0, MAX_OFFSET_SCALE);
                        let (mut lo, mut hi) = (m.root_contraction(), m.max_contraction());
                        for _ in 0..SCALED_INVERSE_STEPS {
                            let mid = 0.5 * (lo + hi);
                            let g = m.constraint_pressure_mpa(mid) + k * m.offset_mpa(mid);
                            if g <= p {
                                lo = mid;
                            } else {
                                hi = mid;
                            }
                        }
                        clamp(0.5 * (lo + hi), m.root_contraction(), m.max_contraction())
                    };
                    for i in 0..=2_000 {
                        let p = -0.01 + 0.6 * i as f32 / 2_000.0;
                        let (a, b) = (branch_contraction(&m, p, br, scale), reference(p));
                        assert_eq!(
                            a.to_bits(),
                            b.to_bits(),
                            "{load} N, {scale}, {p} MPa, {br:?}"
                        );
                    }
                }
            }
        }
    }
}

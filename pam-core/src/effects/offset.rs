//! The ellipse offset `be` of eq. (24) scaled by an effect: its bound
//! ([`MAX_OFFSET_SCALE`]) and the inverse model of a branch with the scaled
//! offset ([`branch_contraction`]), shared by the effects that scale it
//! (memory, rate, width) and the simulator.

use crate::branch::Branch;
use crate::load_model::LoadModel;
use crate::math::clamp;

/// Largest factor any effect may put on the ellipse offset `be` of eq. (24).
pub const MAX_OFFSET_SCALE: f32 = 4.0;

/// Most steps of [`branch_contraction`] when the offset is scaled: as many
/// as a bisection needs to narrow the stroke (about 0.25) below 2·10⁻⁸ of
/// contraction, the bound when every step is a bisection. From the
/// unscaled inverse it takes 2–5 branch evaluations on most inputs.
pub const SCALED_INVERSE_STEPS: usize = 24;

/// The stroke's fraction a bisection of [`SCALED_INVERSE_STEPS`] steps
/// resolves, 2⁻²⁴: the scaled inverse's stop where it is coarser than two
/// `f32` steps at `Rx_i` (for a stroke over four times `Rx_i`).
const SCALED_INVERSE_RESOLUTION: f32 = 1.0 / (1u32 << 24) as f32;

/// Inverse model of one branch with the ellipse offset scaled by
/// `offset_scale`: the contraction `x` in `[R_i, Rx_i]` where
/// `CM(x) ± offset_scale·y_hys(x) = pressure_mpa` (eqs. 25–26 with the
/// height `offset_scale·be`).
///
/// A scale of exactly 1 is [`LoadModel::contraction`]; otherwise a
/// safeguarded Newton iteration, started at that unscaled inverse, inside
/// the bisection's bracket (`branch(lo) <= p < branch(hi)`, from the whole
/// stroke): a step that would leave the bracket or does not halve the step
/// before it is a bisection step instead, so the answer is a crossing
/// inside that bracket (the bisection's own where the scaled branch crosses
/// the pressure once), and it stops once a Newton step is within two `f32`
/// steps at `Rx_i` (2⁻²² of it), or after [`SCALED_INVERSE_STEPS`] steps
/// (bounded work; a step that is a bisection at least halves the bracket).
/// Pressure
/// is clamped to `[0, Pmax]` (NaN → 0), and at `Pmax` the answer is `Rx_i`
/// (the loop closes there, as in the unscaled inverse); the scale is
/// clamped to `[0, MAX_OFFSET_SCALE]` (NaN → 0).
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

/// [`branch_contraction`]'s Newton iteration (out of line: the scale of 1,
/// the table inverse, is the common path of its callers).
#[inline(never)]
fn scaled_branch_contraction(
    model: &LoadModel,
    pressure_mpa: f32,
    branch: Branch,
    offset_scale: f32,
) -> f32 {
    let p = clamp(pressure_mpa, 0.0, model.max_pressure_mpa());
    if p >= model.max_pressure_mpa() {
        // The loop closes at Pmax, as the unscaled inverse's does (a scaled
        // contraction branch also reaches Pmax earlier, over its bulge).
        return model.max_contraction();
    }
    let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    let (mut lo, mut hi) = (model.root_contraction(), model.max_contraction());
    // 2⁻²⁴ of the stroke, or two `f32` steps of the contraction where
    // that is coarser (a Newton step at the answer is rounding).
    let resolution = ((hi - lo) * SCALED_INVERSE_RESOLUTION).max(2.0 * f32::EPSILON * hi);
    // The unscaled branch's answer from its tables: where a scale near 1
    // puts the crossing (while a load switch still builds them, the
    // stroke's middle: their fallback is itself a bisection).
    let mut x = if model.inverse_ready() {
        clamp(model.contraction(p, branch), lo, hi)
    } else {
        0.5 * (lo + hi)
    };
    let mut step_before = hi - lo;
    for _ in 0..SCALED_INVERSE_STEPS {
        let (g, slope) = model.branch_and_slope(x, k);
        let miss = g - p;
        if miss <= 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let newton = x - miss / slope;
        if (newton - x).abs() <= resolution && newton >= lo && newton <= hi {
            // Converged (from one side, the bracket's far end may still be
            // the stroke's end).
            x = newton;
            break;
        }
        // `!(a && b)` is also true for a NaN step (a zero or infinite
        // slope at the stroke's ends).
        let inside = newton > lo && newton < hi;
        let next = if !inside || (2.0 * miss).abs() > (step_before * slope).abs() {
            0.5 * (lo + hi)
        } else {
            newton
        };
        step_before = (next - x).abs();
        x = next;
        if step_before <= resolution {
            break;
        }
    }
    clamp(x, model.root_contraction(), model.max_contraction())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::load_model::INVERSE_TOLERANCE_MPA;
    use crate::{Coeffs, Params};

    /// The 24-step bisection on the forward model the Newton iteration
    /// replaced: the crossing it must find.
    fn bisection(m: &LoadModel, p: f32, br: Branch, scale: f32) -> f32 {
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
    }

    #[test]
    fn the_scaled_branch_inverse_finds_the_bisections_crossing() {
        // Every load, scale (0 to beyond the bound), branch and pressure
        // (below 0 to above Pmax): the contraction within 2e-6 of the
        // bisection's (its own resolution is 1.5e-8; f32 steps near the
        // ellipse's vertical tangents are ~1e-8 of pressure's 1e-7), and the
        // branch's pressure there within the table inverse's tolerance.
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let mut worst_p = 0.0f32;
        for load in [100.0, 333.0, 600.0] {
            let m = coeffs.load_model(load).unwrap();
            for scale in [0.0, 0.5, 0.97, 1.03, 1.3, 2.0, MAX_OFFSET_SCALE, 9.0] {
                for br in [Branch::Contraction, Branch::Expansion] {
                    let k = br.offset_sign() * clamp(scale, 0.0, MAX_OFFSET_SCALE);
                    for i in 0..=2_000 {
                        let p = -0.01 + 0.6 * i as f32 / 2_000.0;
                        let (a, b) = (
                            branch_contraction(&m, p, br, scale),
                            bisection(&m, p, br, scale),
                        );
                        let pc = clamp(p, 0.0, m.max_pressure_mpa());
                        let at = m.constraint_pressure_mpa(a) + k * m.offset_mpa(a);
                        let at_ref = m.constraint_pressure_mpa(b) + k * m.offset_mpa(b);
                        worst_p = worst_p.max((at - pc).abs() - (at_ref - pc).abs());
                        if p >= m.max_pressure_mpa() {
                            // The loop closes at Pmax, whatever the scale.
                            assert_eq!(a, m.max_contraction(), "{load} N, {scale}, {br:?}");
                            continue;
                        }
                        assert!(
                            (a - b).abs() <= 2e-6,
                            "{load} N, scale {scale}, {p} MPa, {br:?}: {a} vs {b}"
                        );
                    }
                }
            }
        }
        assert!(worst_p <= INVERSE_TOLERANCE_MPA, "pressure {worst_p}");
    }
}

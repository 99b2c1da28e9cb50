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

/// The scaled inverse's stop on the pressure, in `f32` steps of `Pmax`:
/// where the branch's pressure misses by no more than this, the miss is the
/// rounding of its evaluation (the cubic and the offset, each a few
/// roundings of a value up to `Pmax`), and a Newton step from there is
/// noise. Without it a miss stuck at one or two `f32` steps of the pressure
/// gives Newton steps just over the contraction's resolution, alternating
/// about the answer, until the 24th step. Used by
/// [`branch_contraction_near`].
pub const SCALED_INVERSE_ROUNDING: f32 = 4.0 * f32::EPSILON;

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
///
/// Work: 3–5 branch evaluations on most inputs, about 75 instructions each
/// on the M4F. Where the pressure's miss sticks at one or two `f32` steps
/// the Newton steps alternate just over the resolution and the iteration
/// runs to its cap (371 of the 720 180 inputs of
/// `the_rounding_stop_keeps_the_scaled_inverse_within_its_step_bound`,
/// mid-stroke too: about 1 800 instructions). The host's simulator stops
/// there ([`branch_contraction_near`], [`SCALED_INVERSE_ROUNDING`]); the
/// chip's path does not: on bench-m4's controller runs, which meet no such
/// input, the extra test per step cost up to 68 instructions in the worst
/// period (`effects` 3 542 → 3 610).
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

/// [`branch_contraction`] for a caller that inverts every sample of a
/// record (the [`Simulator`](crate::Simulator)): where the model has no
/// inverse tables (a load switch whose build is deferred or not done yet),
/// the safeguarded Newton iteration of the scaled inverse started at
/// `near` (the previous sample's answer; the stroke's middle when it is
/// not finite), at any scale, instead of the tables' fallback, a
/// bisection of [`FALLBACK_BISECTION_STEPS`](crate::load_model::FALLBACK_BISECTION_STEPS)
/// steps to 2⁻¹² of the stroke: on a record whose load moves every sample
/// (an isometric test's force) consecutive answers are close, so the
/// iteration takes a few steps where the bisection takes twelve, and it
/// resolves the crossing to the scaled inverse's resolution. With the
/// tables, [`branch_contraction`] itself.
pub fn branch_contraction_near(
    model: &LoadModel,
    pressure_mpa: f32,
    branch: Branch,
    offset_scale: f32,
    near: f32,
) -> f32 {
    if model.inverse_ready() {
        return branch_contraction(model, pressure_mpa, branch, offset_scale);
    }
    let p = clamp(pressure_mpa, 0.0, model.max_pressure_mpa());
    if p >= model.max_pressure_mpa() {
        return model.max_contraction();
    }
    let (lo, hi) = (model.root_contraction(), model.max_contraction());
    let start = if near.is_finite() {
        clamp(near, lo, hi)
    } else {
        0.5 * (lo + hi)
    };
    newton_inverse(model, p, branch, offset_scale, start, true).0
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
    let (lo, hi) = (model.root_contraction(), model.max_contraction());
    // The unscaled branch's answer from its tables: where a scale near 1
    // puts the crossing (while a load switch still builds them, the
    // stroke's middle: their fallback is itself a bisection).
    let start = if model.inverse_ready() {
        // The tables' interpolation without their Newton step: the
        // iteration's first step does that work on the scaled branch.
        clamp(model.contraction_interpolated(p, branch), lo, hi)
    } else {
        0.5 * (lo + hi)
    };
    newton_inverse(model, p, branch, offset_scale, start, false).0
}

/// The iteration of [`scaled_branch_contraction`] for `p` in `[0, Pmax)`
/// from `start` (within the stroke), and the branch evaluations it took.
/// `stop_at_rounding`: also stop where the pressure misses by no more than
/// its own rounding ([`SCALED_INVERSE_ROUNDING`]).
#[inline(always)]
fn newton_inverse(
    model: &LoadModel,
    p: f32,
    branch: Branch,
    offset_scale: f32,
    start: f32,
    stop_at_rounding: bool,
) -> (f32, usize) {
    let k = branch.offset_sign() * clamp(offset_scale, 0.0, MAX_OFFSET_SCALE);
    let (mut lo, mut hi) = (model.root_contraction(), model.max_contraction());
    let resolution = inverse_resolution(model);
    let mut x = start;
    let rounding = SCALED_INVERSE_ROUNDING * model.max_pressure_mpa();
    let mut step_before = hi - lo;
    let mut evaluations = 0;
    for _ in 0..SCALED_INVERSE_STEPS {
        let (g, slope) = model.branch_and_slope(x, k);
        evaluations += 1;
        let miss = g - p;
        if miss <= 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let newton = x - miss / slope;
        let converged =
            (newton - x).abs() <= resolution || (stop_at_rounding && miss.abs() <= rounding);
        if converged && newton >= lo && newton <= hi {
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
    (
        clamp(x, model.root_contraction(), model.max_contraction()),
        evaluations,
    )
}

/// The resolution at which [`branch_contraction`]'s iteration stops: 2⁻²⁴
/// of the stroke, or two `f32` steps of the contraction where that is
/// coarser (a Newton step at the answer is rounding).
#[inline(always)]
pub(crate) fn inverse_resolution(model: &LoadModel) -> f32 {
    let (lo, hi) = (model.root_contraction(), model.max_contraction());
    // (`f32::max` without its NaN handling, a library call on the M4F:
    // both are finite for a validated model.)
    let stroke_resolution = (hi - lo) * SCALED_INVERSE_RESOLUTION;
    let f32_resolution = 2.0 * f32::EPSILON * hi;
    if stroke_resolution >= f32_resolution {
        stroke_resolution
    } else {
        f32_resolution
    }
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

    #[test]
    fn the_inverse_near_the_last_answer_finds_the_bisections_crossing() {
        // Models without their tables (a deferred build, as an isometric
        // record's simulation has them): the iteration from the previous
        // answer along a pressure sweep, and from nothing, at scales 1 and
        // others, within 2e-6 of the 24-step bisection's crossing.
        let family = crate::load_model::FamilyF32::new(
            &crate::LoadFamily::from_params(&Params::DEFAULT).unwrap(),
        );
        for load in [100.0, 333.0, 600.0] {
            let m = family.model_without_tables(load);
            assert!(!m.inverse_ready());
            for scale in [0.5, 1.0, 1.3, 2.0] {
                for br in [Branch::Contraction, Branch::Expansion] {
                    let mut last = f32::NAN;
                    for i in 0..=1_000 {
                        let p = 0.6 * i as f32 / 1_000.0;
                        let warm = branch_contraction_near(&m, p, br, scale, last);
                        let cold = branch_contraction_near(&m, p, br, scale, f32::NAN);
                        last = warm;
                        if p >= m.max_pressure_mpa() {
                            assert_eq!(warm, m.max_contraction());
                            continue;
                        }
                        let b = bisection(&m, p, br, scale);
                        for (how, a) in [("warm", warm), ("cold", cold)] {
                            assert!(
                                (a - b).abs() <= 2e-6,
                                "{load} N, scale {scale}, {p} MPa, {br:?}, {how}: {a} vs {b}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// The scaled inverse from the chip's start (the table inverse) with
    /// the host's stop at the pressure's rounding
    /// ([`branch_contraction_near`]'s iteration).
    fn with_rounding_stop(m: &LoadModel, p: f32, br: Branch, scale: f32) -> (f32, usize) {
        let p = clamp(p, 0.0, m.max_pressure_mpa());
        if p >= m.max_pressure_mpa() {
            return (m.max_contraction(), 0);
        }
        let start = clamp(
            m.contraction(p, br),
            m.root_contraction(),
            m.max_contraction(),
        );
        newton_inverse(m, p, br, scale, start, true)
    }

    #[test]
    fn the_rounding_stop_keeps_the_scaled_inverse_within_its_step_bound() {
        // Every load of the default family and of a wide-loop one, scales
        // from 0 to the bound, both branches, 4 001 pressures: with the
        // stop at the pressure's rounding no input runs to the step cap
        // (without it, 371 do), and every one that takes more than 11
        // evaluations (about a hundred of 720 180) has its answer within 5 %
        // of the stroke of one of its ends, where the ellipse's vertical
        // tangent defeats Newton's steps.
        let mut wide = Params::DEFAULT;
        wide.ellipse_height_mpa *= 3.0;
        let (mut total, mut over_11, mut worst) = (0usize, 0usize, 0usize);
        for params in [Params::DEFAULT, wide] {
            let coeffs = Coeffs::new(params).unwrap();
            for load in [100.0, 200.0, 333.0, 450.0, 600.0] {
                let m = coeffs.load_model(load).unwrap();
                let (root, end) = (m.root_contraction(), m.max_contraction());
                for scale in [0.0, 0.3, 0.7, 0.9, 1.1, 1.3, 2.0, 3.0, MAX_OFFSET_SCALE] {
                    for br in [Branch::Contraction, Branch::Expansion] {
                        for i in 0..=4_000 {
                            let p = 0.6 * i as f32 / 4_000.0;
                            let (x, n) = with_rounding_stop(&m, p, br, scale);
                            total += 1;
                            worst = worst.max(n);
                            if n > 11 {
                                over_11 += 1;
                                let from_end = (x - root).min(end - x) / (end - root);
                                assert!(
                                    from_end <= 0.05,
                                    "{load} N, scale {scale}, {br:?}, {p} MPa: {n} evaluations \
                                     at {from_end} of the stroke from its ends"
                                );
                            }
                        }
                    }
                }
            }
        }
        assert!(worst < SCALED_INVERSE_STEPS, "worst {worst} evaluations");
        assert!(
            over_11 * 1_000 <= total,
            "{over_11} of {total} over 11 evaluations"
        );
    }
}

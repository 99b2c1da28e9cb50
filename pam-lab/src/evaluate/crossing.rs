//! Where a response that does not fall as its input rises crosses a target:
//! the search behind [`super::simulate::pressure_to_reach`] (the pressure
//! the model needs to reach a held length), started where the previous
//! sample's answer was.
//!
//! A bisection over the whole input range costs 26 evaluations a sample,
//! each a full simulator step; on a record sampled finely the answer moves
//! little from one sample to the next, so a bracket grown from the previous
//! answer and closed by false-position steps (the Illinois rule) takes a
//! handful. A bisection step whenever the bracket did not halve over the
//! last two steps bounds the work at about three times the bisection's.

/// Halvings a plain bisection would take over `0..=limit`: the answer is
/// within `limit·2⁻²⁶` (under 1e-8 MPa on 0.6 MPa), or between two
/// neighbouring `f32`s, whichever is wider.
pub const RESOLUTION_HALVINGS: i32 = 26;

/// The first bracket step from the guess, as a fraction of `limit`
/// (0.15 kPa on 0.6 MPa, about a sample's change on a 1 kHz ramp); each
/// further step is four times the last.
const FIRST_STEP_FRACTION: f32 = 1.0 / 4096.0;

/// Evaluations after which the search stops whatever the bracket: three
/// times what the safeguard can spend on top of a bisection's 26 steps, a
/// bound no well-behaved response reaches.
pub const MAX_EVALUATIONS: usize = 120;

/// The input in `0..=limit` where `response` reaches `target`, searched
/// from `guess`:
///
/// - `0` when `response(0) >= target` (the target is reached with
///   nothing);
/// - `limit` when `response(limit) < target` (never reached);
/// - otherwise the middle of a bracket `lo < hi` with
///   `response(lo) < target <= response(hi)`, narrowed to
///   `limit·2⁻²⁶` or to two neighbouring `f32`s.
///
/// `None` when `target` or `limit` is not finite, or `response` gives NaN.
/// `response` must not fall as its input rises; it is called at most
/// [`MAX_EVALUATIONS`] times (the bracket then is as far as it got: a
/// bound no well-behaved response reaches).
pub fn crossing(
    mut response: impl FnMut(f32) -> f32,
    target: f32,
    limit: f32,
    guess: f32,
) -> Option<f32> {
    if !target.is_finite() || !limit.is_finite() {
        return None;
    }
    let limit = limit.max(0.0);
    let evaluations = std::cell::Cell::new(0usize);
    let mut f = |p: f32| {
        evaluations.set(evaluations.get() + 1);
        response(p) - target
    };
    let g = if guess.is_finite() {
        guess.clamp(0.0, limit)
    } else {
        0.5 * limit
    };
    // Grow a bracket from the guess: f(lo) < 0 <= f(hi).
    let mut step = (FIRST_STEP_FRACTION * limit).max(f32::MIN_POSITIVE);
    let fg = f(g);
    let (mut lo, mut f_lo, mut hi, mut f_hi);
    if fg.is_nan() {
        return None;
    }
    if fg < 0.0 {
        if g >= limit {
            return Some(limit);
        }
        (lo, f_lo) = (g, fg);
        loop {
            let next = (lo + step).min(limit);
            let fn_ = f(next);
            if fn_.is_nan() {
                return None;
            }
            if fn_ >= 0.0 {
                (hi, f_hi) = (next, fn_);
                break;
            }
            if next >= limit {
                return Some(limit);
            }
            (lo, f_lo) = (next, fn_);
            step *= 4.0;
        }
    } else {
        if g <= 0.0 {
            return Some(0.0);
        }
        (hi, f_hi) = (g, fg);
        loop {
            let next = (hi - step).max(0.0);
            let fn_ = f(next);
            if fn_.is_nan() {
                return None;
            }
            if fn_ < 0.0 {
                (lo, f_lo) = (next, fn_);
                break;
            }
            if next <= 0.0 {
                return Some(0.0);
            }
            (hi, f_hi) = (next, fn_);
            step *= 4.0;
        }
    }
    // Close it: false position, the Illinois halving of a stale end's value,
    // a bisection when the bracket did not halve over two steps.
    let tolerance = limit * 2f32.powi(-RESOLUTION_HALVINGS);
    let mut stale_side = 0i8;
    let (mut width_two_steps_ago, mut width_one_step_ago) = (f32::INFINITY, f32::INFINITY);
    loop {
        let mid = 0.5 * (lo + hi);
        let width = hi - lo;
        if width <= tolerance || mid <= lo || mid >= hi || evaluations.get() >= MAX_EVALUATIONS {
            return Some(mid);
        }
        let secant = lo - f_lo * width / (f_hi - f_lo);
        let p = if width > 0.5 * width_two_steps_ago
            || !secant.is_finite()
            || secant <= lo
            || secant >= hi
        {
            mid
        } else {
            secant
        };
        let fp = f(p);
        if fp.is_nan() {
            return None;
        }
        if fp < 0.0 {
            (lo, f_lo) = (p, fp);
            if stale_side == 1 {
                f_hi *= 0.5;
            }
            stale_side = 1;
        } else {
            (hi, f_hi) = (p, fp);
            if stale_side == -1 {
                f_lo *= 0.5;
            }
            stale_side = -1;
        }
        width_two_steps_ago = width_one_step_ago;
        width_one_step_ago = width;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain bisection `pressure_to_reach` ran before: both ends first,
    /// then 26 halvings of `0..=limit`.
    fn bisection(response: impl Fn(f32) -> f32, target: f32, limit: f32) -> f32 {
        let (mut lo, mut hi) = (0.0f32, limit);
        if response(lo) >= target {
            return lo;
        }
        if response(hi) <= target {
            return hi;
        }
        for _ in 0..RESOLUTION_HALVINGS {
            let mid = 0.5 * (lo + hi);
            if response(mid) < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    fn counted(
        response: impl Fn(f32) -> f32,
    ) -> (impl FnMut(f32) -> f32, std::rc::Rc<std::cell::Cell<usize>>) {
        let n = std::rc::Rc::new(std::cell::Cell::new(0));
        let m = n.clone();
        (
            move |p| {
                m.set(m.get() + 1);
                response(p)
            },
            n,
        )
    }

    #[test]
    fn it_finds_the_bisections_crossing_from_any_guess() {
        // Smooth, kinked, stepped and flat-ended responses, targets inside
        // and outside, guesses near and far: the answer within the
        // bisection's own resolution of the bisection's answer.
        let limit = 0.6f32;
        type Response = fn(f32) -> f32;
        let responses: [(&str, Response); 5] = [
            ("cubic", |p| 0.3 * (p / 0.6).powi(3) + 0.1 * p),
            ("sqrt", |p| (p / 0.6).sqrt() * 0.25),
            ("kinked", |p| if p < 0.2 { 0.0 } else { (p - 0.2) * 0.5 }),
            ("stepped", |p| ((p * 1000.0).floor() / 1000.0) * 0.4),
            ("saturating", |p| (p * 3.0).min(0.9) / 3.0),
        ];
        for (name, r) in responses {
            for t in 0..=40 {
                let target = -0.01 + 0.31 * t as f32 / 40.0;
                let want = bisection(r, target, limit);
                for guess in [0.0, 0.0001, 0.2, want, want + 0.002, 0.59, limit, f32::NAN] {
                    let got = crossing(r, target, limit, guess).unwrap();
                    // Both bracket the same crossing; a stepped response's
                    // crossing is a step edge both resolve to 2^-26·limit.
                    assert!(
                        (got - want).abs()
                            <= 2.0 * limit * 2f32.powi(-RESOLUTION_HALVINGS)
                                + 2.0 * f32::EPSILON * want.abs(),
                        "{name}: target {target}, guess {guess}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_near_guess_takes_a_handful_of_evaluations_and_none_takes_more_than_the_bound() {
        let limit = 0.6f32;
        let r = |p: f32| 0.3 * (p / 0.6).powi(3) + 0.1 * p + 0.02 * (p / 0.6).sqrt();
        let want = bisection(r, 0.12, limit);
        let (f, n) = counted(r);
        crossing(f, 0.12, limit, want + 1e-4).unwrap();
        assert!(n.get() <= 10, "{} evaluations", n.get());
        // A pathological response (a step exactly at the crossing) still
        // ends within the bound.
        let step = |p: f32| if p < 0.3333 { 0.0 } else { 1.0 };
        let (f, n) = counted(step);
        let got = crossing(f, 0.5, limit, 0.0).unwrap();
        assert!((got - 0.3333).abs() < 1e-6, "{got}");
        assert!(n.get() <= MAX_EVALUATIONS, "{} evaluations", n.get());
    }

    #[test]
    fn ends_and_non_finite_inputs_are_answered_as_documented() {
        let r = |p: f32| p;
        assert_eq!(crossing(r, -1.0, 0.6, 0.3), Some(0.0));
        assert_eq!(crossing(r, 0.0, 0.6, 0.3), Some(0.0));
        assert_eq!(crossing(r, 2.0, 0.6, 0.3), Some(0.6));
        assert_eq!(crossing(r, f32::NAN, 0.6, 0.3), None);
        assert_eq!(crossing(r, 0.1, f32::INFINITY, 0.3), None);
        assert_eq!(crossing(r, 0.1, -1.0, 0.3), Some(0.0));
        // A response that gives NaN anywhere the search looks: no answer.
        assert_eq!(crossing(|_| f32::NAN, 0.1, 0.6, 0.3), None);
        assert_eq!(
            crossing(|p| if p > 0.2 { f32::NAN } else { p }, 0.3, 0.6, 0.1),
            None
        );
        // From a guess at an end, the end is not evaluated twice.
        let (f, n) = counted(|p: f32| p);
        assert_eq!(crossing(f, -1.0, 0.6, 0.0), Some(0.0));
        assert_eq!(n.get(), 1);
        let (f, n) = counted(|p: f32| p);
        assert_eq!(crossing(f, 2.0, 0.6, 0.6), Some(0.6));
        assert_eq!(n.get(), 1);
    }
}

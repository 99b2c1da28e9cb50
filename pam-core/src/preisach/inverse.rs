//! The Preisach model's inverse for a feedforward: the pressure at which
//! the model, driven there from its present state, first reaches a
//! contraction.

use super::relays::Preisach;
use crate::math::{clamp, next_down, next_up};

/// How close to a contraction the staircase counts as reaching it: the
/// rounding of the output's sum (a few `f32` steps of a contraction near
/// 0.1, well below any sensor's resolution). Without it a contraction at
/// the top of a step, summed in another order, can be missed by one
/// rounding and the step taken: an error of the whole step.
const REACHED: f32 = 1e-6;

impl<const N: usize> Preisach<N> {
    /// The pressure in `[0, max_pressure_mpa]` at which the model, moved
    /// there monotonically from its present state, first reaches
    /// `contraction`: rising when `contraction` is above the present output,
    /// falling when below. The state is not changed (apply
    /// [`Self::update_state`] with the result to move on, as the forward
    /// step does).
    ///
    /// Along the path the output is a staircase plus the linear term (see
    /// the [module docs](super)): the thresholds are walked from the present
    /// pressure and the answer is a threshold (where a step passes
    /// `contraction`) or one linear solve between two. With non-negative
    /// weights and a positive linear term the output rises with the
    /// pressure, and the answer's output is `contraction` or, where a step
    /// jumps past it, the least output above it. A contraction beyond what
    /// the path reaches gives the end of the range. Never NaN: a NaN
    /// contraction holds the present pressure (clamped to the range).
    ///
    /// Work: rising, at most `N` rows (four table reads each); falling, at
    /// most `N` columns (four reads each) and one pass over the rows for
    /// their runs; one division.
    pub fn inverse_pressure_mpa(&self, contraction: f32) -> f32 {
        let p_max = self.max_pressure_mpa;
        let p0 = clamp(self.last_mpa, 0.0, p_max);
        let x_now = self.output();
        if !contraction.is_finite() {
            return p0;
        }
        let lin = self.coeffs().linear;
        // The output on the path is `base + lin·p` between thresholds.
        let base = x_now - lin * self.last_mpa;
        if contraction >= x_now {
            self.rising(base, contraction, p0)
        } else {
            self.falling(base, contraction, p0)
        }
    }

    fn rising(&self, mut base: f32, x: f32, p0: f32) -> f32 {
        let c = self.coeffs();
        let lin = c.linear;
        let mut lo = p0;
        // Rows below `⌊u(p0)⌋` reached their `α_i`: fully on, no step.
        let first = self.grid_coordinate(p0) as usize;
        let rows = self
            .on
            .iter()
            .zip(self.alpha.iter())
            .enumerate()
            .skip(first);
        for (i, (&k, &alpha)) in rows {
            let k = usize::from(k);
            if k > i {
                // Fully on already: no step.
                continue;
            }
            if alpha > self.max_pressure_mpa {
                break;
            }
            let alpha = if alpha > lo { alpha } else { lo };
            if base + lin * alpha >= x - REACHED {
                // Below `α_i` (the row turns on at it): a solve rounded
                // onto the threshold is the `f32` step before it.
                let p = least_reaching(base, lin, x, lo, alpha);
                return if p < alpha {
                    p
                } else {
                    lo.max(next_down(alpha))
                };
            }
            base += c.row_prefix(i, i + 1) - c.row_prefix(i, k);
            if base + lin * alpha >= x - REACHED {
                return alpha;
            }
            lo = alpha;
        }
        least_reaching(base, lin, x, lo, self.max_pressure_mpa)
    }

    fn falling(&self, mut base: f32, x: f32, p0: f32) -> f32 {
        let c = self.coeffs();
        let lin = c.linear;
        let mut hi = p0;
        // The rows with relay `j` on are `j..end` (the counts on are
        // `c_i = min(i + 1, g_i)` with `g` non-increasing in `i`, an
        // invariant of `update_state`: a rise sets `g` to `N` on a prefix
        // of the rows, a fall caps it everywhere); going down the columns,
        // `end` only grows, so one pass over the rows finds every run.
        let mut end = 0;
        for (j, &beta) in self.beta.iter().enumerate().rev() {
            if !(beta < hi) {
                // Column `j` is off already at the present pressure.
                continue;
            }
            if base + lin * beta <= x + REACHED {
                // Above `β_j` (the column turns off at it), likewise.
                let p = greatest_reaching(base, lin, x, beta, hi);
                return if p > beta { p } else { hi.min(next_up(beta)) };
            }
            // At `β_j` relay `j` turns off in every row that has it on:
            // none unless row `j` has it.
            let has = |i: usize| self.on.get(i).is_some_and(|&k| usize::from(k) > j);
            if has(j) {
                end = end.max(j + 1);
                while has(end) {
                    end += 1;
                }
                base -= c.column_run(j, j, end);
            }
            if base + lin * beta <= x + REACHED {
                return beta;
            }
            hi = beta;
        }
        greatest_reaching(base, lin, x, 0.0, hi)
    }
}

/// The least `p` in `[lo, hi]` with `base + lin·p ≥ x` (`hi` when none).
fn least_reaching(base: f32, lin: f32, x: f32, lo: f32, hi: f32) -> f32 {
    if base + lin * lo >= x {
        return lo;
    }
    if lin > 0.0 {
        clamp((x - base) / lin, lo, hi)
    } else {
        hi
    }
}

/// The greatest `p` in `[lo, hi]` with `base + lin·p ≤ x` (`lo` when none).
fn greatest_reaching(base: f32, lin: f32, x: f32, lo: f32, hi: f32) -> f32 {
    if base + lin * hi <= x {
        return hi;
    }
    if lin > 0.0 {
        clamp((x - base) / lin, lo, hi)
    } else {
        lo
    }
}

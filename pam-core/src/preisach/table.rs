//! The Preisach model's coefficients: per load, the bias, the linear term
//! and the relay weights as their discrete Everett function; the grid of
//! loads, the relay thresholds and the pressure range, validated once.

use crate::error::Error;

/// Largest magnitude of the bias and of an Everett entry (contraction).
pub const MAX_CONTRACTION: f32 = 10.0;
/// Largest magnitude of the linear term (contraction per MPa).
pub const MAX_LINEAR_PER_MPA: f32 = 100.0;

/// Coefficients of a Preisach model at one load.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PreisachCoeffs<const N: usize> {
    /// Bias, contraction.
    pub bias: f32,
    /// Linear term, contraction per MPa.
    pub linear: f32,
    /// The discrete Everett function: `everett[i][k]` is the sum of the
    /// weights of the relays `(i', j)` with `i' ≤ i` and `j ≤ k` (`j ≤ i'`:
    /// the half-grid). A row's prefix and a column's run of rows are each
    /// a difference of two or four entries ([`Self::row_prefix`],
    /// [`Self::column_run`]).
    pub everett: [[f32; N]; N],
}

impl<const N: usize> PreisachCoeffs<N> {
    /// All zero: contraction 0 at every pressure.
    pub const ZERO: PreisachCoeffs<N> = PreisachCoeffs {
        bias: 0.0,
        linear: 0.0,
        everett: [[0.0; N]; N],
    };

    /// From relay weights `w[i][j]` (`j ≤ i`; the rest ignored).
    pub fn from_weights(bias: f32, linear: f32, w: &[[f32; N]; N]) -> Self {
        let mut everett = [[0.0f32; N]; N];
        let mut above = [0.0f32; N];
        for (i, (row, wrow)) in everett.iter_mut().zip(w.iter()).enumerate() {
            let mut acc = 0.0;
            for (k, ((e, &wk), a)) in row
                .iter_mut()
                .zip(wrow.iter())
                .zip(above.iter_mut())
                .enumerate()
            {
                if k <= i {
                    acc += wk;
                }
                *a += acc;
                *e = *a;
            }
        }
        PreisachCoeffs {
            bias,
            linear,
            everett,
        }
    }

    /// `everett[i][k]`, 0 for a row or column before the first.
    #[inline(always)]
    fn at(&self, i: usize, k: usize) -> f32 {
        self.everett
            .get(i)
            .and_then(|r| r.get(k))
            .copied()
            .unwrap_or(0.0)
    }

    /// Row `i`'s weights of relays `j < count` (the contribution of a row
    /// with `count` relays on): two entries.
    #[inline(always)]
    pub fn row_prefix(&self, i: usize, count: usize) -> f32 {
        let k = count.wrapping_sub(1);
        self.at(i, k) - self.at(i.wrapping_sub(1), k)
    }

    /// Column `j`'s weights over rows `from..to`: four entries.
    #[inline(always)]
    pub fn column_run(&self, j: usize, from: usize, to: usize) -> f32 {
        let (last, before) = (to.wrapping_sub(1), from.wrapping_sub(1));
        let jb = j.wrapping_sub(1);
        (self.at(last, j) - self.at(last, jb)) - (self.at(before, j) - self.at(before, jb))
    }

    /// Every relay's weight summed: the last entry of the Everett function.
    pub fn total_weight(&self) -> f32 {
        self.at(N.wrapping_sub(1), N.wrapping_sub(1))
    }

    /// Relay `(i, j)`'s weight (0 outside the half-grid).
    pub fn weight(&self, i: usize, j: usize) -> f32 {
        if j > i {
            return 0.0;
        }
        self.column_run(j, i, i + 1)
    }
}

/// A Preisach model identified at a grid of `L` loads.
///
/// Relay thresholds: `β_j = lo + j·Δ` and `α_i = lo + (i + 1)·Δ`,
/// `Δ = step_mpa`; relay `(i, j)`, `j ≤ i`, switches on at `p ≥ α_i` and off
/// at `p ≤ β_j`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PreisachTable<const N: usize, const L: usize> {
    /// `lo`, MPa.
    pub lo_mpa: f32,
    /// `Δ`, MPa.
    pub step_mpa: f32,
    /// Highest pressure the model is calibrated to (the inverse's limit), MPa.
    pub max_pressure_mpa: f32,
    /// First grid load, N.
    pub min_load_n: f32,
    /// Grid step, N.
    pub load_step_n: f32,
    /// Coefficients at each grid load.
    pub grid: [PreisachCoeffs<N>; L],
}

impl<const N: usize, const L: usize> PreisachTable<N, L> {
    /// Finite everywhere, the coefficients within [`MAX_CONTRACTION`] and
    /// [`MAX_LINEAR_PER_MPA`]; `Δ > 0`, `lo ≥ 0` and the top threshold
    /// `lo + N·Δ` at most `max_pressure_mpa`; a positive load step; at
    /// least one relay row and one load.
    pub fn validate(&self) -> Result<(), Error> {
        if N == 0 || L == 0 {
            return Err(Error::OutOfRange(
                "preisach",
                "needs at least one relay row and one load",
            ));
        }
        let scalars = [
            ("preisach.lo_mpa", self.lo_mpa),
            ("preisach.step_mpa", self.step_mpa),
            ("preisach.max_pressure_mpa", self.max_pressure_mpa),
            ("preisach.min_load_n", self.min_load_n),
            ("preisach.load_step_n", self.load_step_n),
        ];
        for (name, v) in scalars {
            if !v.is_finite() {
                return Err(Error::NonFinite(name));
            }
        }
        let finite_coeffs = self.grid.iter().all(|c| {
            c.bias.is_finite()
                && c.linear.is_finite()
                && c.everett.iter().flatten().all(|e| e.is_finite())
        });
        if !finite_coeffs {
            return Err(Error::NonFinite("preisach.grid"));
        }
        // A contraction model's magnitudes (a fraction of rest length; per
        // MPa for the linear term): far beyond any muscle, and bounded so
        // that every sum the model forms is finite.
        let bounded = self.grid.iter().all(|c| {
            c.bias.abs() <= MAX_CONTRACTION
                && c.linear.abs() <= MAX_LINEAR_PER_MPA
                && c.everett
                    .iter()
                    .flatten()
                    .all(|e| e.abs() <= MAX_CONTRACTION)
        });
        if !bounded {
            return Err(Error::OutOfRange(
                "preisach.grid",
                "bias and Everett entries must be within ±10, the linear term within ±100 per MPa",
            ));
        }
        if !(self.step_mpa > 0.0) {
            return Err(Error::OutOfRange("preisach.step_mpa", "must be > 0"));
        }
        if !(self.lo_mpa >= 0.0) {
            return Err(Error::OutOfRange("preisach.lo_mpa", "must be >= 0"));
        }
        let top = self.lo_mpa + N as f32 * self.step_mpa;
        if !(top <= self.max_pressure_mpa * (1.0 + 1e-6)) {
            return Err(Error::OutOfRange(
                "preisach.max_pressure_mpa",
                "must be at least the top threshold lo + N*step",
            ));
        }
        if !(self.load_step_n > 0.0) {
            return Err(Error::OutOfRange("preisach.load_step_n", "must be > 0"));
        }
        Ok(())
    }

    /// Coefficients at `load_n`, interpolated linearly between grid loads
    /// (clamped to the grid; NaN → the first load).
    pub fn at_load(&self, load_n: f32) -> PreisachCoeffs<N> {
        let mut out = PreisachCoeffs::ZERO;
        self.blend_rows_into(load_n, 0..N, &mut out);
        out
    }
}

impl<const N: usize, const L: usize> PreisachTable<N, L> {
    /// [`Self::at_load`] for the Everett rows `rows` only, into `out` (and
    /// the bias and linear term with row 0): a load switch spread over
    /// several calls, or (all rows) the whole blend. `out` is left as it
    /// is for a table without loads.
    pub(super) fn blend_rows_into(
        &self,
        load_n: f32,
        rows: core::ops::Range<usize>,
        out: &mut PreisachCoeffs<N>,
    ) {
        let (k, t) = grid_position(load_n, self.min_load_n, self.load_step_n, L);
        let (Some(a), Some(b)) = (self.grid.get(k), self.grid.get(k + 1).or(self.grid.get(k)))
        else {
            return;
        };
        if rows.start == 0 {
            out.bias = lerp(a.bias, b.bias, t);
            out.linear = lerp(a.linear, b.linear, t);
        }
        let (skip, take) = (rows.start, rows.len());
        let pairs = a.everett.iter().zip(b.everett.iter()).skip(skip).take(take);
        for ((ra, rb), ro) in pairs.zip(out.everett.iter_mut().skip(skip)) {
            for ((&ea, &eb), eo) in ra.iter().zip(rb.iter()).zip(ro.iter_mut()) {
                *eo = lerp(ea, eb, t);
            }
        }
    }
}

/// Position of `load_n` on a grid of `l` loads from `min_load_n` in steps
/// of `load_step_n`: the lower grid index and the fraction towards the next
/// one; clamped to the grid, NaN → the first load. (The Preisach table's,
/// and bench-m4's baselines' grids.)
pub fn grid_position(load_n: f32, min_load_n: f32, load_step_n: f32, l: usize) -> (usize, f32) {
    let last = l.saturating_sub(1) as f32;
    let t = (load_n - min_load_n) / load_step_n;
    let t = if t >= 0.0 {
        if t <= last {
            t
        } else {
            last
        }
    } else {
        0.0
    };
    // `t` is in [0, last]: the cast is a floor and cannot wrap.
    let k = t as usize;
    let k = if k + 1 >= l { l.saturating_sub(2) } else { k };
    (k, t - k as f32)
}

fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

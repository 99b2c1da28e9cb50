//! The Preisach model: a second model family beside the paper's, for a
//! muscle whose loops a load family of about ten parameters does not
//! follow closely enough, at a table's cost.
//!
//! An `N × N` half-grid of relays `(α_i, β_j)`, `α_i > β_j` (`N(N+1)/2`
//! relays, 136 for `N = 16`), plus a bias and a linear term, predicts
//! contraction from pressure:
//! `x = b + w_lin·p + Σ w_ij·relay_ij(p)`. Relay `(i, j)` switches on when
//! the pressure reaches `α_i = lo + (i + 1)·Δ` and off when it falls to
//! `β_j = lo + j·Δ` ([`PreisachTable`]).
//!
//! # Load
//! The weights are given at a grid of `L` loads. The model holds the
//! coefficients of its *active load*; when the measured load differs from
//! it by more than [`LOAD_THRESHOLD_N`] (the paper model's tracker
//! threshold), the coefficients of the measured load are interpolated
//! linearly between its two neighbouring grid loads, a few rows per update
//! ([`LOAD_SWITCH_ROWS_PER_UPDATE`]: bounded work, as the paper model's
//! tracker builds a new load's tables), and used once complete. The relay
//! states depend only on the pressure history and carry over a load
//! change.
//!
//! # State
//! In one row `i` of the half-grid (fixed switch-up threshold `α_i`) the
//! relays that are on always form a prefix `j < c_i` in `β_j` (a relay with
//! a higher switch-down threshold was switched off at least as recently).
//! So the relay states are one byte per row, `c_i`, and the weighted sum is
//! `Σ_i E_i[c_i − 1]`, `E_i` row `i`'s prefix sums, each the difference of
//! two entries of the discrete Everett function (the weights summed over
//! rows `≤ i` and columns `≤ k`, [`PreisachCoeffs::everett`]): `2N` table
//! look-ups ([`Preisach::output`]). Rows turn fully on at their `α_i`, and
//! every row's relays from column `j` on turn off at `β_j`, so the rows
//! that have relay `j` on are always `j, j + 1, …` without a gap.
//!
//! # Inverse
//! Along a monotone pressure path from the present state the output is a
//! staircase plus the linear term: rising, row `i` turns fully on at `α_i`;
//! falling, column `j`'s run of rows turns off at `β_j` (four entries of
//! the Everett function). So the pressure at which the model first reaches
//! a contraction is found by walking the thresholds from the present
//! pressure, one linear solve at the end
//! ([`Preisach::inverse_pressure_mpa`]): a feedforward's inverse, exact,
//! in at most `N` steps either way.
//!
//! # Blob
//! [`blob`]: the table framed and checked as the paper model's blob is,
//! with its own magic (`PAMP`); `pam-lab compare` writes it. The firmware
//! boots it (`firmware::boot`, `Feedforward::Preisach`).
//!
//! No allocation and no panic paths (indexing through iterators and `get`).

pub mod blob;
mod inverse;
mod relays;
mod table;

pub use relays::Preisach;
pub use table::{
    grid_position, PreisachCoeffs, PreisachTable, MAX_CONTRACTION, MAX_LINEAR_PER_MPA,
};

/// A measured load this far from the active load (N) switches the active
/// load and re-interpolates the coefficients: the paper model's tracker
/// threshold ([`TrackerConfig::DEFAULT_PRESSURE`](crate::TrackerConfig::DEFAULT_PRESSURE)).
pub const LOAD_THRESHOLD_N: f32 = crate::TrackerConfig::DEFAULT_PRESSURE.load_threshold_n;

/// Rows of the Everett function a load switch interpolates per update
/// ([`Preisach::update_load`]): a switch of the 16-row model takes eight
/// updates at a few hundred instructions each, where all at once it took
/// 4 346 (bench-m4), over a control period's budget.
pub const LOAD_SWITCH_ROWS_PER_UPDATE: usize = 2;

#[cfg(test)]
mod tests;

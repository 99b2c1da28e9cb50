//! [`Preisach`]: the running model, its relay states one byte per row, and
//! the forward step (pressure and load in, contraction out).

use super::table::{PreisachCoeffs, PreisachTable};
use super::{LOAD_SWITCH_ROWS_PER_UPDATE, LOAD_THRESHOLD_N};
use crate::math::{clamp, next_down, next_up};

/// A running Preisach model: the active load's coefficients and the relay
/// states (one byte per row: how many relays of the row are on, see the
/// [module docs](super)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preisach<const N: usize> {
    pub(super) lo_mpa: f32,
    pub(super) step_mpa: f32,
    pub(super) inv_step: f32,
    pub(super) max_pressure_mpa: f32,
    /// The active load's coefficients and the next load's while a load
    /// switch makes them, a few rows an update ([`Self::update_load`]);
    /// which is which, `flip` says (no 1 KB copy when a switch completes).
    bufs: (PreisachCoeffs<N>, PreisachCoeffs<N>),
    /// `bufs.1` is the active one.
    flip: bool,
    /// The least pressure at which row `i` switches fully on in
    /// [`Self::update_state`]'s arithmetic (`α_i`, moved up by the `f32`
    /// steps its rounding needs): the inverse's thresholds.
    pub(super) alpha: [f32; N],
    /// The greatest pressure at which relay column `j` switches off
    /// (`β_j`, moved down likewise).
    pub(super) beta: [f32; N],
    load_n: f32,
    pub(super) last_mpa: f32,
    pub(super) on: [u8; N],
    /// The load `next` is made for and the Everett rows made so far; `None`
    /// without a switch under way.
    switching: Option<(f32, usize)>,
    /// Everett rows made per update ([`LOAD_SWITCH_ROWS_PER_UPDATE`], or
    /// every row: [`Self::switch_loads_at_once`]).
    rows_per_update: usize,
}

impl<const N: usize> Preisach<N> {
    /// A model at `load_n` with every relay off (the muscle empty), then
    /// driven to `pressure_mpa`. The table is the caller's validated one
    /// ([`PreisachTable::validate`]).
    pub fn new<const L: usize>(
        table: &PreisachTable<N, L>,
        load_n: f32,
        pressure_mpa: f32,
    ) -> Self {
        let mut m = Preisach {
            lo_mpa: table.lo_mpa,
            step_mpa: table.step_mpa,
            inv_step: 1.0 / table.step_mpa,
            max_pressure_mpa: table.max_pressure_mpa,
            bufs: (table.at_load(load_n), PreisachCoeffs::ZERO),
            flip: false,
            alpha: [0.0; N],
            beta: [0.0; N],
            load_n,
            last_mpa: 0.0,
            on: [0; N],
            switching: None,
            rows_per_update: LOAD_SWITCH_ROWS_PER_UPDATE,
        };
        m.alpha = core::array::from_fn(|i| m.threshold_up(i));
        m.beta = core::array::from_fn(|j| m.threshold_down(j));
        m.update_state(pressure_mpa);
        m
    }

    fn threshold_up(&self, i: usize) -> f32 {
        let target = (i + 1) as f32;
        let mut a = self.lo_mpa + target * self.step_mpa;
        for _ in 0..4 {
            if self.grid_coordinate(a) >= target {
                break;
            }
            a = next_up(a);
        }
        a
    }

    fn threshold_down(&self, j: usize) -> f32 {
        let target = j as f32;
        let mut b = self.lo_mpa + target * self.step_mpa;
        for _ in 0..4 {
            if self.grid_coordinate(b) <= target {
                break;
            }
            b = next_down(b);
        }
        b
    }

    /// The active load's coefficients.
    #[inline(always)]
    pub fn coeffs(&self) -> &PreisachCoeffs<N> {
        if self.flip {
            &self.bufs.1
        } else {
            &self.bufs.0
        }
    }

    /// The active load, N.
    pub fn load_n(&self) -> f32 {
        self.load_n
    }

    /// Relays on per row (`0..=i + 1` in row `i`).
    pub fn rows_on(&self) -> &[u8; N] {
        &self.on
    }

    /// The last finite pressure, MPa.
    pub fn last_mpa(&self) -> f32 {
        self.last_mpa
    }

    /// Highest pressure the model is calibrated to, MPa.
    pub fn max_pressure_mpa(&self) -> f32 {
        self.max_pressure_mpa
    }

    /// Whether relay `(i, j)` (`j ≤ i`) is on.
    pub fn relay(&self, i: usize, j: usize) -> bool {
        j <= i && self.on.get(i).is_some_and(|&c| j < usize::from(c))
    }

    /// Make a load switch at once in the next [`Self::update_load`] (an
    /// offline evaluation of a record, where a switch's cost does not
    /// matter and the coefficients should follow the load sample by
    /// sample), instead of [`LOAD_SWITCH_ROWS_PER_UPDATE`] rows an update.
    pub fn switch_loads_at_once(mut self) -> Self {
        self.rows_per_update = N.max(1);
        self
    }

    /// Whether a load switch is under way (the coefficients in use are
    /// still the previous load's).
    pub fn switching(&self) -> bool {
        self.switching.is_some()
    }

    /// Follow the measured load: when `load_n` is more than
    /// [`LOAD_THRESHOLD_N`] from the active load (or from the load a switch
    /// under way is for), a switch to it starts; every call makes
    /// [`LOAD_SWITCH_ROWS_PER_UPDATE`] rows of the new load's coefficients
    /// (interpolated between its grid loads), and once all are made they
    /// are used (a switch takes `N / LOAD_SWITCH_ROWS_PER_UPDATE` updates;
    /// until then the previous load's are, whole). Non-finite loads are
    /// ignored.
    #[inline(always)]
    pub fn update_load<const L: usize>(&mut self, table: &PreisachTable<N, L>, load_n: f32) {
        let towards = match self.switching {
            Some((l, _)) => l,
            None => self.load_n,
        };
        if (load_n - towards).abs() > LOAD_THRESHOLD_N {
            self.switching = Some((load_n, 0));
        }
        if self.switching.is_some() {
            self.advance_switch(table);
        }
    }

    /// The rare path of [`Self::update_load`]: the next rows of a switch.
    #[inline(never)]
    fn advance_switch<const L: usize>(&mut self, table: &PreisachTable<N, L>) {
        let Some((load_n, made)) = self.switching else {
            return;
        };
        let end = (made + self.rows_per_update).min(N);
        let next = if self.flip {
            &mut self.bufs.0
        } else {
            &mut self.bufs.1
        };
        table.blend_rows_into(load_n, made..end, next);
        if end >= N {
            self.flip = !self.flip;
            self.load_n = load_n;
            self.switching = None;
        } else {
            self.switching = Some((load_n, end));
        }
    }

    /// `(p − lo)/Δ` clamped to `[0, N]`: rows `i` with `i + 1 ≤ u` have
    /// reached `α_i`, relays `j ≥ u` are at or below `β_j`. The one
    /// arithmetic both the step and the inverse judge a threshold by.
    #[inline(always)]
    pub(super) fn grid_coordinate(&self, pressure_mpa: f32) -> f32 {
        clamp((pressure_mpa - self.lo_mpa) * self.inv_step, 0.0, N as f32)
    }

    /// Switch the relays for `pressure_mpa` (a non-finite pressure holds them).
    #[inline(always)]
    pub fn update_state(&mut self, pressure_mpa: f32) {
        if !pressure_mpa.is_finite() {
            return;
        }
        self.last_mpa = pressure_mpa;
        let u = self.grid_coordinate(pressure_mpa);
        // `u` is in [0, N]: the casts are floors and cannot wrap.
        let up = u as usize; // rows i < up switch fully on
        let down = {
            let f = u as usize;
            if (f as f32) < u {
                f + 1
            } else {
                f
            }
        }; // relays j ≥ down switch off
        let down = if down > N { N } else { down } as u8;
        for (i, c) in self.on.iter_mut().enumerate() {
            let mut v = *c;
            if i < up {
                v = (i + 1) as u8;
            }
            if v > down {
                v = down;
            }
            *c = v;
        }
    }

    /// The model's stroke at the active load: its contraction with every
    /// relay off at 0 MPa (the bias) and with every relay on at
    /// `max_pressure_mpa` (the bias, the linear term there and every
    /// weight). A set-point outside it is beyond what the model says the
    /// muscle reaches along the major loop (with weights of both signs a
    /// minor loop can reach a little beyond; the inverse answers the end of
    /// the range there).
    pub fn stroke(&self) -> (f32, f32) {
        let c = self.coeffs();
        (
            c.bias,
            c.bias + c.linear * self.max_pressure_mpa + c.total_weight(),
        )
    }

    /// The predicted contraction for the current state.
    #[inline(always)]
    pub fn output(&self) -> f32 {
        let c = self.coeffs();
        let mut x = c.bias + c.linear * self.last_mpa;
        // Row `i`'s prefix is `everett[i][k] − everett[i − 1][k]` (a zero
        // row before the first), [`PreisachCoeffs::row_prefix`] unrolled.
        let mut before: &[f32; N] = &[0.0; N];
        for (row, &k) in c.everett.iter().zip(self.on.iter()) {
            let k = usize::from(k).wrapping_sub(1);
            if let (Some(a), Some(b)) = (row.get(k), before.get(k)) {
                x += a - b;
            }
            before = row;
        }
        x
    }

    /// One sample: load, state, output (contraction).
    #[inline]
    pub fn step<const L: usize>(
        &mut self,
        table: &PreisachTable<N, L>,
        pressure_mpa: f32,
        load_n: f32,
    ) -> f32 {
        self.update_load(table, load_n);
        self.update_state(pressure_mpa);
        self.output()
    }
}

//! Identification of the baselines by linear least squares per grid load, and
//! a grid load without training samples filled from its neighbours.

use super::*;
use pam_lab::identify::lsq::linear::NormalEquations;

pub(crate) fn grid_index(load_n: f32) -> usize {
    let k = ((load_n - MIN_LOAD_N) / LOAD_STEP_N).round();
    k.clamp(0.0, (L - 1) as f32) as usize
}

/// Normal equations per grid load (pam-lab's, with its ridge solve).
pub(crate) struct Normal(Vec<NormalEquations>);

impl Normal {
    fn new(m: usize) -> Normal {
        Normal(vec![NormalEquations::new(m); L])
    }

    fn add(&mut self, g: usize, row: &[f64], y: f64) {
        self.0[g].add(row, y);
    }

    /// Least squares with a ridge `RIDGE·mean(diag)` on every column but the bias.
    fn solve(&self, g: usize) -> Vec<f64> {
        match self.0[g].solve(RIDGE) {
            Ok(x) => x,
            Err(e) => panic!("grid load {g}: {e}"),
        }
    }
}

pub(crate) fn pi_thresholds() -> [f32; N] {
    core::array::from_fn(|i| (i + 1) as f32 * PI_MAX_THRESHOLD_MPA / N as f32)
}

pub(crate) fn identify_pi(samples: &[Sample], heldout: &[bool]) -> PiTable<N, L> {
    let thresholds_mpa = pi_thresholds();
    // Identity coefficients: only the state sequence matters while fitting.
    let zero = PiCoeffs {
        bias: 0.0,
        linear: 0.0,
        weights: [0.0; N],
    };
    let mut table = PiTable {
        thresholds_mpa,
        min_load_n: MIN_LOAD_N,
        load_step_n: LOAD_STEP_N,
        grid: [zero; L],
    };
    let first = &samples[0];
    let mut m = PrandtlIshlinskii::new(&table, first.load_n as f32, first.pressure_mpa as f32);
    let mut ne = Normal::new(N + 2);
    let mut row = vec![0.0; N + 2];
    for (s, &h) in samples.iter().zip(heldout) {
        m.update_load(&table, s.load_n as f32);
        m.update_state(s.pressure_mpa as f32);
        if h {
            continue;
        }
        row[0] = 1.0;
        row[1] = f64::from(m.last_mpa());
        for (r, &z) in row[2..].iter_mut().zip(m.plays()) {
            *r = f64::from(z);
        }
        ne.add(grid_index(m.load_n()), &row, s.contraction);
    }
    for g in 0..L {
        let x = ne.solve(g);
        table.grid[g] = PiCoeffs {
            bias: x[0] as f32,
            linear: x[1] as f32,
            weights: core::array::from_fn(|i| x[i + 2] as f32),
        };
    }
    table
}

pub(crate) fn identify_gpi(
    samples: &[Sample],
    heldout: &[bool],
    max_threshold_mpa: f32,
) -> GpiTable<GPI_N, L> {
    let thresholds_mpa: [f32; GPI_N] =
        core::array::from_fn(|i| (i + 1) as f32 * max_threshold_mpa / GPI_N as f32);
    let zero = GpiCoeffs {
        bias: 0.0,
        cubic: [0.0; 3],
        weights: [0.0; GPI_N],
    };
    let mut table = GpiTable {
        thresholds_mpa,
        min_load_n: MIN_LOAD_N,
        load_step_n: LOAD_STEP_N,
        grid: [zero; L],
    };
    let first = &samples[0];
    let mut m = GeneralizedPi::new(&table, first.load_n as f32, first.pressure_mpa as f32);
    let mut ne = Normal::new(GPI_N + 4);
    let mut row = vec![0.0; GPI_N + 4];
    for (s, &h) in samples.iter().zip(heldout) {
        m.update_load(&table, s.load_n as f32);
        m.update_state(s.pressure_mpa as f32);
        if h {
            continue;
        }
        let p = f64::from(m.last_mpa());
        row[0] = 1.0;
        row[1] = p;
        row[2] = p * p;
        row[3] = p * p * p;
        for (r, &z) in row[4..].iter_mut().zip(m.plays()) {
            *r = f64::from(z);
        }
        ne.add(grid_index(m.load_n()), &row, s.contraction);
    }
    for g in 0..L {
        let x = ne.solve(g);
        table.grid[g] = GpiCoeffs {
            bias: x[0] as f32,
            cubic: [x[1] as f32, x[2] as f32, x[3] as f32],
            weights: core::array::from_fn(|i| x[i + 4] as f32),
        };
    }
    table
}

/// Preisach-16 by pam-lab's identification (the one a user's record gets
/// from `pam-lab compare`) on the bench's grid; grid loads without training
/// samples are filled there.
pub(crate) fn identify_preisach(samples: &[Sample], heldout: &[bool]) -> PreisachTable<N, L> {
    let grid = pam_lab::identify::preisach::Grid {
        lo_mpa: PREISACH_LO_MPA,
        step_mpa: PREISACH_STEP_MPA,
        max_pressure_mpa: PREISACH_MAX_MPA,
        min_load_n: MIN_LOAD_N,
        load_step_n: LOAD_STEP_N,
    };
    match pam_lab::identify::preisach::identify(samples, heldout, &grid) {
        Ok(t) => t,
        Err(e) => panic!("Preisach-16 not identified: {e}"),
    }
}

/// Grid loads with training samples (by the grid the tables use).
pub(crate) fn trained_grid(samples: &[Sample], heldout: &[bool]) -> [bool; L] {
    let mut trained = [false; L];
    for (s, &h) in samples.iter().zip(heldout) {
        if !h {
            trained[grid_index(s.load_n as f32)] = true;
        }
    }
    trained
}

pub(crate) use pam_lab::identify::preisach::fill_untrained;

pub(crate) fn lerp_arr<const K: usize>(a: &[f32; K], b: &[f32; K], t: f32) -> [f32; K] {
    core::array::from_fn(|i| a[i] + t * (b[i] - a[i]))
}

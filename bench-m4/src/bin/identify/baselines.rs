//! Identification of the baselines by linear least squares per grid load, and
//! a grid load without training samples filled from its neighbours.

use super::*;

pub(crate) fn grid_index(load_n: f32) -> usize {
    let k = ((load_n - MIN_LOAD_N) / LOAD_STEP_N).round();
    k.clamp(0.0, (L - 1) as f32) as usize
}

/// Normal equations per grid load.
pub(crate) struct Normal {
    ata: Vec<DMatrix<f64>>,
    aty: Vec<DVector<f64>>,
    rows: Vec<usize>,
}

impl Normal {
    fn new(m: usize) -> Normal {
        Normal {
            ata: vec![DMatrix::zeros(m, m); L],
            aty: vec![DVector::zeros(m); L],
            rows: vec![0; L],
        }
    }

    fn add(&mut self, g: usize, row: &[f64], y: f64) {
        let ata = &mut self.ata[g];
        let m = row.len();
        for i in 0..m {
            let ri = row[i];
            if ri == 0.0 {
                continue;
            }
            for j in i..m {
                ata[(i, j)] += ri * row[j];
            }
            self.aty[g][i] += ri * y;
        }
        self.rows[g] += 1;
    }

    /// Least squares with a ridge `RIDGE·mean(diag)` on every column but the bias.
    fn solve(&self, g: usize) -> Vec<f64> {
        let mut a = self.ata[g].clone();
        let m = a.nrows();
        for i in 0..m {
            for j in 0..i {
                a[(i, j)] = a[(j, i)];
            }
        }
        let mean_diag = (0..m).map(|i| a[(i, i)]).sum::<f64>() / m as f64;
        for i in 1..m {
            a[(i, i)] += RIDGE * mean_diag;
        }
        let b = self.aty[g].clone();
        let x = match a.clone().cholesky() {
            Some(c) => c.solve(&b),
            None => a
                .svd(true, true)
                .solve(&b, 1e-12)
                .expect("SVD least squares"),
        };
        x.iter().copied().collect()
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

/// Every grid load without training samples takes the coefficients
/// interpolated linearly from the nearest trained grid loads on each side
/// (the nearest one's where only one side has one): what the table's own
/// `at_load` does between its grid loads, over the wider gap. The models
/// are linear in their coefficients, so this is their prediction
/// interpolated across load.
pub(crate) fn fill_untrained<T: Copy>(
    grid: &mut [T; L],
    trained: &[bool; L],
    mix: impl Fn(&T, &T, f32) -> T,
) {
    for g in 0..L {
        if trained[g] {
            continue;
        }
        let below = (0..g).rev().find(|&k| trained[k]);
        let above = (g + 1..L).find(|&k| trained[k]);
        grid[g] = match (below, above) {
            (Some(a), Some(b)) => mix(&grid[a], &grid[b], (g - a) as f32 / (b - a) as f32),
            (Some(a), None) => grid[a],
            (None, Some(b)) => grid[b],
            (None, None) => grid[g],
        };
    }
}

pub(crate) fn lerp_arr<const K: usize>(a: &[f32; K], b: &[f32; K], t: f32) -> [f32; K] {
    core::array::from_fn(|i| a[i] + t * (b[i] - a[i]))
}

//! The Preisach model (pam-core's [`pam_core::preisach`]) identified on a
//! record: at each grid load, the relay weights, the bias and the linear
//! term by linear least squares on the training samples (the relay states
//! depend on the pressure history only, so the model is linear in its
//! weights); a grid load without training samples takes its neighbours'
//! coefficients, interpolated. The one identification of the family:
//! `pam-lab compare` runs it on a user's record and bench-m4 on its rig.

use pam_core::preisach::{Preisach, PreisachCoeffs, PreisachTable};

use super::lsq::linear::NormalEquations;
use crate::record::Sample;

/// Relay rows of the half-grid (`ROWS·(ROWS + 1)/2` = 136 relays).
pub const ROWS: usize = 16;
/// Grid loads the weights are given at.
pub const LOADS: usize = 6;
/// The table identified.
pub type Table = PreisachTable<ROWS, LOADS>;

/// Ridge on every column but the bias, relative to the mean of the normal
/// equations' diagonal: a relay that no training sample switches gets a
/// zero weight instead of an arbitrary one.
pub const RIDGE: f64 = 1e-6;

/// Where the relays switch and the loads the weights are given at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// Lowest switch-down threshold `β_0`, MPa.
    pub lo_mpa: f32,
    /// Threshold spacing `Δ`, MPa.
    pub step_mpa: f32,
    /// Highest pressure of the model (the inverse's limit), MPa.
    pub max_pressure_mpa: f32,
    /// First grid load, N.
    pub min_load_n: f32,
    /// Grid load step, N.
    pub load_step_n: f32,
}

impl Grid {
    /// The grid for a record: thresholds evenly over 2–98 % of its highest
    /// pressure, loads evenly from its lowest to its highest load. `None`
    /// for a record without a positive finite pressure.
    pub fn for_record(samples: &[Sample]) -> Option<Grid> {
        let finite = |v: f64| v.is_finite().then_some(v);
        let p_max = samples
            .iter()
            .filter_map(|s| finite(s.pressure_mpa))
            .fold(f64::NAN, f64::max);
        // `fold` from NaN keeps NaN only when no pressure is finite.
        if p_max.is_nan() || p_max <= 0.0 {
            return None;
        }
        let (l_min, l_max) = samples
            .iter()
            .filter_map(|s| finite(s.load_n))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), l| {
                (lo.min(l), hi.max(l))
            });
        let span = l_max - l_min;
        let lo = 0.02 * p_max;
        Some(Grid {
            lo_mpa: lo as f32,
            step_mpa: ((0.98 * p_max - lo) / ROWS as f64) as f32,
            max_pressure_mpa: p_max as f32,
            min_load_n: if l_min.is_finite() { l_min as f32 } else { 0.0 },
            load_step_n: if span > 0.0 {
                (span / (LOADS - 1) as f64) as f32
            } else {
                1.0
            },
        })
    }

    /// The grid load nearest `load_n` (clamped to the grid).
    pub fn index(&self, load_n: f32) -> usize {
        let k = ((load_n - self.min_load_n) / self.load_step_n).round();
        if k >= 0.0 {
            (k as usize).min(LOADS - 1)
        } else {
            0
        }
    }

    fn table(&self, grid: [PreisachCoeffs<ROWS>; LOADS]) -> Table {
        PreisachTable {
            lo_mpa: self.lo_mpa,
            step_mpa: self.step_mpa,
            max_pressure_mpa: self.max_pressure_mpa,
            min_load_n: self.min_load_n,
            load_step_n: self.load_step_n,
            grid,
        }
    }
}

/// The table identified on the samples outside `heldout` (the model runs
/// over every sample, so the relay states are those of the whole pressure
/// history; each training sample's row goes to its active load's grid
/// load). A grid load no training sample is nearest to takes the
/// coefficients interpolated from the nearest trained ones on each side
/// (the nearest one's where only one side has one). Refused when pam-core
/// refuses the table or no sample trains.
pub fn identify(samples: &[Sample], heldout: &[bool], grid: &Grid) -> Result<Table, String> {
    let Some(first) = samples.first() else {
        return Err("the record has no samples".into());
    };
    let mut table = grid.table([PreisachCoeffs::ZERO; LOADS]);
    table
        .validate()
        .map_err(|e| format!("the Preisach grid is refused: {e}"))?;
    let relays = ROWS * (ROWS + 1) / 2;
    let m = relays + 2;
    let mut normal = vec![NormalEquations::new(m); LOADS];
    let mut trained = [false; LOADS];
    let mut model = Preisach::new(&table, first.load_n as f32, first.pressure_mpa as f32)
        .switch_loads_at_once();
    let mut row = vec![0.0; m];
    for (s, &h) in samples.iter().zip(heldout) {
        model.update_load(&table, s.load_n as f32);
        model.update_state(s.pressure_mpa as f32);
        if h || !s.contraction.is_finite() {
            continue;
        }
        trained[grid.index(s.load_n as f32)] = true;
        row[0] = 1.0;
        row[1] = f64::from(model.last_mpa());
        let mut c = 2;
        for i in 0..ROWS {
            for j in 0..=i {
                row[c] = if model.relay(i, j) { 1.0 } else { 0.0 };
                c += 1;
            }
        }
        normal[grid.index(model.load_n())].add(&row, s.contraction);
    }
    if !trained.iter().any(|t| *t) {
        return Err("no training sample: every sample is held out".into());
    }
    for (coeffs, normal) in table.grid.iter_mut().zip(&normal) {
        let x = normal.solve(RIDGE)?;
        let mut w = [[0.0f32; ROWS]; ROWS];
        let mut c = 2;
        for (i, wr) in w.iter_mut().enumerate() {
            for v in wr.iter_mut().take(i + 1) {
                *v = x[c] as f32;
                c += 1;
            }
        }
        *coeffs = PreisachCoeffs::from_weights(x[0] as f32, x[1] as f32, &w);
    }
    fill_untrained(&mut table.grid, &trained, mix_coeffs);
    table
        .validate()
        .map_err(|e| format!("pam-core refuses the identified Preisach table: {e}"))?;
    Ok(table)
}

/// Every grid load without training samples takes the coefficients
/// interpolated linearly (`mix(a, b, t)`) from the nearest trained grid
/// loads on each side (the nearest one's where only one side has one):
/// what a table's own `at_load` does between its grid loads, over the
/// wider gap. The models are linear in their coefficients, so this is their
/// prediction interpolated across load. (bench-m4's baselines fill their
/// grids with it too.)
pub fn fill_untrained<T: Copy, const L: usize>(
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

/// [`fill_untrained`] for the Preisach table's coefficients.
fn mix_coeffs(a: &PreisachCoeffs<ROWS>, b: &PreisachCoeffs<ROWS>, t: f32) -> PreisachCoeffs<ROWS> {
    let lerp = |a: f32, b: f32| a + t * (b - a);
    PreisachCoeffs {
        bias: lerp(a.bias, b.bias),
        linear: lerp(a.linear, b.linear),
        everett: core::array::from_fn(|i| {
            core::array::from_fn(|k| lerp(a.everett[i][k], b.everett[i][k]))
        }),
    }
}

/// The table's contraction at every sample, driven by the measured
/// pressure and load from the first sample on (a load switch made at once,
/// as an offline evaluation makes it: `Preisach::switch_loads_at_once`).
pub fn predict(table: &Table, samples: &[Sample]) -> Vec<f64> {
    let Some(first) = samples.first() else {
        return Vec::new();
    };
    let mut model =
        Preisach::new(table, first.load_n as f32, first.pressure_mpa as f32).switch_loads_at_once();
    samples
        .iter()
        .map(|s| f64::from(model.step(table, s.pressure_mpa as f32, s.load_n as f32)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minor-loop record at two loads from a known Preisach table.
    fn record_of(table: &Table) -> Vec<Sample> {
        let mut out = Vec::new();
        let mut model = Preisach::new(table, 100.0, 0.0).switch_loads_at_once();
        let mut t = 0.0;
        for load in [100.0f32, 200.0] {
            for (a, b) in [
                (0.0f32, 0.5f32),
                (0.5, 0.1),
                (0.1, 0.35),
                (0.35, 0.2),
                (0.2, 0.5),
            ] {
                for k in 0..=200 {
                    let p = a + (b - a) * k as f32 / 200.0;
                    t += 0.02;
                    let x = model.step(table, p, load);
                    out.push(Sample {
                        t_s: t,
                        load_n: f64::from(load),
                        pressure_mpa: f64::from(p),
                        contraction: f64::from(x),
                    });
                }
            }
        }
        out
    }

    #[test]
    fn a_preisach_record_is_identified_to_its_rounding() {
        let grid = Grid {
            lo_mpa: 0.01,
            step_mpa: 0.03,
            max_pressure_mpa: 0.5,
            min_load_n: 100.0,
            load_step_n: 20.0,
        };
        let mut truth = grid.table([PreisachCoeffs::ZERO; LOADS]);
        for (g, c) in truth.grid.iter_mut().enumerate() {
            let w: [[f32; ROWS]; ROWS] = core::array::from_fn(|i| {
                core::array::from_fn(|j| 0.001 * ((i + 2 * j + g) % 5) as f32)
            });
            *c = PreisachCoeffs::from_weights(0.01, 0.1 + 0.01 * g as f32, &w);
        }
        let samples = record_of(&truth);
        // The record's own grid is the one it was made on.
        let own = Grid::for_record(&samples).unwrap();
        assert!((own.step_mpa - grid.step_mpa).abs() < 1e-6 && own.load_step_n == 20.0);
        let heldout: Vec<bool> = (0..samples.len()).map(|i| i % 7 == 3).collect();
        let table = identify(&samples, &heldout, &grid).unwrap();
        let predicted = predict(&table, &samples);
        let worst = samples
            .iter()
            .zip(&predicted)
            .map(|(s, x)| (x - s.contraction).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-4, "{worst}");
        // The loads between the two trained ones are filled, not left at 0.
        assert!(table.grid.iter().all(|c| c.linear > 0.05), "{table:?}");
    }

    #[test]
    fn a_record_without_pressure_or_training_samples_is_refused() {
        let s = Sample {
            t_s: 0.0,
            load_n: 100.0,
            pressure_mpa: 0.0,
            contraction: 0.0,
        };
        assert!(Grid::for_record(&[s]).is_none());
        let s = Sample {
            pressure_mpa: 0.3,
            ..s
        };
        let grid = Grid::for_record(&[s]).unwrap();
        assert!(identify(&[s], &[true], &grid).is_err());
        assert!(identify(&[], &[], &grid).is_err());
    }
}

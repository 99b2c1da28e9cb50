//! The least-squares problem: weighted pressure residuals of the training
//! samples and the distance to the feasible set.

use pam_core::effects::shape::table::at_fraction_f64;
use pam_core::effects::ConstraintShape;

use super::static_shape::variables::StaticShape;
use super::*;

/// Training samples, sorted by load so that the per-load model is computed
/// once per run of equal loads.
pub(super) struct TrainSet {
    pub(super) x: Vec<f64>,
    pub(super) p: Vec<f64>,
    pub(super) branch: Vec<Branch>,
    /// `(load, start, end)` runs of equal load.
    pub(super) runs: Vec<(f64, usize, usize)>,
    pub(super) sigma_p: f64,
    pub(super) sigma_x: f64,
}

#[cfg(test)]
impl TrainSet {
    /// A training set without samples, the noise of a typical record.
    pub(super) fn empty() -> TrainSet {
        TrainSet {
            x: Vec::new(),
            p: Vec::new(),
            branch: Vec::new(),
            runs: Vec::new(),
            sigma_p: 1e-3,
            sigma_x: 1e-4,
        }
    }
}

impl TrainSet {
    pub(super) fn len(&self) -> usize {
        self.x.len()
    }

    /// Weighted residuals of the family `fam` into `out[..len]`.
    fn residuals(&self, fam: &LoadFamily, out: &mut [f64]) {
        let (vp, vx) = (self.sigma_p * self.sigma_p, self.sigma_x * self.sigma_x);
        for &(load, start, end) in &self.runs {
            let m = fam.at_load(load);
            let rows = self.x[start..end]
                .iter()
                .zip(&self.branch[start..end])
                .zip(&self.p[start..end]);
            for (o, ((&x, &br), &pm)) in out[start..end].iter_mut().zip(rows) {
                let (p, slope) = m.pressure_and_slope(x, br, 1.0);
                *o = (p - pm) / (vp + slope * slope * vx).sqrt();
            }
        }
    }
}

/// The paper's model's problem: the training residuals at the feasible
/// projection of the optimiser's point, and the distance moved.
pub(super) struct Problem<'a> {
    pub(super) anchor: [f64; NP],
    pub(super) data: &'a TrainSet,
    pub(super) fixed: Fixed,
    /// Weight of the distance to the feasible set, per parameter scale.
    pub(super) penalty_weight: f64,
    /// The stroke table's knots per load, when the shape stage found one
    /// (the paper's model refitted under it).
    pub(super) table: Option<StaticShape>,
}

impl Problem<'_> {
    pub(super) fn n_residuals(&self) -> usize {
        self.data.len() + NP
    }

    pub(super) fn residuals_at(&self, theta: &[f64], out: &mut [f64]) {
        let (inside, _) = project(theta, &self.anchor, &self.fixed);
        let n = self.data.len();
        let fam = family(&inside, &self.fixed);
        match &self.table {
            Some(t) => self.data.table_residuals(&fam, Some(t), &mut out[..n]),
            None => self.data.residuals(&fam, &mut out[..n]),
        }
        for j in 0..NP {
            out[n + j] = self.penalty_weight * (theta[j] - inside[j]) / param_scale(j, &self.fixed);
        }
    }
}

/// Typical magnitude of parameter `j`, for finite-difference steps and the
/// feasibility penalty.
pub(super) fn param_scale(j: usize, fixed: &Fixed) -> f64 {
    match j {
        0..=1 => 0.1,
        2..=3 => fixed.pmax,
        4..=5 => 0.01,
        6 => 0.1,
        _ => 0.01 * fixed.pmax,
    }
}

impl TrainSet {
    /// Weighted residuals of `fam` with the stroke table of knots `nodes`
    /// into `out[..len]`.
    pub(super) fn table_residuals(
        &self,
        fam: &LoadFamily,
        shape: Option<&StaticShape>,
        out: &mut [f64],
    ) {
        self.table_residuals_of(fam, shape, 0..self.len(), out);
    }

    /// [`Self::table_residuals`] of the runs within `rows` (run-aligned,
    /// `table_blocks` of the static-shape stage) into their slice `out`.
    pub(super) fn table_residuals_of(
        &self,
        fam: &LoadFamily,
        shape: Option<&StaticShape>,
        rows: std::ops::Range<usize>,
        out: &mut [f64],
    ) {
        let (vp, vx) = (self.sigma_p * self.sigma_p, self.sigma_x * self.sigma_x);
        self.table_misses_of(fam, shape, rows, out, |miss, slope| {
            miss / (vp + slope * slope * vx).sqrt()
        });
    }

    /// The pressure the model of `fam` with `shape` needs at each training
    /// sample minus the measured one, MPa, unweighted, into `out[..len]`.
    pub(super) fn table_pressure_misses(
        &self,
        fam: &LoadFamily,
        shape: Option<&StaticShape>,
        out: &mut [f64],
    ) {
        self.table_misses_of(fam, shape, 0..self.len(), out, |miss, _| miss);
    }

    /// Each sample's pressure miss and the model pressure's slope in
    /// contraction, for the runs within `rows`, made into `out` by `each`.
    #[inline(always)]
    fn table_misses_of(
        &self,
        fam: &LoadFamily,
        shape: Option<&StaticShape>,
        rows: std::ops::Range<usize>,
        out: &mut [f64],
        each: impl Fn(f64, f64) -> f64,
    ) {
        let span = (fam.max_load_n - fam.min_load_n).max(1e-9);
        let runs = self
            .runs
            .iter()
            .filter(|r| r.1 >= rows.start && r.2 <= rows.end);
        for &(load, start, end) in runs {
            let m = fam.at_load(load);
            let k = shape.map(|s| at_fraction_f64(&s.nodes, (load - fam.min_load_n) / span));
            let steps =
                (load.clamp(fam.min_load_n, fam.max_load_n) - fam.min_load_n) / fam.load_step_n;
            let at = shape.map_or([0.0; 4], |s| {
                ConstraintShape::at_steps_f64(s.coefficients, steps).0
            });
            let samples = self.x[start..end]
                .iter()
                .zip(&self.branch[start..end])
                .zip(&self.p[start..end]);
            let slots = &mut out[start - rows.start..end - rows.start];
            for (o, ((&x, &br), &pm)) in slots.iter_mut().zip(samples) {
                let (p, slope) = ConstraintShape::pressure_and_slope_f64(at, k.as_ref(), &m, x, br);
                *o = each(p - pm, slope);
            }
        }
    }
}

//! The least-squares problem: weighted pressure residuals of the training
//! samples and the distance to the feasible set.

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

pub(super) struct Problem<'a> {
    pub(super) theta: DVector<f64>,
    pub(super) anchor: [f64; NP],
    pub(super) data: &'a TrainSet,
    pub(super) fixed: Fixed,
    /// Weight of the distance to the feasible set, per parameter scale.
    pub(super) penalty_weight: f64,
    pub(super) evaluations: std::sync::atomic::AtomicUsize,
    pub(super) progress: &'a (dyn Fn(Progress) + Sync),
}

impl Problem<'_> {
    fn n_residuals(&self) -> usize {
        self.data.len() + NP
    }

    fn residuals_at(&self, theta: &[f64], out: &mut [f64]) {
        let (inside, _) = project(theta, &self.anchor, &self.fixed);
        let n = self.data.len();
        self.data
            .residuals(&family(&inside, &self.fixed), &mut out[..n]);
        for j in 0..NP {
            out[n + j] = self.penalty_weight * (theta[j] - inside[j]) / param_scale(j, &self.fixed);
        }
        for v in out.iter_mut() {
            if !v.is_finite() {
                *v = 1e6;
            }
        }
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.theta.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let mut r = DVector::zeros(self.n_residuals());
        self.residuals_at(self.theta.as_slice(), r.as_mut_slice());
        let count = 1 + self
            .evaluations
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        (self.progress)(Progress::Evaluation {
            count,
            cost: 0.5 * r.norm_squared(),
        });
        Some(r)
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let theta: Vec<f64> = self.theta.iter().copied().collect();
        let steps: Vec<f64> = theta
            .iter()
            .enumerate()
            .map(|(j, v)| 1e-7 * v.abs().max(param_scale(j, &self.fixed)))
            .collect();
        Some(crate::identify::lsq::forward_difference_jacobian(
            &theta,
            &steps,
            self.n_residuals(),
            &|t, out| self.residuals_at(t, out),
        ))
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

//! Every model's errors over a record: the baselines, pam-core's paper model
//! and its non-local memory.

use super::*;

#[derive(Clone, Copy, Default)]
pub(crate) struct Errors {
    pub(crate) train_sq: f64,
    pub(crate) train_n: usize,
    pub(crate) test_sq: f64,
    pub(crate) test_max: f64,
    pub(crate) test_n: usize,
}

impl Errors {
    pub(crate) fn add(&mut self, heldout: bool, e: f64) {
        if heldout {
            self.test_sq += e * e;
            self.test_max = self.test_max.max(e.abs());
            self.test_n += 1;
        } else {
            self.train_sq += e * e;
            self.train_n += 1;
        }
    }
    pub(crate) fn train_rms(&self) -> f64 {
        (self.train_sq / self.train_n.max(1) as f64).sqrt()
    }
    pub(crate) fn test_rms(&self) -> f64 {
        (self.test_sq / self.test_n.max(1) as f64).sqrt()
    }
}

/// The first sample's load (N) and pressure (MPa): where a baseline starts.
pub(crate) fn start(samples: &[Sample]) -> (f32, f32) {
    samples
        .first()
        .map_or((0.0, 0.0), |s| (s.load_n as f32, s.pressure_mpa as f32))
}

/// A baseline's errors over `samples`: `step(pressure MPa, load N)` gives
/// its contraction, sample by sample.
pub(crate) fn baseline_errors(
    samples: &[Sample],
    heldout: &[bool],
    mut step: impl FnMut(f32, f32) -> f32,
) -> Errors {
    let mut e = Errors::default();
    for (s, &h) in samples.iter().zip(heldout) {
        let x = step(s.pressure_mpa as f32, s.load_n as f32);
        e.add(h, f64::from(x) - s.contraction);
    }
    e
}

pub(crate) fn pi_errors(table: &PiTable<N, L>, samples: &[Sample], heldout: &[bool]) -> Errors {
    let (l0, p0) = start(samples);
    let mut m = PrandtlIshlinskii::new(table, l0, p0);
    baseline_errors(samples, heldout, |p, l| m.step(table, p, l))
}

pub(crate) fn gpi_errors(
    table: &GpiTable<GPI_N, L>,
    samples: &[Sample],
    heldout: &[bool],
) -> Errors {
    let (l0, p0) = start(samples);
    let mut m = GeneralizedPi::new(table, l0, p0);
    baseline_errors(samples, heldout, |p, l| m.step(table, p, l))
}

pub(crate) fn preisach_errors(
    table: &PreisachTable<N, L>,
    samples: &[Sample],
    heldout: &[bool],
) -> Errors {
    let (l0, p0) = start(samples);
    let mut m = Preisach::new(table, l0, p0).switch_loads_at_once();
    baseline_errors(samples, heldout, |p, l| m.step(table, p, l))
}

pub(crate) fn paper_errors(coeffs: &Coeffs, samples: &[Sample], heldout: &[bool]) -> Errors {
    let sim = pam_lab::evaluate::simulate::simulate(
        coeffs,
        &pam_core::Effects::NONE,
        TrackerConfig::DEFAULT_PRESSURE,
        samples,
    );
    let mut e = Errors::default();
    for (s, &h) in sim.iter().zip(heldout) {
        e.add(h, s.error());
    }
    e
}

/// Errors of pam-core's `Simulator` with `effects` on `coeffs`, driven by
/// the measured pressure and load.
pub(crate) fn effects_errors(
    coeffs: &Coeffs,
    effects: Effects,
    samples: &[Sample],
    heldout: &[bool],
) -> Errors {
    let mut sim = Simulator::<16>::new(
        *coeffs,
        effects,
        TrackerConfig::DEFAULT_PRESSURE,
        samples[0].load_n as f32,
    )
    .expect("valid simulator");
    let mut e = Errors::default();
    for (s, &h) in samples.iter().zip(heldout) {
        let x = sim.step(s.t_s as f32, s.pressure_mpa as f32, s.load_n as f32);
        e.add(h, f64::from(x) - s.contraction);
    }
    e
}

/// Errors with the training part of `train` and the held-out part of
/// `test` (a run on another record, every sample held out), or `train`'s
/// own held-out part.
pub(crate) fn merged(train: Errors, test: Option<Errors>) -> Errors {
    match test {
        Some(t) => Errors {
            test_sq: t.test_sq,
            test_max: t.test_max,
            test_n: t.test_n,
            ..train
        },
        None => train,
    }
}

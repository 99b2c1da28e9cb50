//! Generated characterisation records: the paper's model (pam-core) driven
//! through a test protocol, plus Gaussian noise. For tests, benchmarks and
//! examples; real records come from a rig.
//!
//! The generated muscle follows the paper's model exactly, including its jump
//! to the other branch when the pressure reverses inside the loop. The branch
//! is the direction of the noise-free drive pressure.

use pam_core::{Branch, Coeffs, Params};

use crate::record::{Record, Sample};

/// Force, N, of a 10 mm McKibben muscle at gauge pressure `p_mpa` and
/// contraction `eps` from physics, not from pam-core's equations: the
/// Chou–Hannaford law (braid angle 23°) above a threshold pressure
/// `0.04 + 1.2·eps` MPa, less a braid friction of 6 N + 6 % against the
/// pressure's motion (`filling`), never below 0 (a slack muscle). For test
/// plants of isometric records.
pub fn chou_hannaford_force_n(p_mpa: f64, eps: f64, filling: bool) -> f64 {
    let theta = 23f64.to_radians();
    let (a, b) = (3.0 / theta.tan().powi(2), 1.0 / theta.sin().powi(2));
    let area_m2 = std::f64::consts::PI * 0.01f64.powi(2) / 4.0;
    let p_th = 0.04 + 1.2 * eps;
    let ideal = (p_mpa - p_th).max(0.0) * 1e6 * area_m2 * (a * (1.0 - eps).powi(2) - b);
    let friction = 6.0 + 0.06 * ideal;
    (ideal - if filling { friction } else { -friction }).max(0.0)
}

/// One move of the pressure drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Move {
    /// Ramp linearly to `to_mpa` at `rate_mpa_s` (MPa/s, > 0).
    Ramp {
        /// Target pressure, MPa.
        to_mpa: f64,
        /// Ramp rate, MPa/s.
        rate_mpa_s: f64,
    },
    /// Step to `to_mpa` in one sample and hold it for `hold_s` seconds.
    Step {
        /// Target pressure, MPa.
        to_mpa: f64,
        /// Hold time, s.
        hold_s: f64,
    },
}

/// A load held while the drive makes its moves.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// The load, N.
    pub load_n: f64,
    /// The drive's moves.
    pub moves: Vec<Move>,
}

/// A test protocol: stages at a sample rate.
#[derive(Clone, Debug, PartialEq)]
pub struct Protocol {
    /// Sample rate, Hz.
    pub sample_hz: f64,
    /// The stages, in order.
    pub stages: Vec<Stage>,
}

fn full_cycle(pmax: f64, rate: f64) -> [Move; 2] {
    [
        Move::Ramp {
            to_mpa: pmax,
            rate_mpa_s: rate,
        },
        Move::Ramp {
            to_mpa: 0.0,
            rate_mpa_s: rate,
        },
    ]
}

impl Protocol {
    /// The protocol of the example rig records, at each of `loads`: two full
    /// cycles `0 → pmax → 0` at 0.05 MPa/s, partial cycles reversing inside
    /// the loop, full cycles at 0.02 and 0.2 MPa/s, and pressure steps to three
    /// levels with 8 s holds.
    pub fn standard(loads: &[f64], pmax: f64, sample_hz: f64) -> Protocol {
        let r = |to: f64, rate: f64| Move::Ramp {
            to_mpa: to * pmax,
            rate_mpa_s: rate,
        };
        let stages = loads
            .iter()
            .map(|&load_n| {
                let mut moves = Vec::new();
                moves.extend(full_cycle(pmax, 0.05));
                moves.extend(full_cycle(pmax, 0.05));
                moves.extend([r(0.5, 0.05), r(0.4, 0.05), r(0.7, 0.05), r(0.6, 0.05)]);
                moves.extend([r(1.0, 0.05), r(0.0, 0.05)]);
                moves.extend(full_cycle(pmax, 0.02));
                moves.extend(full_cycle(pmax, 0.2));
                for level in [0.25, 0.5, 0.8, 0.5, 0.25, 0.0] {
                    moves.push(Move::Step {
                        to_mpa: level * pmax,
                        hold_s: 8.0,
                    });
                }
                Stage { load_n, moves }
            })
            .collect();
        Protocol { sample_hz, stages }
    }

    /// A short protocol for fast tests: per load two full cycles at
    /// 0.1 MPa/s and one partial cycle, at 50 Hz.
    pub fn quick(loads: &[f64]) -> Protocol {
        let pmax = 0.5;
        let stages = loads
            .iter()
            .map(|&load_n| {
                let mut moves = Vec::new();
                moves.extend(full_cycle(pmax, 0.1));
                moves.extend(full_cycle(pmax, 0.1));
                moves.extend([
                    Move::Ramp {
                        to_mpa: 0.3,
                        rate_mpa_s: 0.1,
                    },
                    Move::Ramp {
                        to_mpa: 0.15,
                        rate_mpa_s: 0.1,
                    },
                    Move::Ramp {
                        to_mpa: 0.0,
                        rate_mpa_s: 0.1,
                    },
                ]);
                Stage { load_n, moves }
            })
            .collect();
        Protocol {
            sample_hz: 50.0,
            stages,
        }
    }

    /// The noise-free drive: `(t_s, load_n, pressure_mpa, branch)` per sample.
    pub fn drive(&self) -> Vec<(f64, f64, f64, Branch)> {
        let dt = 1.0 / self.sample_hz;
        let mut out = Vec::new();
        let mut p = 0.0f64;
        let mut branch = Branch::Contraction;
        let mut t = 0.0;
        let mut push = |p: f64, load: f64, br: Branch, t: &mut f64| {
            out.push((*t, load, p, br));
            *t += dt;
        };
        for stage in &self.stages {
            for mv in &stage.moves {
                match *mv {
                    Move::Ramp { to_mpa, rate_mpa_s } => {
                        let step = rate_mpa_s * dt;
                        if to_mpa > p {
                            branch = Branch::Contraction;
                        } else if to_mpa < p {
                            branch = Branch::Expansion;
                        }
                        let n = ((to_mpa - p).abs() / step).ceil().max(1.0) as usize;
                        let from = p;
                        for k in 1..=n {
                            p = from + (to_mpa - from) * k as f64 / n as f64;
                            push(p, stage.load_n, branch, &mut t);
                        }
                    }
                    Move::Step { to_mpa, hold_s } => {
                        if to_mpa > p {
                            branch = Branch::Contraction;
                        } else if to_mpa < p {
                            branch = Branch::Expansion;
                        }
                        p = to_mpa;
                        let n = (hold_s * self.sample_hz).round().max(1.0) as usize;
                        for _ in 0..n {
                            push(p, stage.load_n, branch, &mut t);
                        }
                    }
                }
            }
        }
        out
    }
}

pub use crate::rng::Rng;

/// Drive the model of `params` through `protocol` and add Gaussian noise of
/// the given standard deviations to the measured pressure and contraction.
///
/// # Panics
/// If `params` does not validate (a programming error in a test).
pub fn generate(
    params: &Params,
    protocol: &Protocol,
    pressure_noise_mpa: f64,
    contraction_noise: f64,
    seed: u64,
) -> Record {
    let coeffs = Coeffs::new(*params).expect("generate: params must validate");
    let mut rng = Rng::new(seed);
    let mut cache = crate::evaluate::errors::ModelCache::new(&coeffs, None);
    let samples = protocol
        .drive()
        .into_iter()
        .map(|(t_s, load_n, p, br)| {
            let x = f64::from(cache.contraction(p as f32, load_n as f32, br));
            Sample {
                t_s,
                load_n,
                pressure_mpa: p + pressure_noise_mpa * rng.normal(),
                contraction: x + contraction_noise * rng.normal(),
            }
        })
        .collect();
    Record::from_samples("generated", samples)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quick_protocol_has_the_expected_shape() {
        let d = Protocol::quick(&[100.0, 200.0]).drive();
        // Per load: 4 ramps of 0.5 MPa and 0.3 + 0.15 + 0.15 at 0.1 MPa/s, 50 Hz.
        assert_eq!(d.len(), 2 * (4 * 250 + 150 + 75 + 75));
        let top = d.iter().map(|s| s.2).fold(0.0, f64::max);
        assert!((top - 0.5).abs() < 1e-12);
        assert_eq!(d[10].3, Branch::Contraction);
        assert_eq!(d[300].3, Branch::Expansion);
        assert!(d.windows(2).all(|w| w[1].0 > w[0].0));
    }

    #[test]
    fn generated_samples_lie_on_the_model_without_noise() {
        let r = generate(&Params::DEFAULT, &Protocol::quick(&[100.0]), 0.0, 0.0, 1);
        let m = Coeffs::new(Params::DEFAULT)
            .unwrap()
            .load_model(100.0)
            .unwrap();
        let s = r.samples[100]; // rising
        let x = m.contraction(s.pressure_mpa as f32, Branch::Contraction);
        assert_eq!(s.contraction, f64::from(x));
    }

    #[test]
    fn normal_noise_has_unit_variance() {
        let mut rng = Rng::new(7);
        let n = 100_000;
        let v: Vec<f64> = (0..n).map(|_| rng.normal()).collect();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(
            mean.abs() < 0.02 && (var - 1.0).abs() < 0.02,
            "{mean} {var}"
        );
    }
}

//! Property: on any plausible rig — isotonic or isometric, a static curve
//! that is convex, near-linear, concave or S-shaped, loads anywhere in
//! 0–800 N, any noise level — `fit` returns a model `Coeffs::new` accepts
//! or a typed error, and never panics.
//!
//! The rigs here are this file's own: a static curve `Pmax·φ(u)` over a
//! load-dependent stroke plus a `sin`-shaped branch offset, evaluated by
//! bisection. None of it is pam-core's cubic, ellipse or load family.
//!
//! ```sh
//! cargo test -p pam-lab --test fit_any_rig -- --nocapture
//! ```

use pam_core::Coeffs;
use pam_lab::identify::fit::{fit, FitConfig, FitError, Holdout};
use pam_lab::record::{Record, Sample};
use pam_lab::synth::Rng;

/// One random rig.
#[derive(Clone, Copy, Debug)]
struct Rig {
    pmax: f64,
    /// Stroke at the lowest load and its shift per newton.
    root: f64,
    max: f64,
    root_per_n: f64,
    max_per_n: f64,
    /// Shape: 0 convex power, 1 concave power, 2 near-linear, 3 S-shaped.
    shape: u8,
    gamma: f64,
    /// Branch offset height, MPa.
    height: f64,
    loads: (f64, f64),
    noise_p: f64,
    noise_x: f64,
    noise_l: f64,
}

impl Rig {
    fn random(rng: &mut Rng) -> Rig {
        let u = |rng: &mut Rng, a: f64, b: f64| a + (b - a) * rng.uniform();
        let lo = u(rng, 0.0, 500.0);
        let shape = (rng.next_u64() % 4) as u8;
        Rig {
            pmax: u(rng, 0.2, 0.8),
            root: u(rng, -0.02, 0.05),
            max: u(rng, 0.12, 0.35),
            root_per_n: u(rng, 0.0, 3e-5),
            max_per_n: u(rng, 0.0, 1.5e-4),
            shape,
            gamma: match shape {
                0 => u(rng, 1.2, 2.5),
                1 => u(rng, 0.4, 0.85),
                2 => u(rng, 0.97, 1.03),
                _ => u(rng, 1.5, 3.0),
            },
            height: u(rng, 0.0, 0.05),
            loads: (lo, u(rng, lo + 50.0, 800.0)),
            noise_p: u(rng, 0.0, 0.004),
            noise_x: u(rng, 0.0, 0.002),
            noise_l: u(rng, 0.0, 3.0),
        }
    }

    fn stroke(&self, load_n: f64) -> (f64, f64) {
        let d = load_n - self.loads.0;
        let r = self.root - self.root_per_n * d;
        let rx = (self.max - self.max_per_n * d).max(r + 0.03);
        (r, rx)
    }

    fn phi(&self, u: f64) -> f64 {
        let u = u.clamp(0.0, 1.0);
        match self.shape {
            0..=2 => u.powf(self.gamma),
            _ => {
                let s = u.powf(self.gamma);
                s / (s + (1.0 - u).powf(self.gamma))
            }
        }
    }

    /// Pressure on a branch (`sign` +1 rising, −1 falling) at `x`, `load_n`.
    fn pressure(&self, x: f64, load_n: f64, sign: f64) -> f64 {
        let (r, rx) = self.stroke(load_n);
        let u = ((x - r) / (rx - r)).clamp(0.0, 1.0);
        (self.pmax * self.phi(u) + sign * self.height * (std::f64::consts::PI * u).sin())
            .clamp(0.0, self.pmax)
    }

    /// Contraction at pressure `p` on a branch, by bisection.
    fn contraction(&self, p: f64, load_n: f64, sign: f64) -> f64 {
        let (mut lo, mut hi) = self.stroke(load_n);
        for _ in 0..50 {
            let mid = 0.5 * (lo + hi);
            if self.pressure(mid, load_n, sign) <= p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// Load at which `x` needs pressure `p` (heavier loads shift the stroke
    /// down, so need more pressure at the same contraction); 0 N when the
    /// muscle is slack there.
    fn load(&self, x: f64, p: f64, sign: f64) -> f64 {
        let (mut lo, mut hi) = (self.loads.0, self.loads.1);
        if self.pressure(x, lo, sign) >= p {
            return 0.0;
        }
        for _ in 0..50 {
            let mid = 0.5 * (lo + hi);
            if self.pressure(x, mid, sign) < p {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// Pressure cycles 0 → Pmax → 0 at 100 samples per sweep.
    fn sweeps(&self) -> impl Iterator<Item = (f64, f64)> + '_ {
        (0..4).flat_map(move |c| {
            (0..100).map(move |k| {
                let f = k as f64 / 100.0;
                if c % 2 == 0 {
                    (self.pmax * f, 1.0)
                } else {
                    (self.pmax * (1.0 - f), -1.0)
                }
            })
        })
    }

    fn isotonic(&self, rng: &mut Rng) -> Record {
        let mut out = Vec::new();
        for k in 0..4 {
            let load = self.loads.0 + (self.loads.1 - self.loads.0) * k as f64 / 3.0;
            for (p, sign) in self.sweeps() {
                out.push(self.sample(out.len(), load, p, self.contraction(p, load, sign), rng));
            }
        }
        Record::from_samples("isotonic", out)
    }

    fn isometric(&self, rng: &mut Rng) -> Record {
        let mut out = Vec::new();
        let (r, rx) = self.stroke(self.loads.0);
        for k in 1..=4 {
            let x = r + (rx - r) * k as f64 / 5.0;
            for (p, sign) in self.sweeps() {
                out.push(self.sample(out.len(), self.load(x, p, sign), p, x, rng));
            }
        }
        Record::from_samples("isometric", out)
    }

    fn sample(&self, i: usize, load: f64, p: f64, x: f64, rng: &mut Rng) -> Sample {
        Sample {
            t_s: i as f64 * 0.02,
            load_n: (load + self.noise_l * rng.normal()).max(0.0),
            pressure_mpa: p + self.noise_p * rng.normal(),
            contraction: x + self.noise_x * rng.normal(),
        }
    }
}

fn check(rec: &Record, rig: &Rig, counts: &mut [usize; 3]) {
    let cfg = FitConfig {
        patience: 20,
        holdout: Holdout::EveryKthCycle(4),
        ..FitConfig::default()
    };
    match fit(rec, &cfg) {
        Ok(r) => {
            Coeffs::new(r.params).unwrap_or_else(|e| panic!("{rig:?}: {e}"));
            assert_eq!(r.coeffs.params(), &r.params);
            counts[0] += 1;
        }
        // A typed refusal with a reason is allowed (for example two loads
        // that fall into one load bin); a panic is not.
        Err(FitError::Data(e)) => {
            assert!(!e.to_string().is_empty());
            counts[1] += 1;
        }
        Err(e @ FitError::Invalid { .. }) => {
            assert!(e.to_string().contains("no valid model"));
            counts[2] += 1;
        }
        Err(e) => panic!("{rig:?}: unexpected {e}"),
    }
}

#[test]
fn fit_returns_a_valid_model_or_a_typed_error_on_any_rig() {
    let mut rng = Rng::new(12);
    let mut counts = [0usize; 3];
    const RIGS: usize = 500;
    for _ in 0..RIGS {
        let rig = Rig::random(&mut rng);
        check(&rig.isotonic(&mut rng), &rig, &mut counts);
        check(&rig.isometric(&mut rng), &rig, &mut counts);
    }
    eprintln!(
        "{} records: {} fitted, {} refused as data, {} refused as no valid model",
        2 * RIGS,
        counts[0],
        counts[1],
        counts[2]
    );
    // The property is "never a panic"; most plausible rigs must also fit.
    assert!(counts[0] >= RIGS, "{counts:?}");
}

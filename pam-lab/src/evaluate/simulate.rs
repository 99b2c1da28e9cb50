//! Driving the model with measured pressure and load, as the firmware would.
//!
//! pam-core's [`Simulator`] runs the model a file holds, its effects
//! included: its tracker follows the measured pressure (the drive signal)
//! and the measured load, and the predicted contraction is the active load
//! model's inverse on the tracker's branch at the measured pressure, with
//! the effects applied (minor loops, rate, creep, width, static shape).
//! Without effects it is exactly the paper's model: a reversal inside the
//! loop jumps to the other branch.
//!
//! The pressure error is the feedforward's quantity (and the natural one of
//! an isometric test): the paper's forward model (eqs. 25–26) at the
//! measured contraction on the tracker's branch and active load, minus the
//! measured pressure. It does not include the effects.

use pam_core::{Branch, Coeffs, Effects, Simulator, TrackerConfig};

use super::crossing::crossing;
use super::errors::ModelCache;
use crate::record::Sample;

/// One simulated sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSample {
    /// Time, s.
    pub t_s: f64,
    /// Measured load, N.
    pub load_n: f64,
    /// Measured pressure, MPa.
    pub pressure_mpa: f64,
    /// Measured contraction.
    pub measured_contraction: f64,
    /// Model contraction.
    pub predicted_contraction: f64,
    /// Model pressure at the measured contraction, MPa: the paper's model
    /// at the tracker's active load and branch with its static shape, as
    /// the feedforward computes it (the dynamic effects left out).
    pub predicted_pressure_mpa: f64,
    /// The tracker's branch.
    pub branch: Branch,
    /// The tracker's active load, N.
    pub active_load_n: f64,
}

impl SimSample {
    /// Predicted − measured contraction.
    pub fn error(&self) -> f64 {
        self.predicted_contraction - self.measured_contraction
    }

    /// Predicted − measured pressure, MPa.
    pub fn pressure_error_mpa(&self) -> f64 {
        self.predicted_pressure_mpa - self.pressure_mpa
    }
}

/// Error summary of a simulation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    /// RMS contraction error.
    pub contraction_rms: f64,
    /// Largest |contraction error|.
    pub contraction_max: f64,
    /// RMS pressure error, MPa.
    pub pressure_rms_mpa: f64,
    /// Largest |pressure error|, MPa.
    pub pressure_max_mpa: f64,
}

/// Reversal points the simulation remembers: pam-core's one depth, the
/// firmware's.
pub use pam_core::effects::memory::MEMORY_DEPTH;

/// `config` with the load model following an isometric record's force:
/// the force moves with the pressure on every sample, so the model switches
/// within twice the load cell's noise `load_noise_n` (at least 0.5 N) from
/// the first sample; with the firmware's 20 N and 5 samples it runs up to
/// 20 N behind the muscle (on the Festo 10 mm muscle, 30 kPa of pressure).
/// What fit's, diagnose's and simulate's isometric evaluations use.
pub fn following_the_force(config: TrackerConfig, load_noise_n: f64) -> TrackerConfig {
    TrackerConfig {
        load_threshold_n: (2.0 * load_noise_n).max(0.5) as f32,
        load_debounce_samples: 1,
        ..config
    }
}

/// When a simulation builds a new load model's inverse tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InverseTables {
    /// At each load switch, as the firmware does (a record whose load
    /// holds between steps).
    AtEachSwitch,
    /// Never after the first model: the inverse by bisection
    /// ([`Simulator::defer_table_builds`]), for a record whose load is a
    /// force that switches the model every few samples (an isometric
    /// test), where a table per switch is most of the work.
    Never,
}

/// The simulator at a record's first sample: on the contraction branch at
/// its load, building inverse tables as `tables` says; `None` when the
/// effects do not validate.
fn start(
    coeffs: &Coeffs,
    effects: &Effects,
    config: TrackerConfig,
    samples: &[Sample],
    tables: InverseTables,
) -> Option<Simulator<MEMORY_DEPTH>> {
    let first_load = samples.first().map_or(0.0, |s| s.load_n as f32);
    let mut sim = Simulator::<MEMORY_DEPTH>::new(*coeffs, *effects, config, first_load).ok()?;
    if tables == InverseTables::Never {
        sim.defer_table_builds();
    }
    Some(sim)
}

/// The record simulator every tool uses: pam-core's [`Simulator`] driven
/// by each sample's measured pressure and load, the tracker starting on
/// the contraction branch at the first sample's load; on the tracker's own
/// branch, or on `branches` when given (diagnose's hindsight branches).
/// `each` gets the sample's index, the simulator after the step and the
/// predicted contraction. Time runs from the record's first sample: the
/// effects' filters integrate time steps in `f32`, which stays exact on a
/// record whose clock starts late. With a pressure delay the simulator is
/// driven by the pressure measured that long before each sample
/// ([`super::retime::delayed_pressures`]). `false` when the effects do not
/// validate (nothing is simulated).
pub fn run_record(
    coeffs: &Coeffs,
    effects: &Effects,
    config: TrackerConfig,
    samples: &[Sample],
    branches: Option<&[Branch]>,
    tables: InverseTables,
    mut each: impl FnMut(usize, &Simulator<MEMORY_DEPTH>, f32),
) -> bool {
    let Some(mut sim) = start(coeffs, effects, config, samples, tables) else {
        return false;
    };
    let delayed = effects
        .pressure_delay
        .map(|d| super::retime::delayed_pressures(samples, f64::from(d.delay_s)));
    let t0 = samples.first().map_or(0.0, |s| s.t_s);
    for (i, s) in samples.iter().enumerate() {
        let p = delayed.as_ref().map_or(s.pressure_mpa, |d| d[i]);
        let (t, p, l) = ((s.t_s - t0) as f32, p as f32, s.load_n as f32);
        let x = match branches.and_then(|b| b.get(i)) {
            Some(&b) => sim.step_on_branch(t, p, l, b),
            None => sim.step(t, p, l),
        };
        each(i, &sim, x);
    }
    true
}

/// The pressure the model needs to reach each sample's measured
/// contraction: at every sample the simulator, stepped with a trial
/// pressure, is searched on `0..=pressure_limit_mpa` from the previous
/// sample's answer ([`crossing`], to `2⁻²⁶` of the interval, as a 26-step
/// bisection) until it gives the sample's contraction, and
/// goes on with the pressure found: the model's own pressure history, as a
/// feedforward's (with the measured one, a lag effect such as creep would
/// need an unbounded pressure to close in one sample what the measured
/// history left open). The load is the measured one. This is an isometric
/// test's prediction (the length held, the pressure the model says it
/// takes) with every effect in, which the static inverse alone leaves out.
/// On a known branch (`branches`) the trial contraction does not fall as
/// the pressure rises, so the search finds the one answer; a contraction
/// outside what the model reaches gives the end of the interval. `NaN`
/// everywhere when the effects do not validate.
///
/// With a pressure lag the pressure found is the muscle's (the model's
/// other effects, searched as above), and the measured pressure predicted
/// is what the lag needs to hold it there, `p + τ·ṗ` ([`lag_lead`]), with
/// the slope taken from the model's own pressures over ±2τ (a slope over
/// one sample would differentiate the measured force's noise: Festo 10,
/// 25, 40 cm, test 10, 36–55 kPa against 10–12 kPa without the lag). It
/// is a prediction of the measured pressure, as a static model's is: the
/// measured pressure itself is not used. (Adding the measured pressure's
/// own lead, `p_measured − lag(p_measured)`, instead compared the model
/// with the measured pressure through the lag, a smoothed target, and
/// leaked the measurement into the prediction: on Festo 40 cm, test 10,
/// it read 0.76× the reference surface; from the model's own pressures the
/// lag cuts 5.7 % of the held-out error there.)
///
/// With a pressure delay the measured pressure predicted at a sample is
/// the one predicted without it `delay_s` later ([`super::retime::shifted`]):
/// the muscle answers then.
pub fn pressure_to_reach(
    coeffs: &Coeffs,
    effects: &Effects,
    config: TrackerConfig,
    samples: &[Sample],
    branches: Option<&[Branch]>,
    tables: InverseTables,
    pressure_limit_mpa: f32,
) -> Vec<f64> {
    let mut out = vec![f64::NAN; samples.len()];
    if let Some(delay) = effects.pressure_delay {
        if delay.validate().is_err() {
            return out;
        }
        let muscle = Effects {
            pressure_delay: None,
            ..*effects
        };
        let at_once = pressure_to_reach(
            coeffs,
            &muscle,
            config,
            samples,
            branches,
            tables,
            pressure_limit_mpa,
        );
        return super::retime::shifted(samples, &at_once, f64::from(delay.delay_s));
    }
    if let Some(lag) = effects.pressure_lag {
        if lag.validate().is_err() {
            return out;
        }
        let muscle = Effects {
            pressure_lag: None,
            ..*effects
        };
        let mut out = pressure_to_reach(
            coeffs,
            &muscle,
            config,
            samples,
            branches,
            tables,
            pressure_limit_mpa,
        );
        let lead = lag_lead(f64::from(lag.time_constant_s), samples, &out);
        for (o, l) in out.iter_mut().zip(lead) {
            *o += l;
        }
        return out;
    }
    let Some(mut sim) = start(coeffs, effects, config, samples, tables) else {
        return out;
    };
    let t0 = samples.first().map_or(0.0, |s| s.t_s);
    let mut guess = samples.first().map_or(0.0, |s| s.pressure_mpa as f32);
    for (i, s) in samples.iter().enumerate() {
        let (t, l) = ((s.t_s - t0) as f32, s.load_n as f32);
        let branch = branches.and_then(|b| b.get(i)).copied();
        let step = |sim: &mut Simulator<MEMORY_DEPTH>, p: f32| match branch {
            Some(b) => sim.step_on_branch(t, p, l, b),
            None => sim.step(t, p, l),
        };
        let reach = |p: f32| step(&mut sim.clone(), p);
        let found = crossing(reach, s.contraction as f32, pressure_limit_mpa, guess);
        guess = found.unwrap_or(guess);
        out[i] = found.map_or(f64::NAN, f64::from);
        step(&mut sim, found.unwrap_or(s.pressure_mpa as f32));
    }
    out
}

/// The lead a first-order lag of time constant `tau_s` needs to follow the
/// pressures `muscle_mpa` (one per sample): `τ·ṗ`, the slope a centred
/// difference over `±2τ` of the samples' time, within the run of rising
/// time (steps in `(0, MAX_STEP_S]`) the sample is in, shortened at the
/// run's ends; 0 where no two samples span the window or a pressure at its
/// ends is not finite. A `NaN` pressure gives `NaN`.
pub fn lag_lead(tau_s: f64, samples: &[Sample], muscle_mpa: &[f64]) -> Vec<f64> {
    let n = samples.len().min(muscle_mpa.len());
    let half = 2.0 * tau_s;
    let mut out = vec![0.0; n];
    for (start, end) in super::retime::runs(&samples[..n]) {
        let (mut lo, mut hi) = (start, start);
        for i in start..end {
            let t = samples[i].t_s;
            while samples[lo].t_s < t - half && lo < i {
                lo += 1;
            }
            if hi < i {
                hi = i;
            }
            while hi + 1 < end && samples[hi + 1].t_s <= t + half {
                hi += 1;
            }
            out[i] = if !muscle_mpa[i].is_finite() {
                f64::NAN
            } else {
                let (a, b) = (muscle_mpa[lo], muscle_mpa[hi]);
                let dt = samples[hi].t_s - samples[lo].t_s;
                if hi > lo && a.is_finite() && b.is_finite() && dt > 0.0 {
                    tau_s * (b - a) / dt
                } else {
                    0.0
                }
            };
        }
    }
    out
}

/// Simulate `samples` with `coeffs` and `effects` ([`run_record`] on the
/// tracker's branches). Effects that do not validate give no samples (a
/// loaded model file has been validated).
pub fn simulate(
    coeffs: &Coeffs,
    effects: &Effects,
    config: TrackerConfig,
    samples: &[Sample],
) -> Vec<SimSample> {
    let mut out = Vec::with_capacity(samples.len());
    // The static model at the tracker's active load, with its static shape
    // as the feedforward applies it (a fitted real muscle's model is mostly
    // its shape: without it the Festo 10 cm model's pressure error here
    // read 38 kPa where fit measures 13).
    let mut statics = ModelCache::new(coeffs, effects.shape.as_ref());
    let delay_s = effects.pressure_delay.map(|d| f64::from(d.delay_s));
    run_record(
        coeffs,
        effects,
        config,
        samples,
        None,
        InverseTables::AtEachSwitch,
        |i, sim, x| {
            let s = &samples[i];
            let p =
                statics.pressure_mpa(s.contraction as f32, sim.tracker().load_n(), sim.branch());
            out.push(SimSample {
                t_s: s.t_s,
                load_n: s.load_n,
                pressure_mpa: s.pressure_mpa,
                measured_contraction: s.contraction,
                predicted_contraction: f64::from(x),
                predicted_pressure_mpa: f64::from(p),
                branch: sim.branch(),
                active_load_n: f64::from(sim.tracker().load_n()),
            });
        },
    );
    // With a pressure delay the measured pressure the static model predicts
    // at a sample is the muscle's that much later.
    if let Some(d) = delay_s {
        let muscle: Vec<f64> = out.iter().map(|s| s.predicted_pressure_mpa).collect();
        for (s, p) in out
            .iter_mut()
            .zip(super::retime::shifted(samples, &muscle, d))
        {
            s.predicted_pressure_mpa = p;
        }
    }
    out
}

/// RMS and maximum |error| of a simulation, contraction and pressure.
pub fn summary(sim: &[SimSample]) -> Summary {
    let n = sim.len().max(1) as f64;
    let rms =
        |f: &dyn Fn(&SimSample) -> f64| (sim.iter().map(|s| f(s).powi(2)).sum::<f64>() / n).sqrt();
    let max = |f: &dyn Fn(&SimSample) -> f64| sim.iter().map(|s| f(s).abs()).fold(0.0, f64::max);
    Summary {
        contraction_rms: rms(&|s| s.error()),
        contraction_max: max(&|s| s.error()),
        pressure_rms_mpa: rms(&|s| s.pressure_error_mpa()),
        pressure_max_mpa: max(&|s| s.pressure_error_mpa()),
    }
}

/// Write a simulation as CSV: the input columns, the prediction, the error
/// and the tracker's state.
pub fn write_csv(w: &mut dyn std::io::Write, sim: &[SimSample]) -> std::io::Result<()> {
    writeln!(
        w,
        "t_s,load_n,pressure_mpa,measured_contraction,predicted_contraction,error_contraction,predicted_pressure_mpa,error_pressure_mpa,branch,active_load_n"
    )?;
    for s in sim {
        writeln!(
            w,
            "{},{},{},{},{:.6},{:.6},{:.6},{:.6},{},{}",
            s.t_s,
            s.load_n,
            s.pressure_mpa,
            s.measured_contraction,
            s.predicted_contraction,
            s.error(),
            s.predicted_pressure_mpa,
            s.pressure_error_mpa(),
            match s.branch {
                Branch::Contraction => "contraction",
                Branch::Expansion => "expansion",
            },
            s.active_load_n
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Protocol};
    use pam_core::Params;

    #[test]
    fn noise_free_full_cycles_are_reproduced() {
        // Full cycles only (no reversal inside the loop, where the tracker's
        // deadband delays the jump): prediction equals the generating model
        // except within the deadband after each reversal.
        let mut proto = Protocol::quick(&[100.0, 300.0]);
        for st in &mut proto.stages {
            st.moves.truncate(4);
        }
        let rec = generate(&Params::DEFAULT, &proto, 0.0, 0.0, 1);
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let sim = simulate(
            &coeffs,
            &Effects::NONE,
            TrackerConfig::DEFAULT_PRESSURE,
            &rec.samples,
        );
        assert_eq!(sim.len(), rec.len());
        let bad = sim.iter().filter(|s| s.error().abs() > 1e-4).count();
        // The forward model has no deadband issue away from the reversals.
        let bad_p = sim
            .iter()
            .filter(|s| s.pressure_error_mpa().abs() > 1e-4)
            .count();
        assert!(bad_p <= 4 * 2 * 4, "{bad_p}");
        // Each reversal at the ends costs at most deadband/step = 3 samples.
        assert!(bad <= 4 * 2 * 4, "{bad}");
        assert_eq!(sim[1990].active_load_n, 300.0);
        let mut out = Vec::new();
        write_csv(&mut out, &sim[..2]).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(text.lines().count(), 3);
    }

    #[test]
    fn the_predicted_pressure_carries_the_static_shape() {
        // A record whose contraction is the shaped model's own, noise-free:
        // the pressure at the measured contraction is the measured one
        // (the bare paper model, without the shape, is far off it).
        let rec = generate(&Params::DEFAULT, &Protocol::quick(&[100.0]), 0.0, 0.0, 1);
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let effects = Effects {
            shape: Some(pam_core::effects::ConstraintShape {
                bulge: 0.2,
                tilt: 0.1,
                ..pam_core::effects::ConstraintShape::NEUTRAL
            }),
            ..Effects::NONE
        };
        let config = TrackerConfig::DEFAULT_PRESSURE;
        let mut samples = rec.samples.clone();
        assert!(run_record(
            &coeffs,
            &effects,
            config,
            &rec.samples,
            None,
            InverseTables::AtEachSwitch,
            |i, _, x| samples[i].contraction = f64::from(x),
        ));
        let sim = simulate(&coeffs, &effects, config, &samples);
        let model = coeffs.load_model(100.0).unwrap();
        let (mut shaped, mut bare, mut n) = (0.0f64, 0.0f64, 0);
        for s in &sim {
            // Inside the stroke, where the inverse is not clamped.
            if s.pressure_mpa > 0.02 && s.pressure_mpa < 0.95 * f64::from(model.max_pressure_mpa())
            {
                shaped = shaped.max(s.pressure_error_mpa().abs());
                let p = model.pressure_mpa(s.measured_contraction as f32, s.branch);
                bare = bare.max((f64::from(p) - s.pressure_mpa).abs());
                n += 1;
            }
        }
        assert!(n > sim.len() / 2, "{n}");
        assert!(shaped < 2e-3, "with the shape {shaped} MPa");
        assert!(bare > 0.02, "without it {bare} MPa");
    }

    #[test]
    fn pressure_to_reach_recovers_the_pressure_that_drove_the_model() {
        // A record whose contraction is the model's own, creep and rate in:
        // one sample ahead, the pressure that reaches it is the pressure
        // that drove it (the static inverse alone would miss the lag).
        let rec = generate(
            &Params::DEFAULT,
            &Protocol::quick(&[100.0, 300.0]),
            0.0,
            0.0,
            1,
        );
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let effects = Effects {
            creep: Some(pam_core::effects::Creep {
                gain: 0.3,
                time_constant_s: 0.5,
            }),
            ..Effects::NONE
        };
        let config = TrackerConfig::DEFAULT_PRESSURE;
        let mut samples = rec.samples.clone();
        let mut branches = Vec::new();
        let mut inside = Vec::new();
        let tables = InverseTables::AtEachSwitch;
        assert!(run_record(
            &coeffs,
            &effects,
            config,
            &rec.samples,
            None,
            tables,
            |i, sim, x| {
                samples[i].contraction = f64::from(x);
                branches.push(sim.branch());
                let (lo, hi) = sim.stroke();
                inside.push(x > lo + 1e-4 && x < hi - 1e-4);
            }
        ));
        let p = pressure_to_reach(
            &coeffs,
            &effects,
            config,
            &samples,
            Some(&branches),
            tables,
            1.0,
        );
        let (mut worst, mut judged) = (0.0f64, 0);
        for i in (0..samples.len()).filter(|&i| inside[i]) {
            worst = worst.max((p[i] - samples[i].pressure_mpa).abs());
            judged += 1;
        }
        assert!(judged > samples.len() / 2, "{judged} of {}", samples.len());
        assert!(worst < 1e-4, "worst {worst} MPa");
        // The static inverse, the creep left out, is far off after steps.
        let static_worst = (0..samples.len())
            .filter(|&i| inside[i])
            .map(|i| {
                let m = coeffs.load_model(samples[i].load_n as f32).unwrap();
                let ps = m.pressure_mpa(samples[i].contraction as f32, branches[i]);
                (f64::from(ps) - samples[i].pressure_mpa).abs()
            })
            .fold(0.0, f64::max);
        assert!(static_worst > 100.0 * worst.max(1e-5), "{static_worst}");
    }

    #[test]
    fn a_pressure_lag_predicts_the_measured_pressure_without_reading_it() {
        // A slow ramp at 1 kHz whose contraction is the model's own, the
        // measured pressure then given white noise the muscle never saw:
        // no prediction can follow that noise, so the error of a model with
        // a pressure lag stays at the noise (the measured pressure's own
        // lead, which the prediction once added, smoothed the noise away:
        // a tenth of it was left).
        let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
        let lag = pam_core::effects::PressureLag {
            time_constant_s: 0.05,
        };
        let effects = Effects {
            pressure_lag: Some(lag),
            ..Effects::NONE
        };
        let n = 20_000;
        let mut samples: Vec<Sample> = (0..n)
            .map(|i| Sample {
                t_s: i as f64 * 1e-3,
                load_n: 100.0,
                pressure_mpa: 0.1 + 0.4 * i as f64 / n as f64,
                contraction: 0.0,
            })
            .collect();
        let config = TrackerConfig::DEFAULT_PRESSURE;
        let tables = InverseTables::AtEachSwitch;
        let clean = samples.clone();
        assert!(run_record(
            &coeffs,
            &effects,
            config,
            &clean,
            None,
            tables,
            |i, _, x| samples[i].contraction = f64::from(x),
        ));
        let sigma = 0.01;
        let mut rng = crate::rng::Rng::new(7);
        for s in &mut samples {
            s.pressure_mpa += sigma * rng.normal();
        }
        let branches = vec![Branch::Contraction; n];
        let p = pressure_to_reach(
            &coeffs,
            &effects,
            config,
            &samples,
            Some(&branches),
            tables,
            1.0,
        );
        // Past the lag's start-up.
        let e: Vec<f64> = (1000..n).map(|i| p[i] - samples[i].pressure_mpa).collect();
        let rms = (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt();
        assert!(rms > 0.9 * sigma && rms < 1.2 * sigma, "{rms}");
        // Against the noise-free pressure it is close: the lead is the lag's.
        let clean_rms = ((1000..n)
            .map(|i| (p[i] - clean[i].pressure_mpa).powi(2))
            .sum::<f64>()
            / (n - 1000) as f64)
            .sqrt();
        assert!(clean_rms < 0.2 * sigma, "{clean_rms}");
    }
}

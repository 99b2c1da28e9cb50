//! The worn muscle: host-sim's plant whose braid and bladder fatigue while
//! the paper's scenarios run, and the firmware's controller tracking it
//! with and without its online adaptation (`firmware::controller::adapt`),
//! against a model freshly identified on the worn muscle.
//!
//! Over [`Wear::duration_s`] the plant's parameters move linearly from the
//! reference muscle's to the worn ones ([`Wear::muscle`]):
//!
//! * **stroke −15 %**: the whole static curve contracts 0.85× as far: the
//!   Tondu–Lopez end factor `k` grows to `k/0.85` (the braid's force at
//!   `ε` is the new muscle's at `kε`), and the bladder's spring with it
//!   (slack contraction `ε_s/k`, stiffnesses `·k`, so its force at `ε` is
//!   the new one's at `kε` too);
//! * **friction +30 %**: `F_c0` and `μ` (the loop's width);
//! * **stiffness −10 %**: the rubber resisting contraction.
//!
//! [`run_worn`] repeats the scenarios over the wear and one repetition
//! more at full wear; that last repetition is scored. The fresh model is
//! `pam-lab fit`'s paper model on an isotonic record of the fully worn
//! muscle ([`identify_worn`]), tracking the same last repetition on the
//! fully worn muscle.

use crate::bench::{controller_config, BenchConfig, Mode};
use crate::characterisation::{isotonic_run_on, to_record, IsotonicProtocol};
use crate::hal_mocks::{rig_io, valve_opening, RigIo, SharedRig, ValveKind};
use crate::plant::MuscleParams;
use crate::pneumatics::PneumaticParams;
use crate::rig::Rig;
use crate::scenarios::Scenario;
use firmware::controller::{AdaptationConfig, Controller, Fault};
use pam_core::{Coeffs, Params};
use std::cell::RefCell;
use std::rc::Rc;

/// How the muscle wears.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wear {
    /// Relative change of the stroke at full wear (−0.15: 15 % shorter).
    pub stroke: f64,
    /// Relative change of the friction (`F_c0` and `μ`) at full wear.
    pub friction: f64,
    /// Relative change of the rubber's stiffness at full wear.
    pub stiffness: f64,
    /// Time from the new muscle to full wear, s.
    pub duration_s: f64,
}

impl Wear {
    /// Stroke −15 %, friction +30 %, stiffness −10 % over an hour.
    pub const HOUR: Wear = Wear {
        stroke: -0.15,
        friction: 0.30,
        stiffness: -0.10,
        duration_s: 3600.0,
    };

    /// The muscle `base` at wear `fraction` (0: new, 1: fully worn;
    /// clamped).
    pub fn muscle(&self, base: &MuscleParams, fraction: f64) -> MuscleParams {
        let f = fraction.clamp(0.0, 1.0);
        // k: the static force balance at ε is the new muscle's at kε.
        let k = 1.0 / (1.0 + self.stroke * f);
        MuscleParams {
            end_factor: base.end_factor * k,
            slack_contraction: base.slack_contraction / k,
            stretch_stiffness_n: base.stretch_stiffness_n * k,
            rubber_stiffness_n: base.rubber_stiffness_n * k * (1.0 + self.stiffness * f),
            friction_base_n: base.friction_base_n * (1.0 + self.friction * f),
            friction_ratio: base.friction_ratio * (1.0 + self.friction * f),
            ..*base
        }
    }

    /// Wear fraction at time `t_s`.
    pub fn fraction_at(&self, t_s: f64) -> f64 {
        if self.duration_s > 0.0 {
            (t_s / self.duration_s).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }
}

/// One repetition's tracking error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Repetition {
    /// Start of the repetition, s.
    pub t_s: f64,
    /// Wear fraction at its end.
    pub wear: f64,
    /// RMS tracking error over it (each scenario's first 3 s left out).
    pub rms_error: f64,
    /// The adapted stroke scale at its end (1 without adaptation).
    pub stroke_scale: f32,
}

/// A long run on the wearing muscle.
#[derive(Clone, Debug, PartialEq)]
pub struct WornRun {
    /// Every repetition, the last one at full wear.
    pub repetitions: Vec<Repetition>,
    /// The first fault, with its time.
    pub first_fault: Option<(f64, Fault)>,
}

impl WornRun {
    /// The scored repetition's RMS error (the last, at full wear).
    pub fn final_rms(&self) -> f64 {
        self.repetitions.last().map_or(f64::NAN, |r| r.rms_error)
    }
}

/// The firmware's configuration for the worn runs: `cfg`'s paper-model
/// feedforward, with `adaptation` when given.
pub fn worn_config(
    cfg: &BenchConfig,
    adaptation: Option<AdaptationConfig>,
) -> firmware::controller::ControllerConfig {
    let mut c = controller_config(Mode::FeedforwardPi, cfg);
    c.adaptation = adaptation;
    c
}

/// Run `scenarios` again and again on `base` wearing by `wear`, with the
/// controller `ctl`, over the wear's duration and one repetition more at
/// full wear. `warmup_s` of each scenario is left out of its error.
pub fn run_worn(
    mut ctl: Controller,
    base: &MuscleParams,
    wear: &Wear,
    scenarios: &[Scenario],
    seed: u64,
    warmup_s: f64,
) -> WornRun {
    let repetition_s: f64 = scenarios.iter().map(|s| s.duration_s).sum();
    let count = if repetition_s > 0.0 {
        (wear.duration_s / repetition_s).ceil() as usize + 1
    } else {
        0
    };
    let load0 = scenarios.first().map_or(100.0, |s| s.load_at(0.0));
    let rig: SharedRig = Rc::new(RefCell::new(Rig::new(
        wear.muscle(base, 0.0),
        PneumaticParams::DEFAULT,
        load0,
        seed,
    )));
    let RigIo {
        mut io,
        inlet,
        exhaust,
        ..
    } = rig_io(&rig).expect("valve config");
    let dt = f64::from(ctl.config().dt_s);
    let mut t_total = 0.0;
    let mut repetitions = Vec::with_capacity(count);
    let mut first_fault = None;
    for _ in 0..count {
        let start = t_total;
        let (mut sum, mut n) = (0.0, 0usize);
        for sc in scenarios {
            let periods = (sc.duration_s / dt).round() as usize;
            for k in 0..periods {
                let t = k as f64 * dt;
                if k % 100 == 0 {
                    let m = wear.muscle(base, wear.fraction_at(t_total));
                    rig.borrow_mut().muscle.set_params(m);
                }
                rig.borrow_mut().set_load_n(sc.load_at(t));
                let reference = sc.reference_at(t);
                let step = ctl.step(&mut io, reference as f32);
                if first_fault.is_none() {
                    first_fault = step.new_fault.map(|f| (t_total, f));
                }
                let opening = valve_opening(ValveKind::PAIR, inlet.fraction(), exhaust.fraction());
                let mut r = rig.borrow_mut();
                if t >= warmup_s {
                    let e = r.true_state().contraction - reference;
                    sum += e * e;
                    n += 1;
                }
                r.opening = opening;
                r.advance(dt);
                t_total += dt;
            }
        }
        repetitions.push(Repetition {
            t_s: start,
            wear: wear.fraction_at(t_total),
            rms_error: (sum / n.max(1) as f64).sqrt(),
            stroke_scale: ctl.adaptation().map_or(1.0, |a| a.scale()),
        });
    }
    WornRun {
        repetitions,
        first_fault,
    }
}

/// `pam-lab fit`'s paper model (no static shape, as the flashed default
/// model) of the fully worn muscle, from its isotonic record
/// ([`IsotonicProtocol::WITH_FAST_CYCLE`]).
pub fn identify_worn(base: &MuscleParams, wear: &Wear, seed: u64) -> Result<Params, String> {
    let muscle = wear.muscle(base, 1.0);
    let sim = Rig::new(
        muscle,
        PneumaticParams::DEFAULT,
        IsotonicProtocol::WITH_FAST_CYCLE.loads_n[0],
        seed,
    );
    let samples = isotonic_run_on(sim, &IsotonicProtocol::WITH_FAST_CYCLE);
    let record = to_record(format!("worn muscle (seed {seed})"), &samples);
    let config = pam_lab::identify::fit::FitConfig {
        static_shape: false,
        ..Default::default()
    };
    let report = pam_lab::identify::fit::fit(&record, &config)
        .map_err(|e| format!("fit refused the worn muscle's record: {e}"))?;
    Coeffs::new(report.params)
        .map(|c| *c.params())
        .map_err(|e| format!("pam-core refused the fitted model: {e}"))
}

/// The three arms of the worn-muscle comparison, on one seed.
#[derive(Clone, Debug, PartialEq)]
pub struct WornComparison {
    /// Seed of the sensor noise (and of the random load steps).
    pub seed: u64,
    /// The flashed model, no adaptation.
    pub flashed: WornRun,
    /// The flashed model with the online adaptation.
    pub adapted: WornRun,
    /// RMS error of the freshly identified model on the fully worn muscle
    /// over the scored repetition, and its first fault.
    pub fresh_rms: f64,
    /// The fresh run's first fault.
    pub fresh_fault: Option<(f64, Fault)>,
}

/// Flashed, adapted and fresh on `scenarios` over `wear`, seed `cfg.seed`.
pub fn compare(
    cfg: &BenchConfig,
    wear: &Wear,
    scenarios: &[Scenario],
    adaptation: AdaptationConfig,
) -> Result<WornComparison, String> {
    let base = MuscleParams::DEFAULT;
    let load0 = scenarios.first().map_or(100.0, |s| s.load_at(0.0)) as f32;
    let controller = |params: Params, adaptation: Option<AdaptationConfig>| {
        let coeffs = Coeffs::new(params).map_err(|e| format!("parameters refused: {e}"))?;
        Controller::new(coeffs, worn_config(cfg, adaptation), load0)
            .map_err(|e| format!("controller refused: {e}"))
    };
    let flashed = run_worn(
        controller(cfg.params, None)?,
        &base,
        wear,
        scenarios,
        cfg.seed,
        cfg.warmup_s,
    );
    let adapted = run_worn(
        controller(cfg.params, Some(adaptation))?,
        &base,
        wear,
        scenarios,
        cfg.seed,
        cfg.warmup_s,
    );
    let fresh_params = identify_worn(&base, wear, cfg.seed)?;
    // The fresh model on the fully worn muscle: one repetition, no wear
    // left to come.
    let worn = wear.muscle(&base, 1.0);
    let fresh = run_worn(
        controller(fresh_params, None)?,
        &worn,
        &Wear {
            duration_s: 0.0,
            stroke: 0.0,
            friction: 0.0,
            stiffness: 0.0,
        },
        scenarios,
        cfg.seed,
        cfg.warmup_s,
    );
    Ok(WornComparison {
        seed: cfg.seed,
        flashed,
        adapted,
        fresh_rms: fresh.final_rms(),
        fresh_fault: fresh.first_fault,
    })
}

/// The comparison's table, Markdown: per seed, the scored repetition's
/// RMS error of each arm and the first fault.
pub fn table(comparisons: &[WornComparison]) -> String {
    let fault = |f: &Option<(f64, Fault)>| match f {
        Some((t, f)) => format!(" (safe state at {t:.0} s: {f:?})"),
        None => String::new(),
    };
    let mut s = String::from(
        "| seed | flashed model | flashed + adaptation (stroke scale) | fresh identification | adapted / fresh |\n|---|---|---|---|---|\n",
    );
    for c in comparisons {
        let a = c.adapted.final_rms();
        s.push_str(&format!(
            "| {} | {:.4}{} | {:.4}{} ({:.3}) | {:.4}{} | {:.2} |\n",
            c.seed,
            c.flashed.final_rms(),
            fault(&c.flashed.first_fault),
            a,
            fault(&c.adapted.first_fault),
            c.adapted.repetitions.last().map_or(1.0, |r| r.stroke_scale),
            c.fresh_rms,
            fault(&c.fresh_fault),
            a / c.fresh_rms
        ));
    }
    s
}

/// Every repetition of every comparison as CSV: seed, start time, wear,
/// the flashed and the adapted model's RMS error, the adapted scale.
pub fn trace_csv(comparisons: &[WornComparison]) -> String {
    let mut s = String::from("seed,t_s,wear,flashed_rms,adapted_rms,stroke_scale\n");
    for c in comparisons {
        for (f, a) in c.flashed.repetitions.iter().zip(&c.adapted.repetitions) {
            s.push_str(&format!(
                "{},{:.1},{:.3},{:.5},{:.5},{:.5}\n",
                c.seed, f.t_s, f.wear, f.rms_error, a.rms_error, a.stroke_scale
            ));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_worn_muscle_contracts_about_15_percent_less() {
        let base = MuscleParams::DEFAULT;
        let worn = Wear::HOUR.muscle(&base, 1.0);
        for (p, load) in [(0.3, 200.0), (0.4, 300.0), (0.5, 100.0)] {
            let ratio = worn.static_contraction(p, load) / base.static_contraction(p, load);
            assert!((0.8..0.92).contains(&ratio), "{p} MPa {load} N: {ratio}");
        }
        assert_eq!(Wear::HOUR.muscle(&base, 0.0), base);
        assert!((worn.friction_ratio / base.friction_ratio - 1.3).abs() < 1e-12);
        assert!((worn.rubber_stiffness_n / base.rubber_stiffness_n - 0.9 / 0.85).abs() < 1e-12);
    }
}

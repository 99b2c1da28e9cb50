//! The closed-loop check: a diagnosed model is written only if it does not
//! make the controller worse.
//!
//! The model diagnose writes is the firmware's feedforward, inverted every
//! period. Before it is written, the firmware's own controller
//! ([`firmware::scenario::track_on`]: `Controller` booted from the model's
//! blob as the image boots it, its safety monitor, the simulated valve pair
//! and sensors with noise) drives a simulated muscle that *is* that model
//! ([`MusclePlant::with_effects`]: pam-core's `Simulator` with the model's
//! effects as the equilibrium, the valves' chamber, a 30 ms mechanical lag)
//! over the middle [`SPAN_OF_STROKE`] of the model's stroke, along each
//! set-point of [`SETPOINTS`] (triangles at three paces, steps held), at
//! the lowest, middle and highest load of the model's range. The
//! controller booted from the model `pam-lab fit` writes for the record
//! drives the same muscle.
//!
//! On a muscle that is its own model, a model's controller is the one with
//! the exact inverse: where it goes to its safe state, or tracks worse
//! than fit's, the firmware cannot use that inverse (host-sim's rate rig: a
//! rate law fitted to slow ramps, whose loop widens many times over at the
//! pressure rate of a step). The diagnosed model is accepted when its
//! controller goes to its safe state in no run where fit's does not, and
//! the geometric mean over the runs of its RMS error over fit's is at most
//! 1; otherwise the model written is fit's, and the report says why. The
//! mean is over several set-points because one alone decides by its pace:
//! on a creep plant of the hidden set, the diagnosed controller's RMS was
//! 1.12–1.19× fit's on 2 s and 4 s triangles and 0.26–0.27× on 8 s ones.
//! The effects named stay named: they describe the record; the check
//! decides what the firmware gets.

use firmware::plant::{MusclePlant, PlantConfig};
use pam_core::{Coeffs, Effects, Params};

/// Share of the stroke the set-points span, centred.
pub const SPAN_OF_STROKE: f32 = 0.6;

/// A set-point of the check, over the span `[low, high]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Setpoint {
    /// `low → high → low` with this period, s; three periods run, the
    /// first (start-up from rest) not judged.
    Triangle(f32),
    /// Held steps to `low`, `high`, the middle and a quarter of the span,
    /// each held this long, s; twice through, the first step not judged.
    Steps(f32),
}

/// The set-points every load runs: the paper's Fig. 6 pace (4 s, the
/// self-test's), half and twice it, and steps held 2 s.
pub const SETPOINTS: [Setpoint; 4] = [
    Setpoint::Triangle(2.0),
    Setpoint::Triangle(4.0),
    Setpoint::Triangle(8.0),
    Setpoint::Steps(2.0),
];

impl Setpoint {
    /// `(run, not judged)`, s.
    fn duration_s(self) -> (f32, f32) {
        match self {
            Setpoint::Triangle(period_s) => (3.0 * period_s, period_s),
            Setpoint::Steps(hold_s) => (8.0 * hold_s, hold_s),
        }
    }

    /// The set-point at `t_s` over `[low, high]`.
    fn at(self, t_s: f32, low: f32, high: f32) -> f32 {
        match self {
            Setpoint::Triangle(period_s) => {
                firmware::exercise::triangle_over(t_s, period_s, low, high)
            }
            Setpoint::Steps(hold_s) => {
                const LEVELS: [f32; 4] = [0.0, 1.0, 0.5, 0.25];
                let k = (t_s / hold_s) as usize % LEVELS.len();
                low + (high - low) * LEVELS.get(k).copied().unwrap_or(0.0)
            }
        }
    }

    /// `"triangle 4 s"`, `"steps held 2 s"`.
    fn label(self) -> String {
        match self {
            Setpoint::Triangle(period_s) => format!("triangle {period_s} s"),
            Setpoint::Steps(hold_s) => format!("steps held {hold_s} s"),
        }
    }
}

/// One controller on the plant at one load.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LoopTracking {
    /// RMS of `|desired − actual|` after the part not judged, contraction.
    pub rms_error: f64,
    /// Largest of the same.
    pub max_error: f64,
    /// Faults the controller reported (each puts the valves safe).
    pub faults: u32,
    /// The first fault and when, `"Implausible(Model) at 0.35 s"`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_fault: Option<String>,
}

/// Both controllers on the plant at one load along one set-point.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LoopRun {
    /// Load, N.
    pub load_n: f64,
    /// The set-point ([`Setpoint`]).
    pub setpoint: String,
    /// The set-point's span, contraction.
    pub low: f64,
    /// See [`LoopRun::low`].
    pub high: f64,
    /// The diagnosed model's controller.
    pub diagnosed: LoopTracking,
    /// fit's model's controller.
    pub fit: LoopTracking,
}

/// The check's outcome.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ClosedLoopCheck {
    /// The diagnosed model checked: its parameters (what the report's
    /// `final_params` are when it is accepted).
    pub params: Params,
    /// Its effects.
    pub effects: Effects,
    /// One run per load judged and set-point.
    pub runs: Vec<LoopRun>,
    /// The geometric mean over the runs of the diagnosed controller's RMS
    /// error over fit's (1 without runs).
    pub diagnosed_over_fit: f64,
    /// The loads not judged, and why.
    pub skipped: Vec<String>,
    /// Whether the diagnosed model is written.
    pub accepted: bool,
    /// Why, in a sentence.
    pub verdict: String,
}

/// The check of the diagnosed model (`diagnosed`: its parameters and
/// effects) against fit's (`fit`), on a plant of the diagnosed model.
/// Never panics: a model the firmware or pam-core refuses is a refusal
/// with its reason.
pub fn check(diagnosed: (&Params, &Effects), fit: (&Params, &Effects)) -> ClosedLoopCheck {
    let (runs, skipped, accepted, verdict) = match runs(diagnosed, fit) {
        Ok((runs, skipped)) if runs.is_empty() => (
            runs,
            skipped,
            true,
            "not judged: no load of the model's range is one the controller reads as plausible \
             at rest"
                .to_string(),
        ),
        Ok((runs, skipped)) => {
            let (runs, accepted, verdict) = judge(runs);
            (runs, skipped, accepted, verdict)
        }
        Err(why) => (Vec::new(), Vec::new(), false, why),
    };
    ClosedLoopCheck {
        params: *diagnosed.0,
        effects: *diagnosed.1,
        diagnosed_over_fit: ratio(&runs),
        runs,
        skipped,
        accepted,
        verdict,
    }
}

/// The geometric mean over `runs` of the diagnosed controller's RMS error
/// over fit's (1 without runs; a run with no error on either side counts
/// as 1).
fn ratio(runs: &[LoopRun]) -> f64 {
    let logs: Vec<f64> = runs
        .iter()
        .map(|r| {
            let (d, f) = (r.diagnosed.rms_error, r.fit.rms_error);
            if d > 0.0 && f > 0.0 && (d / f).is_finite() {
                (d / f).ln()
            } else {
                0.0
            }
        })
        .collect();
    if logs.is_empty() {
        1.0
    } else {
        (logs.iter().sum::<f64>() / logs.len() as f64).exp()
    }
}

/// The verdict on the runs. The diagnosed model makes the controller
/// worse where its controller loses the muscle (an error that is not
/// finite) or goes to its safe state in a run where fit's does not, or
/// where its RMS error is larger than fit's in the geometric
/// mean over the runs ([`ratio`]; a run that went to its safe state counts
/// with its error: how long the valves stayed safe, how the loop came
/// back).
fn judge(runs: Vec<LoopRun>) -> (Vec<LoopRun>, bool, String) {
    let not_finite = runs.iter().find_map(|r| {
        let lost = !r.diagnosed.rms_error.is_finite() && r.fit.rms_error.is_finite();
        lost.then(|| {
            format!(
                "at {:.0} N, {}, the diagnosed model's controller lost the muscle (its error is \
                 not finite) and fit's did not",
                r.load_n, r.setpoint
            )
        })
    });
    let faulted = runs.iter().find_map(|r| {
        let f = r.diagnosed.first_fault.as_ref()?;
        r.fit.first_fault.is_none().then(|| {
            format!(
                "at {:.0} N, {}, the diagnosed model's controller went to its safe state on a \
                 muscle that is that model ({f}), and fit's did not",
                r.load_n, r.setpoint
            )
        })
    });
    let ratio = ratio(&runs);
    let refusal = not_finite.or(faulted).or_else(|| {
        (ratio > 1.0).then(|| {
            format!(
                "the diagnosed model's controller tracks a muscle that is that model worse than \
                 fit's ({ratio:.2}x fit's RMS error, geometric mean over {} runs)",
                runs.len()
            )
        })
    });
    let accepted = refusal.is_none();
    let verdict = refusal.unwrap_or_else(|| {
        format!(
            "the diagnosed model's controller tracks a muscle that is that model no worse than \
             fit's ({ratio:.2}x fit's RMS error, geometric mean over {} runs) and goes to its \
             safe state in no run where fit's does not",
            runs.len()
        )
    });
    (runs, accepted, verdict)
}

/// Both controllers at each load of the diagnosed model's range, run side
/// by side.
fn runs(
    diagnosed: (&Params, &Effects),
    fit: (&Params, &Effects),
) -> Result<(Vec<LoopRun>, Vec<String>), String> {
    let (params, effects) = diagnosed;
    let coeffs = Coeffs::new(*params).map_err(|e| format!("the diagnosed model: {e}"))?;
    let blob_of = |(p, e): (&Params, &Effects)| {
        let (bytes, len) = pam_core::blob::encode_model(p, e);
        bytes.get(..len).map(<[u8]>::to_vec).unwrap_or_default()
    };
    let blobs = [blob_of(diagnosed), blob_of(fit)];
    let (lo, hi) = (params.min_load_n, params.max_load_n);
    let mut skipped = Vec::new();
    let mut judged = Vec::new();
    for load_n in [lo, 0.5 * (lo + hi), hi] {
        match span_at_load(&coeffs, effects, load_n) {
            Ok(ends) => judged.push((load_n, ends)),
            Err(why) => skipped.push(why),
        }
    }
    let cases: Vec<Case> = judged
        .iter()
        .flat_map(|&(l, ends)| SETPOINTS.map(|sp| (l, ends, sp)))
        .collect();
    let jobs: Vec<(Case, usize)> = cases
        .iter()
        .flat_map(|&case| [(case, 0), (case, 1)])
        .collect();
    let done = super::parallel::map(&jobs, |&((load_n, ends, setpoint), which)| {
        track(&coeffs, effects, &blobs[which], load_n, ends, setpoint)
    });
    let runs = cases
        .iter()
        .zip(done.chunks(2))
        .map(|(&(load_n, (low, high), setpoint), pair)| match pair {
            [Ok(d), Ok(f)] => Ok(LoopRun {
                load_n: f64::from(load_n),
                setpoint: setpoint.label(),
                low: f64::from(low),
                high: f64::from(high),
                diagnosed: d.clone(),
                fit: f.clone(),
            }),
            [Err(e), _] => Err(format!("the diagnosed model at {load_n:.0} N: {e}")),
            [_, Err(e)] => Err(format!("fit's model at {load_n:.0} N: {e}")),
            _ => Err("a closed-loop run is missing".to_string()),
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok((runs, skipped))
}

/// One run's load (N), span (`low`, `high`, contraction) and set-point.
type Case = (f32, (f32, f32), Setpoint);

/// The set-points' span at `load_n`: the middle [`SPAN_OF_STROKE`] of the
/// model's stroke as its shape correction makes it, within the contraction
/// the controller's default configuration reads as plausible. A load
/// whose muscle at rest lies outside that contraction (an isometric
/// record's muscle held stretched under a large force) is not judged:
/// the controller goes to its safe state on its first reading, whatever
/// its model.
fn span_at_load(coeffs: &Coeffs, effects: &Effects, load_n: f32) -> Result<(f32, f32), String> {
    let model = coeffs.load_model(load_n).map_err(|e| e.to_string())?;
    let (mut root, mut max) = (model.root_contraction(), model.max_contraction());
    if let Some(shape) = &effects.shape {
        let at_load = shape.at_load(coeffs.params(), load_n);
        (root, max) = (at_load.apply(&model, root), at_load.apply(&model, max));
    }
    let margin = 0.5 * (1.0 - SPAN_OF_STROKE) * (max - root);
    let safety = firmware::controller::ControllerConfig::DEFAULT.safety;
    let (low, high) = (root + margin, (max - margin).min(safety.contraction_max));
    if root >= safety.contraction_min && high > low {
        Ok((low, high))
    } else {
        Err(format!(
            "{load_n:.0} N not judged: the muscle's stroke there ({root:.3} to {max:.3}) starts \
             outside the contraction the controller reads as plausible ({} to {})",
            safety.contraction_min, safety.contraction_max
        ))
    }
}

/// The controller booted from `blob` on a plant of `coeffs` with `effects`
/// at `load_n`, along `setpoint` between `low` and `high`.
fn track(
    coeffs: &Coeffs,
    effects: &Effects,
    blob: &[u8],
    load_n: f32,
    (low, high): (f32, f32),
    setpoint: Setpoint,
) -> Result<LoopTracking, String> {
    // The supply reaches the model's `Pmax` with room for the loop.
    let config = PlantConfig {
        supply_mpa: PlantConfig::DEFAULT
            .supply_mpa
            .max(1.2 * coeffs.params().points.max_pressure_mpa),
        ..PlantConfig::DEFAULT
    };
    let plant =
        MusclePlant::with_effects(*coeffs, *effects, load_n, config).map_err(|e| e.to_string())?;
    let dt_s = firmware::controller::ControllerConfig::DEFAULT.dt_s;
    let (run_s, unjudged_s) = setpoint.duration_s();
    let steps = (run_s / dt_s + 0.5) as u32;
    let eval_from = (unjudged_s / dt_s + 0.5) as u32;
    let desired = |t_s: f32| setpoint.at(t_s, low, high);
    let t = firmware::scenario::track_on(blob, plant, load_n, desired, steps, eval_from)
        .map_err(|e| format!("the firmware refuses it: {e}"))?;
    Ok(LoopTracking {
        rms_error: f64::from(t.rms_error),
        max_error: f64::from(t.max_error),
        faults: t.faults,
        first_fault: t
            .first_fault
            .map(|(k, f)| format!("{f:?} at {:.2} s", k as f32 * dt_s)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tracking(rms: f64, fault: Option<&str>) -> LoopTracking {
        LoopTracking {
            rms_error: rms,
            max_error: 2.0 * rms,
            faults: u32::from(fault.is_some()),
            first_fault: fault.map(str::to_string),
        }
    }

    fn run(load_n: f64, diagnosed: LoopTracking, fit: LoopTracking) -> LoopRun {
        LoopRun {
            load_n,
            setpoint: Setpoint::Triangle(4.0).label(),
            low: 0.05,
            high: 0.15,
            diagnosed,
            fit,
        }
    }

    #[test]
    fn a_fault_or_worse_tracking_at_any_load_refuses_the_model() {
        let good = || run(100.0, tracking(0.001, None), tracking(0.002, None));
        assert!(judge(vec![good(), good()]).1);
        let fault = Some("Implausible(Model) at 0.35 s");
        let faulted = run(350.0, tracking(0.001, fault), tracking(0.002, None));
        let (_, accepted, verdict) = judge(vec![good(), faulted]);
        assert!(!accepted);
        assert!(
            verdict.contains("at 350 N") && verdict.contains("Implausible(Model)"),
            "{verdict}"
        );
        // Both controllers go to their safe state there: the errors decide.
        let both = run(350.0, tracking(0.001, fault), tracking(0.002, fault));
        assert!(judge(vec![good(), both]).1);
        // Worse in one run, better in the geometric mean: accepted; worse
        // in the mean: refused.
        let worse = run(600.0, tracking(0.003, None), tracking(0.002, None));
        assert!(judge(vec![good(), worse]).1);
        let worse = run(600.0, tracking(0.0045, None), tracking(0.002, None));
        let (_, accepted, verdict) = judge(vec![good(), worse]);
        assert!(!accepted);
        assert!(verdict.contains("worse than fit's"), "{verdict}");
        let lost = run(600.0, tracking(f64::NAN, None), tracking(0.002, None));
        let (_, accepted, verdict) = judge(vec![good(), lost]);
        assert!(!accepted);
        assert!(verdict.contains("not finite"), "{verdict}");
    }

    #[test]
    fn the_setpoints_span_low_to_high() {
        let (low, high) = (0.05, 0.15);
        let tri = Setpoint::Triangle(4.0);
        assert!((tri.at(0.0, low, high) - low).abs() < 1e-6);
        assert!((tri.at(2.0, low, high) - high).abs() < 1e-6);
        assert!((tri.at(5.0, low, high) - 0.1).abs() < 1e-6);
        let steps = Setpoint::Steps(2.0);
        let held: Vec<f32> = [1.0, 3.0, 5.0, 7.0, 9.0]
            .iter()
            .map(|&t| steps.at(t, low, high))
            .collect();
        for (got, want) in held.iter().zip([0.05, 0.15, 0.1, 0.075, 0.05]) {
            assert!((got - want).abs() < 1e-6, "{held:?}");
        }
        assert_eq!(tri.duration_s(), (12.0, 4.0));
        assert_eq!(steps.duration_s(), (16.0, 2.0));
    }

    #[test]
    fn the_same_model_passes_its_own_rate_law_never_trips_and_worse_tracking_is_refused() {
        let params = Params::DEFAULT;
        let none = Effects::NONE;
        let same = check((&params, &none), (&params, &none));
        assert!(same.accepted, "{same:?}");
        assert_eq!(same.runs.len(), 3 * SETPOINTS.len());
        assert_eq!(same.diagnosed_over_fit, 1.0);
        for r in &same.runs {
            assert_eq!(r.diagnosed, r.fit);
            assert_eq!(r.diagnosed.faults, 0, "{r:?}");
        }
        let law = |scale_at_rest, scale_per_mpa_per_s, filter_time_s, max_rate_mpa_per_s| Effects {
            rate: Some(pam_core::effects::RateDependence {
                scale_at_rest,
                scale_per_mpa_per_s,
                exponent: 1.0,
                filter_time_s,
                max_rate_mpa_per_s,
            }),
            ..Effects::NONE
        };
        // A rate law fitted to slow ramps (host-sim's rate rig: the loop
        // 0.34 of the paper's at rest, growing 12 per MPa/s, a 0.7 s
        // filter): on a step held, the pressure the muscle sees moves while
        // the desired motion rests, and its loop is that pressure's rate's.
        // The model check judged it by the feedforward's rate alone, and
        // its own controller went to its safe state on a muscle that is
        // that model (firmware test
        // `a_muscle_that_is_its_own_rate_model_passes_the_model_check`).
        let rig = check((&params, &law(0.34, 12.0, 0.7, 3.6)), (&params, &none));
        for r in &rig.runs {
            assert_eq!(r.diagnosed.faults, 0, "{r:?}");
        }
        assert!(rig.accepted, "{rig:?}");
        // A fast law (no narrower at rest, a 50 ms filter): its exact
        // inverse tracks its own muscle worse than the paper's feedforward
        // does (1.02x in the geometric mean), and is refused.
        let fast = check((&params, &law(1.0, 3.0, 0.05, 1.0)), (&params, &none));
        assert!(!fast.accepted, "{fast:?}");
        assert!(
            fast.verdict.contains("worse than fit's"),
            "{}",
            fast.verdict
        );
    }
}

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
//! along a triangle over the middle [`SPAN_OF_STROKE`] of the model's
//! stroke ([`PERIOD_S`], [`CYCLES`] cycles, judged after the first), at the
//! lowest, middle and highest load of the model's range. The controller
//! booted from the model `pam-lab fit` writes for the record drives the
//! same muscle.
//!
//! On a muscle that is its own model, a model's controller is the one with
//! the exact inverse: where it goes to its safe state, or tracks worse
//! than fit's, the firmware cannot use that inverse (host-sim's rate rig: a
//! rate law fitted to slow ramps, whose loop widens many times over at the
//! pressure rate of a step). The diagnosed model is accepted when its
//! controller goes to its safe state at no load where fit's does not, and
//! its RMS error over the loads is no larger than fit's controller's;
//! otherwise the model written is fit's, and the report says why. The
//! effects named stay named: they describe the record; the check decides
//! what the firmware gets.

use firmware::plant::{MusclePlant, PlantConfig};
use pam_core::{Coeffs, Effects, Params};

/// Share of the stroke the triangle spans, centred.
pub const SPAN_OF_STROKE: f32 = 0.6;
/// Period of the triangle, s (the paper's Fig. 6 pace, the self-test's).
pub const PERIOD_S: f32 = 4.0;
/// Cycles run; the first (start-up from rest) is not judged.
pub const CYCLES: u32 = 3;

/// One controller on the plant at one load.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LoopTracking {
    /// RMS of `|desired − actual|` after the first cycle, contraction.
    pub rms_error: f64,
    /// Largest of the same.
    pub max_error: f64,
    /// Faults the controller reported (each puts the valves safe).
    pub faults: u32,
    /// The first fault and when, `"Implausible(Model) at 0.35 s"`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_fault: Option<String>,
}

/// Both controllers on the plant at one load.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LoopRun {
    /// Load, N.
    pub load_n: f64,
    /// The triangle's ends, contraction.
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
    /// One run per load judged.
    pub runs: Vec<LoopRun>,
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
        runs,
        skipped,
        accepted,
        verdict,
    }
}

/// The verdict on the runs. The diagnosed model makes the controller
/// worse where, at some load, its controller goes to its safe state and
/// fit's does not, or where its RMS error over every load's run is larger
/// than fit's (a run that went to its safe state counts with its error:
/// how long the valves stayed safe, how the loop came back).
fn judge(runs: Vec<LoopRun>) -> (Vec<LoopRun>, bool, String) {
    let faulted = runs.iter().find_map(|r| {
        let f = r.diagnosed.first_fault.as_ref()?;
        r.fit.first_fault.is_none().then(|| {
            format!(
                "at {:.0} N the diagnosed model's controller went to its safe state on a muscle \
                 that is that model ({f}), and fit's did not",
                r.load_n
            )
        })
    });
    let rms = |f: fn(&LoopRun) -> f64| {
        (runs.iter().map(|r| f(r).powi(2)).sum::<f64>() / runs.len().max(1) as f64).sqrt()
    };
    let (diagnosed, fit) = (rms(|r| r.diagnosed.rms_error), rms(|r| r.fit.rms_error));
    let worse = diagnosed > fit;
    let refusal = faulted.or_else(|| {
        worse.then(|| {
            format!(
                "the diagnosed model's controller tracks a muscle that is that model worse than \
                 fit's (RMS over the loads {diagnosed:.5} against {fit:.5})"
            )
        })
    });
    let accepted = refusal.is_none();
    let verdict = refusal.unwrap_or_else(|| {
        format!(
            "the diagnosed model's controller tracks a muscle that is that model no worse than \
             fit's (RMS over the loads {diagnosed:.5} against {fit:.5}) and goes to its safe \
             state at no load where fit's does not"
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
        match triangle_ends(&coeffs, effects, load_n) {
            Ok(ends) => judged.push((load_n, ends)),
            Err(why) => skipped.push(why),
        }
    }
    let jobs: Vec<(f32, (f32, f32), usize)> = judged
        .iter()
        .flat_map(|&(l, ends)| [(l, ends, 0), (l, ends, 1)])
        .collect();
    let done = super::parallel::map(&jobs, |&(load_n, ends, which)| {
        track(&coeffs, effects, &blobs[which], load_n, ends)
    });
    let runs = judged
        .iter()
        .zip(done.chunks(2))
        .map(|(&(load_n, (low, high)), pair)| match pair {
            [Ok(d), Ok(f)] => Ok(LoopRun {
                load_n: f64::from(load_n),
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

/// The triangle's ends at `load_n`: the middle [`SPAN_OF_STROKE`] of the
/// model's stroke as its shape correction makes it, within the contraction
/// the controller's default configuration reads as plausible. A load
/// whose muscle at rest lies outside that contraction (an isometric
/// record's muscle held stretched under a large force) is not judged:
/// the controller goes to its safe state on its first reading, whatever
/// its model.
fn triangle_ends(coeffs: &Coeffs, effects: &Effects, load_n: f32) -> Result<(f32, f32), String> {
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
/// at `load_n`, along the triangle between `low` and `high`.
fn track(
    coeffs: &Coeffs,
    effects: &Effects,
    blob: &[u8],
    load_n: f32,
    (low, high): (f32, f32),
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
    let steps = (CYCLES as f32 * PERIOD_S / dt_s + 0.5) as u32;
    let desired = |t_s: f32| {
        let phase = t_s / PERIOD_S;
        let frac = phase - phase.floor();
        let up = if frac < 0.5 {
            2.0 * frac
        } else {
            2.0 - 2.0 * frac
        };
        low + (high - low) * up
    };
    let t = firmware::scenario::track_on(blob, plant, load_n, desired, steps, steps / CYCLES)
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
        // Worse at one load, better overall: accepted; worse overall: refused.
        let worse = run(600.0, tracking(0.0025, None), tracking(0.002, None));
        assert!(judge(vec![good(), worse]).1);
        let worse = run(600.0, tracking(0.004, None), tracking(0.002, None));
        let (_, accepted, verdict) = judge(vec![good(), worse]);
        assert!(!accepted);
        assert!(verdict.contains("worse than fit's"), "{verdict}");
    }

    #[test]
    fn the_same_model_passes_and_a_broken_inverse_is_refused() {
        let params = Params::DEFAULT;
        let none = Effects::NONE;
        let same = check((&params, &none), (&params, &none));
        assert!(same.accepted, "{same:?}");
        assert_eq!(same.runs.len(), 3);
        for r in &same.runs {
            assert_eq!(r.diagnosed, r.fit);
            assert_eq!(r.diagnosed.faults, 0, "{r:?}");
        }
        // A rate law fitted to slow ramps (host-sim's rate rig: the loop
        // 0.34 of the paper's at rest, growing 12 per MPa/s, a 0.7 s
        // filter): a step's pressure rate widens its loop many times over,
        // and its own controller trips the model check on a muscle that is
        // that model.
        let rate = Effects {
            rate: Some(pam_core::effects::RateDependence {
                scale_at_rest: 0.34,
                scale_per_mpa_per_s: 12.0,
                exponent: 1.0,
                filter_time_s: 0.7,
                max_rate_mpa_per_s: 3.6,
            }),
            ..Effects::NONE
        };
        let refused = check((&params, &rate), (&params, &none));
        println!("{refused:#?}");
        assert!(!refused.accepted, "{refused:?}");
    }
}

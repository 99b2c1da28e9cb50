//! What a diagnosed model leaves open, told with its report.

use pam_core::Effects;

use super::config::DiagnoseConfig;
use super::regimes::Regimes;
use super::report::Round;
use crate::record::Sample;

/// Least time the training part must hold the pressure after a step for a
/// rate law's factor at rest to be the record's, not an extrapolation, s.
pub const MIN_TRAINING_HOLD_S: f64 = 1.0;

/// How long the training part (`heldout` false) holds the pressure after
/// a step, s: each such sample's interval, at most 1 s, summed.
pub fn training_hold_s(paced: &Regimes, samples: &[Sample], heldout: &[bool]) -> f64 {
    samples
        .windows(2)
        .zip(paced.hold_after_step.iter().zip(heldout))
        .filter(|(_, (hold, out))| **hold && !**out)
        .map(|(w, _)| (w[1].t_s - w[0].t_s).clamp(0.0, 1.0))
        .fold(0.0, |a, b| a + b)
}

/// What a record leaves open about `effects`, the model written (a rate
/// law the closed-loop check refused is not in it), one sentence each.
///
/// A rate law fitted on a record whose training part holds the pressure
/// after a step for under [`MIN_TRAINING_HOLD_S`] has its factor at rest
/// from the ramps alone: nothing it was fitted on shows the loop while the
/// pressure stands still, which is where a position loop's set-point
/// spends its time. The diagnosis then holds the law linear
/// ([`super::RATE_EXPONENT_WITHOUT_REST`]), so its factor at
/// rest is what the slowest ramps show; the warning stays.
pub fn model_warnings(
    effects: &Effects,
    paced: &Regimes,
    samples: &[Sample],
    heldout: &[bool],
) -> Vec<String> {
    let mut warnings = Vec::new();
    if let Some(rate) = &effects.rate {
        let held_s = training_hold_s(paced, samples, heldout);
        if held_s < MIN_TRAINING_HOLD_S {
            warnings.push(format!(
                "the rate law's factor at rest ({:.2}) is an extrapolation from its slowest ramps (the law held linear): the record's training part holds the pressure after a step for {held_s:.1} s, so nothing the law was fitted on shows the loop while the pressure stands still; record a few steps with holds of several seconds (pam-lab/DIAGNOSE.md, \"What is still not handled\") before using this model as a feedforward",
                rate.scale_at_rest
            ));
        }
    }
    warnings
}

/// What the record would need to show each effect's own regime.
fn regime_protocol(regime: &str) -> &'static str {
    match regime {
        "hold_after_step" => "steps of the pressure held for several seconds",
        "fast_ramp" => "ramps of the pressure several times faster than the rest",
        "after_inner_reversal" => "reversals inside the loop",
        _ => "more of the protocol",
    }
}

/// The effects the record cannot judge: in some round a candidate cut the
/// held-out error and the BIC by the evidence rule's margins but no
/// held-out sample lies in its own regime (a record of ramps alone has no
/// hold after a step for creep), so it was not added. One sentence per
/// effect, its largest cut, and what to record.
pub fn unjudged_warnings(rounds: &[Round], cfg: &DiagnoseConfig) -> Vec<String> {
    let mut found: Vec<(&'static str, &'static str, f64)> = Vec::new();
    for c in rounds.iter().flat_map(|r| &r.candidates) {
        let judged = c.signature.cut().is_finite();
        let earns_overall = c.improvement >= cfg.min_improvement && c.bic_drop >= cfg.min_bic_drop;
        if c.earned || judged || !earns_overall {
            continue;
        }
        match found.iter_mut().find(|(n, _, _)| *n == c.name) {
            Some(f) => f.2 = f.2.max(c.improvement),
            None => found.push((c.name, c.signature.regime, c.improvement)),
        }
    }
    found
        .into_iter()
        .map(|(name, regime, cut)| {
            format!(
                "{name} cuts up to {:.1} % of the held-out error, but none of the held-out samples lies in its own regime ({regime}), so the record cannot tell it from the effects named: record {} to judge it",
                100.0 * cut,
                regime_protocol(regime)
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use pam_core::effects::RateDependence;

    fn paced(holds: &[bool]) -> Regimes {
        Regimes {
            after_inner_reversal: vec![false; holds.len()],
            fast_ramp: vec![false; holds.len()],
            pressure_moving: vec![false; holds.len()],
            slow_ramp: vec![false; holds.len()],
            hold_after_step: holds.to_vec(),
            max_ramp_rate_mpa_per_s: 0.2,
        }
    }

    #[test]
    fn a_rate_law_from_a_record_without_holds_is_flagged() {
        let with_rate = Effects {
            rate: Some(RateDependence::linear(0.0, 9.0)),
            ..Effects::NONE
        };
        // 50 Hz, 200 samples.
        let samples: Vec<Sample> = (0..200)
            .map(|i| Sample {
                t_s: i as f64 * 0.02,
                load_n: 100.0,
                pressure_mpa: 0.1,
                contraction: 0.1,
            })
            .collect();
        let (none, all) = (vec![false; 200], vec![true; 200]);
        let flagged = model_warnings(&with_rate, &paced(&none), &samples, &none);
        assert_eq!(flagged.len(), 1);
        assert!(
            flagged[0].contains("holds the pressure after a step for 0.0 s"),
            "{flagged:?}"
        );
        // A 2 s hold in training shows the loop at rest: nothing to flag.
        let holds: Vec<bool> = (0..200).map(|i| (50..150).contains(&i)).collect();
        assert!(model_warnings(&with_rate, &paced(&holds), &samples, &none).is_empty());
        // The same hold held out, or a single sample of one, does not.
        assert_eq!(
            model_warnings(&with_rate, &paced(&holds), &samples, &all).len(),
            1
        );
        let mut one = vec![false; 200];
        one[60] = true;
        assert_eq!(
            model_warnings(&with_rate, &paced(&one), &samples, &none).len(),
            1
        );
        // Without a rate law the holds do not matter.
        assert!(model_warnings(&Effects::NONE, &paced(&none), &samples, &none).is_empty());
    }

    fn candidate(
        name: &'static str,
        cut: f64,
        bic: f64,
        regime_after: f64,
    ) -> super::super::candidates::CandidateResult {
        use super::super::candidates::{CandidateResult, Signature};
        use super::super::evaluate::ModelErrors;
        let params = pam_core::Params::DEFAULT;
        CandidateResult {
            name,
            rms: 1.0 - cut,
            improvement: cut,
            bic_drop: bic,
            parameters: 2,
            earned: false,
            verdict: String::new(),
            variants: None,
            signature: Signature {
                regime: "hold_after_step",
                rms_before: if regime_after.is_nan() { f64::NAN } else { 1.0 },
                rms_after: regime_after,
            },
            effects: Effects::NONE,
            errors: ModelErrors {
                rms_heldout: 1.0 - cut,
                rms_train: 1.0,
                bic: 0.0,
                regimes: Vec::new(),
                loads: Vec::new(),
                static_shape: 0.0,
            },
            base_params: params,
            coeffs: pam_core::Coeffs::new(params).expect("the paper's defaults"),
        }
    }

    #[test]
    fn an_effect_whose_regime_is_not_held_out_is_named_with_what_to_record() {
        let cfg = DiagnoseConfig::default();
        let round = |candidates| Round {
            rms_start: 1.0,
            candidates,
            added: None,
        };
        // Creep cuts 18 % and the BIC, but no hold after a step is held
        // out: told, once, with its largest cut.
        let rounds = [
            round(vec![candidate("creep", 0.18, 50.0, f64::NAN)]),
            round(vec![candidate("creep", 0.24, 80.0, f64::NAN)]),
        ];
        let w = unjudged_warnings(&rounds, &cfg);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].starts_with("creep cuts up to 24.0 %"), "{w:?}");
        assert!(w[0].contains("steps of the pressure held"), "{w:?}");
        // Judged in its regime, or under the margins: nothing to tell.
        for c in [
            candidate("creep", 0.18, 50.0, 0.9),
            candidate("creep", 0.10, 50.0, f64::NAN),
            candidate("creep", 0.18, 5.0, f64::NAN),
        ] {
            assert!(unjudged_warnings(&[round(vec![c])], &cfg).is_empty());
        }
    }
}

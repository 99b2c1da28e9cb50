//! What a diagnosed model leaves open, told with its report.

use pam_core::Effects;

use super::regimes::Regimes;
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

/// What a record leaves open about `effects`, one sentence each.
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
}

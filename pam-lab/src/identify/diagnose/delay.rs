//! The pressure delay's estimate: how much later the force and length
//! answer the measured pressure, read from the data before any model.
//!
//! A static surface fitted to the training samples with each pressure
//! taken `d` earlier ([`crate::evaluate::retime`]) fits best at the delay
//! the record has. The surface is the reference's
//! ([`crate::identify::reference::ReferenceSurface`], 30 coefficients)
//! with a second surface beside it that changes sign with the branch: on a
//! ramp of constant rate a delay and a hysteresis both put the fill above
//! the vent, and without the branch's surface the delay would stand in
//! for the loop a friction makes (this module's test record with a 15 N
//! friction and no delay: the surface alone fits better at every delay up
//! to 11 ms and beyond). A delay is what is left: a
//! loop that grows with the pressure's rate and closes where the pressure
//! holds. The surfaces follow any static curve and any rate-independent
//! loop, so the estimate does not depend on the model it is added to. The
//! `pressure_delay` candidate is then fit's static model refitted on the
//! record so retimed, with that delay.
//!
//! On the public Festo 10 mm records (tests 8 and 9, diagnose's training
//! part) the surfaces' training RMS falls from 12.2 to 9.0 kPa at 12 ms
//! (10 cm) and from 9.5 to 5.7 kPa at 18 ms (40 cm), one clear minimum
//! each.

use crate::evaluate::errors::median_step_s;
use crate::evaluate::retime::with_delayed_pressure;
use crate::identify::reference::ReferenceSurface;
use crate::record::Sample;
use pam_core::effects::PressureDelay;
use pam_core::{Coeffs, Effects};

use super::evaluate::{Setup, Variant};

/// The most training samples the surface is fitted to at each delay tried
/// (a longer record is thinned evenly): the delay is one number, and each
/// try is a least-squares fit.
const MAX_SAMPLES: usize = 20_000;

/// Coarse steps of the search per fine step.
const COARSE: usize = 4;

/// The delay, s, at which the reference surface and its branch's surface
/// ([`ReferenceSurface::training_rms_with_branch_mpa`]) fitted to the
/// samples `include` selects, each with the pressure measured that much
/// earlier, have their lowest RMS, with that RMS and the RMS without a
/// delay (MPa). `branch_of` gives the branches of the samples as moved (+1
/// filling, −1 venting, 0 on neither: left out), the branch of the pressure
/// the muscle answers;
/// searched over `[0, PressureDelay::MAX_DELAY_S]` in steps of the
/// record's median sampling interval (within `[0.5, 5]` ms), coarse then
/// fine around the coarse minimum. `None` when the surface cannot be
/// fitted.
pub fn estimate_delay_s(
    samples: &[Sample],
    branch_of: impl Fn(&[Sample]) -> Vec<f64>,
    include: impl Fn(usize) -> bool,
) -> Option<DelayEstimate> {
    let dt = median_step_s(samples);
    if !(dt.is_finite() && dt > 0.0) {
        return None;
    }
    let step = dt.clamp(0.0005, 0.005);
    let max_steps = (f64::from(PressureDelay::MAX_DELAY_S) / step).floor() as usize;
    let chosen: Vec<usize> = (0..samples.len()).filter(|&i| include(i)).collect();
    let thin = chosen.len().div_ceil(MAX_SAMPLES).max(1);
    let mut used = vec![false; samples.len()];
    for &i in chosen.iter().step_by(thin) {
        used[i] = true;
    }
    let rms_at = |k: usize| -> f64 {
        let moved = with_delayed_pressure(samples, k as f64 * step);
        let branch = branch_of(&moved);
        ReferenceSurface::training_rms_with_branch_mpa(&moved, &branch, |i| {
            used[i] && branch[i] != 0.0
        })
        .unwrap_or(f64::INFINITY)
    };
    let at_zero = rms_at(0);
    if !at_zero.is_finite() {
        return None;
    }
    let mut best = (0usize, at_zero);
    for k in (COARSE..=max_steps).step_by(COARSE) {
        let r = rms_at(k);
        if r < best.1 {
            best = (k, r);
        }
    }
    let (lo, hi) = (
        best.0.saturating_sub(COARSE - 1),
        (best.0 + COARSE - 1).min(max_steps),
    );
    for k in lo..=hi {
        if k % COARSE != 0 {
            let r = rms_at(k);
            if r < best.1 {
                best = (k, r);
            }
        }
    }
    Some(DelayEstimate {
        delay_s: best.0 as f64 * step,
        rms_mpa: best.1,
        rms_without_mpa: at_zero,
        step_s: step,
    })
}

/// What [`estimate_delay_s`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DelayEstimate {
    /// The delay, s (0: none).
    pub delay_s: f64,
    /// The surface's training RMS there, MPa.
    pub rms_mpa: f64,
    /// Its training RMS without a delay, MPa.
    pub rms_without_mpa: f64,
    /// The search's step, s.
    pub step_s: f64,
}

impl DelayEstimate {
    /// The delay as pam-core's effect, where it is within its range.
    pub fn effect(&self) -> Option<PressureDelay> {
        let d = PressureDelay {
            delay_s: self.delay_s as f32,
        };
        d.validate().is_ok().then_some(d)
    }

    /// The delay and its neighbours a step either side, those within
    /// pam-core's range.
    pub fn neighbourhood(&self) -> Vec<PressureDelay> {
        [-1.0, 0.0, 1.0]
            .iter()
            .map(|k| PressureDelay {
                delay_s: (self.delay_s + k * self.step_s) as f32,
            })
            .filter(|d| self.effect().is_some() && d.validate().is_ok())
            .collect()
    }
}

/// The pressure delay's variant: the delay estimated from the data
/// (`delay.rs`) and fit's static model refitted on the training part so
/// retimed ([`Setup::delayed_static`]), in place of the current static
/// model, with the current dynamic effects. One parameter added: the
/// static model's own are the same number as the current one's.
pub(super) fn variant(
    setup: &Setup<'_>,
    current: Effects,
    current_params: usize,
) -> Option<Variant> {
    let d = setup.delayed_static.as_ref()?;
    let coeffs = Coeffs::new(d.params).ok()?;
    let effects = Effects {
        shape: Some(d.shape),
        pressure_delay: Some(d.delay),
        ..current
    };
    effects.validate().ok()?;
    let n_params = current_params + 1;
    let (errors, res) = setup.errors(&coeffs, effects, n_params);
    Some((d.params, coeffs, effects, errors, res, 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An isometric-like record: pressure sweeps at four held lengths, the
    /// force a smooth function of length and the pressure `delay_s`
    /// earlier, less a friction of `friction_n` against the motion,
    /// sampled at 1 kHz; with each sample's branch.
    fn record(delay_s: f64, friction_n: f64) -> (Vec<Sample>, Vec<f64>) {
        let mut out = Vec::new();
        let mut branch = Vec::new();
        let tau = std::f64::consts::TAU;
        let p_at = |t: f64| 0.3 * (1.0 - (tau * t / 4.0).cos());
        for (h, x) in [0.0, 0.04, 0.08, 0.12].iter().enumerate() {
            for k in 0..8000 {
                let tl = k as f64 * 0.001;
                let rising = (tau * tl / 4.0).sin() >= 0.0;
                let pm = p_at((tl - delay_s).max(0.0));
                let sign = if rising { 1.0 } else { -1.0 };
                let force = (900.0 * pm * (1.0 - 4.0 * x) - 300.0 * x).max(0.0) + 40.0 * pm * pm
                    - sign * friction_n;
                out.push(Sample {
                    t_s: h as f64 * 8.0 + tl,
                    load_n: force,
                    pressure_mpa: p_at(tl),
                    contraction: *x,
                });
                branch.push(sign);
            }
        }
        (out, branch)
    }

    #[test]
    fn the_delay_a_record_has_is_found_and_a_loop_is_not_taken_for_one() {
        for d in [0.004, 0.009, 0.02] {
            for friction in [0.0, 15.0] {
                let (s, b) = record(d, friction);
                let e = estimate_delay_s(&s, |_| b.clone(), |i| s[i].load_n > 20.0).unwrap();
                assert!((e.delay_s - d).abs() <= 0.0006, "{d} {friction}: {e:?}");
                assert!(e.rms_mpa < 0.5 * e.rms_without_mpa, "{d}: {e:?}");
            }
        }
        // A friction loop and no delay: no delay (the surface without the
        // branch's read one).
        let (s, b) = record(0.0, 15.0);
        let e = estimate_delay_s(&s, |_| b.clone(), |i| s[i].load_n > 20.0).unwrap();
        assert!(e.delay_s <= 0.0005, "{e:?}");
    }
}

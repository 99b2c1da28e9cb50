//! How a record is prepared for the simulation the diagnosis compares it
//! with: its pressure denoised, the tracker's settings, the inverse tables,
//! the branches it is simulated on and the channel its segments are cut at.

use pam_core::{Coeffs, TrackerConfig};

use super::regimes::hindsight_branches;
use crate::record::Sample;

/// `samples` with the pressure through [`crate::record::split::running_median`] of
/// `2·half + 1` samples.
pub fn denoise_pressure(samples: &[Sample], half: usize) -> Vec<Sample> {
    let p: Vec<f64> = samples.iter().map(|s| s.pressure_mpa).collect();
    samples
        .iter()
        .zip(crate::record::split::running_median(&p, half))
        .map(|(s, pm)| Sample {
            pressure_mpa: pm,
            ..*s
        })
        .collect()
}

/// Tracker settings for the denoised pressure of a record whose raw
/// pressure noise is `noise_mpa` and load noise `load_noise_n`: a deadband
/// of three raw sigmas (the median leaves about 0.4 of the noise, so its
/// peak-to-peak stays inside), at least 0.002 MPa. A wider band delays every
/// reversal, which where the curve is flat costs more than the noise it
/// rejects.
///
/// The controller debounces a load change over several samples because its
/// load cell is noisy; a record whose load column is clean (the rig's set
/// load, held then stepped: noise below 1 N) switches the load model on the
/// first sample of a step, as the muscle does. Otherwise every load step
/// would leave a few samples on the old load's curve, a residual spike that
/// no effect explains.
///
/// An isometric record's load is the measured force, which moves with the
/// pressure on every sample: the load model follows it
/// ([`crate::evaluate::simulate::following_the_force`]).
pub(super) fn tracker_config(noise_mpa: f64, load_noise_n: f64, isometric: bool) -> TrackerConfig {
    let mut cfg = TrackerConfig::DEFAULT_PRESSURE;
    cfg.direction_deadband = (3.0 * noise_mpa).max(0.002) as f32;
    if load_noise_n < 1.0 {
        cfg.load_debounce_samples = 1;
    }
    if isometric {
        cfg = crate::evaluate::simulate::following_the_force(cfg, load_noise_n);
    }
    cfg
}

/// Inverse tables at each load switch (as the firmware), except on an
/// isometric record: its force switches the load model every few samples,
/// and a table per switch was 80 % of a diagnosis' time there.
pub(super) fn inverse_tables(isometric: bool) -> crate::evaluate::simulate::InverseTables {
    if isometric {
        crate::evaluate::simulate::InverseTables::Never
    } else {
        crate::evaluate::simulate::InverseTables::AtEachSwitch
    }
}

/// The branch of every sample from the sweep split `fit` labels its
/// samples with ([`crate::record::split::split_branches`]; an unlabelled
/// sample keeps the branch before it, the first ones the contraction
/// branch): an isometric record's branches. A logger's valve fills in
/// pulses (the Festo rig every 0.5 s), and the pressure rings by ±10 kPa
/// after each; every ring is a reversal to [`hindsight_branches`]' deadband
/// and a jump of the paper's model between its branches in the middle of
/// a fill. The sweep split follows the fill and the vent.
pub(super) fn sweep_branches(labels: &[Option<pam_core::Branch>]) -> Vec<pam_core::Branch> {
    let mut last = pam_core::Branch::Contraction;
    labels
        .iter()
        .map(|b| {
            if let Some(b) = b {
                last = *b;
            }
            last
        })
        .collect()
}

/// The branches a record is simulated on: an isometric record's from the
/// sweep split `labels` ([`sweep_branches`]), any other's with hindsight
/// from the pressure and the contraction's jumps ([`hindsight_branches`]).
pub(super) fn record_branches(
    samples: &[Sample],
    labels: &[Option<pam_core::Branch>],
    coeffs: &Coeffs,
    tracker: TrackerConfig,
    contraction_noise: f64,
    isometric: bool,
) -> Vec<pam_core::Branch> {
    if isometric {
        sweep_branches(labels)
    } else {
        hindsight_branches(samples, coeffs, tracker, contraction_noise)
    }
}

/// The channel [`crate::record::split::holdout_by_segment`] cuts segments at
/// (a change of more than 1 unit): the load in N for a record that holds its
/// load; for an isometric record, the held contraction in units of five
/// times its noise (at least 1e-4 of rest length), so that every hold is a
/// segment of its own and the force, which moves on every sample, is not.
pub(super) fn hold_channel(samples: &[Sample], isometric: bool) -> Vec<f64> {
    if isometric {
        let noise = crate::record::noise_std(samples.iter().map(|s| s.contraction));
        let unit = (5.0 * noise).max(1e-4);
        samples.iter().map(|s| s.contraction / unit).collect()
    } else {
        samples.iter().map(|s| s.load_n).collect()
    }
}

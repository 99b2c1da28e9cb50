//! A second start for the stroke table's search: the table that makes the
//! paper model's constraint curve follow the reference surface.
//!
//! The table's search from the identity ends in one of several minima
//! (on the Festo records, which training cycles are held out moved test
//! 10's error from 1.01× to 1.45× the reference surface's, with the
//! table's training misfit doubled). The reference surface
//! ([`ReferenceSurface`]) is a linear least-squares fit, so it has one
//! minimum, and it is smooth: at each table load, the model contraction
//! whose constraint pressure (eq. 5, the loop's middle: the surface knows
//! no hysteresis) is the surface's at each measured contraction gives the
//! map the table is, `T(u_model) = u_measured`.

use pam_core::effects::shape::table::{TABLE_KNOTS, TABLE_LOADS, TABLE_SEGMENTS};
use pam_core::LoadFamily;

use super::super::problem::TrainSet;
use super::variables::{MIN_SEGMENT, NT, NV};
use crate::identify::reference::{Point, ReferenceSurface};

/// Points of the measured contraction per table load where the map is
/// sampled.
const GRID: usize = 480;

/// The reference surface fitted to the training samples; `None` with
/// too few of them.
pub(super) fn training_surface(train: &TrainSet) -> Option<ReferenceSurface> {
    let points: Vec<Point> = train
        .runs
        .iter()
        .flat_map(|&(load, start, end)| (start..end).map(move |i| (load, i)))
        .map(|(load_n, i)| Point {
            contraction: train.x[i],
            load_n,
            pressure_mpa: train.p[i],
        })
        .collect();
    ReferenceSurface::fit_points(&points)
}

/// The stage's variables ([`NV`]: the table's, the ends' shifts at zero)
/// of the table that follows `surface` on the paper model `fam`; `None`
/// where a load's stroke is empty.
pub(super) fn reference_start(surface: &ReferenceSurface, fam: &LoadFamily) -> Option<Vec<f64>> {
    let mut w = vec![0.0; NV];
    for i in 0..TABLE_LOADS {
        let load = fam.min_load_n
            + (fam.max_load_n - fam.min_load_n) * i as f64 / (TABLE_LOADS - 1) as f64;
        let knots = knots_at(surface, fam, load)?;
        let lengths = segment_lengths(&knots);
        // The inverse of `variables::knots`: segment `j` is
        // `MIN_SEGMENT + free·e_j/Σe`, `e_0 = 1`.
        let e = |d: f64| (d - MIN_SEGMENT).max(1e-3 * MIN_SEGMENT);
        for j in 1..TABLE_SEGMENTS {
            w[i * (TABLE_SEGMENTS - 1) + j - 1] = (e(lengths[j]) / e(lengths[0])).ln();
        }
    }
    debug_assert!(w[NT..].iter().all(|&v| v == 0.0));
    w.iter().all(|v| v.is_finite()).then_some(w)
}

/// The table's knots at `load`: `T(j/K)` where the surface's pressure at
/// the measured fraction `T` is the constraint pressure at the model's
/// fraction `j/K` (the surface's pressure made non-decreasing along the
/// stroke and held within `[0, Pmax]`).
fn knots_at(surface: &ReferenceSurface, fam: &LoadFamily, load: f64) -> Option<[f64; TABLE_KNOTS]> {
    let m = fam.at_load(load);
    let (root, rx) = (m.cubic.root, m.max_contraction);
    let stroke = rx - root;
    if !(stroke > 0.0) {
        return None;
    }
    // The model fraction whose constraint pressure is each grid point's.
    let mut model = [0.0; GRID + 1];
    let mut p_max_so_far = 0.0f64;
    for (g, u) in model.iter_mut().enumerate() {
        let measured = g as f64 / GRID as f64;
        let p = surface
            .pressure_mpa(root + stroke * measured, load)
            .clamp(0.0, m.max_pressure_mpa);
        p_max_so_far = p_max_so_far.max(p);
        *u = model_fraction(&m.cubic, root, stroke, p_max_so_far);
    }
    // `T(j/K)`: the measured fraction where the model fraction reaches j/K.
    let mut knots = [0.0; TABLE_KNOTS];
    for (j, k) in knots.iter_mut().enumerate() {
        let target = (j + 1) as f64 / TABLE_SEGMENTS as f64;
        let g = model.iter().position(|&u| u >= target).unwrap_or(GRID);
        *k = if g == 0 {
            0.0
        } else {
            let (u0, u1) = (model[g - 1], model[g]);
            let t = if u1 > u0 {
                (target - u0) / (u1 - u0)
            } else {
                1.0
            };
            ((g - 1) as f64 + t.clamp(0.0, 1.0)) / GRID as f64
        };
    }
    Some(knots)
}

/// The model's stroke fraction where the constraint pressure is `p`
/// (bisection: the cubic rises over the stroke for a model pam-core
/// accepts).
fn model_fraction(cubic: &pam_core::FactorCubic, root: f64, stroke: f64, p: f64) -> f64 {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if cubic.eval(root + stroke * mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The segments' lengths of `knots` (with the ends 0 and 1), each at
/// least [`MIN_SEGMENT`] and summing to 1.
fn segment_lengths(knots: &[f64; TABLE_KNOTS]) -> [f64; TABLE_SEGMENTS] {
    let mut d = [0.0; TABLE_SEGMENTS];
    let mut before = 0.0;
    for (j, v) in d.iter_mut().enumerate() {
        let at = knots.get(j).copied().unwrap_or(1.0);
        *v = (at - before).max(MIN_SEGMENT);
        before = at;
    }
    let sum: f64 = d.iter().sum();
    d.map(|v| v / sum)
}

#[cfg(test)]
mod tests {
    use super::super::variables::knots;
    use super::*;
    use pam_core::effects::ConstraintShape;
    use pam_core::{Branch, Params};

    #[test]
    fn the_reference_start_recovers_a_smooth_table() {
        // Samples of the default family with a table that is the same
        // power law at every load, on both branches at every load: the
        // start's knots are within 0.03 of the stroke of it (0.017: the 30
        // coefficients' surface is not the model exactly), where the
        // identity's are up to 0.185 off.
        let fam = LoadFamily::from_params(&Params::DEFAULT).unwrap();
        let truth: [f64; TABLE_KNOTS] =
            std::array::from_fn(|j| ((j + 1) as f64 / TABLE_SEGMENTS as f64).powf(0.6));
        let mut train = TrainSet::empty();
        for k in 0..=12 {
            let load = fam.min_load_n + (fam.max_load_n - fam.min_load_n) * k as f64 / 12.0;
            let m = fam.at_load(load);
            let start = train.x.len();
            for i in 1..40 {
                let x = m.cubic.root + (m.max_contraction - m.cubic.root) * i as f64 / 40.0;
                for br in [Branch::Contraction, Branch::Expansion] {
                    let (p, _) =
                        ConstraintShape::pressure_and_slope_f64([0.0; 4], Some(&truth), &m, x, br);
                    train.x.push(x);
                    train.p.push(p);
                    train.branch.push(br);
                }
            }
            train.runs.push((load, start, train.x.len()));
        }
        let w = reference_start(&training_surface(&train).unwrap(), &fam).unwrap();
        let (mut worst, mut identity_worst) = (0.0f64, 0.0f64);
        for node in knots(&w[..NT]) {
            for (j, (k, t)) in node.iter().zip(&truth).enumerate() {
                worst = worst.max((k - t).abs());
                identity_worst = identity_worst.max(((j + 1) as f64 / 12.0 - t).abs());
            }
        }
        assert!(worst < 0.03, "{worst}");
        assert!(identity_worst > 0.15, "{identity_worst}");
    }
}

//! The static-shape stage: the stroke table of pam-core's constraint shape
//! ([`StrokeTable`]) identified on the paper's model, when the cubic alone
//! leaves a systematic misfit.
//!
//! A measured muscle's static curve is rarely the paper's cubic: the
//! public Festo records' pressure rises far more steeply near the stroke's
//! root than the cubic allows, and differently at each load; a
//! Chou–Hannaford or Tondu–Lopez muscle is hyperbolic at its end. The paper's
//! model then fits only by pressing against its own shape conditions at some
//! load. This stage keeps a paper model of the first stage (its stroke
//! ends, load factors and ellipse: the lower of its two minima, from the
//! data's start point and from the anchor, `fit_with_progress`) and fits
//! the table: at each of
//! [`TABLE_LOADS`] loads, a monotone piecewise-linear map of the stroke
//! fraction, each sample's pressure evaluated as the feedforward evaluates
//! it (pam-core's `f64` path, [`ConstraintShape::pressure_and_slope_f64`]).
//!
//! With it, the ends' shifts of the shape's polynomial part ([`NS`]
//! variables: each end constant, per load step and per squared load step).
//! The table keeps the stroke's ends where the paper puts them, linear in
//! load (eqs. 17–18); a measured muscle's are not. On the Festo records the
//! force a held length reaches at full pressure falls convexly with the
//! length (25 cm: about 375, 225, 125 and 75 N at the four lengths), so a
//! load-linear end misses every full-pressure hold, the largest blocks of
//! samples, by up to 18 kPa of pressure (25 cm, the third length, training
//! samples). The shifts bend the end with load; without bulge or tilt the
//! polynomial part is linear in the stroke fraction, and the chip inverts
//! it with one multiplication.
//!
//! The table's variables are the logarithms of its segments' relative
//! lengths above the least slope pam-core accepts (the first segment's
//! fixed: the knots are normalised to end at 1), and each shift is a
//! `tanh` of its variable scaled inside pam-core's limits, so every point
//! the optimiser visits is a shape pam-core accepts: no constraint to
//! hold, no projection, and the identity at the start.
//!
//! The search starts at the identity. Where its table follows the
//! training samples worse than the reference surface does (RMS pressure
//! error over [`BEHIND_REFERENCE`] times the surface's: a smooth surface
//! without hysteresis does better, so the search stopped in a poor
//! minimum), it runs again from the table that makes the paper model
//! follow the surface ([`reference_start`]), where that table starts
//! closer to the samples than the identity, with the first search's
//! evaluations and on only while it keeps up with it ([`search_from`]'s
//! race), and the lower training cost is kept. On the Festo records (18
//! fits: six lengths, three holdouts) the second search runs on 2 and is
//! kept on one, 25 cm with every fourth training cycle held out
//! (`pam-lab/README.md`, "How firm these ratios are").
//!
//! The stage's model is kept only when it earns its parameters: Bayesian
//! information criterion on the training residuals
//! (`n·ln(SSE₂/SSE₁) + k·ln n < 0`, `k` = the table's variables).

use pam_core::effects::shape::table::{blend_f64, TABLE_KNOTS, TABLE_LOADS, TABLE_SEGMENTS};
use pam_core::effects::{ConstraintShape, StrokeTable};

use super::*;

mod reference_start;
pub(super) mod variables;
use reference_start::{reference_start, training_surface};
use variables::{StaticShape, NT, NV};

/// The share of an even split of the training samples' weight over the
/// table loads below which a table load counts as not determined by them
/// ([`fill_unreached`]). A record with four loads over six table loads
/// puts a third of a load's samples on the table loads between them
/// (half an even share); a load left out of a characterisation gets its
/// neighbours' load noise, under 2 %.
const UNREACHED_SHARE: f64 = 0.1;

/// The paper's model refitted under the table.
pub(super) struct Refit {
    /// The fit vector, its parameters and coefficients (pam-core accepts
    /// them).
    pub(super) theta: Vec<f64>,
    pub(super) params: Params,
    pub(super) coeffs: Coeffs,
    /// Whether the optimiser's point was feasible before the projection.
    pub(super) was_inside: bool,
}

/// What the stage found.
pub(super) struct ShapeStage {
    /// The shape (the stroke table; no polynomial part), as exported.
    pub(super) shape: ConstraintShape,
    /// The paper's model refitted under the table, when that lowered the
    /// training cost.
    pub(super) refit: Option<Refit>,
    /// Residual evaluations spent.
    pub(super) evaluations: usize,
}

/// `nodes` with each table load the training samples do not determine
/// (their blend weights on it, [`TrainSet::table_weights`], add up to
/// under [`UNREACHED_SHARE`] of an even share: a record without samples
/// between its neighbours, such as a characterisation that skips a load,
/// whose only weight there is a neighbouring load's noise) given the
/// knots interpolated linearly from the nearest determined table loads on
/// each side, or the nearest one beyond the last. The search leaves such a
/// load about where it started, the identity: no estimate of that load's
/// curve, and a dip in the model between two loads that were fitted
/// (bench-m4's held-out loads, 300 and 500 N left out of training: 1.74 %
/// held-out RMS against the paper model's 0.99 % before this). A blend of
/// two tables is a table pam-core accepts.
fn fill_unreached(nodes: &mut [[f64; TABLE_KNOTS]; TABLE_LOADS], weights: &[f64; TABLE_LOADS]) {
    let even = weights.iter().sum::<f64>() / TABLE_LOADS as f64;
    let reached: Vec<usize> = (0..TABLE_LOADS)
        .filter(|&i| weights[i] >= UNREACHED_SHARE * even)
        .collect();
    let (Some(&first), Some(&last)) = (reached.first(), reached.last()) else {
        return;
    };
    for i in 0..TABLE_LOADS {
        if reached.contains(&i) {
            continue;
        }
        let below = reached.iter().rev().find(|&&j| j < i).copied();
        let above = reached.iter().find(|&&j| j > i).copied();
        nodes[i] = match (below, above) {
            (Some(a), Some(b)) => {
                let t = (i - a) as f64 / (b - a) as f64;
                let (ka, kb) = (nodes[a], nodes[b]);
                std::array::from_fn(|j| ka[j] + t * (kb[j] - ka[j]))
            }
            (Some(_), None) => nodes[last],
            _ => nodes[first],
        };
    }
}

impl TrainSet {
    /// Per table load, the training samples' blend weights on it
    /// ([`blend_f64`], the arithmetic the residuals use), summed: how many
    /// samples' worth of data its knots are fitted on.
    fn table_weights(&self, fam: &LoadFamily) -> [f64; TABLE_LOADS] {
        let span = (fam.max_load_n - fam.min_load_n).max(1e-9);
        let mut w = [0.0; TABLE_LOADS];
        for &(load, start, end) in &self.runs {
            let (i, t) = blend_f64((load - fam.min_load_n) / span);
            let n = (end - start) as f64;
            w[i] += (1.0 - t) * n;
            if let Some(next) = w.get_mut(i + 1) {
                *next += t * n;
            }
        }
        w
    }

    /// The rows each table load's knots move, per table load: the runs
    /// whose load blends it ([`blend_f64`], the arithmetic the residuals
    /// use), contiguous (the runs are sorted by load); `0..0` for a table
    /// load no run blends.
    fn table_blocks(&self, fam: &LoadFamily) -> Vec<std::ops::Range<usize>> {
        let span = (fam.max_load_n - fam.min_load_n).max(1e-9);
        let mut blocks: Vec<Option<(usize, usize)>> = vec![None; TABLE_LOADS];
        for &(load, start, end) in &self.runs {
            let (i, t) = blend_f64((load - fam.min_load_n) / span);
            let moved = if t > 0.0 { i..i + 2 } else { i..i + 1 };
            for b in &mut blocks[moved] {
                *b = Some(b.map_or((start, end), |(s, e)| (s.min(start), e.max(end))));
            }
        }
        blocks
            .into_iter()
            .map(|b| b.map_or(0..0, |(s, e)| s..e))
            .collect()
    }
}

/// `½·Σr²` of the training residuals with the table of `nodes`.
fn cost(train: &TrainSet, fam: &LoadFamily, shape: Option<&StaticShape>) -> f64 {
    let mut r = vec![0.0; train.len()];
    train.table_residuals(fam, shape, &mut r);
    0.5 * r.iter().map(|v| v * v).sum::<f64>()
}

/// The table for the paper model `fam`, from the variables `w0`.
fn fit_table(
    train: &TrainSet,
    fam: &LoadFamily,
    w0: &[f64],
    patience: usize,
    progress: &(dyn Fn(Progress) + Sync),
) -> Option<lsq::Minimum> {
    let residuals = |w: &[f64], out: &mut [f64]| {
        train.table_residuals(fam, Some(&StaticShape::of(w)), out);
    };
    // A table load's variables move the samples near it only: each
    // Jacobian column is evaluated on those (a third of them on average
    // with six table loads), and the steps come from the normal equations
    // formed over the rows each column pair shares (the crate's QR of the
    // whole 34 683 × 66 Jacobian of Festo 10 cm took most of the stage's
    // 17 s).
    let blocks = train.table_blocks(fam);
    // The ends' shifts move every sample.
    let block_of = |j: usize| match blocks.get(j / (TABLE_SEGMENTS - 1)) {
        Some(b) if j < NT => b.clone(),
        _ => 0..train.len(),
    };
    let residuals_of = |w: &[f64], rows: std::ops::Range<usize>, out: &mut [f64]| {
        train.table_residuals_of(fam, Some(&StaticShape::of(w)), rows, out);
    };
    let on_evaluation = |count, cost| progress(Progress::Evaluation { count, cost });
    let minimum = lsq::minimize_normal(
        &lsq::Residuals {
            m: train.len(),
            residuals: &residuals,
            step: &|_, v| 1e-7 * v.abs().max(1.0),
            on_evaluation: &on_evaluation,
            non_finite: lsq::NonFinite::Penalise,
            bounds: None,
            blocks: Some(lsq::Blocks {
                of: &block_of,
                residuals: &residuals_of,
            }),
        },
        w0,
        patience,
    );
    minimum.usable().then_some(minimum)
}

/// The paper's variables refitted under the table `nodes` from `theta`
/// (the first stage's problem: feasible projection toward `anchor`), then
/// exported; with the training cost under the table.
fn refit_paper(
    train: &TrainSet,
    fixed: &Fixed,
    theta: &[f64],
    anchor: &[f64; NP],
    shape: &StaticShape,
    patience: usize,
    progress: &(dyn Fn(Progress) + Sync),
) -> Option<(Refit, f64)> {
    let problem = Problem {
        anchor: *anchor,
        data: train,
        fixed: *fixed,
        penalty_weight: (train.len() as f64).sqrt(),
        table: Some(*shape),
    };
    let on_evaluation = |count, cost| progress(Progress::Evaluation { count, cost });
    let minimum = lsq::minimize(
        &lsq::Residuals {
            m: problem.n_residuals(),
            residuals: &|t, out| problem.residuals_at(t, out),
            step: &|j, v| 1e-7 * v.abs().max(param_scale(j, fixed)),
            on_evaluation: &on_evaluation,
            non_finite: lsq::NonFinite::Penalise,
            bounds: None,
            blocks: None,
        },
        theta,
        patience,
    );
    if !minimum.usable() {
        return None;
    }
    let (inside, was_inside) = project(&minimum.theta, anchor, fixed);
    let (theta, params, coeffs) = exported(&inside, anchor, fixed).ok()?;
    let c = cost(train, &family(&theta, fixed), Some(shape));
    Some((
        Refit {
            theta,
            params,
            coeffs,
            was_inside,
        },
        c,
    ))
}

/// How far above the reference surface's training RMS pressure error the
/// table's may be before the search runs from the surface's table too
/// ([`reference_start`]): a model with a stroke table that follows its
/// training samples worse than a smooth surface without hysteresis has
/// stopped in a poor minimum.
const BEHIND_REFERENCE: f64 = 1.05;

/// The RMS pressure error, MPa, of the paper model `fam` with `shape` on
/// the training samples (unweighted, as the reference surface's).
fn pressure_rms(train: &TrainSet, fam: &LoadFamily, shape: &StaticShape) -> f64 {
    let mut miss = vec![0.0; train.len()];
    train.table_pressure_misses(fam, Some(shape), &mut miss);
    (miss.iter().map(|v| v * v).sum::<f64>() / train.len().max(1) as f64).sqrt()
}

/// What one search of the table found.
struct Searched {
    /// The table's variables at the search's end, with its training cost.
    minimum: lsq::Minimum,
    /// The paper's model refitted under the table, when that lowered the
    /// training cost.
    refit: Option<Refit>,
    /// Residual evaluations spent.
    evaluations: usize,
    /// The search's first table fit (before the paper's refit).
    first_table: Stage,
}

/// Where a search's first table fit ended: its training cost and the
/// residual evaluations it spent.
#[derive(Clone, Copy, Debug)]
struct Stage {
    cost: f64,
    evaluations: usize,
}

/// The table from the variables `w0` on the paper model `theta`, the
/// paper's model refitted under it (kept where that lowers the training
/// cost), and the table again on it.
///
/// `race`: another search's first table fit. This search's first table
/// then gets about the evaluations that one spent (the optimiser's
/// patience is counted in units of the variables plus one), and where it
/// ends at a higher cost the search stops there. Unbounded, the second
/// start's table took up to 1 943 evaluations and the refit and table
/// after it hundreds more: the Festo 15 cm fit took 66 s instead of 3.5 s,
/// 10 cm's diagnose 117 s instead of 41 s, and a second search that fell
/// behind there never overtook (6 Festo fits of 18 ran two searches).
#[allow(clippy::too_many_arguments)]
fn search_from(
    train: &TrainSet,
    fixed: &Fixed,
    theta: &[f64],
    anchor: &[f64; NP],
    w0: &[f64],
    race: Option<Stage>,
    patience: usize,
    progress: &(dyn Fn(Progress) + Sync),
) -> Option<Searched> {
    let fam = family(theta, fixed);
    let first_patience = race.map_or(patience, |r| {
        r.evaluations.div_ceil(NV + 1).clamp(1, patience)
    });
    let mut minimum = fit_table(train, &fam, w0, first_patience, progress)?;
    let mut evaluations = minimum.evaluations;
    let first_table = Stage {
        cost: minimum.cost,
        evaluations,
    };
    let mut refit = None;
    if race.is_some_and(|r| first_table.cost > r.cost) {
        return Some(Searched {
            minimum,
            refit,
            evaluations,
            first_table,
        });
    }
    if let Some((r, c)) = refit_paper(
        train,
        fixed,
        theta,
        anchor,
        &StaticShape::of(&minimum.theta),
        patience,
        progress,
    ) {
        if c < minimum.cost {
            let fam = family(&r.theta, fixed);
            if let Some(m) = fit_table(train, &fam, &minimum.theta, patience, progress) {
                evaluations += m.evaluations;
                minimum = m;
                refit = Some(r);
            }
        }
    }
    Some(Searched {
        minimum,
        refit,
        evaluations,
        first_table,
    })
}

/// The stage on the first stage's paper model `theta`: the table, the
/// paper's model refitted under it, the table again. `None` when the table
/// does not earn its parameters or pam-core refuses its export.
pub(super) fn fit_static_shape(
    train: &TrainSet,
    fixed: &Fixed,
    theta: &[f64],
    anchor: &[f64; NP],
    patience: usize,
    progress: &(dyn Fn(Progress) + Sync),
) -> Option<ShapeStage> {
    let n = train.len();
    let fam = family(theta, fixed);
    let search = |w0: &[f64], race: Option<Stage>| {
        search_from(train, fixed, theta, anchor, w0, race, patience, progress)
    };
    let mut found = search(&[0.0; NV], None);
    // Behind the reference surface on the training samples: the search
    // from the surface's table too, as long as it keeps up with the first
    // (`search_from`'s `race`), the lower training cost kept.
    if let Some(surface) = training_surface(train) {
        let behind = found.as_ref().is_none_or(|f| {
            let fam = f.refit.as_ref().map_or(fam, |r| family(&r.theta, fixed));
            let rms = pressure_rms(train, &fam, &StaticShape::of(&f.minimum.theta));
            rms > BEHIND_REFERENCE * surface.training_rms_mpa
        });
        if behind {
            let race = found.as_ref().map(|f| f.first_table);
            // Only from a start better than the identity: the surface's
            // table is an approximation (on the Festo records its pressure
            // RMS is 3–10 times the surface's own), and from a start
            // behind the first search's the second never overtook it.
            let start_cost = |w: &[f64]| cost(train, &fam, Some(&StaticShape::of(w)));
            let second = reference_start(&surface, &fam)
                .filter(|w0| start_cost(w0) < start_cost(&[0.0; NV]))
                .and_then(|w0| search(&w0, race));
            if let Some(second) = second {
                // Both searches' evaluations are spent, whichever is kept.
                let spent = second.evaluations + found.as_ref().map_or(0, |f| f.evaluations);
                let mut kept = match found {
                    Some(first) if first.minimum.cost <= second.minimum.cost => first,
                    _ => second,
                };
                kept.evaluations = spent;
                found = Some(kept);
            }
        }
    }
    let Searched {
        minimum,
        refit,
        evaluations,
        ..
    } = found?;
    let before = cost(train, &fam, None);
    let after = minimum.cost;
    let nf = n as f64;
    let earns =
        before > 0.0 && after > 0.0 && nf * (after / before).ln() + NV as f64 * nf.ln() < 0.0;
    if !earns {
        return None;
    }
    let fitted = StaticShape::of(&minimum.theta);
    let mut nodes = fitted.nodes;
    fill_unreached(&mut nodes, &train.table_weights(&fam));
    let shape = ConstraintShape {
        table: StrokeTable {
            knots: nodes.map(|k| k.map(|v| v as f32)),
        },
        ..ConstraintShape::from_coefficients_f64(fitted.coefficients)
    };
    shape.validate().ok()?;
    Some(ShapeStage {
        shape,
        refit,
        evaluations,
    })
}

#[cfg(test)]
mod tests {
    use super::variables::knots;
    use super::*;
    use pam_core::effects::shape::MAX_SHAPE_SLOPE;

    #[test]
    fn every_point_the_search_visits_is_a_shape_pam_core_accepts() {
        // Variables far beyond any fit's (the tanh's tails, the table's
        // clamp): the shape exported validates, and at every load its
        // polynomial part is within the slope limit (the map increasing).
        let params = Params::DEFAULT;
        for seed in 0..200u64 {
            let w: Vec<f64> = (0..NV)
                .map(|j| {
                    let h = (seed * 7919 + j as u64 * 104_729) % 2001;
                    (h as f64 - 1000.0) / 10.0
                })
                .collect();
            let fitted = StaticShape::of(&w);
            let shape = ConstraintShape {
                table: StrokeTable {
                    knots: fitted.nodes.map(|k| k.map(|v| v as f32)),
                },
                ..ConstraintShape::from_coefficients_f64(fitted.coefficients)
            };
            assert!(shape.validate().is_ok(), "{seed}: {shape:?}");
            for k in 0..=10 {
                let load =
                    params.min_load_n + (params.max_load_n - params.min_load_n) * k as f32 / 10.0;
                let (at, _) = ConstraintShape::at_steps_f64(
                    fitted.coefficients,
                    f64::from((load - params.min_load_n) / params.load_step_n),
                );
                let bend = at[0].abs() + at[1].abs() + (at[3] - at[2]).abs();
                assert!(bend <= f64::from(MAX_SHAPE_SLOPE) + 1e-9, "{seed} {k}");
            }
        }
    }

    #[test]
    fn the_ends_shifts_bend_the_stroke_end_with_load() {
        // The paper's stroke end is linear in load (eqs. 17–18); a far end
        // that bends with load, as a measured muscle's does (the Festo
        // records' contraction at full pressure against the force is
        // convex), is the quadratic shift's: the muscle's contraction at
        // full pressure is the model's end moved by the shift's fraction of
        // the stroke at each load.
        let fam = LoadFamily::from_params(&Params::DEFAULT).unwrap();
        let mut w = vec![0.0; NV];
        // The end pulled in, more at higher loads (an end moved out,
        // beyond the paper's, is beyond the stroke the inverse holds to).
        w[NT + 5] = -0.005; // end_shift per squared load step
        let fitted = StaticShape::of(&w);
        let quadratic = f64::from(MAX_SHAPE_SLOPE) * 0.999 * (-0.005f64).tanh();
        assert!((fitted.coefficients[9] - quadratic).abs() < 1e-15);
        let mut ends = Vec::new();
        for k in 0..=4 {
            let load = fam.min_load_n + (fam.max_load_n - fam.min_load_n) * k as f64 / 4.0;
            let steps = (load - fam.min_load_n) / fam.load_step_n;
            let (at, _) = ConstraintShape::at_steps_f64(fitted.coefficients, steps);
            let m = fam.at_load(load);
            let s = m.max_contraction - m.cubic.root;
            // The muscle's far end, and the pressure the model needs there.
            let end = m.cubic.root + s * ConstraintShape::map_fraction_f64(at, 1.0).0;
            let (p, _) =
                ConstraintShape::pressure_and_slope_f64(at, None, &m, end, Branch::Contraction);
            assert!((p - fam.max_pressure_mpa).abs() < 1e-9, "{k}: {p}");
            ends.push(end - m.max_contraction);
        }
        // The end's move from the paper's: the shift's quadratic in load.
        for (k, e) in ends.iter().enumerate() {
            let steps = (fam.max_load_n - fam.min_load_n) * k as f64 / 4.0 / fam.load_step_n;
            let m = fam.at_load(fam.min_load_n + steps * fam.load_step_n);
            let s = m.max_contraction - m.cubic.root;
            assert!(
                (e - s * quadratic * steps * steps).abs() < 1e-12,
                "{k}: {e}"
            );
        }
    }

    #[test]
    fn the_tables_pressure_rms_is_its_residuals_in_pressure() {
        // With unit pressure noise and no contraction noise the training
        // residuals are the pressure errors: their RMS is `pressure_rms`.
        let fam = LoadFamily::from_params(&Params::DEFAULT).unwrap();
        let mut train = TrainSet::empty();
        (train.sigma_p, train.sigma_x) = (1.0, 0.0);
        for (r, load) in [120.0, 333.0, 590.0].into_iter().enumerate() {
            let start = train.len();
            for k in 0..20 {
                train.x.push(0.01 + 0.01 * k as f64);
                train.p.push(0.02 * k as f64 + 0.01 * r as f64);
                train.branch.push(if k % 2 == 0 {
                    Branch::Contraction
                } else {
                    Branch::Expansion
                });
            }
            train.runs.push((load, start, train.len()));
        }
        let w: Vec<f64> = (0..NV).map(|j| 0.2 * (j as f64).cos()).collect();
        let shape = StaticShape::of(&w);
        let mut r = vec![0.0; train.len()];
        train.table_residuals(&fam, Some(&shape), &mut r);
        let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
        assert!(rms > 0.0);
        assert!((pressure_rms(&train, &fam, &shape) - rms).abs() < 1e-12 * rms);
    }

    #[test]
    fn a_search_racing_another_gets_its_evaluations_and_stops_behind_it() {
        // Samples of a paper model other than the start's, with a table far
        // from the identity: the refit under the table lowers the cost, so
        // a search on its own runs it. One racing another search gets about
        // the other's evaluations for its first table, and where that ends
        // at a higher cost it stops there.
        let fixed = Fixed {
            pmax: 0.5,
            min_load_n: 100.0,
            max_load_n: 600.0,
            load_step_n: 100.0,
        };
        let anchor = super::super::feasible_set::anchor(0.02, 0.22, 0.02, fixed.pmax);
        let mut truth = anchor;
        truth[1] = 0.25;
        truth[2] *= 1.2;
        let fam_true = family(&truth, &fixed);
        // A static curve the table has to bend a long way to: the same
        // power law of the stroke at every load.
        let table: [f64; TABLE_KNOTS] =
            std::array::from_fn(|j| ((j + 1) as f64 / TABLE_SEGMENTS as f64).powf(0.5));
        let mut train = TrainSet::empty();
        (train.sigma_p, train.sigma_x) = (0.001, 0.0);
        for load in [100.0, 250.0, 400.0, 600.0] {
            let start = train.len();
            let m = fam_true.at_load(load);
            for k in 0..40 {
                let x = m.cubic.root + (m.max_contraction - m.cubic.root) * (k as f64 + 0.5) / 40.0;
                let br = Branch::Contraction;
                let (p, _) =
                    ConstraintShape::pressure_and_slope_f64([0.0; 4], Some(&table), &m, x, br);
                train.x.push(x);
                train.p.push(p);
                train.branch.push(br);
            }
            train.runs.push((load, start, train.len()));
        }
        let none = |_: Progress| {};
        let search = |race| {
            search_from(
                &train, &fixed, &anchor, &anchor, &[0.0; NV], race, 100, &none,
            )
            .expect("a search on a valid model")
        };
        let alone = search(None);
        assert!(alone.refit.is_some());
        assert!(alone.minimum.cost < alone.first_table.cost);
        assert!(alone.first_table.evaluations > NV + 1);
        // Behind a better first table, with as many evaluations: the same
        // first table, and no more.
        let behind = search(Some(Stage {
            cost: 0.5 * alone.first_table.cost,
            evaluations: alone.first_table.evaluations,
        }));
        assert!(behind.refit.is_none());
        assert_eq!(behind.minimum.cost, alone.first_table.cost);
        assert_eq!(
            behind.first_table.evaluations,
            alone.first_table.evaluations
        );
        assert_eq!(behind.evaluations, alone.first_table.evaluations);
        // Against a search that spent one evaluation: one unit of patience.
        let short = search(Some(Stage {
            cost: f64::INFINITY,
            evaluations: 1,
        }));
        assert!(short.first_table.evaluations <= NV + 1);
        assert!(short.first_table.cost > alone.first_table.cost);
        // Ahead of the other, it goes on to the refit.
        assert!(short.refit.is_some());
    }

    #[test]
    fn a_table_load_moves_only_its_block() {
        // Runs at loads across and beyond the calibrated range, the table
        // loads themselves among them: moving one table load's variables
        // leaves every residual outside its block bit for bit as it was.
        let fam = LoadFamily::from_params(&Params::DEFAULT).unwrap();
        let span = fam.max_load_n - fam.min_load_n;
        let mut loads: Vec<f64> = (0..=50)
            .map(|k| fam.min_load_n - 0.1 * span + 1.2 * span * k as f64 / 50.0)
            .collect();
        loads.extend(
            (0..TABLE_LOADS).map(|i| fam.min_load_n + span * i as f64 / (TABLE_LOADS - 1) as f64),
        );
        loads.sort_by(f64::total_cmp);
        let mut train = TrainSet::empty();
        for &load in &loads {
            let start = train.len();
            for k in 0..5 {
                train.x.push(0.02 + 0.03 * k as f64);
                train.p.push(0.1 + 0.05 * k as f64);
                train.branch.push(Branch::Contraction);
            }
            train.runs.push((load, start, train.len()));
        }
        let blocks = train.table_blocks(&fam);
        let w: Vec<f64> = (0..NV)
            .map(|j| if j < NT { 0.1 * (j as f64).sin() } else { 0.0 })
            .collect();
        let mut base = vec![0.0; train.len()];
        train.table_residuals(&fam, Some(&StaticShape::of(&w)), &mut base);
        for (node, block) in blocks.iter().enumerate() {
            assert!(!block.is_empty(), "{node}");
            let mut moved = w.clone();
            for v in &mut moved[node * (TABLE_SEGMENTS - 1)..(node + 1) * (TABLE_SEGMENTS - 1)] {
                *v += 0.5;
            }
            let mut r = vec![0.0; train.len()];
            train.table_residuals(&fam, Some(&StaticShape::of(&moved)), &mut r);
            let changed: Vec<usize> = (0..r.len()).filter(|&i| r[i] != base[i]).collect();
            assert!(!changed.is_empty(), "{node}");
            assert!(
                changed.iter().all(|i| block.contains(i)),
                "{node}: {block:?} {changed:?}"
            );
            // The block's residuals alone, as the whole evaluation has them.
            let mut part = vec![0.0; block.len()];
            train.table_residuals_of(
                &fam,
                Some(&StaticShape::of(&moved)),
                block.clone(),
                &mut part,
            );
            assert_eq!(part, r[block.clone()]);
        }
    }

    #[test]
    fn table_loads_no_sample_reaches_take_their_neighbours_knots() {
        // A characterisation at the table's loads but the third and fifth
        // (300 and 500 N of 100–600 N), with a few samples of load noise
        // next to its neighbours: those two table loads get the knots
        // halfway between their neighbours', the last reached one is kept.
        let fam = LoadFamily::from_params(&Params::DEFAULT).unwrap();
        let span = fam.max_load_n - fam.min_load_n;
        let mut train = TrainSet::empty();
        let at = |i: usize| fam.min_load_n + span * i as f64 / (TABLE_LOADS - 1) as f64;
        for (load, n) in [
            (at(0), 500),
            (at(1), 500),
            (at(1) + 2.0, 20),
            (at(3), 500),
            (at(5), 500),
        ] {
            let start = train.len();
            for k in 0..n {
                train.x.push(0.02 + 0.0001 * k as f64);
                train.p.push(0.1);
                train.branch.push(Branch::Contraction);
            }
            train.runs.push((load, start, train.len()));
        }
        let weights = train.table_weights(&fam);
        assert!((weights.iter().sum::<f64>() - train.len() as f64).abs() < 1e-9);
        let mut nodes = knots(&(0..NT).map(|j| 0.2 * (j as f64).cos()).collect::<Vec<_>>());
        nodes[2] = knots(&[0.0; NT])[2];
        let before = nodes;
        fill_unreached(&mut nodes, &weights);
        for j in 0..TABLE_KNOTS {
            assert_eq!(nodes[0][j], before[0][j]);
            assert_eq!(nodes[3][j], before[3][j]);
            let mid = 0.5 * (before[1][j] + before[3][j]);
            assert!((nodes[2][j] - mid).abs() < 1e-12, "{j}");
            let mid = 0.5 * (before[3][j] + before[5][j]);
            assert!((nodes[4][j] - mid).abs() < 1e-12, "{j}");
        }
        let table = StrokeTable {
            knots: nodes.map(|k| k.map(|v| v as f32)),
        };
        assert!(table.validate().is_ok());
    }
}

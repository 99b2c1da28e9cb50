//! The candidate effects: their parameter maps (in the coordinates of
//! `coordinates.rs`), the fit of one candidate's parameters on the
//! current base, and the evidence rule.

use crate::identify::lsq;
use pam_core::effects::rate::{MAX_RATE_MPA_PER_S, RATE_EXPONENT_RANGE};
use pam_core::effects::shape::MAX_SHAPE_SLOPE;
use pam_core::effects::{
    ConstraintShape, Creep, LoadDependentWidth, NonLocalMemory, PressureDelay, PressureLag,
    RateDependence,
};
use pam_core::{Coeffs, Effects, Params};
use serde::Serialize;

use super::backfit;
use super::config::DiagnoseConfig;
use super::coordinates::{
    logit, rate_filter_theta, rate_filter_time, rate_saturation, sigmoid, MEMORY_SHAPE, MERGE_SPAN,
    PRESSURE_DELAY_TIME, PRESSURE_LAG_TIME,
};
use super::evaluate::{ModelErrors, Setup, Variant};
use super::refit::refit_base;

/// A candidate effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    /// Minor loops with wiping-out ([`NonLocalMemory`]).
    NonLocalMemory,
    /// Loop height growing with the pressure rate ([`RateDependence`]).
    RateDependence,
    /// Slow relaxation after steps ([`Creep`]).
    Creep,
    /// Loop height linear in load ([`LoadDependentWidth`]).
    LoadDependentWidth,
    /// A static curve outside the cubic family ([`ConstraintShape`]).
    ConstraintShape,
    /// The muscle's pressure lagging the measured one ([`PressureLag`]).
    PressureLag,
    /// The muscle answering the measured pressure later ([`PressureDelay`]).
    PressureDelay,
}

impl EffectKind {
    /// Every candidate, in the order they are tried.
    pub const ALL: [EffectKind; 7] = [
        EffectKind::NonLocalMemory,
        EffectKind::RateDependence,
        EffectKind::Creep,
        EffectKind::LoadDependentWidth,
        EffectKind::ConstraintShape,
        EffectKind::PressureLag,
        EffectKind::PressureDelay,
    ];

    /// Whether the diagnosis offers it on a record: the pressure lag on an
    /// isometric record only (there the pressure is the answer and the
    /// force is measured, so a lag of the pressure alone is told apart
    /// from everything the load does; on an isotonic record it would
    /// compete with the rate law's loop widening with the pressure's rate,
    /// which no record here separates from it yet); the pressure delay
    /// likewise, and only once the static shape is in (its candidate is
    /// fit's static model refitted on the retimed record: offered before
    /// the shape, it would carry the shape's cut as its own).
    pub fn offered(self, isometric: bool, shape_on: bool) -> bool {
        match self {
            EffectKind::PressureLag => isometric,
            EffectKind::PressureDelay => isometric && shape_on,
            _ => true,
        }
    }

    /// The name used in reports.
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::NonLocalMemory => "non_local_memory",
            EffectKind::RateDependence => "rate_dependence",
            EffectKind::Creep => "creep",
            EffectKind::LoadDependentWidth => "load_dependent_width",
            EffectKind::ConstraintShape => "constraint_shape",
            EffectKind::PressureLag => "pressure_lag",
            EffectKind::PressureDelay => "pressure_delay",
        }
    }

    /// Number of parameters the effect adds (the rate's exponent, chosen
    /// from [`RATE_EXPONENTS`] by the fit, counts as one; its saturation
    /// too).
    pub fn parameter_count(self) -> usize {
        match self {
            EffectKind::RateDependence => 5,
            EffectKind::ConstraintShape => 8,
            EffectKind::PressureLag | EffectKind::PressureDelay => 1,
            _ => 2,
        }
    }

    /// How many leading entries of `theta` the optimiser moves; the rest
    /// (the rate's exponent and the record's fastest ramp) are fixed per
    /// start.
    fn free_count(self) -> usize {
        match self {
            EffectKind::RateDependence => 4,
            EffectKind::ConstraintShape => 8,
            EffectKind::PressureLag | EffectKind::PressureDelay => 1,
            _ => 2,
        }
    }

    /// The regime where its signature should show.
    pub fn regime(self) -> &'static str {
        match self {
            EffectKind::NonLocalMemory => "after_inner_reversal",
            EffectKind::RateDependence => "fast_ramp",
            EffectKind::Creep => "hold_after_step",
            EffectKind::LoadDependentWidth => "per_load",
            EffectKind::ConstraintShape => "static_shape",
            // Where the pressure moves fast, the lag's error is largest.
            EffectKind::PressureLag => "fast_ramp",
            // Wherever the pressure moves, steps included: a delay's error
            // is the pressure's rate times the delay.
            EffectKind::PressureDelay => "pressure_moving",
        }
    }

    /// Whether the effect has a state the static curve does not have
    /// (memory, rate, creep, width).
    pub(super) fn is_dynamic(self) -> bool {
        matches!(
            self,
            EffectKind::NonLocalMemory
                | EffectKind::RateDependence
                | EffectKind::Creep
                | EffectKind::LoadDependentWidth
        )
    }

    /// Starting points of the fit, in the unbounded coordinates of
    /// [`Self::apply`]; `max_ramp_rate` is the record's fastest ramp,
    /// MPa/s (the rate law's saturation); `rest_seen`: whether the training
    /// part holds the pressure after steps long enough to show the loop at
    /// rest (else the rate law is held to [`RATE_EXPONENT_WITHOUT_REST`]).
    pub(super) fn starts(self, max_ramp_rate: f64, rest_seen: bool) -> Vec<Vec<f64>> {
        match self {
            // A rescaled branch that merges within 0.03 of contraction, and
            // a quicker blend that is not limited.
            EffectKind::NonLocalMemory => vec![
                vec![MEMORY_SHAPE.theta(1.0), MERGE_SPAN.theta(0.03)],
                vec![MEMORY_SHAPE.theta(5.0), MERGE_SPAN.theta(0.5)],
            ],
            // Two starts per exponent: factor 1 at rest, 5 per (MPa/s)^n,
            // a 0.2 s filter, saturating just above the fastest ramp or
            // near a step's rate (the optimiser does not cross between
            // them: only the few samples after a step see the saturation).
            EffectKind::RateDependence => RATE_EXPONENTS
                .iter()
                .filter(|&&n| rest_seen || n == RATE_EXPONENT_WITHOUT_REST)
                .flat_map(|&n| {
                    [logit(0.05), logit(0.9)].map(|sat| {
                        vec![
                            logit(1.0 / 4.0),
                            logit(5.0 / 100.0),
                            rate_filter_theta(0.2),
                            sat,
                            n,
                            max_ramp_rate,
                        ]
                    })
                })
                .collect(),
            EffectKind::Creep => vec![
                vec![logit(0.1 / 0.95), 1.0f64.ln()],
                vec![logit(0.1 / 0.95), 5.0f64.ln()],
            ],
            EffectKind::LoadDependentWidth => vec![vec![logit(1.0 / 4.0), 0.0]],
            EffectKind::ConstraintShape => vec![vec![0.0; 8]],
            // A line's few milliseconds and a slower answer.
            EffectKind::PressureLag => vec![
                vec![PRESSURE_LAG_TIME.theta(0.01)],
                vec![PRESSURE_LAG_TIME.theta(0.05)],
            ],
            // Estimated from the data, not searched (`delay.rs`).
            EffectKind::PressureDelay => vec![vec![PRESSURE_DELAY_TIME.theta(0.005)]],
        }
    }

    /// `effects` with this effect on, its parameters from unbounded `theta`
    /// (logistic and exponential maps keep them inside their validation
    /// ranges, so the optimiser needs no bounds).
    pub fn apply(self, effects: Effects, theta: &[f64]) -> Effects {
        let t = |i: usize| theta.get(i).copied().unwrap_or(0.0);
        let mut e = effects;
        match self {
            EffectKind::NonLocalMemory => {
                e.memory = Some(NonLocalMemory {
                    shape: MEMORY_SHAPE.value(t(0)) as f32,
                    merge_span: MERGE_SPAN.value(t(1)) as f32,
                })
            }
            EffectKind::RateDependence => {
                // theta: factor at rest, growth, filter, saturation (free);
                // exponent and the record's fastest ramp (fixed per start).
                let (n_lo, n_hi) = RATE_EXPONENT_RANGE;
                let exponent = match theta.get(4) {
                    Some(n) if n.is_finite() => (*n as f32).clamp(n_lo, n_hi),
                    _ => 1.0,
                };
                let fastest_ramp = match theta.get(5) {
                    Some(m) if *m > 0.0 => m.min(f64::from(MAX_RATE_MPA_PER_S)),
                    _ => f64::from(MAX_RATE_MPA_PER_S),
                };
                e.rate = Some(RateDependence {
                    scale_at_rest: (4.0 * sigmoid(t(0))) as f32,
                    scale_per_mpa_per_s: (100.0 * sigmoid(t(1))) as f32,
                    exponent,
                    filter_time_s: rate_filter_time(t(2)) as f32,
                    max_rate_mpa_per_s: rate_saturation(fastest_ramp, t(3)) as f32,
                })
            }
            EffectKind::Creep => {
                e.creep = Some(Creep {
                    gain: (0.95 * sigmoid(t(0))) as f32,
                    time_constant_s: t(1).exp().clamp(0.02, 100.0) as f32,
                })
            }
            EffectKind::LoadDependentWidth => {
                e.width = Some(LoadDependentWidth {
                    scale_at_min_load: (4.0 * sigmoid(t(0))) as f32,
                    scale_per_step: (4.0 * t(1).tanh()) as f32,
                })
            }
            EffectKind::ConstraintShape => {
                // Bulge and tilt within a third of the slope limit each, the
                // stroke ends' shifts' load terms within a sixth each
                // (`at_load` keeps the sum within the limit at every load).
                // The shifts at the minimum load stay zero (the base's
                // stroke ends); their linear load terms overlap the base's
                // regressions of the stroke ends, but the joint refit does
                // not find those where the ends also bend with load.
                let third = f64::from(MAX_SHAPE_SLOPE) / 3.0;
                let sixth = f64::from(MAX_SHAPE_SLOPE) / 6.0;
                e.shape = Some(ConstraintShape {
                    bulge: (third * t(0).tanh()) as f32,
                    tilt: (third * t(1).tanh()) as f32,
                    bulge_per_step: (third * t(2).tanh()) as f32,
                    tilt_per_step: (third * t(3).tanh()) as f32,
                    root_shift: 0.0,
                    end_shift: 0.0,
                    root_shift_per_step: (sixth * t(4).tanh()) as f32,
                    end_shift_per_step: (sixth * t(5).tanh()) as f32,
                    root_shift_per_step_sq: (sixth * t(6).tanh()) as f32,
                    end_shift_per_step_sq: (sixth * t(7).tanh()) as f32,
                    // The base's stroke table (fit's), if it has one.
                    ..e.shape.unwrap_or(ConstraintShape::NEUTRAL)
                })
            }
            EffectKind::PressureLag => {
                e.pressure_lag = Some(PressureLag {
                    time_constant_s: PRESSURE_LAG_TIME.value(t(0)) as f32,
                })
            }
            EffectKind::PressureDelay => {
                e.pressure_delay = Some(PressureDelay {
                    delay_s: PRESSURE_DELAY_TIME.value(t(0)) as f32,
                })
            }
        }
        e
    }

    /// Whether `e` has this effect on.
    pub fn is_on(self, e: &Effects) -> bool {
        match self {
            EffectKind::NonLocalMemory => e.memory.is_some(),
            EffectKind::RateDependence => e.rate.is_some(),
            EffectKind::Creep => e.creep.is_some(),
            EffectKind::LoadDependentWidth => e.width.is_some(),
            EffectKind::ConstraintShape => e.shape.is_some(),
            EffectKind::PressureLag => e.pressure_lag.is_some(),
            EffectKind::PressureDelay => e.pressure_delay.is_some(),
        }
    }
}

/// Exponents of the rate law the diagnosis tries: the ones pam-core
/// evaluates with square roots (`powf` is a software routine on the M4).
pub const RATE_EXPONENTS: [f64; 3] = [0.5, 0.75, 1.0];

/// The rate law's one exponent on a record whose training part never holds
/// the pressure: linear. A sub-linear law's slope is infinite at rest, so
/// a record of ramps alone lets its factor at rest fall to anything below
/// what the slowest ramp shows: on host-sim's rate rig (viscous damping,
/// Maxwell-slip friction) diagnose fitted 0.00 at exponent 0.75, a loop
/// that vanishes where a set-point rests, and its blob tracked the three
/// scenarios 129–161 % of fit's, tripping the model check on the triangle.
/// Linear, the factor at rest is the slowest ramps' (0.34 there): 104–142 %
/// and no trip.
pub const RATE_EXPONENT_WITHOUT_REST: f64 = 1.0;

/// Fitting one candidate's parameters: residuals on the training samples.
struct CandidateProblem<'s, 'a> {
    setup: &'s Setup<'a>,
    coeffs: Coeffs,
    kind: EffectKind,
    base: Effects,
    /// The parameters the optimiser does not move (appended to `theta` for [`EffectKind::apply`]).
    fixed: Vec<f64>,
}

impl CandidateProblem<'_, '_> {
    fn full(&self, theta: &[f64]) -> Vec<f64> {
        theta.iter().chain(&self.fixed).copied().collect()
    }

    /// Training residuals at `theta` into `out`.
    fn residuals_into(&self, theta: &[f64], out: &mut [f64]) {
        let res = self
            .setup
            .residuals_with(&self.coeffs, self.kind.apply(self.base, &self.full(theta)));
        for (o, &i) in out.iter_mut().zip(&self.setup.train_idx) {
            *o = res[i];
        }
    }
}

/// One candidate's result in one round.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateResult {
    /// Effect name.
    pub name: &'static str,
    /// Held-out RMS with the effect added to the current model.
    pub rms: f64,
    /// Relative cut of the held-out RMS against the current model.
    pub improvement: f64,
    /// Fall of the BIC against the current model (positive is better).
    pub bic_drop: f64,
    /// Parameters added.
    pub parameters: usize,
    /// Whether it met the evidence rule.
    pub earned: bool,
    /// Why, in a sentence: each rule it failed with its numbers, or that
    /// it met all three.
    pub verdict: String,
    /// The static shape's two variants, when it had both (with fit's
    /// stroke table and without: the one that earns its place with the
    /// lower held-out RMS is the candidate); for a dynamic effect on fit's
    /// stroke table, its held-out RMS before and after the static model
    /// was refitted under it (`backfit.rs`), when that lowered it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub variants: Option<String>,
    /// Held-out RMS in the effect's own regime, before and after.
    pub signature: Signature,
    /// The fitted effects of the candidate model.
    pub effects: Effects,
    /// Full error breakdown.
    pub errors: ModelErrors,
    /// The base parameters refitted with the candidate on.
    pub base_params: Params,
    /// Their coefficients (not serialised).
    #[serde(skip)]
    pub coeffs: Coeffs,
}

impl CandidateResult {
    /// Its held-out cut times its signature cut (the evidence rule's two
    /// located measures), for ranking the candidates that earn their place.
    pub fn located_gain(&self) -> f64 {
        let g = self.improvement.max(0.0) * self.signature.cut().max(0.0);
        if g.is_finite() {
            g
        } else {
            0.0
        }
    }
}

/// Whether the improvement sits in the regime the effect explains.
#[derive(Clone, Debug, Serialize)]
pub struct Signature {
    /// The regime.
    pub regime: &'static str,
    /// Held-out RMS there with the current model.
    pub rms_before: f64,
    /// Held-out RMS there with the candidate.
    pub rms_after: f64,
}

impl Signature {
    /// The relative cut of the held-out RMS in the regime; not finite
    /// where no held-out sample lies in it (the regime cannot judge).
    pub fn cut(&self) -> f64 {
        1.0 - self.rms_after / self.rms_before
    }
}

/// The best of `starts` for `kind`'s own parameters on `coeffs` with
/// `current` effects, by least squares on the training samples.
pub(super) fn fit_effect_on(
    setup: &Setup<'_>,
    kind: EffectKind,
    current: Effects,
    coeffs: Coeffs,
    starts: Vec<Vec<f64>>,
    cfg: &DiagnoseConfig,
) -> Vec<f64> {
    let mut best: Option<(f64, Vec<f64>)> = None;
    for mut start in starts {
        let fixed = start.split_off(kind.free_count().min(start.len()));
        let problem = CandidateProblem {
            setup,
            coeffs,
            kind,
            base: current,
            fixed,
        };
        let minimum = lsq::minimize(
            &lsq::Residuals {
                m: setup.train_idx.len(),
                residuals: &|t, out| problem.residuals_into(t, out),
                step: &|_, v| 1e-3 * (1.0 + v.abs()),
                on_evaluation: &|_, _| {},
                non_finite: lsq::NonFinite::Refuse,
                bounds: None,
                blocks: None,
            },
            &start,
            cfg.patience,
        );
        let cost = minimum.cost;
        if cost.is_finite() && best.as_ref().is_none_or(|(c, _)| cost < *c) {
            best = Some((cost, problem.full(&minimum.theta)));
        }
    }
    best.map(|(_, t)| t).unwrap_or_default()
}

/// The evidence rule's three tests with their numbers: the ones a
/// candidate failed, or that it met them all.
fn verdict(
    improvement: f64,
    bic_drop: Option<f64>,
    signature: &Signature,
    cfg: &DiagnoseConfig,
) -> String {
    let pct = |x: f64| 100.0 * x;
    let cut = signature.cut();
    let mut failed = Vec::new();
    if improvement.is_nan() || improvement < cfg.min_improvement {
        failed.push(format!(
            "held-out RMS cut {:.1} % < {:.0} %",
            pct(improvement),
            pct(cfg.min_improvement)
        ));
    }
    let bic = match bic_drop {
        Some(d) => {
            if d.is_nan() || d < cfg.min_bic_drop {
                failed.push(format!("BIC drop {d:.1} < {:.0}", cfg.min_bic_drop));
            }
            format!("BIC drop {d:.1}")
        }
        None => "the stroke table's BIC judged by fit's static stage".to_string(),
    };
    if !cut.is_finite() {
        failed.push(format!(
            "no held-out samples in its regime ({})",
            signature.regime
        ));
    } else if cut < cfg.min_improvement {
        failed.push(format!(
            "cut in its regime ({}) {:.1} % < {:.0} %",
            signature.regime,
            pct(cut),
            pct(cfg.min_improvement)
        ));
    }
    if failed.is_empty() {
        format!(
            "earns it: held-out RMS cut {:.1} %, {bic}, cut in its regime ({}) {:.1} %",
            pct(improvement),
            signature.regime,
            pct(cut)
        )
    } else {
        format!("not earned: {}", failed.join("; "))
    }
}

/// Free parameters of fit's static shape: a stroke table's
/// ([`pam_core::effects::shape::StrokeTable`]) interior knots at each of
/// its loads, and its ends' shifts.
pub const STROKE_TABLE_PARAMETERS: usize = crate::identify::fit::STATIC_SHAPE_PARAMETERS;

pub(super) fn evaluate_candidate(
    setup: &Setup<'_>,
    kind: EffectKind,
    model: (Params, Coeffs),
    current: Effects,
    current_errors: &ModelErrors,
    current_params: usize,
    cfg: &DiagnoseConfig,
) -> CandidateResult {
    if kind == EffectKind::PressureDelay {
        if let Some(v) = super::delay::variant(setup, current, current_params) {
            return judge(setup, kind, v, current_errors, current_params, cfg, false);
        }
    }
    // The effect's parameters on the current base, then the base refitted
    // with the effect on (an effect the base fit could not see biases it:
    // creep lags every ramp the static curve was fitted to), then the
    // effect's parameters again on that base.
    // The static shape trades off against the base's stroke ends and load
    // regressions, which the correction's end shifts overlap: it gets
    // a second alternation.
    let alternations = if kind == EffectKind::ConstraintShape {
        2
    } else {
        1
    };
    let fit_variant = |model: (Params, Coeffs), current: Effects, n_params: usize| {
        let mut theta = fit_effect_on(
            setup,
            kind,
            current,
            model.1,
            kind.starts(
                setup.regimes.max_ramp_rate_mpa_per_s,
                setup.rest_in_training,
            ),
            cfg,
        );
        let (mut base_params, mut coeffs) = (model.0, model.1);
        for _ in 0..alternations {
            (base_params, coeffs) = refit_base(
                setup,
                base_params,
                coeffs,
                kind.apply(current, &theta),
                cfg.refit_iterations,
            );
            if cfg.refit_iterations > 0 {
                theta = fit_effect_on(setup, kind, current, coeffs, vec![theta], cfg);
            }
        }
        let effects = kind.apply(current, &theta);
        let (errors, res) = setup.errors(&coeffs, effects, n_params);
        (
            base_params,
            coeffs,
            effects,
            errors,
            res,
            n_params - current_params,
        )
    };
    let n_params = current_params + kind.parameter_count();
    let fitted = fit_variant(model, current, n_params);
    // A dynamic effect on fit's stroke table, with the static model
    // refitted under it too (`backfit.rs`), where that lowers the error.
    let refit_effect = |on: Effects, coeffs: Coeffs| {
        let starts = kind.starts(
            setup.regimes.max_ramp_rate_mpa_per_s,
            setup.rest_in_training,
        );
        let theta = fit_effect_on(setup, kind, on, coeffs, starts, cfg);
        (!theta.is_empty()).then(|| kind.apply(on, &theta))
    };
    let (plain, backfit_note) = if kind.is_dynamic() {
        backfit::kept(setup, fitted, n_params, current_errors, refit_effect)
    } else {
        (fitted, None)
    };
    // The static shape's second variant: fit's static model on the
    // training part as fit made it, its stroke table fitted with the
    // paper's parameters under it, against the pressure. Refitting the base
    // and the correction's terms on the simulated record moved them off it
    // (Festo 25 cm, test 10: 13 kPa as fit made it, 18 kPa refitted).
    let with_table = match (&setup.stroke_table, kind, current.shape) {
        (Some((params, shape)), EffectKind::ConstraintShape, None) => {
            Coeffs::new(*params).ok().map(|coeffs| {
                let effects = Effects {
                    shape: Some(*shape),
                    ..current
                };
                let n_params = current_params + STROKE_TABLE_PARAMETERS;
                let (errors, res) = setup.errors(&coeffs, effects, n_params);
                (
                    *params,
                    coeffs,
                    effects,
                    errors,
                    res,
                    STROKE_TABLE_PARAMETERS,
                )
            })
        }
        _ => None,
    };
    let judged =
        |v: Variant, table: bool| judge(setup, kind, v, current_errors, current_params, cfg, table);
    match with_table {
        None => {
            let mut c = judged(plain, false);
            c.variants = backfit_note;
            c
        }
        Some(table) => {
            // The static shape's two variants: where both earn their
            // place, fit's static model (what `fit` writes) unless the
            // correction alone cuts its held-out RMS by the evidence rule's
            // own margin. Two static models a few per cent apart on held-out
            // samples are a tie, not evidence: on host-sim's memory rig the
            // correction alone read 0.00688 against the table's 0.00699 and
            // its blob tracked the triangle 45 % worse than fit's.
            let (a, b) = (judged(plain, false), judged(table, true));
            let note = format!(
                "fit's static model with its stroke table: {}; the correction alone: {}",
                describe(&b),
                describe(&a)
            );
            let pick_b =
                fits_static_model_stays((a.earned, a.rms), (b.earned, b.rms), cfg.min_improvement);
            // Where the correction alone earns the shape's place and fit's
            // static model is within the margin of it, the evidence is the
            // correction's and the static model written fit's: diagnose's
            // blob is then fit's with the effects alone. (The correction
            // alone written instead, on host-sim's coulomb and memory rigs,
            // 8-10 % below fit's static model on held-out samples, tracked
            // the triangle at 130 % and 138 % of fit's blob.)
            let tie = a.earned && !b.earned && pick_b;
            let evidence = a.verdict.clone();
            let mut chosen = if pick_b { b } else { a };
            if tie {
                chosen.earned = true;
                chosen.verdict = format!(
                    "earns it on the correction alone's evidence ({evidence}); fit's static model \
                     is within the evidence rule's margin of it, so it is the static model written"
                );
            }
            chosen.variants = Some(note);
            chosen
        }
    }
}

/// Of the static shape's two variants, each `(earned, held-out RMS)`,
/// whether `table` (fit's static model) is kept over `correction` (the
/// polynomial correction alone): fit's unless the correction's held-out
/// RMS is below it by `margin` (the evidence rule's own cut) where the
/// correction earns its place (whether fit's earns it too or not: the
/// correction's earning shows a static shape is missing, and two static
/// models closer than the margin are a tie), or it alone does; where
/// neither does, the lower RMS (the verdict shown).
fn fits_static_model_stays(correction: (bool, f64), table: (bool, f64), margin: f64) -> bool {
    match (correction.0, table.0) {
        (true, false) => {
            // A NaN RMS of the correction is no evidence against fit's; a
            // NaN of fit's is no model to keep.
            let clearly_better = correction.1 < (1.0 - margin) * table.1;
            table.1.is_finite() && !clearly_better
        }
        (false, true) => true,
        (true, true) => {
            // A NaN RMS is no evidence: fit's stays.
            let clearly_better = correction.1 < (1.0 - margin) * table.1;
            !clearly_better
        }
        (false, false) => table.1 < correction.1,
    }
}

/// The held-out RMS of `errors` where `kind` shows: its regime's, the
/// worst load's for the width, the static part for the shape; NaN where
/// the record has no held-out sample there.
pub(super) fn regime_rms(kind: EffectKind, errors: &ModelErrors) -> f64 {
    match kind {
        EffectKind::LoadDependentWidth => {
            // Per load: the worst load's RMS is where a width error shows.
            errors.loads.iter().map(|l| l.rms).fold(f64::NAN, f64::max)
        }
        EffectKind::ConstraintShape => errors.static_shape,
        _ => errors
            .regimes
            .iter()
            .find(|r| r.regime == kind.regime())
            .map_or(f64::NAN, |r| r.rms),
    }
}

fn describe(c: &CandidateResult) -> String {
    format!(
        "{} parameters, held-out RMS {:.5}, BIC drop {:.1}",
        c.parameters, c.rms, c.bic_drop
    )
}

/// The evidence rule on one fitted variant of `kind`. `with_table`: the
/// variant carries fit's stroke table, whose knots fit's static stage has
/// already made earn their place on the training part (its BIC over the
/// misfit per load and stroke cell, and its own held-out cycles): here it
/// must cut the held-out RMS overall and in its regime. diagnose's BIC
/// counts independent samples by the residual's correlation length, which
/// on an isometric record runs over whole ramps (39 000 training samples
/// of the Festo muscle count as 78), and no 66 knots pass that against 8
/// terms however large the held-out cut (Festo 25 cm: 70 %, BIC drop −97).
fn judge(
    setup: &Setup<'_>,
    kind: EffectKind,
    variant: Variant,
    current_errors: &ModelErrors,
    current_params: usize,
    cfg: &DiagnoseConfig,
    with_table: bool,
) -> CandidateResult {
    let (base_params, coeffs, effects, errors, res, parameters) = variant;
    let n_params = current_params + parameters;
    let improvement = 1.0 - errors.rms_heldout / current_errors.rms_heldout;
    // The evidence's independent samples: the base residual's correlation
    // length counts the systematic error as the correlated part, and where
    // that error is the effect itself (a static-shape error runs along
    // whole sweeps) the candidate's residual is correlated over far fewer
    // samples. Both models are compared over the shorter of the two
    // lengths (one count for both, as a BIC needs).
    let train_res: Vec<f64> = setup.train_idx.iter().map(|&i| res[i]).collect();
    let cand_corr = crate::evaluate::errors::correlation_length(
        &train_res,
        setup.noise_residual,
        2 * super::config::PRESSURE_MEDIAN_HALF_WIDTH + 1,
    );
    let corr = setup.corr_len.min(cand_corr);
    let n_train = setup.train_idx.len();
    let bic_drop = super::evaluate::bic(current_errors.rms_train, n_train, corr, current_params)
        - super::evaluate::bic(errors.rms_train, n_train, corr, n_params);
    let regime_rms = |e: &ModelErrors| regime_rms(kind, e);
    let signature = Signature {
        regime: kind.regime(),
        rms_before: regime_rms(current_errors),
        rms_after: regime_rms(&errors),
    };
    let signature_cut = signature.cut();
    let earned = improvement >= cfg.min_improvement
        && (with_table || bic_drop >= cfg.min_bic_drop)
        && signature_cut >= cfg.min_improvement;
    let verdict = verdict(
        improvement,
        (!with_table).then_some(bic_drop),
        &signature,
        cfg,
    );
    CandidateResult {
        name: kind.name(),
        rms: errors.rms_heldout,
        improvement,
        bic_drop,
        parameters,
        earned,
        verdict,
        variants: None,
        signature,
        effects,
        errors,
        base_params,
        coeffs,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tie_between_the_static_shapes_goes_to_fits() {
        // (correction alone, fit's static model, margin, fit's stays):
        // host-sim's memory rig's 0.00688 against the table's 0.00699 is a
        // tie; a correction 15 % better replaces fit's static model; so
        // where the correction alone earns its place and fit's does not
        // (the coulomb rig: 0.00724 against 0.00784 is a tie, fit's stays);
        // fit's earning alone keeps it whatever the correction's RMS; where
        // neither earns, the lower RMS (what the verdict reports).
        let cases = [
            ((true, 0.00688), (true, 0.00699), 0.15, true),
            ((true, 0.0059), (true, 0.00699), 0.15, false),
            ((true, 0.0059), (true, 0.0069), 0.0, false),
            ((true, f64::NAN), (true, 0.0069), 0.15, true),
            ((true, 0.00724), (false, 0.00784), 0.15, true),
            ((true, 0.0059), (false, 0.00784), 0.15, false),
            ((true, 0.009), (false, f64::NAN), 0.15, false),
            ((false, 0.001), (true, 0.009), 0.15, true),
            ((false, 0.009), (false, 0.008), 0.15, true),
            ((false, 0.007), (false, 0.008), 0.15, false),
        ];
        for (correction, table, margin, stays) in cases {
            assert_eq!(
                fits_static_model_stays(correction, table, margin),
                stays,
                "{correction:?} {table:?} {margin}"
            );
        }
    }

    #[test]
    fn parameter_maps_stay_valid() {
        for kind in EffectKind::ALL {
            for t in [-50.0, -1.0, 0.0, 1.0, 50.0] {
                let e = kind.apply(Effects::NONE, &[t, -t]);
                assert!(e.validate().is_ok(), "{kind:?} {t}: {e:?}");
                assert!(kind.is_on(&e));
            }
        }
        for n in [0.5, 0.75, 1.0, 0.0, 9.0, f64::NAN] {
            for t in [-50.0, 0.0, 50.0] {
                let e = EffectKind::RateDependence.apply(Effects::NONE, &[t, -t, t, t, n]);
                assert!(e.validate().is_ok(), "{n} {t}: {e:?}");
            }
        }
        for start in EffectKind::RateDependence.starts(0.3, true) {
            let r = EffectKind::RateDependence
                .apply(Effects::NONE, &start)
                .rate
                .unwrap();
            assert!(RATE_EXPONENTS.contains(&f64::from(r.exponent)));
            assert!((r.filter_time_s - 0.2).abs() < 1e-6, "{r:?}");
            // Saturating just above the fastest ramp or near a step's rate.
            let m = r.max_rate_mpa_per_s;
            assert!((m > 0.3 && m < 0.4) || (m > 2.0 && m <= 5.0), "{r:?}");
        }
        // Without holds in training, the linear law alone.
        let linear = EffectKind::RateDependence.starts(0.3, false);
        assert!(!linear.is_empty());
        for start in linear {
            let r = EffectKind::RateDependence
                .apply(Effects::NONE, &start)
                .rate
                .unwrap();
            assert_eq!(f64::from(r.exponent), RATE_EXPONENT_WITHOUT_REST);
        }
        for m in [0.0, -1.0, 0.3, 99.0, f64::NAN] {
            for t in [-50.0, 0.0, 50.0] {
                let e =
                    EffectKind::RateDependence.apply(Effects::NONE, &[0.0, 0.0, 0.0, t, 1.0, m]);
                assert!(e.validate().is_ok(), "{m}: {e:?}");
                let sat = e.rate.unwrap().max_rate_mpa_per_s;
                if m == 0.3 {
                    // Never inside the measured ramps.
                    assert!(sat >= 0.3 - 1e-6, "{t}: {sat}");
                }
            }
        }
    }
}

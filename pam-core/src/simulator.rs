//! [`Simulator`]: the paper's model (the tracker's branch and load, the
//! branch inverse of eqs. 25–26) plus any [`Effects`], predicting contraction
//! from measured `(t_s, pressure_mpa, load_n)` samples one at a time.

use crate::branch::Branch;
use crate::coeffs::Coeffs;
use crate::effects::memory::Blend;
use crate::effects::{
    branch_contraction_near, CreepState, Effects, PressureLagState, RateState, Reversal,
    ReversalStack, ShapeInverse, MAX_STEP_S,
};
use crate::error::Error;
use crate::math::clamp;
use crate::tracker::{Tracker, TrackerConfig};

/// The paper's model plus [`Effects`], predicting contraction from measured
/// pressure and load one sample at a time.
///
/// The pressure lag, when on, turns the measured pressure into the
/// muscle's, which the rest runs on. The branch and the active load come
/// from a [`Tracker`] fed the pressure (the paper's mode switching); the static contraction is the branch inverse
/// (with the memory's minor loop and the scaled offset when those are on);
/// creep filters it. With [`Effects::NONE`] this is exactly the paper's model
/// driven by pressure: `model.contraction(p, branch)`.
///
/// `N` is the capacity of the reversal memory (unused without it). The
/// memory is cleared when the tracker switches the load model.
#[derive(Clone, Debug)]
pub struct Simulator<const N: usize> {
    coeffs: Coeffs,
    effects: Effects,
    /// `effects.memory`'s blend constants.
    blend: Option<Blend>,
    tracker: Tracker,
    stack: ReversalStack<N>,
    rate: RateState,
    creep: CreepState,
    pressure_lag: PressureLagState,
    last_t_s: Option<f32>,
    last_pressure_mpa: f32,
    /// Pressure and static contraction at the extreme of the current sweep.
    extreme: Option<Reversal>,
    /// The offset scale at the extreme (the rate law's factor there).
    extreme_scale: f32,
    last_output: f32,
    /// The branch contraction of the last step: where the next step's
    /// inverse starts while the model has no inverse tables
    /// ([`branch_contraction_near`]); `NaN` before the first.
    last_x_branch: f32,
    /// The constraint shape at the load it was last made for, ready to
    /// apply (made again when the tracker's load changes: the same map as
    /// [`crate::effects::ConstraintShape::at_load`]'s `apply`, bit for bit).
    shape_at_load: Option<(f32, ShapeInverse)>,
    /// The branch in use (the tracker's, or the caller's in
    /// [`Simulator::step_on_branch`]).
    branch: Branch,
}

impl<const N: usize> Simulator<N> {
    /// A simulator starting on the contraction branch at `initial_load_n`.
    pub fn new(
        coeffs: Coeffs,
        effects: Effects,
        config: TrackerConfig,
        initial_load_n: f32,
    ) -> Result<Self, Error> {
        effects.validate()?;
        let tracker = Tracker::new(&coeffs, config, initial_load_n, Branch::Contraction)?;
        let last_output = tracker.model().root_contraction();
        Ok(Simulator {
            coeffs,
            effects,
            blend: effects.memory.map(|m| m.blend_coeffs()),
            tracker,
            stack: ReversalStack::default(),
            rate: RateState::default(),
            creep: CreepState::default(),
            pressure_lag: PressureLagState::default(),
            last_t_s: None,
            last_pressure_mpa: 0.0,
            extreme: None,
            extreme_scale: 1.0,
            last_output,
            last_x_branch: f32::NAN,
            shape_at_load: None,
            branch: Branch::Contraction,
        })
    }

    /// The effects this runs.
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// The tracker (branch and active load).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// Never build a new load model's inverse tables: after a load switch
    /// the inverse runs by
    /// [`FALLBACK_BISECTION_STEPS`](crate::load_model::FALLBACK_BISECTION_STEPS)
    /// bisection steps on the forward model ([`Tracker::defer_build`], no
    /// caller advancing it). For an offline simulation whose load switches
    /// on most samples (an isometric record's measured force), where a
    /// table per switch costs far more than the bisections it saves. The
    /// model active at [`Self::new`] keeps its tables.
    pub fn defer_table_builds(&mut self) {
        self.tracker.defer_build();
    }

    /// The reversal memory.
    pub fn reversals(&self) -> &[Reversal] {
        self.stack.points()
    }

    /// Factor on the ellipse offset from the width and rate effects now.
    pub fn offset_scale(&self) -> f32 {
        crate::feedforward::offset_scale(
            &self.effects,
            self.coeffs.params(),
            self.tracker.load_n(),
            &self.rate,
        )
    }

    /// Feed one sample; returns the predicted contraction (fraction of rest
    /// length), finite and within [`Self::stroke`] (the active model's stroke,
    /// its ends moved by a constraint shape's end terms).
    ///
    /// A non-finite pressure holds the last finite one; a non-finite load is
    /// ignored by the tracker; a non-finite, backwards or longer than
    /// [`MAX_STEP_S`] time step holds the rate filter and the creep lag.
    pub fn step(&mut self, t_s: f32, pressure_mpa: f32, load_n: f32) -> f32 {
        self.step_inner(t_s, pressure_mpa, load_n, None)
    }

    /// As [`Self::step`], but on the `branch` the caller knows (offline, a
    /// reversal is known at its extreme, while the tracker can only see it
    /// once the pressure has moved back by its deadband; where the curve is
    /// flat that delay is a large contraction error). The tracker still
    /// follows the load.
    pub fn step_on_branch(
        &mut self,
        t_s: f32,
        pressure_mpa: f32,
        load_n: f32,
        branch: Branch,
    ) -> f32 {
        self.step_inner(t_s, pressure_mpa, load_n, Some(branch))
    }

    fn step_inner(
        &mut self,
        t_s: f32,
        pressure_mpa: f32,
        load_n: f32,
        branch: Option<Branch>,
    ) -> f32 {
        let p = if pressure_mpa.is_finite() {
            pressure_mpa
        } else {
            self.last_pressure_mpa
        };
        self.last_pressure_mpa = p;
        let dt_s = match (self.last_t_s, t_s.is_finite()) {
            (Some(last), true) => t_s - last,
            _ => f32::NAN,
        };
        if t_s.is_finite() {
            self.last_t_s = Some(t_s);
        }
        let dt_ok = dt_s > 0.0 && dt_s <= MAX_STEP_S;
        // The muscle's pressure: the measured one through the line's lag
        // (everything below runs on it, the tracker's branches too).
        let p = match &self.effects.pressure_lag {
            Some(l) => l.step(
                &mut self.pressure_lag,
                p,
                if dt_ok { dt_s } else { f32::NAN },
            ),
            None => p,
        };

        let update = self.tracker.update(&self.coeffs, p, load_n);
        let branch = branch.unwrap_or(self.tracker.branch());
        let switched = branch != self.branch;
        self.branch = branch;
        if update.load_switch.is_some() {
            // The turning points belong to the old load's loop, and so does
            // the sweep's extreme: pushed at the next reversal it would start
            // a minor loop from a contraction of the old load's curve.
            self.stack.clear();
            self.extreme = None;
        }
        if let Some(r) = &self.effects.rate {
            self.rate.update(
                p,
                if dt_ok { dt_s } else { f32::NAN },
                r.filter_time_s,
                r.max_rate_mpa_per_s,
            );
        }
        let scale = self.offset_scale();
        let model = self.tracker.model();

        // `p` is finite here, as `ReversalStack::follow` needs.
        let x_branch = branch_contraction_near(model, p, branch, scale, self.last_x_branch);
        self.last_x_branch = x_branch;
        let (root, max) = (model.root_contraction(), model.max_contraction());
        // The static contraction, and the same clamped to the stroke (the
        // output without creep). On a minor loop of the memory it is within
        // the stroke already, and the clamp is idempotent (the model's stroke
        // is not empty, `R_i < Rx_i`).
        let (x_static, x_clamped) = match self.blend {
            Some(blend) => {
                if switched {
                    if let Some(r) = self.extreme {
                        self.stack.push_at_scale(r, self.extreme_scale);
                    }
                    self.extreme = None;
                    self.stack.invalidate();
                }
                match self.stack.follow(blend, model, p, x_branch, branch, scale) {
                    Some(x) => (x, x),
                    None => (x_branch, clamp(x_branch, root, max)),
                }
            }
            None => (x_branch, clamp(x_branch, root, max)),
        };
        // Follow the sweep's extreme (the turning point of the next reversal).
        let beyond = match (self.extreme, branch) {
            (None, _) => true,
            (Some(e), Branch::Contraction) => p >= e.pressure_mpa,
            (Some(e), Branch::Expansion) => p <= e.pressure_mpa,
        };
        if beyond || switched {
            self.extreme = Some(Reversal {
                pressure_mpa: p,
                contraction: x_static,
            });
            self.extreme_scale = scale;
        }

        // The static curve's correction along the stroke (after the
        // memory, which works in the paper's model, before the creep, which
        // relaxes towards the muscle's static value): of the unclamped
        // static contraction for the creep, of the clamped one for the
        // output without creep (each path maps the one it uses).
        let x_out = if self.effects.creep.is_some() {
            x_static
        } else {
            x_clamped
        };
        let x_shaped = match &self.effects.shape {
            Some(s) => {
                let load_n = self.tracker.load_n();
                let cached = matches!(
                    self.shape_at_load,
                    Some((made_for, _)) if made_for.to_bits() == load_n.to_bits()
                );
                if !cached {
                    self.shape_at_load =
                        Some((load_n, s.inverse_at_load(self.coeffs.params(), load_n)));
                }
                match &self.shape_at_load {
                    Some((_, at_load)) => at_load.apply(model, x_out),
                    None => x_out,
                }
            }
            None => x_out,
        };
        let x = match &self.effects.creep {
            Some(c) => {
                // Within the stroke the shape's end terms shifted.
                let (lo, hi) = self.stroke();
                clamp(
                    c.step(
                        &mut self.creep,
                        x_shaped,
                        if dt_ok { dt_s } else { f32::NAN },
                    ),
                    lo,
                    hi,
                )
            }
            None => x_shaped,
        };
        self.last_output = x;
        x
    }

    /// The range [`Self::step`]'s prediction lies in: the active model's
    /// stroke `[R_i, Rx_i]`, its ends moved by the constraint shape's
    /// stroke-end terms at the active load when the model has them.
    pub fn stroke(&self) -> (f32, f32) {
        let model = self.tracker.model();
        let (root, max) = (model.root_contraction(), model.max_contraction());
        match &self.effects.shape {
            Some(s) => {
                let s = s.at_load(self.coeffs.params(), self.tracker.load_n());
                (s.apply(model, root), s.apply(model, max))
            }
            None => (root, max),
        }
    }

    /// The branch in use.
    pub fn branch(&self) -> Branch {
        self.branch
    }

    /// The last predicted contraction.
    pub fn last_contraction(&self) -> f32 {
        self.last_output
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::{branch_contraction, Creep, NonLocalMemory};
    use crate::params::Params;

    fn coeffs() -> Coeffs {
        Coeffs::new(Params::DEFAULT).unwrap()
    }

    fn run<const N: usize>(effects: Effects, samples: &[(f32, f32, f32)]) -> std::vec::Vec<f32> {
        let mut sim =
            Simulator::<N>::new(coeffs(), effects, TrackerConfig::DEFAULT_PRESSURE, 100.0).unwrap();
        samples.iter().map(|&(t, p, l)| sim.step(t, p, l)).collect()
    }

    /// 0 → 0.3 → 0.1 → 0.4 → 0 MPa at 0.05 MPa/s, 50 Hz, 100 N.
    fn partial_cycle() -> std::vec::Vec<(f32, f32, f32)> {
        let mut out = std::vec::Vec::new();
        let mut p = 0.0f32;
        let mut t = 0.0f32;
        for target in [0.3f32, 0.1, 0.4, 0.0] {
            while (target - p).abs() > 1e-6 {
                let step = (target - p).clamp(-0.001, 0.001);
                p += step;
                t += 0.02;
                out.push((t, p, 100.0));
            }
        }
        out
    }

    #[test]
    fn no_effects_is_the_paper_model() {
        let samples = partial_cycle();
        let xs = run::<8>(Effects::NONE, &samples);
        let c = coeffs();
        let mut tracker = Tracker::new(
            &c,
            TrackerConfig::DEFAULT_PRESSURE,
            100.0,
            Branch::Contraction,
        )
        .unwrap();
        for (&(_, p, l), x) in samples.iter().zip(xs) {
            tracker.update(&c, p, l);
            assert_eq!(x, tracker.model().contraction(p, tracker.branch()));
        }
    }

    #[test]
    fn memory_removes_the_jump_at_an_inner_reversal() {
        let samples = partial_cycle();
        let base = run::<8>(Effects::NONE, &samples);
        let mem = run::<8>(
            Effects {
                memory: Some(NonLocalMemory::with_shape(1.0)),
                ..Effects::NONE
            },
            &samples,
        );
        let max_jump = |xs: &[f32]| {
            xs.windows(2)
                .map(|w| (w[1] - w[0]).abs())
                .fold(0.0f32, f32::max)
        };
        assert!(max_jump(&base) > 0.02, "the paper's model jumps");
        assert!(max_jump(&mem) < 0.01, "memory: {}", max_jump(&mem));
    }

    #[test]
    fn width_scale_one_matches_and_larger_scale_widens() {
        let m = coeffs().load_model(200.0).unwrap();
        for p in [0.1f32, 0.25, 0.4] {
            let table = m.contraction(p, Branch::Contraction);
            let bis = branch_contraction(&m, p, Branch::Contraction, 1.0 + 1e-7);
            assert!((table - bis).abs() < 2e-3, "{p}: {table} vs {bis}");
            let gap = |s| {
                branch_contraction(&m, p, Branch::Expansion, s)
                    - branch_contraction(&m, p, Branch::Contraction, s)
            };
            assert!(gap(2.0) > gap(1.0 + 1e-7) && gap(1.0 + 1e-7) > gap(0.5));
            assert!(gap(0.0).abs() < 1e-5);
        }
    }

    #[test]
    fn creep_lags_a_step() {
        let mut samples = std::vec::Vec::new();
        for k in 0..1000 {
            let p = if k < 100 { 0.1 } else { 0.3 };
            samples.push((k as f32 * 0.02, p, 100.0));
        }
        let base = run::<4>(Effects::NONE, &samples);
        let crept = run::<4>(
            Effects {
                creep: Some(Creep {
                    gain: 0.3,
                    time_constant_s: 2.0,
                }),
                ..Effects::NONE
            },
            &samples,
        );
        assert!(base[101] - crept[101] > 0.2 * (base[101] - base[99]));
        assert!((base[999] - crept[999]).abs() < 1e-3);
    }

    #[test]
    fn invalid_effects_are_refused() {
        let bad = Effects {
            creep: Some(Creep {
                gain: 2.0,
                time_constant_s: 1.0,
            }),
            ..Effects::NONE
        };
        assert!(
            Simulator::<4>::new(coeffs(), bad, TrackerConfig::DEFAULT_PRESSURE, 100.0).is_err()
        );
    }

    #[test]
    fn deferred_table_builds_agree_with_the_tables() {
        // A load that moves on every sample with the pressure (an
        // isometric test's force): every switch builds tables in one
        // simulator and none in the other; the two agree to the tables'
        // precision (the one without tables runs the scaled inverse's
        // Newton iteration from the last answer: 7.4e-6 of contraction
        // here, where the tables' bisection fallback, 12 steps to 2^-12 of
        // the stroke, agreed to 2.6e-5).
        let cfg = TrackerConfig {
            load_threshold_n: 0.5,
            load_debounce_samples: 1,
            ..TrackerConfig::DEFAULT_PRESSURE
        };
        let mut with = Simulator::<8>::new(coeffs(), Effects::NONE, cfg, 100.0).unwrap();
        let mut without = with.clone();
        without.defer_table_builds();
        let mut worst = 0.0f32;
        for k in 0..2000 {
            let u = k as f32 / 1999.0;
            let p = 0.5 * (1.0 - libm::cosf(4.0 * core::f32::consts::PI * u));
            let load = 100.0 + 400.0 * p;
            let t = k as f32 * 0.001;
            let (a, b) = (with.step(t, p, load), without.step(t, p, load));
            worst = worst.max((a - b).abs());
        }
        assert!(!without.tracker().inverse_ready());
        assert!(worst > 0.0 && worst < 2e-5, "{worst}");
    }
}

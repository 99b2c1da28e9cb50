//! [`ModelInverse`]: the inverse of the [`Simulator`](crate::Simulator)'s
//! model with [`Effects`], for a feedforward: given the desired contraction,
//! the pressure that makes the model produce it.
//!
//! The forward chain is branch → offset scale (width × rate) → branch
//! contraction → minor loop of the memory → shape correction → creep lag;
//! the inverse runs it backwards, each step through the effect's own
//! inverse (no second copy of any equation):
//!
//! 1. creep: the static contraction that makes the lag's next output the
//!    desired one, in closed form from the lag state
//!    ([`Creep::static_contraction`]), clamped to the stroke; the lag then
//!    advances with it as the model's does;
//! 2. shape: the model's contraction whose corrected value that is
//!    ([`ConstraintShape::model_contraction`][model_contraction] at the
//!    active load, through the [`ShapeInverse`] the state keeps for that
//!    load: made once per load switch, [`ModelInverse::shape_at_load`]);
//! 3. the offset scale of width and rate ([`offset_scale`]), the rate from
//!    the feedforward's own filter (the effect's [`RateState`]) of the
//!    constraint pressure (eq. 21) at the model contraction it asked for, up
//!    to the previous period: the rate of the desired motion. Not of the
//!    pressure it commands, which depends on that rate through the offset:
//!    that loop oscillates at 1 kHz (see [`ModelInverse::pressure_mpa`]).
//!    With the memory the law's factor is computed at most on every second
//!    call, and not on a call that starts a minor loop (a reversal's, or
//!    the trial's as the set-point backs off) or goes on searching for a
//!    new loop's ends, and held on the others (the filter takes every
//!    period's pressure): where the scale holds, the memory's cached loop
//!    serves as it is, so the work of moving its ends to a new scale (a
//!    rate law changes it every time it is computed) comes at most every
//!    second period and never with a new loop's search, and a caller can
//!    judge its model in the others ([`InverseState::rebuilt_loop`]; the
//!    firmware's model check). The factor lags the filter by a period or
//!    a few, a small part of the filter's time constant. The model sees the rate of
//!    the pressure it is given, so with this effect the inverse is
//!    approximate (see `tests/feedforward.rs` for the measured round trip);
//! 4. memory: the pressure on the minor loop
//!    ([`ReversalStack::feedforward_pressure_mpa`]: its ends follow a
//!    changing offset scale by Newton steps) or, without memory or with no
//!    reversal remembered, on the branch: constraint pressure plus the
//!    scaled offset ([`branch_pressure_mpa`], eqs. 25/26), the model's
//!    closed-form direction;
//! 5. the rate filter takes this period's constraint pressure;
//! 6. pressure lag: the pressure to command so that the muscle's pressure
//!    (the lag's next output) is the one the model needs, in closed form
//!    from the lag state
//!    ([`PressureLag::command_mpa`](crate::effects::PressureLag::command_mpa)), within `[0, Pmax]`;
//!    the lag advances with the command. A pressure delay adds its delay
//!    to the lag's time constant: the first-order lead of a delay, which
//!    needs the set-point's future to be exact
//!    ([`PressureDelay`](crate::effects::PressureDelay)).
//!
//! Fixed-size state, no allocation, no panic, bounded work: the creep
//! inverse is a few operations, the shape inverse
//! [`SHAPE_INVERSE_STEPS`](crate::effects::shape::SHAPE_INVERSE_STEPS)
//! safeguarded Newton steps, the memory's inverse as documented there (two branch
//! inverses when a minor loop closes, two Newton steps when only the rate
//! effect's offset scale changed, and with the width or rate effect a
//! reversal's new loop starts its ends with two Newton steps and refines
//! them over the next periods).
//!
//! ```
//! use pam_core::effects::{Creep, Effects};
//! use pam_core::feedforward::{InverseState, ModelInverse};
//! use pam_core::{Branch, Coeffs, Params, Simulator, TrackerConfig};
//!
//! let coeffs = Coeffs::new(Params::DEFAULT).unwrap();
//! let effects = Effects {
//!     creep: Some(Creep { gain: 0.3, time_constant_s: 1.0 }),
//!     ..Effects::NONE
//! };
//! let dt_s = 0.01;
//! let inverse = ModelInverse::new(effects, dt_s).unwrap();
//! let mut state = InverseState::<8>::default();
//! let mut sim =
//!     Simulator::<8>::new(coeffs, effects, TrackerConfig::DEFAULT_PRESSURE, 200.0).unwrap();
//! let model = coeffs.load_model(200.0).unwrap();
//! for k in 0..200 {
//!     // A step of the desired contraction: the creep's slow part is
//!     // compensated by a pressure overshoot that decays.
//!     let x_ref = if k < 50 { 0.05 } else { 0.12 };
//!     let p = inverse.pressure_mpa(
//!         &mut state, coeffs.params(), &model, 200.0, x_ref, Branch::Contraction, false,
//!     );
//!     let x = sim.step_on_branch(k as f32 * dt_s, p, 200.0, Branch::Contraction);
//!     assert!((x - x_ref).abs() < 1e-4, "{k}: {x} vs {x_ref}");
//! }
//! ```
//!
//! [model_contraction]: crate::effects::ConstraintShape::model_contraction

use crate::branch::Branch;
use crate::effects::memory::{branch_pressure_mpa, MovedPoints};
use crate::effects::{
    Creep, CreepState, Effects, NonLocalMemory, PressureLag, PressureLagState, RateDependence,
    RateFilter, RateState, Reversal, ReversalStack, ShapeInverse, MAX_OFFSET_SCALE, MAX_STEP_S,
};
use crate::error::Error;
use crate::load_model::LoadModel;
use crate::math::clamp;
use crate::params::Params;

/// Factor on the ellipse offset from the width and rate effects of
/// `effects` at `load_n` and the filtered rate in `rate`, clamped to
/// `[0, MAX_OFFSET_SCALE]`; 1 with neither.
#[inline(always)]
pub fn offset_scale(effects: &Effects, params: &Params, load_n: f32, rate: &RateState) -> f32 {
    let rate_factor = match &effects.rate {
        Some(r) => r.scale(rate),
        None => 1.0,
    };
    scale_with_rate_factor(effects, params, load_n, rate_factor)
}

/// [`offset_scale`] with the rate law's factor given (1 without a rate
/// law): the feedforward's, whose factor is computed every second call at
/// most (the module's step 3).
#[inline(always)]
fn scale_with_rate_factor(
    effects: &Effects,
    params: &Params,
    load_n: f32,
    rate_factor: f32,
) -> f32 {
    let mut m = 1.0;
    if let Some(w) = &effects.width {
        m *= w.scale(params, load_n);
    }
    clamp(m * rate_factor, 0.0, MAX_OFFSET_SCALE)
}

/// The constants of the inverse: the effects and what is derived from them
/// for a fixed period (validated once, then infallible).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelInverse {
    effects: Effects,
    /// Period the feedforward is called at, s.
    dt_s: f32,
    /// The creep lag's gain over one period ([`Creep::lag_gain`]).
    creep_lag_gain: f32,
    /// The lead the command takes: the pressure lag's, with the pressure
    /// delay's added to its time constant
    /// ([`PressureDelay::lead_time_constant_s`](crate::effects::PressureDelay::lead_time_constant_s));
    /// `None` without either.
    lead: Option<PressureLag>,
    /// The lead's gain over one period
    /// ([`PressureLag::lag_gain`](crate::effects::PressureLag::lag_gain)).
    pressure_lag_gain: f32,
    /// The rate law's filter at this period, made once.
    rate_filter: Option<RateFilter>,
    /// Whether the shape has a stroke table that is not the identity
    /// (checked once here, so a shape without one costs no table work when
    /// the load switches).
    shape_table: bool,
}

/// The feedforward's own state: the reversal memory of the pressures it
/// commanded, its rate filter of them, its creep lag, and the shape's
/// inverse at the active load. A state belongs to the [`ModelInverse`] it
/// is used with (a new inverse starts from a new or [reset](Self::reset)
/// state).
#[derive(Clone, Copy, Debug, Default)]
pub struct InverseState<const N: usize> {
    memory: MemoryState<N>,
    rate: RateState,
    creep: CreepState,
    pressure_lag: PressureLagState,
    /// The offset scale of the last call, minus 1 (so that the default
    /// state's 0 is the paper's scale).
    scale_minus_one: f32,
    /// The rate law's factor on the offset ([`RateDependence::scale`]),
    /// whether there is one yet, and whether the last call that could
    /// compute it held it instead (the module's step 3).
    rate_factor: f32,
    rate_factor_known: bool,
    rate_factor_held: bool,
    /// The shape at the active load ready for its inverse, with the bits
    /// of the load and of the parameters [`ConstraintShape::at_load`](crate::effects::ConstraintShape::at_load)
    /// reads (minimum load, load step) it was made for.
    shape: Option<([u32; 3], ShapeInverse)>,
}

impl ModelInverse {
    /// The inverse of the model with `effects`, called every `dt_s` seconds.
    /// Refuses effects that fail [`Effects::validate`] and a period that is
    /// not finite and in `(0, MAX_STEP_S]`.
    pub fn new(effects: Effects, dt_s: f32) -> Result<ModelInverse, Error> {
        effects.validate()?;
        if !dt_s.is_finite() {
            return Err(Error::NonFinite("dt_s"));
        }
        if !(dt_s > 0.0 && dt_s <= MAX_STEP_S) {
            return Err(Error::OutOfRange("dt_s", "must be in (0, MAX_STEP_S] s"));
        }
        let delay_s = effects
            .pressure_delay
            .map_or(0.0, |d| d.lead_time_constant_s());
        let lead = match (effects.pressure_lag, effects.pressure_delay) {
            (None, None) => None,
            (lag, _) => Some(PressureLag {
                time_constant_s: lag.map_or(0.0, |l| l.time_constant_s) + delay_s,
            }),
        };
        Ok(ModelInverse {
            effects,
            dt_s,
            creep_lag_gain: effects.creep.map_or(0.0, |c| c.lag_gain(dt_s)),
            lead,
            pressure_lag_gain: lead.map_or(0.0, |l| l.lag_gain(dt_s)),
            shape_table: effects.shape.is_some_and(|s| !s.table.is_neutral()),
            rate_filter: effects.rate.and_then(|r| RateFilter::of(&r, dt_s)),
        })
    }

    /// The rate law's filter at this period (`None` without a rate law).
    pub fn rate_filter(&self) -> Option<&RateFilter> {
        self.rate_filter.as_ref()
    }

    /// The effects inverted.
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// The period, s.
    pub fn dt_s(&self) -> f32 {
        self.dt_s
    }

    /// The shape at `load_n` ([`ConstraintShape::at_load`](crate::effects::ConstraintShape::at_load))
    /// ready for its inverse, `None` without the shape effect. Made when
    /// the load (or the minimum load or load step of `params`) differs from
    /// the last call's, that is once per load switch, and kept in `state`:
    /// the per-period work is three comparisons. The model check's band
    /// ([`ShapeInverse::apply`]) and [`Self::pressure_mpa`] share it.
    #[inline]
    pub fn shape_at_load<'s, const N: usize>(
        &self,
        state: &'s mut InverseState<N>,
        params: &Params,
        load_n: f32,
    ) -> Option<&'s ShapeInverse> {
        let shape = self.effects.shape.as_ref()?;
        let key = [
            load_n.to_bits(),
            params.min_load_n.to_bits(),
            params.load_step_n.to_bits(),
        ];
        // Element by element: `==` on the arrays calls `memcmp`.
        let same = |k: &[u32; 3]| k[0] == key[0] && k[1] == key[1] && k[2] == key[2];
        if !matches!(&state.shape, Some((k, _)) if same(k)) {
            let inverse = if self.shape_table {
                shape.inverse_at_load(params, load_n)
            } else {
                shape.inverse_at_load_without_table(params, load_n)
            };
            state.shape = Some((key, inverse));
        }
        state.shape.as_ref().map(|(_, s)| s)
    }

    /// The pressure, in `[0, Pmax]`, at which the model with the effects
    /// produces `contraction` (clamped to `model`'s stroke, NaN → `R_i`) on
    /// `branch`, and the state's update for this period. `model` is the
    /// active load's (at `load_n`, which sets the width and the shape);
    /// `branch_switch`: the caller's branch changed on this period (a
    /// reversal, pushed on the memory). Never NaN.
    #[allow(clippy::too_many_arguments)]
    pub fn pressure_mpa<const N: usize>(
        &self,
        state: &mut InverseState<N>,
        params: &Params,
        model: &LoadModel,
        load_n: f32,
        contraction: f32,
        branch: Branch,
        branch_switch: bool,
    ) -> f32 {
        let (root, max) = (model.root_contraction(), model.max_contraction());
        let x_ref = clamp(contraction, root, max);
        let x_static = match &self.effects.creep {
            Some(c) => creep_input(c, &mut state.creep, x_ref, self.creep_lag_gain, root, max),
            None => x_ref,
        };
        let x_model = match self.shape_at_load(state, params, load_n) {
            Some(s) => s.model_contraction(model, x_static),
            None => x_static,
        };
        let scale = if self.effects.width.is_some() || self.effects.rate.is_some() {
            let memory = self.effects.memory.is_some();
            let rate_factor = match &self.effects.rate {
                Some(r) => state.rate_factor(r, memory, x_ref, branch, branch_switch),
                None => 1.0,
            };
            scale_with_rate_factor(&self.effects, params, load_n, rate_factor)
        } else {
            1.0
        };
        state.scale_minus_one = scale - 1.0;
        let p_mpa = match &self.effects.memory {
            Some(m) => {
                state
                    .memory
                    .feedforward_mpa(m, model, x_ref, x_model, branch, branch_switch, scale)
            }
            None => branch_pressure_mpa(model, x_model, branch, scale),
        };
        if let Some(f) = &self.rate_filter {
            // The rate of the constraint pressure at the model contraction
            // (eq. 21, the middle of the loop), not of the commanded one:
            // the commanded pressure depends on the filtered rate through
            // the offset scale, and at 1 kHz that loop's gain
            // (offset × d(scale)/d(rate) / filter time) exceeds 1 for
            // validated laws, so filtering the command oscillates. The
            // constraint pressure follows the desired motion only.
            state
                .rate
                .advance(model.constraint_pressure_mpa(x_model), f);
        }
        match &self.lead {
            Some(l) => l.command_mpa(
                &mut state.pressure_lag,
                p_mpa,
                self.pressure_lag_gain,
                params.points.max_pressure_mpa,
            ),
            None => p_mpa,
        }
    }
}

/// The creep's inverse clamped to the stroke, and the lag advanced with it.
#[inline]
fn creep_input(
    c: &Creep,
    state: &mut CreepState,
    x_ref: f32,
    lag_gain: f32,
    root: f32,
    max: f32,
) -> f32 {
    // Clamp: the static curve cannot leave the stroke, so a step larger
    // than the creep can deliver at once is commanded as far as it goes.
    let u = clamp(c.static_contraction(state, x_ref, lag_gain), root, max);
    c.advance(state, u, lag_gain);
    u
}

impl<const N: usize> InverseState<N> {
    /// Forget everything: memory, rate filter, creep lag (a restart after a
    /// fault: the safe state vents or holds the muscle, so none of it
    /// applies any more).
    pub fn reset(&mut self) {
        *self = InverseState::default();
    }

    /// The factor on the ellipse offset (width and rate) the last call
    /// used; 1 before the first.
    pub fn offset_scale(&self) -> f32 {
        1.0 + self.scale_minus_one
    }

    /// Forget the reversal memory (its turning points belong to the old
    /// load's loop after a load switch).
    pub fn clear_memory(&mut self) {
        self.memory.clear();
    }

    /// The memory's reversal points `(pressure, model contraction)`, oldest
    /// first.
    pub fn reversals(&self) -> &[Reversal] {
        self.memory.stack().points()
    }

    /// The last period computed a minor loop's ends (two branch inverses),
    /// or started or went on searching for them (a reversal's new loop with
    /// the width or rate effect), or moved the cached loop's ends to a new
    /// offset scale (the rate law's factor, every second period while it
    /// changes), instead of using the cached loop as it was.
    pub fn rebuilt_loop(&self) -> bool {
        self.memory.rebuilt_loop
    }

    /// The rate law's factor for this call (the module's step 3): every
    /// call without the memory; with it, on every second call that
    /// neither starts a minor loop nor goes on searching for one's ends
    /// (the first call computes it at once).
    #[inline(always)]
    fn rate_factor(
        &mut self,
        law: &RateDependence,
        memory: bool,
        x_ref: f32,
        branch: Branch,
        branch_switch: bool,
    ) -> f32 {
        if !memory || !self.rate_factor_known {
            self.rate_factor = law.scale(&self.rate);
            self.rate_factor_known = true;
            self.rate_factor_held = false;
            return self.rate_factor;
        }
        if self.memory.searching || self.memory.starts_loop(x_ref, branch, branch_switch) {
            return self.rate_factor;
        }
        if self.rate_factor_held {
            self.rate_factor = law.scale(&self.rate);
        }
        self.rate_factor_held = !self.rate_factor_held;
        self.rate_factor
    }
}

/// The memory part of the feedforward: the reversal points `(feedforward
/// pressure, model contraction)` and the extreme of the current sweep (the
/// next reversal's turning point).
#[derive(Clone, Copy, Debug, Default)]
struct MemoryState<const N: usize> {
    /// The memory and the trial (below), in the order `flip` says: at a
    /// reversal that the trial anticipated, the trial becomes the memory
    /// by flipping it, without copying and with its minor loop cached.
    stacks: (ReversalStack<N>, ReversalStack<N>),
    /// `stacks.1` is the memory, `stacks.0` the trial.
    flip: bool,
    extreme: Option<Reversal>,
    /// The offset scale at `extreme` (the rate law's factor there).
    extreme_scale: f32,
    /// The desired (output) contraction at `extreme`: the set-point backs
    /// off from the extreme in its own terms (creep makes the model
    /// contraction move back and forth under a monotone set-point).
    extreme_ref: f32,
    /// Whether the trial is the memory with `extreme` pushed, kept while
    /// the set-point backs off from it (so its minor loop stays cached).
    trial_valid: bool,
    /// The last feedforward computed a minor loop's ends (two branch
    /// inverses), searched for them, or moved them to a new offset scale,
    /// instead of using the cached loop as it was.
    rebuilt_loop: bool,
    /// The loop the last feedforward used is still searching for its ends.
    searching: bool,
    /// What moving each point of `stacks` to another offset scale needs
    /// ([`MovedPoints`]), one per stack, in the same order.
    moved: (MovedPoints<N>, MovedPoints<N>),
}

impl<const N: usize> MemoryState<N> {
    /// The memory.
    fn stack(&self) -> &ReversalStack<N> {
        if self.flip {
            &self.stacks.1
        } else {
            &self.stacks.0
        }
    }

    /// Whether [`Self::feedforward_mpa`] with these arguments starts a new
    /// minor loop (pushes the extreme, or makes the trial), rather than
    /// going on with a cached or flipped one.
    #[inline(always)]
    fn starts_loop(&self, x_ref: f32, branch: Branch, branch_switch: bool) -> bool {
        if self.extreme.is_none() || self.trial_valid {
            return false;
        }
        branch_switch || self.backing_off(x_ref, branch)
    }

    /// The set-point `x_ref` is back from the sweep's extreme against
    /// `branch`'s direction.
    #[inline(always)]
    fn backing_off(&self, x_ref: f32, branch: Branch) -> bool {
        match branch {
            Branch::Contraction => x_ref < self.extreme_ref,
            Branch::Expansion => x_ref > self.extreme_ref,
        }
    }

    /// The memory and the trial.
    fn stack_and_trial(&mut self) -> (&mut ReversalStack<N>, &mut ReversalStack<N>) {
        memory_and_trial(&mut self.stacks, self.flip)
    }

    fn clear(&mut self) {
        self.stack_and_trial().0.clear();
        self.extreme = None;
        self.trial_valid = false;
        self.rebuilt_loop = false;
    }

    /// The feedforward pressure that holds `x_model` on the memory's curve
    /// for `branch`, then the memory's update for this sample; `x_ref` is
    /// the desired contraction `x_model` was inverted from (creep and shape).
    ///
    /// A mode tracker switches the branch only once the set-point has moved
    /// its direction deadband back from the sweep's extreme. In between,
    /// following the old branch backwards and then changing curve at the
    /// switch would jump by the two curves' slope difference times the
    /// deadband (up to 0.02 MPa where a minor loop is steep). So while the
    /// set-point is back from the extreme the feedforward already follows
    /// the curve the reversal will start, a trial copy of the memory with
    /// the extreme pushed, on the opposite branch; at the switch the trial
    /// becomes the memory (the same points as the memory with the same
    /// push, and its minor loop already computed) and the feedforward
    /// continues without a step. If the set-point turns again first, that
    /// curve passes through the extreme, so the return to the old sweep is
    /// continuous too.
    #[allow(clippy::too_many_arguments)]
    fn feedforward_mpa(
        &mut self,
        params: &NonLocalMemory,
        model: &LoadModel,
        x_ref: f32,
        x_model: f32,
        branch: Branch,
        branch_switch: bool,
        offset_scale: f32,
    ) -> f32 {
        self.rebuilt_loop = false;
        self.searching = false;
        if branch_switch {
            if let Some(r) = self.extreme.take() {
                if self.trial_valid {
                    // The trial is the memory with `r` pushed (the memory
                    // and the extreme have not changed since it was made).
                    self.flip = !self.flip;
                    self.trial_valid = false;
                } else {
                    let scale = self.extreme_scale;
                    let (stack, _, moved, _) = memory_and_trial_moved(self);
                    stack.push_at_scale_moved(r, scale, moved);
                }
            }
        }
        if let Some(e) = self.extreme {
            if self.backing_off(x_ref, branch) {
                let make = !self.trial_valid;
                self.trial_valid = true;
                let scale = self.extreme_scale;
                let (stack, trial, stack_moved, trial_moved) = memory_and_trial_moved(self);
                if make {
                    trial.set_pushed_moved(stack, e, scale, trial_moved, stack_moved);
                }
                let rebuilt = !trial.has_cached_loop_at(offset_scale);
                let p_mpa = trial.feedforward_pressure_mpa_moved(
                    trial_moved,
                    params,
                    model,
                    x_model,
                    branch.opposite(),
                    offset_scale,
                );
                self.searching = trial.searching();
                self.rebuilt_loop = rebuilt;
                return p_mpa;
            }
        }
        // The memory moves on (wipe-out, new extreme): the trial is stale.
        self.trial_valid = false;
        let (stack, _, moved, _) = memory_and_trial_moved(self);
        let before = stack.points().len();
        let cached = stack.has_cached_loop_at(offset_scale);
        let p_mpa = if stack.points().is_empty() {
            // No reversal remembered: `x(p)` is the branch inverse, whose
            // inverse is the forward model, eqs. (25)/(26).
            branch_pressure_mpa(model, x_model, branch, offset_scale)
        } else {
            stack.feedforward_pressure_mpa_moved(
                moved,
                params,
                model,
                x_model,
                branch,
                offset_scale,
            )
        };
        stack.wipe_out(p_mpa, branch);
        let after = stack.points().len();
        if after < before {
            // The points a wipe-out exposes were not the top two: their
            // `Moved` may be another point's.
            if let Some(i) = after.checked_sub(1) {
                moved.forget(i);
            }
            if let Some(i) = after.checked_sub(2) {
                moved.forget(i);
            }
        }
        // A loop's ends were computed unless the cached loop served at
        // this scale (a closed loop, popped here, was evaluated afresh).
        let searching = stack.searching();
        self.rebuilt_loop = before > 0 && (!cached || after < before);
        self.searching = searching;
        // At or beyond the sweep's extreme: the turning point of the next reversal.
        self.extreme = Some(Reversal {
            pressure_mpa: p_mpa,
            contraction: x_model,
        });
        self.extreme_scale = offset_scale;
        self.extreme_ref = x_ref;
        p_mpa
    }
}

/// The memory, the trial and their [`MovedPoints`] of `state` for its
/// `flip`.
fn memory_and_trial_moved<const N: usize>(
    state: &mut MemoryState<N>,
) -> (
    &mut ReversalStack<N>,
    &mut ReversalStack<N>,
    &mut MovedPoints<N>,
    &mut MovedPoints<N>,
) {
    let (a, b) = &mut state.stacks;
    let (ma, mb) = &mut state.moved;
    if state.flip {
        (b, a, mb, ma)
    } else {
        (a, b, ma, mb)
    }
}

/// The memory and the trial of [`MemoryState`]'s `stacks` for its `flip`.
fn memory_and_trial<const N: usize>(
    stacks: &mut (ReversalStack<N>, ReversalStack<N>),
    flip: bool,
) -> (&mut ReversalStack<N>, &mut ReversalStack<N>) {
    let (a, b) = stacks;
    if flip {
        (b, a)
    } else {
        (a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::RateDependence;
    use crate::{Coeffs, Params};

    #[test]
    fn the_rate_laws_factor_comes_every_second_call_at_most_and_never_with_a_new_loop() {
        // Triangles of the set-point with reversals (a branch switch at
        // each turn): the offset scale changes on no two calls in a row,
        // on no call that starts a minor loop or goes on searching for a
        // new loop's ends, and where it changes it is `offset_scale` of
        // the rate filter as the call found it.
        let params = Params::DEFAULT;
        let coeffs = Coeffs::new(params).unwrap();
        let load = 200.0;
        let model = coeffs.load_model(load).unwrap();
        let effects = Effects {
            memory: Some(NonLocalMemory::with_shape(1.0)),
            rate: Some(RateDependence::linear(1.0, 2.0)),
            ..Effects::NONE
        };
        let inverse = ModelInverse::new(effects, 1e-3).unwrap();
        let mut state = InverseState::<8>::default();
        let (mut changes, mut loops, mut searches, mut before_changed) = (0, 0, 0, false);
        let mut branch = Branch::Contraction;
        for k in 0..6000u32 {
            // Turns at 0.04 and 0.14 with a shorter inner loop every other cycle.
            let phase = (k % 1000) as f32 / 1000.0;
            let top = if (k / 1000) % 2 == 0 { 0.14 } else { 0.11 };
            let x_ref = if phase < 0.5 {
                0.04 + (top - 0.04) * 2.0 * phase
            } else {
                top - (top - 0.04) * 2.0 * (phase - 0.5)
            };
            let now = if phase < 0.5 {
                Branch::Contraction
            } else {
                Branch::Expansion
            };
            let switch = now != branch;
            branch = now;
            let starts = state.memory.starts_loop(x_ref, branch, switch);
            let searching = state.memory.searching;
            let expected = offset_scale(&effects, &params, load, &state.rate);
            let scale_before = state.offset_scale();
            let p = inverse.pressure_mpa(&mut state, &params, &model, load, x_ref, branch, switch);
            assert!(p.is_finite());
            let changed = state.offset_scale().to_bits() != scale_before.to_bits();
            if changed {
                changes += 1;
                assert!(!before_changed, "{k}: two calls in a row");
                assert!(!starts, "{k}: with a new loop");
                assert!(!searching, "{k}: while searching");
                assert_eq!(state.offset_scale().to_bits(), expected.to_bits(), "{k}");
            }
            loops += usize::from(starts);
            searches += usize::from(searching);
            before_changed = changed;
        }
        assert!(
            loops >= 10 && searches >= loops && changes > 2000,
            "{loops} loops, {searches} searching, {changes} changes"
        );
    }
}

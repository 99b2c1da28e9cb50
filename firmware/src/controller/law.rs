//! The control law: hysteresis-model feedforward, PI on contraction with
//! anti-windup, and the inner pressure loop to a valve flow command.
//!
//! # Clamps
//! * The desired contraction is clamped to the active model's stroke
//!   `[R_i, Rx_i]` (a Preisach model's: its output empty and full,
//!   [`pam_core::preisach::Preisach::stroke`]): outside it no pressure
//!   holds it, and the integrator would wind up chasing it.
//! * The pressure command is clamped to `[0, min(Pmax, max_command_mpa)]`:
//!   the muscle cannot hold negative gauge pressure, the model is not
//!   calibrated above `Pmax`, and the hardware's limit
//!   ([`SafetyConfig::max_command_mpa`](super::config::SafetyConfig::max_command_mpa))
//!   holds whatever `Pmax` a model brings.
//! * The integral term is clamped to `±integral_limit_mpa`, and it is not
//!   advanced while the pressure command is saturated in the direction the
//!   error pushes it (conditional integration): together they bound windup
//!   when the valve or the supply cannot follow.
//! * The valve command is clamped to `[-1, 1]`.

use super::config::{ControllerConfig, Feedforward};
use super::monitor::{extra_offset_mpa, MeasuredRate, ModelBand};
use super::preisach::PreisachModel;
use pam_core::effects::{Effects, RateState};
use pam_core::feedforward::{InverseState, ModelInverse};
use pam_core::{clamp, Branch, Error, LoadModel, Params};

/// Reversal points the memory feedforward ([`Feedforward::HysteresisMemory`],
/// or [`Feedforward::HysteresisEffects`] with memory) remembers: pam-core's
/// one depth, which the host tools simulate with too.
pub use pam_core::effects::memory::MEMORY_DEPTH;

/// Bisection steps of the minor-loop feedforward's inverse (pam-core's
/// [`ReversalStack::inverse_pressure_mpa`](pam_core::effects::ReversalStack::inverse_pressure_mpa),
/// in branch contraction).
pub use pam_core::effects::memory::MEMORY_INVERSE_STEPS;

/// The effects whose inverse `feedforward` runs, if it runs pam-core's
/// [`ModelInverse`] (the memory and effects modes).
pub(super) fn inverted_effects(feedforward: &Feedforward) -> Option<Effects> {
    match feedforward {
        Feedforward::HysteresisMemory(m) => Some(Effects {
            memory: Some(*m),
            ..Effects::NONE
        }),
        Feedforward::HysteresisEffects(e) => Some(*e),
        Feedforward::Hysteresis
        | Feedforward::Constraint
        | Feedforward::Off
        | Feedforward::Preisach => None,
    }
}

/// The flashed model's contraction for the set-point `x_ref` on a stroke
/// scaled by `scale` about the root ([`super::adapt`]), clamped to the
/// model's stroke; `x_ref` itself at scale 1.
#[inline(always)]
fn adapted_target(model: &LoadModel, scale: f32, x_ref: f32) -> f32 {
    if scale == 1.0 {
        return x_ref;
    }
    let r = model.root_contraction();
    clamp(r + (x_ref - r) / scale, r, model.max_contraction())
}

/// What the law commands for one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Command {
    /// Feedforward pressure, MPa.
    pub feedforward_mpa: f32,
    /// Pressure set-point of the inner loop, MPa.
    pub pressure_cmd_mpa: f32,
    /// Valve flow command in `[-1, 1]`.
    pub flow: f32,
}

/// The law's state: the integrator, and for a feedforward that inverts the
/// model with effects, the inverse's constants and its state (memory, rate
/// filter, creep lag).
#[derive(Clone, Copy, Debug)]
pub(super) struct Law {
    pub integral_mpa: f32,
    /// Highest pressure command, MPa: the lower of the model's `Pmax` and
    /// the hardware's [`SafetyConfig::max_command_mpa`](super::config::SafetyConfig::max_command_mpa).
    max_command_mpa: f32,
    inverse: Option<ModelInverse>,
    state: InverseState<MEMORY_DEPTH>,
    /// With a rate law: the measured pressure through its filter, the
    /// rate the muscle's loop is at (the model check's band, [`MeasuredRate`]).
    measured_rate: RateState,
    /// The adapted stroke scale ([`super::adapt`]; 1: the flashed model),
    /// used by the paper's feedforward.
    pub stroke_scale: f32,
}

impl Law {
    /// The law for a validated configuration and a model whose loop closes
    /// at `pmax_mpa` (the inverse's constants and the command's limit are
    /// computed here, once).
    pub fn new(cfg: &ControllerConfig, pmax_mpa: f32) -> Result<Law, Error> {
        let inverse = match inverted_effects(&cfg.feedforward) {
            Some(e) => Some(ModelInverse::new(e, cfg.dt_s)?),
            None => None,
        };
        Ok(Law {
            integral_mpa: 0.0,
            max_command_mpa: cfg.safety.command_limit_mpa(pmax_mpa),
            inverse,
            state: InverseState::default(),
            measured_rate: RateState::default(),
            stroke_scale: 1.0,
        })
    }

    /// Bumpless restart after a fault: the integral built up before it does
    /// not apply to the state the muscle is in after it, and the safe state
    /// vents (or holds) the muscle, so its loop history no longer applies;
    /// nor do the feedforward's rate filter and creep lag.
    pub fn reset(&mut self) {
        self.integral_mpa = 0.0;
        self.state.reset();
        self.measured_rate = RateState::default();
    }

    /// The turning points belong to the old load's loop.
    pub fn load_switched(&mut self) {
        self.state.clear_memory();
    }

    /// The memory feedforward computed a minor loop's ends on this period
    /// (two branch inverses, table-free and slower while the tracker builds
    /// a new load's tables), or searched for them (a reversal's new loop
    /// with the width or rate effect, in its first periods, which also move
    /// its turning point for the first time), or moved them to the rate
    /// law's new factor, instead of using its cached loop.
    pub fn rebuilt_loop(&self) -> bool {
        self.state.rebuilt_loop()
    }

    /// How the feedforward's model widens the model check's band now
    /// ([`ModelBand`]): the offset its width and rate added on its last
    /// call (the check runs after the law, so this period's), its shape at
    /// `load_n` (made once per load and kept with the feedforward's state,
    /// which inverts the same shape).
    pub fn model_band<'a>(
        &'a mut self,
        params: &'a Params,
        model: &LoadModel,
        load_n: f32,
    ) -> ModelBand<'a> {
        let Some(inv) = &self.inverse else {
            return ModelBand::default();
        };
        let extra_offset_mpa = extra_offset_mpa(self.state.offset_scale(), model);
        let measured = inv.effects().rate.map(|_| MeasuredRate {
            effects: inv.effects(),
            params,
            load_n,
            rate: &self.measured_rate,
        });
        ModelBand {
            extra_offset_mpa,
            shape: inv.shape_at_load(&mut self.state, params, load_n),
            measured,
        }
    }

    /// One period on checked (finite, in range) readings. `ki_dt` is
    /// `ki_mpa_per_s · dt_s`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn command(
        &mut self,
        cfg: &ControllerConfig,
        ki_dt: f32,
        params: &Params,
        model: &LoadModel,
        load_n: f32,
        branch: Branch,
        branch_switch: bool,
        desired_contraction: f32,
        pressure_mpa: f32,
        contraction: f32,
    ) -> Command {
        if let Some(f) = self.inverse.as_ref().and_then(|i| i.rate_filter()) {
            self.measured_rate.advance(pressure_mpa, f);
        }
        // Clamp: the set-point to the active model's stroke [R_i, Rx_i].
        let x_ref = clamp(
            desired_contraction,
            model.root_contraction(),
            model.max_contraction(),
        );
        let feedforward_mpa = match cfg.feedforward {
            // eqs. (25)/(26): the pressure that holds x_ref on the active
            // branch (on the adapted stroke: the flashed model's contraction
            // `R + (x_ref − R)/s`).
            Feedforward::Hysteresis => {
                model.pressure_mpa(adapted_target(model, self.stroke_scale, x_ref), branch)
            }
            // eq. (21): the constraint model, between the two branches.
            Feedforward::Constraint => {
                model.constraint_pressure_mpa(adapted_target(model, self.stroke_scale, x_ref))
            }
            Feedforward::Off => 0.0,
            // eqs. (25)/(26) with the effects inverted (pam-core's
            // `ModelInverse`: creep, shape, width and rate, minor loops).
            Feedforward::HysteresisMemory(_) | Feedforward::HysteresisEffects(_) => {
                match &self.inverse {
                    Some(inv) => inv.pressure_mpa(
                        &mut self.state,
                        params,
                        model,
                        load_n,
                        x_ref,
                        branch,
                        branch_switch,
                    ),
                    // `Law::new` builds the inverse for these modes.
                    None => model.pressure_mpa(x_ref, branch),
                }
            }
            // A Preisach model runs `command_preisach`; the controller
            // refuses this mode with the paper's model (`FeedforwardModel`).
            Feedforward::Preisach => 0.0,
        };
        self.close_loop(
            cfg,
            ki_dt,
            x_ref,
            feedforward_mpa,
            pressure_mpa,
            contraction,
        )
    }

    /// One period of a controller running a Preisach model, on checked
    /// readings: the set-point clamped to the model's stroke at the active
    /// load, [`Feedforward::Preisach`]'s pressure from pam-core's exact
    /// inverse (from the relay states the measured pressure left; see
    /// [`super::preisach`]), then the same PI and inner loop as the paper's
    /// feedforward. [`Feedforward::Off`]: the PI alone.
    #[inline(always)]
    pub fn command_preisach(
        &mut self,
        cfg: &ControllerConfig,
        ki_dt: f32,
        model: &PreisachModel,
        desired_contraction: f32,
        pressure_mpa: f32,
        contraction: f32,
    ) -> Command {
        let x_ref = model.clamp_setpoint(desired_contraction);
        let feedforward_mpa = match cfg.feedforward {
            Feedforward::Preisach => model.feedforward_mpa(x_ref),
            // Off; the controller refuses the paper model's modes here.
            _ => 0.0,
        };
        self.close_loop(
            cfg,
            ki_dt,
            x_ref,
            feedforward_mpa,
            pressure_mpa,
            contraction,
        )
    }

    /// PI on the contraction error added to the feedforward, the clamps and
    /// the anti-windup of the module docs, and the inner pressure loop: the
    /// part of the law every model shares.
    #[inline(always)]
    fn close_loop(
        &mut self,
        cfg: &ControllerConfig,
        ki_dt: f32,
        x_ref: f32,
        feedforward_mpa: f32,
        pressure_mpa: f32,
        contraction: f32,
    ) -> Command {
        let error = x_ref - contraction;
        let max_mpa = self.max_command_mpa;
        let unclamped_mpa = feedforward_mpa + cfg.kp_mpa * error + self.integral_mpa;
        // Clamp: the pressure command to [0, min(Pmax, max_command_mpa)].
        let pressure_cmd_mpa = clamp(unclamped_mpa, 0.0, max_mpa);
        // Anti-windup, conditional integration: hold the integrator while the
        // command is saturated and the error would push it further out.
        let windup =
            (unclamped_mpa > max_mpa && error > 0.0) || (unclamped_mpa < 0.0 && error < 0.0);
        if !windup {
            // Clamp: the integral term to ±integral_limit_mpa.
            self.integral_mpa = clamp(
                self.integral_mpa + ki_dt * error,
                -cfg.integral_limit_mpa,
                cfg.integral_limit_mpa,
            );
        }
        // Inner loop; clamp: the flow command to [-1, 1].
        let flow = clamp(
            cfg.pressure_gain_per_mpa * (pressure_cmd_mpa - pressure_mpa),
            -1.0,
            1.0,
        );
        Command {
            feedforward_mpa,
            pressure_cmd_mpa,
            flow,
        }
    }
}

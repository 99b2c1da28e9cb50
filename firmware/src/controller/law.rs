//! The control law: hysteresis-model feedforward, PI on contraction with
//! anti-windup, and the inner pressure loop to a valve flow command.
//!
//! # Clamps
//! * The desired contraction is clamped to the active model's stroke
//!   `[R_i, Rx_i]`: outside it no pressure holds it, and the integrator
//!   would wind up chasing it.
//! * The pressure command is clamped to `[0, Pmax]` of the model: the muscle
//!   cannot hold negative gauge pressure and the model is not calibrated
//!   above `Pmax`.
//! * The integral term is clamped to `±integral_limit_mpa`, and it is not
//!   advanced while the pressure command is saturated in the direction the
//!   error pushes it (conditional integration): together they bound windup
//!   when the valve or the supply cannot follow.
//! * The valve command is clamped to `[-1, 1]`.

use super::config::{ControllerConfig, Feedforward};
use pam_core::effects::{NonLocalMemory, Reversal, ReversalStack};
use pam_core::{Branch, LoadModel};

/// Reversal points the [`Feedforward::HysteresisMemory`] feedforward
/// remembers (nested minor loops); older ones are dropped.
pub const MEMORY_DEPTH: usize = 8;

/// Bisection steps of the minor-loop feedforward's inverse (pam-core's
/// [`ReversalStack::inverse_pressure_mpa`], in branch contraction).
pub use pam_core::effects::memory::MEMORY_INVERSE_STEPS;

/// `x` limited to `[lo, hi]`, NaN → `lo` (never panics, unlike `f32::clamp`
/// with bad bounds).
pub(crate) fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    if x >= lo {
        if x <= hi {
            x
        } else {
            hi
        }
    } else {
        lo
    }
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

/// The law's state: the integrator and the feedforward's loop memory.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Law {
    pub integral_mpa: f32,
    memory: MemoryState,
}

impl Law {
    /// Bumpless restart after a fault: the integral built up before it does
    /// not apply to the state the muscle is in after it, and the safe state
    /// vents (or holds) the muscle, so its loop history no longer applies.
    pub fn reset(&mut self) {
        self.integral_mpa = 0.0;
        self.memory.clear();
    }

    /// The turning points belong to the old load's loop.
    pub fn load_switched(&mut self) {
        self.memory.clear();
    }

    /// The memory feedforward computed a minor loop's ends on this period
    /// (two branch inverses, table-free and slower while the tracker builds
    /// a new load's tables) instead of using its cached loop.
    pub fn rebuilt_loop(&self) -> bool {
        self.memory.rebuilt_loop
    }

    /// One period on checked (finite, in range) readings. `ki_dt` is
    /// `ki_mpa_per_s · dt_s`.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub fn command(
        &mut self,
        cfg: &ControllerConfig,
        ki_dt: f32,
        model: &LoadModel,
        branch: Branch,
        branch_switch: bool,
        desired_contraction: f32,
        pressure_mpa: f32,
        contraction: f32,
    ) -> Command {
        // Clamp: the set-point to the active model's stroke [R_i, Rx_i].
        let x_ref = clamp(
            desired_contraction,
            model.root_contraction(),
            model.max_contraction(),
        );
        let feedforward_mpa = match cfg.feedforward {
            // eqs. (25)/(26): the pressure that holds x_ref on the active branch.
            Feedforward::Hysteresis => model.pressure_mpa(x_ref, branch),
            // eq. (21): the constraint model, between the two branches.
            Feedforward::Constraint => model.constraint_pressure_mpa(x_ref),
            Feedforward::Off => 0.0,
            // eqs. (25)/(26) with pam-core's minor loops between reversals.
            Feedforward::HysteresisMemory(mem) => {
                self.memory
                    .feedforward_mpa(&mem, model, x_ref, branch, branch_switch)
            }
        };
        let error = x_ref - contraction;
        let max_mpa = model.max_pressure_mpa();
        let unclamped_mpa = feedforward_mpa + cfg.kp_mpa * error + self.integral_mpa;
        // Clamp: the pressure command to the model's range [0, Pmax].
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

/// State of the [`Feedforward::HysteresisMemory`] feedforward: the reversal
/// points `(feedforward pressure, desired contraction)` and the extreme of
/// the current sweep (the next reversal's turning point).
#[derive(Clone, Copy, Debug, Default)]
struct MemoryState {
    stack: ReversalStack<MEMORY_DEPTH>,
    extreme: Option<Reversal>,
    /// The memory with `extreme` pushed, kept while the set-point backs off
    /// from it (so its minor loop stays cached); valid while `trial_valid`.
    trial: ReversalStack<MEMORY_DEPTH>,
    trial_valid: bool,
    /// The last feedforward computed a minor loop's ends (two branch
    /// inverses) instead of using the cached loop.
    rebuilt_loop: bool,
}

impl MemoryState {
    fn clear(&mut self) {
        self.stack.clear();
        self.extreme = None;
        self.trial_valid = false;
        self.rebuilt_loop = false;
    }

    /// The feedforward pressure that holds `x_ref` on the memory's curve for
    /// `branch`, then the memory's update for this sample.
    ///
    /// The mode tracker switches the branch only once the set-point has
    /// moved `direction_deadband` back from the sweep's extreme. In between,
    /// following the old branch backwards and then changing curve at the
    /// switch would jump by the two curves' slope difference times the
    /// deadband (up to 0.02 MPa where a minor loop is steep). So while the
    /// set-point is back from the extreme the feedforward already follows
    /// the curve the reversal will start, a trial copy of the memory with
    /// the extreme pushed, on the opposite branch; at the switch the real
    /// memory takes the same push and the feedforward continues without a
    /// step. If the set-point turns again first, that curve passes through
    /// the extreme, so the return to the old sweep is continuous too.
    fn feedforward_mpa(
        &mut self,
        params: &NonLocalMemory,
        model: &LoadModel,
        x_ref: f32,
        branch: Branch,
        branch_switch: bool,
    ) -> f32 {
        self.rebuilt_loop = false;
        if branch_switch {
            if let Some(r) = self.extreme.take() {
                self.stack.push(r);
            }
        }
        if let Some(e) = self.extreme {
            let backing_off = match branch {
                Branch::Contraction => x_ref < e.contraction,
                Branch::Expansion => x_ref > e.contraction,
            };
            if backing_off {
                if !self.trial_valid {
                    self.trial = self.stack;
                    self.trial.push(e);
                    self.trial_valid = true;
                }
                self.rebuilt_loop = !self.trial.has_cached_loop();
                return self.trial.inverse_pressure_mpa(
                    params,
                    model,
                    x_ref,
                    branch.opposite(),
                    1.0,
                );
            }
        }
        // The memory moves on (wipe-out, new extreme): the trial is stale.
        self.trial_valid = false;
        let before = self.stack.points().len();
        let cached = self.stack.has_cached_loop();
        let p_mpa = if self.stack.points().is_empty() {
            // No reversal remembered: `x(p)` is the branch inverse, whose
            // inverse is the forward model, eqs. (25)/(26).
            model.pressure_mpa(x_ref, branch)
        } else {
            self.stack
                .inverse_pressure_mpa(params, model, x_ref, branch, 1.0)
        };
        self.stack.wipe_out(p_mpa, branch);
        // A loop's ends were computed unless the cached loop served (a
        // closed loop, popped here, was evaluated afresh).
        self.rebuilt_loop = before > 0 && (!cached || self.stack.points().len() < before);
        // At or beyond the sweep's extreme: the turning point of the next reversal.
        self.extreme = Some(Reversal {
            pressure_mpa: p_mpa,
            contraction: x_ref,
        });
        p_mpa
    }
}

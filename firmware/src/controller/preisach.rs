//! The Preisach model as the controller runs it ([`pam_core::preisach`]):
//! the table a Preisach blob carries and the running model, driven by the
//! measured pressure and load.
//!
//! One running model serves both uses, as the paper model's tracker does:
//! its relay states follow the *measured* pressure, so they are the
//! muscle's own history (not the feedforward's), and
//!
//! * its forward output is the model check's prediction of the contraction
//!   at the measured pressure ([`super::monitor`]), with the minor loop the
//!   pressure history has put the muscle on;
//! * its exact inverse from that state is the feedforward
//!   ([`Preisach::inverse_pressure_mpa`]): the pressure at which the model,
//!   driven there from where the muscle is, first reaches the set-point.
//!
//! The relay states need no reset on a fault: they follow every good
//! pressure reading, also while the valves are safe (the exhaust vents the
//! muscle and the relays switch off as the pressure falls), and hold on a
//! bad one.
//!
//! Work per period: pam-core's load update (nothing unless a load switch is
//! under way, then [`pam_core::preisach::LOAD_SWITCH_ROWS_PER_UPDATE`] rows
//! of the new load's coefficients), the relay update (`N` rows), the output
//! (`2N` table reads) and, while controlling, the inverse (at most `N`
//! thresholds either way). No loops over data beyond those bounds, no
//! allocation, no panic paths.

use pam_core::preisach::{Preisach, PreisachTable};

/// Relay rows of the half-grid a flashed Preisach blob carries: the size
/// `pam-lab compare` identifies and writes (`pam_lab::identify::preisach::ROWS`,
/// checked by host-sim's tests).
pub const PREISACH_ROWS: usize = 16;
/// Grid loads of a flashed Preisach blob (`pam_lab::identify::preisach::LOADS`).
pub const PREISACH_LOADS: usize = 6;

/// The table of a flashed Preisach blob.
pub type PreisachTable16 = PreisachTable<PREISACH_ROWS, PREISACH_LOADS>;

/// Length of a flashed Preisach blob, bytes.
pub const PREISACH_BLOB_LEN: usize =
    pam_core::preisach::blob::blob_len(PREISACH_ROWS, PREISACH_LOADS);

/// What the monitor's rules take from a Preisach table: its first and
/// last grid load and its top pressure.
pub fn model_limits(table: &PreisachTable16) -> super::ModelLimits {
    let last = PREISACH_LOADS.saturating_sub(1) as f32;
    super::ModelLimits {
        min_load_n: table.min_load_n,
        max_load_n: table.min_load_n + last * table.load_step_n,
        max_pressure_mpa: table.max_pressure_mpa,
    }
}

/// What one period's [`PreisachModel::follow`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Followed {
    /// The model's contraction at the measured pressure, from the relay
    /// states the pressure history left.
    pub predicted: f32,
    /// A load switch completed on this period: (from, to), N.
    pub switched: Option<(f32, f32)>,
    /// A load switch is under way (the coefficients in use are still the
    /// previous load's).
    pub switching: bool,
}

/// A validated Preisach table and the model running on it.
#[derive(Clone, Debug)]
pub struct PreisachModel {
    table: PreisachTable16,
    model: Preisach<PREISACH_ROWS>,
}

impl PreisachModel {
    /// The model for a validated table (pam-core's blob decoder validates
    /// it), with every relay off (the muscle empty) at `load_n`.
    pub fn new(table: PreisachTable16, load_n: f32) -> PreisachModel {
        let model = Preisach::new(&table, load_n, 0.0);
        PreisachModel { table, model }
    }

    /// The table.
    pub fn table(&self) -> &PreisachTable16 {
        &self.table
    }

    /// The running model (its relay states and active load).
    pub fn model(&self) -> &Preisach<PREISACH_ROWS> {
        &self.model
    }

    /// The calibrated load range (the table's first and last grid load)
    /// and the top pressure.
    pub fn limits(&self) -> super::ModelLimits {
        model_limits(&self.table)
    }

    /// The active load, N.
    pub fn load_n(&self) -> f32 {
        self.model.load_n()
    }

    /// One period's checked readings: the load (a switch starts beyond
    /// pam-core's threshold and is made a few rows a period), then the
    /// relays at the measured pressure, then the output.
    #[inline(always)]
    pub fn follow(&mut self, pressure_mpa: f32, load_n: f32) -> Followed {
        let before = self.model.load_n();
        self.model.update_load(&self.table, load_n);
        self.model.update_state(pressure_mpa);
        let after = self.model.load_n();
        Followed {
            predicted: self.model.output(),
            switched: (after != before).then_some((before, after)),
            switching: self.model.switching(),
        }
    }

    /// The set-point clamped to the model's stroke at the active load
    /// ([`Preisach::stroke`]): beyond it no pressure holds it, and the
    /// integrator would wind up chasing it.
    #[inline(always)]
    pub fn clamp_setpoint(&self, desired_contraction: f32) -> f32 {
        let (lo, hi) = self.model.stroke();
        pam_core::clamp(desired_contraction, lo, hi)
    }

    /// The feedforward pressure for `contraction`: pam-core's exact inverse
    /// from the present relay states, in `[0, max_pressure_mpa]`.
    #[inline(always)]
    pub fn feedforward_mpa(&self, contraction: f32) -> f32 {
        self.model.inverse_pressure_mpa(contraction)
    }
}

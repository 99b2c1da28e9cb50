//! What the controller reads and writes: the hardware bundle [`Io`], one
//! [`Sample`] of the three sensors, and the [`ValveCommand`].

use crate::hal::{ContractionSensor, LoadCell, PressureSensor, SafeState, SensorErrorKind};

/// The hardware a [`Controller`](super::Controller) drives: three sensors
/// and a valve.
///
/// Fields are public so a simulation can reach its mocks between steps.
#[derive(Debug)]
pub struct Io<P, X, L, V> {
    /// Chamber pressure.
    pub pressure: P,
    /// Muscle contraction.
    pub contraction: X,
    /// Load on the muscle.
    pub load: L,
    /// The valve (or valve pair).
    pub valve: V,
}

/// One sample of the three sensors, errors reduced to their kinds.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample {
    /// Chamber pressure, MPa gauge.
    pub pressure_mpa: Result<f32, SensorErrorKind>,
    /// Contraction, fraction of rest length.
    pub contraction: Result<f32, SensorErrorKind>,
    /// Load, N.
    pub load_n: Result<f32, SensorErrorKind>,
}

impl Sample {
    /// Read each sensor once.
    pub fn read<P, X, L>(pressure: &mut P, contraction: &mut X, load: &mut L) -> Sample
    where
        P: PressureSensor,
        X: ContractionSensor,
        L: LoadCell,
    {
        use crate::hal::SensorError;
        Sample {
            pressure_mpa: pressure.read_pressure_mpa(),
            contraction: contraction.read_contraction().map_err(|e| e.kind()),
            load_n: load.read_load_n().map_err(|e| e.kind()),
        }
    }

    /// The readings in the order of the monitor's rule table
    /// (pressure, contraction, load).
    #[inline(always)]
    pub(super) fn readings(&self) -> [Result<f32, SensorErrorKind>; 3] {
        [self.pressure_mpa, self.contraction, self.load_n]
    }
}

/// What the valve is told to do.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ValveCommand {
    /// Flow command in `[-1, 1]` ([`Valve::set_flow`](crate::hal::Valve::set_flow)).
    Flow(f32),
    /// The safe state ([`Valve::set_safe`](crate::hal::Valve::set_safe)).
    Safe(SafeState),
}

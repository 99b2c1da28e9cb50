//! The firmware's HAL traits implemented on the simulated rig.
//!
//! Each mock holds a shared handle to the [`Rig`]; the sensors convert the
//! rig's true state through the rig's noisy sensor models, and the PWM
//! channels record their duty, which [`valve_opening`] turns into the valve
//! paths' openings for the next plant interval. Faults are injectable on
//! every mock.

use crate::pneumatics::ValveOpening;
use crate::rig::Rig;
use firmware::hal::{
    ContractionSensor, Counts, ErrorType, LoadCell, PressureCalibration, PressureSensor,
    SensorErrorKind,
};
use std::cell::{Cell, RefCell};
use std::rc::Rc;

/// The rig, shared between the mocks and the bench loop.
pub type SharedRig = Rc<RefCell<Rig>>;

/// A sensor failure to inject, shared with the bench.
pub type InjectedError = Rc<Cell<Option<SensorErrorKind>>>;

/// A reading to inject in place of the rig's (NaN, a frozen value), shared
/// with the bench.
pub type InjectedValue = Rc<Cell<Option<f32>>>;

/// The last value a mock returned to the firmware (`None` after an error),
/// for the bench's records.
pub type Tap<T> = Rc<Cell<Option<T>>>;

/// The pressure transducer through the firmware's [`PressureSensor`] trait.
#[derive(Debug)]
pub struct SimPressure {
    /// The rig.
    pub rig: SharedRig,
    /// Calibration the firmware applies (the rig's transducer differs from
    /// it by its zero offset and slope tolerance, as real parts do).
    pub calibration: PressureCalibration,
    /// When set, every read fails with this kind.
    pub error: InjectedError,
    /// The code of the last read. Stuck, open-wire, short and drift faults
    /// are injected on the rig's transducer (`Rig::pressure_sensor.fault`).
    pub last_counts: Tap<u16>,
}

impl ErrorType for SimPressure {
    type Error = SensorErrorKind;
}

impl PressureSensor for SimPressure {
    fn read_counts(&mut self) -> Result<Counts, SensorErrorKind> {
        self.last_counts.set(None);
        if let Some(e) = self.error.get() {
            return Err(e);
        }
        let mut rig = self.rig.borrow_mut();
        let p = rig.chamber.pressure_mpa();
        let code = rig.pressure_sensor.read_code(p);
        self.last_counts.set(Some(code));
        Ok(Counts(code))
    }

    fn calibration(&self) -> &PressureCalibration {
        &self.calibration
    }
}

/// The contraction sensor through the firmware's [`ContractionSensor`] trait.
#[derive(Debug)]
pub struct SimContraction {
    /// The rig.
    pub rig: SharedRig,
    /// When set, every read fails with this kind.
    pub error: InjectedError,
    /// When set (and no error is), reads return this instead of the rig's value.
    pub value: InjectedValue,
    /// The last value read.
    pub last: Tap<f32>,
}

impl ErrorType for SimContraction {
    type Error = SensorErrorKind;
}

impl ContractionSensor for SimContraction {
    fn read_contraction(&mut self) -> Result<f32, SensorErrorKind> {
        self.last.set(None);
        if let Some(e) = self.error.get() {
            return Err(e);
        }
        let mut rig = self.rig.borrow_mut();
        let x = rig.muscle.contraction();
        // The rig's sensor is read even when overridden, so its noise
        // sequence does not depend on the injection.
        let measured = rig.contraction_sensor.read(x) as f32;
        let v = self.value.get().unwrap_or(measured);
        self.last.set(Some(v));
        Ok(v)
    }
}

/// The load cell through the firmware's [`LoadCell`] trait.
#[derive(Debug)]
pub struct SimLoad {
    /// The rig.
    pub rig: SharedRig,
    /// When set, every read fails with this kind.
    pub error: InjectedError,
    /// When set (and no error is), reads return this instead of the rig's value.
    pub value: InjectedValue,
    /// The last value read.
    pub last: Tap<f32>,
}

impl ErrorType for SimLoad {
    type Error = SensorErrorKind;
}

impl LoadCell for SimLoad {
    fn read_load_n(&mut self) -> Result<f32, SensorErrorKind> {
        self.last.set(None);
        if let Some(e) = self.error.get() {
            return Err(e);
        }
        let mut rig = self.rig.borrow_mut();
        let l = rig.true_state().load_n;
        let measured = rig.load_cell.read_n(l) as f32;
        let v = self.value.get().unwrap_or(measured);
        self.last.set(Some(v));
        Ok(v)
    }
}

impl SimPressure {
    /// The rig's transducer read through `calibration`, nothing injected.
    pub fn new(rig: SharedRig, calibration: PressureCalibration) -> SimPressure {
        SimPressure {
            rig,
            calibration,
            error: InjectedError::default(),
            last_counts: Tap::default(),
        }
    }
}

impl SimContraction {
    /// The rig's contraction sensor, nothing injected.
    pub fn new(rig: SharedRig) -> SimContraction {
        SimContraction {
            rig,
            error: InjectedError::default(),
            value: InjectedValue::default(),
            last: Tap::default(),
        }
    }
}

impl SimLoad {
    /// The rig's load cell, nothing injected.
    pub fn new(rig: SharedRig) -> SimLoad {
        SimLoad {
            rig,
            error: InjectedError::default(),
            value: InjectedValue::default(),
            last: Tap::default(),
        }
    }
}

/// Error of a [`SimPwm`] write (injected).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimPwmError;

impl embedded_hal::pwm::Error for SimPwmError {
    fn kind(&self) -> embedded_hal::pwm::ErrorKind {
        embedded_hal::pwm::ErrorKind::Other
    }
}

/// A PWM channel driving a valve coil: records its duty.
#[derive(Clone, Debug)]
pub struct SimPwm {
    /// Duty now, counts of [`SimPwm::MAX_DUTY`].
    pub duty: Rc<Cell<u16>>,
    /// When true, writes fail.
    pub fail: Rc<Cell<bool>>,
}

impl SimPwm {
    /// Full-scale duty (a 16-bit timer at 25 Hz PWM has more; 1000 is enough).
    pub const MAX_DUTY: u16 = 1000;

    /// A channel at zero duty.
    pub fn new() -> SimPwm {
        SimPwm {
            duty: Rc::new(Cell::new(0)),
            fail: Rc::new(Cell::new(false)),
        }
    }

    /// Duty as a fraction of full scale.
    pub fn fraction(&self) -> f64 {
        f64::from(self.duty.get()) / f64::from(Self::MAX_DUTY)
    }
}

impl Default for SimPwm {
    fn default() -> Self {
        SimPwm::new()
    }
}

impl embedded_hal::pwm::ErrorType for SimPwm {
    type Error = SimPwmError;
}

impl embedded_hal::pwm::SetDutyCycle for SimPwm {
    fn max_duty_cycle(&self) -> u16 {
        Self::MAX_DUTY
    }

    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), SimPwmError> {
        if self.fail.get() {
            return Err(SimPwmError);
        }
        self.duty.set(duty.min(Self::MAX_DUTY));
        Ok(())
    }
}

/// How the simulated valves turn PWM duty into flow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValveKind {
    /// Inlet and exhaust on/off valves: at PWM rates far above the chamber's
    /// bandwidth the opening averages to the duty, less the part of each
    /// period the coil needs to open the valve (`dead_duty`).
    OnOffPair {
        /// Duty below which the valve does not open at all.
        dead_duty: f64,
    },
    /// One proportional 3/3 valve, closed at 50 % duty, with a spool overlap
    /// of `overlap` (fraction of full duty) either side of the centre.
    Proportional {
        /// Spool overlap, fraction of full duty.
        overlap: f64,
    },
}

impl ValveKind {
    /// A pair of 2 ms valves at 25 Hz PWM (5 % dead duty).
    pub const PAIR: ValveKind = ValveKind::OnOffPair { dead_duty: 0.05 };
    /// A proportional valve with 2 % overlap.
    pub const PROPORTIONAL: ValveKind = ValveKind::Proportional { overlap: 0.02 };
}

/// Openings of the valve paths for the duties of `first` (inlet, or the
/// proportional valve's only channel) and `second` (exhaust; ignored for a
/// proportional valve).
pub fn valve_opening(kind: ValveKind, first: f64, second: f64) -> ValveOpening {
    match kind {
        ValveKind::OnOffPair { dead_duty } => {
            let open = |d: f64| ((d - dead_duty) / (1.0 - dead_duty)).clamp(0.0, 1.0);
            ValveOpening {
                inlet: open(first),
                exhaust: open(second),
            }
        }
        ValveKind::Proportional { overlap } => {
            let span = 0.5 - overlap;
            ValveOpening {
                inlet: ((first - 0.5 - overlap) / span).clamp(0.0, 1.0),
                exhaust: ((0.5 - overlap - first) / span).clamp(0.0, 1.0),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal::pwm::SetDutyCycle;

    #[test]
    fn sensors_read_the_rig_through_the_firmware_traits() {
        let rig: SharedRig = Rc::new(RefCell::new(Rig::reference(200.0, 4)));
        rig.borrow_mut().advance_regulated(0.3, 3.0);
        let err: InjectedError = Rc::new(Cell::new(None));
        let mut p = SimPressure {
            error: err.clone(),
            ..SimPressure::new(rig.clone(), PressureCalibration::ADC12_0_1MPA)
        };
        let mpa = p.read_pressure_mpa().unwrap();
        // Offset +3 kPa, noise 0.8 kPa RMS.
        assert!((mpa - 0.303).abs() < 0.005, "{mpa}");
        let mut x = SimContraction {
            error: err.clone(),
            ..SimContraction::new(rig.clone())
        };
        let true_x = rig.borrow().muscle.contraction() as f32;
        assert!((x.read_contraction().unwrap() - true_x).abs() < 0.002);
        let mut l = SimLoad {
            error: err.clone(),
            ..SimLoad::new(rig.clone())
        };
        assert!((l.read_load_n().unwrap() - 200.0).abs() < 8.0);
        assert!(p.last_counts.get().is_some() && l.last.get().is_some());
        l.value.set(Some(f32::NAN));
        assert!(l.read_load_n().unwrap().is_nan());
        l.value.set(None);
        err.set(Some(SensorErrorKind::Timeout));
        assert_eq!(p.read_pressure_mpa(), Err(SensorErrorKind::Timeout));
        assert_eq!(x.read_contraction(), Err(SensorErrorKind::Timeout));
        // An open transducer line reads code 0: outside the valid window.
        err.set(None);
        rig.borrow_mut().pressure_sensor.fault = crate::sensors::PressureFault::OpenWire;
        assert_eq!(p.read_pressure_mpa(), Err(SensorErrorKind::InvalidCode));
    }

    #[test]
    fn pwm_records_duty_and_fails_on_demand() {
        let mut pwm = SimPwm::new();
        pwm.set_duty_cycle_fraction(1, 4).unwrap();
        assert_eq!(pwm.duty.get(), 250);
        pwm.fail.set(true);
        assert_eq!(pwm.set_duty_cycle(10), Err(SimPwmError));
        assert_eq!(pwm.duty.get(), 250);
    }

    #[test]
    fn valve_openings() {
        let pair = valve_opening(ValveKind::PAIR, 0.05, 1.0);
        assert_eq!(
            pair,
            ValveOpening {
                inlet: 0.0,
                exhaust: 1.0
            }
        );
        let half = valve_opening(ValveKind::PAIR, 0.525, 0.0);
        assert!((half.inlet - 0.5).abs() < 1e-12);
        let closed = valve_opening(ValveKind::PROPORTIONAL, 0.51, 0.0);
        assert_eq!(closed, ValveOpening::default());
        let full = valve_opening(ValveKind::PROPORTIONAL, 1.0, 0.0);
        assert_eq!(full.inlet, 1.0);
        let vent = valve_opening(ValveKind::PROPORTIONAL, 0.0, 0.0);
        assert_eq!(vent.exhaust, 1.0);
    }
}

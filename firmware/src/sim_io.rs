//! The firmware's HAL traits on a simulation: the one set of simulated
//! sensors and PWM channels that every bench running the controller off a
//! board uses — the self-test images, this crate's tests and bench-m4 (on
//! [`crate::plant::SimBus`]) and host-sim (on its physical rig).
//!
//! * [`SimPressure`], [`SimContraction`] and [`SimLoad`] ask their
//!   [`SensorSource`] at the moment the controller reads them. The source is
//!   the simulation behind the sensors: its sensor models, its noise and its
//!   injected faults. [`crate::plant::SimBus`] returns values published
//!   before each step; host-sim's rig draws each sensor's noise at the read.
//! * [`SimPwm`] writes its duty into a [`DutyRegister`] the simulation reads
//!   (a [`Cell`], or an atomic a panic handler can reach), saturating at
//!   [`PWM_MAX_DUTY`] as a timer's compare register does, and fails its
//!   writes while its [`FailSwitch`] is on ([`NeverFails`]: never, and the
//!   error type is [`Infallible`]).
//!
//! Nothing here allocates or panics; the types cost nothing in an image that
//! does not use them.

use core::cell::Cell;
use core::convert::Infallible;
use core::ops::Deref;
use core::sync::atomic::{AtomicU16, Ordering};

use crate::hal::{
    ContractionSensor, Counts, ErrorType, LoadCell, PressureCalibration, PressureSensor,
    SensorErrorKind,
};
use embedded_hal::pwm::{ErrorType as PwmErrorType, SetDutyCycle};

/// What simulated sensors return when the controller reads them: the
/// simulation behind [`SimPressure`], [`SimContraction`] and [`SimLoad`].
/// Each method is called once per read of its sensor, in the controller's
/// order, so a source may draw its noise there.
pub trait SensorSource {
    /// The pressure transducer's code, or the error the read fails with.
    fn pressure_counts(&self) -> Result<Counts, SensorErrorKind>;
    /// The contraction sensor's reading (fraction of rest length), or the
    /// error the read fails with.
    fn contraction(&self) -> Result<f32, SensorErrorKind>;
    /// The load cell's reading, N, or the error the read fails with.
    fn load_n(&self) -> Result<f32, SensorErrorKind>;
}

/// Simulated pressure sensor: the code of its [`SensorSource`], read
/// through `calibration`.
#[derive(Clone, Debug)]
pub struct SimPressure<S> {
    /// The simulation it reads (a reference or shared handle to it).
    pub source: S,
    /// The calibration the firmware applies.
    pub calibration: PressureCalibration,
}

impl<S> ErrorType for SimPressure<S> {
    type Error = SensorErrorKind;
}

impl<S> PressureSensor for SimPressure<S>
where
    S: Deref,
    S::Target: SensorSource,
{
    fn read_counts(&mut self) -> Result<Counts, SensorErrorKind> {
        self.source.pressure_counts()
    }
    fn calibration(&self) -> &PressureCalibration {
        &self.calibration
    }
}

/// Simulated contraction sensor on a [`SensorSource`] (a reference or
/// shared handle to it).
#[derive(Clone, Debug)]
pub struct SimContraction<S>(pub S);

impl<S> ErrorType for SimContraction<S> {
    type Error = SensorErrorKind;
}

impl<S> ContractionSensor for SimContraction<S>
where
    S: Deref,
    S::Target: SensorSource,
{
    fn read_contraction(&mut self) -> Result<f32, SensorErrorKind> {
        self.0.contraction()
    }
}

/// Simulated load cell on a [`SensorSource`] (a reference or shared handle
/// to it).
#[derive(Clone, Debug)]
pub struct SimLoad<S>(pub S);

impl<S> ErrorType for SimLoad<S> {
    type Error = SensorErrorKind;
}

impl<S> LoadCell for SimLoad<S>
where
    S: Deref,
    S::Target: SensorSource,
{
    fn read_load_n(&mut self) -> Result<f32, SensorErrorKind> {
        self.0.load_n()
    }
}

/// Full-scale duty of a [`SimPwm`] (a timer with auto-reload 999).
pub const PWM_MAX_DUTY: u16 = 1000;

/// Where a [`SimPwm`] keeps its duty, counts of [`PWM_MAX_DUTY`].
pub trait DutyRegister {
    /// The duty written last.
    fn duty(&self) -> u16;
    /// Write the duty.
    fn set_duty(&self, duty: u16);
}

impl DutyRegister for Cell<u16> {
    fn duty(&self) -> u16 {
        self.get()
    }
    fn set_duty(&self, duty: u16) {
        self.set(duty);
    }
}

/// A `static` register, so a panic or exception handler can reach it.
impl DutyRegister for AtomicU16 {
    fn duty(&self) -> u16 {
        self.load(Ordering::Relaxed)
    }
    fn set_duty(&self, duty: u16) {
        self.store(duty, Ordering::Relaxed);
    }
}

/// Whether a [`SimPwm`]'s writes fail.
pub trait FailSwitch {
    /// The error a failed write returns.
    type Error: embedded_hal::pwm::Error;
    /// `Err` when the write is to fail.
    fn check(&self) -> Result<(), Self::Error>;
}

/// A channel whose writes never fail.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NeverFails;

impl FailSwitch for NeverFails {
    type Error = Infallible;
    fn check(&self) -> Result<(), Infallible> {
        Ok(())
    }
}

/// Error of a [`SimPwm`] write whose fail switch is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimPwmError;

impl embedded_hal::pwm::Error for SimPwmError {
    fn kind(&self) -> embedded_hal::pwm::ErrorKind {
        embedded_hal::pwm::ErrorKind::Other
    }
}

/// A switch the bench turns (a reference or shared handle to a
/// `Cell<bool>`): writes fail with [`SimPwmError`] while it is `true`.
impl<T: Deref<Target = Cell<bool>>> FailSwitch for T {
    type Error = SimPwmError;
    fn check(&self) -> Result<(), SimPwmError> {
        if self.get() {
            Err(SimPwmError)
        } else {
            Ok(())
        }
    }
}

/// A simulated PWM channel driving a valve coil: writes its duty into the
/// register `duty` points to, unless `fail` fails the write.
#[derive(Clone, Debug, Default)]
pub struct SimPwm<D, F = NeverFails> {
    /// The duty register (a reference or shared handle to it).
    pub duty: D,
    /// The fail switch.
    pub fail: F,
}

impl<D> SimPwm<D> {
    /// A channel on `duty` whose writes never fail.
    pub const fn new(duty: D) -> SimPwm<D> {
        SimPwm {
            duty,
            fail: NeverFails,
        }
    }
}

impl<D, F> SimPwm<D, F>
where
    D: Deref,
    D::Target: DutyRegister,
{
    /// Duty as a fraction of full scale.
    pub fn fraction(&self) -> f64 {
        f64::from(self.duty.duty()) / f64::from(PWM_MAX_DUTY)
    }
}

impl<D, F: FailSwitch> PwmErrorType for SimPwm<D, F> {
    type Error = F::Error;
}

impl<D, F> SetDutyCycle for SimPwm<D, F>
where
    D: Deref,
    D::Target: DutyRegister,
    F: FailSwitch,
{
    fn max_duty_cycle(&self) -> u16 {
        PWM_MAX_DUTY
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), F::Error> {
        self.fail.check()?;
        // A timer's compare register saturates at the reload value.
        self.duty.set_duty(duty.min(PWM_MAX_DUTY));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A source with fixed readings that fails the contraction read.
    struct Fixed;

    impl SensorSource for Fixed {
        fn pressure_counts(&self) -> Result<Counts, SensorErrorKind> {
            Ok(Counts(2048))
        }
        fn contraction(&self) -> Result<f32, SensorErrorKind> {
            Err(SensorErrorKind::Bus)
        }
        fn load_n(&self) -> Result<f32, SensorErrorKind> {
            Ok(200.0)
        }
    }

    #[test]
    fn sensors_read_their_source() {
        let mut p = SimPressure {
            source: &Fixed,
            calibration: PressureCalibration::ADC12_0_1MPA,
        };
        assert_eq!(p.read_counts(), Ok(Counts(2048)));
        assert_eq!(
            SimContraction(&Fixed).read_contraction(),
            Err(SensorErrorKind::Bus)
        );
        assert_eq!(SimLoad(&Fixed).read_load_n(), Ok(200.0));
    }

    #[test]
    fn pwm_saturates_and_fails_on_demand() {
        let duty = Cell::new(0u16);
        let mut pwm = SimPwm::new(&duty);
        pwm.set_duty_cycle(1500).unwrap();
        assert_eq!(duty.get(), PWM_MAX_DUTY);
        pwm.set_duty_cycle_fraction(1, 4).unwrap();
        assert_eq!((duty.get(), pwm.fraction()), (250, 0.25));

        let fail = Cell::new(false);
        let mut switched = SimPwm {
            duty: &duty,
            fail: &fail,
        };
        switched.set_duty_cycle(10).unwrap();
        fail.set(true);
        assert_eq!(switched.set_duty_cycle(20), Err(SimPwmError));
        assert_eq!(duty.get(), 10);

        static REGISTER: AtomicU16 = AtomicU16::new(0);
        let mut atomic = SimPwm::new(&REGISTER);
        atomic.set_duty_cycle(PWM_MAX_DUTY + 1).unwrap();
        assert_eq!(REGISTER.load(Ordering::Relaxed), PWM_MAX_DUTY);
    }
}

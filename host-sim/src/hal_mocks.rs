//! The rig behind the firmware's simulated sensors and PWM channels.
//!
//! The mocks themselves are the firmware's ([`firmware::sim_io`]: one set
//! for every bench). Here is what they read and drive on this rig:
//! [`RigSensors`], the [`SensorSource`] that converts the rig's true state
//! through its noisy sensor models at each read, with the bench's injection
//! hooks on every sensor; [`RigPwm`], a channel whose duty and fail switch
//! the bench shares; and [`valve_opening`], which turns the channels' duties
//! into the valve paths' openings for the next plant interval.

use crate::pneumatics::ValveOpening;
use crate::rig::Rig;
use firmware::controller::Io;
use firmware::hal::{
    Counts, HalConfigError, PressureCalibration, SensorErrorKind, ValvePair, ValvePairConfig,
};
use firmware::sim_io::{SensorSource, SimContraction, SimLoad, SimPressure, SimPwm};
use std::cell::{Cell, RefCell};
use std::rc::Rc;

/// The rig, shared between the sensors and the bench loop.
pub type SharedRig = Rc<RefCell<Rig>>;

/// The rig's sensors, shared between the firmware's simulated sensors and
/// the bench (which injects through them).
pub type SharedSensors = Rc<RigSensors>;

/// A PWM channel driving one of the rig's valve coils: its duty (counts of
/// [`firmware::sim_io::PWM_MAX_DUTY`]) and its fail switch (writes fail
/// while it is `true`), both shared with the bench.
pub type RigPwm = SimPwm<Rc<Cell<u16>>, Rc<Cell<bool>>>;

/// What the bench injects into one sensor's reads, and what the sensor last
/// returned.
#[derive(Debug)]
pub struct Injection<T: Copy> {
    /// When set, every read fails with this kind.
    pub error: Cell<Option<SensorErrorKind>>,
    /// When set (and no error is), reads return this instead of the rig's
    /// value. Stuck, open-wire, short and drift faults of the pressure
    /// transducer are injected on the rig (`Rig::pressure_sensor.fault`).
    pub value: Cell<Option<T>>,
    /// The value of the last read (`None` after an error), for the bench's
    /// records.
    pub last: Cell<Option<T>>,
}

impl<T: Copy> Default for Injection<T> {
    fn default() -> Self {
        Injection {
            error: Cell::new(None),
            value: Cell::new(None),
            last: Cell::new(None),
        }
    }
}

impl<T: Copy> Injection<T> {
    /// One read: the injected error, else the injected value or the
    /// sensor's `measured` reading. The sensor is read even when its value
    /// is overridden, so its noise sequence does not depend on the
    /// injection.
    fn read(&self, measured: impl FnOnce() -> T) -> Result<T, SensorErrorKind> {
        self.last.set(None);
        if let Some(e) = self.error.get() {
            return Err(e);
        }
        let measured = measured();
        let v = self.value.get().unwrap_or(measured);
        self.last.set(Some(v));
        Ok(v)
    }
}

/// The rig's pressure transducer, contraction sensor and load cell, read
/// through their noisy models when the firmware reads them, with an
/// [`Injection`] on each.
#[derive(Debug)]
pub struct RigSensors {
    /// The rig.
    pub rig: SharedRig,
    /// The pressure transducer's code.
    pub pressure: Injection<u16>,
    /// The contraction sensor.
    pub contraction: Injection<f32>,
    /// The load cell.
    pub load: Injection<f32>,
}

impl RigSensors {
    /// The sensors of `rig`, nothing injected.
    pub fn new(rig: SharedRig) -> SharedSensors {
        Rc::new(RigSensors {
            rig,
            pressure: Injection::default(),
            contraction: Injection::default(),
            load: Injection::default(),
        })
    }
}

impl SensorSource for RigSensors {
    fn pressure_counts(&self) -> Result<Counts, SensorErrorKind> {
        self.pressure
            .read(|| {
                let mut rig = self.rig.borrow_mut();
                let p = rig.chamber.pressure_mpa();
                rig.pressure_sensor.read_code(p)
            })
            .map(Counts)
    }

    fn contraction(&self) -> Result<f32, SensorErrorKind> {
        self.contraction.read(|| {
            let mut rig = self.rig.borrow_mut();
            let x = rig.muscle.contraction();
            rig.contraction_sensor.read(x) as f32
        })
    }

    fn load_n(&self) -> Result<f32, SensorErrorKind> {
        self.load.read(|| {
            let mut rig = self.rig.borrow_mut();
            let l = rig.true_state().load_n;
            rig.load_cell.read_n(l) as f32
        })
    }
}

/// The simulated valve pair.
pub type PairValve = ValvePair<RigPwm, RigPwm>;
/// The hardware the controller drives: the firmware's simulated sensors on
/// [`RigSensors`] and a valve pair of [`RigPwm`]s.
pub type SimIo = Io<
    SimPressure<SharedSensors>,
    SimContraction<SharedSensors>,
    SimLoad<SharedSensors>,
    PairValve,
>;

/// The controller's hardware on a rig, with the bench's handles to it.
#[derive(Debug)]
pub struct RigIo {
    /// What the controller reads and drives.
    pub io: SimIo,
    /// The rig's sensors (injection and the last reads).
    pub sensors: SharedSensors,
    /// The inlet channel.
    pub inlet: RigPwm,
    /// The exhaust channel.
    pub exhaust: RigPwm,
}

/// The firmware's hardware on `rig`: its sensors, the transducer read
/// through the ADC12 0–1 MPa calibration (the rig's transducer differs from
/// it by its zero offset and slope tolerance, as real parts do), and an
/// on/off valve pair with the default configuration, both channels at zero
/// duty; nothing injected.
pub fn rig_io(rig: &SharedRig) -> Result<RigIo, HalConfigError> {
    let sensors = RigSensors::new(rig.clone());
    let (inlet, exhaust) = (RigPwm::default(), RigPwm::default());
    let io = Io {
        pressure: SimPressure {
            source: sensors.clone(),
            calibration: PressureCalibration::ADC12_0_1MPA,
        },
        contraction: SimContraction(sensors.clone()),
        load: SimLoad(sensors.clone()),
        valve: ValvePair::new(inlet.clone(), exhaust.clone(), ValvePairConfig::DEFAULT)?,
    };
    Ok(RigIo {
        io,
        sensors,
        inlet,
        exhaust,
    })
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
    use firmware::hal::{ContractionSensor, LoadCell, PressureSensor};
    use firmware::sim_io::SimPwmError;

    #[test]
    fn sensors_read_the_rig_through_the_firmware_traits() {
        let rig: SharedRig = Rc::new(RefCell::new(Rig::reference(200.0, 4)));
        rig.borrow_mut().advance_regulated(0.3, 3.0);
        let RigIo {
            io:
                Io {
                    pressure: mut p,
                    contraction: mut x,
                    load: mut l,
                    ..
                },
            sensors,
            ..
        } = rig_io(&rig).unwrap();
        let mpa = p.read_pressure_mpa().unwrap();
        // Offset +3 kPa, noise 0.8 kPa RMS.
        assert!((mpa - 0.303).abs() < 0.005, "{mpa}");
        let true_x = rig.borrow().muscle.contraction() as f32;
        assert!((x.read_contraction().unwrap() - true_x).abs() < 0.002);
        assert!((l.read_load_n().unwrap() - 200.0).abs() < 8.0);
        assert!(sensors.pressure.last.get().is_some() && sensors.load.last.get().is_some());
        sensors.load.value.set(Some(f32::NAN));
        assert!(l.read_load_n().unwrap().is_nan());
        sensors.load.value.set(None);
        sensors.pressure.error.set(Some(SensorErrorKind::Timeout));
        sensors
            .contraction
            .error
            .set(Some(SensorErrorKind::Timeout));
        assert_eq!(p.read_pressure_mpa(), Err(SensorErrorKind::Timeout));
        assert_eq!(x.read_contraction(), Err(SensorErrorKind::Timeout));
        assert_eq!(sensors.contraction.last.get(), None);
        // An open transducer line reads code 0: outside the valid window.
        sensors.pressure.error.set(None);
        rig.borrow_mut().pressure_sensor.fault = crate::sensors::PressureFault::OpenWire;
        assert_eq!(p.read_pressure_mpa(), Err(SensorErrorKind::InvalidCode));
    }

    #[test]
    fn pwm_records_duty_and_fails_on_demand() {
        let mut pwm = RigPwm::default();
        let bench = pwm.clone();
        pwm.set_duty_cycle_fraction(1, 4).unwrap();
        assert_eq!((bench.duty.get(), bench.fraction()), (250, 0.25));
        bench.fail.set(true);
        assert_eq!(pwm.set_duty_cycle(10), Err(SimPwmError));
        assert_eq!(bench.duty.get(), 250);
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

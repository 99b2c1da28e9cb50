//! Hardware traits the controller is generic over, in the shape of
//! embedded-hal 1.0: fallible methods, an [`ErrorType`] with an error that
//! maps to a `#[non_exhaustive]` [`SensorErrorKind`], blanket impls for
//! `&mut T`, optional `defmt::Format`.
//!
//! * [`PressureSensor`]: raw converter [`Counts`] plus a [`PressureCalibration`]
//!   to MPa (gauge).
//! * [`ContractionSensor`]: contraction as a fraction of rest length.
//! * [`LoadCell`]: the load on the muscle, N. The load is *measured*, not
//!   estimated: the model family is indexed by load (eqs. 16–21), and an
//!   estimate from pressure and contraction would have to invert that same
//!   family, where on the hysteresis loop a heavier load on the expansion
//!   branch and a lighter load on the contraction branch give the same
//!   pressure–contraction pair (the loop height `2·be` is comparable to the
//!   pressure change of a load step). A load cell in series with the muscle
//!   is also what rehabilitation orthoses already carry for interaction force.
//! * [`Valve`]: a flow command in `[-1, 1]` turned into PWM duty through
//!   [`SetDutyCycle`], by [`ProportionalValve`] (one proportional flow valve)
//!   or [`ValvePair`] (an inlet and an exhaust on/off valve).
//!
//! Valve errors use embedded-hal's own [`embedded_hal::pwm::Error`] and
//! [`embedded_hal::pwm::ErrorType`].

pub use embedded_hal::pwm::SetDutyCycle;
use embedded_hal::pwm::{Error as PwmError, ErrorKind as PwmErrorKind, ErrorType as PwmErrorType};

/// What went wrong reading a sensor, in a form the controller can act on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SensorErrorKind {
    /// The bus to the converter failed (SPI, I²C, ADC DMA overrun).
    Bus,
    /// No conversion arrived in time.
    Timeout,
    /// The converter returned a code outside the sensor's valid window (an
    /// open or shorted transducer line).
    InvalidCode,
    /// Anything else.
    Other,
}

impl core::fmt::Display for SensorErrorKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            SensorErrorKind::Bus => "bus error",
            SensorErrorKind::Timeout => "conversion timed out",
            SensorErrorKind::InvalidCode => "code outside the valid window",
            SensorErrorKind::Other => "sensor error",
        })
    }
}

/// Why a calibration or a valve setting was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HalConfigError {
    /// The calibration's slope (`mpa_per_count`, `units_per_count`) is zero
    /// or not finite.
    Slope,
    /// The calibration's `zero_counts` is not finite.
    Zero,
    /// The calibration's `min_valid` exceeds `max_valid`.
    Window,
    /// A [`ValvePairConfig::deadband`] outside `[0, 1)`.
    Deadband,
    /// A [`ValvePairConfig::min_open_duty`] outside `[0, 1)`.
    MinOpenDuty,
    /// A [`ProportionalValve`] closed duty outside `(0, 1)`.
    ClosedDuty,
}

impl core::fmt::Display for HalConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            HalConfigError::Slope => "calibration slope must be finite and non-zero",
            HalConfigError::Zero => "calibration zero_counts must be finite",
            HalConfigError::Window => "calibration min_valid must not exceed max_valid",
            HalConfigError::Deadband => "valve deadband must be in [0, 1)",
            HalConfigError::MinOpenDuty => "valve min_open_duty must be in [0, 1)",
            HalConfigError::ClosedDuty => "valve closed_duty must be in (0, 1)",
        })
    }
}

impl core::error::Error for HalConfigError {}

/// A sensor error: any type that can say which [`SensorErrorKind`] it is.
pub trait SensorError: core::fmt::Debug {
    /// The generic kind of this error.
    fn kind(&self) -> SensorErrorKind;
}

impl SensorError for SensorErrorKind {
    fn kind(&self) -> SensorErrorKind {
        *self
    }
}

impl SensorError for core::convert::Infallible {
    fn kind(&self) -> SensorErrorKind {
        match *self {}
    }
}

/// The error type of a sensor.
pub trait ErrorType {
    /// Error returned by the sensor's read methods.
    type Error: SensorError;
}

impl<T: ErrorType + ?Sized> ErrorType for &mut T {
    type Error = T::Error;
}

/// A raw converter code (ADC counts), before calibration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counts(pub u16);

/// Affine calibration of a pressure transducer: `pressure_mpa = (counts −
/// zero_counts) · mpa_per_count`, valid only for codes in
/// `[min_valid, max_valid]`.
///
/// Transducers with a live zero (for example 0.5–4.5 V ratiometric) never
/// output codes near 0 or full scale when healthy, so codes outside the
/// window are a broken line, not a pressure.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PressureCalibration {
    /// Code at 0 MPa gauge.
    pub zero_counts: f32,
    /// MPa per count (the slope; must be finite and non-zero).
    pub mpa_per_count: f32,
    /// Lowest valid code.
    pub min_valid: Counts,
    /// Highest valid code.
    pub max_valid: Counts,
}

impl PressureCalibration {
    /// A 12-bit ADC reading a 0.5–4.5 V, 0–1 MPa transducer through a 5 V →
    /// 3.3 V divider: 0 MPa at 409.6 counts, 1 MPa at 3686.4 counts; codes
    /// below 200 or above 3900 are a broken line.
    pub const ADC12_0_1MPA: PressureCalibration = PressureCalibration {
        zero_counts: 409.6,
        mpa_per_count: 1.0 / 3276.8,
        min_valid: Counts(200),
        max_valid: Counts(3900),
    };

    /// The same calibration as a [`LinearCalibration`] in MPa: the checks
    /// and the conversion are that one's.
    #[inline]
    pub const fn linear(&self) -> LinearCalibration {
        LinearCalibration {
            zero_counts: self.zero_counts,
            units_per_count: self.mpa_per_count,
            min_valid: self.min_valid,
            max_valid: self.max_valid,
        }
    }

    /// Check that the calibration can convert: finite, non-zero slope,
    /// finite zero, non-empty window.
    pub fn validate(&self) -> Result<(), HalConfigError> {
        self.linear().validate()
    }

    /// Counts to MPa; a code outside the valid window is
    /// [`SensorErrorKind::InvalidCode`].
    #[inline]
    pub fn to_mpa(&self, counts: Counts) -> Result<f32, SensorErrorKind> {
        self.linear().to_value(counts)
    }

    /// MPa to the nearest code, saturating at the converter's range
    /// `[0, u16::MAX]` (NaN → 0). For simulated sensors.
    pub fn to_counts(&self, pressure_mpa: f32) -> Counts {
        let c = pressure_mpa / self.mpa_per_count + self.zero_counts + 0.5;
        // `as` saturates and maps NaN to 0: the documented clamp.
        Counts(c as u16)
    }
}

/// Affine calibration of an analog sensor other than pressure (a
/// potentiometer for contraction, an amplified strain gauge for load):
/// `value = (counts − zero_counts) · units_per_count`, valid only for codes
/// in `[min_valid, max_valid]`.
///
/// As for [`PressureCalibration`], the window rejects codes that a healthy
/// sensor cannot produce (an open wiper pulled to a rail, a saturated
/// amplifier) with [`SensorErrorKind::InvalidCode`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinearCalibration {
    /// Code at a value of 0.
    pub zero_counts: f32,
    /// Value per count (the slope; must be finite and non-zero; negative for
    /// a sensor mounted the other way round).
    pub units_per_count: f32,
    /// Lowest valid code.
    pub min_valid: Counts,
    /// Highest valid code.
    pub max_valid: Counts,
}

impl LinearCalibration {
    /// Check that the calibration can convert: finite, non-zero slope,
    /// finite zero, non-empty window.
    pub fn validate(&self) -> Result<(), HalConfigError> {
        if !(self.units_per_count.is_finite() && self.units_per_count != 0.0) {
            return Err(HalConfigError::Slope);
        }
        if !self.zero_counts.is_finite() {
            return Err(HalConfigError::Zero);
        }
        if self.min_valid > self.max_valid {
            return Err(HalConfigError::Window);
        }
        Ok(())
    }

    /// Counts to the sensor's unit; a code outside the valid window is
    /// [`SensorErrorKind::InvalidCode`].
    pub fn to_value(&self, counts: Counts) -> Result<f32, SensorErrorKind> {
        if counts < self.min_valid || counts > self.max_valid {
            return Err(SensorErrorKind::InvalidCode);
        }
        Ok((f32::from(counts.0) - self.zero_counts) * self.units_per_count)
    }
}

/// A pressure transducer on the muscle's chamber.
pub trait PressureSensor: ErrorType {
    /// One conversion, raw counts.
    fn read_counts(&mut self) -> Result<Counts, Self::Error>;

    /// The calibration from counts to MPa.
    fn calibration(&self) -> &PressureCalibration;

    /// One conversion in MPa (gauge): [`read_counts`](Self::read_counts)
    /// through [`calibration`](Self::calibration); a read error is reported
    /// by its kind.
    fn read_pressure_mpa(&mut self) -> Result<f32, SensorErrorKind> {
        let counts = self.read_counts().map_err(|e| e.kind())?;
        self.calibration().to_mpa(counts)
    }
}

impl<T: PressureSensor + ?Sized> PressureSensor for &mut T {
    fn read_counts(&mut self) -> Result<Counts, Self::Error> {
        T::read_counts(self)
    }
    fn calibration(&self) -> &PressureCalibration {
        T::calibration(self)
    }
}

/// A length sensor on the muscle (linear potentiometer, encoder on the joint).
pub trait ContractionSensor: ErrorType {
    /// Contraction `(L0 − L)/L0` as a fraction of the rest length `L0`.
    fn read_contraction(&mut self) -> Result<f32, Self::Error>;
}

impl<T: ContractionSensor + ?Sized> ContractionSensor for &mut T {
    fn read_contraction(&mut self) -> Result<f32, Self::Error> {
        T::read_contraction(self)
    }
}

/// A load cell in series with the muscle (see the module docs for why the
/// load is measured rather than estimated).
pub trait LoadCell: ErrorType {
    /// Tension on the muscle, N.
    fn read_load_n(&mut self) -> Result<f32, Self::Error>;
}

impl<T: LoadCell + ?Sized> LoadCell for &mut T {
    fn read_load_n(&mut self) -> Result<f32, Self::Error> {
        T::read_load_n(self)
    }
}

/// What the valves do when the controller is in a fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SafeState {
    /// Vent the muscle: inlet closed, exhaust fully open. The muscle goes
    /// limp and the orthosis joint follows the patient (the default).
    Exhaust,
    /// Close both ways and hold the air in the muscle (for set-ups where a
    /// limp muscle would drop a load).
    Hold,
}

/// A valve (or valve set) driven by a flow command.
///
/// `command` is in `[-1, 1]`: `+1` fills at the full rate, `−1` vents at the
/// full rate, `0` holds (both ways closed). Implementations clamp the command
/// to `[-1, 1]` and treat NaN as `0`.
pub trait Valve: PwmErrorType {
    /// Drive the valve with a flow command.
    fn set_flow(&mut self, command: f32) -> Result<(), Self::Error>;

    /// Put the valve in a safe state.
    fn set_safe(&mut self, state: SafeState) -> Result<(), Self::Error>;
}

impl<T: Valve + ?Sized> Valve for &mut T {
    fn set_flow(&mut self, command: f32) -> Result<(), Self::Error> {
        T::set_flow(self, command)
    }
    fn set_safe(&mut self, state: SafeState) -> Result<(), Self::Error> {
        T::set_safe(self, state)
    }
}

/// `command` limited to `[-1, 1]`, NaN → 0 (hold).
fn clamp_command(command: f32) -> f32 {
    if command >= -1.0 {
        if command <= 1.0 {
            command
        } else {
            1.0
        }
    } else if command < -1.0 {
        -1.0
    } else {
        0.0
    }
}

/// Set `fraction` (clamped to `[0, 1]`, NaN → 0) of the channel's full duty.
fn set_fraction<P: SetDutyCycle>(pwm: &mut P, fraction: f32) -> Result<(), P::Error> {
    let max = pwm.max_duty_cycle();
    let f = if fraction >= 0.0 {
        if fraction <= 1.0 {
            fraction
        } else {
            1.0
        }
    } else {
        0.0
    };
    // f·max + 0.5 is in [0, max + 0.5], so the cast neither wraps nor saturates past max.
    pwm.set_duty_cycle((f * f32::from(max) + 0.5) as u16)
}

/// One proportional flow-control valve (3/3, closed centre, for example a
/// Festo MPYE driven through an RC-filtered PWM): duty `closed_duty` closes
/// both ways, full duty fills at the full rate, zero duty vents at the full
/// rate.
#[derive(Debug)]
pub struct ProportionalValve<P> {
    pwm: P,
    closed_duty: f32,
}

impl<P: SetDutyCycle> ProportionalValve<P> {
    /// A valve on `pwm` whose closed centre is at `closed_duty` (fraction of
    /// full duty, strictly between 0 and 1; typically 0.5).
    pub fn new(pwm: P, closed_duty: f32) -> Result<Self, HalConfigError> {
        if !(closed_duty > 0.0 && closed_duty < 1.0) {
            return Err(HalConfigError::ClosedDuty);
        }
        Ok(ProportionalValve { pwm, closed_duty })
    }

    /// Duty fraction for a flow command: piecewise linear through
    /// `(−1, 0)`, `(0, closed_duty)`, `(1, 1)`.
    pub fn duty_fraction(&self, command: f32) -> f32 {
        let c = clamp_command(command);
        if c >= 0.0 {
            self.closed_duty + c * (1.0 - self.closed_duty)
        } else {
            self.closed_duty * (1.0 + c)
        }
    }

    /// Give the PWM channel back.
    pub fn release(self) -> P {
        self.pwm
    }
}

impl<P: SetDutyCycle> PwmErrorType for ProportionalValve<P> {
    type Error = P::Error;
}

impl<P: SetDutyCycle> Valve for ProportionalValve<P> {
    fn set_flow(&mut self, command: f32) -> Result<(), Self::Error> {
        let f = self.duty_fraction(command);
        set_fraction(&mut self.pwm, f)
    }

    fn set_safe(&mut self, state: SafeState) -> Result<(), Self::Error> {
        match state {
            SafeState::Exhaust => self.pwm.set_duty_cycle_fully_off(),
            SafeState::Hold => set_fraction(&mut self.pwm, self.closed_duty),
        }
    }
}

/// Tuning of a [`ValvePair`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ValvePairConfig {
    /// Commands with `|command| < deadband` close both valves, so noise
    /// around the set-point does not chatter the valves.
    pub deadband: f32,
    /// Duty below which an on/off valve does not open within one PWM period
    /// (its opening time over the PWM period). Commands beyond the deadband
    /// map linearly onto `[min_open_duty, 1]`, which compensates it.
    pub min_open_duty: f32,
}

impl ValvePairConfig {
    /// 1 % deadband; 5 % minimum opening duty (a 2 ms valve at 25 Hz PWM).
    pub const DEFAULT: ValvePairConfig = ValvePairConfig {
        deadband: 0.01,
        min_open_duty: 0.05,
    };

    /// Check: both in `[0, 1)`.
    pub fn validate(&self) -> Result<(), HalConfigError> {
        if !(self.deadband >= 0.0 && self.deadband < 1.0) {
            return Err(HalConfigError::Deadband);
        }
        if !(self.min_open_duty >= 0.0 && self.min_open_duty < 1.0) {
            return Err(HalConfigError::MinOpenDuty);
        }
        Ok(())
    }
}

/// Which valve of a [`ValvePair`] failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PairError<I, E> {
    /// The inlet channel refused a duty.
    Inlet(I),
    /// The exhaust channel refused a duty.
    Exhaust(E),
}

impl<I: PwmError, E: PwmError> PwmError for PairError<I, E> {
    fn kind(&self) -> PwmErrorKind {
        match self {
            PairError::Inlet(e) => e.kind(),
            PairError::Exhaust(e) => e.kind(),
        }
    }
}

/// An inlet (supply → muscle) and an exhaust (muscle → atmosphere) on/off
/// valve, each PWM-driven. A flow command never opens both: the valve being
/// closed is written before the one being opened, so a failed write leaves
/// at most the previous state, never both open.
///
/// The safe state is best effort on both channels: the inlet is closed
/// first, and a refused inlet write does not stop the exhaust from being
/// written. With a dead inlet channel left open, venting through the
/// exhaust lowers the muscle pressure (both open), where stopping at the
/// failed write would leave the muscle filling to supply pressure.
#[derive(Debug)]
pub struct ValvePair<I, E> {
    inlet: I,
    exhaust: E,
    config: ValvePairConfig,
}

impl<I: SetDutyCycle, E: SetDutyCycle> ValvePair<I, E> {
    /// A pair on two PWM channels.
    pub fn new(inlet: I, exhaust: E, config: ValvePairConfig) -> Result<Self, HalConfigError> {
        config.validate()?;
        Ok(ValvePair {
            inlet,
            exhaust,
            config,
        })
    }

    /// Duty fraction for `|command|` (0 inside the deadband).
    pub fn duty_fraction(&self, command: f32) -> f32 {
        let m = clamp_command(command).abs();
        if m <= 0.0 || m < self.config.deadband {
            0.0
        } else {
            let open = self.config.min_open_duty;
            open + (1.0 - open) * m
        }
    }

    /// Give the PWM channels back.
    pub fn release(self) -> (I, E) {
        (self.inlet, self.exhaust)
    }

    fn write(&mut self, inlet: f32, exhaust: f32) -> Result<(), PairError<I::Error, E::Error>> {
        if inlet > 0.0 {
            set_fraction(&mut self.exhaust, 0.0).map_err(PairError::Exhaust)?;
            set_fraction(&mut self.inlet, inlet).map_err(PairError::Inlet)
        } else {
            set_fraction(&mut self.inlet, 0.0).map_err(PairError::Inlet)?;
            set_fraction(&mut self.exhaust, exhaust).map_err(PairError::Exhaust)
        }
    }
}

impl<I: SetDutyCycle, E: SetDutyCycle> PwmErrorType for ValvePair<I, E> {
    type Error = PairError<I::Error, E::Error>;
}

impl<I: SetDutyCycle, E: SetDutyCycle> Valve for ValvePair<I, E> {
    fn set_flow(&mut self, command: f32) -> Result<(), Self::Error> {
        let d = self.duty_fraction(command);
        if command > 0.0 {
            self.write(d, 0.0)
        } else {
            self.write(0.0, d)
        }
    }

    fn set_safe(&mut self, state: SafeState) -> Result<(), Self::Error> {
        let exhaust = match state {
            SafeState::Exhaust => 1.0,
            SafeState::Hold => 0.0,
        };
        let inlet = set_fraction(&mut self.inlet, 0.0).map_err(PairError::Inlet);
        let exhaust = set_fraction(&mut self.exhaust, exhaust).map_err(PairError::Exhaust);
        inlet.and(exhaust)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::convert::Infallible;

    /// A PWM channel that records its duty; `fail` makes every write fail.
    #[derive(Debug, Default)]
    struct Pwm {
        duty: u16,
        fail: bool,
    }

    #[derive(Debug)]
    struct PwmFault;
    impl PwmError for PwmFault {
        fn kind(&self) -> PwmErrorKind {
            PwmErrorKind::Other
        }
    }
    impl PwmErrorType for Pwm {
        type Error = PwmFault;
    }
    impl SetDutyCycle for Pwm {
        fn max_duty_cycle(&self) -> u16 {
            1000
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), PwmFault> {
            if self.fail {
                return Err(PwmFault);
            }
            assert!(duty <= 1000, "duty {duty} beyond max");
            self.duty = duty;
            Ok(())
        }
    }

    #[test]
    fn calibration_round_trip_and_window() {
        let cal = PressureCalibration::ADC12_0_1MPA;
        cal.validate().unwrap();
        for p in [0.0, 0.1, 0.25, 0.5, 0.9] {
            let mpa = cal.to_mpa(cal.to_counts(p)).unwrap();
            assert!(
                (mpa - p).abs() <= 0.5 * cal.mpa_per_count + 1e-6,
                "{p} → {mpa}"
            );
        }
        assert_eq!(cal.to_mpa(Counts(0)), Err(SensorErrorKind::InvalidCode));
        assert_eq!(cal.to_mpa(Counts(4095)), Err(SensorErrorKind::InvalidCode));
        assert_eq!(cal.to_counts(f32::NAN), Counts(0));
        assert_eq!(cal.to_counts(1e9), Counts(u16::MAX));
        let mut bad = cal;
        bad.mpa_per_count = 0.0;
        assert!(bad.validate().is_err());
    }

    #[test]
    fn linear_calibration_maps_and_rejects() {
        let cal = LinearCalibration {
            zero_counts: 100.0,
            units_per_count: -0.5,
            min_valid: Counts(10),
            max_valid: Counts(4000),
        };
        cal.validate().unwrap();
        assert_eq!(cal.to_value(Counts(100)), Ok(0.0));
        assert_eq!(cal.to_value(Counts(300)), Ok(-100.0));
        assert_eq!(cal.to_value(Counts(9)), Err(SensorErrorKind::InvalidCode));
        assert_eq!(
            cal.to_value(Counts(4001)),
            Err(SensorErrorKind::InvalidCode)
        );
        for bad in [
            LinearCalibration {
                units_per_count: 0.0,
                ..cal
            },
            LinearCalibration {
                units_per_count: f32::NAN,
                ..cal
            },
            LinearCalibration {
                zero_counts: f32::INFINITY,
                ..cal
            },
            LinearCalibration {
                min_valid: Counts(4001),
                ..cal
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }

    struct Fixed(Result<Counts, SensorErrorKind>);
    impl ErrorType for Fixed {
        type Error = SensorErrorKind;
    }
    impl PressureSensor for Fixed {
        fn read_counts(&mut self) -> Result<Counts, SensorErrorKind> {
            self.0
        }
        fn calibration(&self) -> &PressureCalibration {
            &PressureCalibration::ADC12_0_1MPA
        }
    }

    #[test]
    fn pressure_read_maps_errors_to_kinds_and_works_through_mut_ref() {
        fn read<P: PressureSensor>(mut p: P) -> Result<f32, SensorErrorKind> {
            p.read_pressure_mpa()
        }
        let mut ok = Fixed(Ok(Counts(2048)));
        assert!((read(&mut ok).unwrap() - 0.5).abs() < 1e-3);
        assert_eq!(
            read(Fixed(Err(SensorErrorKind::Timeout))),
            Err(SensorErrorKind::Timeout)
        );
        let _: fn(&Infallible) -> SensorErrorKind = SensorError::kind;
    }

    #[test]
    fn proportional_valve_maps_commands_and_safe_states() {
        let mut v = ProportionalValve::new(Pwm::default(), 0.5).unwrap();
        v.set_flow(0.0).unwrap();
        assert_eq!(v.pwm.duty, 500);
        v.set_flow(1.0).unwrap();
        assert_eq!(v.pwm.duty, 1000);
        v.set_flow(-0.5).unwrap();
        assert_eq!(v.pwm.duty, 250);
        for c in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 7.0] {
            v.set_flow(c).unwrap();
        }
        assert_eq!(v.pwm.duty, 1000, "+7 clamps to full fill");
        v.set_flow(f32::NAN).unwrap();
        assert_eq!(v.pwm.duty, 500, "NaN holds");
        v.set_safe(SafeState::Exhaust).unwrap();
        assert_eq!(v.pwm.duty, 0);
        v.set_safe(SafeState::Hold).unwrap();
        assert_eq!(v.pwm.duty, 500);
        assert!(ProportionalValve::new(Pwm::default(), 1.0).is_err());
        assert!(ProportionalValve::new(Pwm::default(), f32::NAN).is_err());
    }

    #[test]
    fn valve_pair_never_opens_both_and_reports_which_failed() {
        let mut v =
            ValvePair::new(Pwm::default(), Pwm::default(), ValvePairConfig::DEFAULT).unwrap();
        let mut c = -1.0f32;
        while c <= 1.0 {
            v.set_flow(c).unwrap();
            assert!(v.inlet.duty == 0 || v.exhaust.duty == 0, "both open at {c}");
            c += 0.001;
        }
        v.set_flow(0.005).unwrap();
        assert_eq!((v.inlet.duty, v.exhaust.duty), (0, 0), "deadband");
        v.set_flow(0.02).unwrap();
        assert_eq!((v.inlet.duty, v.exhaust.duty), (69, 0), "0.05 + 0.95·0.02");
        v.set_flow(-1.0).unwrap();
        assert_eq!((v.inlet.duty, v.exhaust.duty), (0, 1000));
        v.set_safe(SafeState::Hold).unwrap();
        assert_eq!((v.inlet.duty, v.exhaust.duty), (0, 0));
        v.set_flow(1.0).unwrap();
        v.set_safe(SafeState::Exhaust).unwrap();
        assert_eq!((v.inlet.duty, v.exhaust.duty), (0, 1000));
        v.exhaust.fail = true;
        assert!(matches!(v.set_flow(0.5), Err(PairError::Exhaust(_))));
        assert_eq!(
            v.inlet.duty, 0,
            "the inlet is not opened after the exhaust write failed"
        );
        assert_eq!(v.set_flow(0.5).unwrap_err().kind(), PwmErrorKind::Other);
        // A dead inlet channel left open: the safe state still opens the exhaust.
        v.exhaust.fail = false;
        v.set_flow(1.0).unwrap();
        v.inlet.fail = true;
        assert!(matches!(
            v.set_safe(SafeState::Exhaust),
            Err(PairError::Inlet(_))
        ));
        assert_eq!((v.inlet.duty, v.exhaust.duty), (1000, 1000));
        v.inlet.fail = false;
        v.set_safe(SafeState::Exhaust).unwrap();
        assert_eq!((v.inlet.duty, v.exhaust.duty), (0, 1000));
        let bad = ValvePairConfig {
            deadband: f32::NAN,
            ..ValvePairConfig::DEFAULT
        };
        assert!(ValvePair::new(Pwm::default(), Pwm::default(), bad).is_err());
    }
}

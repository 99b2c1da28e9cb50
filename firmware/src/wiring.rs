//! The default wiring of the STM32F405RG valve controller (the board image,
//! `cargo fw-build`): clocks, pins, timers and sensor calibrations.
//!
//! These are plain numbers, compiled and tested on the host; `board` (chip
//! builds only) applies them to the peripherals. To change the wiring or a
//! calibration, edit the constant here (and, for a pin, the pin in
//! `board::init`), then rebuild; `cargo test -p firmware` checks that each
//! calibration validates and maps its documented points.
//!
//! | signal | pin | peripheral |
//! |---|---|---|
//! | inlet valve (supply → muscle) | PA8 | TIM1 CH1, PWM at [`VALVE_PWM_HZ`] |
//! | exhaust valve (muscle → air) | PA9 | TIM1 CH2, PWM at [`VALVE_PWM_HZ`] |
//! | pressure transducer | PC0 | ADC1 IN10, [`PRESSURE`] |
//! | contraction potentiometer | PC1 | ADC2 IN11, [`CONTRACTION`] |
//! | load cell amplifier | PC2 | ADC3 IN12, [`LOAD`] |
//! | control tick | — | TIM2 update interrupt at [`CONTROL_HZ`] |
//!
//! Each sensor has its own ADC, so each sensor driver owns its converter.

use crate::hal::{Counts, LinearCalibration, PressureCalibration, ValvePairConfig};

/// External crystal, Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// Core clock from the PLL, Hz (the F405's maximum).
pub const SYSCLK_HZ: u32 = 168_000_000;
/// APB1 clock, Hz (its maximum; TIM2 runs at twice this, 84 MHz).
pub const PCLK1_HZ: u32 = 42_000_000;
/// APB2 clock, Hz (its maximum; TIM1 runs at twice this, 168 MHz; the ADCs
/// divide it by [`ADC_PRESCALER`]).
pub const PCLK2_HZ: u32 = 84_000_000;

/// Control rate, Hz: TIM2's update interrupt; must match
/// `ControllerConfig::DEFAULT.dt_s`.
pub const CONTROL_HZ: u32 = 1_000;

/// Independent watchdog timeout, ms (nominal: the IWDG runs on the LSI RC
/// oscillator, 32 kHz nominal, 17–47 kHz over the F405's range, so the
/// real timeout is 14–38 ms). The control interrupt feeds it after every
/// completed step; 20 missed periods reset the chip into the safe state.
/// The first window after the start is this one too (`board::Watchdog`).
pub const WATCHDOG_MS: u32 = 20;
/// The LSI oscillator's nominal frequency, Hz (the IWDG's clock).
pub const LSI_HZ: u32 = 32_000;
/// IWDG prescaler (PR = 0, divide by 4): 0.125 ms per count at the nominal
/// LSI, the finest step, and up to 512 ms.
pub const WATCHDOG_PRESCALER: u32 = 4;
/// IWDG reload value: the timeout is (RLR + 1) counts of LSI / prescaler
/// (RM0090 §21.3), so 159 for [`WATCHDOG_MS`].
pub const WATCHDOG_RELOAD: u16 = (WATCHDOG_MS * LSI_HZ / 1_000 / WATCHDOG_PRESCALER - 1) as u16;
/// Polls of a status flag (RCC_CSR.LSIRDY, IWDG_SR.PVU, IWDG_SR.RVU) before
/// the watchdog setup gives up. An update takes up to 5 LSI cycles, 294 µs
/// at the slowest LSI (17 kHz), 49 400 core cycles at 168 MHz; the LSI
/// starts within 40 µs. A poll is at least one core cycle, so this cap is
/// at least twice the longest wait, and at most a few tens of ms.
pub const WATCHDOG_MAX_POLLS: u32 = 100_000;

/// PWM frequency of the valve channels, Hz. 25 Hz is a 40 ms period, so
/// `ValvePairConfig::DEFAULT.min_open_duty` (5 %) is the 2 ms opening time of
/// a fast on/off valve. A proportional valve behind an RC filter wants
/// kHz instead (see the README).
pub const VALVE_PWM_HZ: u32 = 25;
/// The valve pair's tuning.
pub const VALVE_PAIR: ValvePairConfig = ValvePairConfig::DEFAULT;
/// The PWM channels must offer at least this many duty steps; fewer means
/// the timer clock or [`VALVE_PWM_HZ`] is wrong, and boot refuses to run.
pub const MIN_DUTY_STEPS: u16 = 1_000;

/// ADC clock divider from PCLK2: 84 MHz / 4 = 21 MHz (the F405's ADC
/// maximum is 36 MHz).
pub const ADC_PRESCALER: u32 = 4;
/// ADC sampling time, ADC clock cycles: the longest the F405 offers, for the
/// source impedance of the dividers, the potentiometer and the amplifier.
pub const ADC_SAMPLE_CYCLES: u32 = 480;
/// ADC clock cycles of one 12-bit conversion: sampling plus 12.
pub const ADC_CONVERSION_CYCLES: u32 = ADC_SAMPLE_CYCLES + 12;
/// A conversion that has not ended after this many core cycles is a
/// [`SensorErrorKind::Timeout`](crate::hal::SensorErrorKind::Timeout): three
/// conversion times (3 · 492 · 8 = 11 808 cycles, 70 µs at 168 MHz).
pub const ADC_TIMEOUT_CYCLES: u32 =
    3 * ADC_CONVERSION_CYCLES * (SYSCLK_HZ / (PCLK2_HZ / ADC_PRESCALER));

/// Pressure transducer: 0.5–4.5 V ratiometric, 0–1 MPa gauge, on 5 V,
/// through a divider of ratio 0.66 (for example 1.7 kΩ over 3.3 kΩ) to the
/// 3.3 V ADC: 0 MPa at 409.6 counts, 1 MPa at 3686.4; codes below 200 or
/// above 3900 are an open or shorted line.
pub const PRESSURE: PressureCalibration = PressureCalibration::ADC12_0_1MPA;

/// Rest length of the muscle, mm (a 300 mm muscle; contraction is a
/// fraction of it).
pub const MUSCLE_REST_LENGTH_MM: f32 = 300.0;
/// Electrical stroke of the linear potentiometer, mm, with its track across
/// VDDA (3.3 V) so the wiper is ratiometric to the ADC reference.
pub const POT_STROKE_MM: f32 = 100.0;
/// Wiper position at the muscle's rest length, mm from the track's low end;
/// the wiper moves toward the high end as the muscle shortens.
pub const POT_AT_REST_MM: f32 = 5.0;
/// ADC codes over the potentiometer's stroke (12 bits).
const ADC_FULL_SCALE: f32 = 4095.0;

/// Contraction potentiometer: contraction = (counts − counts at rest) ·
/// (stroke / 4095) / rest length, i.e. 0 at 204.75 counts and 8.14·10⁻⁵
/// per count; the track spans −0.017 to 0.317. Codes below 40 or above 4055
/// are outside the muscle's travel: an open wiper (pulled down by a 1 MΩ
/// resistor) or a shorted one.
pub const CONTRACTION: LinearCalibration = LinearCalibration {
    zero_counts: POT_AT_REST_MM / POT_STROKE_MM * ADC_FULL_SCALE,
    units_per_count: POT_STROKE_MM / ADC_FULL_SCALE / MUSCLE_REST_LENGTH_MM,
    min_valid: Counts(40),
    max_valid: Counts(4055),
};

/// Load cell: a 1000 N S-beam cell, 2 mV/V, excited from VDDA (3.3 V, so
/// ratiometric to the ADC), through an instrumentation amplifier of gain 400
/// with its reference at 0.33 V: 0 N at 0.33 V (409.6 counts), 1000 N at
/// 2.97 V (3686.4 counts), 0.305 N per count. Codes below 100 (−94 N) or
/// above 4000 (1096 N) are a saturated amplifier or a broken bridge.
/// Offset (`zero_counts`) and scale are set by hand: read the counts with no
/// load and with a known weight, and put them here.
pub const LOAD: LinearCalibration = LinearCalibration {
    zero_counts: 409.6,
    units_per_count: 1000.0 / 3276.8,
    min_valid: Counts(100),
    max_valid: Counts(4000),
};

// The ADC clock within the F405's 36 MHz limit.
const _: () = assert!(PCLK2_HZ / ADC_PRESCALER <= 36_000_000);
// Three sensors timing out in one step still leave three quarters of the
// control period.
const _: () = assert!(3 * ADC_TIMEOUT_CYCLES < SYSCLK_HZ / CONTROL_HZ / 4);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::ControllerConfig;

    #[test]
    fn calibrations_validate_and_map_their_documented_points() {
        PRESSURE.validate().unwrap();
        CONTRACTION.validate().unwrap();
        LOAD.validate().unwrap();
        VALVE_PAIR.validate().unwrap();
        // 0.5 V → 0 MPa, 4.5 V → 1 MPa through the 0.66 divider.
        let counts = |volts: f32| Counts((volts * 0.66 / 3.3 * 4096.0 + 0.5) as u16);
        assert!(PRESSURE.to_mpa(counts(0.5)).unwrap().abs() < 1e-3);
        assert!((PRESSURE.to_mpa(counts(4.5)).unwrap() - 1.0).abs() < 1e-3);
        // Wiper at 5 mm: rest; at 35 mm: 30 mm shorter, 10 % of 300 mm.
        let at_mm = |mm: f32| Counts((mm / POT_STROKE_MM * ADC_FULL_SCALE + 0.5) as u16);
        assert!(CONTRACTION.to_value(at_mm(5.0)).unwrap().abs() < 1e-4);
        assert!((CONTRACTION.to_value(at_mm(35.0)).unwrap() - 0.10).abs() < 1e-4);
        // The window covers the controller's plausible range of contraction.
        let lo = CONTRACTION.to_value(CONTRACTION.min_valid).unwrap();
        let hi = CONTRACTION.to_value(CONTRACTION.max_valid).unwrap();
        let safety = ControllerConfig::DEFAULT.safety;
        assert!(lo < 0.0 && hi > 0.3, "{lo} {hi} {safety:?}");
        // 0 N at 0.33 V, 1000 N at 2.97 V.
        let at_v = |v: f32| Counts((v / 3.3 * 4096.0 + 0.5) as u16);
        assert!(LOAD.to_value(at_v(0.33)).unwrap().abs() < 0.5);
        assert!((LOAD.to_value(at_v(2.97)).unwrap() - 1000.0).abs() < 0.5);
        assert!(LOAD.to_value(Counts(4095)).is_err() && LOAD.to_value(Counts(0)).is_err());
    }

    #[test]
    fn watchdog_registers_give_the_stated_timeout() {
        // RM0090's table: at /4, RLR 0 is 0.125 ms and 0xFFF 512 ms.
        let timeout_ms = |rlr: u16, lsi_hz: u32| {
            (f64::from(rlr) + 1.0) * f64::from(WATCHDOG_PRESCALER) / f64::from(lsi_hz) * 1e3
        };
        assert_eq!(timeout_ms(0, LSI_HZ), 0.125);
        assert_eq!(timeout_ms(0xFFF, LSI_HZ), 512.0);
        assert_eq!(WATCHDOG_RELOAD, 159);
        assert_eq!(timeout_ms(WATCHDOG_RELOAD, LSI_HZ), f64::from(WATCHDOG_MS));
        // 14–38 ms over the LSI's 17–47 kHz, as documented.
        assert_eq!(timeout_ms(WATCHDOG_RELOAD, 47_000).round(), 14.0);
        assert_eq!(timeout_ms(WATCHDOG_RELOAD, 17_000).round(), 38.0);
        // The bounded waits: at least twice 5 cycles of the slowest LSI at
        // one core cycle per poll.
        let slowest_update_cycles = 5 * SYSCLK_HZ / 17_000;
        assert!(WATCHDOG_MAX_POLLS >= 2 * slowest_update_cycles);
    }

    #[test]
    fn timing_fits_the_control_period() {
        let dt_s = ControllerConfig::DEFAULT.dt_s;
        assert!((dt_s * CONTROL_HZ as f32 - 1.0).abs() < 1e-6);
        assert_eq!(ADC_TIMEOUT_CYCLES, 11_808);
        // The HAL's prescaler choice for TIM1 (stm32f4xx-hal `compute_arr_presc`):
        // ticks / 65536 → PSC, ticks / (PSC + 1) − 1 → ARR; max duty = ARR + 1.
        let ticks = 2 * PCLK2_HZ / VALVE_PWM_HZ;
        let psc = (ticks - 1) / (1 << 16);
        let max_duty = ticks / (psc + 1);
        assert_eq!((psc, max_duty), (102, 65_242));
        assert!(max_duty >= u32::from(MIN_DUTY_STEPS) && max_duty < 1 << 16);
    }
}

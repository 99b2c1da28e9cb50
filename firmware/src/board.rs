//! Board support for the STM32F405RG valve controller, on `stm32f4xx-hal`
//! (chip builds with the `chip` feature only; host builds and `cargo test`
//! do not compile it). The numbers and the pin table are in
//! [`crate::wiring`].
//!
//! * Clocks: 8 MHz HSE → PLL → 168 MHz core, 42 MHz APB1, 84 MHz APB2.
//! * Valves: TIM1 CH1 (PA8, inlet) and CH2 (PA9, exhaust) as a
//!   [`ValvePair`] of `stm32f4xx-hal` PWM channels (embedded-hal 1.0
//!   [`SetDutyCycle`](crate::hal::SetDutyCycle)).
//! * Sensors: one ADC each ([`AdcInput`]), raw codes through the
//!   calibrations of [`crate::wiring`]. A conversion is started and polled
//!   with a deadline on the DWT cycle counter, so a converter that never
//!   finishes is a [`SensorErrorKind::Timeout`], an overrun a
//!   [`SensorErrorKind::Bus`], a code outside the window
//!   [`SensorErrorKind::InvalidCode`]. (The HAL's own `Adc::convert` waits
//!   without a bound and can panic, so the control step does not use it.)
//! * Tick: TIM2 update interrupt at 1 kHz ([`init`] returns the counter; the
//!   image unmasks the interrupt).
//!
//! * Watchdog: the IWDG ([`Watchdog`]), configured by [`init`] for
//!   [`wiring::WATCHDOG_MS`] and returned unstarted; the image starts it
//!   just before control begins and feeds it after every completed step.
//!   [`init`] reads (and clears) the reset flags, so the image knows a
//!   watchdog reset and boots latched.
//! * Crash: [`valves_safe_now`] drives the valve pins to the safe state as
//!   plain GPIO outputs, independent of the timer and of any driver state;
//!   the image's panic handler and its exception handlers
//!   ([`crate::crash`]: HardFault, NMI, all others) call it first.
//!
//! Initialisation ([`init`]) may panic inside the HAL (its clock
//! configuration asserts on impossible clock trees); that is before any
//! control and before the valves can open. The control step
//! ([`pam_board_control_step`]) is checked panic-free by
//! `firmware/panic-check.sh`.

use crate::controller::{Controller, Io, Step};
use crate::hal::{
    ContractionSensor, Counts, ErrorType, HalConfigError, LinearCalibration, LoadCell,
    PressureCalibration, PressureSensor, SafeState, SensorErrorKind, Valve, ValvePair,
};
use crate::wiring;
use core::ops::Deref;
use cortex_m::peripheral::DWT;
use stm32f4xx_hal::gpio::{Analog, PC0, PC1, PC2};
use stm32f4xx_hal::hal_02::adc::Channel;
use stm32f4xx_hal::pac::{self, adc1::RegisterBlock as AdcRegisters, ADC1, ADC2, ADC3, TIM1, TIM2};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Config, Enable, Rcc, Reset};
use stm32f4xx_hal::timer::{CounterHz, Event, PwmChannel};

/// Upper bound on status polls of one conversion, in case the cycle counter
/// is stopped (it is started by [`init`]); far beyond the deadline at any
/// poll cost of one cycle or more.
const ADC_MAX_POLLS: u32 = wiring::ADC_TIMEOUT_CYCLES;

/// One ADC converting one channel on demand (single conversion, software
/// start), with the pin held in analog mode.
pub struct AdcInput<A, P> {
    adc: A,
    _pin: P,
}

impl<A, P> AdcInput<A, P>
where
    A: Deref<Target = AdcRegisters> + Enable + Reset,
    P: Channel<A, ID = u8>,
{
    /// Clock and configure `adc` for single 12-bit conversions of `pin`'s
    /// channel with [`wiring::ADC_SAMPLE_CYCLES`] sampling, then power it up.
    /// The ADC prescaler (common to the three ADCs) is set by [`init`].
    pub fn new(adc: A, pin: P, rcc: &mut Rcc) -> Self {
        A::enable(rcc);
        let ch = P::channel();
        // 12 bits, no scan, no interrupts; one conversion per SWSTART.
        adc.cr1().reset();
        adc.cr2().reset();
        adc.sqr1().reset(); // sequence length 1
                            // SAFETY: SQ1 is a 5-bit channel number; `ch` comes from the HAL's
                            // pin-to-channel table for this ADC (0..=18), a valid channel.
        #[allow(unsafe_code)]
        adc.sqr3().write(|w| unsafe { w.sq1().bits(ch) });
        match ch {
            0..=9 => adc.smpr2().modify(|_, w| w.smp(ch).cycles480()),
            _ => adc.smpr1().modify(|_, w| w.smp(ch - 10).cycles480()),
        };
        adc.cr2().modify(|_, w| w.adon().set_bit());
        AdcInput { adc, _pin: pin }
    }

    /// One conversion, raw 12-bit counts.
    ///
    /// Errors: [`SensorErrorKind::Bus`] on an overrun flag,
    /// [`SensorErrorKind::Timeout`] when no end of conversion arrives within
    /// [`wiring::ADC_TIMEOUT_CYCLES`].
    pub fn read(&mut self) -> Result<Counts, SensorErrorKind> {
        let adc = &*self.adc;
        // Clear stale status (the flags are cleared by writing 0).
        adc.sr()
            .modify(|_, w| w.eoc().clear_bit().ovr().clear_bit().strt().clear_bit());
        adc.cr2().modify(|_, w| w.swstart().set_bit());
        let start = DWT::cycle_count();
        let mut polls = 0u32;
        loop {
            let sr = adc.sr().read();
            if sr.ovr().bit_is_set() {
                return Err(SensorErrorKind::Bus);
            }
            if sr.eoc().bit_is_set() {
                // Reading DR also clears EOC.
                return Ok(Counts(adc.dr().read().data().bits()));
            }
            polls += 1;
            if DWT::cycle_count().wrapping_sub(start) > wiring::ADC_TIMEOUT_CYCLES
                || polls > ADC_MAX_POLLS
            {
                return Err(SensorErrorKind::Timeout);
            }
        }
    }
}

/// The pressure transducer on ADC1 / PC0.
pub struct BoardPressure {
    input: AdcInput<ADC1, PC0<Analog>>,
    calibration: PressureCalibration,
}

impl ErrorType for BoardPressure {
    type Error = SensorErrorKind;
}

impl PressureSensor for BoardPressure {
    fn read_counts(&mut self) -> Result<Counts, SensorErrorKind> {
        self.input.read()
    }
    fn calibration(&self) -> &PressureCalibration {
        &self.calibration
    }
}

/// The contraction potentiometer on ADC2 / PC1.
pub struct BoardContraction {
    input: AdcInput<ADC2, PC1<Analog>>,
    calibration: LinearCalibration,
}

impl ErrorType for BoardContraction {
    type Error = SensorErrorKind;
}

impl ContractionSensor for BoardContraction {
    fn read_contraction(&mut self) -> Result<f32, SensorErrorKind> {
        self.calibration.to_value(self.input.read()?)
    }
}

/// The load cell amplifier on ADC3 / PC2.
pub struct BoardLoad {
    input: AdcInput<ADC3, PC2<Analog>>,
    calibration: LinearCalibration,
}

impl ErrorType for BoardLoad {
    type Error = SensorErrorKind;
}

impl LoadCell for BoardLoad {
    fn read_load_n(&mut self) -> Result<f32, SensorErrorKind> {
        self.calibration.to_value(self.input.read()?)
    }
}

/// Inlet (TIM1 CH1, PA8) and exhaust (TIM1 CH2, PA9) valve channels.
pub type BoardValve = ValvePair<PwmChannel<TIM1, 0>, PwmChannel<TIM1, 1>>;

/// The board's hardware as the controller sees it.
pub type BoardIo = Io<BoardPressure, BoardContraction, BoardLoad, BoardValve>;

/// Why [`init`] refused to set up the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum BoardError {
    /// A calibration or the valve pair's settings in [`crate::wiring`].
    Hal(HalConfigError),
    /// The valve PWM has fewer than [`wiring::MIN_DUTY_STEPS`] duty steps
    /// (timer clock or [`wiring::VALVE_PWM_HZ`] wrong).
    DutySteps,
    /// TIM2 refused [`wiring::CONTROL_HZ`].
    ControlRate,
    /// The watchdog could not be configured within
    /// [`wiring::WATCHDOG_MAX_POLLS`] polls.
    Watchdog(WatchdogError),
}

impl From<HalConfigError> for BoardError {
    fn from(e: HalConfigError) -> Self {
        BoardError::Hal(e)
    }
}

impl core::fmt::Display for BoardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BoardError::Hal(e) => write!(f, "{e}"),
            BoardError::DutySteps => {
                f.write_str("valve PWM has too few duty steps (timer clock or VALVE_PWM_HZ)")
            }
            BoardError::ControlRate => f.write_str("TIM2 refused the control rate"),
            BoardError::Watchdog(e) => write!(f, "watchdog: {e}"),
        }
    }
}

/// Drive the valve pins to `safe` at once, as GPIO outputs: inlet (PA8)
/// low, exhaust (PA9) high for [`SafeState::Exhaust`], both low for
/// [`SafeState::Hold`]. For the panic and exception handlers: it does not
/// need the timer, the HAL objects or any lock, only GPIOA, whose clock it
/// enables; so the NMI handler, which may preempt a critical section, can
/// call it too. The output level is written before the pins switch from the
/// timer's alternate function to output, so they never glitch open.
///
/// The valves are energise-to-open (wiring table in firmware/README.md):
/// high is open. Whatever state the program was in, after this call
/// nothing but a reset changes the pins (the caller never returns).
pub fn valves_safe_now(safe: SafeState) {
    // SAFETY: called only from the panic and exception handlers, which never
    // return: the code they interrupted never runs again, so nothing else
    // uses these register blocks afterwards. The writes are single-register read-modify-writes of GPIOA and
    // RCC's enable bit, valid in any state of the chip.
    #[allow(unsafe_code)]
    let (rcc, gpioa) = unsafe { (pac::RCC::steal(), pac::GPIOA::steal()) };
    rcc.ahb1enr().modify(|_, w| w.gpioaen().set_bit());
    // BSRR: bits 0–15 set, 16–31 reset. PA8 (inlet) reset; PA9 (exhaust)
    // set for Exhaust, reset for Hold.
    let bsrr = match safe {
        SafeState::Exhaust => (1 << (16 + 8)) | (1 << 9),
        SafeState::Hold => (1 << (16 + 8)) | (1 << (16 + 9)),
    };
    // SAFETY: BSRR accepts any bit pattern (atomic set/reset of pins).
    #[allow(unsafe_code)]
    gpioa.bsrr().write(|w| unsafe { w.bits(bsrr) });
    // MODER: 2 bits per pin, 0b01 = general-purpose output, for PA8 and PA9.
    // SAFETY: only the two pins' fields change, to a valid mode.
    #[allow(unsafe_code)]
    gpioa
        .moder()
        .modify(|r, w| unsafe { w.bits((r.bits() & !(0xF << 16)) | (0b0101 << 16)) });
}

/// Why [`Watchdog::configure`] gave up: a status flag still set after
/// [`wiring::WATCHDOG_MAX_POLLS`] polls.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum WatchdogError {
    /// The LSI oscillator, the IWDG's clock, did not report ready.
    LsiNotReady,
    /// IWDG_SR.PVU: a prescaler update did not finish.
    PrescalerBusy,
    /// IWDG_SR.RVU: a reload value update did not finish.
    ReloadBusy,
}

impl core::fmt::Display for WatchdogError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            WatchdogError::LsiNotReady => "the LSI oscillator did not start",
            WatchdogError::PrescalerBusy => "the prescaler update did not finish (SR.PVU)",
            WatchdogError::ReloadBusy => "the reload value update did not finish (SR.RVU)",
        })
    }
}

/// Poll `done` up to [`wiring::WATCHDOG_MAX_POLLS`] times; `Err(e)` if it
/// never held.
fn poll_until(mut done: impl FnMut() -> bool, e: WatchdogError) -> Result<(), WatchdogError> {
    for _ in 0..wiring::WATCHDOG_MAX_POLLS {
        if done() {
            return Ok(());
        }
    }
    Err(e)
}

/// The independent watchdog (IWDG), configured by hand, not through the
/// HAL's `IndependentWatchdog`: that one writes the prescaler and reload
/// registers without waiting for the status register's PVU and RVU flags
/// (with the LSI that applies them not yet running), and its start leaves
/// the counter at its reset value 0xFFF, so until the first feed the window
/// was 4096 counts of its prescaler (16 s for 20 ms), not the stated one.
pub struct Watchdog {
    iwdg: pac::IWDG,
}

impl Watchdog {
    /// Set the IWDG to [`wiring::WATCHDOG_MS`] (prescaler
    /// [`wiring::WATCHDOG_PRESCALER`], reload [`wiring::WATCHDOG_RELOAD`]),
    /// not started, as RM0090 §21 asks: LSI on and ready; key 0x5555 to
    /// unlock PR and RLR; PR written once SR.PVU is clear, RLR once SR.RVU is
    /// clear; then both flags clear again, so the values are in the
    /// watchdog's own domain before [`Watchdog::start`] loads the counter.
    /// Each wait is bounded by [`wiring::WATCHDOG_MAX_POLLS`] polls; on a
    /// timeout the watchdog is left unstarted and the caller keeps the valves
    /// safe and runs no control.
    pub fn configure(iwdg: pac::IWDG, rcc: &pac::RCC) -> Result<Self, WatchdogError> {
        rcc.csr().modify(|_, w| w.lsion().set_bit());
        poll_until(
            || rcc.csr().read().lsirdy().bit_is_set(),
            WatchdogError::LsiNotReady,
        )?;
        iwdg.kr().write(|w| w.key().unlock());
        poll_until(
            || iwdg.sr().read().pvu().bit_is_clear(),
            WatchdogError::PrescalerBusy,
        )?;
        const _: () = assert!(wiring::WATCHDOG_PRESCALER == 4);
        iwdg.pr().write(|w| w.pr().divide_by4());
        poll_until(
            || iwdg.sr().read().rvu().bit_is_clear(),
            WatchdogError::ReloadBusy,
        )?;
        iwdg.rlr().write(|w| w.rl().set(wiring::WATCHDOG_RELOAD));
        poll_until(
            || iwdg.sr().read().pvu().bit_is_clear(),
            WatchdogError::PrescalerBusy,
        )?;
        poll_until(
            || iwdg.sr().read().rvu().bit_is_clear(),
            WatchdogError::ReloadBusy,
        )?;
        Ok(Watchdog { iwdg })
    }

    /// Start the watchdog: reload (key 0xAAAA, which also locks PR and RLR
    /// again), start (0xCCCC), and reload once more, since the start runs
    /// the counter from its reset value 0xFFF (512 ms at this prescaler,
    /// RM0090 §21.3): the first window is [`wiring::WATCHDOG_MS`] too. It
    /// cannot be stopped but by a reset.
    pub fn start(&mut self) {
        self.iwdg.kr().write(|w| w.key().feed());
        self.iwdg.kr().write(|w| w.key().start());
        self.iwdg.kr().write(|w| w.key().feed());
    }

    /// Reload the counter: another [`wiring::WATCHDOG_MS`] before a reset.
    pub fn feed(&mut self) {
        self.iwdg.kr().write(|w| w.key().feed());
    }
}

/// What [`init`] hands back.
pub struct Board {
    /// Sensors and valves.
    pub io: BoardIo,
    /// TIM2 counting at [`wiring::CONTROL_HZ`], its update interrupt enabled
    /// in the timer (the NVIC line is still masked).
    pub tick: CounterHz<TIM2>,
    /// The PWM channels' full duty (timer counts per period).
    pub max_duty: u16,
    /// The independent watchdog, configured and not started (it cannot be
    /// stopped once started; the image starts it when control begins).
    pub watchdog: Watchdog,
    /// The last reset was the independent watchdog's (the reset flags are
    /// cleared by [`init`], so a later reset by the NRST pin or a power
    /// cycle reads `false`).
    pub watchdog_reset: bool,
}

/// Clocks, valves (left in `safe`), sensors and the control tick.
///
/// The valve pins are driven, with both channels at the safe state's duty,
/// before the sensors and the watchdog are set up. Errors (valves left in
/// `safe`): a configuration the wiring constants make invalid (calibrations,
/// too few duty steps), or a watchdog that did not take its configuration
/// ([`Watchdog::configure`]).
pub fn init(
    dp: pac::Peripherals,
    dcb: &mut cortex_m::peripheral::DCB,
    dwt: &mut DWT,
    safe: SafeState,
) -> Result<Board, BoardError> {
    // Why the chip reset; then clear the flags for the next boot.
    let watchdog_reset = dp.RCC.csr().read().wdgrstf().bit_is_set();
    dp.RCC.csr().modify(|_, w| w.rmvf().set_bit());
    let mut rcc = dp.RCC.freeze(
        Config::hse(wiring::HSE_HZ.Hz())
            .sysclk(wiring::SYSCLK_HZ.Hz())
            .pclk1(wiring::PCLK1_HZ.Hz())
            .pclk2(wiring::PCLK2_HZ.Hz()),
    );
    // The ADC deadline runs on the cycle counter.
    dcb.enable_trace();
    dwt.enable_cycle_counter();

    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    // Valves first: a PWM channel starts at duty 0 (closed), then the safe
    // state is written before the outputs are enabled.
    let (_pwm, (ch1, ch2, ..)) = dp.TIM1.pwm_hz(wiring::VALVE_PWM_HZ.Hz(), &mut rcc);
    let mut inlet = ch1.with(gpioa.pa8);
    let mut exhaust = ch2.with(gpioa.pa9);
    let max_duty = inlet.get_max_duty();
    let _ = ValvePair::new(&mut inlet, &mut exhaust, wiring::VALVE_PAIR)?.set_safe(safe);
    inlet.enable();
    exhaust.enable();
    let mut valve = ValvePair::new(inlet, exhaust, wiring::VALVE_PAIR)?;
    // A wrapped or tiny ARR would make every duty 0 or coarse.
    if max_duty < wiring::MIN_DUTY_STEPS {
        let _ = valve.set_safe(safe);
        return Err(BoardError::DutySteps);
    }
    let _ = valve.set_safe(safe);

    wiring::PRESSURE.validate()?;
    wiring::CONTRACTION.validate()?;
    wiring::LOAD.validate()?;
    // ADC clock: PCLK2 / 4 = 21 MHz, common to the three ADCs.
    const _: () = assert!(wiring::ADC_PRESCALER == 4);
    dp.ADC_COMMON.ccr().modify(|_, w| w.adcpre().div4());
    let pressure = BoardPressure {
        input: AdcInput::new(dp.ADC1, gpioc.pc0.into_analog(), &mut rcc),
        calibration: wiring::PRESSURE,
    };
    let contraction = BoardContraction {
        input: AdcInput::new(dp.ADC2, gpioc.pc1.into_analog(), &mut rcc),
        calibration: wiring::CONTRACTION,
    };
    let load = BoardLoad {
        input: AdcInput::new(dp.ADC3, gpioc.pc2.into_analog(), &mut rcc),
        calibration: wiring::LOAD,
    };

    let mut tick = dp.TIM2.counter_hz(&mut rcc);
    tick.start(wiring::CONTROL_HZ.Hz())
        .map_err(|_| BoardError::ControlRate)?;
    tick.listen(Event::Update);

    // Halted by a debugger, the IWDG stops too (probe-rs breakpoints).
    dp.DBGMCU
        .apb1_fz()
        .modify(|_, w| w.dbg_iwdg_stop().set_bit());
    let watchdog = match Watchdog::configure(dp.IWDG, &rcc) {
        Ok(w) => w,
        Err(e) => {
            let _ = valve.set_safe(safe);
            return Err(BoardError::Watchdog(e));
        }
    };

    Ok(Board {
        io: Io {
            pressure,
            contraction,
            load,
            valve,
        },
        tick,
        max_duty,
        watchdog,
        watchdog_reset,
    })
}

/// One control period of the board image: [`Controller::step`] on
/// [`BoardIo`] (three ADC conversions, the controller's update, two PWM
/// duty writes).
///
/// Not inlined and exported unmangled as `pam_board_control_step`, so that
/// `firmware/panic-check.sh` finds it in the LTO image and checks that no
/// panic is reachable from it.
// `no_mangle` is flagged by the `unsafe_code` lint (symbol clashes); the
// name is unique to this crate.
#[allow(unsafe_code)]
#[no_mangle]
#[inline(never)]
pub fn pam_board_control_step(
    ctl: &mut Controller,
    io: &mut BoardIo,
    desired_contraction: f32,
) -> Step {
    ctl.step(io, desired_contraction)
}

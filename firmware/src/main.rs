//! The board controller: what a user flashes on the STM32F405RG valve
//! controller (`cargo fw-build`, `cargo fw-run`; feature `chip`).
//!
//! Boot sets up the board ([`firmware::board::init`]: clocks, valves in the
//! safe state, three ADCs, TIM2), then boots the coefficient blob from its
//! flash sector ([`firmware::boot`]), which refuses it unless magic,
//! version, length, CRC-32 and the parameter validation all pass; a
//! refused blob leaves the valves in the safe state, is reported through
//! defmt, and no control runs. With a good blob the TIM2 update interrupt
//! runs one control step per millisecond: three ADC conversions, the
//! controller, two PWM duties. On any fault the controller puts the valves
//! in its safe state in that same step.
//!
//! The set-point is the exercise of [`firmware::exercise::triangle`]
//! (contraction 0.06 → 0.16 → 0.06, 4 s period, repeated); replace
//! [`setpoint`] with the orthosis's own set-point source.
//!
//! Every tick reports to the controller whether it overran (the next tick
//! arrived before the step finished); `overrun_limit` overruns in a row are
//! `Fault::Overrun`. Every 10 s the interrupt logs the largest step time in
//! core cycles and the number of overruns since boot, and with feature
//! `adapt` the adapted stroke scale (`controller::adapt`).
//!
//! # When things go wrong
//! * **Stall**: the independent watchdog ([`wiring::WATCHDOG_MS`]) is
//!   started just before control begins and fed only after a completed
//!   control step. A stalled loop (an endless loop, a lock-up, an interrupt
//!   that no longer fires) resets the chip: the valve pins are undriven
//!   during the reset (both valves de-energise and close: the muscle holds
//!   its air), then boot writes the safe state and, seeing the watchdog's
//!   reset flag, starts **latched** (`Fault::Watchdog`): no control until
//!   an operator resets the board (NRST button or power cycle). A
//!   watchdog that does not take its configuration within its bounded
//!   waits ([`board::Watchdog::configure`]) refuses the boot: valves safe,
//!   no control.
//! * **Panic, HardFault, NMI, any other exception or unexpected
//!   interrupt**: the handlers ([`firmware::crash`]) first drive the valve
//!   pins to the safe state directly ([`board::valves_safe_now`]), then
//!   (the panic handler logs once) wait for the watchdog, which resets
//!   into the latched boot above (before the watchdog is started, they
//!   halt with the valves safe).
//! * **Latched faults** (more than `latch_trips` trips within the window):
//!   the valves stay safe; the operator resets with the NRST button or a
//!   power cycle (the latch lives in RAM).
#![no_std]
#![no_main]

use core::cell::RefCell;
use core::sync::atomic::{AtomicBool, Ordering};
use cortex_m::peripheral::{DWT, NVIC};
use cortex_m_rt::entry;
use critical_section::Mutex;
use defmt_rtt as _;
use firmware::board::{self, pam_board_control_step, BoardIo, Watchdog};
use firmware::boot::BootError;
use firmware::controller::{AdaptationConfig, ControllerConfig, Fault};
use firmware::crash::Exception;
use firmware::hal::{LoadCell, SafeState, Valve};
use firmware::{exercise, wiring, Controller};
use stm32f4xx_hal::pac::{self, interrupt, Interrupt, TIM2};
use stm32f4xx_hal::timer::{CounterHz, Flag};
use stm32f4xx_hal::{ClearFlags, ReadFlags};

/// The safe state the crash handlers write (the controller's default).
const SAFE: SafeState = ControllerConfig::DEFAULT.safety.safe_state;

/// Ticks in one period of the exercise trajectory.
const TRAJECTORY_TICKS: u32 = (exercise::PERIOD_S * wiring::CONTROL_HZ as f32) as u32;
/// Ticks between two timing reports (10 s).
const REPORT_TICKS: u32 = 10 * wiring::CONTROL_HZ;

/// Everything the control interrupt owns.
struct ControlLoop {
    ctl: Controller,
    io: BoardIo,
    tick: CounterHz<TIM2>,
    /// Fed after every completed step.
    watchdog: Watchdog,
    /// Position in the trajectory, ticks (`< TRAJECTORY_TICKS`).
    phase: u32,
    /// Steps since boot (wraps after 49 days; used only in log lines).
    steps: u32,
    /// Largest step time in the current report window, core cycles.
    max_cycles: u32,
    /// Ticks that arrived before their step finished, since boot.
    overruns: u32,
}

/// The control loop, put here by `main` before the interrupt is unmasked and
/// used only by the interrupt from then on. One static rather than a
/// hand-over plus a handler-local copy: `None` of this type is not all-zero
/// bits, so each such static costs its full size (1040 B) in `.data`, flash
/// and RAM both.
static LOOP: Mutex<RefCell<Option<ControlLoop>>> = Mutex::new(RefCell::new(None));

/// The desired contraction at `phase` ticks into the trajectory.
fn setpoint(phase: u32) -> f32 {
    exercise::triangle(phase as f32 * ControllerConfig::DEFAULT.dt_s)
}

/// No control: valves stay where `init` left them (safe), the core sleeps.
fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

#[entry]
fn main() -> ! {
    let config = ControllerConfig {
        // Feature `adapt`: the online adaptation of the model's stroke.
        adaptation: cfg!(feature = "adapt").then_some(AdaptationConfig::DEFAULT),
        ..ControllerConfig::DEFAULT
    };
    let safe = config.safety.safe_state;
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        halt()
    };
    let mut board = match board::init(dp, &mut cp.DCB, &mut cp.DWT, safe) {
        Ok(b) => b,
        Err(why) => {
            defmt::error!("board: init refused: {}; valves safe, no control", why);
            halt()
        }
    };
    defmt::info!(
        "board: {} Hz core, valve PWM {} Hz with {} duty steps, control {} Hz",
        wiring::SYSCLK_HZ,
        wiring::VALVE_PWM_HZ,
        board.max_duty,
        wiring::CONTROL_HZ
    );

    let blob = firmware::coeffs_blob();
    // The tracker starts at the measured load (clamped to the calibrated
    // range); a failed read starts it at the lightest load, and the first
    // step reports the fault. The load is read only once the blob passed.
    let booted = firmware::boot::boot(blob, config, |limits| match board.io.load.read_load_n() {
        Ok(l) if l.is_finite() => l,
        _ => limits.min_load_n,
    });
    let (mut ctl, load_n) = match booted {
        // A model with effects runs the feedforward that inverts them.
        Ok(b) => (b.controller, b.initial_load_n),
        Err(BootError::Blob(e)) => {
            defmt::error!(
                "boot: coefficient blob refused: {}; valves safe, no control",
                e
            );
            let _ = board.io.valve.set_safe(safe);
            halt()
        }
        Err(BootError::Controller(e)) => {
            defmt::error!("boot: controller refused: {}; valves safe, no control", e);
            let _ = board.io.valve.set_safe(safe);
            halt()
        }
    };
    defmt::info!(
        "boot: {} blob accepted ({} bytes), load {} N",
        if ctl.preisach().is_some() {
            "Preisach"
        } else {
            "coefficient"
        },
        blob.len(),
        load_n
    );
    let pmax_mpa = ctl.model_limits().max_pressure_mpa;
    let limit_mpa = ctl.config().safety.max_command_mpa;
    if limit_mpa < pmax_mpa {
        // The model's loop closes above what the hardware may be
        // commanded: set-points near the top of its stroke are out of reach.
        defmt::warn!(
            "boot: the model's Pmax {} MPa is above max_command_mpa {} MPa: commands stop at {} MPa",
            pmax_mpa,
            limit_mpa,
            limit_mpa
        );
    }
    if board.watchdog_reset {
        // The last run stalled: do not resume on our own.
        ctl.latch(Fault::Watchdog);
        defmt::error!(
            "boot: reset by the watchdog; valves safe and latched until NRST or power cycle"
        );
    }
    let mut watchdog = board.watchdog;

    critical_section::with(|cs| {
        LOOP.borrow(cs).replace(Some(ControlLoop {
            ctl,
            io: board.io,
            tick: board.tick,
            watchdog: {
                // From here a stall resets the chip (`board::init`
                // configured it, or refused to boot).
                watchdog.start();
                watchdog
            },
            phase: 0,
            steps: 0,
            max_cycles: 0,
            overruns: 0,
        }))
    });
    // SAFETY: unmasking cannot break a critical section here: `main` holds
    // none, and the handler's state was handed over just above.
    #[allow(unsafe_code)]
    unsafe {
        NVIC::unmask(Interrupt::TIM2)
    };
    halt()
}

#[interrupt]
fn TIM2() {
    // The step runs inside the critical section: this is the image's only
    // interrupt, so masking the others delays nothing.
    critical_section::with(|cs| {
        let mut state = LOOP.borrow(cs).try_borrow_mut();
        match state.as_deref_mut() {
            Ok(Some(s)) => control(s),
            // Nothing to run (cannot happen: main fills LOOP before
            // unmasking); mask the line so a pending flag does not spin.
            _ => NVIC::mask(Interrupt::TIM2),
        }
    });
}

/// One tick: the control step, its timing, and the log lines.
fn control(s: &mut ControlLoop) {
    s.tick.clear_flags(Flag::Update);
    let t0 = DWT::cycle_count();
    let step = pam_board_control_step(&mut s.ctl, &mut s.io, setpoint(s.phase));
    let cycles = DWT::cycle_count().wrapping_sub(t0);
    let overran = s.tick.flags().contains(Flag::Update);
    if overran {
        s.overruns = s.overruns.saturating_add(1);
    }
    s.ctl.record_overrun(overran);
    // Fed only here, after a step that completed.
    s.watchdog.feed();
    s.max_cycles = s.max_cycles.max(cycles);
    s.phase = if s.phase + 1 >= TRAJECTORY_TICKS {
        0
    } else {
        s.phase + 1
    };
    s.steps = s.steps.wrapping_add(1);

    if let Some(f) = step.new_fault {
        defmt::warn!("step {}: fault: {}; valves safe", s.steps, f);
    }
    if step.latched && step.new_fault.is_some() {
        defmt::error!(
            "step {}: valves latched safe until NRST or power cycle",
            s.steps
        );
    }
    if step.recovered {
        defmt::info!("step {}: recovered after a run of good readings", s.steps);
    }
    if s.steps % REPORT_TICKS == 0 {
        defmt::info!(
            "step {}: max step {} cycles over the last {} steps, {} overruns since boot",
            s.steps,
            s.max_cycles,
            REPORT_TICKS,
            s.overruns
        );
        s.max_cycles = 0;
        if let Some(a) = s.ctl.adaptation() {
            // The adapted parameter, for the host (pam-lab adapt turns it
            // into a model).
            defmt::info!(
                "step {}: adaptation: stroke scale {} after {} samples",
                s.steps,
                a.scale(),
                a.updates()
            );
        }
    }
}

/// Set by the first panic: a panic inside the handler (defmt's logger
/// taken, say) must not recurse into logging.
static PANICKING: AtomicBool = AtomicBool::new(false);

/// Valves safe first, then (once) the log line, then wait for the
/// watchdog to reset into the latched boot (before the watchdog runs:
/// stay here, valves safe).
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    board::valves_safe_now(SAFE);
    if !PANICKING.swap(true, Ordering::Relaxed) {
        defmt::error!("panic: {}; valves safe", defmt::Display2Format(info));
    }
    loop {
        cortex_m::asm::nop();
    }
}

firmware::crash_handlers!(crashed);

/// HardFault, the NMI and every exception or interrupt without a handler of
/// its own ([`firmware::crash`]): as the panic handler, valves safe first,
/// then wait for the watchdog (no log line: defmt's logger may be the
/// interrupted code's).
fn crashed(_exception: Exception) -> ! {
    board::valves_safe_now(SAFE);
    loop {
        cortex_m::asm::nop();
    }
}

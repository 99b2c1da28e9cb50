//! The self-test image: the real controller against the simulated muscle,
//! on an STM32F405 board (feature `selftest`, `cargo fw-selftest-run`) or
//! under QEMU's `netduinoplus2` (feature `qemu`, `cargo fw-qemu`). The board
//! controller that drives real valves is `src/main.rs` (`cargo fw-build`).
//!
//! Boot decodes the coefficient blob from its flash sector once
//! ([`firmware::boot`]) and refuses it unless magic, version, length,
//! CRC-32 and the parameter validation all pass; a refused blob leaves the
//! valves in the safe state and the image stops. With a good blob the image
//! runs [`firmware::scenario`]: the controller drives the simulated muscle
//! through the triangle trajectory, faults and recoveries are logged through
//! defmt (and, under QEMU, over semihosting), and the result decides the
//! exit code under QEMU (0 only if the run passes).
//!
//! With feature `qemu-panic` (`cargo fw-qemu-panic`) the image instead runs
//! the controller on the simulated muscle with the inlet filling, then
//! panics on purpose: the panic handler must put the valves in the safe
//! state before anything else; it prints the duties and exits with code
//! [`PANIC_EXIT_CODE`] when they are safe (1 otherwise). With feature
//! `qemu-nmi` (`cargo fw-qemu --features qemu-nmi`) the same run pends the
//! non-maskable interrupt instead, and with `qemu-unhandled` PendSV, which
//! has no handler of its own: the exception handlers ([`firmware::crash`],
//! shared with the board controller) must put the valves safe; the image
//! prints the duties and exits with 0 only when the pended exception
//! entered them and the valves read safe.
#![no_std]
#![no_main]

#[cfg(all(feature = "selftest", feature = "qemu"))]
compile_error!("enable one of the features `selftest` (board) and `qemu`, not both");
#[cfg(any(
    all(feature = "qemu-panic", feature = "qemu-nmi"),
    all(feature = "qemu-panic", feature = "qemu-unhandled"),
    all(feature = "qemu-nmi", feature = "qemu-unhandled"),
))]
compile_error!("enable at most one of the features `qemu-panic`, `qemu-nmi` and `qemu-unhandled`");

#[cfg(feature = "qemu")]
use core::sync::atomic::{AtomicU16, Ordering};
use cortex_m_rt::entry;
use defmt_rtt as _;
use firmware::controller::{ControllerConfig, Feedforward, Step};
#[cfg(feature = "qemu")]
use firmware::crash::Exception;
use firmware::hal::{SafeState, Valve, ValvePair, ValvePairConfig};
use firmware::plant::SimBus;
use firmware::scenario::{self, Report};
use firmware::sim_io::SimPwm;
#[cfg(feature = "qemu")]
use firmware::sim_io::PWM_MAX_DUTY;
#[cfg(feature = "qemu")]
use firmware::Controller;
#[cfg(not(feature = "qemu"))]
use panic_probe as _;

/// Exit code of the `qemu-panic` image when the panic handler left the
/// valves safe (the code a Rust program exits with on a panic).
#[cfg(feature = "qemu")]
pub const PANIC_EXIT_CODE: u32 = 101;

/// The valve duties of the `qemu-panic`, `qemu-nmi` and `qemu-unhandled`
/// runs, statics so the panic and exception handlers reach them as the
/// board's reach its pins.
#[cfg(feature = "qemu")]
static INLET_DUTY: AtomicU16 = AtomicU16::new(0);
#[cfg(feature = "qemu")]
static EXHAUST_DUTY: AtomicU16 = AtomicU16::new(0);

/// The exception the `qemu-nmi` or `qemu-unhandled` run pends, and so the
/// one its exception handler must be entered by (PendSV is vector 14,
/// cortex-m-rt's `irqn` −2).
#[cfg(feature = "qemu")]
const PENDED: Option<Exception> = if cfg!(feature = "qemu-nmi") {
    Some(Exception::Nmi)
} else if cfg!(feature = "qemu-unhandled") {
    Some(Exception::Unhandled { irqn: -2 })
} else {
    None
};

/// Log through defmt and, in the QEMU image, over semihosting as text.
macro_rules! log {
    ($level:ident, $($arg:tt)*) => {{
        defmt::$level!($($arg)*);
        #[cfg(feature = "qemu")]
        cortex_m_semihosting::hprintln!($($arg)*);
    }};
}

/// Stop: under QEMU exit with the given status; on a board hit a breakpoint
/// (probe-rs ends `run` there) and then sleep.
fn finish(passed: bool) -> ! {
    #[cfg(feature = "qemu")]
    cortex_m_semihosting::debug::exit(if passed {
        cortex_m_semihosting::debug::EXIT_SUCCESS
    } else {
        cortex_m_semihosting::debug::EXIT_FAILURE
    });
    #[cfg(not(feature = "qemu"))]
    {
        let _ = passed;
        cortex_m::asm::bkpt();
    }
    loop {
        cortex_m::asm::wfi();
    }
}

fn on_event(k: u32, step: &Step) {
    if let Some(f) = step.new_fault {
        log!(warn, "step {}: fault: {}; valves safe", k, f);
    }
    if step.recovered {
        log!(info, "step {}: recovered after a run of good readings", k);
    }
}

fn report(name: &str, r: &Report) {
    log!(
        info,
        "{}: max |error| {} (bound {}), rms {}, over {} steps, stroke scale {}",
        name,
        r.max_error,
        scenario::MAX_ERROR_BOUND,
        r.rms_error,
        r.steps,
        r.stroke_scale
    );
}

/// The `qemu-panic`, `qemu-nmi` and `qemu-unhandled` runs: control on the
/// simulated muscle, set-point at the top of the stroke, so the inlet is
/// filling; then a deliberate panic, or the pended exception ([`PENDED`]).
/// `ctl` is the controller boot built from the blob.
#[cfg(feature = "qemu")]
fn fault_demo(mut ctl: Controller) -> ! {
    use firmware::controller::Io;
    use firmware::hal::PressureCalibration;
    use firmware::plant::{MusclePlant, Noise, PlantConfig};
    use firmware::sim_io::{SimContraction, SimLoad, SimPressure};
    let Ok(valve) = ValvePair::new(
        SimPwm::new(&INLET_DUTY),
        SimPwm::new(&EXHAUST_DUTY),
        ValvePairConfig::DEFAULT,
    ) else {
        finish(false)
    };
    let bus = SimBus::new();
    let calibration = PressureCalibration::ADC12_0_1MPA;
    let mut io = Io {
        pressure: SimPressure {
            source: &bus,
            calibration,
        },
        contraction: SimContraction(&bus),
        load: SimLoad(&bus),
        valve,
    };
    // The blob's own model as the muscle; a Preisach blob's, which has no
    // load model to build the plant from, gets the run-pass scenario's.
    let plant_model = match ctl.coeffs() {
        Some(c) => c.load_model_clamped(scenario::LOAD_N),
        None => match pam_core::Coeffs::new(scenario::plant_params()) {
            Ok(c) => c.load_model_clamped(scenario::LOAD_N),
            Err(_) => finish(false),
        },
    };
    let mut plant = MusclePlant::new(plant_model, PlantConfig::DEFAULT);
    let mut noise = Noise::new(7);
    let dt_s = ControllerConfig::DEFAULT.dt_s;
    let max = f32::from(PWM_MAX_DUTY);
    for _ in 0..40 {
        bus.publish(
            &plant,
            scenario::LOAD_N,
            &calibration,
            &mut noise,
            scenario::NOISE,
        );
        ctl.step(&mut io, scenario::HIGH);
        let (i, e) = (
            INLET_DUTY.load(Ordering::Relaxed),
            EXHAUST_DUTY.load(Ordering::Relaxed),
        );
        plant.step(f32::from(i) / max, f32::from(e) / max, dt_s);
    }
    let (i, e) = (
        INLET_DUTY.load(Ordering::Relaxed),
        EXHAUST_DUTY.load(Ordering::Relaxed),
    );
    cortex_m_semihosting::hprintln!(
        "before the {}: inlet duty {}/{}, exhaust {}/{}, pressure {} MPa",
        match PENDED {
            Some(Exception::Nmi) => "NMI",
            Some(_) => "PendSV",
            None => "panic",
        },
        i,
        PWM_MAX_DUTY,
        e,
        PWM_MAX_DUTY,
        plant.pressure_mpa()
    );
    match PENDED {
        Some(Exception::Nmi) => {
            // The NMI, pended by software as the clock security system
            // would (ICSR bit 31, NMIPENDSET); it is taken at once.
            // SAFETY: writing NMIPENDSET pends the NMI; the zeros written to
            // the register's other bits change nothing.
            #[allow(unsafe_code)]
            unsafe {
                (*cortex_m::peripheral::SCB::PTR).icsr.write(1 << 31)
            };
        }
        // PendSV, taken at once (nothing masks it here).
        Some(_) => cortex_m::peripheral::SCB::set_pendsv(),
        None => {
            // The deliberate fault: an index the compiler cannot see is out
            // of range.
            let table = [0u8; 4];
            let k = core::hint::black_box(usize::from(i) + 4);
            let _ = core::hint::black_box(table[k]);
        }
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
    cortex_m_semihosting::hprintln!("the fault returned to thread mode");
    finish(false)
}

#[entry]
fn main() -> ! {
    // The image's valves are the simulated pair; put them in the safe state
    // before anything else, as a board's would be.
    let bus = SimBus::new();
    let mut valve = match ValvePair::new(
        SimPwm::new(&bus.inlet_duty),
        SimPwm::new(&bus.exhaust_duty),
        ValvePairConfig::DEFAULT,
    ) {
        Ok(v) => v,
        Err(why) => {
            log!(error, "valve configuration refused: {}", why);
            finish(false)
        }
    };
    let safe = ControllerConfig::DEFAULT.safety.safe_state;
    let _ = valve.set_safe(safe);

    let blob = firmware::coeffs_blob();
    // Decoded once: the controller of the fault demos, and the effects the
    // acceptance line names.
    let booted = match firmware::boot::boot(blob, ControllerConfig::DEFAULT, |_| scenario::LOAD_N) {
        Ok(b) => b,
        Err(e) => {
            log!(error, "boot: coefficient blob refused: {}", e.reason());
            let _ = valve.set_safe(SafeState::Exhaust);
            finish(false)
        }
    };
    let effects = booted.effects;
    let with_effects = effects != pam_core::Effects::NONE;
    let preisach = booted.controller.preisach().is_some();
    let named = |on: bool, name: &'static str| if on { name } else { "" };
    if preisach {
        log!(
            info,
            "boot: Preisach blob accepted ({} bytes, version {}, {} x {} relay rows at {} loads)",
            blob.len(),
            blob.get(4).copied().unwrap_or(0),
            firmware::controller::preisach::PREISACH_ROWS,
            firmware::controller::preisach::PREISACH_ROWS,
            firmware::controller::preisach::PREISACH_LOADS
        );
    } else {
        log!(
            info,
            "boot: coefficient blob accepted ({} bytes, version {}{}{}{}{}{}{}{})",
            blob.len(),
            blob.get(4).copied().unwrap_or(0),
            named(effects.memory.is_some(), ", non-local memory"),
            named(effects.rate.is_some(), ", rate dependence"),
            named(effects.creep.is_some(), ", creep"),
            named(effects.width.is_some(), ", load-dependent width"),
            named(effects.shape.is_some(), ", constraint shape"),
            named(effects.pressure_lag.is_some(), ", pressure lag"),
            named(effects.pressure_delay.is_some(), ", pressure delay")
        );
    }
    #[cfg(feature = "qemu")]
    if cfg!(feature = "qemu-panic") || PENDED.is_some() {
        fault_demo(booted.controller)
    }

    let run = |ff: Feedforward, events: bool| {
        scenario::run(blob, ff, |k, s| {
            if events {
                on_event(k, s)
            }
        })
    };
    let result = match run(Feedforward::Hysteresis, true) {
        Ok(r) => r,
        Err(e) => {
            log!(error, "scenario refused: {}", e);
            finish(false)
        }
    };
    report(
        if preisach {
            "Preisach feedforward"
        } else if with_effects {
            "hysteresis feedforward inverting the blob's effects"
        } else {
            "hysteresis feedforward"
        },
        &result,
    );
    // The same run without hysteresis compensation, for comparison only (a
    // Preisach model has no constraint model: refused, not run).
    if let Ok(r) = run(Feedforward::Constraint, false) {
        report("constraint-model feedforward", &r);
    }
    if let Ok(r) = run(Feedforward::Off, false) {
        report("no feedforward (PI only)", &r);
    }
    let passed = result.passed();
    log!(
        info,
        "fault caught in the same step: {}, recovery after {} good samples",
        result.fault_caught,
        result.recovery_steps.unwrap_or(0)
    );
    if passed {
        log!(info, "PASS");
    } else {
        log!(error, "FAIL");
    }
    finish(passed)
}

/// The exhaust-safe duties, straight to the valve channels.
#[cfg(feature = "qemu")]
fn valves_safe_now() {
    INLET_DUTY.store(0, Ordering::Relaxed);
    EXHAUST_DUTY.store(PWM_MAX_DUTY, Ordering::Relaxed);
}

/// Under QEMU: valves safe first, then report and end the emulator (with
/// [`PANIC_EXIT_CODE`] in the `qemu-panic` image when the valves read
/// safe, with a failure otherwise).
#[cfg(feature = "qemu")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    valves_safe_now();
    let (i, e) = (
        INLET_DUTY.load(Ordering::Relaxed),
        EXHAUST_DUTY.load(Ordering::Relaxed),
    );
    cortex_m_semihosting::hprintln!("panic: {}", info);
    cortex_m_semihosting::hprintln!(
        "panic handler: valves inlet duty {}/{}, exhaust {}/{}",
        i,
        PWM_MAX_DUTY,
        e,
        PWM_MAX_DUTY
    );
    if cfg!(feature = "qemu-panic") && (i, e) == (0, PWM_MAX_DUTY) {
        cortex_m_semihosting::hprintln!("panic handler: valves safe (exhaust open, inlet closed)");
        exit_with(PANIC_EXIT_CODE);
    }
    finish(false)
}

/// Semihosting `SYS_EXIT_EXTENDED`: QEMU exits with `code`.
#[cfg(feature = "qemu")]
fn exit_with(code: u32) {
    /// `ADP_Stopped_ApplicationExit`.
    const APPLICATION_EXIT: u32 = 0x20026;
    /// `SYS_EXIT_EXTENDED`.
    const SYS_EXIT_EXTENDED: usize = 0x20;
    let block = [APPLICATION_EXIT, code];
    // SAFETY: the semihosting call reads the two-word block, which lives on
    // this stack frame for the call's duration.
    #[allow(unsafe_code)]
    unsafe {
        cortex_m_semihosting::syscall(SYS_EXIT_EXTENDED, &block)
    };
}

#[cfg(feature = "qemu")]
firmware::crash_handlers!(crashed);

/// Under QEMU, HardFault, the NMI and every exception or interrupt without
/// a handler of its own ([`firmware::crash`]): valves safe first, then print
/// the duties and end the emulator, with success only for the exception
/// the `qemu-nmi` or `qemu-unhandled` run pended ([`PENDED`]) with the
/// valves read safe.
#[cfg(feature = "qemu")]
fn crashed(exception: Exception) -> ! {
    valves_safe_now();
    let (i, e) = (
        INLET_DUTY.load(Ordering::Relaxed),
        EXHAUST_DUTY.load(Ordering::Relaxed),
    );
    cortex_m_semihosting::hprintln!(
        "{}: valves inlet duty {}/{}, exhaust {}/{}",
        exception,
        i,
        PWM_MAX_DUTY,
        e,
        PWM_MAX_DUTY
    );
    finish(PENDED == Some(exception) && (i, e) == (0, PWM_MAX_DUTY))
}

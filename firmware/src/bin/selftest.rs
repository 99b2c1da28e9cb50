//! The self-test image: the real controller against the simulated muscle,
//! on an STM32F405 board (feature `selftest`, `cargo fw-selftest-run`) or
//! under QEMU's `netduinoplus2` (feature `qemu`, `cargo fw-qemu`). The board
//! controller that drives real valves is `src/main.rs` (`cargo fw-build`).
//!
//! Boot reads the coefficient blob from its flash sector and refuses it
//! unless magic, version, length, CRC-32 and the parameter validation all
//! pass; a refused blob leaves the valves in the safe state and the image
//! stops. With a good blob the image runs [`firmware::scenario`]: the
//! controller drives the simulated muscle through the triangle trajectory,
//! faults and recoveries are logged through defmt (and, under QEMU, over
//! semihosting), and the result decides the exit code under QEMU (0 only if
//! the run passes).
#![no_std]
#![no_main]

#[cfg(all(feature = "selftest", feature = "qemu"))]
compile_error!("enable one of the features `selftest` (board) and `qemu`, not both");

use cortex_m_rt::entry;
use defmt_rtt as _;
use firmware::controller::{ControllerConfig, Feedforward, Step};
use firmware::hal::{SafeState, Valve, ValvePair, ValvePairConfig};
use firmware::plant::{SimBus, SimPwm};
use firmware::scenario::{self, Report};
use firmware::Controller;
use pam_core::blob::BLOB_LEN;
#[cfg(not(feature = "qemu"))]
use panic_probe as _;

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
        "{}: max |error| {} (bound {}), rms {}, over {} steps",
        name,
        r.max_error,
        scenario::MAX_ERROR_BOUND,
        r.rms_error,
        r.steps
    );
}

#[entry]
fn main() -> ! {
    // The image's valves are the simulated pair; put them in the safe state
    // before anything else, as a board's would be.
    let bus = SimBus::new();
    let mut valve = match ValvePair::new(
        SimPwm(&bus.inlet_duty),
        SimPwm(&bus.exhaust_duty),
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
    if let Err(e) = Controller::from_blob(blob, ControllerConfig::DEFAULT, scenario::LOAD_N) {
        log!(error, "boot: coefficient blob refused: {}", e);
        let _ = valve.set_safe(SafeState::Exhaust);
        finish(false)
    }
    log!(info, "boot: coefficient blob accepted ({} bytes)", BLOB_LEN);

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
    report("hysteresis feedforward", &result);
    // The same run without hysteresis compensation, for comparison only.
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

/// Under QEMU a panic must end the emulator with a failure, not hang it.
#[cfg(feature = "qemu")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m_semihosting::hprintln!("panic: {}", info);
    finish(false)
}

/// Under QEMU a hard fault must end the emulator with a failure, not hang it.
#[cfg(feature = "qemu")]
#[allow(unsafe_code)] // cortex-m-rt requires the HardFault handler to be `unsafe fn`.
#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    cortex_m_semihosting::hprintln!("hard fault at pc {:#010x}", frame.pc());
    finish(false)
}

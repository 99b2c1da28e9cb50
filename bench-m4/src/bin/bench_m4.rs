//! The bench image: runs each measured call between two marker functions; the
//! `insn_count` QEMU plugin counts the instructions executed in between.
//! Names go out through semihosting in the same order as the plugin's regions.
#![no_std]
#![no_main]

use core::hint::black_box;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use pam_core::{Branch, Coeffs, Params, Tracker, TrackerConfig};

static STARTS: AtomicU32 = AtomicU32::new(0);
static ENDS: AtomicU32 = AtomicU32::new(0);

/// Start of a measured region. Its body differs from the end marker's (another
/// static), so LTO cannot fold the two into one address.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_marker_start() {
    STARTS.fetch_add(1, Ordering::Relaxed);
}

/// End of a measured region.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_marker_end() {
    ENDS.fetch_add(3, Ordering::Relaxed);
}

#[inline(always)]
fn measure<R>(f: impl FnOnce() -> R) -> R {
    bench_marker_start();
    let r = f();
    bench_marker_end();
    r
}

/// Run `f` once per input between markers; announce the group first.
fn group<T: Copy, R>(name: &str, inputs: &[T], mut f: impl FnMut(T) -> R) {
    hprintln!("group {} {}", name, inputs.len());
    for &x in inputs {
        black_box(measure(|| f(black_box(x))));
    }
}

#[entry]
fn main() -> ! {
    let Ok(coeffs) = Coeffs::new(Params::DEFAULT) else {
        debug::exit(debug::EXIT_FAILURE);
        loop {}
    };
    let model = coeffs.load_model_clamped(200.0);
    // The hardware square root must agree with the host's: at u = 0.6 of the
    // ellipse's half-width the offset is 0.8·be.
    let half = 0.5 * (model.max_contraction() - model.root_contraction());
    let x = model.root_contraction() + half * 1.6;
    let want = 0.8 * model.ellipse_height_mpa();
    if (model.offset_mpa(x) - want).abs() > 1e-6 {
        hprintln!("sqrt self-check failed");
        debug::exit(debug::EXIT_FAILURE);
    }
    let stroke = [
        0.0f32, 0.02, 0.04, 0.06, 0.08, 0.10, 0.12, 0.14, 0.16, 0.18, 0.20, 0.22, 0.24, 0.01, 0.11,
        0.21,
    ];
    let pressures: [f32; 16] = core::array::from_fn(|i| 0.5 * (i as f32 + 0.5) / 16.0);

    group("empty", &[0u8; 8], |x| x);
    group("forward_contraction", &stroke, |x| {
        model.pressure_mpa(x, Branch::Contraction)
    });
    group("forward_expansion", &stroke, |x| {
        model.pressure_mpa(x, Branch::Expansion)
    });
    group("inverse_contraction", &pressures, |p| {
        model.contraction(p, Branch::Contraction)
    });
    group("inverse_expansion", &pressures, |p| {
        model.contraction(p, Branch::Expansion)
    });

    let Ok(mut tracker) = Tracker::new(
        &coeffs,
        TrackerConfig::DEFAULT_PRESSURE,
        200.0,
        Branch::Contraction,
    ) else {
        debug::exit(debug::EXIT_FAILURE);
        loop {}
    };
    // A triangle of pressure samples with one reversal, at a steady load.
    let drive: [f32; 16] = core::array::from_fn(|i| {
        if i < 8 {
            0.1 + 0.01 * i as f32
        } else {
            0.17 - 0.01 * (i - 8) as f32
        }
    });
    group("tracker_update", &drive, |d| {
        tracker.update(&coeffs, d, 200.0).branch_switch.is_some()
    });

    hprintln!("done");
    debug::exit(debug::EXIT_SUCCESS);
    loop {}
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {}
}

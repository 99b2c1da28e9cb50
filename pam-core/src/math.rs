//! The few math primitives of the hot path, chosen per target.
//!
//! On `thumbv7em-none-eabihf` the FPU has `VSQRT.F32` (one instruction, 14
//! cycles), while `libm::sqrtf` is a software routine of 50–76 instructions
//! and `f32::sqrt` is not available in `no_std` on stable Rust (its `core`
//! form, `core::f32::math::sqrt`, is still behind the unstable
//! `core_float_math` feature in Rust 1.95). So the square
//! root is the one audited `unsafe` shim of this crate on ARM hard-float
//! targets (every `eabihf` FPU has `VSQRT.F32`), and
//! `libm::sqrtf` everywhere else (host tests, other targets).

/// Square root of a non-negative, finite `x` (callers clamp first).
#[inline(always)]
pub fn sqrt(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let bits: u32;
        // SAFETY: pure register arithmetic. The `sreg` operand class needs the
        // unstable `vfp2` target feature on stable Rust, so the value travels
        // in and out through core registers. `s0` is named as a discarded
        // output: rustc accepts clobbers of any register without the target
        // feature and hands them to LLVM as a clobber (`~{s0}`), so the
        // register allocator keeps nothing live in s0 across the asm (no
        // save/restore needed; checked in the disassembly of the bench image).
        // Every `eabihf` target has an FPU with VSQRT.F32.
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {y}, s0",
                x = in(reg) x.to_bits(),
                y = lateout(reg) bits,
                out("s0") _,
                options(pure, nomem, nostack, preserves_flags)
            );
        }
        f32::from_bits(bits)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// `x` limited to `[lo, hi]`; NaN maps to `lo`. Unlike `f32::clamp` it never
/// panics (the caller guarantees `lo <= hi`, and an inverted pair still
/// returns one of the two bounds).
#[inline(always)]
pub fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    if x >= lo {
        if x <= hi {
            x
        } else {
            hi
        }
    } else {
        lo
    }
}

/// `f64` square root for the host-side model path (construction, fitting):
/// `libm::sqrt` so that the same code builds without `std`.
#[inline]
pub fn sqrt_f64(x: f64) -> f64 {
    libm::sqrt(x)
}

/// `f64` [`clamp`]: `x` limited to `[lo, hi]`, NaN maps to `lo`, never panics.
#[inline]
pub fn clamp_f64(x: f64, lo: f64, hi: f64) -> f64 {
    if x >= lo {
        if x <= hi {
            x
        } else {
            hi
        }
    } else {
        lo
    }
}

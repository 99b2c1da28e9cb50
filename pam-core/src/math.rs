//! The few math primitives of the hot path, chosen per target.
//!
//! On `thumbv7em-none-eabihf` the FPU has `VSQRT.F32` (one instruction, 14
//! cycles), while `libm::sqrtf` is a software routine of 50–76 instructions
//! and `f32::sqrt` is not available in `no_std` on stable Rust. So the square
//! root is the one audited `unsafe` shim of this crate on that target, and
//! `libm::sqrtf` everywhere else (host tests, other targets).

/// Square root of a non-negative, finite `x` (callers clamp first).
#[inline(always)]
pub fn sqrt(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_feature = "vfp2"))]
    {
        let y: f32;
        // SAFETY: VSQRT.F32 reads one S register and writes one; it touches no
        // memory, no stack and no flags other than the FPSCR exception bits.
        #[allow(unsafe_code)]
        unsafe {
            core::arch::asm!(
                "vsqrt.f32 {y}, {x}",
                x = in(sreg) x,
                y = lateout(sreg) y,
                options(pure, nomem, nostack)
            );
        }
        y
    }
    #[cfg(not(all(target_arch = "arm", target_feature = "vfp2")))]
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

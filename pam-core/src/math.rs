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
//!
//! [`powf`] is a power of pam-core's own for the rate law's exponents other
//! than 0.5, 0.75 and 1: `libm::powf` is a correctly rounded software
//! routine of 241 instructions on the M4F, this one 115 (bench-m4's
//! `effects` row); the rate law needs six digits, not 24 bits (micromath's
//! `exp(n·ln x)` is 16 % off at some rates, too far).

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

/// `x^n` for `x > 0` and a moderate `n` (the rate law: `x` up to
/// `MAX_RATE_MPA_PER_S`, `n` in `RATE_EXPONENT_RANGE`), to 2e-6 relative
/// where `|n·ln x| <= 21` (rates from 1e-6 to 5 MPa/s; test
/// `the_power_is_within_two_millionths_on_the_rate_laws_range`; beyond, the
/// `f32` rounding of `n·ln x` grows the error with it): `e^(n·ln x)` with
/// `ln x` from the exponent bits and the series
/// `ln m = 2·atanh((m − 1)/(m + 1))` for the mantissa in `[√½, √2)` (four
/// terms, the fifth under 2e-8), and `e^y = 2^k·e^r`, `|r| <= ln2/2`, by
/// its Taylor series to `r⁶/6!` (the next term under 2e-7). No table, one
/// division. `0` for `x <= 0`, NaN or a result below `f32`'s normal range;
/// `x` not finite gives `x`.
#[inline(never)]
pub fn powf(x: f32, n: f32) -> f32 {
    // Cody–Waite: `ln 2` as a part an integer up to 2¹² multiplies exactly
    // (its low 12 mantissa bits zero) and the rest.
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    if !(x > 0.0) {
        return 0.0;
    }
    if !x.is_finite() || !n.is_finite() {
        return x;
    }
    if x < f32::MIN_POSITIVE {
        // Subnormal: no exponent bits to read; the rate law's term there
        // is zero to any precision it needs.
        return 0.0;
    }
    let bits = x.to_bits();
    // A normal `x`: the biased exponent is in 1..=254.
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    if m > core::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let ln_m = 2.0 * t * (1.0 + t2 * (1.0 / 3.0 + t2 * (1.0 / 5.0 + t2 * (1.0 / 7.0))));
    // `ln x = e·ln 2 + ln m`, `e·ln 2` in the two parts of `LN2_HI`/`LN2_LO`
    // (Cody–Waite: `e·LN2_HI` is exact).
    let y = n * (e as f32 * LN2_HI + (e as f32 * LN2_LO + ln_m));
    // e^y = 2^k·e^r; below 2^-126 the result is not a normal f32.
    let v = y * core::f32::consts::LOG2_E;
    if !(v > -126.0) {
        return 0.0;
    }
    if !(v < 127.0) {
        return f32::MAX;
    }
    // `v` is in (−126, 127): the casts cannot wrap.
    let k = if v >= 0.0 {
        (v + 0.5) as i32
    } else {
        (v - 0.5) as i32
    };
    let r = (y - k as f32 * LN2_HI) - k as f32 * LN2_LO;
    let er = 1.0
        + r * (1.0
            + r * (1.0 / 2.0
                + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0))))));
    // `k + 127` is in 1..=254 after the rounding: a normal power of two.
    let scale = f32::from_bits(((k + 127).clamp(1, 254) as u32) << 23);
    er * scale
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

/// The least `f32` above `x` (`f32::next_up`, which is newer than the
/// crate's MSRV); NaN and +∞ are returned as they are.
pub(crate) fn next_up(x: f32) -> f32 {
    if x.is_nan() || x == f32::INFINITY {
        return x;
    }
    let bits = x.to_bits();
    if x == 0.0 {
        return f32::from_bits(1);
    }
    f32::from_bits(if x > 0.0 { bits + 1 } else { bits - 1 })
}

/// The greatest `f32` below `x`: `-next_up(-x)`.
pub(crate) fn next_down(x: f32) -> f32 {
    -next_up(-x)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_up_and_down_are_the_neighbouring_floats() {
        for x in [0.0f32, -0.0, 1e-30, 0.07, -0.07, 3.5, 1e30, -1e30] {
            let (u, d) = (next_up(x), next_down(x));
            assert!(u > x && d < x, "{x}");
            assert_eq!(next_down(u), if x == 0.0 { 0.0 } else { x }, "{x}");
            assert!(
                (u - x) <= f32::EPSILON * x.abs().max(f32::MIN_POSITIVE),
                "{x}"
            );
        }
        assert!(next_up(f32::NAN).is_nan());
        assert_eq!(next_up(f32::INFINITY), f32::INFINITY);
        assert_eq!(next_down(f32::NEG_INFINITY), f32::NEG_INFINITY);
    }

    #[test]
    fn the_power_is_within_two_millionths_on_the_rate_laws_range() {
        // Every exponent a rate law accepts, every filtered rate from 1e-6
        // MPa/s to the largest, 5: against the power in f64.
        let mut worst = 0.0f64;
        for i in 0..=120 {
            let n = 0.3 + 1.2 * i as f32 / 120.0;
            for j in 0..=3_000 {
                let x = 1e-6f32 * 10f32.powf(j as f32 * (5f32.log10() + 6.0) / 3_000.0);
                let got = f64::from(powf(x, n));
                let want = f64::from(x).powf(f64::from(n));
                worst = worst.max((got - want).abs() / want);
            }
        }
        assert!(worst <= 2e-6, "worst relative error {worst:e}");
        // Far outside it, still a power (the error grows with |n·ln x|).
        let far = f64::from(powf(1e-30, 1.2));
        let want = f64::from(1e-30f32).powf(1.2);
        assert!((far / want - 1.0).abs() < 1e-4, "{far} vs {want}");
        assert_eq!(powf(0.0, 0.7), 0.0);
        assert_eq!(powf(-1.0, 0.7), 0.0);
        assert_eq!(powf(f32::NAN, 0.7), 0.0);
        assert_eq!(powf(1e-40, 0.7), 0.0);
        assert_eq!(powf(1.0, 0.7), 1.0);
        assert_eq!(powf(f32::INFINITY, 0.7), f32::INFINITY);
    }
}

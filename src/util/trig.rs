//! `f64` sine and cosine for the angles the calibration meets, and an exact floating remainder.
//!
//! [`sin`], [`cos`] and [`sincos`] return bit for bit what `libm`'s functions of the same names
//! return for |x| < 2²⁰·π/2 (about 1.65e6 rad, 260,000 turns): the same kernels and the same
//! Cody–Waite argument reduction, with the same constants and operation order (from FreeBSD's
//! msun by way of musl and `libm`; notice below). What is left out is the Payne–Hanek reduction
//! of huge arguments (3.4 KiB of firmware flash with its table), which headings, heading errors
//! and arc angles never need. A larger argument is first folded into (−2π, 2π) by the exact
//! remainder [`fmod`] with the `f64` value of 2π, whose representation error (2.4e-16) makes the
//! folded angle off by at most |x|·4e-17 rad: 2.5e-10 rad after a million turns.
//!
//! [`fmod`] is `x − n·y` for the integer `n` that truncates `x/y`, computed exactly (the result is
//! always representable), as C's `fmod` and `libm::fmod`.
//!
//! ```text
//! ====================================================
//! Copyright (C) 1993 by Sun Microsystems, Inc. All rights reserved.
//!
//! Developed at SunPro, a Sun Microsystems, Inc. business.
//! Permission to use, copy, modify, and distribute this
//! software is freely granted, provided that this notice
//! is preserved.
//! ====================================================
//! ```

use core::f64::consts::TAU;

/// Sine of `x` (radians); `libm::sin` bit for bit for |x| < 2²⁰·π/2, see the module docs.
pub fn sin(x: f64) -> f64 {
    let ix = high_word(x);
    if ix <= 0x3fe9_21fb {
        // |x| ≲ π/4
        if ix < 0x3e50_0000 {
            return x; // |x| < 2⁻²⁶
        }
        return k_sin(x, 0.0, false);
    }
    if ix >= 0x7ff0_0000 {
        return f64::NAN; // ±∞, NaN
    }
    let (n, y0, y1) = rem_pio2(x);
    match n & 3 {
        0 => k_sin(y0, y1, true),
        1 => k_cos(y0, y1),
        2 => -k_sin(y0, y1, true),
        _ => -k_cos(y0, y1),
    }
}

/// Cosine of `x` (radians); `libm::cos` bit for bit for |x| < 2²⁰·π/2, see the module docs.
pub fn cos(x: f64) -> f64 {
    let ix = high_word(x);
    if ix <= 0x3fe9_21fb {
        if ix < 0x3e46_a09e {
            return 1.0; // |x| < 2⁻²⁷·√2
        }
        return k_cos(x, 0.0);
    }
    if ix >= 0x7ff0_0000 {
        return f64::NAN;
    }
    let (n, y0, y1) = rem_pio2(x);
    match n & 3 {
        0 => k_cos(y0, y1),
        1 => -k_sin(y0, y1, true),
        2 => -k_cos(y0, y1),
        _ => k_sin(y0, y1, true),
    }
}

/// `(sin x, cos x)`; `libm::sincos` bit for bit for |x| < 2²⁰·π/2, see the module docs.
pub fn sincos(x: f64) -> (f64, f64) {
    let ix = high_word(x);
    if ix <= 0x3fe9_21fb {
        if ix < 0x3e46_a09e {
            return (x, 1.0);
        }
        return (k_sin(x, 0.0, false), k_cos(x, 0.0));
    }
    if ix >= 0x7ff0_0000 {
        return (f64::NAN, f64::NAN);
    }
    let (n, y0, y1) = rem_pio2(x);
    let (s, c) = (k_sin(y0, y1, true), k_cos(y0, y1));
    match n & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Largest |x| [`sincos_f32`] reduces itself; `k·π/2` with `k` up to 2¹² is exact in its
/// three-part constant.
const SINCOS_F32_REDUCED: f32 = 6000.0;

/// `(sin x, cos x)` in `f32` with `f32` kernels (the FPU of the Cortex-M4F; `libm::sincosf`
/// evaluates its kernels in `f64`, which is soft-float there). Cody–Waite reduction by π/2 with
/// a three-part constant (Cephes), then FreeBSD's `__sindf`/`__cosdf` polynomials on
/// |r| ≤ π/4 (their coefficients rounded to `f32`). Within 1.2e-7 of the true values for
/// |x| ≤ 6000 (test `sincos_f32_error`); larger or non-finite arguments go through [`sincos`]
/// (correctly rounded to `f32` there, and no Payne–Hanek table in the firmware as
/// `libm::sincosf` would bring). Not bit-identical to `libm::sincosf`, but the same on every IEEE target:
/// plain `f32` arithmetic, no fused operations.
pub fn sincos_f32(x: f32) -> (f32, f32) {
    const FRAC_2_PI: f32 = core::f32::consts::FRAC_2_PI;
    // π/2 = P1 + P2 + P3; P1 and P2 have few significant bits, so k·P1 and k·P2 are exact.
    const P1: f32 = 1.570_312_5;
    const P2: f32 = 4.837_513e-4;
    const P3: f32 = 7.549_79e-8;
    const S1: f32 = -0.166_666_67;
    const S2: f32 = 0.008_333_329;
    const S3: f32 = -1.983_933_5e-4;
    const S4: f32 = 2.718_311_5e-6;
    const C0: f32 = -0.5;
    const C1: f32 = 0.041_666_623;
    const C2: f32 = -0.001_388_676_4;
    const C3: f32 = 2.439_045e-5;
    if x.is_nan() || x.abs() > SINCOS_F32_REDUCED {
        let (s, c) = sincos(f64::from(x));
        return (s as f32, c as f32);
    }
    let half = if x < 0.0 { -0.5 } else { 0.5 };
    let k = (x * FRAC_2_PI + half) as i32;
    let kf = k as f32;
    let r = ((x - kf * P1) - kf * P2) - kf * P3;
    let z = r * r;
    let w = z * z;
    let s = r + r * z * (S1 + z * S2) + r * z * w * (S3 + z * S4);
    let c = ((1.0 + z * C0) + w * C1) + w * z * (C2 + z * C3);
    match k & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// An angle in degrees wrapped into (-180, 180].
pub fn wrap_deg(d: f64) -> f64 {
    let mut d = fmod(d, 360.0);
    if d > 180.0 {
        d -= 360.0;
    } else if d <= -180.0 {
        d += 360.0;
    }
    d
}

/// `x − n·y` with `n = trunc(x/y)`, exact; the sign of `x`. NaN for a NaN or infinite `x`, a
/// NaN or zero `y`; `x` itself for an infinite `y`.
pub fn fmod(x: f64, y: f64) -> f64 {
    if x.is_nan() || y.is_nan() || x.is_infinite() || y == 0.0 {
        return f64::NAN;
    }
    let ay = y.abs();
    if x.abs() < ay {
        return x; // also the infinite `y`
    }
    let (mx, ex) = mantissa_exponent(x.abs());
    let (my, ey) = mantissa_exponent(ay);
    // |x| ≥ |y| with both mantissas in [2⁵², 2⁵³): ex ≥ ey. Long division one bit at a time.
    let mut r = mx % my;
    for _ in ey..ex {
        r = (r << 1) % my;
    }
    // r < my < 2⁵³ is exact as f64, and r·2^ey is the representable result. Below 2⁻¹⁰⁷⁴ (a
    // subnormal `y`) r is a multiple of the difference, and m·2⁻¹⁰⁷⁴ has the bits m for m < 2⁵³.
    let magnitude = if ey >= -1074 {
        r as f64 * pow2(ey)
    } else {
        f64::from_bits(r >> (-1074 - ey))
    };
    if x.is_sign_negative() {
        -magnitude
    } else {
        magnitude
    }
}

/// `(m, e)` with `v = m·2^e`, `m` in [2⁵², 2⁵³), for a finite `v > 0`.
fn mantissa_exponent(v: f64) -> (u64, i32) {
    let bits = v.to_bits();
    let biased = (bits >> 52) as i32;
    let fraction = bits & ((1 << 52) - 1);
    if biased == 0 {
        // Subnormal: v = fraction·2⁻¹⁰⁷⁴; shift its top bit up to bit 52.
        let shift = fraction.leading_zeros() as i32 - 11;
        (fraction << shift, -1074 - shift)
    } else {
        (fraction | (1 << 52), biased - 1075)
    }
}

/// 2^e for −1074 ≤ e ≤ 1023 (exact).
fn pow2(e: i32) -> f64 {
    if e >= -1022 {
        f64::from_bits(((e + 1023) as u64) << 52)
    } else {
        f64::from_bits(1 << (e + 1074))
    }
}

/// The high 32 bits of `x` without the sign.
fn high_word(x: f64) -> u32 {
    (x.to_bits() >> 32) as u32 & 0x7fff_ffff
}

// Kernels on [−π/4, π/4] (`y` the tail of the reduced argument).
const S1: f64 = f64::from_bits(0xbfc5_5555_5555_5549); // -1.66666666666666324348e-1
const S2: f64 = f64::from_bits(0x3f81_1111_1110_f8a6); // 8.33333333332248946124e-3
const S3: f64 = f64::from_bits(0xbf2a_01a0_19c1_61d5); // -1.98412698298579493134e-4
const S4: f64 = f64::from_bits(0x3ec7_1de3_57b1_fe7d); // 2.75573137070700676789e-6
const S5: f64 = f64::from_bits(0xbe5a_e5e6_8a2b_9ceb); // -2.50507602534068634195e-8
const S6: f64 = f64::from_bits(0x3de5_d93a_5acf_d57c); // 1.58969099521155010221e-10
const C1: f64 = f64::from_bits(0x3fa5_5555_5555_554c); // 4.16666666666666019037e-2
const C2: f64 = f64::from_bits(0xbf56_c16c_16c1_5177); // -1.38888888888741095749e-3
const C3: f64 = f64::from_bits(0x3efa_01a0_19cb_1590); // 2.48015872894767294178e-5
const C4: f64 = f64::from_bits(0xbe92_7e4f_809c_52ad); // -2.75573143513906633035e-7
const C5: f64 = f64::from_bits(0x3e21_ee9e_bdb4_b1c4); // 2.08757232129817482790e-9
const C6: f64 = f64::from_bits(0xbda8_fae9_be88_38d4); // -1.13596475577881948265e-11

fn k_sin(x: f64, y: f64, with_tail: bool) -> f64 {
    let z = x * x;
    let w = z * z;
    let r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    let v = z * x;
    if with_tail {
        x - ((z * (0.5 * y - v * r) - y) - v * S1)
    } else {
        x + v * (S1 + z * r)
    }
}

fn k_cos(x: f64, y: f64) -> f64 {
    let z = x * x;
    let w = z * z;
    let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    w + (((1.0 - w) - hz) + (z * r - x * y))
}

// π/2 in pieces for the reduction.
const TO_INT: f64 = 1.5 / f64::EPSILON;
const INV_PIO2: f64 = f64::from_bits(0x3fe4_5f30_6dc9_c883); // 6.36619772367581382433e-1
const PIO2_1: f64 = f64::from_bits(0x3ff9_21fb_5440_0000); // 1.57079632673412561417
const PIO2_1T: f64 = f64::from_bits(0x3dd0_b461_1a62_6331); // 6.07710050650619224932e-11
const PIO2_2: f64 = f64::from_bits(0x3dd0_b461_1a60_0000); // 6.07710050630396597660e-11
const PIO2_2T: f64 = f64::from_bits(0x3ba3_198a_2e03_7073); // 2.02226624879595063154e-21
const PIO2_3: f64 = f64::from_bits(0x3ba3_198a_2e00_0000); // 2.02226624871116645580e-21
const PIO2_3T: f64 = f64::from_bits(0x397b_839a_2520_49c1); // 8.47842766036889956997e-32

/// `(n, y0, y1)` with `x = n·π/2 + y0 + y1`, |y0 + y1| ≤ π/4 (about).
fn rem_pio2(x: f64) -> (i32, f64, f64) {
    let ix = high_word(x);
    // Small multiples of π/2 by one subtraction, as libm does (bit-identical results need the
    // same branches); the multiples of the pieces are exact constants.
    let near = |p: f64, t: f64, n: i32| near_multiple(x, p, t, n);
    if ix <= 0x400f_6a7a {
        // |x| ≲ 5π/4
        if ix & 0xfffff == 0x921fb {
            return medium(x, ix); // |x| ≈ π/2 or π: cancellation
        }
        return if ix <= 0x4002_d97c {
            near(1.0 * PIO2_1, 1.0 * PIO2_1T, 1)
        } else {
            near(2.0 * PIO2_1, 2.0 * PIO2_1T, 2)
        };
    }
    if ix <= 0x401c_463b {
        // |x| ≲ 9π/4
        if ix <= 0x4015_fdbc {
            if ix == 0x4012_d97c {
                return medium(x, ix); // |x| ≈ 3π/2
            }
            return near(3.0 * PIO2_1, 3.0 * PIO2_1T, 3);
        }
        if ix == 0x4019_21fb {
            return medium(x, ix); // |x| ≈ 2π
        }
        return near(4.0 * PIO2_1, 4.0 * PIO2_1T, 4);
    }
    if ix < 0x4139_21fb {
        return medium(x, ix); // |x| < 2²⁰·π/2
    }
    // Huge: fold into (−2π, 2π) first (module docs), then the reduction above (which expects
    // |x| > π/4).
    let folded = fmod(x, TAU);
    if high_word(folded) <= 0x3fe9_21fb {
        return (0, folded, 0.0);
    }
    rem_pio2(folded)
}

/// `x ∓ n·π/2` as `(±n, y0, y1)`, with `p`, `t` = n·`PIO2_1`, n·`PIO2_1T`.
#[inline(always)]
fn near_multiple(x: f64, p: f64, t: f64, n: i32) -> (i32, f64, f64) {
    if x.is_sign_negative() {
        let z = x + p;
        let y0 = z + t;
        (-n, y0, (z - y0) + t)
    } else {
        let z = x - p;
        let y0 = z - t;
        (n, y0, (z - y0) - t)
    }
}

/// Cody–Waite reduction in up to three rounds (good to 151 bits for |x| < 2²⁰·π/2).
fn medium(x: f64, ix: u32) -> (i32, f64, f64) {
    let f_n = (x * INV_PIO2 + TO_INT) - TO_INT;
    let n = f_n as i32;
    let mut r = x - f_n * PIO2_1;
    let mut w = f_n * PIO2_1T;
    let mut y0 = r - w;
    let ex = (ix >> 20) as i32;
    let ey = (y0.to_bits() >> 52) as i32 & 0x7ff;
    if ex - ey > 16 {
        let t = r;
        w = f_n * PIO2_2;
        r = t - w;
        w = f_n * PIO2_2T - ((t - r) - w);
        y0 = r - w;
        let ey = (y0.to_bits() >> 52) as i32 & 0x7ff;
        if ex - ey > 49 {
            let t = r;
            w = f_n * PIO2_3;
            r = t - w;
            w = f_n * PIO2_3T - ((t - r) - w);
            y0 = r - w;
        }
    }
    (n, y0, (r - y0) - w)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `f32` kernel against `f64` sine and cosine of the same `f32` argument: within 1.2e-7
    /// (two `f32` ulps of values near 1) over |x| ≤ 6000, at multiples of π/2 and their
    /// neighbours and at random arguments; beyond 6000 it is the `f64` [`sincos`] rounded.
    #[test]
    fn sincos_f32_error() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut worst = 0.0f64;
        let mut check = |x: f32| {
            let (s, c) = sincos_f32(x);
            let e = (f64::from(s) - f64::from(x).sin())
                .abs()
                .max((f64::from(c) - f64::from(x).cos()).abs());
            assert!(e < 1.2e-7, "x = {x}: {s} {c} ({e:e})");
            worst = worst.max(e);
        };
        for k in -3820..=3820 {
            let x = (f64::from(k) * core::f64::consts::FRAC_PI_2) as f32;
            for y in [
                x,
                f32::from_bits(x.to_bits() + 1),
                f32::from_bits(x.to_bits().max(1) - 1),
            ] {
                check(y);
            }
        }
        for _ in 0..200_000 {
            let u = (next(&mut state) >> 11) as f64 / (1u64 << 53) as f64;
            check(((u - 0.5) * 12_000.0) as f32);
            check(((u - 0.5) * 8.0) as f32);
        }
        check(0.0);
        check(-0.0);
        check(1e-30);
        assert!(worst > 0.0);
        let (s, c) = sincos(7000.0);
        assert_eq!(sincos_f32(7000.0), (s as f32, c as f32));
        assert!(sincos_f32(f32::NAN).0.is_nan());
    }

    /// xorshift64: reproducible arguments without a dependency.
    fn next(state: &mut u64) -> u64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    }

    /// Arguments over the whole supported range, denser where the reduction has its branches
    /// (multiples of π/2 and their neighbours, tiny values), both signs.
    fn arguments() -> Vec<f64> {
        let mut v = vec![0.0, -0.0, 1e-300, 2f64.powi(-26), 2f64.powi(-27) * 1.5];
        for k in -2_000..=2_000 {
            let c = f64::from(k) * core::f64::consts::FRAC_PI_2;
            for d in -3i32..=3 {
                let mut x = c;
                for _ in 0..d.abs() {
                    x = if d > 0 { x.next_up() } else { x.next_down() };
                }
                v.push(x);
            }
        }
        let mut s = 0x9e37_79b9_7f4a_7c15;
        for _ in 0..200_000 {
            let u = (next(&mut s) >> 11) as f64 / (1u64 << 53) as f64;
            let scale = [0.8, 4.0, 8.0, 30.0, 1e3, 1.6e6][(next(&mut s) % 6) as usize];
            let x = (2.0 * u - 1.0) * scale;
            v.push(x);
        }
        v
    }

    #[test]
    fn sin_cos_sincos_bit_identical_to_libm_in_range() {
        for x in arguments() {
            assert!(x.abs() < 1.647e6);
            assert_eq!(sin(x).to_bits(), libm::sin(x).to_bits(), "sin({x:e})");
            assert_eq!(cos(x).to_bits(), libm::cos(x).to_bits(), "cos({x:e})");
            let (s, c) = sincos(x);
            let (ls, lc) = libm::sincos(x);
            assert_eq!(
                (s.to_bits(), c.to_bits()),
                (ls.to_bits(), lc.to_bits()),
                "{x:e}"
            );
        }
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(sin(x).is_nan() && cos(x).is_nan());
            assert!(sincos(x).0.is_nan() && sincos(x).1.is_nan());
        }
    }

    /// Beyond 2²⁰·π/2 the fold by the `f64` 2π costs |x|·4e-17 rad at most (module docs): the
    /// difference to the correctly reduced `std` values stays within that plus a few ulp.
    #[test]
    fn huge_arguments_within_the_fold_error() {
        let mut s = 7;
        for _ in 0..20_000 {
            let e = (next(&mut s) % 40) as i32 + 21; // 2²¹ … 2⁶⁰
            let u = 1.0 + (next(&mut s) >> 11) as f64 / (1u64 << 53) as f64;
            let sign = if next(&mut s) & 1 == 0 { 1.0 } else { -1.0 };
            let x = sign * u * 2f64.powi(e);
            let bound = x.abs() * 4e-17 + 4.0 * f64::EPSILON;
            assert!((sin(x) - x.sin()).abs() <= bound, "sin({x:e})");
            assert!((cos(x) - x.cos()).abs() <= bound, "cos({x:e})");
            let (si, co) = sincos(x);
            assert!((si - x.sin()).abs() <= bound && (co - x.cos()).abs() <= bound);
        }
        assert!((sin(f64::MAX) - f64::MAX.sin()).abs() <= 2.0);
    }

    #[test]
    fn fmod_bit_identical_to_libm() {
        let mut s = 99;
        let mut cases = vec![
            (0.0, 360.0),
            (-0.0, 360.0),
            (360.0, 360.0),
            (-720.0, 360.0),
            (f64::MAX, 360.0),
            (f64::MAX, TAU),
            (-f64::MAX, 1e-300),
            (5e-324, 3e-324),
            (1e-310, 3e-320),
            (7.0, f64::INFINITY),
        ];
        for _ in 0..100_000 {
            let x = f64::from_bits(next(&mut s) & !(0x7ff << 52) | ((next(&mut s) % 2047) << 52));
            let y = [360.0, TAU, 1.0, 0.1, 3e-310][(next(&mut s) % 5) as usize];
            cases.push((x, y));
            cases.push((x, -y));
        }
        for (x, y) in cases {
            assert_eq!(
                fmod(x, y).to_bits(),
                libm::fmod(x, y).to_bits(),
                "fmod({x:e}, {y:e})"
            );
        }
        assert!(fmod(f64::NAN, 1.0).is_nan() && fmod(1.0, f64::NAN).is_nan());
        assert!(fmod(f64::INFINITY, 1.0).is_nan() && fmod(1.0, 0.0).is_nan());
    }
}

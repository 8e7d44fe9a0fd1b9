//! Small decimal formatting of `f64` without `core`'s float formatting machinery.
//!
//! `core::fmt`'s float formatting (Grisu/Dragon with their tables) costs about 12 KB of flash;
//! the replies only need three shapes, produced here with integer arithmetic:
//!
//! - [`Decimal`]: fixed decimals, like `{:.N}` / `{:+.N}`;
//! - [`Scientific`]: one digit, `N` decimals and a decimal exponent, like `{:.Ne}`;
//! - [`Plain`]: up to 9 decimals with trailing zeros removed, the `{}` text of "round" numbers
//!   such as range bounds (`0.1`, `10`, `0.001`).
//!
//! The value `m · 2^e` of the `f64` is scaled by `10^N` exactly in 128-bit integers and rounded
//! half to even, which is what `core` does, so the text is byte for byte the same as `core`'s
//! whenever the rounded result fits in a `u64` (`|v| · 10^N < 1.8e19`), for every `N ≤ 19`.
//! Larger values fall back to [`Scientific`]. `Scientific` is exact for `|v| < 10^N` and
//! `|v| ≥ 10^(N−19)`; outside that (|v| ≥ 1000 or < 1e-16 for `N = 3`) its scaling takes a few
//! extra roundings, so a digit may differ from `core` at an exact half-way point. NaN prints as
//! `NaN`, infinities as `inf`/`-inf` (`+inf` with [`Decimal::signed`]), and a negative zero
//! keeps its sign (`-0.000`), as in `core`.
//!
//! Every type pads through [`fmt::Formatter::pad`], so width and alignment (`{:<9}`) work; do
//! not pass a precision in the format string, the number of decimals is part of the value.

use core::fmt;

/// `10^k` for `k = 0..=19` (all that fit in a `u64`).
const POW10: [u64; 20] = {
    let mut t = [1u64; 20];
    let mut k = 1;
    while k < 20 {
        t[k] = t[k - 1] * 10;
        k += 1;
    }
    t
};

/// Largest number of decimals [`Decimal`] and [`Scientific`] print (more are clamped).
pub const MAX_PLACES: u8 = 17;

/// `{:.N}` (or `{:+.N}` with [`Decimal::signed`]) of an `f64`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decimal {
    /// The value.
    pub value: f64,
    /// Digits after the decimal point (0 prints no point), at most [`MAX_PLACES`].
    pub places: u8,
    /// Print `+` before non-negative values.
    pub plus_sign: bool,
}

impl Decimal {
    /// `value` with `places` decimals, like `{:.places}`.
    pub const fn fixed(value: f64, places: u8) -> Self {
        Self {
            value,
            places,
            plus_sign: false,
        }
    }

    /// `value` with `places` decimals and an explicit sign, like `{:+.places}`.
    pub const fn signed(value: f64, places: u8) -> Self {
        Self {
            value,
            places,
            plus_sign: true,
        }
    }
}

/// `{:.Ne}` of an `f64`: `d.ddde-4`, exponent without `+` or leading zeros.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scientific {
    /// The value.
    pub value: f64,
    /// Digits after the decimal point of the mantissa, at most [`MAX_PLACES`].
    pub places: u8,
}

impl Scientific {
    /// `value` with `places` mantissa decimals, like `{:.places e}`.
    pub const fn new(value: f64, places: u8) -> Self {
        Self { value, places }
    }
}

/// `{}` of an `f64` whose shortest decimal form has at most 9 decimals and that is below
/// 1.8e10 in magnitude (range bounds, limits): 9 decimals with trailing zeros and a bare point
/// removed. Other values print their 9-decimal rounding (trimmed) or, when too large, the
/// [`Scientific`] form with 9 decimals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plain(pub f64);

/// Text buffer for one number: sign, up to 20 integer digits, point, up to 19 decimals, `e-324`.
struct Buf {
    bytes: [u8; 48],
    len: usize,
}

impl Buf {
    const fn new() -> Self {
        Self {
            bytes: [0; 48],
            len: 0,
        }
    }

    fn push(&mut self, b: u8) {
        if let Some(slot) = self.bytes.get_mut(self.len) {
            *slot = b;
            self.len += 1;
        }
    }

    fn push_str(&mut self, s: &str) {
        for &b in s.as_bytes() {
            self.push(b);
        }
    }

    /// Appends the decimal digits of `v`, at least `min_digits` of them (zero-padded).
    fn push_digits(&mut self, mut v: u64, min_digits: usize) {
        let mut digits = [0u8; 20];
        let mut n = 0;
        while (v > 0 || n < min_digits) && n < digits.len() {
            digits[n] = b'0' + (v % 10) as u8;
            v /= 10;
            n += 1;
        }
        if n == 0 {
            self.push(b'0');
        }
        for &d in digits[..n].iter().rev() {
            self.push(d);
        }
    }

    fn as_str(&self) -> &str {
        // Only ASCII is ever pushed.
        core::str::from_utf8(self.bytes.get(..self.len).unwrap_or(&[])).unwrap_or("")
    }
}

/// `(m, e)` with `|v| = m · 2^e` exactly.
fn decompose(v: f64) -> (u64, i32) {
    let bits = v.to_bits();
    let frac = bits & ((1u64 << 52) - 1);
    let exp = ((bits >> 52) & 0x7ff) as i32;
    if exp == 0 {
        (frac, -1074)
    } else {
        (frac | (1u64 << 52), exp - 1075)
    }
}

/// `|v| · 10^s` rounded half to even, exactly, for `s ≤ 19`; `None` when it exceeds `u64`.
fn scaled(m: u64, e: i32, s: u8) -> Option<u64> {
    let pow = POW10.get(usize::from(s)).copied()?;
    // m < 2^53 and 10^19 < 2^64: the product fits in 117 bits.
    let n = u128::from(m) * u128::from(pow);
    let q = if e >= 0 {
        if n != 0 && n.leading_zeros() <= e.unsigned_abs() {
            return None;
        }
        n << e
    } else {
        let sh = e.unsigned_abs();
        if sh >= 118 {
            // n < 2^117 ≤ half of 2^sh: rounds to zero.
            return Some(0);
        }
        let q = n >> sh;
        let rem = n & ((1u128 << sh) - 1);
        let half = 1u128 << (sh - 1);
        q + u128::from(rem > half || (rem == half && q & 1 == 1))
    };
    u64::try_from(q).ok()
}

/// Sign prefix: `-` for a set sign bit (also `-0.0`), `+` when asked for, else nothing.
fn sign(v: f64, plus: bool) -> &'static str {
    if v.is_sign_negative() {
        "-"
    } else if plus {
        "+"
    } else {
        ""
    }
}

/// Writes NaN/infinity the way `core` does; `false` for a finite value.
fn non_finite(buf: &mut Buf, v: f64, plus: bool) -> bool {
    if v.is_nan() {
        buf.push_str("NaN");
    } else if v.is_infinite() {
        buf.push_str(sign(v, plus));
        buf.push_str("inf");
    } else {
        return false;
    }
    true
}

fn write_fixed(buf: &mut Buf, v: f64, places: u8, plus: bool) {
    if non_finite(buf, v, plus) {
        return;
    }
    let places = places.min(MAX_PLACES);
    let (m, e) = decompose(v);
    let Some(q) = scaled(m, e, places) else {
        write_scientific(buf, v, places, plus);
        return;
    };
    buf.push_str(sign(v, plus));
    let pow = POW10[usize::from(places)];
    buf.push_digits(q / pow, 1);
    if places > 0 {
        buf.push(b'.');
        buf.push_digits(q % pow, usize::from(places));
    }
}

/// `|v| · 10^s` rounded half to even, for any `s`: exact for `0 ≤ s ≤ 19`, otherwise after
/// scaling by powers of ten in `f64` (a few roundings).
fn scaled_any(v: f64, s: i32) -> Option<u64> {
    let (m, e) = decompose(v);
    if (0..=19).contains(&s) {
        return scaled(m, e, s as u8);
    }
    let mut x = libm::fabs(v);
    let mut rest = s;
    while rest > 19 {
        x *= 1e19;
        rest -= 19;
    }
    while rest < 0 {
        let step = rest.max(-19);
        x /= POW10[step.unsigned_abs() as usize] as f64;
        rest -= step;
    }
    let (m, e) = decompose(x);
    scaled(m, e, rest as u8)
}

fn write_scientific(buf: &mut Buf, v: f64, places: u8, plus: bool) {
    if non_finite(buf, v, plus) {
        return;
    }
    let places = places.min(MAX_PLACES);
    let p = i32::from(places);
    let (m, e) = decompose(v);
    let top = POW10[usize::from(places) + 1];
    let (mut digits, mut k) = (0u64, 0i32);
    if m != 0 {
        // floor(log2 |v|), then floor(log10 |v|) or one less (78913 / 2^18 ≈ log10 2).
        let log2 = 63 - m.leading_zeros() as i32 + e;
        k = (log2 * 78_913) >> 18;
        for _ in 0..2 {
            digits = scaled_any(v, p - k).unwrap_or(top);
            if digits < top {
                break;
            }
            k += 1;
        }
        if digits >= top {
            // Rounded up to 10^(p+1): one digit more in the exponent.
            digits /= 10;
            k += 1;
        }
    }
    buf.push_str(sign(v, plus));
    let pow = POW10[usize::from(places)];
    buf.push_digits(digits / pow, 1);
    if places > 0 {
        buf.push(b'.');
        buf.push_digits(digits % pow, usize::from(places));
    }
    buf.push(b'e');
    if k < 0 {
        buf.push(b'-');
    }
    buf.push_digits(u64::from(k.unsigned_abs()), 1);
}

impl fmt::Display for Decimal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut buf = Buf::new();
        write_fixed(&mut buf, self.value, self.places, self.plus_sign);
        f.pad(buf.as_str())
    }
}

impl fmt::Display for Scientific {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut buf = Buf::new();
        write_scientific(&mut buf, self.value, self.places, false);
        f.pad(buf.as_str())
    }
}

impl fmt::Display for Plain {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut buf = Buf::new();
        write_fixed(&mut buf, self.0, 9, false);
        let text = buf.as_str();
        // Trailing zeros and then a bare point go, unless the text is an exponent form. Plain
        // byte loops: `str::contains`, `trim_end_matches` and `<[u8]>::contains` would link
        // 0.4 KiB of searchers.
        let bytes = text.as_bytes();
        let (mut point, mut exponent) = (false, false);
        for &b in bytes {
            point |= b == b'.';
            exponent |= b == b'e';
        }
        let mut end = bytes.len();
        if point && !exponent {
            while end > 0 && bytes.get(end - 1) == Some(&b'0') {
                end -= 1;
            }
            if end > 0 && bytes.get(end - 1) == Some(&b'.') {
                end -= 1;
            }
        }
        f.pad(text.get(..end).unwrap_or(text))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// xorshift64*: reproducible random bits.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
        }
    }

    /// A random finite f64 spread over many magnitudes, sometimes a value on a decimal grid
    /// (ties and round numbers), sometimes a random bit pattern.
    fn value(rng: &mut Rng) -> f64 {
        let r = rng.next();
        let v = match r % 4 {
            0 => f64::from_bits(rng.next()),
            1 => {
                // k/2^j: exact binary fractions, the half-way cases of decimal rounding.
                (rng.next() % 1_000_000) as f64 / f64::from(1u32 << (rng.next() % 24))
            }
            2 => (rng.next() % 2_000_001) as f64 / POW10[(rng.next() % 10) as usize] as f64,
            _ => {
                let mant = (rng.next() >> 11) as f64 / (1u64 << 53) as f64;
                mant * libm::pow(10.0, (rng.next() % 40) as f64 - 20.0)
            }
        };
        if r & (1 << 40) != 0 { -v } else { v }
    }

    #[test]
    fn fixed_matches_core_bit_for_bit() {
        // Exact agreement is the claim wherever |v|·10^N < 1.8e19: no tolerance.
        let mut rng = Rng(0x0DDB_1A5E_5BAD_5EED);
        let mut checked = 0;
        for _ in 0..300_000 {
            let v = value(&mut rng);
            let places = (rng.next() % 10) as u8;
            let p = usize::from(places);
            if !v.is_finite() || libm::fabs(v) * libm::pow(10.0, f64::from(places)) >= 1.8e19 {
                continue;
            }
            checked += 1;
            assert_eq!(
                Decimal::fixed(v, places).to_string(),
                format!("{v:.p$}"),
                "{v:e} .{p}"
            );
            assert_eq!(
                Decimal::signed(v, places).to_string(),
                format!("{v:+.p$}"),
                "{v:e} +.{p}"
            );
        }
        assert!(checked > 100_000, "{checked}");
    }

    #[test]
    fn scientific_matches_core_in_exact_domain() {
        let mut rng = Rng(0x1234_5678_9ABC_DEF1);
        let mut checked = 0;
        for _ in 0..300_000 {
            let v = value(&mut rng);
            let places = (rng.next() % 8) as u8;
            let p = usize::from(places);
            let a = libm::fabs(v);
            // Exact domain documented above: 10^(N-19) ≤ |v| < 10^N (or zero).
            let lo = libm::pow(10.0, f64::from(places) - 19.0);
            let hi = libm::pow(10.0, f64::from(places));
            if !(a == 0.0 || (a >= lo * 10.0 && a < hi / 10.0)) {
                continue;
            }
            checked += 1;
            assert_eq!(
                Scientific::new(v, places).to_string(),
                format!("{v:.p$e}"),
                "{v:e} .{p}e"
            );
        }
        assert!(checked > 50_000, "{checked}");
    }

    #[test]
    fn scientific_outside_exact_domain_is_close() {
        // Large and tiny values take a few f64 roundings: the printed mantissa may differ from
        // core's in the last digit only (one unit), the exponent never.
        let mut rng = Rng(42);
        for _ in 0..50_000 {
            let v = f64::from_bits(rng.next() >> 2 | 1 << 61)
                * if rng.next() & 1 == 0 { 1.0 } else { 1e-250 };
            if !v.is_finite() || v == 0.0 {
                continue;
            }
            let ours = Scientific::new(v, 6).to_string();
            let core = format!("{v:.6e}");
            let (om, oe) = ours.split_once('e').expect("exponent");
            let (cm, ce) = core.split_once('e').expect("exponent");
            assert_eq!(oe, ce, "{ours} vs {core}");
            let om: f64 = om.parse().expect("mantissa");
            let cm: f64 = cm.parse().expect("mantissa");
            assert!(libm::fabs(om - cm) < 1.5e-6, "{ours} vs {core}");
        }
    }

    #[test]
    fn special_values_as_core() {
        for v in [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            0.0,
            -0.0,
            5e-324,
            1e-300,
        ] {
            for places in [0u8, 3, 6] {
                let p = usize::from(places);
                assert_eq!(Decimal::fixed(v, places).to_string(), format!("{v:.p$}"));
                assert_eq!(Scientific::new(v, places).to_string(), format!("{v:.p$e}"));
                if !v.is_nan() {
                    assert_eq!(Decimal::signed(v, places).to_string(), format!("{v:+.p$}"));
                }
            }
        }
    }

    #[test]
    fn too_large_for_fixed_falls_back_to_exponent() {
        assert_eq!(Decimal::fixed(1.5e25, 3).to_string(), "1.500e25");
        assert_eq!(Decimal::signed(-2e19, 1).to_string(), "-2.0e19");
    }

    #[test]
    fn plain_is_shortest_for_round_numbers() {
        for v in [
            0.0,
            0.1,
            0.001,
            0.01,
            0.05,
            1.0,
            2.0,
            5.0,
            10.0,
            20.0,
            100.0,
            360.0,
            6.0,
            1e8,
            4_294_967_295.0,
            -100.0,
            -360.0,
            0.5,
            2.5,
            0.123_456_789,
        ] {
            assert_eq!(Plain(v).to_string(), format!("{v}"));
        }
        // Too large for the fixed form: the exponent form keeps its zeros.
        assert_eq!(Plain(2e30).to_string(), "2.000000000e30");
        assert_eq!(format!("{:>6}|", Plain(-0.25)), " -0.25|");
    }

    #[test]
    fn padding_and_alignment() {
        assert_eq!(format!("{:<9}|", Scientific::new(2.5e-4, 3)), "2.500e-4 |");
        assert_eq!(format!("{:>8}", Decimal::fixed(1.2, 3)), "   1.200");
    }
}

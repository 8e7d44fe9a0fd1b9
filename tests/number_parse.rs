//! Property tests of the protocol's number parser against `str::parse::<f64>`.
//!
//! - exactness: 200,000 random decimal strings with ≤ 15 significant digits and a decimal
//!   exponent within ±22 (written in many shapes: sign, leading/trailing zeros, point anywhere,
//!   explicit exponent) parse to exactly the bits `str::parse` gives;
//! - grammar: 200,000 random short strings over the number alphabet are accepted or rejected
//!   exactly as by `str::parse` (except the documented digit limit), and accepted ones agree on
//!   NaN/infinity and, for finite values, to within a few ulp.
//!
//! The generator is a seeded xorshift64*, so a failure is reproducible from the printed text.

use odocal::protocol::number::{MAX_DIGITS, NumberError, parse_f64};

#[path = "support/rng.rs"]
mod rng;
use rng::Rng;

/// A decimal string for `digits × 10^k` with 1..=15 significant digits and |k| ≤ 22.
fn exact_domain_string(rng: &mut Rng, s: &mut String) {
    s.clear();
    let n = 1 + rng.below(15) as usize;
    let mut digits: Vec<u8> = (0..n).map(|_| b'0' + rng.below(10) as u8).collect();
    digits[0] = b'1' + rng.below(9) as u8;
    // Value = digits × 10^k; |k| ≤ 22.
    let k = rng.below(45) as i32 - 22;
    // Write it as (digits with a point after `int_len` of them) × 10^explicit.
    let int_len = rng.below(n as u64 + 1) as i32;
    let explicit = k + n as i32 - int_len;
    match rng.below(3) {
        0 => s.push('-'),
        1 => s.push('+'),
        _ => {}
    }
    for _ in 0..rng.below(3) {
        s.push('0');
    }
    if explicit > 0 && rng.below(2) == 0 && explicit <= 8 {
        // Trailing zeros in place of the exponent.
        s.extend(digits.iter().map(|&d| d as char));
        for _ in 0..explicit {
            s.push('0');
        }
        if rng.below(2) == 0 {
            s.push('.');
        }
        return;
    }
    let int_len = int_len as usize;
    s.extend(digits[..int_len].iter().map(|&d| d as char));
    if int_len < n || rng.below(4) == 0 {
        s.push('.');
    }
    s.extend(digits[int_len..].iter().map(|&d| d as char));
    for _ in 0..rng.below(3) {
        if int_len < n {
            s.push('0');
        }
    }
    if explicit != 0 || rng.below(4) == 0 {
        s.push(if rng.below(2) == 0 { 'e' } else { 'E' });
        if explicit >= 0 && rng.below(2) == 0 {
            s.push('+');
        }
        s.push_str(&explicit.to_string());
    }
}

#[test]
fn bit_identical_to_core_in_exact_domain() {
    let mut rng = Rng(0xC0FF_EE00_1234_5678);
    let mut s = String::new();
    for i in 0..200_000 {
        exact_domain_string(&mut rng, &mut s);
        let core: f64 = s
            .parse()
            .unwrap_or_else(|e| panic!("{i}: core rejects {s:?}: {e}"));
        let ours = parse_f64(&s).unwrap_or_else(|e| panic!("{i}: rejects {s:?}: {e}"));
        // Exactness is the claim: compare the bits, no tolerance.
        assert_eq!(
            ours.to_bits(),
            core.to_bits(),
            "{i}: {s:?}: {ours:e} vs {core:e}"
        );
    }
}

#[test]
fn grammar_and_classification_match_core() {
    const ALPHABET: &[&str] = &[
        "0", "1", "5", "9", "0", "7", ".", "e", "E", "+", "-", "inf", "nan", "Infinity", "x", "_",
        " ", "99", "308", "400",
    ];
    let mut rng = Rng(0x5EED_0000_0000_0001);
    let (mut accepted, mut rejected) = (0u32, 0u32);
    let mut s = String::new();
    for i in 0..200_000 {
        s.clear();
        for _ in 0..1 + rng.below(8) {
            s.push_str(ALPHABET[rng.below(ALPHABET.len() as u64) as usize]);
        }
        let core = s.parse::<f64>();
        let ours = parse_f64(&s);
        match (ours, core) {
            (Ok(a), Ok(b)) => {
                accepted += 1;
                assert_eq!(a.is_nan(), b.is_nan(), "{i}: {s:?}");
                assert_eq!(a.is_infinite(), b.is_infinite(), "{i}: {s:?}");
                assert_eq!(a.is_sign_negative(), b.is_sign_negative(), "{i}: {s:?}");
                if a.is_finite() && b != 0.0 {
                    // Outside the exact domain the scaling takes a few roundings: 1e-14
                    // relative is ~45 ulp, far more than the ≤ 20 steps can add.
                    let rel = ((a - b) / b).abs();
                    assert!(rel < 1e-14, "{i}: {s:?}: {a:e} vs {b:e}");
                } else if a.is_finite() {
                    assert_eq!(a, b, "{i}: {s:?}");
                }
            }
            (Err(NumberError::TooManyDigits), Ok(_)) => {
                let significant = s
                    .trim_start_matches(['+', '-', '0', '.'])
                    .bytes()
                    .take_while(|b| b.is_ascii_digit() || *b == b'.')
                    .filter(u8::is_ascii_digit)
                    .count();
                assert!(significant > MAX_DIGITS as usize, "{i}: {s:?}");
            }
            (Err(_), Err(_)) => rejected += 1,
            (ours, core) => panic!("{i}: {s:?}: ours {ours:?}, core {core:?}"),
        }
    }
    // The generator must exercise both outcomes many times (measured: tens of thousands each).
    assert!(
        accepted > 10_000 && rejected > 10_000,
        "{accepted} / {rejected}"
    );
}

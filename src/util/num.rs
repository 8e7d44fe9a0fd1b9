//! Small numeric helpers shared by the control code.
//!
//! [`clamp`] replaces `f32::clamp`/`f64::clamp`: those assert `min <= max` with a message that
//! formats both bounds with `Debug`, which alone links `core`'s float formatting (about 10 KB of
//! flash) into the firmware. Callers pass bounds that are ordered by construction.
//!
//! [`fmax`] and [`fmin`] are `libm::fmax`/`libm::fmin` out of line: `libm` inlines its NaN
//! handling (about 30 bytes) into each of the two dozen callers, a call costs a few.

/// `x` limited to `[lo, hi]`; NaN stays NaN (like `f64::clamp`). Bounds out of order or NaN do
/// not panic: the result is then `lo` when `x < lo`, else `hi` when `x > hi`, else `x`.
#[inline]
pub fn clamp<T: PartialOrd>(x: T, lo: T, hi: T) -> T {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

/// Whether `v` is finite and within `[lo, hi]`: the range check of the limits, motor models and
/// stored settings, out of line (inlined, each of its 14 uses cost about 40 bytes).
#[inline(never)]
pub fn within(v: f32, lo: f32, hi: f32) -> bool {
    v.is_finite() && v >= lo && v <= hi
}

/// `libm::round(x) as u32` (saturating; NaN gives 0), out of line: the integer parameters
/// and the identification's block length share one copy of the saturating conversion.
#[inline(never)]
pub fn round_u32(x: f64) -> u32 {
    libm::round(x) as u32
}

/// `libm::ceil(x) as i64` (saturating; NaN gives 0), out of line: the saturating conversion
/// is a few soft-float comparisons at each of the callers that turn a distance into counts.
#[inline(never)]
pub fn ceil_i64(x: f64) -> i64 {
    libm::ceil(x) as i64
}

/// `libm::fmax` (the larger of `x` and `y`; the other one when either is NaN), out of line.
#[inline(never)]
pub fn fmax(x: f64, y: f64) -> f64 {
    libm::fmax(x, y)
}

/// `libm::fmin` (the smaller of `x` and `y`; the other one when either is NaN), out of line.
#[inline(never)]
pub fn fmin(x: f64, y: f64) -> f64 {
    libm::fmin(x, y)
}

#[cfg(test)]
mod tests {
    use super::{ceil_i64, clamp, round_u32, within};

    #[test]
    fn round_u32_saturates() {
        assert_eq!(round_u32(2.5), 3);
        assert_eq!(round_u32(2.49), 2);
        assert_eq!(round_u32(-3.0), 0);
        assert_eq!(round_u32(f64::NAN), 0);
        assert_eq!(round_u32(1e12), u32::MAX);
    }

    #[test]
    fn within_is_finite_and_inclusive() {
        assert!(within(0.001, 0.001, 5.0));
        assert!(within(5.0, 0.001, 5.0));
        assert!(!within(5.000_001, 0.001, 5.0));
        assert!(!within(0.0, 0.001, 5.0));
        assert!(!within(f32::NAN, 0.001, 5.0));
        assert!(!within(f32::INFINITY, 0.0, f32::INFINITY));
    }

    #[test]
    fn ceil_i64_saturates() {
        assert_eq!(ceil_i64(1.2), 2);
        assert_eq!(ceil_i64(-1.5), -1);
        assert_eq!(ceil_i64(3.0), 3);
        assert_eq!(ceil_i64(f64::NAN), 0);
        assert_eq!(ceil_i64(1e30), i64::MAX);
        assert_eq!(ceil_i64(f64::NEG_INFINITY), i64::MIN);
    }

    #[test]
    fn same_as_core_for_ordered_bounds() {
        // Every pairing of values below, inside, at and above the bounds, plus NaN and -0.0:
        // the result must be bit-identical to core's clamp.
        let xs = [
            -3.0,
            -1.0,
            -0.5,
            -0.0,
            0.0,
            0.5,
            1.0,
            3.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for &x in &xs {
            for (lo, hi) in [(-1.0, 1.0), (0.0, 0.0), (-0.5, 2.0)] {
                assert_eq!(
                    clamp(x, lo, hi).to_bits(),
                    x.clamp(lo, hi).to_bits(),
                    "{x} {lo} {hi}"
                );
            }
        }
        assert!(clamp(f64::NAN, -1.0, 1.0).is_nan());
        assert_eq!(clamp(2.5f32, -1.0, 1.0), 1.0);
    }
}

//! Two `f64` lanes computed side by side: the plant's right and left wheel (or the two
//! coordinates of a position) in one SSE2 instruction on x86-64, plain pairs elsewhere.
//!
//! Every operation is the IEEE operation of each lane, so the results are bit-identical to the
//! same arithmetic written with scalars, on every architecture.
//!
//! [`Host`] is the arithmetic host-sim runs the library's robot model with: these lanes and the
//! platform's `exp` and `sin_cos`.

use core::ops::{Add, Div, Mul, Sub};

use odocal::plant::{Lanes, Numerics};

#[cfg(target_arch = "x86_64")]
mod lanes {
    use core::arch::x86_64::{
        __m128d, _mm_add_pd, _mm_cvtsd_f64, _mm_div_pd, _mm_mul_pd, _mm_set_pd, _mm_set1_pd,
        _mm_sub_pd, _mm_unpackhi_pd,
    };

    // SAFETY (every `unsafe` block below): the intrinsics only need SSE2, which every x86-64
    // processor has (it is part of the architecture's baseline, always enabled by rustc).

    #[derive(Clone, Copy, Debug)]
    pub struct Lanes(__m128d);

    impl Lanes {
        #[inline(always)]
        pub fn new(a: f64, b: f64) -> Self {
            Lanes(unsafe { _mm_set_pd(b, a) })
        }
        #[inline(always)]
        pub fn splat(a: f64) -> Self {
            Lanes(unsafe { _mm_set1_pd(a) })
        }
        #[inline(always)]
        pub fn a(self) -> f64 {
            unsafe { _mm_cvtsd_f64(self.0) }
        }
        #[inline(always)]
        pub fn b(self) -> f64 {
            unsafe { _mm_cvtsd_f64(_mm_unpackhi_pd(self.0, self.0)) }
        }
        #[inline(always)]
        pub fn add(self, o: Self) -> Self {
            Lanes(unsafe { _mm_add_pd(self.0, o.0) })
        }
        #[inline(always)]
        pub fn sub(self, o: Self) -> Self {
            Lanes(unsafe { _mm_sub_pd(self.0, o.0) })
        }
        #[inline(always)]
        pub fn mul(self, o: Self) -> Self {
            Lanes(unsafe { _mm_mul_pd(self.0, o.0) })
        }
        #[inline(always)]
        pub fn div(self, o: Self) -> Self {
            Lanes(unsafe { _mm_div_pd(self.0, o.0) })
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
mod lanes {
    #[derive(Clone, Copy, Debug)]
    pub struct Lanes([f64; 2]);

    impl Lanes {
        #[inline(always)]
        pub fn new(a: f64, b: f64) -> Self {
            Lanes([a, b])
        }
        #[inline(always)]
        pub fn splat(a: f64) -> Self {
            Lanes([a, a])
        }
        #[inline(always)]
        pub fn a(self) -> f64 {
            self.0[0]
        }
        #[inline(always)]
        pub fn b(self) -> f64 {
            self.0[1]
        }
        #[inline(always)]
        pub fn add(self, o: Self) -> Self {
            Lanes([self.0[0] + o.0[0], self.0[1] + o.0[1]])
        }
        #[inline(always)]
        pub fn sub(self, o: Self) -> Self {
            Lanes([self.0[0] - o.0[0], self.0[1] - o.0[1]])
        }
        #[inline(always)]
        pub fn mul(self, o: Self) -> Self {
            Lanes([self.0[0] * o.0[0], self.0[1] * o.0[1]])
        }
        #[inline(always)]
        pub fn div(self, o: Self) -> Self {
            Lanes([self.0[0] / o.0[0], self.0[1] / o.0[1]])
        }
    }
}

/// Two `f64` lanes `(a, b)`; arithmetic is lane by lane.
#[derive(Clone, Copy, Debug)]
pub struct Pair(lanes::Lanes);

impl Lanes for Pair {
    #[inline(always)]
    fn new(a: f64, b: f64) -> Self {
        Pair(lanes::Lanes::new(a, b))
    }

    #[inline(always)]
    fn splat(v: f64) -> Self {
        Pair(lanes::Lanes::splat(v))
    }

    #[inline(always)]
    fn a(self) -> f64 {
        self.0.a()
    }

    #[inline(always)]
    fn b(self) -> f64 {
        self.0.b()
    }
}

/// host-sim's arithmetic for the robot model: [`Pair`] lanes, the platform's `exp`/`sin_cos`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Host;

impl Numerics for Host {
    type Pair = Pair;

    #[inline(always)]
    fn exp(x: f64) -> f64 {
        x.exp()
    }

    #[inline(always)]
    fn sin_cos(x: f64) -> (f64, f64) {
        x.sin_cos()
    }
}

impl Add for Pair {
    type Output = Pair;
    #[inline(always)]
    fn add(self, o: Pair) -> Pair {
        Pair(self.0.add(o.0))
    }
}

impl Sub for Pair {
    type Output = Pair;
    #[inline(always)]
    fn sub(self, o: Pair) -> Pair {
        Pair(self.0.sub(o.0))
    }
}

impl Mul for Pair {
    type Output = Pair;
    #[inline(always)]
    fn mul(self, o: Pair) -> Pair {
        Pair(self.0.mul(o.0))
    }
}

impl Div for Pair {
    type Output = Pair;
    #[inline(always)]
    fn div(self, o: Pair) -> Pair {
        Pair(self.0.div(o.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_are_the_scalar_operations() {
        // Values whose products and quotients round (not exact in binary).
        let (a, b, c, d) = (0.1, -1.0 / 3.0, 2.0f64.sqrt(), 1e-300);
        let x = Pair::new(a, b);
        let y = Pair::new(c, d);
        let bits = |p: Pair| (p.a().to_bits(), p.b().to_bits());
        assert_eq!(bits(x + y), ((a + c).to_bits(), (b + d).to_bits()));
        assert_eq!(bits(x - y), ((a - c).to_bits(), (b - d).to_bits()));
        assert_eq!(bits(x * y), ((a * c).to_bits(), (b * d).to_bits()));
        assert_eq!(bits(x / y), ((a / c).to_bits(), (b / d).to_bits()));
        assert_eq!(bits(Pair::splat(c)), (c.to_bits(), c.to_bits()));
    }
}

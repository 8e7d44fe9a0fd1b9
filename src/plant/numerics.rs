//! The arithmetic the robot model is generic over: two `f64` lanes (the right and left wheel, or
//! the x and y of a position) and the two transcendental functions it evaluates (`exp` for the
//! motor lag's decay, `sin_cos` for the heading).
//!
//! [`Portable`] is plain pairs and `libm`: the same bits on the host and on the Cortex-M4
//! (the emulator board and qemu-bench run it on the target, and qemu-bench's fidelity check
//! compares the two). host-sim supplies its own: SSE2 lanes and the platform's `exp`/`sin_cos`
//! (faster on the host; the platform's functions may differ from `libm`'s in the last bit).

use core::ops::{Add, Div, Mul, Sub};

/// Two `f64` lanes `(a, b)`; every operator is the IEEE operation of each lane, so a lane's
/// result is bit-identical to the same arithmetic written with scalars.
pub trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// The pair `(a, b)`.
    fn new(a: f64, b: f64) -> Self;
    /// `(v, v)`.
    fn splat(v: f64) -> Self;
    /// The first lane.
    fn a(self) -> f64;
    /// The second lane.
    fn b(self) -> f64;
}

/// The lanes and functions one build of the model computes with.
pub trait Numerics {
    /// The two-lane type of the wheel and position arithmetic.
    type Pair: Lanes;
    /// `e^x`.
    fn exp(x: f64) -> f64;
    /// `(sin x, cos x)`.
    fn sin_cos(x: f64) -> (f64, f64);
}

/// Plain pairs and `libm`: identical on every target.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Portable;

impl Numerics for Portable {
    type Pair = ScalarPair;

    #[inline(always)]
    fn exp(x: f64) -> f64 {
        libm::exp(x)
    }

    #[inline(always)]
    fn sin_cos(x: f64) -> (f64, f64) {
        libm::sincos(x)
    }
}

/// Two `f64`s, lane by lane.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ScalarPair([f64; 2]);

impl Lanes for ScalarPair {
    #[inline(always)]
    fn new(a: f64, b: f64) -> Self {
        ScalarPair([a, b])
    }
    #[inline(always)]
    fn splat(v: f64) -> Self {
        ScalarPair([v, v])
    }
    #[inline(always)]
    fn a(self) -> f64 {
        self.0[0]
    }
    #[inline(always)]
    fn b(self) -> f64 {
        self.0[1]
    }
}

impl Add for ScalarPair {
    type Output = ScalarPair;
    #[inline(always)]
    fn add(self, o: ScalarPair) -> ScalarPair {
        ScalarPair([self.0[0] + o.0[0], self.0[1] + o.0[1]])
    }
}

impl Sub for ScalarPair {
    type Output = ScalarPair;
    #[inline(always)]
    fn sub(self, o: ScalarPair) -> ScalarPair {
        ScalarPair([self.0[0] - o.0[0], self.0[1] - o.0[1]])
    }
}

impl Mul for ScalarPair {
    type Output = ScalarPair;
    #[inline(always)]
    fn mul(self, o: ScalarPair) -> ScalarPair {
        ScalarPair([self.0[0] * o.0[0], self.0[1] * o.0[1]])
    }
}

impl Div for ScalarPair {
    type Output = ScalarPair;
    #[inline(always)]
    fn div(self, o: ScalarPair) -> ScalarPair {
        ScalarPair([self.0[0] / o.0[0], self.0[1] / o.0[1]])
    }
}

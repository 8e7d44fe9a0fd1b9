//! Odometry: pose from wheel tick totals (paper eq. 1–4), in exact integer arithmetic.
//!
//! Frame: the pose is given in the odometry frame set by the last reset (start pose at the
//! origin heading +x unless another pose is given), y to the left, heading CCW positive.
//!
//! Numerics (the budget: ≤ 0.1 mm from an `f64` exact-arc reference after 1 km at 1 kHz):
//! - **Heading** is computed from the `i64` tick totals, never accumulated:
//!   `θ = θ₀ + g_R·(N_R − N_R0) − g_L·(N_L − N_L0)` with `g = Δd_wheel / (2π b)` in turns × 2^64
//!   per tick, in wrapping `u64` arithmetic ([`Angle`]). Drift-free; the constant's rounding
//!   (≤ 2^-65 turn per tick) gives 1e-11 rad after 4·10^8 ticks (1 km).
//! - **Wheel travel** per tick is a Q48 metre constant (rounding ≤ 2^-49 m, 1.5e-9 relative for
//!   the reference robot's 2.36 µm per tick); a period's travel `k_R ΔN_R + k_L ΔN_L` is exact in
//!   `i128`.
//! - **Position** accumulates in `i64` Q40 metres ([`I24F40`], resolution 9.1e-13 m, range
//!   ±8,388 km). Every increment is rounded to nearest, so 3.6·10^6 steps (1 km at 0.3 m/s)
//!   add at most 3.3 µm.
//! - **Trigonometry** is the table + Taylor [`Angle::sin_cos_q30`] (error < 1.5e-9).
//!
//! Integration per period, `Δd = (Δd_R + Δd_L)/2`, `Δθ = (Δd_R − Δd_L)/b`:
//! - [`Integration::Midpoint`]: `x += Δd cos(θ + Δθ/2)` — the paper's eq. (1);
//! - [`Integration::ExactArc`]: the same times `sinc(Δθ/2) ≈ 1 − Δθ²/24`, exact for a
//!   constant-curvature period (the neglected `Δθ⁴/1920` is < 1e-14 at 0.01 rad per period).

use fixed::types::I24F40;

use crate::kinematics::angle::Angle;
use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::{Geometry, GeometryError};
use crate::kinematics::reference::PoseF64;

/// 2^-40: one step of a Q40 position, metres (exact in `f64` and `f32`).
const Q40_STEP_M: f64 = 1.0 / (1u64 << 40) as f64;

/// A Q40 position in metres: exactly `q.to_num::<f64>()` (an `i64` to `f64` cast rounds to the
/// nearest, ties to even, as `fixed` does, and the scaling by 2^-40 is exact), without `fixed`'s
/// generic conversion (about 150 B of flash for each target type).
pub fn metres(q: I24F40) -> f64 {
    q.to_bits() as f64 * Q40_STEP_M
}

/// [`metres`] as an `f32`: exactly `q.to_num::<f32>()`, for the same reasons.
pub fn metres_f32(q: I24F40) -> f32 {
    q.to_bits() as f32 * Q40_STEP_M as f32
}

/// Integration rule for one control period.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Integration {
    /// Midpoint heading (paper eq. 1).
    Midpoint,
    /// Exact circular arc per period.
    #[default]
    ExactArc,
}

/// A pose in the odometry's native fixed-point form.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct Pose {
    /// x, metres (Q40).
    pub x: I24F40,
    /// y, metres (Q40).
    pub y: I24F40,
    /// Heading (binary angle).
    pub heading: Angle,
}

impl Pose {
    /// Conversion to `f64` metres and radians (heading in `[-π, π)`).
    pub fn to_f64(&self) -> PoseF64 {
        PoseF64::new(metres(self.x), metres(self.y), self.heading.to_radians())
    }

    /// The fixed-point pose nearest to `p` (position saturates at ±8,388 km).
    pub fn from_f64(p: &PoseF64) -> Pose {
        Pose {
            x: I24F40::saturating_from_num(p.x_m),
            y: I24F40::saturating_from_num(p.y_m),
            heading: Angle::from_radians(p.theta_rad),
        }
    }
}

/// Evolving odometry state (owned by the control task).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OdometryState {
    /// Tick totals at the last reset.
    origin: WheelTicks,
    /// Heading at the last reset.
    origin_heading: Angle,
    /// Tick totals at the last update.
    last: WheelTicks,
    /// Current pose.
    pose: Pose,
}

impl OdometryState {
    /// The current pose.
    pub fn pose(&self) -> Pose {
        self.pose
    }

    /// Tick totals at the last update.
    pub fn last_ticks(&self) -> WheelTicks {
        self.last
    }
}

/// Odometry configuration: fixed-point constants derived from a validated [`Geometry`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Odometry {
    /// Right wheel travel per tick, Q48 metres.
    right_q48: i64,
    /// Left wheel travel per tick, Q48 metres.
    left_q48: i64,
    /// Heading change per right tick, turns × 2^64.
    turn_right_q64: u64,
    /// Heading change per left tick, turns × 2^64.
    turn_left_q64: u64,
    integration: Integration,
}

/// `v · 2^shift` rounded, for positive `v` that fits (construction time only).
fn to_fixed(v: f64, shift: i32) -> u64 {
    libm::round(libm::ldexp(v, shift)) as u64
}

impl Odometry {
    /// Builds the runtime constants for `geometry`.
    ///
    /// # Errors
    /// The geometry's [`GeometryError`] when it is not valid.
    pub fn new(geometry: &Geometry, integration: Integration) -> Result<Self, GeometryError> {
        geometry.validate()?;
        let kr = geometry.meters_per_tick_right();
        let kl = geometry.meters_per_tick_left();
        let turn = 1.0 / (2.0 * core::f64::consts::PI * geometry.wheelbase_m);
        Ok(Odometry {
            right_q48: to_fixed(kr, 48) as i64,
            left_q48: to_fixed(kl, 48) as i64,
            turn_right_q64: to_fixed(kr * turn, 64),
            turn_left_q64: to_fixed(kl * turn, 64),
            integration,
        })
    }

    /// The integration rule.
    pub fn integration(&self) -> Integration {
        self.integration
    }

    /// Starts a new odometry frame: the robot is at `pose` when the totals are `totals`.
    pub fn reset(&self, state: &mut OdometryState, totals: WheelTicks, pose: Pose) {
        *state = OdometryState {
            origin: totals,
            origin_heading: pose.heading,
            last: totals,
            pose,
        };
    }

    /// Heading for tick totals in the frame of `state`.
    #[inline]
    fn heading(&self, state: &OdometryState, totals: WheelTicks) -> Angle {
        let n = totals - state.origin;
        let turns = self
            .turn_right_q64
            .wrapping_mul(n.right as u64)
            .wrapping_sub(self.turn_left_q64.wrapping_mul(n.left as u64));
        Angle(state.origin_heading.0.wrapping_add(turns))
    }

    /// Advances the pose to the new tick totals (one control period) and returns it.
    #[inline]
    pub fn update(&self, state: &mut OdometryState, totals: WheelTicks) -> Pose {
        let d = totals - state.last;
        let heading = self.heading(state, totals);
        let dtheta = heading.delta(state.pose.heading);
        let mid = state.pose.heading.add_q64(dtheta >> 1);
        // 2Δd in Q48 metres, exact.
        let mut travel = i128::from(self.right_q48) * i128::from(d.right)
            + i128::from(self.left_q48) * i128::from(d.left);
        if self.integration == Integration::ExactArc {
            // sinc(Δθ/2) ≈ 1 − Δθ²/24, Q32.
            let dt = Angle::small_q64_to_rad_q32(dtheta);
            // |Δθ| ≤ 0.0123 rad (the clamp), so Δθ² in Q32 is < 2^20: dividing it as a u32
            // gives the same bits as an i64 division but compiles to a multiply instead of a
            // 64-bit division call (about 100 instructions on the Cortex-M4).
            let dt2 = ((dt * dt) >> 32) as u32;
            let factor = (1i64 << 32) - i64::from(dt2 / 24);
            travel = (travel * i128::from(factor)) >> 32;
        }
        let (sin, cos) = mid.sin_cos_q30();
        // travel (Q48, = 2Δd) × cos (Q30) → Q78 of 2Δd → Q40 of Δd: shift by 30 + 48 + 1 − 40.
        const SHIFT: u32 = 39;
        const HALF: i128 = 1 << (SHIFT - 1);
        let dx = ((travel * i128::from(cos) + HALF) >> SHIFT) as i64;
        let dy = ((travel * i128::from(sin) + HALF) >> SHIFT) as i64;
        // The new pose is built in registers and stored once (returning `state.pose` re-read
        // just-written halves as one wide load, which stalls store forwarding on the host).
        let pose = Pose {
            x: I24F40::from_bits(state.pose.x.to_bits().wrapping_add(dx)),
            y: I24F40::from_bits(state.pose.y.to_bits().wrapping_add(dy)),
            heading,
        };
        state.pose = pose;
        state.last = totals;
        pose
    }
}

#[cfg(test)]
mod tests {
    use core::f64::consts::PI;

    use super::*;
    use crate::kinematics::reference::ArcModel;

    /// `metres` and `metres_f32` are `fixed`'s conversions bit for bit: at the ends of the
    /// range, at ties and beyond 2^53 (where both round) and over random bits (xorshift64).
    #[test]
    fn metres_are_fixeds_conversions() {
        let mut bits = std::vec![
            0,
            1,
            -1,
            i64::MAX,
            i64::MIN,
            (1 << 53) + 1,
            (1 << 53) + 3,
            (1 << 24) + 1,
            -(1 << 60) - 1,
        ];
        let mut x = 0x9E37_79B9_7F4A_7C15_u64;
        for shift in 0..64 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            bits.push((x >> shift) as i64);
            bits.push(-((x >> shift) as i64));
        }
        for b in bits {
            let q = I24F40::from_bits(b);
            assert_eq!(metres(q).to_bits(), q.to_num::<f64>().to_bits(), "{b}");
            assert_eq!(metres_f32(q).to_bits(), q.to_num::<f32>().to_bits(), "{b}");
        }
    }

    fn setup(g: &Geometry) -> (Odometry, OdometryState) {
        let odo = Odometry::new(g, Integration::ExactArc).unwrap();
        let mut st = OdometryState::default();
        odo.reset(&mut st, WheelTicks::default(), Pose::default());
        (odo, st)
    }

    /// Drives `per_step` ticks per period for `steps` periods.
    fn drive(odo: &Odometry, st: &mut OdometryState, per_step: WheelTicks, steps: i64) -> PoseF64 {
        let start = st.last_ticks();
        for i in 1..=steps {
            odo.update(
                st,
                WheelTicks::new(
                    start.right + per_step.right * i,
                    start.left + per_step.left * i,
                ),
            );
        }
        st.pose().to_f64()
    }

    #[test]
    fn straight_line() {
        let g = Geometry::PAPER_NOMINAL;
        let (odo, mut st) = setup(&g);
        // 1 m: 200,000 / (π 0.15) ticks; 424 ticks per ms ≈ 0.3 m/s.
        let p = drive(&odo, &mut st, WheelTicks::new(424, 424), 1000);
        let expected = 424_000.0 * g.meters_per_tick_right();
        assert!((p.x_m - expected).abs() < 1e-9, "{p:?}");
        assert!(p.y_m.abs() < 1e-12 && p.theta_rad.abs() < 1e-15);
    }

    #[test]
    fn in_place_turn() {
        let g = Geometry::PAPER_NOMINAL;
        let (odo, mut st) = setup(&g);
        // Quarter turn: each wheel travels π b / 4.
        let ticks = (PI * g.wheelbase_m / 4.0 / g.meters_per_tick_right()).round() as i64;
        let p = drive(
            &odo,
            &mut st,
            WheelTicks::new(ticks / 1000, -(ticks / 1000)),
            1000,
        );
        let expected =
            2.0 * (ticks / 1000 * 1000) as f64 * g.meters_per_tick_right() / g.wheelbase_m;
        assert!((p.theta_rad - expected).abs() < 1e-12, "{p:?}");
        assert!(p.x_m.abs() < 1e-9 && p.y_m.abs() < 1e-9);
    }

    #[test]
    fn constant_arc_matches_closed_form() {
        let g = Geometry::PAPER_NOMINAL.with_factors(0.995, 1.01, 1.0);
        let (odo, mut st) = setup(&g);
        let per = WheelTicks::new(500, 350);
        let steps = 20_000;
        let p = drive(&odo, &mut st, per, steps);
        let kr = g.meters_per_tick_right();
        let kl = g.meters_per_tick_left();
        let theta = (kr * 500.0 - kl * 350.0) * steps as f64 / g.wheelbase_m;
        let r = 0.5 * (kr * 500.0 + kl * 350.0) * steps as f64 / theta;
        assert!((p.x_m - r * theta.sin()).abs() < 1e-7, "{p:?}");
        assert!((p.y_m - r * (1.0 - theta.cos())).abs() < 1e-7, "{p:?}");
        let wrapped = (theta + PI).rem_euclid(2.0 * PI) - PI;
        // 1.7e7 ticks × ≤ 2^-65 turn rounding of the per-tick constants ≤ 5.8e-12 rad.
        assert!(
            (p.theta_rad - wrapped).abs() < 6e-12,
            "{} vs {wrapped}",
            p.theta_rad
        );
    }

    #[test]
    fn reference_arc_model_agrees_on_a_single_step() {
        let g = Geometry::PAPER_NOMINAL;
        let (odo, mut st) = setup(&g);
        let knots = [WheelTicks::new(0, 0), WheelTicks::new(800, -300)];
        odo.update(&mut st, knots[1]);
        let r = ArcModel::from_geometry(&g).integrate(PoseF64::default(), &knots);
        assert!(st.pose().to_f64().distance_to(&r) < 1e-11);
    }

    #[test]
    fn sinc_correction_fits_u32_at_the_clamp() {
        // `update` divides Δθ² (Q32) as a u32; that equals the i64 division only while
        // Δθ² < 2^32. At the clamp |Δθ| = 2π/2^9 rad, Δθ² = 1.5e-4 rad² = 6.5e5 in Q32; the
        // bound 2^20 leaves a factor 1.6 of margin and fails if the clamp is ever widened 1.3×.
        for extreme in [i64::MAX, i64::MIN, 1 << 55, -(1 << 55)] {
            let dt = Angle::small_q64_to_rad_q32(extreme);
            let dt2 = (dt * dt) >> 32;
            assert!((0..1 << 20).contains(&dt2), "{extreme}: {dt2}");
        }
    }

    #[test]
    fn reset_starts_a_new_frame() {
        let g = Geometry::PAPER_NOMINAL;
        let (odo, mut st) = setup(&g);
        drive(&odo, &mut st, WheelTicks::new(100, 300), 100);
        let here = st.last_ticks();
        odo.reset(
            &mut st,
            here,
            Pose::from_f64(&PoseF64::new(1.0, 2.0, PI / 2.0)),
        );
        let p = drive(&odo, &mut st, WheelTicks::new(424, 424), 1000);
        assert!((p.x_m - 1.0).abs() < 1e-9);
        assert!((p.y_m - 2.0 - 424_000.0 * g.meters_per_tick_right()).abs() < 1e-9);
    }
}

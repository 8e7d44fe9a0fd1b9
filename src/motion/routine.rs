//! Test-path routines: the UMBmark square (CW/CCW), a straight line and a full circle, as a pure
//! state machine stepped once per control period.
//!
//! A path is a list of segments ([`crate::motion::path`]). Each segment is one
//! [`Trapezoid`] over its own parameter (metres along the path for legs and arcs, radians for
//! turns), mapped *linearly* to both wheels' tick references, so the wheels follow one profile:
//! on a leg they travel equal distances at every instant, on a turn equal and opposite ones.
//!
//! The tick targets of a segment ([`crate::motion::path::segment_ticks`]) are computed from the
//! geometry handed in when the run starts (the current calibrated `D_R`, `D_L`, `b`; the
//! controller changes it only while idle); references are cumulative ticks since the run start
//! and continue
//! from the previous segment's *target*, so tracking errors do not add up along the path. A segment ends when its profile is over and
//! both wheels have stayed within `settle_tolerance_ticks` of the target for `settle_periods`
//! periods (or `settle_timeout_periods` have passed since the profile ended): the robot stops at
//! every corner, as UMBmark expects.
//!
//! The routine records the run's *knots* (see [`crate::motion::run`]): the measured cumulative ticks at
//! the start, at every segment end and at evenly spaced points of the profile inside each segment
//! (`(MAX_KNOTS − 1) / segments` knots per segment: 24 for a square, 199 for a line or circle).
//!
//! Signs: positive ticks roll forward; CCW turns drive the right wheel forward.
//!
//! Numerics: every segment is planned in `f64` when the run starts ([`Routine::new`]: profile,
//! whole-tick targets, the period at which the profile ends). The control period then uses only
//! integers and `f32` (the Cortex-M4F's FPU is single precision): the time since the segment
//! start is an integer count of periods, turned into seconds by one division; the reference is
//! `f32` ticks *relative to the segment start* (within about 8·2⁻²⁴ of the segment's length in
//! ticks: ≤ 0.5 tick on a 2 m leg of 849k ticks, the encoder itself resolves 1 tick); segment
//! starts, targets and knots stay integer ticks, so no rounding carries from one segment into
//! the next and the reference ends every segment exactly on its integer target.

use heapless::Vec;

use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::motion::path::{
    PathError, SegmentKind, segment, segment_count, segment_scales, segment_ticks, validate_path,
};
use crate::motion::profile::{MotionLimits, Trapezoid};
use crate::motion::run::{Direction, MAX_KNOTS, MAX_RUNS, PathKind};
use crate::motion::speed::WheelReference;
use crate::util::num::fmin;

/// Settling rules of the routine, in control periods and ticks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct SettleConfig {
    /// Largest |target − measured| per wheel at which a segment counts as reached, ticks.
    pub tolerance_ticks: u32,
    /// Consecutive periods within tolerance needed to end a segment.
    pub periods: u32,
    /// Periods after the profile's end after which the segment ends anyway.
    pub timeout_periods: u32,
}

/// A segment as planned when the run starts: profile plus its linear map to wheel ticks.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Plan {
    kind: SegmentKind,
    profile: Trapezoid,
    /// Ticks per profile unit, right and left (signed; scaled so the end is a whole tick).
    scale: (f32, f32),
    /// Reference ticks of the whole segment (end − start), right and left.
    travel: (i64, i64),
    /// The first period (counted from 0 at the segment start) whose instant `k / rate` is at or
    /// past the profile's end.
    profile_periods: u32,
}

/// A segment being driven.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Active {
    /// Cumulative reference ticks at the segment start.
    start: WheelTicks,
    /// Periods since the segment start.
    periods: u32,
    /// Periods the wheels have been within tolerance after the profile ended.
    settled: u32,
    /// Next interior knot to record (1-based).
    next_knot: usize,
    /// Reference position of the previous step, ticks since the segment start.
    prev_ref: (f32, f32),
}

/// What the routine asks of the wheels for the next period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoutineStep {
    /// Right wheel reference.
    pub right: WheelReference,
    /// Left wheel reference.
    pub left: WheelReference,
    /// Index of the segment being driven.
    pub segment: usize,
    /// The segment being driven.
    pub kind: SegmentKind,
    /// Reference minus measured ticks, right and left, at the instant of the measurement.
    pub error: (f32, f32),
    /// The path is complete: the knots are final, the motors should stop.
    pub finished: bool,
}

/// Number of distinct segments a path can have: the segments of every path repeat with period
/// 2 (a square alternates legs and turns, a line and a circle are one segment), so
/// `segment(path, i) == segment(path, i % PLANS)`.
const PLANS: usize = 2;

/// The routine state machine for one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Routine {
    path: PathKind,
    rate_hz: f32,
    settle: SettleConfig,
    index: usize,
    /// The plan of segment `i` is `plans[i % PLANS]`.
    plans: [Plan; PLANS],
    active: Active,
    knots: Vec<WheelTicks, MAX_KNOTS>,
    finished: bool,
}

/// `d` ticks as `f32`. Differences of tick totals within a run fit an `i32` (±2.1e9 ticks are
/// ±5 km of the paper's robot); the `i32` conversion is one FPU instruction where an `i64` one
/// is a library call.
#[inline]
pub(crate) fn ticks_f32(d: i64) -> f32 {
    match i32::try_from(d) {
        Ok(v) => v as f32,
        Err(_) if d < 0 => i32::MIN as f32,
        Err(_) => i32::MAX as f32,
    }
}

/// Speed and acceleration limits of a segment's own parameter.
fn segment_limits(kind: &SegmentKind, g: &Geometry, l: &MotionLimits) -> (f64, f64) {
    let v = f64::from(l.max_speed_mps);
    let a = f64::from(l.max_accel_mps2);
    let w = f64::from(l.max_turn_rate_radps);
    let aw = f64::from(l.max_turn_accel_radps2);
    let half_b = 0.5 * g.wheelbase_m;
    match *kind {
        SegmentKind::Straight { .. } => (v, a),
        // Wheel speed is ω·b/2.
        SegmentKind::Turn { .. } => (fmin(w, v / half_b), fmin(aw, a / half_b)),
        SegmentKind::Arc { radius_m, .. } => {
            // The outer wheel is the faster one: v·(1 + b/2r).
            let outer = 1.0 + half_b / radius_m;
            (
                fmin(v / outer, w * radius_m),
                fmin(a / outer, aw * radius_m),
            )
        }
    }
}

impl Plan {
    /// Plans `kind` for `g` and `l` at `rate_hz` (config time, `f64`).
    fn new(kind: SegmentKind, g: &Geometry, l: &MotionLimits, rate_hz: f64) -> Plan {
        let (distance, _, _) = segment_scales(&kind, g);
        let (v, a) = segment_limits(&kind, g, l);
        let profile = Trapezoid::new(distance, v, a);
        let end = segment_ticks(&kind, g);
        let scale = if distance > 0.0 {
            (
                (end.right as f64 / distance) as f32,
                (end.left as f64 / distance) as f32,
            )
        } else {
            (0.0, 0.0)
        };
        Plan {
            kind,
            profile,
            scale,
            travel: (end.right, end.left),
            // Saturating: a profile longer than u32::MAX periods is not a valid path.
            profile_periods: libm::ceil(profile.duration() * rate_hz) as u32,
        }
    }
}

impl Active {
    fn new(start: WheelTicks) -> Active {
        Active {
            start,
            periods: 0,
            settled: 0,
            next_knot: 1,
            prev_ref: (0.0, 0.0),
        }
    }
}

impl Routine {
    /// Starts a run of `path` at control rate `rate_hz`; the first segment's targets come from
    /// `geometry` and `limits` (both already validated by the caller).
    ///
    /// # Errors
    /// [`PathError`] when the path's size is implausible.
    pub fn new(
        path: PathKind,
        geometry: &Geometry,
        limits: &MotionLimits,
        rate_hz: u32,
        settle: SettleConfig,
    ) -> Result<Routine, PathError> {
        validate_path(&path)?;
        let mut knots = Vec::new();
        // Cannot fail: the capacity is positive.
        let _ = knots.push(WheelTicks::default());
        let rate = rate_hz.max(1);
        let plan = |i| Plan::new(segment(&path, i), geometry, limits, f64::from(rate));
        let plans = [plan(0), plan(1)];
        Ok(Routine {
            path,
            rate_hz: rate as f32,
            settle,
            index: 0,
            active: Active::new(WheelTicks::default()),
            plans,
            knots,
            finished: false,
        })
    }

    /// The path being driven.
    pub fn path(&self) -> &PathKind {
        &self.path
    }

    /// The knots recorded so far (cumulative measured ticks since the run start).
    pub fn knots(&self) -> &[WheelTicks] {
        &self.knots
    }

    /// Index of the segment being driven.
    pub fn segment_index(&self) -> usize {
        self.index
    }

    /// The recorded knots, consuming the routine.
    pub fn into_knots(self) -> Vec<WheelTicks, MAX_KNOTS> {
        self.knots
    }

    /// Whether the path is complete.
    pub fn is_finished(&self) -> bool {
        self.finished
    }

    /// One control period. `measured` is the cumulative measured ticks since the run start.
    pub fn step(&mut self, measured: WheelTicks) -> RoutineStep {
        if self.finished {
            let end = self.segment_end();
            return self.hold((
                ticks_f32(end.right - measured.right),
                ticks_f32(end.left - measured.left),
            ));
        }
        let plan = &self.plans[self.index % PLANS];
        let a = &mut self.active;
        // `k` counts the periods since the segment start: its instant is that of the
        // measurement; the period that starts now is driven with the feed-forward of its
        // midpoint. An integer count, so the time never accumulates rounding (below 2²⁴
        // periods, 28 min at 10 kHz, `k` is exact in `f32`; above, the time's relative error
        // stays 2⁻²⁴).
        a.periods = a.periods.saturating_add(1);
        let k = a.periods - 1;
        let done = k >= plan.profile_periods;
        let t = k as f32;
        let s = plan.profile.sample(t / self.rate_hz);
        let ff = plan.profile.sample((t + 0.5) / self.rate_hz);
        // Reference and error relative to the segment start; once the profile is over the
        // reference is the integer target itself.
        let end = WheelTicks::new(
            a.start.right.wrapping_add(plan.travel.0),
            a.start.left.wrapping_add(plan.travel.1),
        );
        let (pos_r, pos_l, error) = if done {
            (
                ticks_f32(plan.travel.0),
                ticks_f32(plan.travel.1),
                (
                    ticks_f32(end.right - measured.right),
                    ticks_f32(end.left - measured.left),
                ),
            )
        } else {
            let (pr, pl) = (plan.scale.0 * s.position, plan.scale.1 * s.position);
            (
                pr,
                pl,
                (
                    pr - ticks_f32(measured.right - a.start.right),
                    pl - ticks_f32(measured.left - a.start.left),
                ),
            )
        };
        let right = WheelReference {
            delta_ticks: pos_r - a.prev_ref.0,
            velocity_tps: plan.scale.0 * ff.velocity,
            accel_tps2: plan.scale.0 * ff.accel,
        };
        let left = WheelReference {
            delta_ticks: pos_l - a.prev_ref.1,
            velocity_tps: plan.scale.1 * ff.velocity,
            accel_tps2: plan.scale.1 * ff.accel,
        };
        a.prev_ref = (pos_r, pos_l);

        // Interior knots at evenly spaced fractions of the profile's distance.
        let per = (MAX_KNOTS - 1) / segment_count(&self.path);
        if a.next_knot < per
            && s.position * per as f32 >= plan.profile.distance() * a.next_knot as f32
        {
            let _ = self.knots.push(measured);
            a.next_knot += 1;
        }

        let step = RoutineStep {
            right,
            left,
            segment: self.index,
            kind: plan.kind,
            error,
            finished: false,
        };
        if !done {
            return step;
        }
        let tol = u64::from(self.settle.tolerance_ticks);
        let in_tol = (end.right - measured.right).unsigned_abs() <= tol
            && (end.left - measured.left).unsigned_abs() <= tol;
        a.settled = if in_tol { a.settled + 1 } else { 0 };
        let timed_out = k
            >= plan
                .profile_periods
                .saturating_add(self.settle.timeout_periods);
        if a.settled < self.settle.periods && !timed_out {
            return step;
        }
        if a.settled < self.settle.periods {
            warn!("segment {} ended by the settle timeout", self.index);
        }
        // Segment boundary knot (fill any interior knots not reached, e.g. an empty profile).
        while a.next_knot < per {
            let _ = self.knots.push(measured);
            a.next_knot += 1;
        }
        let _ = self.knots.push(measured);
        if self.index + 1 >= segment_count(&self.path) {
            self.finished = true;
            return RoutineStep {
                finished: true,
                ..step
            };
        }
        self.index += 1;
        self.active = Active::new(end);
        step
    }

    /// Cumulative reference ticks at the end of the segment being driven (its target).
    fn segment_end(&self) -> WheelTicks {
        let (start, travel) = (self.active.start, self.plans[self.index % PLANS].travel);
        // Tick totals since the run start stay far from i64's range (2.1e13 km of the paper's
        // robot): a plain wrapping add.
        WheelTicks::new(
            start.right.wrapping_add(travel.0),
            start.left.wrapping_add(travel.1),
        )
    }

    /// The reference once the path is complete: hold the last target.
    fn hold(&self, error: (f32, f32)) -> RoutineStep {
        RoutineStep {
            right: WheelReference::default(),
            left: WheelReference::default(),
            segment: self.index,
            kind: self.plans[self.index % PLANS].kind,
            error,
            finished: true,
        }
    }
}

/// The planned sequence of button-started runs: squares of one side, alternating CW and CCW.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct RunPlan {
    /// Side length, metres.
    pub side_m: f64,
    /// Direction of the next run.
    pub next: Direction,
}

impl RunPlan {
    /// The square sides `set square_side` accepts and a stored record may hold, metres.
    pub const SIDE_RANGE_M: (f64, f64) = (0.1, 10.0);
    /// The runs per direction `set runs_per_direction` accepts and a stored record may hold:
    /// both directions' runs fit the run store ([`MAX_RUNS`]).
    pub const RUNS_PER_DIRECTION_RANGE: (u8, u8) = (1, (MAX_RUNS / 2) as u8);

    /// A plan starting with `first`.
    pub const fn new(side_m: f64, first: Direction) -> Self {
        RunPlan {
            side_m,
            next: first,
        }
    }

    /// The path the next run should drive.
    pub fn next_path(&self) -> PathKind {
        PathKind::Square {
            direction: self.next,
            side_m: self.side_m,
        }
    }

    /// Call after the next run was started: the following one goes the other way.
    pub fn advance(&mut self) {
        self.next = self.next.opposite();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    use crate::kinematics::reference::ArcModel;
    use crate::kinematics::reference::PoseF64;

    const SETTLE: SettleConfig = SettleConfig {
        tolerance_ticks: 2,
        periods: 5,
        timeout_periods: 2000,
    };

    /// Drives the routine with perfect wheels: measured = the reference, rounded down.
    fn ideal_run(path: PathKind, g: &Geometry) -> (Routine, usize, f64) {
        let limits = MotionLimits::DEFAULT;
        let mut r = Routine::new(path, g, &limits, 1000, SETTLE).unwrap();
        let mut pos = (0.0f64, 0.0f64);
        let mut steps = 0;
        let mut worst_sync = 0.0f64;
        let mut seg_start = (0usize, pos);
        loop {
            let meas = WheelTicks::new(pos.0.floor() as i64, pos.1.floor() as i64);
            let s = r.step(meas);
            if s.finished {
                break;
            }
            if s.segment != seg_start.0 {
                seg_start = (s.segment, pos);
            }
            pos.0 += f64::from(s.right.delta_ticks);
            pos.1 += f64::from(s.left.delta_ticks);
            if let SegmentKind::Straight { .. } = s.kind {
                let (r0, l0) = seg_start.1;
                worst_sync = worst_sync.max(((pos.0 - r0) - (pos.1 - l0)).abs());
            }
            steps += 1;
            assert!(steps < 10_000_000);
        }
        (r, steps, worst_sync)
    }

    #[test]
    fn square_targets_close_the_square() {
        let g = Geometry::PAPER_NOMINAL;
        for direction in [Direction::Cw, Direction::Ccw] {
            let path = PathKind::Square {
                direction,
                side_m: 2.0,
            };
            let (r, _, sync) = ideal_run(path, &g);
            // The references of both wheels are identical on a leg with equal wheels; only the
            // f32 increments differ in rounding (≪ 1 tick).
            assert!(sync < 0.01, "sync {sync}");
            let knots = r.knots();
            assert_eq!(knots.len(), 1 + 8 * ((MAX_KNOTS - 1) / 8));
            let end = ArcModel::from_geometry(&g).integrate(PoseF64::default(), knots);
            // Whole-tick rounding of each target: ≤ 0.5 tick (1.2 µm) per wheel per segment,
            // i.e. ≤ 3e-6 rad per turn, × 2 m lever arm ≈ 6 µm per corner; 50 µm allows all.
            assert!(end.x_m.abs() < 5e-5 && end.y_m.abs() < 5e-5, "{end:?}");
            let turned = end.theta_rad - direction.turn_sign() * 2.0 * PI;
            assert!(turned.abs() < 2e-5, "{end:?}");
            // Every knot is non-decreasing in distance along legs and the first is zero.
            assert_eq!(knots[0], WheelTicks::default());
        }
    }

    #[test]
    fn segments_repeat_with_the_plans_period() {
        for path in [
            PathKind::Square {
                direction: Direction::Cw,
                side_m: 1.0,
            },
            PathKind::Square {
                direction: Direction::Ccw,
                side_m: 3.0,
            },
            PathKind::Line { length_m: 2.0 },
            PathKind::Circle {
                direction: Direction::Ccw,
                radius_m: 1.5,
            },
        ] {
            for i in 0..segment_count(&path) {
                assert_eq!(segment(&path, i), segment(&path, i % PLANS), "{path:?} {i}");
            }
        }
    }

    #[test]
    fn turn_direction_follows_the_path() {
        let g = Geometry::PAPER_NOMINAL;
        let limits = MotionLimits::DEFAULT;
        let path = PathKind::Square {
            direction: Direction::Cw,
            side_m: 1.0,
        };
        let r = Routine::new(path, &g, &limits, 1000, SETTLE).unwrap();
        let (dr, dl) = r.plans[1].travel;
        // CW: right wheel backwards, left forwards, equal magnitude (π b / 4 ≈ 0.302 m).
        assert!(dr < 0 && dl > 0 && dr == -dl, "{dr} {dl}");
        let expected = (0.25 * PI * g.wheelbase_m / g.meters_per_tick_right()).round() as i64;
        assert_eq!(dl, expected);
    }

    #[test]
    fn calibrated_geometry_gives_unequal_ticks_equal_travel() {
        let g = Geometry::PAPER_NOMINAL.with_factors(0.995, 1.01, 1.0);
        let path = PathKind::Line { length_m: 1.0 };
        let (r, _, _) = ideal_run(path, &g);
        let last = *r.knots().last().unwrap();
        let travel_r = last.right as f64 * g.meters_per_tick_right();
        let travel_l = last.left as f64 * g.meters_per_tick_left();
        // One tick of rounding plus one of flooring: 2 × 2.4 µm.
        assert!((travel_r - 1.0).abs() < 5e-6 && (travel_l - 1.0).abs() < 5e-6);
        assert_eq!(r.knots().len(), MAX_KNOTS);
    }

    #[test]
    fn circle_returns_to_start() {
        let g = Geometry::PAPER_NOMINAL;
        for direction in [Direction::Cw, Direction::Ccw] {
            let path = PathKind::Circle {
                direction,
                radius_m: 1.0,
            };
            let (r, steps, _) = ideal_run(path, &g);
            let end = ArcModel::from_geometry(&g).integrate(PoseF64::default(), r.knots());
            assert!(end.distance_to(&PoseF64::default()) < 2e-5, "{end:?}");
            let turned = end.theta_rad * direction.turn_sign();
            assert!((turned - 2.0 * PI).abs() < 1e-5, "{end:?}");
            // Outer wheel at ≤ 0.3 m/s: the centre moves at ≤ 0.3/(1 + b/2r) = 0.252 m/s.
            assert!(steps as f64 / 1000.0 > 2.0 * PI / 0.26, "{steps}");
        }
    }

    #[test]
    fn rejects_bad_sizes() {
        let g = Geometry::PAPER_NOMINAL;
        let l = MotionLimits::DEFAULT;
        for path in [
            PathKind::Line { length_m: f64::NAN },
            PathKind::Square {
                direction: Direction::Cw,
                side_m: 0.0,
            },
            PathKind::Circle {
                direction: Direction::Ccw,
                radius_m: 1e3,
            },
        ] {
            assert_eq!(
                Routine::new(path, &g, &l, 1000, SETTLE).err(),
                Some(PathError::Size)
            );
        }
    }

    #[test]
    fn plan_alternates() {
        let mut p = RunPlan::new(4.0, Direction::Cw);
        assert_eq!(
            p.next_path(),
            PathKind::Square {
                direction: Direction::Cw,
                side_m: 4.0
            }
        );
        p.advance();
        assert_eq!(p.next, Direction::Ccw);
        p.advance();
        assert_eq!(p.next, Direction::Cw);
    }
}
#[cfg(test)]
mod size_probe {
    use core::mem::size_of;

    /// The routine's state stays within the sizes it was trimmed to (the controller's bound is
    /// checked beside it, in [`crate::motion::controller`]) so that the firmware's static RAM
    /// stays within its 48 KiB budget (docs/performance.md, Firmware footprint, has the margin).
    /// The bounds are the host's sizes (64-bit `usize`; the board's are no larger): a type that
    /// grows fails here, and raising its bound is a change to check against the footprint.
    #[test]
    fn sizes() {
        let sizes = [
            ("Plan", size_of::<super::Plan>(), 72),
            ("Active", size_of::<super::Active>(), 40),
            ("Routine", size_of::<super::Routine>(), 1840),
            (
                "Trapezoid",
                size_of::<crate::motion::profile::Trapezoid>(),
                20,
            ),
            ("SegmentKind", size_of::<super::SegmentKind>(), 24),
            ("SpeedPi", size_of::<crate::motion::speed::SpeedPi>(), 52),
        ];
        for (name, size, max) in sizes {
            assert!(size <= max, "{name} is {size} B, above its {max} B");
        }
    }
}

//! The messages the bridge publishes for one `stream` line of the board, as a function of the
//! line, its arrival on the PC and what came before it: `odom`, the `odom → base_link`
//! transform and `joint_states`. Nothing here touches DDS; the run loop publishes what
//! [`Odometer::messages`] returns.
//!
//! - **Stamp**: the board's time of the pose mapped to the PC's clock ([`ClockMap`]: the board's
//!   time plus the offset the minimum delay so far sets), the same on the three messages; never
//!   the line's arrival time.
//! - **`odom`**: the line's pose; its twist is `v = (v_R + v_L) / 2` forward and
//!   `ω = (v_R − v_L) / b` about z (ROS: counter-clockwise positive, as the board's θ).
//! - **`joint_states`**: the left joint first, then the right one (their names in that order);
//!   a wheel's position is the sum of its mean speed times the line intervals divided by its
//!   radius (the line's speeds are means over the interval before it), its velocity the line's
//!   wheel speed divided by its radius.

use odocal::protocol::stream::StreamSample;

use super::clock::ClockMap;
use super::msgs::Covariance;
use super::msgs::builtin_interfaces::Time;
use super::msgs::geometry_msgs::{
    Point, Pose, PoseWithCovariance, Quaternion, Transform, TransformStamped, Twist,
    TwistWithCovariance, Vector3,
};
use super::msgs::nav_msgs::Odometry;
use super::msgs::sensor_msgs::JointState;
use super::msgs::std_msgs::Header;
use crate::covariance::PoseCovariance;

/// One parsed `stream t x y θ v_R v_L` line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamLine {
    pub t_s: f64,
    pub x_m: f64,
    pub y_m: f64,
    pub theta_rad: f64,
    pub v_right: f64,
    pub v_left: f64,
}

impl StreamLine {
    /// Reads a `stream …` line by the protocol's reader (`None` for anything else).
    pub fn parse(line: &str) -> Option<StreamLine> {
        let s = StreamSample::parse(line)?;
        Some(StreamLine {
            // Exact µs over 1e6: the nearest double to the seconds the line wrote.
            t_s: s.t_us as f64 / 1e6,
            x_m: s.x_m,
            y_m: s.y_m,
            theta_rad: s.theta_rad,
            v_right: s.v_right_mps,
            v_left: s.v_left_mps,
        })
    }
}

/// The frames and joints the messages name.
#[derive(Clone, Debug, PartialEq)]
pub struct Names {
    /// `Odometry.header.frame_id`, the transform's parent.
    pub odom_frame: String,
    /// `Odometry.child_frame_id`, the transform's child.
    pub base_frame: String,
    /// The left wheel's joint.
    pub left_joint: String,
    /// The right wheel's joint.
    pub right_joint: String,
}

/// The board's active geometry: what turns wheel speeds into joint rates and a turn rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wheels {
    /// Right wheel diameter, m.
    pub d_right: f64,
    /// Left wheel diameter, m.
    pub d_left: f64,
    /// Wheelbase, m.
    pub wheelbase: f64,
}

/// What one stream line publishes.
#[derive(Clone, Debug, PartialEq)]
pub struct Messages {
    /// The line as parsed.
    pub line: StreamLine,
    /// The stamp of all three messages, seconds on the PC's clock.
    pub stamp_s: f64,
    pub odom: Odometry,
    pub tf: TransformStamped,
    pub joints: JointState,
}

/// Turns the board's stream lines into messages (see the module's text).
#[derive(Debug)]
pub struct Odometer {
    names: Names,
    wheels: Wheels,
    clock: ClockMap,
    cov: PoseCovariance,
    twist_cov: Covariance,
    prev: Option<StreamLine>,
    /// Right and left wheel angles so far, rad.
    wheel_rad: (f64, f64),
    /// The pose the board's pose is composed onto (x, y, θ): where `odom` was when the board
    /// last reset (REP 105: `odom` stays continuous).
    carry: (f64, f64, f64),
    /// The last published pose in `odom` (x, y, θ).
    published: (f64, f64, f64),
}

impl Odometer {
    /// An odometer at its first line: joint positions 0, the pose covariance `cov` as it
    /// starts, the twist covariance `twist_cov` on every message.
    pub fn new(
        names: Names,
        wheels: Wheels,
        clock: ClockMap,
        cov: PoseCovariance,
        twist_cov: Covariance,
    ) -> Odometer {
        Odometer {
            names,
            wheels,
            clock,
            cov,
            twist_cov,
            prev: None,
            wheel_rad: (0.0, 0.0),
            carry: (0.0, 0.0, 0.0),
            published: (0.0, 0.0, 0.0),
        }
    }

    /// The board reset (its pose restarts at the origin): from the next line on, its pose is
    /// composed onto the last published one, which is returned (x, y, θ).
    pub fn board_reset(&mut self) -> (f64, f64, f64) {
        self.carry = self.published;
        self.prev = None;
        self.carry
    }

    /// The board's geometry changed (a calibration applied): joint rates and turn rates from
    /// the next line on use it; the pose goes on from where it is.
    pub fn set_wheels(&mut self, wheels: Wheels) {
        self.wheels = wheels;
    }

    /// The board's odometry was reset on purpose (`odom reset`): the published pose restarts at
    /// the origin with it, and its covariance with the pose.
    pub fn odom_reset(&mut self) {
        self.carry = (0.0, 0.0, 0.0);
        self.published = (0.0, 0.0, 0.0);
        self.prev = None;
        self.cov.restart();
    }

    /// The messages of `line` (without its line end), which arrived at `arrived_s` on the PC's
    /// clock; `None` when it is not a stream line.
    pub fn messages(&mut self, line: &str, arrived_s: f64) -> Option<Messages> {
        let board = StreamLine::parse(line)?;
        // A board time that went backwards is a reset the bridge did not see (its boot event
        // was sent while the port was away): the same as `board_reset`.
        if self.prev.is_some_and(|p| board.t_s < p.t_s) {
            self.carry = self.published;
        }
        // The board's pose after the pose carried over its resets.
        let (cx, cy, ct) = self.carry;
        let (sin, cos) = ct.sin_cos();
        let s = StreamLine {
            x_m: cx + cos * board.x_m - sin * board.y_m,
            y_m: cy + sin * board.x_m + cos * board.y_m,
            theta_rad: odocal::calibration::wrap_angle(ct + board.theta_rad),
            ..board
        };
        self.published = (s.x_m, s.y_m, s.theta_rad);
        // The line's bytes on the wire include its CR LF.
        let stamp_s = self.clock.map(s.t_s, arrived_s, line.len() + 2);
        let dt = self.prev.map_or(0.0, |p| (s.t_s - p.t_s).max(0.0));
        self.prev = Some(s);
        let w = &self.wheels;
        let (dr, dl) = (s.v_right * dt, s.v_left * dt);
        self.wheel_rad.0 += dr / (0.5 * w.d_right);
        self.wheel_rad.1 += dl / (0.5 * w.d_left);
        self.cov.step(dr, dl);
        let header = |frame: &str| Header {
            stamp: Time::from_secs(stamp_s),
            frame_id: frame.to_string(),
        };
        let q = Quaternion::from_yaw(s.theta_rad);
        let v = 0.5 * (s.v_right + s.v_left);
        let turn = (s.v_right - s.v_left) / w.wheelbase;
        let n = &self.names;
        let odom = Odometry {
            header: header(&n.odom_frame),
            child_frame_id: n.base_frame.clone(),
            pose: PoseWithCovariance {
                pose: Pose {
                    position: Point {
                        x: s.x_m,
                        y: s.y_m,
                        z: 0.0,
                    },
                    orientation: q,
                },
                covariance: Covariance(crate::covariance::pose_ros(&self.cov)),
            },
            twist: TwistWithCovariance {
                twist: Twist::planar(v, turn),
                covariance: self.twist_cov,
            },
        };
        let tf = TransformStamped {
            header: header(&n.odom_frame),
            child_frame_id: n.base_frame.clone(),
            transform: Transform {
                translation: Vector3 {
                    x: s.x_m,
                    y: s.y_m,
                    z: 0.0,
                },
                rotation: q,
            },
        };
        let joints = JointState {
            header: header(""),
            name: vec![n.left_joint.clone(), n.right_joint.clone()],
            position: vec![self.wheel_rad.1, self.wheel_rad.0],
            velocity: vec![s.v_left / (0.5 * w.d_left), s.v_right / (0.5 * w.d_right)],
            effort: Vec::new(),
        };
        Some(Messages {
            line: s,
            stamp_s,
            odom,
            tf,
            joints,
        })
    }

    /// The clock map (its statistics for the diagnostics).
    pub fn clock(&self) -> &ClockMap {
        &self.clock
    }

    /// The pose covariance model (the distance and rotation driven).
    pub fn covariance(&self) -> &PoseCovariance {
        &self.cov
    }

    /// The pose covariance's inputs from now on ([`PoseCovariance::set_uncertainty`]).
    pub fn set_uncertainty(&mut self, u: crate::covariance::Uncertainty) {
        self.cov.set_uncertainty(u);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::covariance::Uncertainty;

    /// Seconds between the board's clock and the PC's (the PC's realtime clock, epoch seconds).
    const OFFSET_S: f64 = 1_700_000_000.0;

    fn names() -> Names {
        Names {
            odom_frame: "odom".into(),
            base_frame: "base_link".into(),
            left_joint: "left_wheel_joint".into(),
            right_joint: "right_wheel_joint".into(),
        }
    }

    /// Unequal wheels (right 100 mm, left 200 mm) on a 0.4 m wheelbase, on a pseudo-terminal
    /// (no wire time): a right/left mix-up changes every joint value.
    fn odometer() -> Odometer {
        let u = Uncertainty {
            sd_d: 1e-3,
            sd_b: 1e-3,
            sd_s: 1e-3,
            slip_m2_per_m: 1e-6,
            scrub_m2_per_rad: 1e-6,
        };
        Odometer::new(
            names(),
            Wheels {
                d_right: 0.1,
                d_left: 0.2,
                wheelbase: 0.4,
            },
            ClockMap::new(None, 10.0),
            PoseCovariance::new(0.4, u),
            Covariance::default(),
        )
    }

    /// The board's `stream` line for board time `t_s`, pose (x, y, θ in degrees) and wheel speeds,
    /// by the protocol's own writer.
    fn line(t_s: f64, (x, y, deg): (f64, f64, f64), v_right: f64, v_left: f64) -> String {
        let mut s = String::new();
        odocal::protocol::stream::StreamSample {
            t_us: (t_s * 1e6).round() as u64,
            x_m: x,
            y_m: y,
            theta_rad: deg.to_radians(),
            v_right_mps: v_right,
            v_left_mps: v_left,
        }
        .write(&mut s)
        .unwrap();
        s.trim_end().to_string()
    }

    /// The messages of `text`, which arrived at `arrived_s` on the PC's clock.
    fn feed(o: &mut Odometer, text: &str, arrived_s: f64) -> Messages {
        o.messages(text, arrived_s)
            .unwrap_or_else(|| panic!("not a stream line: {text}"))
    }

    #[test]
    fn stream_lines_parse() {
        let s = StreamLine::parse("stream 0.005000 +0.500000 +0.250000 +5.7296 +0.2500 -0.1250")
            .unwrap();
        assert_eq!((s.t_s, s.x_m, s.y_m), (0.005, 0.5, 0.25));
        assert!((s.theta_rad - 0.1).abs() < 1e-5);
        assert_eq!((s.v_right, s.v_left), (0.25, -0.125));
        assert_eq!(StreamLine::parse("event run 1 finished"), None);
        assert_eq!(StreamLine::parse("stream 1 2 3"), None);
        assert_eq!(odometer().messages("ok x=0 y=0", 0.0), None);
    }

    #[test]
    fn joint_states_name_left_then_right_and_do_not_exchange_the_wheels() {
        // Right wheel 0.3 m/s on its 100 mm wheel, left 0.1 m/s on its 200 mm wheel, for two
        // 10 ms intervals: right 6 mm = 0.12 rad at 6 rad/s, left 2 mm = 0.02 rad at 1 rad/s.
        let mut o = odometer();
        let mut m = feed(
            &mut o,
            &line(5.00, (0.0, 0.0, 0.0), 0.3, 0.1),
            OFFSET_S + 5.0,
        );
        for t in [5.01, 5.02] {
            m = feed(&mut o, &line(t, (0.0, 0.0, 0.0), 0.3, 0.1), OFFSET_S + t);
        }
        let j = &m.joints;
        assert_eq!(j.name, ["left_wheel_joint", "right_wheel_joint"]);
        let (left, right) = (j.position[0], j.position[1]);
        // Float arithmetic on the printed speeds and times: 1e-12 rad.
        assert!(
            (left - 0.02).abs() < 1e-12,
            "left joint {left} rad, want 0.02"
        );
        assert!(
            (right - 0.12).abs() < 1e-12,
            "right joint {right} rad, want 0.12"
        );
        let (w_left, w_right) = (j.velocity[0], j.velocity[1]);
        assert!(
            (w_left - 1.0).abs() < 1e-12,
            "left joint {w_left} rad/s, want 1"
        );
        assert!(
            (w_right - 6.0).abs() < 1e-12,
            "right joint {w_right} rad/s, want 6"
        );
        assert!(j.effort.is_empty());
    }

    #[test]
    fn odom_turn_rate_is_positive_for_a_ccw_pivot_and_negative_for_a_cw_one() {
        // ω = (v_R − v_L) / b on the 0.4 m wheelbase; ROS's z is up, so CCW is positive.
        let cases = [
            // CCW pivot: right forward, left back: +0.5 rad/s, no forward speed.
            ("CCW pivot", 0.1, -0.1, 0.0, 0.5),
            // CW pivot: -0.5 rad/s.
            ("CW pivot", -0.1, 0.1, 0.0, -0.5),
            // CW arc: the left wheel faster: 0.2 m/s forward, -0.5 rad/s.
            ("CW arc", 0.1, 0.3, 0.2, -0.5),
            // CCW arc: 0.2 m/s, +0.5 rad/s.
            ("CCW arc", 0.3, 0.1, 0.2, 0.5),
        ];
        for (what, v_right, v_left, v, w) in cases {
            let mut o = odometer();
            let m = feed(
                &mut o,
                &line(1.0, (0.0, 0.0, 0.0), v_right, v_left),
                OFFSET_S + 1.0,
            );
            let t = m.odom.twist.twist;
            assert!(
                (t.angular.z - w).abs() < 1e-12,
                "{what}: angular.z {} want {w}",
                t.angular.z
            );
            assert!(
                (t.linear.x - v).abs() < 1e-12,
                "{what}: linear.x {} want {v}",
                t.linear.x
            );
            assert_eq!(
                (t.linear.y, t.linear.z, t.angular.x, t.angular.y),
                (0.0, 0.0, 0.0, 0.0)
            );
        }
    }

    #[test]
    fn odom_and_tf_carry_the_lines_pose_in_their_frames() {
        let mut o = odometer();
        let m = feed(
            &mut o,
            &line(2.0, (0.5, -0.25, 90.0), 0.0, 0.0),
            OFFSET_S + 2.0,
        );
        let p = m.odom.pose.pose;
        assert_eq!(
            (p.position.x, p.position.y, p.position.z),
            (0.5, -0.25, 0.0)
        );
        // 90° about z: (0, 0, sin 45°, cos 45°).
        let half = std::f64::consts::FRAC_1_SQRT_2;
        let q = p.orientation;
        assert!(
            q.x == 0.0 && q.y == 0.0 && (q.z - half).abs() < 1e-12 && (q.w - half).abs() < 1e-12
        );
        assert_eq!(m.tf.transform.rotation, q);
        assert_eq!(
            (m.tf.transform.translation.x, m.tf.transform.translation.y),
            (0.5, -0.25)
        );
        assert_eq!(
            (
                m.odom.header.frame_id.as_str(),
                m.odom.child_frame_id.as_str()
            ),
            ("odom", "base_link")
        );
        assert_eq!(
            (m.tf.header.frame_id.as_str(), m.tf.child_frame_id.as_str()),
            ("odom", "base_link")
        );
    }

    #[test]
    fn every_message_is_stamped_with_the_boards_time_on_the_pc_clock_not_its_arrival() {
        // The board's clock is OFFSET_S behind the PC's; the lines arrive late by 4, 1, 15, 5
        // and 20 ms (the third and fourth together, as a USB adapter's buffer hands them over).
        // The smallest delay so far sets the offset: the first line is stamped with its own
        // 4 ms, every later one with the 1 ms of the second: stamp = board time + OFFSET_S +
        // 1 ms, whatever the order and grouping of the arrivals.
        let arrivals = [
            (5.00, 5.004, 0.004),
            (5.01, 5.011, 0.001),
            (5.02, 5.035, 0.001),
            (5.03, 5.035, 0.001),
            (5.04, 5.060, 0.001),
        ];
        let mut o = odometer();
        for (t_board, t_arrival, offset_above) in arrivals {
            let arrived = OFFSET_S + t_arrival;
            let m = feed(&mut o, &line(t_board, (0.0, 0.0, 0.0), 0.0, 0.0), arrived);
            let want = OFFSET_S + t_board + offset_above;
            // Epoch seconds in an f64 hold 0.24 µs; the stamp's nanoseconds round once more.
            for (what, stamp) in [
                ("odom", m.odom.header.stamp),
                ("tf", m.tf.header.stamp),
                ("joint_states", m.joints.header.stamp),
            ] {
                assert!(
                    (stamp.secs() - want).abs() < 1e-6,
                    "board t={t_board}: {what} stamped {:.6}, want {want:.6} (arrived {arrived:.6})",
                    stamp.secs()
                );
            }
            assert!((m.stamp_s - want).abs() < 1e-6);
        }
    }

    /// After a board reset `odom` goes on from where it was: the board's new pose (from its
    /// origin) is composed onto the last published one, turned by its heading.
    #[test]
    fn odom_stays_continuous_across_a_board_reset() {
        let mut o = odometer();
        let at = |o: &mut Odometer, t: f64, pose: (f64, f64, f64)| {
            let m = o.messages(&line(t, pose, 0.0, 0.0), OFFSET_S + t).unwrap();
            (m.line.x_m, m.line.y_m, m.line.theta_rad)
        };
        let before = at(&mut o, 5.0, (1.0, 2.0, 90.0));
        assert_eq!(o.board_reset(), before);
        // The board restarts at its origin, then drives 0.5 m along its new x.
        let start = at(&mut o, 0.01, (0.0, 0.0, 0.0));
        let (x, y, th) = at(&mut o, 2.0, (0.5, 0.0, 10.0));
        assert!((start.0 - 1.0).abs() < 1e-12 && (start.1 - 2.0).abs() < 1e-12);
        assert!((x - 1.0).abs() < 1e-9, "{x}");
        assert!((y - 2.5).abs() < 1e-9, "{y}");
        assert!((th - 100f64.to_radians()).abs() < 1e-6, "{th}");
    }

    /// A reset whose boot event the bridge never saw (the port was away): the board's time
    /// going backwards carries the pose over as the boot event does.
    #[test]
    fn a_board_time_that_goes_backwards_carries_the_pose_over() {
        let mut o = odometer();
        let at = |o: &mut Odometer, t: f64, pose: (f64, f64, f64)| {
            let m = o.messages(&line(t, pose, 0.0, 0.0), OFFSET_S + t).unwrap();
            (m.line.x_m, m.line.y_m, m.line.theta_rad)
        };
        let before = at(&mut o, 7.0, (-0.5, 0.25, -45.0));
        let after = at(&mut o, 0.3, (0.0, 0.0, 0.0));
        assert_eq!(after, before);
        // And not again while the new board's time goes forward.
        let (x, _, _) = at(&mut o, 0.4, (0.1, 0.0, 0.0));
        assert!(
            (x - (-0.5 + 0.1 * (-45f64).to_radians().cos())).abs() < 1e-9,
            "{x}"
        );
    }

    /// `odom reset` on the board: the published pose restarts at the origin (not carried over as
    /// after a reset), and its covariance with it, from zero.
    #[test]
    fn odom_reset_restarts_the_pose_and_its_covariance() {
        let mut o = odometer();
        let at = |o: &mut Odometer, t: f64, pose: (f64, f64, f64), v: f64| {
            let m = o.messages(&line(t, pose, v, v), OFFSET_S + t).unwrap();
            (m.line.x_m, m.odom.pose.covariance.0[0])
        };
        at(&mut o, 1.0, (0.0, 0.0, 0.0), 0.5);
        let (_, grown) = at(&mut o, 3.0, (1.0, 0.0, 0.0), 0.5);
        assert!(grown > 0.0);
        o.odom_reset();
        let (x, var) = at(&mut o, 3.1, (0.0, 0.0, 0.0), 0.0);
        assert_eq!((x, var), (0.0, 0.0));
        let (x, var) = at(&mut o, 4.1, (0.2, 0.0, 0.0), 0.2);
        assert!(
            (x - 0.2).abs() < 1e-12 && var > 0.0 && var < grown,
            "{x} {var} {grown}"
        );
    }
}

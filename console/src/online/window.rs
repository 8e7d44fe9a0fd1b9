//! Windows of driving: the wheels' ticks and the reference's poses over one stretch, on the
//! board's clock, and the gates a window must pass before it is fitted.
//!
//! The wheels come from the board's stream lines (their mean wheel speeds times the line
//! intervals, in ticks of the board's applied geometry); the reference from the robot's
//! localization, its stamps already on the board's clock. Each reference interval gives one knot:
//! the first stream line at or after the interval's start, the reference interpolated at that
//! line's instant (so the knot's ticks are exactly the board's). A window closes once its wheels
//! have rolled [`WindowOptions::length_m`]; it is then expressed in its own start frame:
//! - the start frame is the reference's pose at the first knot, smoothed over the first
//!   [`ANCHOR_KNOTS`] knots (each carried back to the first by the wheels' motion in between,
//!   with the latest estimate's geometry once there is one: carried with the board's, a spin's
//!   half second would lend the window's turn the board's wheelbase error), so one noisy
//!   sample does not rotate the whole window;
//! - the end pose (its heading is the fit's end-heading residual) is smoothed the same way over
//!   the last knots.
//!
//! Gates (a window that fails one is counted and never fitted):
//! - **gap**: two reference samples further apart than [`WindowOptions::max_gap_s`], or no
//!   stream line between them;
//! - **jump**: from one knot to the next, the reference moved differently from the wheels by
//!   more than its own noise (5σ) plus 10 % of the motion plus 2 cm / 2° — a relocalisation; the
//!   next window starts after it;
//! - **disagree**: over the whole window, the reference's end differs from the wheels' by more
//!   than 10 % of the travel plus 5σ — beyond any geometry the fit may find (factors within
//!   a few percent): the robot lifted, pushed or slipping;
//! - **reset**: the board's time went back (it was reset) in the middle of a window.

use std::collections::VecDeque;

use odocal::calibration::wrap_angle as wrap;
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};

/// Knots the start and end of a window are smoothed over.
pub const ANCHOR_KNOTS: usize = 10;
/// Noise multiple of the jump and disagreement gates.
const GATE_SIGMAS: f64 = 5.0;
/// Fraction of the motion the gates allow beyond the noise (geometry errors are a few percent).
const GATE_FRACTION: f64 = 0.1;
/// Floor of the jump gate: position, metres, and heading, radians.
const JUMP_FLOOR_M: f64 = 0.02;
const JUMP_FLOOR_RAD: f64 = 2.0 * std::f64::consts::PI / 180.0;

/// One reference sample: the robot's axle centre in the reference's fixed frame, on the board's
/// clock, with its 1σ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefSample {
    /// Board time, seconds.
    pub t_s: f64,
    pub pose: PoseF64,
    /// 1σ of x and of y, metres.
    pub sd_xy_m: f64,
    /// 1σ of the heading, radians.
    pub sd_theta_rad: f64,
}

/// How windows are cut and gated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowOptions {
    /// Wheel travel (mean of the two wheels' absolute travel) that closes a window, metres.
    pub length_m: f64,
    /// Longest interval between two reference samples, seconds.
    pub max_gap_s: f64,
}

/// Why a window was not fitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejected {
    Gap,
    Jump,
    Disagree,
    Reset,
}

impl Rejected {
    /// The word the log and the bridge use.
    pub fn as_str(self) -> &'static str {
        match self {
            Rejected::Gap => "gap",
            Rejected::Jump => "jump",
            Rejected::Disagree => "disagree",
            Rejected::Reset => "reset",
        }
    }

    /// The word's reason.
    pub fn parse(s: &str) -> Option<Rejected> {
        [
            Rejected::Gap,
            Rejected::Jump,
            Rejected::Disagree,
            Rejected::Reset,
        ]
        .into_iter()
        .find(|r| r.as_str() == s)
    }
}

/// A closed window, in its own start frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Window {
    /// Board times of its first and last knot, seconds.
    pub t0_s: f64,
    pub t1_s: f64,
    /// The board's geometry while it was driven (the ticks are in it).
    pub geometry: Geometry,
    /// Cumulative ticks from the first knot (the first is `(0, 0)`).
    pub knots: Vec<WheelTicks>,
    /// The reference at every knot in the start frame (the first is the origin).
    pub truth: Vec<PoseF64>,
    /// The smoothed end pose in the start frame.
    pub end: PoseF64,
    /// Wheel travel, metres.
    pub travel_m: f64,
    /// Mean 1σ of the reference over the window: position (m) and heading (rad).
    pub sd_xy_m: f64,
    pub sd_theta_rad: f64,
    /// `None` when it passed every gate.
    pub rejected: Option<Rejected>,
}

impl Window {
    /// Its weight in the fit's terms: `1/σ²` of the reference's position, 1/m².
    pub fn weight(&self) -> f64 {
        1.0 / (self.sd_xy_m * self.sd_xy_m)
    }
}

/// `b` in the frame of `a` (`a⁻¹ ∘ b`, the library's [`PoseF64::relative`]), the heading
/// wrapped.
pub fn relative(a: &PoseF64, b: &PoseF64) -> PoseF64 {
    let r = a.relative(b);
    PoseF64::new(r.x_m, r.y_m, wrap(r.theta_rad))
}

/// `a ∘ d`: the pose `d` (in the frame of `a`) in `a`'s frame's parent.
pub fn compose(a: &PoseF64, d: &PoseF64) -> PoseF64 {
    let (s, c) = a.theta_rad.sin_cos();
    PoseF64::new(
        a.x_m + c * d.x_m - s * d.y_m,
        a.y_m + s * d.x_m + c * d.y_m,
        wrap(a.theta_rad + d.theta_rad),
    )
}

/// The inverse of a relative pose.
fn inverse(d: &PoseF64) -> PoseF64 {
    relative(d, &PoseF64::default())
}

/// The mean of poses near each other (headings averaged as deviations from the first).
fn mean_pose(poses: &[PoseF64]) -> PoseF64 {
    let Some(first) = poses.first() else {
        return PoseF64::default();
    };
    let n = poses.len() as f64;
    let (mut x, mut y, mut dt) = (0.0, 0.0, 0.0);
    for p in poses {
        x += p.x_m;
        y += p.y_m;
        dt += wrap(p.theta_rad - first.theta_rad);
    }
    PoseF64::new(x / n, y / n, wrap(first.theta_rad + dt / n))
}

/// A stream line's wheels: board time and the cumulative ticks since the bridge started.
#[derive(Clone, Copy, Debug)]
struct Wheels {
    t_s: f64,
    right: f64,
    left: f64,
}

/// One knot of the window being built.
#[derive(Clone, Copy, Debug)]
struct Knot {
    t_s: f64,
    right: f64,
    left: f64,
    reference: RefSample,
}

/// Cuts the board's stream and the reference into windows (see the module's text).
#[derive(Debug)]
pub struct Windower {
    options: WindowOptions,
    geometry: Geometry,
    /// Recent stream lines, oldest first.
    wheels: VecDeque<Wheels>,
    /// Reference samples not yet made knots, oldest first.
    refs: VecDeque<RefSample>,
    /// The window being built.
    knots: Vec<Knot>,
    travel_m: f64,
    /// Board time of the last stream line.
    last_t_s: Option<f64>,
    /// The geometry the ends of a window are carried with (the latest estimate's).
    carry: Option<Geometry>,
}

impl Windower {
    /// A windower for a board driving with `geometry`.
    pub fn new(options: WindowOptions, geometry: Geometry) -> Windower {
        Windower {
            options,
            geometry,
            wheels: VecDeque::new(),
            refs: VecDeque::new(),
            knots: Vec::new(),
            travel_m: 0.0,
            last_t_s: None,
            carry: None,
        }
    }

    /// The geometry the latest estimate found: the ends of the next windows are carried with it.
    pub fn set_carry(&mut self, geometry: Geometry) {
        self.carry = Some(geometry);
    }

    /// The board's geometry from now on (a calibration was applied): the window being built is
    /// dropped (its ticks would mix two geometries), uncounted.
    pub fn set_geometry(&mut self, geometry: Geometry) {
        self.geometry = geometry;
        self.knots.clear();
        self.travel_m = 0.0;
    }

    /// A stream line: board time `t_s` and the mean wheel speeds over the interval before it
    /// (m/s, in the board's geometry). Returns a window the board's reset cut short.
    pub fn stream(&mut self, t_s: f64, v_right: f64, v_left: f64) -> Option<Window> {
        let mut cut = None;
        if self.last_t_s.is_some_and(|last| t_s < last) {
            // The board was reset: its time and its odometry start again.
            cut = self.reject(Rejected::Reset);
            self.wheels.clear();
            self.refs.clear();
        }
        let (right, left) = match (self.wheels.back(), self.last_t_s) {
            (Some(w), Some(last)) if t_s >= last => {
                let dt = t_s - last;
                (
                    w.right + v_right * dt / self.geometry.meters_per_tick_right(),
                    w.left + v_left * dt / self.geometry.meters_per_tick_left(),
                )
            }
            _ => (0.0, 0.0),
        };
        self.last_t_s = Some(t_s);
        self.wheels.push_back(Wheels { t_s, right, left });
        cut
    }

    /// A reference sample on the board's clock (one older than the last is dropped).
    pub fn reference(&mut self, r: RefSample) {
        if self.refs.back().is_some_and(|last| r.t_s <= last.t_s) {
            return;
        }
        self.refs.push_back(r);
    }

    /// Makes the knots the stream and the reference now cover; returns the windows closed (or
    /// rejected) on the way.
    pub fn step(&mut self) -> Vec<Window> {
        let mut out = Vec::new();
        while self.refs.len() >= 2 {
            let (r0, r1) = (self.refs[0], self.refs[1]);
            let Some(latest) = self.wheels.back().map(|w| w.t_s) else {
                break;
            };
            if latest < r0.t_s {
                break;
            }
            self.refs.pop_front();
            // The stream lines before this interval are no longer needed.
            while self.wheels.len() > 1 && self.wheels[1].t_s <= r0.t_s {
                self.wheels.pop_front();
            }
            let line = self.wheels.iter().find(|w| w.t_s >= r0.t_s).copied();
            let Some(line) =
                line.filter(|w| w.t_s <= r1.t_s && r1.t_s - r0.t_s <= self.options.max_gap_s)
            else {
                out.extend(self.reject(Rejected::Gap));
                continue;
            };
            let f = (line.t_s - r0.t_s) / (r1.t_s - r0.t_s);
            let reference = RefSample {
                t_s: line.t_s,
                pose: PoseF64::new(
                    r0.pose.x_m + f * (r1.pose.x_m - r0.pose.x_m),
                    r0.pose.y_m + f * (r1.pose.y_m - r0.pose.y_m),
                    wrap(r0.pose.theta_rad + f * wrap(r1.pose.theta_rad - r0.pose.theta_rad)),
                ),
                sd_xy_m: r0.sd_xy_m.max(r1.sd_xy_m),
                sd_theta_rad: r0.sd_theta_rad.max(r1.sd_theta_rad),
            };
            let knot = Knot {
                t_s: line.t_s,
                right: line.right,
                left: line.left,
                reference,
            };
            out.extend(self.add(knot));
        }
        // Without reference samples the stream is kept a few seconds only.
        while self
            .wheels
            .front()
            .zip(self.wheels.back())
            .is_some_and(|(a, b)| b.t_s - a.t_s > 5.0 && self.refs.is_empty())
        {
            self.wheels.pop_front();
        }
        out
    }

    /// Ticks from knot `a` to knot `b`, rounded to whole ticks.
    fn ticks(a: &Knot, b: &Knot) -> WheelTicks {
        WheelTicks {
            right: (b.right - a.right).round() as i64,
            left: (b.left - a.left).round() as i64,
        }
    }

    /// The wheels' motion from knot `a` to knot `b` in `a`'s frame, by the board's geometry.
    fn wheel_motion(&self, a: &Knot, b: &Knot) -> PoseF64 {
        Self::motion(&self.geometry, a, b)
    }

    /// The wheels' motion from knot `a` to knot `b` in `a`'s frame, by `geometry` (the ticks
    /// counted as the board counts them).
    fn motion(geometry: &Geometry, a: &Knot, b: &Knot) -> PoseF64 {
        ArcModel::from_geometry(geometry).integrate(
            PoseF64::default(),
            &[WheelTicks::default(), Self::ticks(a, b)],
        )
    }

    /// Adds a knot: the jump gate, then the window closed once it is long enough.
    fn add(&mut self, knot: Knot) -> Option<Window> {
        let Some(prev) = self.knots.last().copied() else {
            self.knots.push(knot);
            return None;
        };
        let wheels = self.wheel_motion(&prev, &knot);
        let seen = relative(&prev.reference.pose, &knot.reference.pose);
        let (a, b) = (&prev.reference, &knot.reference);
        let sd_p = a.sd_xy_m.hypot(b.sd_xy_m);
        let sd_t = a.sd_theta_rad.hypot(b.sd_theta_rad);
        let moved = wheels.x_m.hypot(wheels.y_m);
        let dp = (seen.x_m - wheels.x_m).hypot(seen.y_m - wheels.y_m);
        let dt = wrap(seen.theta_rad - wheels.theta_rad).abs();
        if dp > GATE_SIGMAS * sd_p + GATE_FRACTION * moved + JUMP_FLOOR_M
            || dt > GATE_SIGMAS * sd_t + GATE_FRACTION * wheels.theta_rad.abs() + JUMP_FLOOR_RAD
        {
            let w = self.reject(Rejected::Jump);
            // The reference is consistent again after the jump: the next window starts here.
            self.knots.push(knot);
            return w;
        }
        let t = Self::ticks(&prev, &knot);
        self.travel_m += 0.5
            * ((t.right as f64 * self.geometry.meters_per_tick_right()).abs()
                + (t.left as f64 * self.geometry.meters_per_tick_left()).abs());
        self.knots.push(knot);
        (self.travel_m >= self.options.length_m).then(|| self.close())
    }

    /// The window being built, rejected for `why` (`None` when no window had begun moving).
    fn reject(&mut self, why: Rejected) -> Option<Window> {
        if self.knots.len() < 2 {
            self.knots.clear();
            self.travel_m = 0.0;
            return None;
        }
        let mut w = self.window();
        w.rejected = Some(why);
        self.knots.clear();
        self.travel_m = 0.0;
        Some(w)
    }

    /// The window as built so far, gated for disagreement; the next one starts at its last knot.
    fn close(&mut self) -> Window {
        let w = self.window();
        let last = self.knots.last().copied();
        self.knots.clear();
        self.travel_m = 0.0;
        self.knots.extend(last);
        w
    }

    /// The window of the knots so far (at least two), in its start frame.
    fn window(&self) -> Window {
        let k = &self.knots;
        let n = k.len();
        let a = ANCHOR_KNOTS.min(n);
        // Each of the first knots' reference carried back to the first knot by the wheels.
        let carry = self.carry.unwrap_or(self.geometry);
        let starts: Vec<PoseF64> = k[..a]
            .iter()
            .map(|kn| {
                compose(
                    &kn.reference.pose,
                    &inverse(&Self::motion(&carry, &k[0], kn)),
                )
            })
            .collect();
        let anchor = mean_pose(&starts);
        let ends: Vec<PoseF64> = k[n - a..]
            .iter()
            .map(|kn| compose(&kn.reference.pose, &Self::motion(&carry, kn, &k[n - 1])))
            .collect();
        let end = relative(&anchor, &mean_pose(&ends));
        let knots: Vec<WheelTicks> = k.iter().map(|kn| Self::ticks(&k[0], kn)).collect();
        let mut truth: Vec<PoseF64> = k
            .iter()
            .map(|kn| relative(&anchor, &kn.reference.pose))
            .collect();
        truth[0] = PoseF64::default();
        let sd_xy_m = k.iter().map(|kn| kn.reference.sd_xy_m).sum::<f64>() / n as f64;
        let sd_theta_rad = k.iter().map(|kn| kn.reference.sd_theta_rad).sum::<f64>() / n as f64;
        let wheels_end =
            ArcModel::from_geometry(&self.geometry).integrate(PoseF64::default(), &knots);
        // Smoothing over `a` knots divides the end's noise by √a (and the anchor's).
        let sd_end = sd_xy_m * (2.0 / a as f64).sqrt();
        let off = (end.x_m - wheels_end.x_m).hypot(end.y_m - wheels_end.y_m);
        let rejected = (off > GATE_FRACTION * self.travel_m + GATE_SIGMAS * sd_end)
            .then_some(Rejected::Disagree);
        Window {
            t0_s: k[0].t_s,
            t1_s: k[n - 1].t_s,
            geometry: self.geometry,
            knots,
            truth,
            end,
            travel_m: self.travel_m,
            sd_xy_m,
            sd_theta_rad,
            rejected,
        }
    }
}

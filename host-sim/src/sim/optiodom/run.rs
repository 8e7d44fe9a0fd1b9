//! One recorded run and its conversion into a calibration input: the path it drove (a square of
//! the session's side, a circle of the radius its ground truth shows, or a line of its mean wheel
//! travel), its odometry re-integrated with a believed geometry, and its end pose or whole path
//! in the ground truth, from its start or its [anchor](super::anchor).

use odocal::calibration::RunObservation;
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::{ArcModel, PoseF64};
use odocal::motion::run::{Direction, Measurement, PathKind};

use super::Kind;

/// One recorded run.
#[derive(Clone, Debug)]
pub struct OptiRun {
    /// Turn direction of a square or circle run (as its wheels turned it); `None` for other kinds.
    pub direction: Option<Direction>,
    /// Cumulative (scaled) ticks, one knot per row, first `(0, 0)`.
    pub knots: Vec<WheelTicks>,
    /// Ground truth at every knot, in the start frame.
    pub truth: Vec<PoseF64>,
    /// Ground-truth end pose in the start frame.
    pub truth_end: PoseF64,
    /// Ground truth in the robot's start frame: [`OptiRun::truth`] turned by the session's
    /// heading offset (equal to it when the session has none; see
    /// [`heading_offset`](super::heading_offset)).
    pub aligned: Vec<PoseF64>,
    /// The knot from which the calibration measures the run (0: its start; see
    /// [`anchor`](super::anchor)).
    pub anchor: usize,
    /// From the anchor on (empty when it is 0): the aligned truth, then the recorded truth, each
    /// in its own frame at the anchor.
    pub(super) from_anchor: [Vec<PoseF64>; 2],
}

/// Mean absolute wheel travel between the two knots of `w` with `g`, metres.
pub(super) fn step_travel_m(w: &[WheelTicks], g: &Geometry) -> f64 {
    let (right, left) = wheel_travel(w[1] - w[0], g);
    0.5 * (right.abs() + left.abs())
}

/// The signed travel of the right and left wheel for the tick counts `d` with `g`, metres.
pub(super) fn wheel_travel(d: WheelTicks, g: &Geometry) -> (f64, f64) {
    (
        d.right as f64 * g.meters_per_tick_right(),
        d.left as f64 * g.meters_per_tick_left(),
    )
}

impl OptiRun {
    /// A run from its knots and ground truth (start frame); its aligned truth starts as the
    /// recorded one (the session turns it once its heading offset is known).
    pub fn new(direction: Option<Direction>, knots: Vec<WheelTicks>, truth: Vec<PoseF64>) -> Self {
        OptiRun {
            direction,
            truth_end: truth.last().copied().unwrap_or_default(),
            aligned: truth.clone(),
            knots,
            truth,
            anchor: 0,
            from_anchor: [Vec::new(), Vec::new()],
        }
    }

    /// Length of the ground-truth path, metres.
    pub fn truth_length_m(&self) -> f64 {
        self.truth.windows(2).map(|w| w[0].distance_to(&w[1])).sum()
    }

    /// Mean absolute wheel travel with `g`, metres (the arc the wheels roll for a turn).
    pub fn wheel_travel_m(&self, g: &Geometry) -> f64 {
        self.knots.windows(2).map(|w| step_travel_m(w, g)).sum()
    }

    /// The path this run drove, as the calibration describes it (see the module docs).
    pub fn path(&self, kind: Kind, side_m: f64, belief: &Geometry) -> PathKind {
        match (kind, self.direction) {
            (Kind::Square, Some(direction)) => PathKind::Square { direction, side_m },
            (Kind::Circular, Some(direction)) => {
                let turn = self
                    .truth
                    .last()
                    .map_or(0.0, |t| t.theta_rad.abs())
                    .max(f64::EPSILON);
                PathKind::Circle {
                    direction,
                    radius_m: self.truth_length_m() / turn,
                }
            }
            _ => PathKind::Line {
                length_m: self.wheel_travel_m(belief),
            },
        }
    }

    /// The run as a calibration input, driven with `belief` (odometry re-integrated with it);
    /// with `along_path`, the ground truth at every knot is passed too (fit to the whole path).
    /// The truth is the [aligned](OptiRun::aligned) one, or with `recorded` the one in the file;
    /// the run is measured from its [anchor](OptiRun::anchor), or with `from_start` from its
    /// first knot.
    pub fn observation(
        &self,
        kind: Kind,
        side_m: f64,
        belief: &Geometry,
        along_path: bool,
        recorded: bool,
        from_start: bool,
    ) -> RunObservation<'_> {
        let (first, truth) = if from_start || self.anchor == 0 {
            (0, if recorded { &self.truth } else { &self.aligned })
        } else {
            (self.anchor, &self.from_anchor[usize::from(recorded)])
        };
        let knots = &self.knots[first..];
        let end = truth.last().copied().unwrap_or_default();
        RunObservation {
            path: self.path(kind, side_m, belief),
            geometry: *belief,
            knots,
            odometry_end: ArcModel::from_geometry(belief).integrate(PoseF64::default(), knots),
            measured: Measurement {
                x_m: end.x_m,
                y_m: end.y_m,
                theta_rad: Some(end.theta_rad),
            },
            truth_path: if along_path { truth } else { &[] },
        }
    }
}

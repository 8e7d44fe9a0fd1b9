//! Reader for OptiOdom differential-drive sessions (`<id>_metadata.csv` + `<id>_run-NN.csv`) of
//! every kind: `square`, `circular`, `ivanjko`, `free` (the name of the session's parent folder).
//!
//! Each run row is `time_s, x_gt_m, y_gt_m, theta_gt_rad, ticks_right, ticks_left` per 50 ms
//! cycle; the ticks are per-cycle increments (the motion from the previous row). The reader turns
//! them into cumulative knots, one knot per row, and expresses every ground-truth pose in the
//! frame of the first one (the run's start frame: origin, heading +x), so that knot `j` and truth
//! pose `j` belong together. A square or circle run turns in the direction its wheels turned it
//! (about ∓2π of odometry heading); the file order (the first `N/2` runs CW, the rest CCW) decides
//! only for a run that turned less than half a turn.
//! Rows whose ground truth the motion capture lost (any of its fields empty or `NaN`) keep their
//! ticks; inside a run their truth is interpolated in time between the neighbouring rows, at a run's
//! ends they are cut (the run starts and ends at rows with ground truth), and `replay` says how many
//! ([`TruthGaps`]). Any other unreadable value is an error naming file, line and field, and so is
//! a glitch: motion faster than [`MAX_ROW_SPEED_M_S`] between two rows, or a tick count that is not
//! a whole number within ±[`MAX_ROW_TICKS`]. A run whose wheels turn it more than
//! [`SWAP_MIN_TURN_RAD`] one way while its ground truth turns more than that the other way is refused
//! too: its right and left tick columns are swapped (or an encoder counts backwards).
//!
//! The encoder resolution `ngear · encRes` is not an integer (43.7 · 64 = 2796.8 ticks per wheel
//! revolution); [`Geometry::counts_per_rev`] is, so ticks and resolution are both multiplied by
//! the smallest power of ten that makes it one (here 10). Travel per tick is unchanged.
//!
//! As calibration input ([`OptiRun::observation`]) a run is described by the path it drove:
//! a square of the session's side `L`; a circle of the radius the ground truth shows (path
//! length / total turn); Ivanjko's straight lines and in-place turns and free paths as a line
//! whose length is the mean wheel travel (for a turn in place, the arc the wheels roll). That
//! length is what the exact method weights the heading residual with, and what groups runs of
//! similar size in its robust scale.
//!
//! The reader is split by concept: [`session`] reads a session folder (its metadata, its run
//! files in order, the checks that span a run), [`run_file`] reads one run file (rows, dropouts,
//! glitches), [`heading_offset`] measures and removes the motion-capture heading offset,
//! [`anchor`] places each run's start anchor past its start transient, [`run`] turns a run
//! into a calibration input, [`recorded`] reads when a session was recorded from its id, and
//! [`playback`] lays a session's runs out in time as wheel motion (`serial --replay`).

pub mod anchor;
pub mod heading_offset;
pub mod playback;
pub mod recorded;
pub mod run;
pub mod run_file;
pub mod session;

#[cfg(test)]
mod fixtures;

use odocal::kinematics::geometry::Geometry;

pub use self::anchor::{ANCHOR_MIN_TRAVEL_M, START_TRAVEL_M};
pub use self::heading_offset::{
    OFFSET_HALF_WINDOW, OFFSET_MAX_TURN_RAD, OFFSET_MIN_CHORD_M, OFFSET_MIN_SAMPLES, TruthOffset,
    truth_heading_offset,
};
pub use self::recorded::recorded_days;
pub use self::run::OptiRun;
pub use self::run_file::{MAX_ROW_GAP, MAX_ROW_SPEED_M_S, MAX_ROW_TICKS, TruthGaps};
pub use self::session::{SIDE_MISMATCH, SWAP_MIN_TURN_RAD, read_session};

/// The kind of a session: the name of its parent folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// UMBmark squares.
    Square,
    /// Circles, CW then CCW.
    Circular,
    /// Ivanjko's test: straight lines and 180° in-place turns.
    Ivanjko,
    /// Freely driven paths.
    Free,
}

impl Kind {
    /// The folder name (`square`, `circular`, `ivanjko`, `free`).
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Square => "square",
            Kind::Circular => "circular",
            Kind::Ivanjko => "ivanjko",
            Kind::Free => "free",
        }
    }

    /// The kind of a folder name.
    pub fn parse(name: &str) -> Option<Kind> {
        [Kind::Square, Kind::Circular, Kind::Ivanjko, Kind::Free]
            .into_iter()
            .find(|k| k.as_str() == name)
    }
}

/// One session (one folder).
#[derive(Clone, Debug)]
pub struct Session {
    /// Session id (folder name).
    pub id: String,
    /// Kind (parent folder name).
    pub kind: Kind,
    /// Nominal geometry of the session (its `Di`, `Li`, scaled resolution).
    pub nominal: Geometry,
    /// Factor applied to the raw ticks.
    pub tick_scale: i64,
    /// Square side, metres (squares; 0 otherwise).
    pub side_m: f64,
    /// Runs in file order.
    pub runs: Vec<OptiRun>,
    /// Heading offset of the ground truth, when it could be measured.
    pub truth_offset: Option<TruthOffset>,
    /// Rows without ground truth (motion-capture dropouts), over all runs.
    pub truth_gaps: TruthGaps,
}

//! A session's runs as wheel motion in time, for `serial --replay`: the runs one after another,
//! each row's ticks spread evenly over its [`ROW_US`], the robot at rest for [`PAUSE_US`]
//! between runs.
//!
//! Time is counted from the start of the playback (microseconds, the board clock's unit).
//! Run `i` plays from its start to its start plus `(knots − 1) · ROW_US`; at a time `τ` within
//! it, row `j = τ / ROW_US` is a fraction `f` through, and each wheel's count is its knot `j`
//! plus `⌊f · (knot j+1 − knot j)⌋` (exactly the knot at every row boundary), on top of the
//! totals of the runs before. The ground truth is the run's recorded one turned by the
//! session's measured motion-capture heading offset ([`OptiRun::aligned`], in its start frame:
//! the robot's own heading, as `replay` calibrates with it) interpolated linearly in time, its heading unwrapped from the run's
//! start (each row's turn taken the short way round).

use std::f64::consts::TAU;

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::reference::PoseF64;

use super::{OptiRun, Session};

/// Time between two rows of a run file, µs (the OptiOdom logger's 50 ms cycle).
pub const ROW_US: u64 = 50_000;

/// Time the robot rests between two runs, µs.
pub const PAUSE_US: u64 = 2_000_000;

/// Where the playback is at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Cue {
    /// Run `index` (from 0) plays: the encoders' totals and the run's ground truth now.
    Run {
        /// The run, from 0 in file order.
        index: usize,
        /// Wheel counts since the playback started (scaled ticks, as the session's knots).
        ticks: WheelTicks,
        /// Recorded ground truth in the run's start frame, heading unwrapped.
        truth: PoseF64,
    },
    /// At rest between runs, or after the last one (`done`).
    Rest {
        /// Wheel counts since the playback started.
        ticks: WheelTicks,
        /// Whether every run has played.
        done: bool,
    },
}

impl Cue {
    /// The wheel counts since the playback started.
    pub fn ticks(&self) -> WheelTicks {
        match *self {
            Cue::Run { ticks, .. } | Cue::Rest { ticks, .. } => ticks,
        }
    }
}

/// One run on the playback's time line.
#[derive(Clone, Debug)]
struct Track {
    /// When it starts, µs.
    start_us: u64,
    /// The counts of the runs before it.
    base: WheelTicks,
    /// Its cumulative knots, one per row.
    knots: Vec<WheelTicks>,
    /// Its ground truth at every knot, heading unwrapped.
    truth: Vec<PoseF64>,
}

impl Track {
    /// When it ends (its last knot), µs.
    fn end_us(&self) -> u64 {
        self.start_us + ROW_US * (self.knots.len().saturating_sub(1) as u64)
    }

    /// The counts and the ground truth `tau_us` into the run (at most its length).
    fn at(&self, tau_us: u64) -> (WheelTicks, PoseF64) {
        let j = (tau_us / ROW_US) as usize;
        let into = (tau_us % ROW_US) as i64;
        let (Some(&k0), Some(&t0)) = (self.knots.get(j), self.truth.get(j)) else {
            return (self.base, PoseF64::default());
        };
        let (Some(&k1), Some(&t1)) = (self.knots.get(j + 1), self.truth.get(j + 1)) else {
            return (plus(self.base, k0), t0);
        };
        let spread = |a: i64, b: i64| a + ((b - a) * into).div_euclid(ROW_US as i64);
        let ticks = WheelTicks::new(spread(k0.right, k1.right), spread(k0.left, k1.left));
        let f = into as f64 / ROW_US as f64;
        let truth = PoseF64::new(
            t0.x_m + f * (t1.x_m - t0.x_m),
            t0.y_m + f * (t1.y_m - t0.y_m),
            t0.theta_rad + f * (t1.theta_rad - t0.theta_rad),
        );
        (plus(self.base, ticks), truth)
    }
}

/// `a + b`, wheel by wheel.
fn plus(a: WheelTicks, b: WheelTicks) -> WheelTicks {
    WheelTicks::new(a.right + b.right, a.left + b.left)
}

/// The heading of `truth` unwrapped from its first pose: each step's turn the short way round.
fn unwrapped(truth: &[PoseF64]) -> Vec<PoseF64> {
    let mut out: Vec<PoseF64> = Vec::with_capacity(truth.len());
    for p in truth {
        let theta = match out.last() {
            Some(prev) => {
                let turn = p.theta_rad - prev.theta_rad;
                prev.theta_rad + (turn - TAU * (turn / TAU).round())
            }
            None => p.theta_rad,
        };
        out.push(PoseF64::new(p.x_m, p.y_m, theta));
    }
    out
}

/// A session's runs on one time line.
#[derive(Clone, Debug)]
pub struct Playback {
    tracks: Vec<Track>,
}

impl Playback {
    /// The runs of `session` in file order.
    pub fn new(session: &Session) -> Self {
        Playback::of_runs(&session.runs)
    }

    /// `runs` one after another, [`PAUSE_US`] apart.
    pub fn of_runs(runs: &[OptiRun]) -> Self {
        let mut tracks: Vec<Track> = Vec::with_capacity(runs.len());
        for run in runs {
            let (start_us, base) = match tracks.last() {
                Some(t) => (
                    t.end_us() + PAUSE_US,
                    plus(t.base, t.knots.last().copied().unwrap_or_default()),
                ),
                None => (0, WheelTicks::default()),
            };
            tracks.push(Track {
                start_us,
                base,
                knots: run.knots.clone(),
                truth: unwrapped(&run.aligned),
            });
        }
        Playback { tracks }
    }

    /// The number of runs.
    pub fn runs(&self) -> usize {
        self.tracks.len()
    }

    /// When the last run ends, µs after the start.
    pub fn duration_us(&self) -> u64 {
        self.tracks.last().map_or(0, Track::end_us)
    }

    /// Where the playback is `t_us` after its start.
    pub fn at(&self, t_us: u64) -> Cue {
        let mut ticks = WheelTicks::default();
        for (index, track) in self.tracks.iter().enumerate() {
            if t_us < track.start_us {
                return Cue::Rest { ticks, done: false };
            }
            if t_us <= track.end_us() {
                let (ticks, truth) = track.at(t_us - track.start_us);
                return Cue::Run {
                    index,
                    ticks,
                    truth,
                };
            }
            ticks = plus(track.base, track.knots.last().copied().unwrap_or_default());
        }
        Cue::Rest { ticks, done: true }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two runs: three rows each, the second turning through ±π (its file heading wrapped).
    fn two_runs() -> Playback {
        let k = |r, l| WheelTicks::new(r, l);
        let run1 = OptiRun::new(
            None,
            vec![k(0, 0), k(100, 50), k(150, 150)],
            vec![
                PoseF64::new(0.0, 0.0, 0.0),
                PoseF64::new(0.1, 0.0, 0.0),
                PoseF64::new(0.2, 0.0, 0.0),
            ],
        );
        let run2 = OptiRun::new(
            None,
            vec![k(0, 0), k(-7, 3), k(-10, 10)],
            vec![
                PoseF64::new(0.0, 0.0, 0.0),
                PoseF64::new(0.0, 0.0, 3.0),
                PoseF64::new(0.0, 0.0, -3.0),
            ],
        );
        Playback::of_runs(&[run1, run2])
    }

    #[test]
    fn rows_are_spread_evenly_and_runs_follow_each_other_after_a_pause() {
        let p = two_runs();
        assert_eq!(p.runs(), 2);
        assert_eq!(p.duration_us(), 2 * ROW_US + PAUSE_US + 2 * ROW_US);
        // A fifth into row 0: ⌊100/5⌋, ⌊50/5⌋; the truth a fifth of the way.
        let Cue::Run {
            index: 0,
            ticks,
            truth,
        } = p.at(ROW_US / 5)
        else {
            panic!("{:?}", p.at(ROW_US / 5));
        };
        assert_eq!(ticks, WheelTicks::new(20, 10));
        assert!((truth.x_m - 0.02).abs() < 1e-15, "{truth:?}");
        // Exactly each knot at the row boundaries, the last one included.
        assert_eq!(p.at(ROW_US).ticks(), WheelTicks::new(100, 50));
        assert!(matches!(p.at(2 * ROW_US), Cue::Run { index: 0, .. }));
        assert_eq!(p.at(2 * ROW_US).ticks(), WheelTicks::new(150, 150));
        // At rest between the runs, then run 2 on top of run 1's totals; counts going
        // backwards round down (⌊−7 · 0.5⌋ = −4).
        assert_eq!(
            p.at(2 * ROW_US + 1),
            Cue::Rest {
                ticks: WheelTicks::new(150, 150),
                done: false
            }
        );
        let start2 = 2 * ROW_US + PAUSE_US;
        assert!(matches!(p.at(start2), Cue::Run { index: 1, .. }));
        assert_eq!(p.at(start2 + ROW_US / 2).ticks(), WheelTicks::new(146, 151));
        assert_eq!(
            p.at(p.duration_us() + 1),
            Cue::Rest {
                ticks: WheelTicks::new(140, 160),
                done: true
            }
        );
    }

    #[test]
    fn the_truth_heading_is_unwrapped_the_short_way_round() {
        let p = two_runs();
        let start2 = 2 * ROW_US + PAUSE_US;
        // 3 rad, then −3 rad in the file: 2π − 6 rad further on, not 6 rad back.
        let Cue::Run { truth, .. } = p.at(start2 + 2 * ROW_US) else {
            panic!();
        };
        assert!((truth.theta_rad - (TAU - 3.0)).abs() < 1e-12, "{truth:?}");
        let Cue::Run { truth, .. } = p.at(start2 + 3 * ROW_US / 2) else {
            panic!();
        };
        assert!((truth.theta_rad - 0.5 * (3.0 + TAU - 3.0)).abs() < 1e-12);
    }
}

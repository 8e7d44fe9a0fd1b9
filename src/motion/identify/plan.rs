//! The step plan: the passes (per direction, per wheel when lifted) of three duty steps, a coast
//! and a brake, stepped once per control period, with the checks each period and each finished
//! segment make (no motion, counts against the duty, the other wheel moving, too fast).

use super::report::{IdentifyFailure, IdentifyProblem};
use super::stats::WheelLog;
use super::{
    BLOCK_MS, BRAKE_MS, COAST_MS, IdentifyMode, LEVEL_MS, LEVELS, MAX_SPEED_MPS, MIN_MOTION_M,
};
use crate::motion::motor::StopMode;
use crate::motion::wheel::Wheel;
use crate::util::num::{ceil_i64, round_u32};

/// The segments of a pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Segment {
    Level(usize),
    Coast,
    Brake,
}

pub(super) const SEGMENTS: [Segment; 5] = [
    Segment::Level(0),
    Segment::Level(1),
    Segment::Level(2),
    Segment::Coast,
    Segment::Brake,
];

/// What the routine commands for one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IdentifyStep {
    /// Open-loop duties (right, left), wheel frame (forward positive).
    Duty(f32, f32),
    /// Motors stopped this way for the period.
    Stop(StopMode),
    /// An abnormal response: stop the motors and latch the failure.
    Failed(IdentifyFailure),
    /// The last segment ended: the statistics are complete and frozen; stop the motors. The
    /// result (a report, or a failure the fit detects) is [`Identify::fit`], computed outside
    /// the control period.
    Finished,
}

/// The identification routine (see the `identify` module docs); stepped once per control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identify {
    pub(super) mode: IdentifyMode,
    pub(super) rate_hz: u32,
    /// Metres per count, per wheel (right, left).
    pub(super) m_per_tick: (f64, f64),
    /// Counts in the last quarter of a step that are motion, per wheel.
    pub(super) min_counts: (i64, i64),
    /// Counts per period that exceed [`MAX_SPEED_MPS`], per wheel.
    pub(super) max_counts: (i64, i64),
    pub(super) pass: usize,
    pub(super) segment: usize,
    /// Periods the current segment's command has been applied (the one whose counts arrive
    /// next included).
    pub(super) done_in_segment: u32,
    pub(super) started: bool,
    /// The previous period's counts within this segment, per wheel.
    pub(super) previous: (Option<i64>, Option<i64>),
    /// Counts in the last quarter of the current step: (right, left).
    pub(super) tail: (i64, i64),
    /// Periods per block.
    pub(super) block_periods: u32,
    /// Counts of the block being summed (right, left) and its periods so far.
    pub(super) block: (i64, i64),
    pub(super) in_block: u32,
    /// Statistics per wheel (right, left).
    pub(super) logs: [WheelLog; 2],
}

impl Identify {
    /// A routine at `rate_hz` for wheels of `m_per_tick` metres per count (right, left).
    pub fn new(mode: IdentifyMode, rate_hz: u32, m_per_tick: (f64, f64)) -> Self {
        let rate = f64::from(rate_hz.max(1));
        let min = |m: f64| ceil_i64(MIN_MOTION_M / m);
        let max = |m: f64| ceil_i64(MAX_SPEED_MPS / (m * rate));
        Identify {
            mode,
            rate_hz: rate_hz.max(1),
            m_per_tick,
            min_counts: (min(m_per_tick.0), min(m_per_tick.1)),
            max_counts: (max(m_per_tick.0), max(m_per_tick.1)),
            pass: 0,
            segment: 0,
            done_in_segment: 0,
            started: false,
            previous: (None, None),
            tail: (0, 0),
            block_periods: round_u32(f64::from(BLOCK_MS) * rate / 1000.0).max(1),
            block: (0, 0),
            in_block: 0,
            logs: [WheelLog::default(); 2],
        }
    }

    /// Where the robot is.
    pub fn mode(&self) -> IdentifyMode {
        self.mode
    }

    /// Whether the last segment has ended ([`IdentifyStep::Finished`]): the statistics are
    /// complete and no longer change.
    pub fn is_finished(&self) -> bool {
        self.pass >= self.mode.passes()
    }

    /// Periods of segment `s`: its duration at the control rate, rounded (in integers: the
    /// control period calls this).
    fn segment_periods(&self, s: Segment) -> u32 {
        let ms = match s {
            Segment::Level(_) => LEVEL_MS,
            Segment::Coast => COAST_MS,
            Segment::Brake => BRAKE_MS,
        };
        // ≤ 500 ms × 10 kHz: far inside u32 (saturating all the same).
        (ms.saturating_mul(self.rate_hz).saturating_add(500) / 1000).max(4)
    }

    /// The wheels driven in this pass (right, left) and the direction index (0 forward).
    fn pass_shape(&self) -> ((bool, bool), usize) {
        match self.mode {
            IdentifyMode::Lifted => (
                if self.pass < 2 {
                    (true, false)
                } else {
                    (false, true)
                },
                self.pass % 2,
            ),
            IdentifyMode::Floor => ((true, true), self.pass % 2),
        }
    }

    /// One period: `dr`, `dl` are the counts of the period that just ended (during which the
    /// previous step's command was applied).
    pub fn step(&mut self, dr: i64, dl: i64) -> IdentifyStep {
        if self.is_finished() {
            return IdentifyStep::Finished;
        }
        if self.started {
            if let Some(f) = self.record(dr, dl) {
                return IdentifyStep::Failed(f);
            }
            let seg = SEGMENTS[self.segment % SEGMENTS.len()];
            if self.done_in_segment >= self.segment_periods(seg) {
                if let Some(f) = self.end_segment(seg) {
                    return IdentifyStep::Failed(f);
                }
                let ((on_r, on_l), dir) = self.pass_shape();
                for (log, on) in self.logs.iter_mut().zip([on_r, on_l]) {
                    if on {
                        log.close(seg, dir);
                    }
                }
                self.segment += 1;
                if self.segment == SEGMENTS.len() {
                    self.segment = 0;
                    self.pass += 1;
                }
                self.done_in_segment = 0;
                self.previous = (None, None);
                self.tail = (0, 0);
                self.block = (0, 0);
                self.in_block = 0;
                if self.is_finished() {
                    // The fit is not computed here, in the control period: see `fit`.
                    return IdentifyStep::Finished;
                }
            }
        }
        self.started = true;
        self.done_in_segment += 1;
        let ((r, l), dir) = self.pass_shape();
        match SEGMENTS[self.segment % SEGMENTS.len()] {
            Segment::Level(i) => {
                let d = if dir == 0 { LEVELS[i] } else { -LEVELS[i] };
                IdentifyStep::Duty(if r { d } else { 0.0 }, if l { d } else { 0.0 })
            }
            Segment::Coast => IdentifyStep::Stop(StopMode::Coast),
            Segment::Brake => IdentifyStep::Stop(StopMode::Brake),
        }
    }

    /// Adds the counts of the period that just ended to the current segment's statistics.
    fn record(&mut self, dr: i64, dl: i64) -> Option<IdentifyFailure> {
        let ((on_r, on_l), _) = self.pass_shape();
        let seg = SEGMENTS[self.segment % SEGMENTS.len()];
        let tail_from = self.segment_periods(seg) * 3 / 4;
        if matches!(seg, Segment::Level(_)) && self.done_in_segment > tail_from {
            self.tail.0 += dr;
            self.tail.1 += dl;
        }
        for (wheel, c, limit) in [
            (Wheel::Right, dr, self.max_counts.0),
            (Wheel::Left, dl, self.max_counts.1),
        ] {
            if c.abs() > limit {
                return Some(IdentifyFailure {
                    wheel,
                    problem: IdentifyProblem::TooFast,
                });
            }
        }
        self.block.0 += dr;
        self.block.1 += dl;
        self.in_block += 1;
        if self.in_block < self.block_periods {
            return None;
        }
        let (br, bl) = self.block;
        self.block = (0, 0);
        self.in_block = 0;
        for (w, on, c) in [(0usize, on_r, br), (1, on_l, bl)] {
            if !on {
                continue;
            }
            let prev = if w == 0 {
                &mut self.previous.0
            } else {
                &mut self.previous.1
            };
            let running = &mut self.logs[w].running;
            match (seg, *prev) {
                (Segment::Level(_), Some(x)) => running.add(x, c),
                (Segment::Coast, Some(x)) if x != 0 && c != 0 => running.add(x, c),
                _ => {}
            }
            *prev = Some(c);
        }
        None
    }

    /// Checks a finished duty step: motion, sign, and (lifted) the other wheel.
    fn end_segment(&self, seg: Segment) -> Option<IdentifyFailure> {
        if !matches!(seg, Segment::Level(_)) {
            return None;
        }
        let ((on_r, on_l), dir) = self.pass_shape();
        let sign = if dir == 0 { 1 } else { -1 };
        let lifted = self.mode == IdentifyMode::Lifted;
        for (wheel, on, own, other, min) in [
            (
                Wheel::Right,
                on_r,
                self.tail.0,
                self.tail.1,
                self.min_counts.0,
            ),
            (
                Wheel::Left,
                on_l,
                self.tail.1,
                self.tail.0,
                self.min_counts.1,
            ),
        ] {
            if !on {
                continue;
            }
            let fail = |problem| Some(IdentifyFailure { wheel, problem });
            if lifted && other.abs() > own.abs().max(min) {
                return fail(IdentifyProblem::CrossWired);
            }
            if own.abs() < min {
                return fail(IdentifyProblem::NoMotion);
            }
            if own * sign < 0 {
                return fail(IdentifyProblem::Reversed);
            }
        }
        None
    }
}

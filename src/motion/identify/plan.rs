//! The step plan: a probe (a slow duty staircase that finds where the wheel starts to move and
//! how fast it gains speed), then the passes (per direction, per wheel when lifted) of three duty
//! steps chosen from the probe, a coast and a brake, stepped once per control period, with the
//! checks each period, block and finished segment make (no motion, counts against the duty, the
//! other wheel moving, faster than the cap, farther than the travel bound, a response the probe
//! did not predict).

use super::report::{IdentifyFailure, IdentifyProblem};
use super::stats::WheelLog;
use super::{
    BLOCK_MS, BRAKE_MS, COAST_MS, IdentifyMode, LEVEL_FRACTIONS, LEVEL_MS, MAX_SPEED_MPS,
    PROBE_END_FRACTION, PROBE_STAIR_MS, PROBE_START_DUTY, PROBE_STEP_DUTY, PROBE_TRAVEL_M,
    RESPONSE_TOLERANCE, SPEED_MARGIN, STOP_TIME_S, TRAVEL_LIMIT_M,
};
use crate::motion::motor::StopMode;
use crate::motion::wheel::{MIN_MOTION_M, Wheel};
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

/// The probe of the wheels a pass set drives (both on the floor, one lifted).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Probe {
    /// The staircase's current duty.
    duty: f32,
    /// Periods of the current stair, and (after the staircase) of the brake to rest.
    periods: u32,
    /// Counts of the last whole block of the stair (right, left).
    last_block: (i64, i64),
    /// The previous stair: its duty and last block, once the wheels moved at it.
    moving: Option<(f32, (i64, i64))>,
    /// The staircase is over; the wheels brake to rest before the first step.
    braking: bool,
}

/// The line `|v| = K (duty − d0)` a probe measured for a wheel: gain (m/s per duty) and dead-band.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Line {
    pub(super) gain: f64,
    pub(super) deadband: f64,
}

impl Line {
    fn speed(&self, duty: f64) -> f64 {
        self.gain * (duty - self.deadband)
    }
}

/// The identification routine (see the `identify` module docs); stepped once per control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identify {
    pub(super) mode: IdentifyMode,
    pub(super) rate_hz: u32,
    /// The fastest wheel speed the routine aims for, m/s: the operator's `max_speed` (at most
    /// [`MAX_SPEED_MPS`]).
    pub(super) cap_mps: f64,
    /// Counts per block above which a wheel is faster than the cap plus [`SPEED_MARGIN`].
    pub(super) block_cap_counts: (i64, i64),
    /// Counts from the start (right, left), for the floor's travel bound.
    pub(super) travel: (i64, i64),
    /// The probe of the current pass set (`None` once its steps run).
    pub(super) probe: Option<Probe>,
    /// The probe's line per wheel (right, left).
    pub(super) lines: [Line; 2],
    /// The duty steps per wheel (right, left), chosen from the probe.
    pub(super) levels: [[f32; 3]; 2],
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
    /// A routine at `rate_hz` for wheels of `m_per_tick` metres per count (right, left) whose
    /// speed stays within `max_speed_mps` (the operator's limit; at most [`MAX_SPEED_MPS`]).
    pub fn new(
        mode: IdentifyMode,
        rate_hz: u32,
        m_per_tick: (f64, f64),
        max_speed_mps: f64,
    ) -> Self {
        let rate = f64::from(rate_hz.max(1));
        let min = |m: f64| ceil_i64(MIN_MOTION_M / m);
        let max = |m: f64| ceil_i64(MAX_SPEED_MPS / (m * rate));
        let cap_mps = if max_speed_mps > 0.0 {
            max_speed_mps.min(MAX_SPEED_MPS)
        } else {
            MAX_SPEED_MPS
        };
        let block_periods = round_u32(f64::from(BLOCK_MS) * rate / 1000.0).max(1);
        let block_s = f64::from(block_periods) / rate;
        let block_cap = |m: f64| ceil_i64(cap_mps * (1.0 + SPEED_MARGIN) * block_s / m);
        Identify {
            mode,
            rate_hz: rate_hz.max(1),
            cap_mps,
            block_cap_counts: (block_cap(m_per_tick.0), block_cap(m_per_tick.1)),
            travel: (0, 0),
            probe: Some(Probe {
                duty: PROBE_START_DUTY,
                ..Probe::default()
            }),
            lines: [Line::default(); 2],
            levels: [[0.0; 3]; 2],
            m_per_tick,
            min_counts: (min(m_per_tick.0), min(m_per_tick.1)),
            max_counts: (max(m_per_tick.0), max(m_per_tick.1)),
            pass: 0,
            segment: 0,
            done_in_segment: 0,
            started: false,
            previous: (None, None),
            tail: (0, 0),
            block_periods,
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

    /// Periods of segment `s`: its duration at the control rate.
    fn segment_periods(&self, s: Segment) -> u32 {
        self.periods(match s {
            Segment::Level(_) => LEVEL_MS,
            Segment::Coast => COAST_MS,
            Segment::Brake => BRAKE_MS,
        })
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

    /// Periods of `ms` at the control rate, rounded, at least 4 (integers: the control period
    /// calls this).
    fn periods(&self, ms: u32) -> u32 {
        // ≤ 500 ms × 10 kHz: far inside u32 (saturating all the same).
        (ms.saturating_mul(self.rate_hz).saturating_add(500) / 1000).max(4)
    }

    /// One period: `dr`, `dl` are the counts of the period that just ended (during which the
    /// previous step's command was applied).
    pub fn step(&mut self, dr: i64, dl: i64) -> IdentifyStep {
        if self.is_finished() {
            return IdentifyStep::Finished;
        }
        if self.started
            && let Some(f) = self.supervise(dr, dl)
        {
            return IdentifyStep::Failed(f);
        }
        if self.probe.is_some() {
            match self.step_probe(dr, dl) {
                Some(command) => return command,
                // The probe's brake is over: the steps start now (these counts were the brake's).
                None => self.started = false,
            }
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
                    if self.mode == IdentifyMode::Lifted && self.pass == 2 {
                        // The left wheel gets its own probe.
                        self.probe = Some(Probe {
                            duty: PROBE_START_DUTY,
                            ..Probe::default()
                        });
                    }
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
        let ((r, l), dir) = self.pass_shape();
        if let Some(p) = self.probe {
            return IdentifyStep::Duty(if r { p.duty } else { 0.0 }, if l { p.duty } else { 0.0 });
        }
        self.done_in_segment += 1;
        match SEGMENTS[self.segment % SEGMENTS.len()] {
            Segment::Level(i) => {
                let duty = |w: usize| {
                    let d = self.levels[w][i];
                    if dir == 0 { d } else { -d }
                };
                IdentifyStep::Duty(if r { duty(0) } else { 0.0 }, if l { duty(1) } else { 0.0 })
            }
            Segment::Coast => IdentifyStep::Stop(StopMode::Coast),
            Segment::Brake => IdentifyStep::Stop(StopMode::Brake),
        }
    }

    /// The counts of periods the board missed beyond the share the next [`Self::step`] is
    /// given (the controller hands each step one period's share of a catch-up): they count
    /// toward the travel bound, which the next step checks.
    pub fn catch_up(&mut self, dr: i64, dl: i64) {
        if self.started {
            self.travel.0 += dr;
            self.travel.1 += dl;
        }
    }

    /// The checks of every period, probe and steps alike: no wheel faster than the encoder
    /// can follow ([`MAX_SPEED_MPS`] per period), and on the floor the robot no farther than
    /// [`TRAVEL_LIMIT_M`] from where it started.
    fn supervise(&mut self, dr: i64, dl: i64) -> Option<IdentifyFailure> {
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
        self.travel.0 += dr;
        self.travel.1 += dl;
        if self.mode == IdentifyMode::Floor {
            let right = self.travel.0 as f64 * self.m_per_tick.0;
            let left = self.travel.1 as f64 * self.m_per_tick.1;
            // Where it would come to rest if stopped now: a bound, not a trigger.
            let speed = self.centre_speed(dr, dl);
            if libm::fabs(0.5 * (right + left)) + libm::fabs(speed) * STOP_TIME_S > TRAVEL_LIMIT_M {
                let wheel = if libm::fabs(right) >= libm::fabs(left) {
                    Wheel::Right
                } else {
                    Wheel::Left
                };
                return Some(IdentifyFailure {
                    wheel,
                    problem: IdentifyProblem::TooFar,
                });
            }
        }
        None
    }

    /// The robot's speed from one period's counts, m/s.
    fn centre_speed(&self, dr: i64, dl: i64) -> f64 {
        0.5 * (dr as f64 * self.m_per_tick.0 + dl as f64 * self.m_per_tick.1)
            * f64::from(self.rate_hz)
    }

    /// The robot's distance from the start (signed, forward positive), m.
    fn position_m(&self) -> f64 {
        0.5 * (self.travel.0 as f64 * self.m_per_tick.0 + self.travel.1 as f64 * self.m_per_tick.1)
    }

    /// A whole block's counts faster than the cap (plus its margin) on a driven wheel.
    fn over_cap(&self, block: (i64, i64)) -> Option<IdentifyFailure> {
        for (wheel, c, limit) in [
            (Wheel::Right, block.0, self.block_cap_counts.0),
            (Wheel::Left, block.1, self.block_cap_counts.1),
        ] {
            if c.abs() > limit {
                return Some(IdentifyFailure {
                    wheel,
                    problem: IdentifyProblem::TooFast,
                });
            }
        }
        None
    }

    /// One period of the probe: the staircase (forward, [`PROBE_STEP_DUTY`] every
    /// [`PROBE_STAIR_MS`]) until every driven wheel has moved at two stairs and reached
    /// [`PROBE_END_FRACTION`] of the cap, then a brake to rest. `None` when the brake is over.
    fn step_probe(&mut self, dr: i64, dl: i64) -> Option<IdentifyStep> {
        let mut probe = self.probe?;
        let ((on_r, on_l), _) = self.pass_shape();
        let drive =
            |d: f32| IdentifyStep::Duty(if on_r { d } else { 0.0 }, if on_l { d } else { 0.0 });
        if !self.started {
            self.started = true;
            return Some(drive(probe.duty));
        }
        probe.periods += 1;
        if probe.braking {
            if probe.periods >= self.periods(BRAKE_MS) {
                self.probe = None;
                self.block = (0, 0);
                self.in_block = 0;
                return None;
            }
            self.probe = Some(probe);
            return Some(IdentifyStep::Stop(StopMode::Brake));
        }
        self.block.0 += dr;
        self.block.1 += dl;
        self.in_block += 1;
        if self.in_block >= self.block_periods {
            if let Some(f) = self.over_cap(self.block) {
                return Some(IdentifyStep::Failed(f));
            }
            probe.last_block = self.block;
            self.block = (0, 0);
            self.in_block = 0;
        }
        if probe.periods < self.periods(PROBE_STAIR_MS) {
            self.probe = Some(probe);
            return Some(drive(probe.duty));
        }
        // The stair is over: judge its last block.
        let block_s = f64::from(self.block_periods) / f64::from(self.rate_hz);
        let speed = |c: i64, m: f64| c as f64 * m / block_s;
        let (vr, vl) = (
            speed(probe.last_block.0, self.m_per_tick.0),
            speed(probe.last_block.1, self.m_per_tick.1),
        );
        // Moving: 2 % of the cap, and at least three counts per block (the quantisation).
        let motion =
            (3.0 * self.m_per_tick.0.max(self.m_per_tick.1) / block_s).max(0.02 * self.cap_mps);
        let lifted = self.mode == IdentifyMode::Lifted;
        let mut moving = true;
        let mut reached = true;
        let mut slowest = (Wheel::Right, f64::INFINITY);
        for (wheel, on, own, other) in [(Wheel::Right, on_r, vr, vl), (Wheel::Left, on_l, vl, vr)] {
            if !on {
                continue;
            }
            let fail = |problem| Some(IdentifyStep::Failed(IdentifyFailure { wheel, problem }));
            if lifted && libm::fabs(other) > libm::fabs(own).max(motion) {
                return fail(IdentifyProblem::CrossWired);
            }
            if own <= -motion {
                return fail(IdentifyProblem::Reversed);
            }
            moving &= own >= motion;
            reached &= own >= PROBE_END_FRACTION * self.cap_mps;
            if own < slowest.1 {
                slowest = (wheel, own);
            }
        }
        // On the floor a probe that used its share of the travel ends at a stair that moved.
        let far = self.mode == IdentifyMode::Floor
            && moving
            && libm::fabs(self.position_m()) >= PROBE_TRAVEL_M;
        if (reached || far)
            && let Some((d1, b1)) = probe.moving
        {
            let v1 = (
                speed(b1.0, self.m_per_tick.0),
                speed(b1.1, self.m_per_tick.1),
            );
            if let Err(f) = self.choose_levels((on_r, on_l), (d1, v1), (probe.duty, (vr, vl))) {
                return Some(IdentifyStep::Failed(f));
            }
            probe.braking = true;
            probe.periods = 0;
            self.probe = Some(probe);
            return Some(IdentifyStep::Stop(StopMode::Brake));
        }
        if moving {
            probe.moving = Some((probe.duty, probe.last_block));
        }
        probe.duty += PROBE_STEP_DUTY;
        probe.periods = 0;
        if probe.duty > 1.0 {
            return Some(IdentifyStep::Failed(IdentifyFailure {
                wheel: slowest.0,
                problem: IdentifyProblem::NoMotion,
            }));
        }
        self.probe = Some(probe);
        Some(drive(probe.duty))
    }

    /// The speed the steps take [`LEVEL_FRACTIONS`] of, m/s: the cap, and on the floor at most
    /// what keeps a pass within the travel left (from where the probe's brake ends, at most
    /// [`STOP_TIME_S`] at the probe's speed away): the steps of [`LEVEL_MS`] each, then the
    /// coast with no deceleration counted and a stop from the top step's speed.
    fn step_cap_mps(&self, probe_speed: f64) -> f64 {
        if self.mode != IdentifyMode::Floor {
            return self.cap_mps;
        }
        let left =
            TRAVEL_LIMIT_M - libm::fabs(self.position_m()) - libm::fabs(probe_speed) * STOP_TIME_S;
        let level_s = f64::from(LEVEL_MS) / 1000.0;
        let stop_s = f64::from(COAST_MS) / 1000.0 + STOP_TIME_S;
        let per_mps = LEVEL_FRACTIONS.iter().sum::<f64>() * level_s + LEVEL_FRACTIONS[2] * stop_s;
        self.cap_mps.min(left.max(0.0) / per_mps)
    }

    /// The probe's line per driven wheel through its last two stairs, and the duty steps that
    /// give [`LEVEL_FRACTIONS`] of the step cap on it ([`Self::step_cap_mps`]; on the floor one
    /// duty for both wheels: the smaller, so the faster wheel stays within the cap).
    fn choose_levels(
        &mut self,
        (on_r, on_l): (bool, bool),
        (d1, v1): (f32, (f64, f64)),
        (d2, v2): (f32, (f64, f64)),
    ) -> Result<(), IdentifyFailure> {
        let mut levels = [1.0f32; 3];
        let cap = self.step_cap_mps(0.5 * (v2.0 + v2.1));
        for (w, wheel, on, a, b) in [
            (0usize, Wheel::Right, on_r, v1.0, v2.0),
            (1, Wheel::Left, on_l, v1.1, v2.1),
        ] {
            if !on {
                continue;
            }
            let gain = (b - a) / f64::from(d2 - d1);
            if !(gain > 0.0 && gain.is_finite()) {
                return Err(IdentifyFailure {
                    wheel,
                    problem: IdentifyProblem::Implausible,
                });
            }
            let line = Line {
                gain,
                deadband: f64::from(d2) - b / gain,
            };
            self.lines[w] = line;
            for (level, f) in levels.iter_mut().zip(LEVEL_FRACTIONS) {
                let d = (line.deadband + f * cap / gain) as f32;
                *level = level.min(d);
            }
        }
        // Increasing, at least one probe stair apart, within full duty.
        let mut floor = PROBE_START_DUTY;
        for level in &mut levels {
            *level = level.max(floor).min(1.0);
            floor = *level + PROBE_STEP_DUTY;
        }
        for (w, on) in [(0usize, on_r), (1, on_l)] {
            if on {
                self.levels[w] = levels;
            }
        }
        Ok(())
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
        self.block.0 += dr;
        self.block.1 += dl;
        self.in_block += 1;
        if self.in_block < self.block_periods {
            return None;
        }
        let (br, bl) = self.block;
        if let Some(f) = self.over_cap(self.block) {
            return Some(f);
        }
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
        let Segment::Level(level) = seg else {
            return None;
        };
        let periods = self.segment_periods(seg);
        let tail_s = f64::from(periods - periods * 3 / 4) / f64::from(self.rate_hz);
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
            // The open loop's following error: the step's speed against the probe's line.
            let w = usize::from(wheel == Wheel::Left);
            let m = if w == 0 {
                self.m_per_tick.0
            } else {
                self.m_per_tick.1
            };
            let measured = own.abs() as f64 * m / tail_s;
            let predicted = self.lines[w].speed(f64::from(self.levels[w][level]));
            if predicted > 0.0 && libm::fabs(measured - predicted) > RESPONSE_TOLERANCE * predicted
            {
                return fail(IdentifyProblem::Changed);
            }
        }
        None
    }
}

//! Motor identification: each wheel's plant for the speed loop ([`MotorParams`]), measured on
//! the robot.
//!
//! Driven by the controller at the control rate, open loop (no speed loop, no following-error
//! check; the stall and encoder-glitch checks stay on). Per direction (forward, then backward)
//! a *pass* applies three duty steps ([`LEVELS`], [`LEVEL_MS`] each), then lets the wheel coast
//! ([`COAST_MS`]) and brakes it to rest ([`BRAKE_MS`]). With the wheels off the ground
//! ([`IdentifyMode::Lifted`]) each wheel has its own passes, right first, and the other wheel
//! must stay still; on the floor ([`IdentifyMode::Floor`]) both wheels get the same duty, so the
//! robot drives forward and back.
//!
//! **Fit, online, decimated.** The encoder is read every period and its counts are summed over
//! blocks of [`BLOCK_MS`] (10 periods at 1 kHz); nothing is logged: the segment being driven
//! keeps exact integer sums of the pairs `(s_j, s_{j+1})` of successive block counts, and a
//! finished duty step only its means and centred moments, so the RAM is fixed (0.3 KiB for both
//! wheels) whatever the rate and length. For a
//! first-order motor with the duty held (zero-order hold), the block counts obey exactly
//! `s_{j+1} = a·s_j + (1 − a)·v_ss` within a step (blocks start with the step, so none mixes two
//! duties), with `a = e^{−T/τ}` for the block length `T` and `v_ss` the step's steady count per
//! block. Blocks rather than single periods: the encoder's quantisation makes successive counts
//! anti-correlated, which biases the slope by about `1/(12·var(s))`; at one period that is 20 %
//! of `1 − a` for a 120 ms motor, over 10-period blocks it is below 1e-4 of it. One common slope `a` is fitted to all six steps of a wheel (least
//! squares with one intercept per step), which gives `τ`, each step's `v_ss`, and the
//! residual. The steady speeds against the duty are then a straight line per direction,
//! `|v_ss| = K·(|duty| − d₀)`: its slope is the gain `K` of that direction, its zero crossing
//! the dead-band `d₀`. The coast is fitted the same way (`s_{k+1} = a_c·s_k + c`, a viscous and
//! a constant friction term) and reported as the deceleration from the top step's speed.
//!
//! **Fit, outside the control period.** The period in which the last segment ends only closes
//! it and returns [`IdentifyStep::Finished`]: the statistics stay where they are, frozen, and the
//! motors stop. The fit ([`Identify::fit`]: a few `log`, `sqrt` and divisions per wheel in `f64`,
//! about 52,000 instructions of soft-float on the Cortex-M4F, more than three 10 kHz periods) runs when the
//! report is taken ([`crate::motion::controller::Controller::take_check_report`]), in the task
//! that takes it, at a lower priority than the control task.
//!
//! **Plausibility.** The routine stops the motors and reports a [`IdentifyFailure`] (the
//! controller latches it as a fault) when a step shows no motion, counts against the duty (a
//! reversed motor or encoder: the bring-up check's finding), motion of the other wheel's
//! encoder instead (lifted: swapped wiring), a speed beyond [`MAX_SPEED_MPS`], a top step that
//! gains less than 70 % of the speed the lower steps predict (saturation: supply or current
//! limit), or a fit that does not describe the response (residual above 5 % of the top speed,
//! `a` outside (0, 1), parameters outside [`MotorParams::validate`]'s ranges).

use crate::motion::motor::StopMode;
use crate::motion::speed::MotorParams;
use crate::motion::wheel::Wheel;
use crate::util::num::{ceil_i64, fmax, round_u32};

/// The duty steps of a pass, in order (magnitudes). The lowest must exceed the dead-band and
/// the stall check's 0.1.
pub const LEVELS: [f32; 3] = [0.2, 0.35, 0.5];
/// Length of one duty step, ms (2.7 time constants of a 150 ms motor; the fit needs the
/// transient, not the steady state).
pub const LEVEL_MS: u32 = 400;
/// Coasting after the steps, ms.
pub const COAST_MS: u32 = 500;
/// Braking to rest before the next pass, ms.
pub const BRAKE_MS: u32 = 300;
/// Length of the blocks the counts are summed over for the fit, ms.
pub const BLOCK_MS: u32 = 10;
/// Fastest wheel speed the routine allows, m/s (below the encoder glitch limit of 3 m/s).
pub const MAX_SPEED_MPS: f64 = 2.0;
/// Smallest wheel travel in the last quarter of a step that counts as motion, m.
pub const MIN_MOTION_M: f64 = 0.001;
/// Largest fit residual (RMS of the one-period prediction) against the top step's speed.
pub const MAX_RELATIVE_RESIDUAL: f64 = 0.05;
/// Smallest gain of the top step against the lower steps' slope (below: saturation).
pub const MIN_TOP_SLOPE_RATIO: f64 = 0.7;

/// Where the robot is during the identification (the operator's choice).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum IdentifyMode {
    /// Wheels off the ground: each wheel in turn, the other one must stay still.
    Lifted,
    /// On the floor: both wheels at once, the robot drives forward and back.
    Floor,
}

impl IdentifyMode {
    /// Passes (forward and backward per wheel, or per robot on the floor).
    pub fn passes(self) -> usize {
        match self {
            IdentifyMode::Lifted => 4,
            IdentifyMode::Floor => 2,
        }
    }

    /// Total length, ms.
    pub fn duration_ms(self) -> u32 {
        self.passes() as u32 * (LEVELS.len() as u32 * LEVEL_MS + COAST_MS + BRAKE_MS)
    }
}

/// What was wrong with a wheel's response.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum IdentifyProblem {
    /// The wheel did not move at a duty step.
    NoMotion,
    /// The wheel's counts ran against the duty: motor or encoder reversed.
    Reversed,
    /// The other wheel's encoder moved more than this one's (lifted): swapped wiring.
    CrossWired,
    /// The top duty step gained too little speed: supply or current limit.
    Saturated,
    /// The wheel turned faster than [`MAX_SPEED_MPS`].
    TooFast,
    /// The first-order model does not describe the response (noisy, slipping, out of range).
    Implausible,
    /// The stall check latched (no count at a commanded duty for its time).
    Stalled,
    /// An encoder counter jumped.
    EncoderGlitch,
}

impl IdentifyProblem {
    /// What the operator reads.
    pub fn describe(self) -> &'static str {
        match self {
            IdentifyProblem::NoMotion | IdentifyProblem::Stalled => {
                "no motion: check motor power, the encoder, that the wheel is free, and a dead-band below 20 % duty"
            }
            IdentifyProblem::Reversed => {
                "counts run against the duty: motor or encoder reversed (run bringup)"
            }
            IdentifyProblem::CrossWired => {
                "the other wheel's encoder moved: motors or encoders swapped between the sides (run bringup)"
            }
            IdentifyProblem::Saturated => {
                "speed saturates at the top duty step: check the motor supply and current limit"
            }
            IdentifyProblem::TooFast => "wheel faster than 2 m/s: motor too strong for the steps",
            IdentifyProblem::Implausible => {
                "response not a first-order motor (slipping, loose coupling, noisy encoder)"
            }
            IdentifyProblem::EncoderGlitch => "encoder counter jumped",
        }
    }
}

/// Why an identification ended without a result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct IdentifyFailure {
    /// The wheel.
    pub wheel: Wheel,
    /// What was wrong.
    pub problem: IdentifyProblem,
}

/// One wheel's identified plant.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct MotorFit {
    /// The plant for the speed loop.
    pub params: MotorParams,
    /// Deceleration when coasting from `coast_from_mps` (mean of both directions), m/s².
    pub coast_decel_mps2: f32,
    /// Speed the coast deceleration refers to (the top step's, mean of both directions), m/s.
    pub coast_from_mps: f32,
    /// RMS residual of the one-period speed prediction, m/s.
    pub residual_mps: f32,
}

/// A finished identification.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct IdentifyReport {
    /// Where the robot was.
    pub mode: IdentifyMode,
    /// Right motor.
    pub right: MotorFit,
    /// Left motor.
    pub left: MotorFit,
}

/// Exact integer sums of the block pairs `(x, y)` of the segment being driven.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Running {
    n: u32,
    sx: i64,
    sy: i64,
    sxx: i64,
    sxy: i64,
    syy: i64,
}

/// Means and centred second moments of a segment's pairs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Moments {
    n: f64,
    mx: f64,
    my: f64,
    cxx: f64,
    cxy: f64,
    cyy: f64,
}

impl Running {
    fn add(&mut self, x: i64, y: i64) {
        self.n += 1;
        self.sx += x;
        self.sy += y;
        // A block count is below 2 m/s for 10 ms (the routine stops faster wheels), so the
        // sums of products stay far inside i64; saturating all the same.
        self.sxx = self.sxx.saturating_add(x.saturating_mul(x));
        self.sxy = self.sxy.saturating_add(x.saturating_mul(y));
        self.syy = self.syy.saturating_add(y.saturating_mul(y));
    }

    fn moments(&self) -> Moments {
        if self.n == 0 {
            return Moments::default();
        }
        let n = f64::from(self.n);
        let (sx, sy) = (self.sx as f64, self.sy as f64);
        Moments {
            n,
            mx: sx / n,
            my: sy / n,
            cxx: self.sxx as f64 - sx * sx / n,
            cxy: self.sxy as f64 - sx * sy / n,
            cyy: self.syy as f64 - sy * sy / n,
        }
    }
}

/// What is kept of one wheel: the running sums of the current segment, and of each finished
/// segment only what the fit needs (160 B per wheel).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct WheelLog {
    running: Running,
    /// Centred moments `(Σxx, Σxy, Σyy)` of all duty steps, each about its own means.
    pooled: (f64, f64, f64),
    /// Pairs and steps in `pooled`.
    pairs: u32,
    steps: u32,
    /// Means `(x̄, ȳ)` of each duty step, per direction.
    step_means: [[(f32, f32); 3]; 2],
    /// Coast per direction: `Σxx`, `Σxy` (centred), `x̄`, `ȳ`.
    coast: [[f32; 4]; 2],
}

impl WheelLog {
    /// Keeps what the fit needs of the finished `seg` of direction `dir`, and clears the sums.
    /// Once per finished segment, not per period; `f64` because the centred moments subtract
    /// sums of squares (up to ~1e10 over a step's blocks) whose difference `f32` would keep to a
    /// few digits.
    fn close(&mut self, seg: Segment, dir: usize) {
        let m = self.running.moments();
        self.running = Running::default();
        match seg {
            Segment::Level(i) => {
                if m.n < 2.0 {
                    return;
                }
                self.pooled.0 += m.cxx;
                self.pooled.1 += m.cxy;
                self.pooled.2 += m.cyy;
                self.pairs += m.n as u32;
                self.steps += 1;
                if let Some(s) = self.step_means.get_mut(dir).and_then(|d| d.get_mut(i)) {
                    *s = (m.mx as f32, m.my as f32);
                }
            }
            Segment::Coast => {
                if let Some(c) = self.coast.get_mut(dir) {
                    *c = [m.cxx as f32, m.cxy as f32, m.mx as f32, m.my as f32];
                }
            }
            Segment::Brake => {}
        }
    }
}

/// The segments of a pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Segment {
    Level(usize),
    Coast,
    Brake,
}

const SEGMENTS: [Segment; 5] = [
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

/// The identification routine (see the module docs); stepped once per control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identify {
    mode: IdentifyMode,
    rate_hz: u32,
    /// Metres per count, per wheel (right, left).
    m_per_tick: (f64, f64),
    /// Counts in the last quarter of a step that are motion, per wheel.
    min_counts: (i64, i64),
    /// Counts per period that exceed [`MAX_SPEED_MPS`], per wheel.
    max_counts: (i64, i64),
    pass: usize,
    segment: usize,
    /// Periods the current segment's command has been applied (the one whose counts arrive
    /// next included).
    done_in_segment: u32,
    started: bool,
    /// The previous period's counts within this segment, per wheel.
    previous: (Option<i64>, Option<i64>),
    /// Counts in the last quarter of the current step: (right, left).
    tail: (i64, i64),
    /// Periods per block.
    block_periods: u32,
    /// Counts of the block being summed (right, left) and its periods so far.
    block: (i64, i64),
    in_block: u32,
    /// Statistics per wheel (right, left).
    logs: [WheelLog; 2],
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

    /// The fit of both wheels (see the module docs) from the statistics of a finished
    /// identification ([`Identify::is_finished`]), where they are: a report with both motors'
    /// parameters, or the failure the fit detects (slope, residual, saturation, parameters out of
    /// range). Not for the control period: about 52,000 instructions of soft-float `f64` and
    /// `libm` on the Cortex-M4F.
    ///
    /// # Errors
    /// The wheel and [`IdentifyProblem`] when the fit does not describe a plausible motor;
    /// [`IdentifyProblem::Implausible`] (right wheel) for an identification not finished yet,
    /// whose statistics are incomplete.
    pub fn fit(&self) -> Result<IdentifyReport, IdentifyFailure> {
        if !self.is_finished() {
            return Err(IdentifyFailure {
                wheel: Wheel::Right,
                problem: IdentifyProblem::Implausible,
            });
        }
        let block_hz = f64::from(self.rate_hz) / f64::from(self.block_periods);
        Ok(IdentifyReport {
            mode: self.mode,
            right: fit_wheel(&self.logs[0], self.m_per_tick.0 * block_hz, block_hz).map_err(
                |problem| IdentifyFailure {
                    wheel: Wheel::Right,
                    problem,
                },
            )?,
            left: fit_wheel(&self.logs[1], self.m_per_tick.1 * block_hz, block_hz).map_err(
                |problem| IdentifyFailure {
                    wheel: Wheel::Left,
                    problem,
                },
            )?,
        })
    }
}

/// Fits one wheel's two directions; `mps_per_count` converts counts per block to m/s,
/// `block_hz` is the block rate.
fn fit_wheel(
    log: &WheelLog,
    mps_per_count: f64,
    block_hz: f64,
) -> Result<MotorFit, IdentifyProblem> {
    let bad = IdentifyProblem::Implausible;
    // Common slope over the six steps, one intercept per step.
    let (cxx, cxy, cyy) = log.pooled;
    let (n, groups) = (f64::from(log.pairs), f64::from(log.steps));
    if cxx <= 0.0 || n <= groups + 1.0 {
        return Err(bad);
    }
    let a = cxy / cxx;
    if !(a > 0.0 && a < 1.0) {
        return Err(bad);
    }
    let residual = libm::sqrt(fmax(cyy - a * cxy, 0.0) / (n - groups - 1.0)) * mps_per_count;
    let tau = -1.0 / (block_hz * libm::log(a));
    let mut gains = [0.0f64; 2];
    let mut deadbands = [0.0f64; 2];
    let mut top = 0.0f64;
    let mut coast = 0.0f64;
    let mut coast_from = 0.0f64;
    for (d, (means, c)) in log.step_means.iter().zip(log.coast.iter()).enumerate() {
        // Steady speed of each step, m/s (magnitude: the sign was checked per step).
        let v = means.map(|(mx, my)| {
            libm::fabs((f64::from(my) - a * f64::from(mx)) / (1.0 - a)) * mps_per_count
        });
        let u = LEVELS.map(f64::from);
        let slope_lo = (v[1] - v[0]) / (u[1] - u[0]);
        let slope_hi = (v[2] - v[1]) / (u[2] - u[1]);
        if slope_lo.is_nan() || slope_lo <= 0.0 {
            return Err(bad);
        }
        if slope_hi < MIN_TOP_SLOPE_RATIO * slope_lo {
            return Err(IdentifyProblem::Saturated);
        }
        // Least-squares line through the three steps: |v| = K (u − d0).
        let (um, vm) = ((u[0] + u[1] + u[2]) / 3.0, (v[0] + v[1] + v[2]) / 3.0);
        let (mut suu, mut suv) = (0.0, 0.0);
        for i in 0..3 {
            suu += (u[i] - um) * (u[i] - um);
            suv += (u[i] - um) * (v[i] - vm);
        }
        let k = suv / suu;
        gains[d] = k;
        deadbands[d] = um - vm / k;
        top = fmax(top, v[2]);
        // Coast from the top step's speed, as a deceleration.
        let [xx, xy, mx, my] = c.map(f64::from);
        if xx <= 0.0 {
            return Err(bad);
        }
        let ac = xy / xx;
        if !(ac > 0.0 && ac < 1.0) {
            return Err(bad);
        }
        // dv/dt = −(v − v∞)/τ_c: v∞ (the fixed point, beyond zero with constant friction)
        // and τ_c are the same for the block sums as for the continuous speed.
        let v_inf = (my - ac * mx) / (1.0 - ac);
        let tau_c = -1.0 / (block_hz * libm::log(ac));
        let sign = if d == 0 { 1.0 } else { -1.0 };
        let v0 = sign * v[2] / mps_per_count;
        coast += 0.5 * sign * (v0 - v_inf) * mps_per_count / tau_c;
        coast_from += 0.5 * v[2];
    }
    if residual > MAX_RELATIVE_RESIDUAL * top {
        return Err(bad);
    }
    // A dead-band estimate a little below zero is noise on a motor without one.
    let deadband = 0.5 * (deadbands[0] + deadbands[1]);
    if deadband < -0.02 {
        return Err(bad);
    }
    let params = MotorParams {
        gain_forward_mps: gains[0] as f32,
        gain_backward_mps: gains[1] as f32,
        time_constant_s: tau as f32,
        deadband: fmax(deadband, 0.0) as f32,
    };
    params.validate().map_err(|_| bad)?;
    Ok(MotorFit {
        params,
        coast_decel_mps2: coast as f32,
        coast_from_mps: coast_from as f32,
        residual_mps: residual as f32,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const M_PER_TICK: f64 = core::f64::consts::PI * 0.15 / 200_000.0;

    /// A lifted wheel pair with first-order motors `(K_fwd, K_back, τ, d0)` per wheel (m/s per
    /// duty), integrated exactly over each period (10 sub-steps are not needed: the duty is
    /// constant over a period), encoder floor-quantised; `sign` = −1 reverses a wheel's counts.
    /// The result: the fit of the finished identification, or the failure a period reported.
    fn run(
        mode: IdentifyMode,
        motors: [(f64, f64, f64, f64); 2],
        sign: [i64; 2],
    ) -> Result<IdentifyReport, IdentifyFailure> {
        let rate = 1000u32;
        let dt = 1e-3;
        let mut id = Identify::new(mode, rate, (M_PER_TICK, M_PER_TICK));
        let mut v = [0.0f64; 2];
        let mut pos = [0.0f64; 2];
        let mut counted = [0i64; 2];
        let (mut dr, mut dl) = (0, 0);
        for _ in 0..20 * rate {
            let step = id.step(dr, dl);
            let (duty, tau_scale) = match step {
                IdentifyStep::Duty(r, l) => ([f64::from(r), f64::from(l)], 1.0),
                IdentifyStep::Stop(StopMode::Coast) => ([0.0; 2], 4.0),
                IdentifyStep::Stop(StopMode::Brake) => ([0.0; 2], 0.5),
                IdentifyStep::Failed(f) => return Err(f),
                IdentifyStep::Finished => {
                    assert!(id.is_finished());
                    // Frozen: stepping again changes nothing.
                    let frozen = id;
                    assert_eq!(id.step(dr, dl), IdentifyStep::Finished);
                    assert_eq!(id, frozen);
                    return id.fit();
                }
            };
            let mut d = [0i64; 2];
            for w in 0..2 {
                let (kf, kb, tau, d0) = motors[w];
                let u = duty[w];
                let eff = if u.abs() > d0 {
                    u - d0.copysign(u)
                } else {
                    0.0
                };
                let target = eff * if eff >= 0.0 { kf } else { kb } / M_PER_TICK;
                let tau = tau * tau_scale;
                let e = (-dt / tau).exp();
                pos[w] += target * dt + (v[w] - target) * tau * (1.0 - e);
                v[w] = target + (v[w] - target) * e;
                let c = pos[w].floor() as i64;
                d[w] = (c - counted[w]) * sign[w];
                counted[w] = c;
            }
            (dr, dl) = (d[0], d[1]);
        }
        panic!("the identification did not end");
    }

    #[test]
    fn lifted_identification_recovers_both_motors() {
        let motors = [(0.5, 0.45, 0.12, 0.05), (2.0, 2.1, 0.025, 0.08)];
        let r = run(IdentifyMode::Lifted, motors, [1, 1]).expect("a plausible fit");
        for (fit, (kf, kb, tau, d0)) in [(r.right, motors[0]), (r.left, motors[1])] {
            let p = fit.params;
            // Exact plant, 1 kHz, only the encoder's quantisation (2.4 µm) as noise: every
            // parameter within 1 % (the bound is 5 %).
            let close = |est: f32, truth: f64| (f64::from(est) - truth).abs() <= 0.01 * truth;
            assert!(close(p.gain_forward_mps, kf), "{p:?}");
            assert!(close(p.gain_backward_mps, kb), "{p:?}");
            assert!(close(p.time_constant_s, tau), "{p:?}");
            assert!(close(p.deadband, d0), "{p:?}");
            // Coasting with τ_c = 4τ from the top speed v: v/τ_c (no constant friction here).
            let decel = f64::from(fit.coast_from_mps) / (4.0 * tau);
            assert!(
                (f64::from(fit.coast_decel_mps2) - decel).abs() < 0.02 * decel,
                "{fit:?}"
            );
        }
    }

    #[test]
    fn reversed_and_silent_wheels_fail() {
        let ok = (1.0, 1.0, 0.05, 0.0);
        let f = run(IdentifyMode::Floor, [ok, ok], [1, -1]);
        assert_eq!(
            f,
            Err(IdentifyFailure {
                wheel: Wheel::Left,
                problem: IdentifyProblem::Reversed
            })
        );
        let dead = (1.0, 1.0, 0.05, 0.3);
        let f = run(IdentifyMode::Lifted, [dead, ok], [1, 1]);
        assert_eq!(
            f,
            Err(IdentifyFailure {
                wheel: Wheel::Right,
                problem: IdentifyProblem::NoMotion
            })
        );
        // 5 m/s at full duty: the top step would run at 2.5 m/s.
        let fast = (5.0, 5.0, 0.05, 0.0);
        let f = run(IdentifyMode::Lifted, [fast, ok], [1, 1]);
        assert!(
            matches!(
                f,
                Err(IdentifyFailure {
                    problem: IdentifyProblem::TooFast,
                    ..
                })
            ),
            "{f:?}"
        );
    }

    #[test]
    fn a_saturating_motor_is_refused() {
        // A line through the first two steps, then almost no gain: the supply limits.
        let mut id = Identify::new(IdentifyMode::Floor, 1000, (M_PER_TICK, M_PER_TICK));
        let (mut dr, mut dl) = (0i64, 0i64);
        let mut v = 0.0f64;
        for _ in 0..20_000 {
            let duty = match id.step(dr, dl) {
                IdentifyStep::Duty(r, _) => f64::from(r),
                IdentifyStep::Stop(_) => 0.0,
                // Saturation is the fit's finding: every duty step moved the wheel.
                IdentifyStep::Finished => {
                    let f = id.fit();
                    assert!(
                        matches!(
                            f,
                            Err(IdentifyFailure {
                                problem: IdentifyProblem::Saturated,
                                ..
                            })
                        ),
                        "{f:?}"
                    );
                    return;
                }
                other => panic!("{other:?}"),
            };
            // Until the last segment ends the statistics are incomplete: no fit.
            assert_eq!(
                id.fit(),
                Err(IdentifyFailure {
                    wheel: Wheel::Right,
                    problem: IdentifyProblem::Implausible
                })
            );
            let capped = duty.clamp(-0.37, 0.37);
            let target = capped / M_PER_TICK;
            v = target + (v - target) * (-1e-3f64 / 0.05).exp();
            dr = (v * 1e-3).round() as i64;
            dl = dr;
        }
        panic!("the identification did not end");
    }
}

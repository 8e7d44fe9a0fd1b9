//! The mode state machine: idle, a routine run, velocity driving with a deadman, or a bring-up
//! check; starting, aborting and finishing them, and the button's actions.

use core::fmt;

use super::{Controller, Fault, MotorCommand, Tracking, WheelScale};

use crate::kinematics::angle::Angle;
use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::odometry::{Pose, metres};
use crate::kinematics::reference::PoseF64;
use crate::motion::bringup::{CheckKind, CheckReport, PulseCheck, PulseStep, PushCheck};
use crate::motion::button::Press;
use crate::motion::identify::{Identify, IdentifyFailure, IdentifyReport, IdentifyStep};
use crate::motion::motor::StopMode;
use crate::motion::path::{PathError, validate_path};
use crate::motion::routine::{Routine, RunPlan};
use crate::motion::run::{PathKind, RunRecord};
use crate::motion::speed::WheelReference;
use crate::util::num::clamp;

/// Why a run was not started.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum StartError {
    /// A run or velocity drive is active.
    Busy,
    /// A fault is latched; clear it first.
    Faulted,
    /// The encoders have not been read yet (no `step` so far).
    NotReady,
    /// The path's size is implausible.
    Path(PathError),
}

impl fmt::Display for StartError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StartError::Busy => f.write_str("busy"),
            StartError::Faulted => f.write_str("fault latched, clear it first"),
            StartError::NotReady => f.write_str("encoders not read yet"),
            StartError::Path(e) => write!(f, "{e}"),
        }
    }
}

/// Why a velocity command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum DriveError {
    /// A routine is running.
    Busy,
    /// A fault is latched; clear it first.
    Faulted,
    /// The encoders have not been read yet.
    NotReady,
    /// A speed is not finite.
    NotFinite,
}

impl fmt::Display for DriveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            DriveError::Busy => "busy",
            DriveError::Faulted => "fault latched, clear it first",
            DriveError::NotReady => "encoders not read yet",
            DriveError::NotFinite => "speeds must be finite",
        })
    }
}

/// What a button press did (see [`Controller::on_press`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum ButtonAction {
    /// A short press started this run.
    Started(PathKind),
    /// A short press could not start a run.
    StartRefused(StartError),
    /// A short press cleared a latched fault (the next short press starts).
    ClearedFault,
    /// A long press aborted any motion.
    Aborted,
}

/// A bring-up check in progress.
///
/// The identification's statistics (0.3 KiB) make its variant the large one; without an
/// allocator there is nothing to box them into, and only one check runs at a time, so the
/// controller holds that space once either way.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum ActiveCheck {
    /// Motor pulses.
    Pulses(PulseCheck),
    /// Hand push.
    Push(PushCheck),
    /// Motor identification: running, or finished and waiting for its fit (its statistics stay
    /// here, frozen, until [`Controller::take_check_report`]).
    Identify(Identify),
}

impl ActiveCheck {
    /// Which check this is.
    pub(super) fn kind(&self) -> CheckKind {
        match self {
            ActiveCheck::Pulses(_) => CheckKind::Pulses,
            ActiveCheck::Push(_) => CheckKind::Push,
            ActiveCheck::Identify(i) => CheckKind::Identify(i.mode()),
        }
    }
}

/// A routine in progress, or complete and waiting for [`Controller::take_finished_run`]: the
/// run stays where it was driven, so completing it costs the control period no copy of its
/// knots and no conversion (the record is built when it is taken).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct ActiveRun {
    pub(super) routine: Routine,
    pub(super) start_totals: WheelTicks,
    /// The run's start frame (origin, heading +x) in the odometry frame.
    pub(super) frame: RunFrame,
    /// The odometry pose (odometry frame) when the path was complete.
    pub(super) end: Pose,
}

impl ActiveRun {
    /// Whether the path is complete.
    pub(super) fn done(&self) -> bool {
        self.routine.is_finished()
    }

    /// The record of a completed run driven with `geometry`.
    fn into_record(self, geometry: Geometry) -> RunRecord {
        RunRecord {
            path: *self.routine.path(),
            geometry,
            odometry_end: self.frame.map(&self.end),
            knots: self.routine.into_knots(),
            measured: None,
        }
    }
}

/// Where a run's start frame lies in the odometry frame: a pose `p` of the odometry is the
/// pose `R(rotation)·p + shift` of the run (heading + rotation).
///
/// The odometry integrates one pose per period (bit-exact fixed point); a run's end pose in its
/// own frame is this map applied once, when the record is built, instead of a second
/// odometry integrated every period. The heading maps exactly (binary angles, wrapping), the
/// position through one `f64` rotation (relative error ~1e-16: 1e-13 m at 1 km from the
/// odometry origin), against the odometry's own 9.1e-13 m resolution per period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct RunFrame {
    rotation: Angle,
    /// Metres, after the rotation.
    shift: (f64, f64),
}

/// `(x, y)` rotated by `a`.
fn rotate(a: Angle, x: f64, y: f64) -> (f64, f64) {
    let (sin, cos) = crate::util::trig::sincos(a.to_radians());
    (cos * x - sin * y, sin * x + cos * y)
}

impl RunFrame {
    /// The frame whose origin is the odometry pose `at`.
    pub(super) fn starting_at(at: &Pose) -> Self {
        let rotation = Angle(at.heading.0.wrapping_neg());
        let (x, y) = rotate(rotation, metres(at.x), metres(at.y));
        RunFrame {
            rotation,
            shift: (-x, -y),
        }
    }

    /// The same frame after the odometry frame was reset at its pose `at` (`at` becomes the
    /// odometry's origin): `R(ρ)·(R(θ)·p + P) + s = R(ρ + θ)·p + (R(ρ)·P + s)`.
    pub(super) fn after_reset(&self, at: &Pose) -> Self {
        let (x, y) = rotate(self.rotation, metres(at.x), metres(at.y));
        RunFrame {
            rotation: Angle(self.rotation.0.wrapping_add(at.heading.0)),
            shift: (x + self.shift.0, y + self.shift.1),
        }
    }

    /// The odometry pose `p` in the run frame.
    pub(super) fn map(&self, p: &Pose) -> PoseF64 {
        let (x, y) = rotate(self.rotation, metres(p.x), metres(p.y));
        PoseF64::new(
            x + self.shift.0,
            y + self.shift.1,
            Angle(p.heading.0.wrapping_add(self.rotation.0)).to_radians(),
        )
    }
}

/// Velocity mode state. `f32`: speeds are bounded by the limits (≤ 5 m/s, ≤ 20 rad/s) and
/// ramped by bounded steps toward a target, never accumulated without bound; a speed's relative
/// error stays a few units of 2⁻²⁴ (< 1 µm/s), and the speed loop integrates the wheels'
/// per-period increments, not positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct DriveState {
    /// Commanded centre speed (m/s) and turn rate (rad/s), clamped to the limits.
    pub(super) target: (f32, f32),
    /// Ramped reference speed and turn rate at the previous and at the current step.
    pub(super) previous: (f32, f32),
    /// See `previous`.
    pub(super) now: (f32, f32),
    /// Periods left before the deadman stops the motors.
    pub(super) remaining: u32,
}

impl Controller {
    pub(super) fn step_run(&mut self, dr: i64, dl: i64) -> (MotorCommand, Option<Tracking>) {
        let Some(run) = self.run.as_mut().filter(|r| !r.done()) else {
            return (MotorCommand::Stop(self.config.stop_mode), None);
        };
        let since_start = self.totals - run.start_totals;
        let s = run.routine.step(since_start);
        let tracking = Tracking {
            segment: s.segment,
            kind: s.kind,
            error_right_ticks: s.error.0,
            error_left_ticks: s.error.1,
        };
        if s.finished {
            run.end = self.odo_state.pose();
            info!("run finished");
            return (MotorCommand::Stop(self.config.stop_mode), Some(tracking));
        }
        (self.duties(&s.right, &s.left, dr, dl), Some(tracking))
    }

    /// Whether a run is being driven (not complete).
    pub(super) fn driving_run(&self) -> bool {
        self.run.as_ref().is_some_and(|r| !r.done())
    }

    pub(super) fn step_drive(&mut self, dr: i64, dl: i64) -> MotorCommand {
        let rate = self.config.rate_hz as f32;
        let l = &self.config.limits;
        let scales = self.wheel_scales;
        let Some(d) = self.drive.as_mut() else {
            return MotorCommand::Stop(self.config.stop_mode);
        };
        if d.remaining == 0 {
            info!("drive deadman: stopping");
            self.drive = None;
            return MotorCommand::Stop(self.config.stop_mode);
        }
        d.remaining -= 1;
        let ramp =
            |cur: f32, target: f32, max_accel: f32| ramp_toward(cur, target, max_accel, rate);
        // The reference ramps linearly between steps: the period that just ended went from
        // `previous` to `now` (its increment is compared with the encoders'); the one that
        // starts goes from `now` to `next` (its midpoint speed is the feed-forward).
        let (prev, now) = (d.previous, d.now);
        let next = (
            ramp(now.0, d.target.0, l.max_accel_mps2),
            ramp(now.1, d.target.1, l.max_turn_accel_radps2),
        );
        d.previous = now;
        d.now = next;
        // Wheel speed in ticks/s: (v ± ω·b/2) / (m per tick), with both factors per wheel
        // derived when the geometry changes.
        let wheel = |(v, w): (f32, f32), s: &WheelScale| v * s.ticks_per_m + w * s.ticks_per_rad;
        let reference = |s: &WheelScale| {
            let (a, b, c) = (wheel(prev, s), wheel(now, s), wheel(next, s));
            WheelReference {
                delta_ticks: 0.5 * (a + b) / rate,
                velocity_tps: 0.5 * (b + c),
                accel_tps2: (c - b) * rate,
            }
        };
        let r = reference(&scales.0);
        let lf = reference(&scales.1);
        self.duties(&r, &lf, dr, dl)
    }

    /// Starts a run of `path` from the current pose (its start frame is the current pose).
    ///
    /// # Errors
    /// [`StartError`] when busy, faulted, not ready, or the path is implausible.
    pub fn start(&mut self, path: PathKind) -> Result<(), StartError> {
        self.ready_to_start()?;
        validate_path(&path).map_err(StartError::Path)?;
        let routine = Routine::new(
            path,
            &self.config.geometry,
            &self.config.limits,
            self.config.rate_hz,
            self.config.settle,
        )
        .map_err(StartError::Path)?;
        self.stash_finished_run();
        self.run = Some(ActiveRun {
            routine,
            start_totals: self.totals,
            frame: RunFrame::starting_at(&self.odo_state.pose()),
            end: Pose::default(),
        });
        self.reset_loops();
        info!("run started");
        Ok(())
    }

    pub(super) fn reset_loops(&mut self) {
        // A new motion measures from where it starts.
        self.pose_lost = false;
        self.pi_state = Default::default();
        self.stall_count = (0, 0);
        self.last_duty = (0.0, 0.0);
        self.following.reset();
    }

    /// Ends any run or velocity drive; the next step commands a stop. The run is discarded.
    pub fn abort(&mut self) {
        if !self.is_idle() {
            warn!("motion aborted");
        }
        self.discard_driven_run();
        self.drive = None;
        self.end_running_check();
    }

    /// Velocity mode: centre speed `v_mps` and turn rate `w_radps` (CCW positive), each clamped
    /// to the limits and ramped with the acceleration limits. The motors stop `deadman_ms` after
    /// the last call.
    ///
    /// # Errors
    /// [`DriveError`] while a routine runs, a fault is latched, before the first step, or for
    /// non-finite speeds.
    pub fn drive(&mut self, v_mps: f32, w_radps: f32) -> Result<(), DriveError> {
        if self.fault.is_some() {
            return Err(DriveError::Faulted);
        }
        if self.driving_run() || self.check.is_some() {
            return Err(DriveError::Busy);
        }
        if self.encoders.is_none() {
            return Err(DriveError::NotReady);
        }
        if !v_mps.is_finite() || !w_radps.is_finite() {
            return Err(DriveError::NotFinite);
        }
        let l = &self.config.limits;
        let target = (
            clamp(v_mps, -l.max_speed_mps, l.max_speed_mps),
            clamp(w_radps, -l.max_turn_rate_radps, l.max_turn_rate_radps),
        );
        let remaining = self.deadman_periods;
        match self.drive.as_mut() {
            Some(d) => {
                d.target = target;
                d.remaining = remaining;
            }
            None => {
                self.reset_loops();
                self.drive = Some(DriveState {
                    target,
                    previous: (0.0, 0.0),
                    now: (0.0, 0.0),
                    remaining,
                });
            }
        }
        Ok(())
    }

    /// The user button: a short press starts the next planned run (and advances the plan so
    /// runs alternate CW/CCW) or, while a fault is latched, clears it; a long press aborts.
    pub fn on_press(&mut self, press: Press, plan: &mut RunPlan) -> ButtonAction {
        match press {
            Press::Long => {
                self.abort();
                ButtonAction::Aborted
            }
            Press::Short if self.fault.is_some() => {
                self.clear_fault();
                ButtonAction::ClearedFault
            }
            Press::Short => {
                let path = plan.next_path();
                match self.start(path) {
                    Ok(()) => {
                        plan.advance();
                        ButtonAction::Started(path)
                    }
                    Err(e) => ButtonAction::StartRefused(e),
                }
            }
        }
    }

    /// The record of a completed run, once (the older first if two are waiting).
    pub fn take_finished_run(&mut self) -> Option<RunRecord> {
        // Checked first: `take` copies the whole slot, knot storage included, even when empty
        // (the session polls this every period).
        if self.finished.is_some() {
            return self.finished.take();
        }
        if self.run.as_ref().is_some_and(|r| r.done()) {
            let geometry = self.config.geometry;
            return self.run.take().map(|r| r.into_record(geometry));
        }
        None
    }

    /// Turns a completed run not taken yet into its record, before a new run replaces it or
    /// the geometry it was driven with changes (both only while idle, never in a period).
    pub(super) fn stash_finished_run(&mut self) {
        if self.run.as_ref().is_some_and(|r| r.done()) {
            let geometry = self.config.geometry;
            self.finished = self.run.take().map(|r| r.into_record(geometry));
        }
    }

    /// Ends the run being driven, if any; a completed one stays to be taken.
    pub(super) fn discard_driven_run(&mut self) {
        if self.driving_run() {
            self.run = None;
        }
    }

    pub(super) fn is_idle(&self) -> bool {
        !self.driving_run() && self.drive.is_none() && self.check.is_none()
    }

    /// Whether a run or a check may start now: no fault, idle, encoders read.
    fn ready_to_start(&self) -> Result<(), StartError> {
        if self.fault.is_some() {
            Err(StartError::Faulted)
        } else if !self.is_idle() {
            Err(StartError::Busy)
        } else if self.encoders.is_none() {
            Err(StartError::NotReady)
        } else {
            Ok(())
        }
    }

    /// Starts a bring-up check ([`crate::motion::bringup`]) or a motor identification
    /// ([`crate::motion::identify`]): the motor pulses need the wheels off the ground, the push
    /// check needs the operator to push the robot forward by hand, the identification wheels
    /// off the ground or the robot on a free floor, as its mode says.
    ///
    /// # Errors
    /// As [`Controller::start`]: a latched fault, not idle, before the first step.
    pub fn start_check(&mut self, kind: CheckKind) -> Result<(), StartError> {
        self.ready_to_start()?;
        let rate = self.config.rate_hz;
        let g = &self.config.geometry;
        self.check = Some(match kind {
            CheckKind::Pulses => ActiveCheck::Pulses(PulseCheck::new(rate)),
            CheckKind::Identify(mode) => ActiveCheck::Identify(Identify::new(
                mode,
                rate,
                (g.meters_per_tick_right(), g.meters_per_tick_left()),
                f64::from(self.config.limits.max_speed_mps),
            )),
            CheckKind::Push => ActiveCheck::Push(PushCheck::new(
                rate,
                (
                    1.0 / g.meters_per_tick_right(),
                    1.0 / g.meters_per_tick_left(),
                ),
            )),
        });
        self.check_report = None;
        self.reset_loops();
        info!("bring-up check started");
        Ok(())
    }

    /// The report of the last completed bring-up check, once.
    ///
    /// A finished motor identification's report is computed here, by its fit
    /// ([`Identify::fit`], tens of thousands of instructions of soft-float on the board), not in
    /// the control period that finished it; a failure the fit finds latches
    /// [`Fault::Identify`] and is reported as [`CheckReport::IdentifyFailed`], as a failure found
    /// in a period is. A caller that must not hold the controller during the fit (the firmware's
    /// console task, which shares it with the control task) computes the fit of a copy of
    /// [`Controller::finished_identification`] and hands it to
    /// [`Controller::conclude_identification`].
    pub fn take_check_report(&mut self) -> Option<CheckReport> {
        if let Some(report) = self.check_report.take() {
            return Some(report);
        }
        let fit = self.finished_identification()?.fit();
        self.conclude_identification(fit)
    }

    /// A motor identification whose last segment has ended, waiting for its fit: its frozen
    /// statistics, where they are (the controller is busy until
    /// [`Controller::conclude_identification`]).
    pub fn finished_identification(&self) -> Option<&Identify> {
        match &self.check {
            Some(ActiveCheck::Identify(i)) if i.is_finished() => Some(i),
            _ => None,
        }
    }

    /// Ends the finished identification with `fit`, the result of its [`Identify::fit`]: its
    /// report, or, for a failure, latches [`Fault::Identify`] and reports it. `None` (and `fit`
    /// is dropped) when no finished identification is waiting.
    pub fn conclude_identification(
        &mut self,
        fit: Result<IdentifyReport, IdentifyFailure>,
    ) -> Option<CheckReport> {
        self.finished_identification()?;
        self.check = None;
        Some(match fit {
            Ok(report) => CheckReport::Identify(report),
            Err(failure) => {
                self.latch(Fault::Identify(failure));
                CheckReport::IdentifyFailed(failure)
            }
        })
    }

    /// Ends a check in progress; a finished identification stays until its report is taken.
    pub(super) fn end_running_check(&mut self) {
        if self.finished_identification().is_none() {
            self.check = None;
        }
    }

    /// The counts of missed periods beyond the one period's share [`Self::step_check`] is
    /// given: the checks that sum the motion take them whole (identification's travel bound,
    /// the push check's distance).
    pub(super) fn check_catch_up(&mut self, dr: i64, dl: i64) {
        match self.check.as_mut() {
            Some(ActiveCheck::Identify(i)) => i.catch_up(dr, dl),
            Some(ActiveCheck::Push(p)) => p.catch_up(dr, dl),
            Some(ActiveCheck::Pulses(_)) | None => {}
        }
    }

    /// One period of the bring-up check (open loop: no speed loop, no following error).
    pub(super) fn step_check(&mut self, dr: i64, dl: i64) -> MotorCommand {
        let coast = MotorCommand::Stop(StopMode::Coast);
        let Some(check) = self.check.as_mut() else {
            return coast;
        };
        match check {
            ActiveCheck::Pulses(p) => match p.step(dr, dl) {
                PulseStep::Duty(right, left) => MotorCommand::Duty { right, left },
                PulseStep::Off => coast,
                PulseStep::Done(report) => {
                    self.check = None;
                    self.check_report = Some(CheckReport::Pulses(report));
                    coast
                }
            },
            ActiveCheck::Push(p) => {
                if let Some(report) = p.step(dr, dl) {
                    self.check = None;
                    self.check_report = Some(CheckReport::Push(report));
                }
                coast
            }
            // Finished, waiting for the fit: stopped as when idle.
            ActiveCheck::Identify(i) if i.is_finished() => {
                MotorCommand::Stop(self.config.stop_mode)
            }
            ActiveCheck::Identify(i) => match i.step(dr, dl) {
                IdentifyStep::Duty(right, left) => MotorCommand::Duty { right, left },
                IdentifyStep::Stop(mode) => MotorCommand::Stop(mode),
                IdentifyStep::Failed(failure) => {
                    // Latching reports the failure and ends the routine.
                    self.latch(Fault::Identify(failure));
                    coast
                }
                // The statistics stay frozen in place; the fit runs when the report is taken.
                IdentifyStep::Finished => coast,
            },
        }
    }
}

/// One period of a velocity ramp: `cur` moved toward `target` by at most `max_accel / rate_hz`.
/// Out of line: inlined at both call sites it would exist twice in flash.
#[inline(never)]
pub(super) fn ramp_toward(cur: f32, target: f32, max_accel: f32, rate_hz: f32) -> f32 {
    let step = max_accel / rate_hz;
    cur + clamp(target - cur, -step, step)
}

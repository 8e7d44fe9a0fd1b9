//! The session's periodic poll and the pose stream it writes (`stream on [hz]|off`).
//!
//! Owns the stream schedule ([`Stream`]: period, next line, previous sample for the wheel
//! speeds) and the hold while a line is typed. The poll itself collects finished runs and
//! check results and stores changed runs, each through the part that owns it.

use core::fmt::{self, Write};

use super::Session;
use super::traits::{Calibrator, Robot, SettingsAndRuns};
use crate::kinematics::encoder::WheelTicks;
use crate::protocol::outcome::{Ack, write_ack};
use crate::protocol::stream::StreamSample;

/// Default pose-stream rate, Hz.
pub const DEFAULT_STREAM_HZ: u32 = 10;

/// Pose-stream schedule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Stream {
    period_us: u64,
    /// Time of the next line; `None` = emit at the next poll.
    next_due_us: Option<u64>,
    /// Time and wheel tick totals of the previous line, for the wheel speeds.
    last: Option<(u64, WheelTicks)>,
}

impl<C: Calibrator> Session<C> {
    /// Periodic work: collects finished runs (announcing them with `event` lines), stores
    /// changed runs in flash once the motors are stopped, and writes a `stream` line when one
    /// is due at `now_us` (a monotonic time, microseconds). All of it holds while a line is
    /// being typed ([`Session::set_typing`]), so no unsolicited line cuts into the echo.
    ///
    /// # Errors
    /// Only if `out` refuses the text.
    pub fn poll(
        &mut self,
        now_us: u64,
        robot: &mut dyn Robot,
        storage: &mut dyn SettingsAndRuns,
        out: &mut dyn Write,
    ) -> fmt::Result {
        // Unsolicited lines hold while a line is typed with live echo, as the stream does: they
        // would land between the typed characters. The next poll after Enter (or the command's
        // own collection) writes them.
        if self.typing {
            return Ok(());
        }
        self.collect_finished(robot, out)?;
        self.collect_check(robot, out)?;
        self.store_runs(robot, storage, out)?;
        if self.stream_due(now_us) {
            let pose = robot.pose();
            let totals = robot.totals();
            let (vr, vl) = self.wheel_speeds(now_us, totals);
            let sample = StreamSample {
                t_us: now_us,
                x_m: pose.x_m,
                y_m: pose.y_m,
                theta_rad: pose.theta_rad,
                v_right_mps: vr,
                v_left_mps: vl,
            };
            sample.write(out)?;
        }
        Ok(())
    }

    /// `stream on [hz]` (`Some(rate)`, `None` for the default rate) or `stream off` (`None`).
    pub(super) fn set_stream(
        &mut self,
        on: Option<Option<u32>>,
        out: &mut dyn Write,
    ) -> fmt::Result {
        match on {
            Some(hz) => {
                let hz = hz.unwrap_or(DEFAULT_STREAM_HZ).max(1);
                self.stream = Some(Stream {
                    period_us: 1_000_000 / u64::from(hz),
                    next_due_us: None,
                    last: None,
                });
                write_ack(out, Ack::Stream { hz: Some(hz) })
            }
            None => {
                self.stream = None;
                write_ack(out, Ack::Stream { hz: None })
            }
        }
    }

    /// Mean wheel speeds `(right, left)` in m/s since the previous stream line (0 for the first
    /// line), from the tick totals and the active geometry; remembers this sample.
    fn wheel_speeds(&mut self, now_us: u64, totals: WheelTicks) -> (f64, f64) {
        let g = self.settings.active;
        let Some(stream) = self.stream.as_mut() else {
            return (0.0, 0.0);
        };
        let speeds = match stream.last {
            Some((t, prev)) if now_us > t => {
                let dt = (now_us - t) as f64 * 1e-6;
                (
                    (totals.right - prev.right) as f64 * g.meters_per_tick_right() / dt,
                    (totals.left - prev.left) as f64 * g.meters_per_tick_left() / dt,
                )
            }
            _ => (0.0, 0.0),
        };
        stream.last = Some((now_us, totals));
        speeds
    }

    /// Tells the session whether a line is being typed at the console and echoed as it is typed
    /// ([`crate::protocol::line::LineAssembler::typing`]). Meanwhile the pose stream holds: its
    /// lines would land between the typed characters, cutting both. It resumes with the next
    /// poll after the line ends (Enter or Ctrl-C), restarting its schedule from there.
    pub fn set_typing(&mut self, typing: bool) {
        self.typing = typing;
    }

    /// Whether a stream line is due at `now_us`; if so, schedules the next one. The schedule
    /// advances by whole periods (no drift); after a stall longer than one period, or if the
    /// clock went backwards (a wrapped timer), it restarts from `now_us` instead of bursting or
    /// falling silent.
    pub fn stream_due(&mut self, now_us: u64) -> bool {
        let Some(stream) = self.stream.as_mut() else {
            return false;
        };
        let period = stream.period_us;
        match stream.next_due_us {
            Some(due) if now_us < due && due - now_us <= period => false,
            Some(due) if now_us >= due && now_us - due < period => {
                stream.next_due_us = Some(due + period);
                true
            }
            _ => {
                stream.next_due_us = Some(now_us + period);
                true
            }
        }
    }
}

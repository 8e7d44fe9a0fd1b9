//! The simulated board: the simulated robot speaking the board's serial protocol.
//!
//! [`Board`] is the simulated board: the library's [`Controller`] stepping the simulated robot
//! at the control rate through the app core's control period (`app::control::period`, retimed
//! by `app::control::Pacing` after `set control_hz`, as the firmware's control task), the library's [`Session`] executing protocol lines, and the library's
//! [`ParamAndRunStore`] on the simulated storage flash ([`SimParamFlash`], sectors 1–2 and 10–11), which
//! outlives the board: dropping a `Board` and booting a new one over the same flash is a
//! simulated reboot. Bytes go through the library's receive loop and [`LineAssembler`], exactly
//! as the USART2 RX interrupt feeds them on the board: a stop key (Ctrl-C, Esc) stops the
//! controller at once, before any queued line; lines wait in an input queue for the session, as
//! they wait for the console task on the board; a line that starts while others wait is echoed
//! with its reply, any other as its bytes arrive. The queue here is unbounded (the simulated
//! board executes a line as soon as it is its turn; the board's queue holds
//! [`odocal::protocol::rx::INPUT_QUEUE_BYTES`]).

use std::collections::VecDeque;

use odocal::app::console::LineSource;
use odocal::app::control::{MissedPeriods, Pacing};
use odocal::app::serial::LineQueue;
use odocal::app::{Handoff, console, control, serial};
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::bringup::CheckKind;
use odocal::motion::button::Press;
use odocal::motion::controller::{Controller, Status, StepOutput};
use odocal::motion::identify::IdentifyMode;
use odocal::protocol::line::LineEvent;
use odocal::protocol::rx::{InputItem, Received, RxRead};
use odocal::protocol::{Command, FinalLine, LineAssembler, ParamName};
use odocal::session::library::{LibraryCalibrator, LockedController};
use odocal::session::{Booted, Session, boot};
use odocal::storage::ParamAndRunStore;

use crate::sim::flash::{SimFlash, SimParamFlash};
use crate::sim::robot::{Sim, SimConfig};

/// Speed at which the simulated operator pushes the robot during `bringup push`, m/s.
pub const HAND_PUSH_MPS: f64 = 0.1;

/// The core clock the simulated cycle counter runs at, Hz (the F407's).
pub const CORE_HZ: u32 = 168_000_000;

/// The simulated board, over a simulated parameter flash that outlives it.
pub struct Board<'f> {
    /// The simulated robot.
    pub sim: Sim,
    /// The library's controller, stepped once per control period.
    pub controller: Controller,
    /// The protocol session.
    pub session: Session<LibraryCalibrator>,
    /// Parameter storage on the simulated flash.
    pub store: ParamAndRunStore<&'f mut SimFlash>,
    /// What the receive, the control period and the console tell each other, as on the board.
    handoff: Handoff,
    /// The control period's bookkeeping (retiming after `set control_hz`), as on the board.
    pacing: Pacing,
    /// Periods missed before each period, from the simulated cycle counter, as on the board.
    missed: MissedPeriods,
    /// Periods missed before the last one (what the control task told the controller).
    last_missed: u32,
    assembler: LineAssembler,
    /// Received lines and stop keys not yet handled by the session.
    input: Input,
    now_us: u64,
    period_us: u64,
    /// True pose when the current (or last) run started.
    run_start: Option<PoseF64>,
    running: bool,
}

/// Whether a reply (as [`Board::send`] returns it) ends in `ok`: its final line read by the
/// protocol's own grammar.
pub fn accepted(reply: &str) -> bool {
    reply
        .lines()
        .rev()
        .find_map(FinalLine::parse)
        .is_some_and(FinalLine::is_ok)
}

impl<'f> Board<'f> {
    /// Boots: loads the parameters from `flash` (defaults and a warning if there are none),
    /// configures the controller with them, restores the stored runs and measurements, and
    /// reads the encoders once. The boot messages (`event` lines) are appended to `out`.
    ///
    /// The board runs at its stored control rate (`control_hz`), and the robot is stepped once
    /// per period of it. `config.rate_hz` is the rate the simulated operator wants: when the
    /// stored one differs, the board is told with `set control_hz` (the reply is appended to
    /// `out`), as an operator would type it.
    ///
    /// # Errors
    /// An invalid controller configuration or flash range, or a refused rate, as text.
    pub fn boot(
        config: SimConfig,
        flash: &'f mut SimParamFlash,
        out: &mut String,
    ) -> Result<Board<'f>, String> {
        let wanted_hz = config.rate_hz;
        let mut board = Board::boot_at_stored_rate(config, flash, out)?;
        board.operator_set(ParamName::ControlHz, f64::from(wanted_hz), out)?;
        Ok(board)
    }

    /// The simulated operator types `set <name> <value>` when the board's value differs (the
    /// reply is appended to `out`); nothing when it is already `value`.
    ///
    /// # Errors
    /// The command and the board's reply when it refuses it.
    pub fn operator_set(
        &mut self,
        name: ParamName,
        value: f64,
        out: &mut String,
    ) -> Result<(), String> {
        if self.session.settings().value(name) == value {
            return Ok(());
        }
        let set = Command::Set { name, value }.to_string();
        let reply = self.send(&set);
        if !accepted(&reply) {
            return Err(format!("{set}: {}", reply.trim_end()));
        }
        out.push_str(&reply);
        Ok(())
    }

    /// [`Board::boot`] without the simulated operator: the board runs at its stored control
    /// rate whatever `config.rate_hz` says, as a board does after a reset.
    ///
    /// # Errors
    /// An invalid controller configuration or flash range, as text.
    pub fn boot_at_stored_rate(
        mut config: SimConfig,
        flash: &'f mut SimParamFlash,
        out: &mut String,
    ) -> Result<Board<'f>, String> {
        let mut store = flash.store();
        let loaded = store.load_blocking();
        // The firmware's boot: no fault record, no reset flags, no board note.
        let Booted {
            controller,
            mut session,
            controller_refused,
        } = boot(
            &loaded,
            LibraryCalibrator::default(),
            None,
            None,
            |_, _| Ok(()),
            out,
        )
        .map_err(|e| format!("built-in defaults: {e}"))?;
        if let Some(e) = controller_refused {
            return Err(format!("stored parameters: {e}"));
        }
        config.rate_hz = controller.config().rate_hz;
        session
            .restore_runs(&mut store, out)
            .map_err(|e| e.to_string())?;
        let period_us = 1_000_000 / u64::from(config.rate_hz);
        let handoff = Handoff::new();
        let pacing = Pacing::new(&handoff, config.rate_hz);
        let missed = MissedPeriods::new(CORE_HZ, config.rate_hz);
        let mut board = Board {
            sim: Sim::new(config),
            controller,
            session,
            store,
            handoff,
            pacing,
            missed,
            last_missed: 0,
            assembler: LineAssembler::new(),
            input: Input::default(),
            now_us: 0,
            period_us,
            run_start: None,
            running: false,
        };
        // The control task runs from boot on; the controller needs one encoder read to start.
        board.sim.step(&mut board.controller);
        Ok(board)
    }

    /// Simulated time since boot, microseconds: the board's clock (the `t` of its `stream`
    /// lines), advanced by one control period after each period.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    /// The control period the board runs at now, microseconds.
    pub fn period_us(&self) -> u64 {
        self.period_us
    }

    /// Bytes received on the serial port, as the receive interrupt takes them: assembled into
    /// lines (queued for [`Board::process`]); a stop key or a garbled line ending in `stop` stops
    /// the controller now; the echo (when on) is appended to `out`.
    pub fn receive(&mut self, bytes: &[u8], out: &mut String) {
        self.receive_reads(bytes.iter().map(|&b| RxRead::Byte(b)), out);
    }

    /// As [`Board::receive`], with receive errors (overrun, framing, noise) among the bytes.
    pub fn receive_reads(&mut self, reads: impl IntoIterator<Item = RxRead>, out: &mut String) {
        let mut reads = reads.into_iter();
        // The simulated board answers at once: nothing is ever on its way out.
        serial::receive(
            &self.handoff,
            &mut self.assembler,
            || reads.next().unwrap_or(RxRead::Empty),
            usize::MAX,
            false,
            &mut self.input,
            |bytes| out.push_str(&String::from_utf8_lossy(bytes)),
        );
    }

    /// Whether received input waits for the session.
    pub fn has_input(&self) -> bool {
        !self.input.0.is_empty()
    }

    /// Executes queued input on the session, replies appended to `out`. With `lines_at_rest`,
    /// a line waits until the robot is at rest (stop keys never wait), for scripts that send
    /// everything at once.
    pub fn process(&mut self, out: &mut String, lines_at_rest: bool) {
        while let Some(received) = self.input.0.front() {
            if lines_at_rest && !received.item.is_stop() && !self.at_rest() {
                break;
            }
            let _ = console::take_line(
                &self.handoff,
                &mut self.session,
                &mut self.input,
                &mut LockedController(&mut self.controller),
                &mut self.store,
                out,
            );
            self.note_run_start();
        }
    }

    /// One protocol line (terminator added), executed at once, as a program sends it; returns
    /// the reply text (without the echo, which a program ignores or turns off).
    ///
    /// Input already queued (e.g. the next lines of a script waiting for the robot to come to
    /// rest) stays queued: only this line is executed.
    pub fn send(&mut self, line: &str) -> String {
        let queued = std::mem::take(&mut self.input);
        let mut echo = String::new();
        self.receive(line.as_bytes(), &mut echo);
        self.receive(b"\r", &mut echo);
        let mut out = String::new();
        self.process(&mut out, false);
        self.input = queued;
        out
    }

    /// The button: a short press (next planned run, or clear a fault) or a long one (stop).
    pub fn press_button(&mut self, long: bool, out: &mut String) {
        let press = if long { Press::Long } else { Press::Short };
        let _ = console::press(
            &mut self.session,
            press,
            &mut LockedController(&mut self.controller),
            out,
        );
        self.note_run_start();
    }

    fn note_run_start(&mut self) {
        let running = matches!(self.controller.status(), Status::Running { .. });
        if running && !self.running {
            self.run_start = Some(self.sim.true_pose());
        }
        self.running = running;
    }

    /// The CPU stalls for `periods` control periods (a flash erase on the board's single bank):
    /// no period runs while simulated time goes on. The robot moves meanwhile only as the
    /// caller moves it ([`Sim::advance`], a hand push); the next period learns from the cycle
    /// counter how many periods it missed, as the board's control task does.
    pub fn stall(&mut self, periods: u32) {
        self.now_us += u64::from(periods) * self.period_us;
    }

    /// How many periods were missed before the last period ran (0 when it was on time).
    pub fn last_missed(&self) -> u32 {
        self.last_missed
    }

    /// One control period: the controller reads the encoders and drives the motors, the robot
    /// moves, and the session gets its periodic poll (finished runs, pose stream).
    pub fn step(&mut self, out: &mut String) -> StepOutput {
        let output = self.period(&self.controller.status(), out);
        self.running = matches!(self.controller.status(), Status::Running { .. });
        output
    }

    /// [`Board::step`] from the controller's `status` now, without noting the status after it.
    fn period(&mut self, status: &Status, out: &mut String) -> StepOutput {
        // The simulated operator's hand: during `bringup push` it pushes the robot forward.
        let pushing = matches!(status, Status::Checking(CheckKind::Push));
        self.sim.set_push(pushing.then_some(HAND_PUSH_MPS));
        // The core's cycle counter at this period's start (it wraps, as the DWT's does).
        let now_cycles = (self.now_us.wrapping_mul(u64::from(CORE_HZ / 1_000_000))) as u32;
        let missed = self.missed.observe(now_cycles);
        self.last_missed = missed;
        let (handoff, controller, pacing) = (&self.handoff, &mut self.controller, &mut self.pacing);
        let mut retime_hz = None;
        let output = self.sim.step_with(|r, l, motors| {
            let out = control::period(handoff, controller, missed, r, l, None, motors);
            // `set control_hz` retimed the controller: the period source follows from this
            // period on, as the board's timer does after the period that saw the new rate.
            retime_hz = pacing
                .after_period(handoff, controller.config().rate_hz)
                .retime_hz;
            if let Some(hz) = retime_hz {
                motors.set_rate_hz(hz);
            }
            out
        });
        if let Some(hz) = retime_hz {
            self.period_us = 1_000_000 / u64::from(hz);
            self.missed.set_rate(hz);
        }
        self.now_us += self.period_us;
        let _ = console::poll(
            &self.handoff,
            &mut self.session,
            self.now_us,
            &mut LockedController(&mut self.controller),
            &mut self.store,
            out,
        );
        output
    }

    /// Whether the controller is idle (or faulted) with the wheels at rest.
    pub fn at_rest(&self) -> bool {
        self.at_rest_in(&self.controller.status())
    }

    /// [`Board::at_rest`] with the controller's `status` now.
    fn at_rest_in(&self, status: &Status) -> bool {
        !matches!(
            status,
            Status::Running { .. } | Status::Driving | Status::Checking(_)
        ) && self.controller.motors_stopped().is_ok()
    }

    /// Steps until [`Board::at_rest`] or `max_periods`; returns the periods stepped.
    pub fn run_until_rest(&mut self, max_periods: u64, out: &mut String) -> u64 {
        let mut n = 0;
        let mut status = self.controller.status();
        while n < max_periods && !self.at_rest_in(&status) {
            self.period(&status, out);
            status = self.controller.status();
            self.running = matches!(status, Status::Running { .. });
            n += 1;
        }
        n
    }

    /// The true pose now, in the start frame of the last run (what the operator measures).
    pub fn true_pose_in_run_frame(&self) -> Option<PoseF64> {
        self.run_start.map(|s| s.relative(&self.sim.true_pose()))
    }

    /// Sends `identify <mode>` (`lifted` or `floor`) and steps the board until the motor
    /// identification has ended and the robot is at rest; returns the reply and the
    /// `event identify …` lines.
    ///
    /// # Errors
    /// The text so far when the command is refused, the identification reports an error, or it
    /// does not end within a minute of robot time.
    pub fn identify(&mut self, mode: IdentifyMode) -> Result<String, String> {
        let mut out = self.send(&Command::Identify { mode }.to_string());
        if !accepted(&out) {
            return Err(out);
        }
        // 60 s at the controller's rate (the simulated robot follows it from the first period).
        let limit = 60 * u64::from(self.controller.config().rate_hz);
        let mut n = 0;
        while matches!(
            self.controller.status(),
            Status::Checking(CheckKind::Identify(_))
        ) {
            self.step(&mut out);
            n += 1;
            if n > limit {
                return Err(format!("{out}identification did not end"));
            }
        }
        self.run_until_rest(limit, &mut out);
        if out.contains("event identify done") {
            Ok(out)
        } else {
            Err(out)
        }
    }

    /// The geometry the controller uses.
    pub fn controller_geometry(&self) -> Geometry {
        self.controller.config().geometry
    }
}

/// The `measure` line for the true end pose of the last run (run start frame, heading wrapped).
pub fn measure_line(board: &Board) -> Option<String> {
    board.true_pose_in_run_frame().map(|p| {
        format!(
            "measure {:.6}m {:.6}m {:.4}deg",
            p.x_m,
            p.y_m,
            odocal::calibration::wrap_angle(p.theta_rad).to_degrees()
        )
    })
}

/// The simulated board's input queue: unbounded (the simulated board executes a line as soon as
/// it is its turn; the board's queue holds [`odocal::protocol::rx::INPUT_QUEUE_BYTES`]).
#[derive(Debug, Default)]
struct Input(VecDeque<Received>);

impl LineQueue for Input {
    fn send(&mut self, event: &LineEvent<'_>, echoed: bool) -> bool {
        self.0.push_back(Received {
            item: InputItem::from_event(*event),
            echoed,
        });
        true
    }

    fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

impl LineSource for Input {
    fn take(&mut self) -> Option<Received> {
        self.0.pop_front()
    }

    fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

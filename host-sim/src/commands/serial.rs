//! The `serial` subcommand: connects a simulated [`Board`] to stdin/stdout or, with `--pty`, to a
//! pseudo-terminal whose path it prints, so picocom/minicom or a script can connect as to the
//! real board. The simulation runs in real time (in 10 ms slices) while commands arrive; with
//! `--fast` it runs as fast as possible and takes each input line only once the robot is at rest
//! (for scripts). After each run the true end pose in the run's start frame is printed on
//! stderr, as the operator would measure it on the floor; `--auto-measure` enters it as a
//! `measure` command (only for a run that finished and was stored, never after an abort).
//!
//! With `--pty`, this program's own stdin is the rest of the board: `button` (short press),
//! `button long`, `reboot` or `reset` (a new board over the same flash, as after a reset or
//! power cycle; with `--image`, the file's contents), `play` (`--replay`) and `help`. The flash keeps the parameters
//! and the session's runs with their measurements, so the new board resumes the session: its
//! boot events (`event boot: …`, then `event runs restored: <n> runs, <m> measured` when runs
//! were stored) go to the pty, as on the board, and are also printed on stderr, since a
//! terminal program that opens the pty later never sees them. The pty stays open across the
//! restart.
//!
//! For a test of a calibration that runs on the robot's computer (a bridge on the pty, a test
//! process reading this program's stdout):
//! - `--speed K`: in real time, each 10 ms of wall clock runs K·10 ms of board time.
//! - `--truth-hz HZ` (with `--pty`): `truth T X Y THETA` on stdout every 1/HZ s of board time
//!   (flushed): `T` the board's clock in seconds with 6 decimals, exactly as a `stream` line at
//!   that period prints it; `X`, `Y` (m) and `THETA` (rad, unwrapped: counted on from the start,
//!   CCW positive) the robot's true pose in the world frame (the frame its odometry starts in),
//!   6 decimals. A line is due on a grid of 1/HZ from boot and printed after the first control
//!   period that reaches it: when 1/HZ is a whole number of control periods, the `T`s are
//!   exactly 1/HZ apart. After `reboot` the lines go on with the new board: `T` restarts with
//!   its clock, and the pose with the robot the simulator puts back at the origin (as every boot
//!   of a simulated board does).
//! - `--wear T:ED:EB` (repeatable): at board time T s the robot's true E_d and E_b become ED
//!   and EB (wheel diameters and wheelbase change, not the pose; the mean diameter stays);
//!   `wear at T s: E_d ED, E_b EB` on stderr when it happens, `T` the board time then. A wear
//!   stays across `reboot`; one not yet due happens when the new board's clock reaches it.
//! - `--replay SESSION_DIR` (with `--pty`): the board boots with the OptiOdom session's nominal
//!   geometry (the simulated operator `set`s its diameters, wheelbase and encoder resolution, as
//!   `--rate-hz` sets the rate) and its encoders count the session's recorded wheel motion
//!   instead of the simulated wheels, which are held from boot on (motor commands move nothing;
//!   [`Sim::play_counts`] turns the robot model's own counters, which the board reads as ever).
//!   `play` on this program's stdin starts it: the runs play in file order in board time (each
//!   row's ticks spread evenly over its 50 ms, 2 s at rest between runs:
//!   [`Playback`](crate::sim::optiodom::playback::Playback)), `replay run N started` on stdout
//!   at each run's first period and `replay done` after the last. With `--truth-hz` the truth
//!   lines are then the run's recorded ground truth turned by the session's motion-capture heading offset (interpolated in time, in the run's start
//!   frame, heading unwrapped), and there are none outside a run. A `reboot` does not stop the
//!   recording: the new board counts it on from where it is.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use odocal::motion::controller::Status;
use odocal::protocol::ParamName;

use self::replay::Replay;
use self::truth::{TruthClock, board_seconds, print_truth};
use crate::sim::board::{Board, measure_line};
use crate::sim::flash::{SimFlash, SimParamFlash};
use crate::sim::robot::{
    MotorArgs, Sim, SimConfig, Wear, WiringOption, parse_wear, sim_config, true_geometry,
};

mod replay;
mod truth;

/// Command-line arguments of the `serial` subcommand.
#[derive(clap::Args, Debug, Clone)]
pub struct SerialArgs {
    /// Serve the protocol on a new pseudo-terminal (its path is printed) instead of stdin/stdout.
    #[arg(long)]
    pub pty: bool,
    /// Run as fast as possible; each input line is taken once the robot is at rest.
    #[arg(long)]
    pub fast: bool,
    /// True E_b of the simulated robot.
    #[arg(long, default_value_t = 1.010)]
    pub eb: f64,
    /// True E_d of the simulated robot.
    #[arg(long, default_value_t = 0.995)]
    pub ed: f64,
    /// Relative slip noise per millisecond of travel (standard deviation; per control period at 1 kHz).
    #[arg(long, default_value_t = 0.0)]
    pub slip: f64,
    /// Seed of the slip noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Control rate, Hz: 1000, 2000, 4000, 5000, 8000 or 10000 (the board's `control_hz`).
    /// Given, the simulated operator sets it with `set control_hz` at boot and after every
    /// `reboot`; without it the board runs at its stored rate (1000 Hz on an erased flash).
    #[arg(long = "rate-hz", visible_alias = "rate", value_parser = crate::commands::parse_rate_hz)]
    pub rate: Option<u32>,
    /// Flash image file: loaded at boot (missing = erased flash) and written back whenever the
    /// flash changed (`save`, a stored run, a measurement, `drop`), so parameters and runs
    /// survive a restart of the simulator.
    #[arg(long)]
    pub image: Option<std::path::PathBuf>,
    /// After each run, enter `measure` with the true end pose as the operator would (the line
    /// is echoed with a `> ` prefix), so a piped script can run a whole calibration.
    #[arg(long)]
    pub auto_measure: bool,
    /// With `--fast`: take each line, and measure (`--auto-measure`), only once both wheels have
    /// come to rest for good (speed below the smallest normal `f64`, about 18 s of robot time
    /// after a brake: from then on no count and no pose coordinate changes), so the timing of the
    /// input does not matter. The firmware-in-the-loop test drives the emulator the same way
    /// and compares the results.
    #[arg(long)]
    pub settle: bool,
    /// How the simulated robot is wired: a reversed motor or encoder, to rehearse the bring-up
    /// check (`bringup push`, `bringup`) and the following-error fault on the console.
    #[arg(long, value_enum, default_value_t = WiringOption::Standard)]
    pub wiring: WiringOption,
    /// The simulated motors (`--motor-gain R,L`, `--motor-tau R,L`, `--motor-deadband R,L`, as
    /// for `drive` and `session`): rehearse `identify` with weak or strong motors.
    #[command(flatten)]
    pub motors: MotorArgs,
    /// Real time K times faster (K > 0): each 10 ms of wall clock runs K·10 ms of board time.
    #[arg(long, value_name = "K", default_value_t = 1.0, value_parser = parse_positive,
          allow_negative_numbers = true, conflicts_with = "fast")]
    pub speed: f64,
    /// Print `truth T X Y THETA` on stdout every 1/HZ s of board time (HZ > 0): the board's
    /// time in seconds as its `stream` lines print it, the robot's true pose (m, m, rad
    /// unwrapped) in the world frame.
    #[arg(long = "truth-hz", value_name = "HZ", value_parser = parse_positive,
          allow_negative_numbers = true, requires = "pty")]
    pub truth_hz: Option<f64>,
    /// At board time T s the robot's true E_d and E_b become ED and EB (a tyre worn, a load
    /// added; repeatable); announced on stderr. Not with `--replay` (its wheels are held).
    #[arg(long, value_name = "T:ED:EB", value_parser = parse_wear, conflicts_with = "replay")]
    pub wear: Vec<Wear>,
    /// An OptiOdom session folder whose recorded wheel motion the board's encoders count, from
    /// `play` typed on this program's stdin on (the board boots with the session's geometry).
    #[arg(long, value_name = "SESSION_DIR", requires = "pty")]
    pub replay: Option<PathBuf>,
}

/// `--speed`, `--truth-hz`: a positive finite number.
///
/// # Errors
/// Not a number, or not above 0 and finite.
fn parse_positive(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        Ok(_) => Err("must be a finite number above 0".into()),
        Err(e) => Err(format!("{s}: {e}")),
    }
}

/// Opens a pseudo-terminal in raw mode; returns the master's file and the slave's path. The
/// slave stays open in this process so the master never sees end-of-file between clients.
#[allow(unsafe_code)] // openpty, termios and descriptor ownership (each block says why)
fn open_pty() -> Result<(std::fs::File, String, std::fs::File), String> {
    use std::os::fd::FromRawFd;
    let (mut master, mut slave) = (0, 0);
    // SAFETY: openpty writes two valid descriptors on success; the name, termios and winsize
    // pointers may be null.
    let rc = unsafe {
        libc::openpty(
            &mut master,
            &mut slave,
            std::ptr::null_mut(),
            std::ptr::null(),
            std::ptr::null(),
        )
    };
    if rc != 0 {
        return Err(format!("openpty: {}", std::io::Error::last_os_error()));
    }
    // SAFETY: `slave` is an open terminal descriptor; `t` is fully written by tcgetattr.
    let path = unsafe {
        let mut t: libc::termios = std::mem::zeroed();
        if libc::tcgetattr(slave, &mut t) == 0 {
            libc::cfmakeraw(&mut t);
            libc::tcsetattr(slave, libc::TCSANOW, &t);
        }
        let name = libc::ptsname(master);
        if name.is_null() {
            return Err("ptsname failed".into());
        }
        std::ffi::CStr::from_ptr(name)
            .to_string_lossy()
            .into_owned()
    };
    // SAFETY: both descriptors are open and owned by nothing else.
    let (m, s) = unsafe {
        (
            std::fs::File::from_raw_fd(master),
            std::fs::File::from_raw_fd(slave),
        )
    };
    Ok((m, path, s))
}

/// Boots the simulated board: at the rate `config` asks for when `--rate-hz` was given (the
/// simulated operator sets it), else at the board's stored rate. With `--replay` the operator
/// sets the session's nominal geometry too, and the encoders take the recording's counts.
fn boot_board<'f>(
    config: SimConfig,
    operator_rate: bool,
    replay: Option<&Replay>,
    flash: &'f mut SimParamFlash,
    out: &mut String,
) -> Result<Board<'f>, String> {
    let mut board = if operator_rate {
        Board::boot(config, flash, out)?
    } else {
        Board::boot_at_stored_rate(config, flash, out)?
    };
    if let Some(r) = replay {
        let g = r.geometry;
        for (name, value) in [
            (ParamName::DiameterRight, g.diameter_right_m),
            (ParamName::DiameterLeft, g.diameter_left_m),
            (ParamName::Wheelbase, g.wheelbase_m),
            (ParamName::CountsPerRev, f64::from(g.counts_per_rev)),
        ] {
            board
                .operator_set(name, value, out)
                .map_err(|e| format!("--replay: the session's geometry: {e}"))?;
        }
        board.sim.play_counts(r.ticks());
    }
    Ok(board)
}

/// Applies the wears due at `now_us` (`pending` sorted by time) to the robot and to `config`
/// (so that a new board's robot keeps them), each announced on stderr.
fn apply_wears(pending: &mut Vec<Wear>, now_us: u64, sim: &mut Sim, config: &mut SimConfig) {
    while let Some(w) = pending.first().copied()
        && w.at_us() <= now_us
    {
        pending.remove(0);
        sim.apply_wear(&w);
        config.robot.true_geometry = true_geometry(w.ed, w.eb);
        eprintln!(
            "wear at {} s: E_d {}, E_b {}",
            board_seconds(now_us),
            w.ed,
            w.eb
        );
    }
}

/// Runs the simulated board on stdin/stdout or a pseudo-terminal until the input ends (stdin)
/// or the process is stopped (pty).
///
/// # Errors
/// I/O or configuration failures, as text.
pub fn run(args: &SerialArgs) -> Result<(), String> {
    let mut config = sim_config(
        args.ed,
        args.eb,
        args.slip,
        args.seed,
        args.rate
            .unwrap_or(odocal::motion::controller::DEFAULT_RATE_HZ),
    );
    config.wiring = args.wiring.wiring();
    args.motors.apply(&mut config)?;
    let mut replay = args.replay.as_deref().map(Replay::open).transpose()?;
    let mut wears = args.wear.clone();
    wears.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    let mut truth = args.truth_hz.map(TruthClock::new);

    let mut out = String::new();
    let mut flash = match &args.image {
        Some(path) => SimParamFlash::open(path).map_err(|e| format!("{}: {e}", path.display()))?,
        None => SimParamFlash::erased(),
    };
    let mut board = boot_board(
        config,
        args.rate.is_some(),
        replay.as_ref(),
        &mut flash,
        &mut out,
    )?;
    apply_wears(&mut wears, board.now_us(), &mut board.sim, &mut config);
    let (tx, rx) = mpsc::channel::<Option<Vec<u8>>>();
    let (ctl_tx, ctl_rx) = mpsc::channel::<Option<Vec<u8>>>();
    let (mut writer, _slave) = connect(args, replay.as_ref(), &out, tx, ctl_tx)?;
    let mut control = Vec::new();
    let mut input_done = false;
    let mut deadline = Instant::now();
    let mut ends = RunEnds::default();
    let mut image_touched = board.store.flash().bytes_touched();
    // Board time the slices have given and the periods not yet taken, µs.
    let mut budget_us = 0.0;
    let mut powered = true;
    loop {
        // What has arrived goes to the receive side at once (stop keys act now); lines wait in
        // the board's input queue.
        loop {
            match rx.try_recv() {
                // A board without power loses what is sent to it.
                Ok(Some(bytes)) if powered => board.receive(&bytes, &mut out),
                Ok(Some(_)) => {}
                Ok(None) | Err(mpsc::TryRecvError::Disconnected) => {
                    input_done = true;
                    break;
                }
                Err(mpsc::TryRecvError::Empty) => break,
            }
        }
        while let Ok(Some(bytes)) = ctl_rx.try_recv() {
            control.extend_from_slice(&bytes);
        }
        while let Some(end) = control.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = control.drain(..=end).collect();
            let line = String::from_utf8_lossy(&line).trim().to_ascii_lowercase();
            match line.as_str() {
                "" => {}
                "button" => board.press_button(false, &mut out),
                "button long" => board.press_button(true, &mut out),
                "power off" => {
                    powered = false;
                    eprintln!("sim: power off: the board is silent until `power on`");
                }
                "reboot" | "reset" | "power on" => {
                    powered = true;
                    drop(board);
                    if let Some(path) = &args.image {
                        flash = SimParamFlash::open(path)
                            .map_err(|e| format!("{}: {e}", path.display()))?;
                    }
                    let mut boot = String::new();
                    board = boot_board(
                        config,
                        args.rate.is_some(),
                        replay.as_ref(),
                        &mut flash,
                        &mut boot,
                    )?;
                    apply_wears(&mut wears, board.now_us(), &mut board.sim, &mut config);
                    if let Some(t) = &mut truth {
                        t.restart();
                    }
                    image_touched = board.store.flash().bytes_touched();
                    eprint!("sim: {boot}");
                    out.push_str(&boot);
                    ends = RunEnds::default();
                }
                "play" => match &mut replay {
                    Some(r) => r.play()?,
                    None => eprintln!(
                        "sim: nothing to play (start the simulator with --replay SESSION_DIR)"
                    ),
                },
                other => control_help(other),
            }
        }
        let settled = |board: &Board| {
            let (r, l) = board.sim.wheel_speeds_mps();
            !args.settle || (r.abs() < f64::MIN_POSITIVE && l.abs() < f64::MIN_POSITIVE)
        };
        // With --fast, each line once the robot is at rest (and, with --settle, the wheels
        // still); a stop key has already stopped the controller on arrival.
        if powered && (!args.fast || settled(&board)) {
            board.process(&mut out, args.fast);
        }
        // 10 ms of wall clock runs K·10 ms of board time (`--speed`; with `--fast` 10 ms a
        // pass), in whole periods of the rate the board runs at now (`set control_hz` retimes
        // it); the rest waits for the next slice.
        budget_us += match (powered, args.fast) {
            (false, _) => 0.0,
            (true, true) => 1e4,
            (true, false) => 1e4 * args.speed,
        };
        let mut world = World {
            replay: replay.as_mut(),
            wears: &mut wears,
            config: &mut config,
            truth: truth.as_mut(),
        };
        world.run_periods(&mut board, &mut budget_us, &mut out)?;
        write_image(args, &mut board, &mut image_touched)?;
        let still = settled(&board);
        ends.after_slice(&mut board, args, still, &mut out);
        if !out.is_empty() {
            writer
                .write_all(out.as_bytes())
                .and_then(|()| writer.flush())
                .map_err(|e| e.to_string())?;
            out.clear();
        }
        if input_done && !board.has_input() && board.at_rest() {
            return Ok(());
        }
        pace(args, &board, input_done, &mut deadline);
    }
}

/// The simulator's answer to a control line that is `help` or unknown.
fn control_help(line: &str) {
    const LINES: &str = "button | button long | reboot (or reset) | power off | power on | play";
    if line == "help" {
        eprintln!(
            "sim: {LINES} (the board's button; reset: parameters, runs and measurements survive \
             it; power off: the board stops and is silent, what is sent to it lost, until power \
             on boots it; the console is the pty; `play` starts --replay's recording)"
        );
    } else {
        eprintln!("sim: unknown `{line}` ({LINES})");
    }
}

/// Commands (`save`, `measure`, `drop`) and finished runs write the flash: the image file
/// (`--image`) follows when the board's flash changed since `touched`.
fn write_image(args: &SerialArgs, board: &mut Board<'_>, touched: &mut u64) -> Result<(), String> {
    let now = board.store.flash().bytes_touched();
    if let Some(path) = &args.image
        && now != *touched
    {
        *touched = now;
        let mut image = vec![0u8; SimFlash::CAPACITY];
        board.store.flash().copy_image(&mut image);
        std::fs::write(path, image).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

fn spawn_reader<R>(mut read: R, tx: mpsc::Sender<Option<Vec<u8>>>)
where
    R: FnMut(&mut [u8]) -> std::io::Result<usize> + Send + 'static,
{
    std::thread::spawn(move || {
        let mut buf = [0u8; 256];
        loop {
            match read(&mut buf) {
                Ok(0) | Err(_) => {
                    let _ = tx.send(None);
                    return;
                }
                Ok(n) => {
                    if tx.send(Some(buf[..n].to_vec())).is_err() {
                        return;
                    }
                }
            }
        }
    });
}

/// What changes the simulated robot between its periods: the recording it plays, the wears
/// still due, its configuration and the truth lines' clock.
struct World<'a> {
    replay: Option<&'a mut Replay>,
    wears: &'a mut Vec<Wear>,
    config: &'a mut SimConfig,
    truth: Option<&'a mut TruthClock>,
}

impl World<'_> {
    /// Runs the whole control periods `budget_us` holds (the rest waits for the next slice),
    /// with the recording's counts, the wears as they fall due, and the truth lines.
    fn run_periods(
        &mut self,
        board: &mut Board<'_>,
        budget_us: &mut f64,
        out: &mut String,
    ) -> Result<(), String> {
        while *budget_us >= board.period_us() as f64 {
            let before = board.now_us();
            if let Some(r) = &self.replay {
                r.before_period(&mut board.sim);
            }
            board.step(out);
            let now = board.now_us();
            *budget_us -= (now - before) as f64;
            if let Some(r) = &mut self.replay {
                r.after_period(now - before)?;
            }
            apply_wears(self.wears, now, &mut board.sim, self.config);
            if let Some(t) = &mut self.truth
                && t.due(now)
            {
                let pose = match &self.replay {
                    Some(r) => r.truth(),
                    None => Some(board.sim.true_pose()),
                };
                if let Some(p) = pose {
                    print_truth(now, p)?;
                }
            }
        }
        Ok(())
    }
}

/// The ends of runs: the true end pose said (and measured with `--auto-measure`) once the robot
/// is at rest after a run.
#[derive(Default)]
struct RunEnds {
    was_running: bool,
    report_at_rest: bool,
    stored_before: usize,
}

impl RunEnds {
    /// After a slice: a run that ended is reported once the robot is at rest (`settled`: and,
    /// with `--settle`, its wheels still).
    fn after_slice(
        &mut self,
        board: &mut Board<'_>,
        args: &SerialArgs,
        settled: bool,
        out: &mut String,
    ) {
        let running = matches!(board.controller.status(), Status::Running { .. });
        self.report_at_rest |= self.was_running && !running;
        self.was_running = running;
        if self.report_at_rest && board.at_rest() && settled {
            self.report_at_rest = false;
            // Only a run that finished was stored; an aborted one is not, and measuring it
            // would fill an earlier run.
            let stored = board.session.runs().len();
            let finished = stored > self.stored_before
                && board
                    .session
                    .runs()
                    .last()
                    .is_some_and(|r| r.measured.is_none());
            self.stored_before = stored;
            if let Some(line) = measure_line(board) {
                let what = if finished {
                    ""
                } else {
                    " (aborted, not stored)"
                };
                eprintln!("sim: true end pose in the run's start frame{what}: {line}");
                if args.auto_measure && finished {
                    out.push_str(&format!("> {line}\r\n"));
                    out.push_str(&board.send(&line));
                }
            }
        }
        self.stored_before = self.stored_before.min(board.session.runs().len());
    }
}

/// Waits for the next 10 ms slice of the wall clock (real time), or, with `--fast`, a moment
/// when there is nothing to do until input arrives.
fn pace(args: &SerialArgs, board: &Board<'_>, input_done: bool, deadline: &mut Instant) {
    if !args.fast {
        *deadline += Duration::from_millis(10);
        let now = Instant::now();
        if *deadline > now {
            std::thread::sleep(*deadline - now);
        } else {
            *deadline = now;
        }
    } else if !board.has_input() && !input_done && board.at_rest() {
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// The board's console: a new pseudo-terminal (its path printed, this program's stdin then the
/// rest of the board: `button`, `reboot`, `play`) or stdin/stdout; its bytes go to `tx`, the
/// control lines to `ctl_tx`. Returns the writer and the pty's slave, kept open.
fn connect(
    args: &SerialArgs,
    replay: Option<&Replay>,
    out: &str,
    tx: mpsc::Sender<Option<Vec<u8>>>,
    ctl_tx: mpsc::Sender<Option<Vec<u8>>>,
) -> Result<(Box<dyn Write>, Option<std::fs::File>), String> {
    if args.pty {
        let (master, path, slave) = open_pty()?;
        println!("pty {path}");
        eprintln!(
            "serial: connect to {path} at 115200 baud (e.g. picocom -b 115200 {path}); Ctrl-C to quit"
        );
        eprintln!("serial: type `button`, `button long` or `reboot` here (`help` lists them)");
        if let (Some(r), Some(dir)) = (replay, &args.replay) {
            eprintln!(
                "serial: replay of {} ({} runs, {} s): type `play` here to start it",
                dir.display(),
                r.playback.runs(),
                board_seconds(r.playback.duration_us())
            );
        }
        eprint!("sim: {out}");
        let mut reader = master.try_clone().map_err(|e| e.to_string())?;
        spawn_reader(move |buf| reader.read(buf), tx);
        spawn_reader(|buf| std::io::stdin().read(buf), ctl_tx);
        Ok((Box::new(master), Some(slave)))
    } else {
        spawn_reader(|buf| std::io::stdin().read(buf), tx);
        Ok((Box::new(std::io::stdout()), None))
    }
}

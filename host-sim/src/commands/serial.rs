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
//! power cycle; with `--image`, the file's contents) and `help`. The flash keeps the parameters
//! and the session's runs with their measurements, so the new board resumes the session: its
//! boot events (`event boot: …`, then `event runs restored: <n> runs, <m> measured` when runs
//! were stored) go to the pty, as on the board, and are also printed on stderr, since a
//! terminal program that opens the pty later never sees them. The pty stays open across the
//! restart.

use std::io::{Read, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use odocal::motion::controller::Status;

use crate::sim::board::{Board, measure_line};
use crate::sim::flash::{SimFlash, SimParamFlash};
use crate::sim::robot::{MotorArgs, SimConfig, WiringOption, sim_config};

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
/// simulated operator sets it), else at the board's stored rate.
fn boot_board<'f>(
    config: SimConfig,
    operator_rate: bool,
    flash: &'f mut SimParamFlash,
    out: &mut String,
) -> Result<Board<'f>, String> {
    if operator_rate {
        Board::boot(config, flash, out)
    } else {
        Board::boot_at_stored_rate(config, flash, out)
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

    let mut out = String::new();
    let mut flash = match &args.image {
        Some(path) => SimParamFlash::open(path).map_err(|e| format!("{}: {e}", path.display()))?,
        None => SimParamFlash::erased(),
    };
    let mut board = boot_board(config, args.rate.is_some(), &mut flash, &mut out)?;
    let (tx, rx) = mpsc::channel::<Option<Vec<u8>>>();
    let (ctl_tx, ctl_rx) = mpsc::channel::<Option<Vec<u8>>>();
    let (mut writer, _slave): (Box<dyn Write>, Option<std::fs::File>) = if args.pty {
        let (master, path, slave) = open_pty()?;
        println!("pty {path}");
        eprintln!(
            "serial: connect to {path} at 115200 baud (e.g. picocom -b 115200 {path}); Ctrl-C to quit"
        );
        eprintln!("serial: type `button`, `button long` or `reboot` here (`help` lists them)");
        eprint!("sim: {out}");
        let mut reader = master.try_clone().map_err(|e| e.to_string())?;
        spawn_reader(move |buf| reader.read(buf), tx);
        spawn_reader(|buf| std::io::stdin().read(buf), ctl_tx);
        (Box::new(master), Some(slave))
    } else {
        spawn_reader(|buf| std::io::stdin().read(buf), tx);
        (Box::new(std::io::stdout()), None)
    };
    let mut control = Vec::new();
    let mut input_done = false;
    let mut deadline = Instant::now();
    let mut was_running = false;
    let mut report_at_rest = false;
    let mut stored_before = 0;
    let mut image_touched = board.store.flash().bytes_touched();
    loop {
        // What has arrived goes to the receive side at once (stop keys act now); lines wait in
        // the board's input queue.
        loop {
            match rx.try_recv() {
                Ok(Some(bytes)) => board.receive(&bytes, &mut out),
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
                "reboot" | "reset" => {
                    drop(board);
                    if let Some(path) = &args.image {
                        flash = SimParamFlash::open(path)
                            .map_err(|e| format!("{}: {e}", path.display()))?;
                    }
                    let mut boot = String::new();
                    board = boot_board(config, args.rate.is_some(), &mut flash, &mut boot)?;
                    image_touched = board.store.flash().bytes_touched();
                    eprint!("sim: {boot}");
                    out.push_str(&boot);
                    (was_running, report_at_rest, stored_before) = (false, false, 0);
                }
                "help" => eprintln!(
                    "sim: button | button long | reboot (or reset) (the board's button and \
                     reset: parameters, runs and measurements survive it; the console is the \
                     pty)"
                ),
                other => {
                    eprintln!("sim: unknown `{other}` (button | button long | reboot | reset)")
                }
            }
        }
        let settled = |board: &Board| {
            let (r, l) = board.sim.wheel_speeds_mps();
            !args.settle || (r.abs() < f64::MIN_POSITIVE && l.abs() < f64::MIN_POSITIVE)
        };
        // With --fast, each line once the robot is at rest (and, with --settle, the wheels
        // still); a stop key has already stopped the controller on arrival.
        if !args.fast || settled(&board) {
            board.process(&mut out, args.fast);
        }
        // 10 ms of robot time per slice at the rate the board runs at now (`set control_hz`
        // retimes it).
        let slice_periods = u64::from(board.controller.config().rate_hz / 100).max(1);
        for _ in 0..slice_periods {
            board.step(&mut out);
        }
        // Commands (`save`, `measure`, `drop`) and finished runs write the flash.
        let touched = board.store.flash().bytes_touched();
        if let Some(path) = &args.image
            && touched != image_touched
        {
            image_touched = touched;
            let mut image = vec![0u8; SimFlash::CAPACITY];
            board.store.flash().copy_image(&mut image);
            std::fs::write(path, image).map_err(|e| format!("{}: {e}", path.display()))?;
        }
        let running = matches!(board.controller.status(), Status::Running { .. });
        report_at_rest |= was_running && !running;
        was_running = running;
        if report_at_rest && board.at_rest() && settled(&board) {
            report_at_rest = false;
            // Only a run that finished was stored; an aborted one is not, and measuring it
            // would fill an earlier run.
            let stored = board.session.runs().len();
            let finished = stored > stored_before
                && board
                    .session
                    .runs()
                    .last()
                    .is_some_and(|r| r.measured.is_none());
            stored_before = stored;
            if let Some(line) = measure_line(&board) {
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
        stored_before = stored_before.min(board.session.runs().len());
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
        if !args.fast {
            deadline += Duration::from_millis(10);
            let now = Instant::now();
            if deadline > now {
                std::thread::sleep(deadline - now);
            } else {
                deadline = now;
            }
        } else if !board.has_input() && !input_done && board.at_rest() {
            // Nothing to do until input arrives.
            std::thread::sleep(Duration::from_millis(1));
        }
    }
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

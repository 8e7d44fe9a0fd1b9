//! The `serial` subcommand: the simulated robot speaking the board's serial protocol.
//!
//! [`Board`] is the simulated board: the library's [`Controller`] stepping the simulated robot
//! at the control rate, the library's [`Session`] executing protocol lines, and the library's
//! [`ParamStore`] on the simulated parameter flash ([`SimParamFlash`], sectors 10–11), which
//! outlives the board: dropping a `Board` and booting a new one over the same flash is a
//! simulated reboot. Bytes go through the library's [`LineAssembler`], exactly as the USART2 RX
//! interrupt feeds it on the board.
//!
//! [`run`] connects a board to stdin/stdout or, with `--pty`, to a pseudo-terminal whose path it
//! prints, so picocom/minicom or a script can connect as to the real board. The simulation runs
//! in real time (in 10 ms slices) while commands arrive; with `--fast` it runs as fast as
//! possible and takes each input line only once the robot is at rest (for scripts). After each
//! run the true end pose in the run's start frame is printed on stderr, as the operator would
//! measure it on the floor; `--auto-measure` enters it as a `measure` command.

use std::fmt::Write as _;
use std::io::{Read, Write};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use odocal::controller::{Controller, Status, StepOutput};
use odocal::geometry::Geometry;
use odocal::protocol::LineAssembler;
use odocal::protocol::reply::line_error_reply;
use odocal::reference::PoseF64;
use odocal::session::library::LibraryCalibrator;
use odocal::session::{Session, Settings};
use odocal::storage::ParamStore;

use crate::flash::{SimFlash, SimParamFlash};
use crate::robot::{Sim, SimConfig, default_controller, sim_config};

/// The simulated board, over a simulated parameter flash that outlives it.
pub struct Board<'f> {
    /// The simulated robot.
    pub sim: Sim,
    /// The library's controller, stepped once per control period.
    pub controller: Controller,
    /// The protocol session.
    pub session: Session<LibraryCalibrator>,
    /// Parameter storage on the simulated flash.
    pub store: ParamStore<&'f mut SimFlash>,
    assembler: LineAssembler,
    now_us: u64,
    period_us: u64,
    /// True pose when the current (or last) run started.
    run_start: Option<PoseF64>,
    running: bool,
}

impl<'f> Board<'f> {
    /// Boots: loads the parameters from `flash` (defaults and a warning if there are none),
    /// configures the controller with them and reads the encoders once. The boot message (an
    /// `event` line) is appended to `out`.
    ///
    /// # Errors
    /// An invalid controller configuration or flash range, as text.
    pub fn boot(
        config: SimConfig,
        flash: &'f mut SimParamFlash,
        out: &mut String,
    ) -> Result<Board<'f>, String> {
        let mut store = flash.store();
        let loaded = store.load_blocking();
        let settings = Settings::from(&loaded.record);
        let mut controller = default_controller(settings.active, config.rate_hz)?;
        controller
            .set_limits(settings.motion)
            .map_err(|e| format!("stored limits: {e}"))?;
        match loaded.warning {
            None => write!(out, "event boot: parameters loaded\r\n"),
            Some(w) => write!(out, "event boot: default parameters ({w})\r\n"),
        }
        .map_err(|e| e.to_string())?;
        let period_us = 1_000_000 / u64::from(config.rate_hz);
        let mut board = Board {
            sim: Sim::new(config),
            controller,
            session: Session::new(settings, LibraryCalibrator::default()),
            store,
            assembler: LineAssembler::new(),
            now_us: 0,
            period_us,
            run_start: None,
            running: false,
        };
        // The control task runs from boot on; the controller needs one encoder read to start.
        board.sim.step(&mut board.controller);
        Ok(board)
    }

    /// Simulated time since boot, microseconds.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    /// Bytes received on the serial port: assembled into lines and executed; replies are
    /// appended to `out`.
    pub fn receive(&mut self, bytes: &[u8], out: &mut String) {
        for &b in bytes {
            let Some(line) = self.assembler.push(b) else {
                continue;
            };
            match line {
                Ok(text) => {
                    let _ =
                        self.session
                            .handle_line(text, &mut self.controller, &mut self.store, out);
                }
                Err(e) => out.push_str(&line_error_reply(&e)),
            }
            self.note_run_start();
        }
    }

    /// One protocol line (terminator added); returns the reply text.
    pub fn send(&mut self, line: &str) -> String {
        let mut out = String::new();
        self.receive(line.as_bytes(), &mut out);
        self.receive(b"\r\n", &mut out);
        out
    }

    /// The button: a short press (next planned run, or clear a fault) or a long one (stop).
    pub fn press_button(&mut self, long: bool, out: &mut String) {
        let _ = if long {
            self.session.button_long(&mut self.controller, out)
        } else {
            self.session.button_short(&mut self.controller, out)
        };
        self.note_run_start();
    }

    fn note_run_start(&mut self) {
        let running = matches!(self.controller.status(), Status::Running { .. });
        if running && !self.running {
            self.run_start = Some(self.sim.true_pose());
        }
        self.running = running;
    }

    /// One control period: the controller reads the encoders and drives the motors, the robot
    /// moves, and the session gets its periodic poll (finished runs, pose stream).
    pub fn step(&mut self, out: &mut String) -> StepOutput {
        let output = self.sim.step(&mut self.controller);
        self.now_us += self.period_us;
        let _ = self.session.poll(self.now_us, &mut self.controller, out);
        self.running = matches!(self.controller.status(), Status::Running { .. });
        output
    }

    /// Whether the controller is idle (or faulted) with the wheels at rest.
    pub fn at_rest(&self) -> bool {
        !matches!(
            self.controller.status(),
            Status::Running { .. } | Status::Driving
        ) && self.controller.motors_stopped()
    }

    /// Steps until [`Board::at_rest`] or `max_periods`; returns the periods stepped.
    pub fn run_until_rest(&mut self, max_periods: u64, out: &mut String) -> u64 {
        let mut n = 0;
        while n < max_periods && !self.at_rest() {
            self.step(out);
            n += 1;
        }
        n
    }

    /// The true pose now, in the start frame of the last run (what the operator measures).
    pub fn true_pose_in_run_frame(&self) -> Option<PoseF64> {
        self.run_start.map(|s| s.relative(&self.sim.true_pose()))
    }

    /// The geometry the controller uses.
    pub fn controller_geometry(&self) -> Geometry {
        self.controller.config().geometry
    }
}

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
    /// Relative slip noise per control period (standard deviation).
    #[arg(long, default_value_t = 0.0)]
    pub slip: f64,
    /// Seed of the slip noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Control rate, Hz.
    #[arg(long, default_value_t = 1000)]
    pub rate: u32,
    /// Flash image file: loaded at boot (missing = erased flash) and written back after every
    /// command that changed the flash, so `save` survives a restart of the simulator.
    #[arg(long)]
    pub image: Option<std::path::PathBuf>,
    /// After each run, enter `measure` with the true end pose as the operator would (the line
    /// is echoed with a `> ` prefix), so a piped script can run a whole calibration.
    #[arg(long)]
    pub auto_measure: bool,
}

/// Opens a pseudo-terminal in raw mode; returns the master's file and the slave's path. The
/// slave stays open in this process so the master never sees end-of-file between clients.
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

/// Runs the simulated board on stdin/stdout or a pseudo-terminal until the input ends (stdin)
/// or the process is stopped (pty).
///
/// # Errors
/// I/O or configuration failures, as text.
pub fn run(args: &SerialArgs) -> Result<(), String> {
    let config = sim_config(args.ed, args.eb, args.slip, args.seed, args.rate);
    let mut out = String::new();
    let mut flash = match &args.image {
        Some(path) => SimParamFlash::open(path).map_err(|e| format!("{}: {e}", path.display()))?,
        None => SimParamFlash::erased(),
    };
    let mut board = Board::boot(config, &mut flash, &mut out)?;
    let (tx, rx) = mpsc::channel::<Option<Vec<u8>>>();
    let (mut writer, _slave): (Box<dyn Write>, Option<std::fs::File>) = if args.pty {
        let (master, path, slave) = open_pty()?;
        println!("pty {path}");
        eprintln!("serial: connect to {path} (e.g. picocom {path}); Ctrl-C to quit");
        let mut reader = master.try_clone().map_err(|e| e.to_string())?;
        spawn_reader(move |buf| reader.read(buf), tx);
        (Box::new(master), Some(slave))
    } else {
        spawn_reader(|buf| std::io::stdin().read(buf), tx);
        (Box::new(std::io::stdout()), None)
    };
    let slice_periods = u64::from(args.rate / 100).max(1);
    let mut pending: Vec<u8> = Vec::new();
    let mut input_done = false;
    let mut deadline = Instant::now();
    let mut was_running = false;
    let mut report_at_rest = false;
    loop {
        // Collect what has arrived.
        loop {
            match rx.try_recv() {
                Ok(Some(bytes)) => pending.extend_from_slice(&bytes),
                Ok(None) | Err(mpsc::TryRecvError::Disconnected) => {
                    input_done = true;
                    break;
                }
                Err(mpsc::TryRecvError::Empty) => break,
            }
        }
        let touched = board.store.flash().bytes_touched();
        if args.fast {
            // One line at a time, each once the robot is at rest.
            if board.at_rest()
                && let Some(end) = pending.iter().position(|&b| b == b'\n')
            {
                let line: Vec<u8> = pending.drain(..=end).collect();
                board.receive(&line, &mut out);
            }
        } else {
            board.receive(&pending, &mut out);
            pending.clear();
        }
        if let Some(path) = &args.image
            && board.store.flash().bytes_touched() != touched
        {
            let mut image = vec![0u8; SimFlash::CAPACITY];
            board.store.flash().copy_image(&mut image);
            std::fs::write(path, image).map_err(|e| format!("{}: {e}", path.display()))?;
        }
        for _ in 0..slice_periods {
            board.step(&mut out);
        }
        let running = matches!(board.controller.status(), Status::Running { .. });
        report_at_rest |= was_running && !running;
        was_running = running;
        if report_at_rest && board.at_rest() {
            report_at_rest = false;
            if let Some(line) = measure_line(&board) {
                eprintln!("sim: true end pose in the run's start frame: {line}");
                if args.auto_measure {
                    out.push_str(&format!("> {line}\r\n"));
                    out.push_str(&board.send(&line));
                }
            }
        }
        if !out.is_empty() {
            writer
                .write_all(out.as_bytes())
                .and_then(|()| writer.flush())
                .map_err(|e| e.to_string())?;
            out.clear();
        }
        let idle_input = pending.iter().all(|&b| b != b'\n');
        if input_done && idle_input && board.at_rest() {
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
        } else if pending.is_empty() && !input_done && board.at_rest() {
            // Nothing to do until input arrives.
            std::thread::sleep(Duration::from_millis(1));
        }
    }
}

/// The `measure` line for the true end pose of the last run (run start frame, heading wrapped).
pub fn measure_line(board: &Board) -> Option<String> {
    board.true_pose_in_run_frame().map(|p| {
        format!(
            "measure {:.6} {:.6} {:.4}",
            p.x_m,
            p.y_m,
            odocal::calibration::wrap_angle(p.theta_rad).to_degrees()
        )
    })
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

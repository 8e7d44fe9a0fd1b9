//! The guided session: connect, show what the board holds, the robot's setup (geometry,
//! bring-up, identification), plan, drive and measure every run, calibrate, apply, save,
//! verify, check square, summary — with every line in the session log, so it can be resumed,
//! recalibrated or exported.
//!
//! Runs are kept by *slot* (their place in the session). The board numbers its stored runs
//! 1..k; `board` maps them to slots. After a board reset that lost the runs (firmware without
//! run persistence), the logged runs stay in their slots, new runs get new slots, and the
//! calibration of all of them is computed on the PC with the library (`calibrate` on the board
//! would see only the runs it holds).

mod board_runs;
mod check;
mod fit;
mod plan;
mod results;
mod runs;
mod setup;
mod typed;

use typed::{SQUARE_SIDE_M, WHEEL_DIAMETER_M, WHEELBASE_M, length, measurement_words};

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use odocal::kinematics::geometry::Geometry;
use odocal::motion::run::{PathKind, RunRecord};
use odocal::protocol::token::{self, EventTag, LinesDropped};
use odocal::protocol::{Command, ErrorCode, ParamName};
use serde_json::json;

use crate::link::{Link, LinkError, Reply};
use crate::log::{LogContents, SessionLog, calibration_of, nominal_of, param};
use crate::ui::{AskError, Ui};

/// Options of a guided session.
#[derive(clap::Args, Debug, Clone)]
pub struct Options {
    /// Serial port of the board (e.g. /dev/ttyUSB0, or the pty `cargo sim serial --pty`
    /// prints). Without it, the candidate ports are listed.
    #[arg(long)]
    pub port: Option<String>,
    /// Session log to write (JSON lines); default target/odocal-console/session-<time>.jsonl.
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Continue the session of this log (after a crash, a disconnect or a board reset).
    #[arg(long, conflicts_with = "log")]
    pub resume: Option<PathBuf>,
    /// Answers to the questions, one a line, in order (then --yes, then stdin).
    #[arg(long)]
    pub answers: Option<PathBuf>,
    /// Take the default answer of every question that has one (apply, save and a bring-up
    /// proposal have none: they need a typed y, from --answers or stdin).
    #[arg(long, short = 'y')]
    pub yes: bool,
    /// Pose stream rate during runs, Hz.
    #[arg(long, default_value_t = 10)]
    pub stream_hz: u32,
}

/// Longest time a run may take before the tool gives up waiting (the robot is stopped first).
const RUN_TIMEOUT: Duration = Duration::from_secs(600);
/// Reply time of an ordinary command.
const REPLY: Duration = Duration::from_secs(5);
/// `calibrate` takes several seconds on the board (4.3 s measured under QEMU).
const CALIBRATE: Duration = Duration::from_secs(120);

enum Stop {
    Failed(String),
    Interrupted,
    Disconnected(String),
    /// `back` at a question whose step has no earlier question: the step before it is asked
    /// again (see [`Step`]).
    Back,
}

impl From<LinkError> for Stop {
    fn from(e: LinkError) -> Self {
        match e {
            LinkError::Interrupted => Stop::Interrupted,
            LinkError::Disconnected(why) => Stop::Disconnected(why),
            LinkError::Timeout(_) => Stop::Failed(e.to_string()),
        }
    }
}

impl From<AskError> for Stop {
    fn from(e: AskError) -> Self {
        match e {
            AskError::Interrupted => Stop::Interrupted,
            AskError::NoAnswer(_) => Stop::Failed(e.to_string()),
            AskError::Back => Stop::Back,
        }
    }
}

impl From<String> for Stop {
    fn from(e: String) -> Self {
        Stop::Failed(e)
    }
}

/// The steps of a guided session, in order. `back` at a step's first question returns to the
/// step before (a step's later questions return to its earlier ones); nothing done is undone by
/// it: a value entered stays until it is entered again, a driven run stays measured, and every
/// change not saved stays offered for `save`. A step entered again by `back` proposes to keep
/// what was done (`k`, `s`), so Enter moves nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    /// The nominal geometry (entered or kept).
    Geometry,
    /// The bring-up check (run or skipped).
    Bringup,
    /// The motor identification (run or skipped).
    Identify,
    /// On a board that holds a calibration: new runs, or a check square with it only.
    Keep,
    /// The square side and the runs per direction (and the board's runs from before).
    Plan,
    /// Driving and measuring the runs; `back` at a run's start asks the last run's measurement
    /// again.
    Runs,
    /// `calibrate`, flagged runs, apply and save.
    Results,
    /// The check square with the applied calibration.
    Check,
}

impl Step {
    fn name(self) -> &'static str {
        match self {
            Step::Geometry => "nominal geometry",
            Step::Bringup => "bring-up check",
            Step::Identify => "motor identification",
            Step::Keep => "the board's calibration",
            Step::Plan => "plan",
            Step::Runs => "runs",
            Step::Results => "calibration",
            Step::Check => "check square",
        }
    }
}

/// Where the session goes after a step.
enum Next {
    /// The next step.
    Forward,
    /// This step (the runs changed: drive what is missing, calibrate again).
    To(Step),
    /// The session's end (the summary).
    End,
}

/// What the session has done, so that a step asked again by `back` defaults to keeping it.
#[derive(Clone, Copy, Debug, Default)]
struct Done {
    geometry: bool,
    bringup: bool,
    identify: bool,
    /// The board's runs from before this session were dropped or taken.
    runs_from_before: bool,
}

/// One run of the session.
struct Slot {
    record: Option<RunRecord>,
    path: Vec<(f64, f64)>,
}

struct Guide {
    link: Link,
    ui: Ui,
    opts: Options,
    slots: Vec<Slot>,
    /// The board's runs in its store order: (the number the board gives it, slot). The board
    /// keeps a run's number for its session (a dropped run leaves a gap).
    board: Vec<(usize, usize)>,
    nominal: Geometry,
    side_m: f64,
    per_direction: u32,
    /// The method applied in this session (the plot's "after" cloud).
    applied: Option<String>,
    /// What the board held when the session connected.
    holds: setup::Holds,
    /// The operator chose to drive no more runs (`skip`).
    stop_runs: bool,
    /// Runs per direction (CW, CCW) dropped without being driven again.
    less: [u32; 2],
    /// Whether the applied calibration was saved.
    saved: bool,
    /// Changes made on the board this session and not saved yet (the nominal geometry, the
    /// wiring, the speed-loop tuning): offered for `save` even when no calibration is applied.
    pending: Vec<&'static str>,
    /// The runs (board numbers) the last `calibrate` flagged.
    flagged: Vec<usize>,
    /// The check square's end error and the runs' mean end error before (if any), metres.
    check: Option<(f64, Option<f64>)>,
    /// What the session has done (the defaults of a step asked again).
    done: Done,
}

fn log_default() -> PathBuf {
    let t = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    new_log_path(Path::new("target/odocal-console"), t)
}

/// `dir/session-<t>.jsonl`, or `session-<t>-2.jsonl`, … when a session started in the same
/// second already has that name (the log is opened for appending: two sessions must not share
/// one).
fn new_log_path(dir: &Path, t: u64) -> PathBuf {
    let mut path = dir.join(format!("session-{t}.jsonl"));
    let mut k = 2;
    while path.exists() {
        path = dir.join(format!("session-{t}-{k}.jsonl"));
        k += 1;
    }
    path
}

/// Runs the guided session.
///
/// # Errors
/// What stopped the session, as text (the log has everything up to there).
pub fn run(opts: &Options) -> Result<(), String> {
    let Some(port) = &opts.port else {
        let ports = crate::link::candidate_ports();
        let mut text = String::from("no --port given; ");
        if ports.is_empty() {
            text.push_str(
                "no USB serial port found: plug in the board's USB-UART adapter (or start \
                 `cargo sim serial --pty` and give the pty it prints)",
            );
        } else {
            text.push_str("candidate ports:");
            for p in ports {
                text.push_str(&format!("\n  cargo console --port {p}"));
            }
        }
        return Err(text);
    };
    let (log_path, resumed) = match &opts.resume {
        Some(p) => (p.clone(), Some(LogContents::read(p)?)),
        None => (opts.log.clone().unwrap_or_else(log_default), None),
    };
    // A new session never appends to an existing log (two sessions in one file).
    if resumed.is_none() && log_path.exists() {
        return Err(format!(
            "{} exists: give a new --log name, or --resume {} to continue that session",
            log_path.display(),
            log_path.display()
        ));
    }
    let answers = match &opts.answers {
        Some(p) => std::fs::read_to_string(p)
            .map_err(|e| format!("{}: {e}", p.display()))?
            .lines()
            .map(str::to_string)
            .collect(),
        None => Vec::new(),
    };
    let mut log = SessionLog::open(&log_path)?;
    log.note(
        if resumed.is_some() { "resume" } else { "start" },
        &format!("odocal-console {} on {port}", env!("CARGO_PKG_VERSION")),
    );
    let mut ui = Ui::new(answers, opts.yes);
    ui.say(&format!("odocal console: board on {port}"));
    // A port that cannot be opened, or a device that does not answer as a board, leaves no new
    // log behind (a resumed one is kept).
    let forget_log = |_: &String| {
        if resumed.is_none() {
            let _ = std::fs::remove_file(&log_path);
        }
    };
    let mut link = Link::open(port, log).inspect_err(forget_log)?;
    let version = link.handshake().inspect_err(forget_log)?;
    ui.say(&format!("session log: {}", log_path.display()));
    ui.say(&format!("board: {version}"));
    let mut g = Guide {
        link,
        ui,
        opts: opts.clone(),
        slots: Vec::new(),
        board: Vec::new(),
        nominal: Geometry::PAPER_NOMINAL,
        side_m: 2.0,
        per_direction: 5,
        applied: None,
        holds: setup::Holds::default(),
        stop_runs: false,
        less: [0, 0],
        saved: false,
        pending: Vec::new(),
        flagged: Vec::new(),
        check: None,
        done: Done::default(),
    };
    let result = g.session(resumed);
    // Ctrl-C: the robot first.
    let stopped = matches!(result, Err(Stop::Interrupted)) && g.stop_robot();
    if matches!(result, Err(Stop::Interrupted | Stop::Failed(_))) {
        // The pose stream the session turned on: a terminal opened on the port afterwards is
        // not flooded with it.
        let _ = g
            .link
            .command(&Command::Stream { on: None }.to_string(), REPLY);
    }
    if !matches!(result, Err(Stop::Disconnected(_))) {
        // The echo the handshake turned off, on again (as after a boot): a terminal opened on
        // the port afterwards shows what is typed.
        let _ = g
            .link
            .command(&Command::Echo { on: true }.to_string(), REPLY);
    }
    let svg = g.plot();
    match result {
        Ok(()) => {
            if let Some(p) = svg {
                g.ui.say(&format!("plot: {}", p.display()));
            }
            g.ui.say(&format!("session log: {}", log_path.display()));
            Ok(())
        }
        Err(Stop::Interrupted) => {
            g.link
                .log
                .note("interrupted", "Ctrl-C: robot stopped, session left");
            Err(format!(
                "Ctrl-C: {}; nothing is lost: continue with `cargo console --port {port} \
                 --resume {}`",
                if stopped {
                    "the robot is stopped"
                } else {
                    "stop sent to the robot"
                },
                log_path.display()
            ))
        }
        Err(Stop::Disconnected(why)) => {
            g.link.log.note("disconnect", &why);
            Err(format!(
                "lost the connection to the board on {port} ({why}). The robot stops by itself \
             when a run ends; every run and measurement so far is in {}: reconnect and continue \
             with `cargo console --port <PORT> --resume {}`",
                log_path.display(),
                log_path.display()
            ))
        }
        Err(Stop::Failed(e)) => Err(format!(
            "{e}\n(session log: {}; `--resume` continues it)",
            log_path.display()
        )),
        // The session's steps answer every `back`; none ends it.
        Err(Stop::Back) => Err(format!(
            "back past the session's first question\n(session log: {}; `--resume` continues it)",
            log_path.display()
        )),
    }
}

/// The tag of an event line (`None`: not an event, or one the console does not read).
fn event_tag(line: &str) -> Option<EventTag> {
    EventTag::parse(line).map(|(tag, _)| tag)
}

/// Whether two tags name the same event, whatever the run's number.
fn same_event(a: EventTag, b: EventTag) -> bool {
    std::mem::discriminant(&a) == std::mem::discriminant(&b)
}

/// `event <tag>` as the board writes it, for a message.
fn event_head(tag: EventTag) -> String {
    let mut head = String::new();
    let _ = tag.write(&mut head);
    head.trim_end_matches([' ', ':']).to_string()
}

/// The value after `key=` in a reply text.
fn field<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    text.split_whitespace()
        .find_map(|w| w.strip_prefix(key)?.strip_prefix('='))
}

fn path_text(p: &PathKind) -> String {
    match p {
        PathKind::Square { direction, side_m } => {
            format!("square {} L={side_m:.3} m", direction.as_str())
        }
        PathKind::Line { length_m } => format!("line d={length_m:.3} m"),
        PathKind::Circle {
            direction,
            radius_m,
        } => format!("circle {} r={radius_m:.3} m", direction.as_str()),
    }
}

impl Guide {
    fn cmd(&mut self, command: Command<'_>) -> Result<Reply, Stop> {
        self.cmd_timeout(command, REPLY)
    }

    /// A command; `err 10` (busy) is waited out with a message, a fault is reported.
    fn cmd_timeout(&mut self, command: Command<'_>, timeout: Duration) -> Result<Reply, Stop> {
        let line = &command.to_string();
        let mut waited = false;
        loop {
            let r = self.link.command(line, timeout)?;
            // `err 10` is something in progress (wait for it), or lines the board's input queue
            // dropped (not a reply to wait out).
            let dropped = LinesDropped::parse(r.text());
            if r.is_err(ErrorCode::Busy) && dropped.is_none() {
                if !waited {
                    self.ui.say(&format!(
                        "  the board is busy ({}): waiting for the robot to stop",
                        r.text()
                    ));
                    waited = true;
                }
                let _ = self.link.next_unsolicited(Duration::from_secs(1))?;
                continue;
            }
            return Ok(r);
        }
    }

    fn wait_event(&mut self, want: EventTag, seconds: u64) -> Result<String, Stop> {
        self.wait_event_of(&[want], seconds)
    }

    /// The first unsolicited event with one of the tags `wants`, within `seconds` (a run event
    /// of any run number when its tag in `wants` is one of a run).
    fn wait_event_of(&mut self, wants: &[EventTag], seconds: u64) -> Result<String, Stop> {
        let deadline = std::time::Instant::now() + Duration::from_secs(seconds);
        while std::time::Instant::now() < deadline {
            if let Some(l) = self.link.next_unsolicited(Duration::from_millis(200))?
                && event_tag(&l).is_some_and(|t| wants.iter().any(|w| same_event(*w, t)))
            {
                return Ok(l);
            }
        }
        Err(Stop::Failed(format!(
            "no `{}` from the board",
            wants
                .iter()
                .map(|w| event_head(*w))
                .collect::<Vec<_>>()
                .join("` or `")
        )))
    }

    fn session(&mut self, resumed: Option<LogContents>) -> Result<(), Stop> {
        self.show_board()?;
        let steps: Vec<Step> = match resumed {
            Some(c) => {
                self.resume(c)?;
                vec![Step::Runs, Step::Results, Step::Check]
            }
            None => {
                self.setup_intro(self.holds);
                let mut steps = vec![Step::Geometry, Step::Bringup, Step::Identify];
                if self.holds.calibration {
                    steps.push(Step::Keep);
                }
                steps.extend([Step::Plan, Step::Runs, Step::Results, Step::Check]);
                steps
            }
        };
        let mut i = 0;
        // The step is asked again by `back` from the next one.
        let mut back = false;
        while let Some(&step) = steps.get(i) {
            match self.step(step, back) {
                Ok(Next::Forward) => (i, back) = (i + 1, false),
                Ok(Next::To(s)) => {
                    i = steps.iter().position(|&t| t == s).unwrap_or(i + 1);
                    back = false;
                }
                Ok(Next::End) => break,
                Err(Stop::Back) if i == 0 => {
                    self.ui
                        .say("  back: there is no question before this one; asked again");
                    back = false;
                }
                Err(Stop::Back) => {
                    i -= 1;
                    back = true;
                    self.ui.say(&format!("  back to: {}", steps[i].name()));
                }
                Err(e) => return Err(e),
            }
        }
        self.summary()?;
        let _ = self.cmd(Command::Stream { on: None })?;
        Ok(())
    }

    /// One step of the session; `back`: asked again by `back` from the next step.
    fn step(&mut self, step: Step, back: bool) -> Result<Next, Stop> {
        match step {
            Step::Geometry => self.geometry_step(self.holds.geometry || self.done.geometry)?,
            Step::Bringup => self.bringup_step(self.holds.factory() && !self.done.bringup)?,
            Step::Identify => self.identify_step(self.holds.tuning || self.done.identify)?,
            Step::Keep => {
                // `c`: the check square with the board's calibration, then the summary; `back`
                // from its first question asks this one again.
                while self.keep_calibration()? {
                    match self.check_only() {
                        Err(Stop::Back) => continue,
                        r => return r.map(|()| Next::End),
                    }
                }
            }
            Step::Plan => self.plan()?,
            Step::Runs => {
                if back {
                    // The question before the results: the last run's measurement.
                    self.measure_last_again()?;
                }
                let r = self.cmd(Command::Stream {
                    on: Some(Some(self.opts.stream_hz)),
                })?;
                if !r.ok() {
                    return Err(Stop::Failed(format!("stream on: {}", r.last)));
                }
                self.drive_missing_runs()?;
            }
            Step::Results => {
                let table = self.calibrate()?;
                if self.review_flagged_runs(&table)?
                    || self.review_poor_fit(&table)?
                    || self.apply_save_verify(&table)?
                {
                    return Ok(Next::To(Step::Runs));
                }
            }
            Step::Check => {
                if self.applied.is_some() {
                    self.check_square()?;
                }
            }
        }
        Ok(Next::Forward)
    }

    /// Asks with `ask` until it gives something other than `back`, saying `why` there is no
    /// question to go back to.
    fn no_back<T>(
        &mut self,
        why: &str,
        mut ask: impl FnMut(&mut Self) -> Result<T, Stop>,
    ) -> Result<T, Stop> {
        loop {
            match ask(self) {
                Err(Stop::Back) => self.ui.say(&format!("  back: {why}")),
                r => return r,
            }
        }
    }

    /// Sends the stop key (the board stops any motion within one control period) and shows the
    /// run it aborted; whether the board confirmed the stop.
    fn stop_robot(&mut self) -> bool {
        let stopped = self.link.stop_key().is_ok() && self.wait_event(EventTag::Stopped, 2).is_ok();
        // A run in progress is reported aborted right after.
        if stopped
            && let Ok(l) =
                self.wait_event_of(&[EventTag::RunAborted(0), EventTag::RunFinished(0)], 1)
        {
            self.ui.say(&l);
        }
        stopped
    }

    /// Sets the board up again after a reset seen during a run: the echo off and the pose
    /// stream on (a boot turns the echo on and the stream off); shows what the boot said (the
    /// runs it restored).
    pub(super) fn after_reset(&mut self) -> Result<(), Stop> {
        let echo = self.cmd(Command::Echo { on: false })?;
        let stream = self.cmd(Command::Stream {
            on: Some(Some(self.opts.stream_hz)),
        })?;
        for r in [echo, stream] {
            if !r.ok() {
                return Err(Stop::Failed(format!("after the reset: {}", r.last)));
            }
        }
        while let Some(l) = self.link.next_unsolicited(Duration::ZERO)? {
            if l.starts_with(token::EVENT) {
                self.ui.say(&format!("  {l}"));
            }
        }
        Ok(())
    }

    /// `status` and `params`: geometry, calibration, faults.
    fn show_board(&mut self) -> Result<(), Stop> {
        let params = self.cmd(Command::Params)?;
        self.nominal = nominal_of(&params.data)
            .ok_or_else(|| Stop::Failed("`params` without the geometry".into()))?;
        self.link
            .log
            .entry("nominal", json!({ "params": params.data }), true);
        let n = self.nominal;
        self.ui.say(&format!(
            "geometry: D_R={:.6} m D_L={:.6} m b={:.6} m, {} counts/rev",
            n.diameter_right_m, n.diameter_left_m, n.wheelbase_m, n.counts_per_rev
        ));
        let calibration = calibration_of(&params.data);
        self.ui.say(&format!("calibration: {calibration}"));
        self.holds = setup::Holds::of(&params.data);
        if let Some(v) = param(&params.data, ParamName::SquareSide.as_str()) {
            self.side_m = v;
        }
        if let Some(v) = param(&params.data, "runs_per_direction") {
            self.per_direction = v as u32;
        }
        let status = self.cmd(Command::Status)?;
        let fault = field(status.text(), "fault").unwrap_or("none").to_string();
        self.ui.say(&format!("fault: {fault}"));
        if fault != "none" {
            self.ui.warn(&format!(
                "the board has a latched fault ({fault}): the motors are stopped. Fix the cause \
                 (likely: {}; see README, Troubleshooting)",
                runs::fault_cause(&fault)
                    .unwrap_or("a blocked wheel, a loose encoder, a miswired motor")
            ));
            let clear = self.no_back("there is no question before this one", |g| {
                Ok(g.ui.confirm("Clear the fault now", true)?)
            })?;
            if clear {
                let r = self.cmd(Command::Clear)?;
                self.ui.say(&format!("  {}", r.last));
            } else {
                return Err(Stop::Failed("a fault is latched".into()));
            }
        }
        if field(status.text(), "state") != Some("idle") {
            self.ui.say("the robot is moving: waiting for it to stop");
            loop {
                let s = self.cmd(Command::Status)?;
                if field(s.text(), "state") == Some("idle") {
                    break;
                }
                let _ = self.link.next_unsolicited(Duration::from_secs(1))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::new_log_path;

    #[test]
    fn two_sessions_started_in_the_same_second_get_two_logs() {
        let dir = std::env::temp_dir().join(format!("odocal-console-logs-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let first = new_log_path(&dir, 1_795_474_681);
        assert_eq!(first, dir.join("session-1795474681.jsonl"));
        std::fs::write(&first, "").unwrap();
        let second = new_log_path(&dir, 1_795_474_681);
        assert_eq!(second, dir.join("session-1795474681-2.jsonl"));
        std::fs::write(&second, "").unwrap();
        assert_eq!(
            new_log_path(&dir, 1_795_474_681),
            dir.join("session-1795474681-3.jsonl")
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}

//! Golden tests of the session: the exact reply text of every command, against a scripted robot,
//! an in-memory parameter store and a calibrator with known answers.
//!
//! The doubles here only record what the session asked for and return scripted values; the
//! closed-loop behaviour against the real controller and calibration is tested in host-sim.

use odocal::calibration::fit_check::FitCheck;
use odocal::motion::bringup::{CheckKind, CheckReport};
use odocal::motion::controller::{Fault, Wheel};
use odocal::motion::wiring::Wiring;
use std::fmt;

use odocal::calibration::CalibrationError;
use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::profile::MotionLimits;
use odocal::motion::run::{MAX_KNOTS, PathKind, RunRecord};
use odocal::motion::speed::{MotorParams, SpeedTuning};
use odocal::session::{
    Calibrator, Culprit, MAX_RUNS, MotorsRunning, MotorsStopped, Numbered, Reading, Robot,
    RobotError, Session, Settings, SettingsAndRuns, Solution, SolveError, Status, StoreError,
};
use odocal::storage::{FlashFault, FlashTooSmall, RunsLoaded, StoredRun};

#[derive(Default)]
struct ScriptedRobot {
    running: Option<PathKind>,
    driving: bool,
    fault: Option<Fault>,
    pose: PoseF64,
    finished: Vec<RunRecord>,
    geometry: Option<Geometry>,
    limits: Option<MotionLimits>,
    drives: Vec<(f32, f32)>,
    aborts: usize,
    totals: WheelTicks,
    wiring: Option<Wiring>,
    check: Option<CheckKind>,
    check_reports: Vec<CheckReport>,
    tuning: Option<SpeedTuning>,
    rate_hz: Option<u32>,
}

impl ScriptedRobot {
    /// Ends the current routine with the given odometry end pose.
    fn finish(&mut self, x_m: f64, y_m: f64) {
        let path = self.running.take().expect("a run is in progress");
        let mut knots = heapless::Vec::new();
        knots.push(WheelTicks::new(0, 0)).unwrap();
        self.finished.push(RunRecord {
            path,
            geometry: self.geometry.unwrap_or(Geometry::PAPER_NOMINAL),
            knots,
            odometry_end: PoseF64::new(x_m, y_m, 0.0),
            measured: None,
        });
    }
    fn check_idle(&self) -> Result<(), RobotError> {
        if let Some(f) = self.fault {
            return Err(RobotError::Fault(odocal::session::library::fault_name(&f)));
        }
        if self.running.is_some() || self.driving {
            return Err(RobotError::Busy);
        }
        Ok(())
    }
}

impl Robot for ScriptedRobot {
    fn start(&mut self, path: PathKind) -> Result<(), RobotError> {
        self.check_idle()?;
        self.running = Some(path);
        Ok(())
    }
    fn abort(&mut self) {
        self.aborts += 1;
        self.running = None;
        self.driving = false;
    }
    fn drive(&mut self, v: f32, w: f32) -> Result<(), RobotError> {
        if self.running.is_some() {
            return Err(RobotError::Busy);
        }
        self.drives.push((v, w));
        self.driving = true;
        Ok(())
    }
    fn take_finished_run(&mut self) -> Option<RunRecord> {
        if self.finished.is_empty() {
            None
        } else {
            Some(self.finished.remove(0))
        }
    }
    fn set_geometry(&mut self, g: Geometry) -> Result<(), RobotError> {
        self.check_idle()?;
        self.geometry = Some(g);
        Ok(())
    }
    fn set_limits(&mut self, l: &MotionLimits) -> Result<(), RobotError> {
        self.check_idle()?;
        self.limits = Some(*l);
        Ok(())
    }
    fn status(&mut self) -> Status {
        match (self.fault, self.running, self.driving) {
            (Some(f), _, _) => Status::Faulted(f),
            (None, Some(path), _) => Status::Running { path, segment: 0 },
            (None, None, true) => Status::Driving,
            (None, None, false) => Status::Idle,
        }
    }
    fn pose(&mut self) -> PoseF64 {
        self.pose
    }
    fn totals(&mut self) -> WheelTicks {
        self.totals
    }
    fn clear_fault(&mut self) {
        self.fault = None;
    }
    fn reset_odometry(&mut self) -> Result<(), RobotError> {
        self.check_idle()?;
        self.pose = PoseF64::default();
        Ok(())
    }
    fn motors_stopped(&mut self) -> Result<MotorsStopped, MotorsRunning> {
        if self.running.is_none() && !self.driving {
            Ok(MotorsStopped::without_controller())
        } else {
            Err(MotorsRunning)
        }
    }
    fn set_wiring(&mut self, w: Wiring) -> Result<(), RobotError> {
        self.check_idle()?;
        self.wiring = Some(w);
        Ok(())
    }
    fn start_check(&mut self, kind: CheckKind) -> Result<(), RobotError> {
        self.check_idle()?;
        self.check = Some(kind);
        Ok(())
    }
    fn take_check_report(&mut self) -> Option<CheckReport> {
        if self.check_reports.is_empty() {
            None
        } else {
            self.check = None;
            Some(self.check_reports.remove(0))
        }
    }
    fn set_tuning(&mut self, t: &SpeedTuning) -> Result<(), RobotError> {
        self.check_idle()?;
        self.tuning = Some(*t);
        Ok(())
    }
    fn set_rate(&mut self, rate_hz: u32) -> Result<(), RobotError> {
        self.check_idle()?;
        self.rate_hz = Some(rate_hz);
        Ok(())
    }
}

#[derive(Default)]
struct MemoryStore {
    saved: Option<Settings>,
    /// The committed runs, as a flash store keeps them.
    runs: Vec<RunRecord>,
    run_saves: usize,
    next_key: u8,
    /// Run saves fail (a flash driver error).
    fail_runs: bool,
    /// Nothing can be written (e.g. the part's flash is smaller than the storage map).
    unusable: Option<StoreError>,
}

impl SettingsAndRuns for MemoryStore {
    fn usable(&self) -> Result<(), StoreError> {
        self.unusable.map_or(Ok(()), Err)
    }
    fn save(&mut self, s: &Settings, _: MotorsStopped) -> Result<(), StoreError> {
        self.saved = Some(s.clone());
        Ok(())
    }
    fn save_runs(
        &mut self,
        runs: &[RunRecord],
        ids: &mut [Option<StoredRun>],
        _: MotorsStopped,
    ) -> Result<(), StoreError> {
        if self.fail_runs {
            return Err(StoreError::Flash(FlashFault::Other));
        }
        for id in ids.iter_mut().filter(|id| id.is_none()) {
            self.next_key = self.next_key.wrapping_add(1);
            *id = Some(StoredRun {
                key: self.next_key,
                serial: u32::from(self.next_key),
            });
        }
        self.runs = runs.to_vec();
        self.run_saves += 1;
        Ok(())
    }
    fn load_runs(
        &mut self,
        runs: &mut heapless::Vec<RunRecord, MAX_RUNS>,
        ids: &mut heapless::Vec<Option<StoredRun>, MAX_RUNS>,
    ) -> RunsLoaded {
        runs.clear();
        ids.clear();
        for (i, r) in self.runs.iter().enumerate() {
            runs.push(r.clone()).unwrap();
            ids.push(Some(StoredRun {
                key: i as u8,
                serial: i as u32,
            }))
            .unwrap();
        }
        RunsLoaded {
            found: self.run_saves > 0,
            restored: self.runs.len(),
            measured: self.runs.iter().filter(|r| r.measured.is_some()).count(),
            skipped: 0,
            problem: None,
        }
    }
}

/// Known answers: `alpha` succeeds with fixed factors, `beta` always fails, `wild` succeeds
/// with an `E_b` the parameter record refuses to store.
struct KnownCalibrator {
    solves: usize,
    runs_changes: usize,
}

impl Calibrator for KnownCalibrator {
    fn methods(&self) -> &[&'static str] {
        &["alpha", "beta", "wild"]
    }
    fn runs_changed(&mut self) {
        self.runs_changes += 1;
    }
    fn solve(
        &mut self,
        runs: &[RunRecord],
        nominal: &Geometry,
        method: &str,
    ) -> Result<Solution, SolveError> {
        self.solves += 1;
        assert!(runs.iter().any(|r| r.measured.is_some()));
        match method {
            "alpha" => Ok(Solution {
                e_d: 0.995,
                e_b: 1.01,
                e_s: 1.0,
                geometry: nominal.with_factors(0.995, 1.01, 1.0),
                e_max_m: Some(0.0012),
                sd_e_d: Some(2.5e-4),
                sd_e_b: None,
                residuals: heapless::Vec::new(),
            }),
            "beta" => Err(SolveError::Failed(CalibrationError::Degenerate)),
            "wild" => Ok(Solution {
                e_d: 1.0,
                e_b: 1.3,
                e_s: 1.0,
                geometry: nominal.with_factors(1.0, 1.3, 1.0),
                e_max_m: None,
                sd_e_d: None,
                sd_e_b: None,
                residuals: heapless::Vec::new(),
            }),
            _ => Err(SolveError::UnknownMethod),
        }
    }
    /// Its reading changes nothing of its known answers.
    fn set_reading(&mut self, _: Reading) {}
    /// Its results carry no residuals to check.
    fn fit_check(&mut self, _: &[RunRecord], _: &Geometry) -> Option<FitCheck> {
        None
    }
    /// Known prediction errors: `alpha` 2 mm, `wild` 50 mm, `beta` none (it never solves).
    fn prediction_error(&mut self, _: &[RunRecord], _: &Geometry, method: &str) -> Option<f64> {
        match method {
            "alpha" => Some(0.002),
            "wild" => Some(0.05),
            _ => None,
        }
    }
    /// Its results carry no per-run residuals: no run to name.
    fn culprit(&mut self, _: &[RunRecord], _: &Geometry) -> Culprit {
        Culprit::CannotTell
    }
    fn advice(
        &mut self,
        _: Numbered<'_>,
        _: &Geometry,
        only: Option<&str>,
        out: &mut dyn fmt::Write,
    ) -> fmt::Result {
        write!(
            out,
            "  advice {} L=2.000 m is adequate\r\n",
            only.unwrap_or("all")
        )
    }
}

struct Bench {
    session: Session<KnownCalibrator>,
    robot: ScriptedRobot,
    store: MemoryStore,
}

impl Bench {
    fn new() -> Self {
        Bench {
            session: Session::new(
                Settings::default(),
                KnownCalibrator {
                    solves: 0,
                    runs_changes: 0,
                },
            ),
            robot: ScriptedRobot::default(),
            store: MemoryStore::default(),
        }
    }
    fn send(&mut self, line: &str) -> String {
        let mut out = String::new();
        self.session
            .handle_line(line, &mut self.robot, &mut self.store, &mut out)
            .unwrap();
        out
    }
    fn poll(&mut self, now_us: u64) -> String {
        let mut out = String::new();
        self.session
            .poll(now_us, &mut self.robot, &mut self.store, &mut out)
            .unwrap();
        out
    }
    /// Runs one square in `dir`, ending at odometry (x, y), and measures it at (mx, my).
    fn measured_run(&mut self, dir: &str, x: f64, y: f64, mx: f64, my: f64) {
        assert!(self.send(&format!("run {dir}")).starts_with("ok run"));
        self.robot.finish(x, y);
        assert!(self.poll(0).starts_with("event run"));
        assert!(
            self.send(&format!("measure {mx}m {my}m"))
                .starts_with("ok run")
        );
    }
}

#[test]
fn params_golden() {
    let mut b = Bench::new();
    assert_eq!(
        b.send("params"),
        "  d_right 0.150000000 m\r\n\
         \x20 d_left 0.150000000 m\r\n\
         \x20 wheelbase 0.385000000 m\r\n\
         \x20 counts_per_rev 200000 counts/rev\r\n\
         \x20 max_speed 0.300 m/s\r\n\
         \x20 max_accel 0.300 m/s^2\r\n\
         \x20 max_turn_rate 1.000 rad/s\r\n\
         \x20 max_turn_accel 2.000 rad/s^2\r\n\
         \x20 square_side 2.000 m\r\n\
         \x20 runs_per_direction 5 runs\r\n\
         \x20 motor_right_sign 1 (1 standard, -1 reversed)\r\n\
         \x20 motor_left_sign 1 (1 standard, -1 reversed)\r\n\
         \x20 encoder_right_sign 1 (1 standard, -1 reversed)\r\n\
         \x20 encoder_left_sign 1 (1 standard, -1 reversed)\r\n\
         \x20 motor_right_gain_fwd 1.0000 m/s per duty\r\n\
         \x20 motor_right_gain_back 1.0000 m/s per duty\r\n\
         \x20 motor_right_tau 0.0500 s\r\n\
         \x20 motor_right_deadband 0.0000 duty\r\n\
         \x20 motor_left_gain_fwd 1.0000 m/s per duty\r\n\
         \x20 motor_left_gain_back 1.0000 m/s per duty\r\n\
         \x20 motor_left_tau 0.0500 s\r\n\
         \x20 motor_left_deadband 0.0000 duty\r\n\
         \x20 speed_bandwidth 30.0000 rad/s\r\n\
         \x20 control_hz 1000 Hz\r\n\
         \x20 measure_sd 0.001000 m\r\n\
         \x20 heading_sd 0.200 deg\r\n\
         \x20 speed_loop right kp=3.500 ki=135.000 kii=1350.000 ff_fwd=1.0000 ff_back=1.0000 ff_accel=0.0500 deadband=0.0000\r\n\
         \x20 speed_loop left kp=3.500 ki=135.000 kii=1350.000 ff_fwd=1.0000 ff_back=1.0000 ff_accel=0.0500 deadband=0.0000\r\n\
         \x20 active d_right=0.150000000 d_left=0.150000000 wheelbase=0.385000000 m\r\n\
         \x20 calibration none\r\n\
         \x20 convention standard\r\n\
         ok\r\n"
    );
}

#[test]
fn help_lists_every_command_then_ok() {
    let mut b = Bench::new();
    assert_eq!(
        b.send("help"),
        "  help                           this list\r\n\
         \x20 status                         state, pose, faults, session progress\r\n\
         \x20 params                         parameters and the active calibration\r\n\
         \x20 set <name> <value>             change a parameter (params; measure_unit, heading_unit)\r\n\
         \x20 run cw|ccw [L]                 drive a square of side L m (default: planned side)\r\n\
         \x20 next                           start the next planned run (button short press)\r\n\
         \x20 line [d]                       drive straight d m\r\n\
         \x20 circle cw|ccw [r]              drive a full circle of radius r m\r\n\
         \x20 stop                           stop now (Ctrl-C or Esc also stop at once)\r\n\
         \x20 clear                          clear a latched fault (stall, glitch, following)\r\n\
         \x20 measure [#n] <x> <y> [th]      true end pose of the last run, or of run n, units written (5mm 1cm 2deg)\r\n\
         \x20 runs                           list stored runs\r\n\
         \x20 record <n> [first]             run n's full record with its tick knots (host tools)\r\n\
         \x20 drop <n>|all yes               delete run n, or every run\r\n\
         \x20 calibrate [method]             compute all methods (or one) from measured runs\r\n\
         \x20 convention [name]              how measured runs are read (y-right, ...)\r\n\
         \x20 apply <method> [yes]           use a method's result (then save; yes: with a flagged run)\r\n\
         \x20 apply online <E_d> <E_b> <E_s> use factors computed elsewhere (then save)\r\n\
         \x20 save                           store parameters in flash (motors stopped)\r\n\
         \x20 reset-params [yes]             restore the defaults (then save; yes: discard changes)\r\n\
         \x20 pose                           odometry pose\r\n\
         \x20 odom reset                     set the odometry pose to the origin\r\n\
         \x20 bringup [motors|push]          wiring check: motor pulses (wheels up) or a hand push\r\n\
         \x20 identify [lifted|floor]        motor identification: duty steps, fit, speed-loop tuning\r\n\
         \x20 stream on [hz]|off             pose + wheel speed stream, 1..100 Hz\r\n\
         \x20 drive <v_mps> <w_radps>        velocity command, motors stop 500 ms after the last\r\n\
         \x20 echo on|off                    echo typed characters (on at boot; scripts: off)\r\n\
         \x20 version                        firmware and protocol version\r\n\
         ok 28 commands\r\n"
    );
}

#[test]
fn set_golden_and_pushes_to_the_robot() {
    let mut b = Bench::new();
    assert_eq!(
        b.send("set max_speed 0.5"),
        "ok max_speed = 0.500 m/s (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.limits.unwrap().max_speed_mps, 0.5);
    assert_eq!(
        b.send("set wheelbase 0.4"),
        "ok wheelbase = 0.400000000 m (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.geometry.unwrap().wheelbase_m, 0.4);
    assert_eq!(
        b.send("set runs_per_direction 3"),
        "ok runs_per_direction = 3 runs (not saved; save to keep)\r\n"
    );
    assert_eq!(
        b.send("set square_side 1.5"),
        "ok square_side = 1.500 m (not saved; save to keep)\r\n"
    );
    // The geometry is checked as a whole.
    assert_eq!(
        b.send("set d_right 2"),
        "err 17: d_right/d_left would be 13.333, outside 0.5..2 (change the other diameter \
         first, or both in steps)\r\n"
    );
    assert_eq!(
        b.send("set wheelbase 0.01"),
        "err 17: wheelbase/wheel diameter would be 0.067, outside 0.5..50\r\n"
    );
    assert_eq!(b.session.settings().nominal.wheelbase_m, 0.4);
    assert_eq!(
        b.send("set max_speed 0.5"),
        "ok max_speed = 0.500 m/s (unchanged)\r\n"
    );
    // Out-of-range values never reach the settings.
    assert_eq!(
        b.send("set max_speed 2.01"),
        "err 6: <value> must be within 0.01..2 m/s\r\n"
    );
    assert_eq!(b.session.settings().motion.max_speed_mps, 0.5);
    // Busy robot: the change is refused and not kept.
    b.send("run cw");
    assert_eq!(
        b.send("set max_speed 0.2"),
        "err 10: a run is in progress (square cw L=1.500 m): wait for it to finish\r\n"
    );
    assert_eq!(b.session.settings().motion.max_speed_mps, 0.5);
}

#[test]
fn control_rate_is_set_validated_pushed_and_saved() {
    let mut b = Bench::new();
    assert_eq!(b.session.settings().control_hz, 1000);
    assert_eq!(
        b.send("set control_hz 10000"),
        "ok control_hz = 10000 Hz (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.rate_hz, Some(10_000));
    // Within 1..10 kHz but not a rate the timers divide to: refused, nothing changes.
    let rule = "err 17: control rate must be 1000, 2000, 4000, 5000, 8000 or 10000 Hz \
                (1..10 kHz, whole kHz with a whole number of microseconds per period)\r\n";
    assert_eq!(b.send("set control_hz 3000"), rule);
    assert_eq!(b.send("set control_hz 2500"), rule);
    assert_eq!(
        b.send("set control_hz 20000"),
        "err 6: <value> must be within 1000..10000 Hz\r\n"
    );
    assert!(b.send("set control_hz 1000.5").starts_with("err "));
    assert_eq!(b.robot.rate_hz, Some(10_000));
    assert_eq!(b.session.settings().control_hz, 10_000);
    assert_eq!(
        b.send("set control_hz 10000"),
        "ok control_hz = 10000 Hz (unchanged)\r\n"
    );
    assert!(b.send("params").contains("  control_hz 10000 Hz\r\n"));
    assert!(b.send("save").starts_with("ok"));
    assert_eq!(b.store.saved.as_ref().map(|s| s.control_hz), Some(10_000));
    // Only while idle.
    b.send("run cw");
    assert_eq!(
        b.send("set control_hz 2000"),
        "err 10: a run is in progress (square cw L=2.000 m): wait for it to finish\r\n"
    );
    assert_eq!(b.robot.rate_hz, Some(10_000));
}

#[test]
fn run_lifecycle_golden() {
    let mut b = Bench::new();
    assert_eq!(
        b.send("measure 0.01m 0.02m"),
        "err 12: no finished run to measure (run cw|ccw or next first)\r\n"
    );
    assert_eq!(
        b.send("run cw"),
        "ok run 1 started: square cw L=2.000 m\r\n"
    );
    assert_eq!(
        b.send("run ccw"),
        "err 10: a run is in progress (square cw L=2.000 m): wait for it to finish\r\n"
    );
    assert_eq!(
        b.send("status"),
        "ok state=running square cw L=2.000 m fault=none x=+0.000000 y=+0.000000 \
         theta_deg=+0.0000 plan cw 0/5 ccw 0/5 measured cw 0 ccw 0 runs 0/12 calibration=none\r\n"
    );
    b.robot.finish(0.0123, -0.0045);
    assert_eq!(
        b.poll(1_000),
        "event run 1 finished: square cw L=2.000 m odometry end x=+0.012300 y=-0.004500 \
         theta_deg=+0.0000; measure it\r\n"
    );
    assert_eq!(
        b.send("measure 0.0223m -0.0145m 0.5deg"),
        "ok run 1 square cw L=2.000 m measured: read x=+22.300 mm y=-14.500 mm theta=+0.50 deg; \
         error vs odometry dx=+0.010000 dy=-0.010000 m\r\n"
    );
    // A second plain `measure` never replaces silently: it needs the run number.
    assert_eq!(
        b.send("measure 0.0223m -0.0145m"),
        "err 12: run 1 is already measured (measure #1 x y [theta] replaces it)\r\n"
    );
    assert_eq!(
        b.send("measure #1 0.0233m -0.0145m"),
        "ok run 1 square cw L=2.000 m measured (replaced x=+0.022300 y=-0.014500 \
         theta_deg=+0.5000): read x=+23.300 mm y=-14.500 mm; error vs odometry dx=+0.011000 dy=-0.010000 m (heading kept: \
         theta_deg=+0.5000)\r\n"
    );
    assert_eq!(
        b.send("measure #2 0m 0m"),
        "err 14: no run 2 (1 stored)\r\n"
    );
    assert_eq!(b.send("line 1"), "ok run 2 started: line d=1.000 m\r\n");
    // A finished run is collected before the next command runs, without an explicit poll.
    b.robot.finish(1.0, 0.0);
    assert_eq!(
        b.send("runs"),
        "event run 2 finished: line d=1.000 m odometry end x=+1.000000 y=+0.000000 \
         theta_deg=+0.0000; measure it\r\n\
         \x20 run 1 square cw L=2.000 m odometry x=+0.012300 y=-0.004500 measured x=+0.023300 \
         y=-0.014500 theta_deg=+0.5000\r\n\
         \x20 run 2 line d=1.000 m odometry x=+1.000000 y=+0.000000 not measured\r\n\
         ok 2 runs, 1 measured\r\n"
    );
    assert_eq!(b.send("drop 3"), "err 14: no run 3 (2 stored)\r\n");
    // A run is measured or dropped before the next one starts (by command or button).
    // Nothing moves the robot away from the end it is to be measured at.
    for start in [
        "run cw",
        "next",
        "line",
        "circle cw 0.5",
        "drive 0.1 0",
        "identify floor",
        "identify",
        "bringup",
        "bringup push",
    ] {
        assert_eq!(
            b.send(start),
            "err 24: run 2 (line d=1.000 m) is not measured yet: measure it or drop it first \
             (measure x y [theta], or drop 2)\r\n",
            "{start}"
        );
    }
    let mut out = String::new();
    b.session.button_short(&mut b.robot, &mut out).unwrap();
    assert_eq!(
        out,
        "event button: err 24: run 2 (line d=1.000 m) is not measured yet: measure it or drop \
         it first (measure x y [theta], or drop 2)\r\n"
    );
    assert_eq!(b.robot.running, None);
    assert_eq!(
        b.send("measure 1.001m 0.002m"),
        "ok run 2 line d=1.000 m measured: read x=+1001.000 mm y=+2.000 mm; error vs odometry \
         dx=+0.001000 dy=+0.002000 m\r\n"
    );
    // Squares beyond the plan are counted apart.
    b.send("set runs_per_direction 1");
    for _ in 0..2 {
        b.send("run cw");
        b.robot.finish(0.0, 0.0);
        b.send("measure 0.001m 0.001m");
    }
    let status = b.send("status");
    assert!(
        status.contains(" plan cw 1/1 ccw 0/1 (+2 extra) measured cw 3 ccw 0 runs 4/12 "),
        "{status}"
    );
    b.send("drop 4");
    b.send("drop 3");
    b.send("set runs_per_direction 5");
    assert_eq!(
        b.send("drop 2"),
        "ok dropped run 2: line d=1.000 m; 1 run left\r\n"
    );
    assert_eq!(
        b.send("circle ccw"),
        "ok run 5 started: circle ccw r=1.000 m\r\n"
    );
    assert_eq!(
        b.send("measure 0.0223m -0.0145m"),
        "err 10: a run is driving: measure after its `event run … finished` line\r\n"
    );
    assert_eq!(
        b.send("stop"),
        "event run 5 aborted, not stored: circle ccw r=1.000 m\r\n\
         ok stopped: run 5 aborted, not stored\r\n"
    );
    assert_eq!(b.robot.aborts, 1);
    assert_eq!(b.send("stop"), "ok stopped\r\n");
    // The aborted run's measurement must not land on run 1.
    assert_eq!(
        b.send("measure 0.0223m -0.0145m"),
        "err 12: run 5 was aborted and not stored: nothing to measure (drive it again; \
         measure #<n> x y fills an earlier run)\r\n"
    );
    assert_eq!(b.session.runs().len(), 1);
}

#[test]
fn runs_keep_their_numbers_when_one_is_dropped() {
    let mut b = Bench::new();
    b.measured_run("cw", 0.01, -0.02, 0.012, -0.018);
    b.measured_run("ccw", 0.02, 0.01, 0.021, 0.012);
    assert_eq!(
        b.send("drop 1"),
        "ok dropped run 1: square cw L=2.000 m; 1 run left\r\n"
    );
    assert_eq!(
        b.send("runs"),
        "\x20 run 2 square ccw L=2.000 m odometry x=+0.020000 y=+0.010000 measured x=+0.021000 \
         y=+0.012000\r\n\
         ok 1 run, 1 measured\r\n"
    );
    // Numbers typed from the list before still mean the same runs.
    assert_eq!(b.send("drop 1"), "err 14: no run 1 (1 stored)\r\n");
    assert!(
        b.send("measure #2 21mm 13mm")
            .starts_with("ok run 2 square ccw")
    );
    assert!(b.send("record 2").contains("ok"));
    // The next run gets a new number, never a dropped one.
    assert_eq!(
        b.send("run cw"),
        "ok run 3 started: square cw L=2.000 m\r\n"
    );
    b.robot.finish(0.0, 0.0);
    assert!(b.poll(0).starts_with("event run 3 finished"));
    assert_eq!(
        b.send("drive 0.1 0"),
        "err 24: run 3 (square cw L=2.000 m) is not measured yet: measure it or drop it first \
         (measure x y [theta], or drop 3)\r\n"
    );
    assert!(b.send("measure 1mm 2mm").starts_with("ok run 3 "));
    assert_eq!(b.send("drive 0.1 0"), "ok\r\n");
}

#[test]
fn stop_keys_and_garbled_stop_lines_stop() {
    use odocal::protocol::{LineError, LineEvent, StopKey};
    let event = |b: &mut Bench, e: LineEvent<'_>| {
        let mut out = String::new();
        b.session
            .handle_event(e, &mut b.robot, &mut b.store, &mut out)
            .unwrap();
        out
    };
    let mut b = Bench::new();
    // Idle: nothing moves, nothing to say.
    assert_eq!(event(&mut b, LineEvent::Stop(StopKey::Escape)), "");
    assert_eq!(
        event(&mut b, LineEvent::Stop(StopKey::CtrlC)),
        "event stopped (Ctrl-C)\r\n"
    );
    b.send("run cw");
    assert_eq!(
        event(&mut b, LineEvent::Stop(StopKey::CtrlC)),
        "event stopped (Ctrl-C)\r\nevent run 1 aborted, not stored: square cw L=2.000 m\r\n"
    );
    b.send("drive 0.1 0");
    assert_eq!(
        event(&mut b, LineEvent::Stop(StopKey::Escape)),
        "event stopped (Esc)\r\n"
    );
    assert!(!b.robot.driving);
    b.send("run cw");
    assert_eq!(
        event(
            &mut b,
            LineEvent::Rejected {
                error: LineError::ReceiveError,
                stop: true
            }
        ),
        "event run 1 aborted, not stored: square cw L=2.000 m\r\n\
         ok stopped: run 1 aborted, not stored\r\n"
    );
    assert_eq!(
        event(
            &mut b,
            LineEvent::Rejected {
                error: LineError::ReceiveError,
                stop: false
            }
        ),
        "err 21: receive error (overrun, framing or noise) in this line, ignored\r\n"
    );
    // Stray text before `stop` does not keep it from stopping.
    b.send("run ccw");
    assert_eq!(
        b.send("~~ stop"),
        "event run 1 aborted, not stored: square ccw L=2.000 m\r\n\
         ok stopped: run 1 aborted, not stored\r\n"
    );
    // A fault ends the run too, and says so.
    b.send("run cw");
    b.robot.running = None;
    b.robot.fault = Some(Fault::Stall {
        wheel: Wheel::Right,
    });
    assert_eq!(
        b.poll(0),
        "event run 1 aborted, not stored: square cw L=2.000 m (fault: stall)\r\n\
         event fault: Right wheel stalled\r\n"
    );
    // Echo is on at boot, for a person at a terminal.
    assert!(b.session.echo());
    assert_eq!(b.send("echo off"), "ok echo off\r\n");
    assert!(!b.session.echo());
    assert_eq!(b.send("echo on"), "ok echo on\r\n");
}

#[test]
fn units_are_never_inferred_and_an_implausible_end_needs_yes() {
    let mut b = Bench::new();
    b.send("run cw");
    b.robot.finish(0.0123, -0.0045);
    b.poll(0);
    // A bare value has no unit until the session declares one: the reply names the units.
    assert_eq!(
        b.send("measure -0.5355 -0.5326"),
        "err 26: <x> -0.5355 has no unit: write mm, cm or m after it (-0.5355mm), or declare one for this session: set measure_unit mm|cm|m\r\n"
    );
    assert_eq!(
        b.send("measure 41.841mm 39.523mm -1.5"),
        "err 26: <theta> -1.5 has no unit: write deg or rad after it (-1.5deg), or declare one for this session: set heading_unit deg|rad\r\n"
    );
    // 41.841 mm typed as metres: far beyond what the nominal geometry's tolerance allows on a
    // 2 m square; kept only with yes.
    assert_eq!(
        b.send("measure 41.841m 39.523m"),
        "err 22: run 1 square cw L=2.000 m: measured end 57.551 m from the odometry end, more than 0.661 m (the nominal geometry's tolerance on this path, plus measuring): check the values, their units and signs, or add yes to keep it\r\n"
    );
    assert_eq!(
        b.send("measure 0.041841m 0.039523m 60deg"),
        "err 22: run 1 square cw L=2.000 m: measured heading +60.0 deg from the odometry heading, more than 28.3 deg (the nominal geometry's tolerance on this path, plus measuring): check the values, their units and signs, or add yes to keep it\r\n"
    );
    assert_eq!(b.session.runs()[0].measured, None);
    // Units written against the number or apart from it; the reply echoes the values as read.
    assert_eq!(
        b.send("measure 41.841 mm 3.9523 cm -0.02618 rad"),
        "ok run 1 square cw L=2.000 m measured: read x=+41.841 mm y=+39.523 mm theta=-1.50 deg; error vs odometry dx=+0.029541 dy=+0.044023 m\r\n"
    );
    let m = b.session.runs()[0].measured.unwrap();
    assert_eq!((m.x_m, m.y_m), (41.841 * 0.001, 3.9523 * 0.01));
    assert!((m.theta_rad.unwrap() + 0.02618).abs() < 1e-15);
    // A declared unit reads the bare values for the rest of the session.
    assert_eq!(
        b.send("set measure_unit cm"),
        "ok measure_unit = cm: bare measure values are cm (this session only, not saved)\r\n"
    );
    assert_eq!(
        b.send("set heading_unit deg"),
        "ok heading_unit = deg: bare heading values are deg (this session only, not saved)\r\n"
    );
    assert_eq!(
        b.send("measure #1 4.1841 3.9523 -1.5"),
        "ok run 1 square cw L=2.000 m measured (replaced x=+0.041841 y=+0.039523 theta_deg=-1.5000): read x=+41.841 mm y=+39.523 mm theta=-1.50 deg; error vs odometry dx=+0.029541 dy=+0.044023 m\r\n"
    );
    // Beyond the bound with yes: kept as typed.
    assert!(
        b.send("measure #1 41.841m 39.523m yes")
            .starts_with("ok run 1 ")
    );
    assert_eq!(b.session.runs()[0].measured.unwrap().x_m, 41.841);
    // The declarations are not settings: a new session (a reboot) has none.
    let mut fresh = Bench::new();
    fresh.send("run cw");
    fresh.robot.finish(0.0, 0.0);
    fresh.poll(0);
    assert!(
        fresh
            .send("measure 1 2")
            .starts_with("err 26: <x> 1 has no unit")
    );
}

#[test]
fn calibrate_refused_until_both_directions_measured() {
    let mut b = Bench::new();
    // A misspelt method is named as such before anything else.
    assert_eq!(
        b.send("calibrate exakt"),
        "err 7: unknown method; one of alpha|beta|wild\r\n"
    );
    assert_eq!(
        b.send("apply exakt"),
        "err 7: unknown method; one of alpha|beta|wild\r\n"
    );
    assert_eq!(
        b.send("calibrate"),
        "err 13: need measured square runs in both directions (measured: cw 0, ccw 0)\r\n"
    );
    b.measured_run("cw", 0.01, 0.0, 0.02, 0.01);
    b.measured_run("cw", 0.01, 0.0, 0.02, 0.01);
    // An unmeasured CCW run does not count.
    b.send("run ccw");
    b.robot.finish(0.0, 0.0);
    assert_eq!(
        b.send("calibrate"),
        "event run 3 finished: square ccw L=2.000 m odometry end x=+0.000000 y=+0.000000 \
         theta_deg=+0.0000; measure it\r\n\
         err 13: need measured square runs in both directions (measured: cw 2, ccw 0)\r\n"
    );
    assert_eq!(
        b.send("apply alpha"),
        "err 13: need measured square runs in both directions (measured: cw 2, ccw 0)\r\n"
    );
    assert_eq!(b.session.calibrator().solves, 0);
}

#[test]
fn calibrate_apply_save_golden() {
    let mut b = Bench::new();
    b.measured_run("cw", 0.01, 0.0, 0.02, 0.01);
    b.measured_run("ccw", 0.01, 0.0, 0.02, 0.01);
    let table = "  method       E_d          E_b          E_s          D_R_mm     D_L_mm     b_mm       \
                 loo_mm    E_max_mm  sd_E_d    sd_E_b\r\n\
                 \x20 alpha        0.995000000  1.010000000  1.000000000  149.6241   150.3759   388.8500   \
                 2.000     1.200     2.500e-4  n/a  [lowest loo]\r\n\
                 \x20 beta         failed: degenerate: the runs do not determine every factor\r\n\
                 \x20 wild         1.000000000  1.300000000  1.000000000  150.0000   150.0000   500.5000   \
                 50.000    -         n/a       n/a\r\n\
                 \x20 advice all L=2.000 m is adequate\r\n\
                 ok 2 solved from 2 measured runs (cw 1, ccw 1); apply <method> to use one\r\n";
    assert_eq!(b.send("calibrate"), table);
    // Runs are kept across calibrate: the same answer again.
    assert_eq!(b.send("calibrate"), table);
    assert_eq!(b.send("runs").lines().count(), 3);
    assert_eq!(
        b.send("calibrate gamma"),
        "err 7: unknown method; one of alpha|beta|wild\r\n"
    );
    // One method: its row and its advice only.
    assert_eq!(
        b.send("calibrate alpha").lines().last(),
        Some("ok 1 solved from 2 measured runs (cw 1, ccw 1); apply <method> to use one")
    );
    assert!(
        b.send("calibrate alpha")
            .contains("  advice alpha L=2.000 m")
    );
    assert_eq!(
        b.send("calibrate beta"),
        "  method       E_d          E_b          E_s          D_R_mm     D_L_mm     b_mm       \
         loo_mm    E_max_mm  sd_E_d    sd_E_b\r\n\
         \x20 beta         failed: degenerate: the runs do not determine every factor\r\n\
         err 16: no method succeeded (check the measurements: runs)\r\n"
    );
    // One rule for apply and save: what the record cannot store is not applied.
    let refused = "err 17: parameters not storable: E_d, E_b and E_s must be within 0.8..1.25\r\n";
    assert_eq!(b.send("apply wild"), refused);
    assert_eq!(b.session.settings().calibration, None);
    let mut wild = Settings::default();
    wild.active = wild.nominal.with_factors(1.0, 1.3, 1.0);
    wild.calibration = Some(odocal::session::AppliedCalibration {
        method: heapless::String::try_from("wild").unwrap(),
        e_d: 1.0,
        e_b: 1.3,
        e_s: 1.0,
        runs_used: 2,
        e_max_m: 0.0,
    });
    assert_eq!(
        format!(
            "err 17: {}\r\n",
            odocal::session::storable(&wild).unwrap_err()
        ),
        refused
    );
    assert_eq!(
        b.send("apply beta"),
        "err 16: degenerate: the runs do not determine every factor\r\n"
    );
    assert_eq!(
        b.send("apply ALPHA"),
        "ok applied alpha: E_d=0.995000000 E_b=1.010000000 E_s=1.000000000 (not saved; save to keep)\r\n"
    );
    let expected = Geometry::PAPER_NOMINAL.with_factors(0.995, 1.01, 1.0);
    assert_eq!(b.robot.geometry, Some(expected));
    let params = b.send("params");
    assert!(params.contains(
        "  active d_right=0.149624060 d_left=0.150375940 wheelbase=0.388850000 m\r\n\
         \x20 calibration alpha E_d=0.995000000 E_b=1.010000000 E_s=1.000000000 runs=2 E_max=1.200 mm\r\n"
    ), "{params}");
    b.send("drive 0.1 0");
    assert_eq!(
        b.send("save"),
        "err 18: motors not confirmed stopped (running, or the control loop has not run yet), flash \
         not written\r\n"
    );
    assert!(b.store.saved.is_none());
    // Nothing that takes seconds (the exact solve) or changes parameters while moving: the
    // console must stay free for `stop`.
    for busy in ["calibrate", "apply alpha", "set square_side 1"] {
        assert_eq!(
            b.send(busy),
            "err 10: drive is in progress: wait for the motors to stop (500 ms after the last drive)\r\n",
            "{busy}"
        );
    }
    b.send("stop");
    assert_eq!(b.send("save"), "ok saved\r\n");
    assert_eq!(b.store.saved.as_ref(), Some(b.session.settings()));
    // Re-entering a value changes nothing.
    assert_eq!(
        b.send("set d_left 0.150"),
        "ok d_left = 0.150000000 m (unchanged)\r\n"
    );
    assert!(b.session.settings().calibration.is_some());
    // A geometry change drops the calibration (its factors were relative to the old nominal),
    // says so, and setting the old value back restores it.
    let applied = b.session.settings().clone();
    assert_eq!(
        b.send("set d_left 0.151"),
        "ok d_left = 0.151000000 m (calibration alpha dropped: it is relative to the old \
         geometry; set the old value back to restore it) (not saved; save to keep)\r\n"
    );
    assert_eq!(b.session.settings().calibration, None);
    assert_eq!(
        b.send("set d_left 0.15"),
        "ok d_left = 0.150000000 m (calibration alpha restored) (not saved; save to keep)\r\n"
    );
    assert_eq!(b.session.settings(), &applied);
    assert_eq!(b.robot.geometry, Some(applied.active));
    b.send("set d_left 0.151");
    let saved = b.store.saved.clone();
    // A change not saved is not discarded without a yes.
    assert_eq!(
        b.send("reset-params"),
        "err 25: reset-params discards changes not saved: type reset-params yes to do it (save \
         first to keep them)\r\n"
    );
    assert_eq!(b.session.settings().nominal.diameter_left_m, 0.151);
    assert_eq!(
        b.send("reset-params yes"),
        "ok parameters reset to defaults (not saved; save to keep)\r\n"
    );
    assert_eq!(b.session.settings(), &Settings::default());
    // RAM only: the flash keeps what was saved until `save`.
    assert_eq!(b.store.saved, saved);
    assert_eq!(b.send("save"), "ok saved\r\n");
    assert_eq!(b.store.saved.as_ref(), Some(&Settings::default()));
}

#[test]
fn next_alternates_and_completes_the_plan() {
    let mut b = Bench::new();
    b.send("set runs_per_direction 2");
    let mut dirs = Vec::new();
    for k in 1..=4 {
        let reply = b.send("next");
        dirs.push(reply.clone());
        b.robot.finish(0.0, 0.0);
        let dir = if k % 2 == 1 { "cw" } else { "ccw" };
        assert_eq!(
            b.send("measure 0.001m 0m"),
            format!(
                "event run {k} finished: square {dir} L=2.000 m odometry end x=+0.000000 \
                 y=+0.000000 theta_deg=+0.0000; measure it\r\n\
                 ok run {k} square {dir} L=2.000 m measured: read x=+1.000 mm y=+0.000 mm; error \
                 vs odometry dx=+0.001000 \
                 dy=+0.000000 m\r\n"
            )
        );
    }
    assert_eq!(
        dirs,
        [
            "ok run 1 started: square cw L=2.000 m\r\n",
            "ok run 2 started: square ccw L=2.000 m\r\n",
            "ok run 3 started: square cw L=2.000 m\r\n",
            "ok run 4 started: square ccw L=2.000 m\r\n",
        ]
    );
    let done = b.send("next");
    assert!(
        done.ends_with("err 20: all planned runs done (calibrate, or run cw|ccw for more)\r\n"),
        "{done}"
    );
    // Dropping a CCW run re-opens the plan for that direction.
    b.send("drop 2");
    assert!(
        b.send("next")
            .ends_with("ok run 5 started: square ccw L=2.000 m\r\n")
    );
}

#[test]
fn button_starts_next_clears_faults_and_stops() {
    let mut b = Bench::new();
    let mut out = String::new();
    b.session.button_short(&mut b.robot, &mut out).unwrap();
    assert_eq!(
        out,
        "event button: ok run 1 started: square cw L=2.000 m\r\n"
    );
    out.clear();
    b.session.button_short(&mut b.robot, &mut out).unwrap();
    assert_eq!(
        out,
        "event button: err 10: a run is in progress (square cw L=2.000 m): wait for it to finish\r\n"
    );
    out.clear();
    b.session.button_long(&mut b.robot, &mut out).unwrap();
    assert_eq!(
        out,
        "event run 1 aborted, not stored: square cw L=2.000 m\r\nevent button: ok stopped\r\n"
    );
    assert_eq!(b.robot.aborts, 1);
    out.clear();
    b.robot.fault = Some(Fault::Stall {
        wheel: Wheel::Right,
    });
    b.session.button_short(&mut b.robot, &mut out).unwrap();
    // The fault is announced in full once (as the controller reports it), then cleared.
    assert_eq!(
        out,
        "event fault: Right wheel stalled\r\nevent button: ok fault cleared\r\n"
    );
    assert_eq!(b.robot.fault, None);
}

#[test]
fn store_full_refuses_new_runs() {
    let mut b = Bench::new();
    for _ in 0..MAX_RUNS {
        b.send("line 0.5");
        b.robot.finish(0.5, 0.0);
        assert!(b.send("measure 0.5m 0m").contains("\r\nok run "));
    }
    let reply = b.send("line 0.5");
    assert!(
        reply.ends_with("err 15: run store full (drop <n> first)\r\n"),
        "{reply}"
    );
    assert_eq!(b.session.runs().len(), MAX_RUNS);
}

#[test]
fn pose_odom_drive_golden() {
    let mut b = Bench::new();
    b.robot.pose = PoseF64::new(1.25, -0.5, -190f64.to_radians());
    assert_eq!(
        b.send("pose"),
        "ok x=+1.250000 y=-0.500000 theta_deg=+170.0000\r\n"
    );
    assert_eq!(b.send("odom reset"), "ok odometry reset\r\n");
    assert_eq!(b.robot.pose, PoseF64::default());
    assert_eq!(b.send("drive 0.3 -0.25"), "ok\r\n");
    assert_eq!(b.robot.drives, vec![(0.3, -0.25)]);
    assert_eq!(
        b.send("odom reset"),
        "err 10: drive is in progress: wait for the motors to stop (500 ms after the last drive)\r\n"
    );
    b.send("stop");
    b.send("run cw");
    assert_eq!(
        b.send("drive 0.1 0"),
        "err 10: a run is in progress (square cw L=2.000 m): wait for it to finish\r\n"
    );
    b.robot.fault = Some(Fault::Stall {
        wheel: Wheel::Right,
    });
    b.robot.running = None;
    assert_eq!(
        b.send("run cw"),
        "event run 1 aborted, not stored: square cw L=2.000 m (fault: stall)\r\n\
         event fault: Right wheel stalled\r\n\
         err 11: fault latched: stall\r\n"
    );
    assert_eq!(b.send("clear"), "ok fault cleared (stall)\r\n");
    assert_eq!(b.robot.fault, None);
    assert_eq!(b.send("clear"), "ok no fault latched\r\n");
    // A drive beyond the limits is limited, and the reply says so.
    assert_eq!(
        b.send("drive 1.5 0"),
        "ok limited to v=+0.300 m/s w=+0.000 rad/s (max_speed, max_turn_rate)\r\n"
    );
    b.send("stop");
    assert_eq!(
        b.send("run cw"),
        "ok run 1 started: square cw L=2.000 m\r\n"
    );
    assert_eq!(b.send(""), "");
    assert_eq!(b.send("warp 9"), "err 1: unknown command (try help)\r\n");
}

#[test]
fn stream_schedule_and_text() {
    let mut b = Bench::new();
    b.robot.pose = PoseF64::new(0.5, 0.25, 0.1);
    assert_eq!(b.poll(0), "");
    assert_eq!(b.send("stream on 100"), "ok stream on 100 Hz\r\n");
    // First line at the first poll (no speed yet), then one per 10 ms period.
    assert_eq!(
        b.poll(5_000),
        "stream 0.005000 +0.500000 +0.250000 +5.7296 +0.0000 +0.0000\r\n"
    );
    assert_eq!(b.poll(14_999), "");
    // 2000 and -1000 ticks in 10 ms: v = ticks × π·0.150 m / 200000 / 0.01 s
    // = +0.4712 and -0.2356 m/s.
    b.robot.totals = WheelTicks::new(2000, -1000);
    assert_eq!(
        b.poll(15_000),
        "stream 0.015000 +0.500000 +0.250000 +5.7296 +0.4712 -0.2356\r\n"
    );
    let mut lines = 0;
    // Poll every 1 ms for 1 s: exactly 99 more lines (due at 25 ms, 35 ms, … 1005 ms).
    for t in (16_000..=1_005_000).step_by(1_000) {
        lines += b.poll(t).lines().count();
    }
    assert_eq!(lines, 99);
    // A stall of several periods restarts the schedule instead of bursting.
    assert_eq!(b.poll(2_000_000).lines().count(), 1);
    assert_eq!(b.poll(2_005_000).lines().count(), 0);
    assert_eq!(b.poll(2_010_000).lines().count(), 1);
    // The clock going backwards (a wrapped timer) restarts the schedule too.
    assert_eq!(b.poll(1_000).lines().count(), 1);
    assert_eq!(b.poll(5_000).lines().count(), 0);
    assert_eq!(b.poll(11_000).lines().count(), 1);
    assert_eq!(b.send("stream on"), "ok stream on 10 Hz\r\n");
    assert_eq!(b.send("stream off"), "ok stream off\r\n");
    assert_eq!(b.poll(3_000_000), "");
}

#[test]
fn the_stream_holds_while_a_line_is_typed() {
    let mut b = Bench::new();
    assert_eq!(b.send("stream on 100"), "ok stream on 100 Hz\r\n");
    assert_eq!(b.poll(0).lines().count(), 1);
    // A person types a line (echoed as typed): no stream line lands between the characters,
    // however long it takes.
    b.session.set_typing(true);
    for t in (1_000..=500_000).step_by(1_000) {
        assert_eq!(b.poll(t), "", "at {t} µs");
    }
    // Enter: the stream resumes at once and keeps its period from there.
    b.session.set_typing(false);
    assert_eq!(b.poll(501_000).lines().count(), 1);
    assert_eq!(b.poll(505_000), "");
    assert_eq!(b.poll(511_000).lines().count(), 1);
}

#[test]
fn run_store_ram() {
    // The store holds MAX_RUNS records inline; report its size so the RAM budget is visible.
    let record = size_of::<RunRecord>();
    let session = size_of::<Session<KnownCalibrator>>();
    println!("RunRecord {record} B, Session {session} B for {MAX_RUNS} runs");
    // MAX_KNOTS knots × 16 B, plus path, geometry, poses and measurement: under 300 B more.
    let knots = MAX_KNOTS * size_of::<WheelTicks>();
    assert!(record >= knots && record < knots + 300, "{record}");
    // The session is the store, where each run is stored in flash, plus settings (with the
    // speed-loop tuning: 40 B) and the stream state: under 600 B more.
    let ids = MAX_RUNS * size_of::<Option<StoredRun>>();
    let numbers = MAX_RUNS * size_of::<u16>();
    assert!(
        session < MAX_RUNS * record + ids + numbers + 600,
        "{session}"
    );
}

/// The wiring check: the operator's instructions, and the verdicts and proposals from the
/// controller's counts. The pulses alone cannot tell a reversed motor from a reversed encoder;
/// after a hand push that shows the left encoder counting backward, they can.
#[test]
fn bringup_replies_and_proposals_are_exact() {
    use odocal::motion::bringup::{PulseCounts, PulseReport, PushReport, WheelPulses};
    let mut b = Bench::new();
    assert_eq!(
        b.send("bringup"),
        "ok bringup motors: wheels must be off the ground; pulsing right then left at 25 % duty, 2 s\r\n"
    );
    assert_eq!(b.robot.check, Some(CheckKind::Pulses));
    let healthy = WheelPulses {
        forward: PulseCounts {
            own: 30_000,
            other: 12,
        },
        backward: PulseCounts {
            own: -29_000,
            other: -3,
        },
    };
    let reversed = WheelPulses {
        forward: PulseCounts {
            own: -30_000,
            other: 0,
        },
        backward: PulseCounts {
            own: 29_000,
            other: 0,
        },
    };
    b.robot.check_reports.push(CheckReport::Pulses(PulseReport {
        right: healthy,
        left: reversed,
    }));
    assert_eq!(
        b.poll(0),
        "event bringup motors: right forward +30000 back -29000 (other wheel +12/-3): ok\r\n\
         event bringup motors: left forward -30000 back +29000 (other wheel +0/+0): counts run against the duty: motor or encoder reversed; run `bringup push` to tell which\r\n\
         event bringup done: 1 finding, no setting fixes it: see above, then check again\r\n"
    );
    assert_eq!(
        b.send("bringup push"),
        "ok bringup push: motors off; push the robot straight forward by hand about 5 cm within 5 s\r\n"
    );
    b.robot.check_reports.push(CheckReport::Push(PushReport {
        right: 21_000,
        left: -20_900,
    }));
    assert_eq!(
        b.poll(0),
        "event bringup push: right encoder +21000 counts, counts forward: ok\r\n\
         event bringup push: left encoder -20900 counts, counts backward: encoder reversed\r\n\
         event bringup propose: set encoder_left_sign -1\r\n\
         event bringup done: 1 finding; apply the proposal with set, then save and check again\r\n"
    );
    b.send("bringup");
    b.robot.check_reports.push(CheckReport::Pulses(PulseReport {
        right: healthy,
        left: reversed,
    }));
    let events = b.poll(0);
    assert!(
        events.contains("left forward -30000 back +29000 (other wheel +0/+0): encoder reversed (push check)\r\nevent bringup propose: set encoder_left_sign -1\r\n"),
        "{events}"
    );
    assert_eq!(
        b.send("set encoder_left_sign -1"),
        "ok encoder_left_sign = -1 (1 standard, -1 reversed) (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.wiring.map(|w| w.encoder_left_reversed), Some(true));
    assert!(b.send("set encoder_left_sign 0").starts_with("err "));
    assert!(b.send("bringup sideways").starts_with("err "));
}

#[test]
fn runs_and_measurements_are_stored_as_they_change_and_restored_after_a_reset() {
    let mut b = Bench::new();
    b.measured_run("cw", 0.01, -0.02, 0.012, -0.018);
    b.measured_run("ccw", 0.02, 0.01, 0.021, 0.012);
    assert_eq!(b.store.runs, b.session.runs());
    assert!(b.store.runs.iter().all(|r| r.measured.is_some()));
    // Every change told the calibrator (a kept exact fit is stale): 2 runs, 2 measurements.
    assert_eq!(b.session.calibrator().runs_changes, 4);
    // While the motors run nothing is written (a page change would erase a sector): the drop
    // is stored once they stop.
    assert_eq!(b.send("drive 0.1 0"), "ok\r\n");
    assert!(b.send("drop 1").starts_with("ok dropped run 1"));
    assert_eq!(b.store.runs.len(), 2);
    assert!(!b.session.runs_stored());
    b.robot.driving = false;
    assert_eq!(b.poll(0), "");
    assert_eq!(b.store.runs, b.session.runs());
    // A flash failure is reported once, and the next change tries again.
    b.store.fail_runs = true;
    // The run left keeps its number: run 2 (a dropped run leaves a gap).
    assert!(
        b.send("measure #1 0.022m 0.011m")
            .starts_with("err 14: no run 1 (1 stored)")
    );
    let reply = b.send("measure #2 0.022m 0.011m");
    assert!(
        reply.ends_with("\r\nevent runs not stored: flash error: flash driver error\r\n"),
        "{reply}"
    );
    b.store.fail_runs = false;
    assert_eq!(b.poll(0), "");
    assert!(!b.session.runs_stored());
    assert!(b.send("measure #2 0.023m 0.011m").starts_with("ok run 2"));
    assert!(b.session.runs_stored());
    assert_eq!(b.store.runs, b.session.runs());
    // A reset: a new session over the same storage resumes with the runs and measurements.
    let listing = b.send("runs");
    let mut resumed = Session::new(
        Settings::default(),
        KnownCalibrator {
            solves: 0,
            runs_changes: 0,
        },
    );
    let mut out = String::new();
    resumed.restore_runs(&mut b.store, &mut out).unwrap();
    assert_eq!(out, "event runs restored: 1 run, 1 measured\r\n");
    b.session = resumed;
    // A reboot starts a new session: the restored runs are numbered from 1 again.
    assert!(listing.starts_with("  run 2 square ccw"), "{listing}");
    assert_eq!(b.send("runs"), listing.replacen("  run 2 ", "  run 1 ", 1));
    // `drop all` asks first.
    assert_eq!(
        b.send("drop all"),
        "err 25: drop all forgets 1 run and their measurements, in flash too: type drop all \
         yes to do it\r\n"
    );
    assert_eq!(b.session.runs().len(), 1);
    assert_eq!(b.send("drop all yes"), "ok dropped all 1 run\r\n");
    assert!(b.store.runs.is_empty());
}

/// Motor identification: the operator's instructions per mode, the result lines, the tuning it
/// applies (seen by the robot and in `params`), and the refusal of an implausible response.
#[test]
fn identify_replies_are_exact_and_the_result_becomes_the_tuning() {
    use odocal::motion::identify::{
        IdentifyFailure, IdentifyMode, IdentifyProblem, IdentifyReport, MotorFit,
    };
    let mut b = Bench::new();
    assert_eq!(
        b.send("identify"),
        "ok identify lifted: wheels must be off the ground; right then left; a slow probe, then steps to 25/50/75 % of max_speed 0.30 m/s forward and backward, about 11 s\r\n"
    );
    assert_eq!(
        b.robot.check,
        Some(CheckKind::Identify(IdentifyMode::Lifted))
    );
    let fit = |k_fwd: f32, k_back: f32, tau: f32, d0: f32| MotorFit {
        params: MotorParams {
            gain_forward_mps: k_fwd,
            gain_backward_mps: k_back,
            time_constant_s: tau,
            deadband: d0,
        },
        coast_decel_mps2: 0.4375,
        coast_from_mps: 0.2125,
        residual_mps: 0.00016,
    };
    let report = IdentifyReport {
        mode: IdentifyMode::Lifted,
        right: fit(0.5, 0.48, 0.12, 0.05),
        left: fit(0.6, 0.61, 0.15, 0.04),
    };
    b.robot.check_reports.push(CheckReport::Identify(report));
    assert_eq!(
        b.poll(0),
        "event identify right: gain_fwd=0.5000 gain_back=0.4800 m/s per duty, tau=0.1200 s, deadband=0.0500, coast 0.438 m/s^2 from 0.213 m/s, residual 0.00016 m/s\r\n\
         event identify left: gain_fwd=0.6000 gain_back=0.6100 m/s per duty, tau=0.1500 s, deadband=0.0400, coast 0.438 m/s^2 from 0.213 m/s, residual 0.00016 m/s\r\n\
         event identify done (lifted): speed-loop tuning applied, bandwidth 30.0 rad/s (not saved; save to keep)\r\n"
    );
    let applied = b.robot.tuning.expect("the tuning reached the robot");
    assert_eq!(applied.right, report.right.params);
    assert_eq!(applied.left, report.left.params);
    assert_eq!(
        applied.bandwidth_radps,
        SpeedTuning::DEFAULT.bandwidth_radps
    );
    let params = b.send("params");
    assert!(
        params.contains("  motor_right_tau 0.1200 s\r\n  motor_right_deadband 0.0500 duty\r\n"),
        "{params}"
    );
    // Derived by pole placement at 30 rad/s: kp = (3·30·0.12 − 1)/0.49, ff = 1/K per direction.
    assert!(
        params.contains(
            "  speed_loop right kp=20.000 ki=661.224 kii=6612.245 ff_fwd=2.0000 ff_back=2.0833 ff_accel=0.2400 deadband=0.0500\r\n"
        ),
        "{params}"
    );
    // Saved with the rest of the parameters.
    assert_eq!(b.send("save"), "ok saved\r\n");
    assert_eq!(b.store.saved.as_ref().map(|s| s.tuning), Some(applied));

    assert_eq!(
        b.send("identify floor"),
        "ok identify floor: robot on the floor with 1 m free ahead and behind (it stays within 1 m, with lower steps if that needs them); both wheels; a slow probe, then steps to 25/50/75 % of max_speed 0.30 m/s forward and backward, about 7 s\r\n"
    );
    b.robot
        .check_reports
        .push(CheckReport::IdentifyFailed(IdentifyFailure {
            wheel: Wheel::Left,
            problem: IdentifyProblem::Reversed,
        }));
    b.robot.fault = Some(Fault::Identify(IdentifyFailure {
        wheel: Wheel::Left,
        problem: IdentifyProblem::Reversed,
    }));
    assert_eq!(
        b.poll(0),
        "event identify err 23: left motor: counts run against the duty: motor or encoder reversed (run bringup); motors stopped, tuning unchanged, fault latched (clear)\r\n"
    );
    assert_eq!(b.robot.tuning, Some(applied));
    assert!(
        b.send("identify")
            .starts_with("err 11: fault latched: identify")
    );
    assert!(b.send("identify sideways").starts_with("err 7: "));
}

/// The tuning parameters follow the geometry's rules: each value within its range (parser),
/// the set as a whole consistent (a motor's two directions within 0.5..2 of each other), a
/// value equal to the current one changes nothing.
#[test]
fn tuning_parameters_are_validated_like_the_geometry() {
    let mut b = Bench::new();
    assert_eq!(
        b.send("set motor_left_gain_fwd 0.6"),
        "ok motor_left_gain_fwd = 0.6000 m/s per duty (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.tuning.map(|t| t.left.gain_forward_mps), Some(0.6));
    assert_eq!(
        b.send("set motor_left_gain_fwd 0.6"),
        "ok motor_left_gain_fwd = 0.6000 m/s per duty (unchanged)\r\n"
    );
    assert_eq!(
        b.send("set motor_left_gain_back 0.25"),
        "err 17: a motor's forward/backward gain ratio must be within 0.5..2 (change the other direction first, or both in steps)\r\n"
    );
    assert!(b.send("set motor_right_tau 5").starts_with("err 6: "));
    assert!(b.send("set speed_bandwidth 0").starts_with("err 6: "));
    assert_eq!(
        b.send("set speed_bandwidth 20"),
        "ok speed_bandwidth = 20.0000 rad/s (not saved; save to keep)\r\n"
    );
    assert_eq!(b.robot.tuning.map(|t| t.bandwidth_radps), Some(20.0));
}

/// A store that can never write (a part's flash smaller than the storage map) says so before
/// the motors are asked about: `save` names the store even while the robot drives, as the board
/// does on a 512 KiB part before its control loop has run (fil/degraded_boot_test.py).
#[test]
fn save_names_a_store_that_cannot_write_before_the_motors() {
    let mut b = Bench::new();
    b.store.unusable = Some(StoreError::FlashTooSmall(FlashTooSmall {
        part_kib: 512,
        needed_kib: 1024,
    }));
    b.send("drive 0.1 0");
    assert_eq!(
        b.send("save"),
        "err 19: flash error: no storage: this part's flash is smaller than the storage map\r\n"
    );
    assert!(b.store.saved.is_none());
    b.store.unusable = None;
    assert!(b.send("save").starts_with("err 18: "));
}

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

#[path = "session_golden/bringup.rs"]
mod bringup;
#[path = "session_golden/calibrate.rs"]
mod calibrate;
#[path = "session_golden/runs.rs"]
mod runs;
#[path = "session_golden/stream.rs"]
mod stream;

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

//! A session on a robot that does what it is told at once: always idle between runs, every
//! setting accepted, a run finishes when the test says so, nothing stored. For the tests of
//! what the session keeps from a command (a declared unit, a parameter's value), where the
//! robot's behaviour is not the subject.

use odocal::kinematics::encoder::WheelTicks;
use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;
use odocal::motion::bringup::{CheckKind, CheckReport};
use odocal::motion::profile::MotionLimits;
use odocal::motion::run::{PathKind, RunRecord};
use odocal::motion::speed::SpeedTuning;
use odocal::motion::wiring::Wiring;
use odocal::session::library::LibraryCalibrator;
use odocal::session::{
    MAX_RUNS, MotorsRunning, MotorsStopped, Robot, RobotError, Session, Settings, SettingsAndRuns,
    Status, StoreError,
};
use odocal::storage::{RunsLoaded, StoredRun};

/// The robot: idle unless a run was started and not yet finished.
#[derive(Default)]
pub struct ObedientRobot {
    running: Option<PathKind>,
    finished: Option<RunRecord>,
}

#[allow(dead_code)] // each test binary uses its own subset
impl ObedientRobot {
    /// Ends the run in progress with the odometry's end pose `(x, y)` (heading 0).
    pub fn finish(&mut self, x_m: f64, y_m: f64) {
        let path = self.running.take().expect("a run is in progress");
        let mut knots = heapless::Vec::new();
        knots.push(WheelTicks::new(0, 0)).expect("one knot");
        self.finished = Some(RunRecord {
            path,
            geometry: Geometry::PAPER_NOMINAL,
            knots,
            odometry_end: PoseF64::new(x_m, y_m, 0.0),
            measured: None,
        });
    }
}

#[allow(dead_code)] // each test binary uses its own subset
impl ObedientRobot {
    /// Ends the run in progress as `record` (its path the one started).
    pub fn finish_as(&mut self, record: RunRecord) {
        let path = self.running.take().expect("a run is in progress");
        assert_eq!(path, record.path, "the run driven is the one recorded");
        self.finished = Some(record);
    }
}

impl Robot for ObedientRobot {
    fn start(&mut self, path: PathKind) -> Result<(), RobotError> {
        self.running = Some(path);
        Ok(())
    }
    fn abort(&mut self) {
        self.running = None;
    }
    fn drive(&mut self, _: f32, _: f32) -> Result<(), RobotError> {
        Ok(())
    }
    fn take_finished_run(&mut self) -> Option<RunRecord> {
        self.finished.take()
    }
    fn set_geometry(&mut self, _: Geometry) -> Result<(), RobotError> {
        Ok(())
    }
    fn set_limits(&mut self, _: &MotionLimits) -> Result<(), RobotError> {
        Ok(())
    }
    fn status(&mut self) -> Status {
        match self.running {
            Some(path) => Status::Running { path, segment: 0 },
            None => Status::Idle,
        }
    }
    fn pose(&mut self) -> PoseF64 {
        PoseF64::default()
    }
    fn totals(&mut self) -> WheelTicks {
        WheelTicks::default()
    }
    fn clear_fault(&mut self) {}
    fn reset_odometry(&mut self) -> Result<(), RobotError> {
        Ok(())
    }
    fn motors_stopped(&mut self) -> Result<MotorsStopped, MotorsRunning> {
        match self.running {
            None => Ok(MotorsStopped::without_controller()),
            Some(_) => Err(MotorsRunning),
        }
    }
    fn set_wiring(&mut self, _: Wiring) -> Result<(), RobotError> {
        Ok(())
    }
    fn start_check(&mut self, _: CheckKind) -> Result<(), RobotError> {
        Ok(())
    }
    fn take_check_report(&mut self) -> Option<CheckReport> {
        None
    }
    fn set_tuning(&mut self, _: &SpeedTuning) -> Result<(), RobotError> {
        Ok(())
    }
    fn set_rate(&mut self, _: u32) -> Result<(), RobotError> {
        Ok(())
    }
}

/// A store that keeps nothing and never fails.
pub struct NoStore;

impl SettingsAndRuns for NoStore {
    fn usable(&self) -> Result<(), StoreError> {
        Ok(())
    }
    fn save(&mut self, _: &Settings, _: MotorsStopped) -> Result<(), StoreError> {
        Ok(())
    }
    fn save_runs(
        &mut self,
        _: &[RunRecord],
        ids: &mut [Option<StoredRun>],
        _: MotorsStopped,
    ) -> Result<(), StoreError> {
        for (i, id) in ids.iter_mut().enumerate() {
            *id = Some(StoredRun {
                key: i as u8,
                serial: i as u32,
            });
        }
        Ok(())
    }
    fn load_runs(
        &mut self,
        runs: &mut heapless::Vec<RunRecord, MAX_RUNS>,
        ids: &mut heapless::Vec<Option<StoredRun>, MAX_RUNS>,
    ) -> RunsLoaded {
        runs.clear();
        ids.clear();
        RunsLoaded {
            found: false,
            restored: 0,
            measured: 0,
            skipped: 0,
            problem: None,
        }
    }
}

/// The library's session with its own calibrator, the defaults as settings.
pub struct Bench {
    pub session: Session<LibraryCalibrator>,
    pub robot: ObedientRobot,
}

#[allow(dead_code)] // each test binary uses its own subset
impl Bench {
    pub fn new() -> Self {
        Bench {
            session: Session::new(Settings::default(), LibraryCalibrator::default()),
            robot: ObedientRobot::default(),
        }
    }

    /// The session's reply to `line`.
    pub fn send(&mut self, line: &str) -> String {
        let mut out = String::new();
        self.session
            .handle_line(line, &mut self.robot, &mut NoStore, &mut out)
            .expect("a String takes every reply");
        out
    }

    /// What the session writes when it polls (a finished run's event).
    pub fn poll(&mut self) -> String {
        let mut out = String::new();
        self.session
            .poll(0, &mut self.robot, &mut NoStore, &mut out)
            .expect("a String takes every reply");
        out
    }
}

//! `apply online <E_d> <E_b> <E_s>`: calibration factors computed elsewhere (the PC bridge's
//! online estimate) applied through the board's own command, on the real controller, session and
//! parameter store over a RAM flash laid out as the board's: no runs and no `calibrate` needed,
//! the calibration named `online` in `params`, kept by `save` across a reboot, the odometry pose
//! unmoved by the new geometry, and every refusal leaving the settings as they were.

mod storage_support;

use odocal::kinematics::geometry::Geometry;
use odocal::motion::controller::Controller;
use odocal::protocol::Command;
use odocal::session::library::{LibraryCalibrator, LockedController};
use odocal::session::{Session, boot};
use storage_support::{BoardFlash, board_store};

/// A board: its flash, the controller (with its encoder counters) and the session booted over it.
struct Board {
    flash: Box<BoardFlash>,
    controller: Controller,
    session: Session<LibraryCalibrator>,
    counts: (u32, u32),
}

impl Board {
    /// Boots from what `flash` holds, as the firmware's `init` does, and runs the control loop
    /// until the motors count as stopped.
    fn boot(mut flash: Box<BoardFlash>) -> Board {
        let loaded = board_store(&mut *flash).load_blocking();
        let mut event = String::new();
        let booted = boot(
            &loaded,
            LibraryCalibrator::default(),
            None,
            None,
            |_, _| Ok(()),
            &mut event,
        )
        .unwrap();
        let mut board = Board {
            flash,
            controller: booted.controller,
            session: booted.session,
            counts: (0, 0),
        };
        board.roll(0, 200);
        board
    }

    /// `periods` control periods with the wheels turning `step` counts each per period.
    fn roll(&mut self, step: u32, periods: u32) {
        for _ in 0..periods {
            self.counts.0 = self.counts.0.wrapping_add(step);
            self.counts.1 = self.counts.1.wrapping_add(step / 2);
            self.controller.step(self.counts.0, self.counts.1);
        }
    }

    fn execute(&mut self, command: Command<'_>) -> String {
        let mut out = String::new();
        let mut store = board_store(&mut *self.flash);
        let mut robot = LockedController(&mut self.controller);
        self.session
            .execute(command, &mut robot, &mut store, &mut out)
            .unwrap();
        out
    }

    fn send(&mut self, line: &str) -> String {
        let mut out = String::new();
        let mut store = board_store(&mut *self.flash);
        let mut robot = LockedController(&mut self.controller);
        self.session
            .handle_line(line, &mut robot, &mut store, &mut out)
            .unwrap();
        out
    }

    /// `params`' lines from `active` on.
    fn calibration_lines(&mut self) -> String {
        let params = self.send("params");
        let at = params.find("  active ").expect("an active line");
        params[at..].to_owned()
    }
}

const APPLIED: &str = "ok applied online: E_d=0.995000000 E_b=1.010000000 E_s=1.000000000 (not saved; save to \
     keep)\r\n";
const PARAMS_ONLINE: &str = "  active d_right=0.149624060 d_left=0.150375940 \
                             wheelbase=0.388850000 m\r\n  \
                             calibration online E_d=0.995000000 E_b=1.010000000 \
                             E_s=1.000000000 runs=0 E_max=0.000 mm\r\n  \
                             convention standard\r\nok\r\n";

#[test]
fn factors_from_elsewhere_are_applied_saved_and_restored_at_boot() {
    let mut board = Board::boot(Box::default());
    assert!(board.session.runs().is_empty());
    assert_eq!(board.send("apply online 0.995 1.01 1"), APPLIED);
    assert_eq!(board.calibration_lines(), PARAMS_ONLINE);
    let geometry = Geometry::PAPER_NOMINAL.with_factors(0.995, 1.01, 1.0);
    assert_eq!(board.controller.config().geometry, geometry);
    assert_eq!(board.session.settings().active, geometry);
    assert_eq!(board.send("save"), "ok saved\r\n");

    let mut rebooted = Board::boot(board.flash);
    assert_eq!(rebooted.calibration_lines(), PARAMS_ONLINE);
    assert_eq!(rebooted.controller.config().geometry, geometry);
    let c = rebooted.session.settings().calibration.clone().unwrap();
    assert_eq!(
        (
            c.method.as_str(),
            c.e_d,
            c.e_b,
            c.e_s,
            c.runs_used,
            c.e_max_m
        ),
        ("online", 0.995, 1.01, 1.0, 0, 0.0)
    );
    // The command a host builds is the line it sends.
    let command = Command::ApplyFactors {
        e_d: 0.998,
        e_b: 1.002,
        e_s: 0.999,
    };
    assert_eq!(command.to_string(), "apply online 0.998 1.002 0.999");
    assert_eq!(
        rebooted.execute(command),
        "ok applied online: E_d=0.998000000 E_b=1.002000000 E_s=0.999000000 (not saved; save \
         to keep)\r\n"
    );
}

#[test]
fn the_pose_does_not_jump_when_the_geometry_changes() {
    let mut board = Board::boot(Box::default());
    board.roll(400, 500);
    let before = board.controller.pose();
    assert_ne!(before.x.to_bits(), 0);
    assert_ne!(before.heading.0, 0);
    let pose = board.send("pose");
    assert_eq!(board.send("apply online 0.995 1.01 1"), APPLIED);
    assert_eq!(board.controller.pose(), before);
    assert_eq!(board.send("pose"), pose);
    // From here on the wheels' counts are integrated with the new geometry.
    board.roll(400, 1);
    assert_ne!(board.controller.pose(), before);
}

#[test]
fn refusals_change_nothing() {
    let mut board = Board::boot(Box::default());
    let settings = board.session.settings().clone();
    let geometry = board.controller.config().geometry;
    for (line, reply) in [
        // Out of the range a stored record holds.
        (
            "apply online 1.5 1 1",
            "err 6: <E_d> must be within 0.8..1.25\r\n",
        ),
        (
            "apply online 1 1 0.79",
            "err 6: <E_s> must be within 0.8..1.25\r\n",
        ),
        // Within it one by one, but a wheel 39 % larger than its nominal one.
        (
            "apply online 0.8 1 1.25",
            "err 17: parameters not storable: calibrated geometry must be within 0.8..1.25 x \
             nominal\r\n",
        ),
        // Malformed: never taken for a method named `online`.
        ("apply online", "err 2: missing argument <E_d>\r\n"),
        (
            "apply online 1 2",
            "err 6: <E_b> must be within 0.8..1.25\r\n",
        ),
        ("apply online 1 1", "err 2: missing argument <E_s>\r\n"),
        ("apply online nan 1 1", "err 5: <E_d> must be finite\r\n"),
        ("apply online 1 1 1 yes", "err 3: too many arguments\r\n"),
    ] {
        assert_eq!(board.send(line), reply, "{line}");
        assert_eq!(board.session.settings(), &settings, "{line}");
        assert_eq!(board.controller.config().geometry, geometry, "{line}");
    }
    // A command built by a host past the parser meets the record's rule.
    let wild = Command::ApplyFactors {
        e_d: 1.5,
        e_b: 1.0,
        e_s: 1.0,
    };
    assert_eq!(
        board.execute(wild),
        "err 17: parameters not storable: E_d, E_b and E_s must be within 0.8..1.25\r\n"
    );
    assert_eq!(board.session.settings(), &settings);
    // Nothing changes while the motors run: the reply `apply` gives.
    assert_eq!(board.send("drive 0.1 0"), "ok\r\n");
    let busy = "err 10: drive is in progress: wait for the motors to stop (500 ms after the last \
                drive)\r\n";
    assert_eq!(board.send("apply online 0.995 1.01 1"), busy);
    assert_eq!(board.send("apply exact"), busy);
    assert_eq!(board.session.settings(), &settings);
    assert_eq!(board.controller.config().geometry, geometry);
}

//! Text of the session's multi-line replies (help, status, params, runs, calibrate, stream).
//!
//! Positions in metres with 6 decimals (1 µm), headings in degrees, factors with 9 decimals
//! (parameters carry 1e-9 relative precision), geometry in the `calibrate` table in millimetres.

use crate::motion::bringup::CheckKind;
use crate::motion::identify::IdentifyMode;
use core::fmt::{self, Write};

use super::traits::{Health, Solution, SolveError};
use super::{Calibrator, Session, Settings};
use crate::kinematics::reference::PoseF64;
use crate::motion::controller::Status;
use crate::motion::run::RunRecord;
pub(super) use crate::protocol::refusal::write_path;
use crate::protocol::reply::write_ok;
use crate::protocol::token::{
    self, ACTIVE, CALIBRATION, DISAGREES, LOWEST_LOO, METHOD_FAILED, RUNS_DISAGREE, TABLE_HEADER,
    WITH_FLAGGED,
};
use crate::protocol::{EOL, ParamName};
use crate::util::decimal::{Decimal, Scientific};
use crate::util::trig::wrap_deg;

/// `<n> <noun>` with the noun in the plural unless `n` is 1 (`1 run`, `2 runs`).
pub(crate) struct Count(pub usize, pub &'static str);

impl fmt::Display for Count {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Count(n, noun) = *self;
        write!(f, "{n} {noun}")?;
        if n != 1 {
            f.write_str("s")?;
        }
        Ok(())
    }
}

/// `help` text: one data line per command, the command and its description separated by a tab
/// (printed as a command column of [`HELP_COLUMN`] characters: no padding is stored).
const HELP: &[&str] = &[
    "help\tthis list",
    "status\tstate, pose, faults, session progress",
    "params\tparameters and the active calibration",
    "set <name> <value>\tchange a parameter (params; measure_unit, heading_unit)",
    "run cw|ccw [L]\tdrive a square of side L m (default: planned side)",
    "next\tstart the next planned run (button short press)",
    "line [d]\tdrive straight d m",
    "circle cw|ccw [r]\tdrive a full circle of radius r m",
    "stop\tstop now (Ctrl-C or Esc also stop at once)",
    "clear\tclear a latched fault (stall, glitch, following)",
    "measure [#n] <x> <y> [th]\ttrue end pose of the last run, or of run n, units written (5mm 1cm 2deg)",
    "runs\tlist stored runs",
    "record <n> [first]\trun n's full record with its tick knots (host tools)",
    "drop <n>|all yes\tdelete run n, or every run",
    "calibrate [method]\tcompute all methods (or one) from measured runs",
    "convention [name]\thow measured runs are read (y-right, ...)",
    "apply <method> [yes]\tuse a method's result (then save; yes: with a flagged run)",
    "apply online <E_d> <E_b> <E_s>\tuse factors computed elsewhere (then save)",
    "save\tstore parameters in flash (motors stopped)",
    "reset-params [yes]\trestore the defaults (then save; yes: discard changes)",
    "pose\todometry pose",
    "odom reset\tset the odometry pose to the origin",
    "bringup [motors|push]\twiring check: motor pulses (wheels up) or a hand push",
    "identify [lifted|floor]\tmotor identification: duty steps, fit, speed-loop tuning",
    "stream on [hz]|off\tpose + wheel speed stream, 1..100 Hz",
    "drive <v_mps> <w_radps>\tvelocity command, motors stop 500 ms after the last",
    "echo on|off\techo typed characters (on at boot; scripts: off)",
    "version\tfirmware and protocol version",
];

/// Width of the `help` command column (the longest command, `apply online …`, and a space).
const HELP_COLUMN: usize = 31;

pub(super) fn write_help(out: &mut dyn Write) -> fmt::Result {
    for line in HELP {
        let tab = line.bytes().position(|b| b == b'\t').unwrap_or(line.len());
        let command = line.get(..tab).unwrap_or(line);
        let description = line.get(tab + 1..).unwrap_or("");
        write!(out, "  {command:<HELP_COLUMN$}{description}\r\n")?;
    }
    write_ok(out, format_args!("{} commands", HELP.len()))
}

pub(super) fn write_pose(out: &mut dyn Write, p: &PoseF64) -> fmt::Result {
    write!(
        out,
        "x={} y={} theta_deg={}",
        Decimal::signed(p.x_m, 6),
        Decimal::signed(p.y_m, 6),
        Decimal::signed(wrap_deg(p.theta_rad.to_degrees()), 4)
    )
}

/// The text of the `status` reply (after `ok `): `state=… fault=… x=… … calibration=…` and what
/// there is to say about the control loop's health and the last reset.
pub(super) fn write_status_text<C: Calibrator>(
    out: &mut dyn Write,
    status: &Status,
    health: &Health,
    pose: &PoseF64,
    session: &Session<C>,
) -> fmt::Result {
    out.write_str("state=")?;
    match *status {
        Status::Idle | Status::Faulted(_) => out.write_str("idle")?,
        Status::Driving => out.write_str("driving")?,
        Status::Checking(CheckKind::Pulses) => out.write_str("bringup-motors")?,
        Status::Checking(CheckKind::Push) => out.write_str("bringup-push")?,
        Status::Checking(CheckKind::Identify(IdentifyMode::Lifted)) => {
            out.write_str("identify-lifted")?
        }
        Status::Checking(CheckKind::Identify(IdentifyMode::Floor)) => {
            out.write_str("identify-floor")?
        }
        Status::Running { path, .. } => {
            out.write_str("running ")?;
            write_path(out, &path)?;
        }
    }
    let fault = status
        .fault()
        .as_ref()
        .map_or("none", super::library::fault_name);
    write!(out, " fault={fault} ")?;
    write_pose(out, pose)?;
    let p = session.progress();
    // Widened: the replies print unsigned numbers through the `u32` formatter only.
    let n = u32::from(session.settings.runs_per_direction);
    let planned = usize::from(session.settings.runs_per_direction);
    // Squares beyond the plan (`run cw|ccw`) are counted apart, never as `6/5`.
    let extra = p.cw.saturating_sub(planned) + p.ccw.saturating_sub(planned);
    write!(
        out,
        " plan cw {}/{n} ccw {}/{n}",
        p.cw.min(planned),
        p.ccw.min(planned)
    )?;
    if extra > 0 {
        write!(out, " (+{extra} extra)")?;
    }
    write!(
        out,
        " measured cw {} ccw {} runs {}/{} calibration={}",
        p.cw_measured,
        p.ccw_measured,
        session.runs.len(),
        super::MAX_RUNS,
        session
            .settings
            .calibration
            .as_ref()
            .map_or("none", |c| c.method.as_str()),
    )?;
    // Only when there is something to say: control periods missed while moving, a pose the
    // counters cannot vouch for, the crash the last reset came from (until `clear`).
    if health.missed_periods > 0 {
        write!(out, " missed_periods={}", health.missed_periods)?;
    }
    if health.pose_lost {
        out.write_str(" pose=lost")?;
    }
    if let Some(crash) = &session.last_crash {
        write!(out, " reset=\"{crash}\"")?;
    }
    Ok(())
}

pub(super) fn write_param_value(out: &mut dyn Write, s: &Settings, name: ParamName) -> fmt::Result {
    crate::protocol::outcome::write_param_value(out, name, s.value(name))
}

pub(super) fn write_params(out: &mut dyn Write, s: &Settings) -> fmt::Result {
    for name in ParamName::ALL {
        write!(out, "  {} ", name.as_str())?;
        write_param_value(out, s, name)?;
        out.write_str(EOL)?;
    }
    let t = &s.tuning;
    for (side, motor) in [("right", &t.right), ("left", &t.left)] {
        // Gains in metres (meters per tick = 1): duty per m/s, per m, per m·s.
        let g = t.gains(motor, 1.0);
        write!(
            out,
            "  speed_loop {side} kp={} ki={} kii={} ff_fwd={} ff_back={} ff_accel={} deadband={}\r\n",
            Decimal::fixed(f64::from(g.kp), 3),
            Decimal::fixed(f64::from(g.ki), 3),
            Decimal::fixed(f64::from(g.kii), 3),
            Decimal::fixed(f64::from(g.kff_v), 4),
            Decimal::fixed(f64::from(g.kff_v_back), 4),
            Decimal::fixed(f64::from(g.kff_v * g.tau_s), 4),
            Decimal::fixed(f64::from(g.deadband), 4),
        )?;
    }
    let a = &s.active;
    write!(
        out,
        "  {ACTIVE}{}={} {}={} {}={} m\r\n",
        ParamName::DiameterRight.as_str(),
        Decimal::fixed(a.diameter_right_m, 9),
        ParamName::DiameterLeft.as_str(),
        Decimal::fixed(a.diameter_left_m, 9),
        ParamName::Wheelbase.as_str(),
        Decimal::fixed(a.wheelbase_m, 9)
    )?;
    match &s.calibration {
        None => write!(out, "  {CALIBRATION}none\r\n")?,
        Some(c) => write!(
            out,
            "  {CALIBRATION}{} E_d={} E_b={} E_s={} runs={} E_max={} mm\r\n",
            c.method,
            Decimal::fixed(c.e_d, 9),
            Decimal::fixed(c.e_b, 9),
            Decimal::fixed(c.e_s, 9),
            u32::from(c.runs_used),
            Decimal::fixed(c.e_max_m * 1e3, 3)
        )?,
    }
    write!(out, "  convention {}\r\nok\r\n", s.convention.as_str())
}

/// The `runs` reply: each stored run under the number it keeps for the session.
pub(super) fn write_runs(out: &mut dyn Write, runs: &[RunRecord], numbers: &[u16]) -> fmt::Result {
    let mut measured = 0u32;
    for (i, r) in runs.iter().enumerate() {
        let number = numbers.get(i).map_or(i + 1, |&n| usize::from(n));
        write!(out, "  run {number} ")?;
        write_path(out, &r.path)?;
        let o = r.odometry_end;
        write!(
            out,
            " odometry x={} y={}",
            Decimal::signed(o.x_m, 6),
            Decimal::signed(o.y_m, 6)
        )?;
        match r.measured {
            None => write!(out, " not measured")?,
            Some(m) => {
                measured += 1;
                write!(
                    out,
                    " measured x={} y={}",
                    Decimal::signed(m.x_m, 6),
                    Decimal::signed(m.y_m, 6)
                )?;
                if let Some(t) = m.theta_rad {
                    write!(out, " theta_deg={}", Decimal::signed(t.to_degrees(), 4))?;
                }
            }
        }
        out.write_str(EOL)?;
    }
    write_ok(
        out,
        format_args!("{}, {measured} measured", Count(runs.len(), "run")),
    )
}

/// The per-run residual list of one result, then a line naming the runs that disagree with the
/// others (robust scale) and the run whose removal makes the others agree (`culprit`,
/// leave-one-out; `None`: no single run does), so a swapped or mistyped measurement is caught
/// before `apply` and a good run is not dropped for it.
pub(super) fn write_residuals(
    out: &mut dyn Write,
    method: &str,
    residuals: &[super::RunResidual],
    culprit: Option<usize>,
) -> fmt::Result {
    write!(
        out,
        "  residuals vs {method} (measured - fitted end; weight of the robust fit)\r\n"
    )?;
    for r in residuals {
        write!(
            out,
            "  run {:<2} dx={} mm dy={} mm",
            r.run,
            Decimal::signed(r.dx_m * 1e3, 3),
            Decimal::signed(r.dy_m * 1e3, 3)
        )?;
        if let Some(t) = r.dtheta_rad {
            write!(out, " dtheta={} deg", Decimal::signed(t.to_degrees(), 3))?;
        }
        write!(out, " weight={}", Decimal::fixed(r.weight, 2))?;
        if r.outlier {
            out.write_str(DISAGREES)?;
        }
        out.write_str(EOL)?;
    }
    if !residuals.iter().any(|r| r.outlier) {
        return Ok(());
    }
    write!(
        out,
        "  {RUNS_DISAGREE}by more than the robust scale (x/y swapped, a sign, a unit?)"
    )?;
    match culprit {
        Some(n) => {
            out.write_str("; ")?;
            token::write_culprit(out, n)?;
            write!(
                out,
                " (each run left out in turn): check run {n}, then measure #{n} x y or drop {n}, \
                 and calibrate again\r\n"
            )
        }
        None => write!(
            out,
            "; leaving out one run at a time does not tell which (none or several restore \
             agreement): check the flagged runs' measurements\r\n"
        ),
    }
}

pub(super) fn write_solution_header(out: &mut dyn Write) -> fmt::Result {
    write!(
        out,
        "  {TABLE_HEADER}      E_d          E_b          E_s          D_R_mm     D_L_mm     \
         b_mm       loo_mm    E_max_mm  sd_E_d    sd_E_b\r\n"
    )
}

/// One optional 1σ column, left-aligned to 9 characters (`pad`) or unpadded (last column);
/// `n/a` when the method cannot compute it (a closed form from one run per direction, or
/// runs that agree exactly).
fn write_opt(out: &mut dyn Write, v: Option<f64>, pad: bool) -> fmt::Result {
    match (v, pad) {
        (Some(v), true) => write!(out, " {:<9}", Scientific::new(v, 3)),
        (Some(v), false) => write!(out, " {}", Scientific::new(v, 3)),
        (None, true) => write!(out, " {:<9}", "n/a"),
        (None, false) => write!(out, " n/a"),
    }
}

/// A millimetre column of `value` metres, 3 decimals, left-aligned to 9 characters (`-`: none).
fn write_mm(out: &mut dyn Write, value: Option<f64>) -> fmt::Result {
    match value {
        Some(e) => write!(out, " {:<9}", Decimal::fixed(e * 1e3, 3)),
        None => write!(out, " {:<9}", "-"),
    }
}

/// One method's row of the `calibrate` table with its leave-one-out error `loo_m`; the row of
/// the `lowest` leave-one-out error ends with [`LOWEST_LOO`], a result computed with flagged runs
/// (`flagged`, non-empty) with `  [with flagged run <n>…]`.
pub(super) fn write_solution_row(
    out: &mut dyn Write,
    name: &str,
    result: &Result<Solution, SolveError>,
    (loo_m, lowest): (Option<f64>, bool),
    flagged: &[usize],
) -> fmt::Result {
    write!(out, "  {name:<12}")?;
    match result {
        Err(e) => write!(out, " {METHOD_FAILED}{e}")?,
        Ok(s) => {
            let g = &s.geometry;
            write!(
                out,
                " {}  {}  {}  {:<10} {:<10} {:<10}",
                Decimal::fixed(s.e_d, 9),
                Decimal::fixed(s.e_b, 9),
                Decimal::fixed(s.e_s, 9),
                Decimal::fixed(g.diameter_right_m * 1e3, 4),
                Decimal::fixed(g.diameter_left_m * 1e3, 4),
                Decimal::fixed(g.wheelbase_m * 1e3, 4)
            )?;
            write_mm(out, loo_m)?;
            write_mm(out, s.e_max_m)?;
            write_opt(out, s.sd_e_d, true)?;
            write_opt(out, s.sd_e_b, false)?;
            if lowest {
                out.write_str(LOWEST_LOO)?;
            }
            if !flagged.is_empty() {
                out.write_str(WITH_FLAGGED)?;
                if flagged.len() > 1 {
                    out.write_str("s")?;
                }
                for n in flagged {
                    write!(out, " {n}")?;
                }
                out.write_str("]")?;
            }
        }
    }
    out.write_str(EOL)
}

#[cfg(test)]
mod header_tests {
    /// The header names [`token::TABLE_COLUMNS`], in order: a host reads the rows by them.
    #[test]
    fn the_header_names_the_table_columns_in_order() {
        let mut header = std::string::String::new();
        super::write_solution_header(&mut header).unwrap();
        let names: std::vec::Vec<&str> = header.split_whitespace().skip(1).collect();
        assert_eq!(names, crate::protocol::token::TABLE_COLUMNS);
    }
}

//! The printed report of a simulated session: what was done, the board's calibration table and
//! the before/after table (E_max, parameter errors against the truth, rectangle end error).

use std::fmt::Write as _;

use odocal::kinematics::geometry::Geometry;

use super::SessionReport;

/// Relative errors `(ΔE_b, ΔE_d)` of `g` against the truth (both relative to nominal).
pub fn parameter_errors(g: &Geometry, truth: &Geometry) -> (f64, f64) {
    (
        g.wheelbase_m / truth.wheelbase_m - 1.0,
        g.diameter_ratio() / truth.diameter_ratio() - 1.0,
    )
}

/// The report as text.
pub fn text(r: &SessionReport) -> String {
    let a = &r.args;
    let nominal = Geometry::PAPER_NOMINAL;
    let mut s = String::new();
    header(r, &mut s);
    let _ = writeln!(
        s,
        "calibration runs: {n} CW + {n} CCW squares at L = {} m through the serial protocol \
         (next / measure): E_max,syst = {:.2} mm, scatter {:.2} mm; {:.0} s simulated in {:.3} s",
        r.side_m,
        r.e_max_before_m * 1e3,
        r.scatter_m * 1e3,
        r.calibration_runs_sim_s,
        r.calibration_runs_wall_s,
        n = a.runs
    );
    let _ = writeln!(s, "\nboard> calibrate");
    if let Some(block) = reply_block(&r.transcript, "> calibrate") {
        s.push_str(&block);
    }
    let _ = writeln!(
        s,
        "\napplied and saved: {}; reboot: {}",
        a.method,
        if r.reboot_kept_calibration {
            "the new board loaded it from flash and uses it"
        } else {
            "FAILED: the rebooted board does not use the saved calibration"
        }
    );
    let _ = writeln!(s, "board> params   (after the reboot)");
    for line in r.params_after_reboot.lines() {
        if line.starts_with("  active") || line.starts_with("  calibration") {
            let _ = writeln!(s, "{line}");
        }
    }
    let _ = writeln!(
        s,
        "verification on the rebooted board: {n} CW + {n} CCW squares, measured \
         E_max,syst {:.2} mm → {:.2} mm",
        r.e_max_before_m * 1e3,
        r.e_max_after_m * 1e3,
        n = a.runs
    );

    let _ = writeln!(
        s,
        "\nbefore/after (fresh {n}+{n} squares at L = {} m per parameter set, true end poses; \
         rectangle = {} CCW laps of 3.6 m × 8.7 m)",
        r.side_m,
        a.laps,
        n = a.runs
    );
    let _ = writeln!(
        s,
        "{:<11} {:>12} {:>12} {:>10} {:>10} {:>11} {:>11} {:>11}",
        "parameters", "E_b", "E_d", "ΔE_b rel", "ΔE_d rel", "E_max pred", "E_max true", "rectangle"
    );
    let _ = writeln!(
        s,
        "{:<11} {:>12} {:>12} {:>10} {:>10} {:>11} {:>11} {:>11}",
        "", "", "", "", "", "mm", "mm", "final m"
    );
    for v in &r.verifications {
        let (_, eb, _) = odocal::calibration::factors_of(&v.belief, &nominal);
        let (db, dd) = parameter_errors(&v.belief, &r.truth);
        let pred = r
            .calibration
            .iter()
            .find(|c| c.method == v.label)
            .and_then(|c| c.e_max_predicted_m)
            .map_or("-".to_string(), |e| format!("{:.3}", e * 1e3));
        let _ = writeln!(
            s,
            "{:<11} {:>12.9} {:>12.9} {:>+10.2e} {:>+10.2e} {:>11} {:>11.3} {:>11.4}",
            v.label,
            eb,
            v.belief.diameter_ratio(),
            db,
            dd,
            pred,
            v.e_max_m * 1e3,
            v.rectangle.final_error_m
        );
    }
    for c in r.calibration.iter().filter(|c| c.factors.is_none()) {
        let _ = writeln!(
            s,
            "{:<11} failed: {}",
            c.method,
            c.failure.as_deref().unwrap_or("")
        );
    }
    if let Some(sw) = &r.sweep {
        let _ = writeln!(
            s,
            "\nparameter error against side (paper-mode Monte Carlo, {} trials per side, \
             σ_meas = {} mm, slip σ = {:.2e} per substep matching the observed scatter):",
            a.sweep_trials, a.meas_mm, r.sweep_slip
        );
        let _ = writeln!(
            s,
            "{:>11} {:>20} {:>20}",
            "method", "sweep best L (err)", "advice L (pred)"
        );
        for b in &sw.best {
            let f = |v: Option<(f64, f64)>| {
                v.map_or("-".to_string(), |(l, e)| format!("{l} m ({e:.1e})"))
            };
            let _ = writeln!(
                s,
                "{:>11} {:>20} {:>20}",
                b.method.as_str(),
                f(b.sweep),
                f(b.advice_on_grid)
            );
        }
    }
    s
}

/// The reply lines that followed `command` in a transcript (up to the final `ok`/`err`).
pub fn reply_block(transcript: &str, command: &str) -> Option<String> {
    let mut lines = transcript.lines().skip_while(|l| *l != command);
    lines.next()?;
    let mut out = String::new();
    for l in lines {
        out.push_str(l);
        out.push('\n');
        if odocal::protocol::FinalLine::parse(l).is_some() {
            break;
        }
    }
    Some(out)
}

/// The report's opening lines: the simulated robot, the motors' identification, the track.
fn header(r: &SessionReport, s: &mut String) {
    let a = &r.args;
    let _ = writeln!(s, "odocal simulated calibration session");
    let _ = writeln!(
        s,
        "robot: true E_b = {}, E_d = {} (unknown to the robot); slip σ = {} per ms; \
         measurement σ = {} mm, {}°; seed {}",
        a.eb, a.ed, a.slip, a.meas_mm, a.meas_deg, a.seed
    );
    if let Some(events) = &r.identification {
        let _ = writeln!(
            s,
            "motors differ from the defaults: identified first (identify floor)"
        );
        for line in events.lines().filter(|l| l.starts_with("event identify")) {
            let _ = writeln!(s, "  {line}");
        }
    }
    match (a.side, r.advice) {
        (Some(l), _) => {
            let _ = writeln!(s, "track: L = {l} m (--side)");
        }
        (None, Some((l, e))) => {
            let _ = writeln!(
                s,
                "track: pilot scatter {:.2} mm at 1 m; advice for {} (L ≤ {} m): L = {l} m, \
                 expected parameter error {:.1e}",
                r.pilot_scatter_m * 1e3,
                a.method,
                a.max_side,
                e
            );
        }
        (None, None) => {}
    }
}

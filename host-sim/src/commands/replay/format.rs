//! The two output formats of `replay`: the aligned text table (per parameter set, session and
//! run, with the fit's per-run listing) and one JSON object per line.

use std::fmt::Write as _;

use odocal::calibration::{Calibration, factors_of};
use odocal::kinematics::geometry::Geometry;

use super::evaluation::{SetEval, geometry_on};
use super::methods::{FitOptions, ParamSet, Pool, default_method};
use crate::sim::optiodom::{ANCHOR_MIN_TRAVEL_M, START_TRAVEL_M, Session, TruthGaps};

fn json_str(s: &str) -> String {
    let mut o = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(o, "\\u{:04x}", c as u32);
            }
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

/// The JSON fields shared by a parameter set's rows: method, default, calib_sessions, factors.
fn set_fields(set: &ParamSet, g: &Geometry, reference: &Geometry) -> String {
    let (e_d, e_b, e_s) = factors_of(g, reference);
    let calib = set
        .calib_sessions
        .iter()
        .map(|s| json_str(s))
        .collect::<Vec<_>>()
        .join(",");
    format!(
        "\"method\":{},\"default\":{},\"calib_sessions\":[{calib}],\"E_b\":{e_b:.9},\"E_d\":{e_d:.9},\"E_s\":{e_s:.9},\"D_R_m\":{:.9},\"D_L_m\":{:.9},\"b_m\":{:.9}",
        json_str(&set.method),
        set.method == default_method(),
        g.diameter_right_m,
        g.diameter_left_m,
        g.wheelbase_m
    )
}

/// The JSON lines of one evaluated parameter set: one per run, then the summary.
pub fn json_lines(
    set: &ParamSet,
    eval: &SetEval,
    sessions: &[Session],
    reference: &Geometry,
) -> Vec<String> {
    let mut out = Vec::new();
    for (si, ri, e) in &eval.runs {
        let s = &sessions[*si];
        out.push(format!(
            "{{{},\"session\":{},\"kind\":\"{}\",\"run\":{},\"final_pos_err_m\":{:e},\"final_pos_cov_m2\":[[{:e},{:e}],[{:e},{:e}]],\"nees\":{},\"final_heading_err_rad\":{:e},\"path_rms_m\":{:e},\"path_max_m\":{:e}}}",
            set_fields(set, &geometry_on(set, s), reference),
            json_str(&s.id),
            s.kind.as_str(),
            ri + 1,
            e.final_pos_err_m,
            e.final_pos_cov_m2[0][0],
            e.final_pos_cov_m2[0][1],
            e.final_pos_cov_m2[1][0],
            e.final_pos_cov_m2[1][1],
            e.nees.map_or_else(|| "null".to_string(), |v| format!("{v:e}")),
            e.final_heading_err_rad,
            e.path_rms_m,
            e.path_max_m
        ));
    }
    let per = sessions
        .iter()
        .zip(&eval.sessions)
        .map(|(s, m)| {
            let offset = s.truth_offset.map_or_else(String::new, |o| {
                format!(",\"truth_heading_offset_rad\":{:e}", o.heading_rad)
            });
            format!(
                "{}:{{\"kind\":\"{}\",{}{offset}}}",
                json_str(&s.id),
                s.kind.as_str(),
                m.json()
            )
        })
        .collect::<Vec<_>>()
        .join(",");
    // A nominal row's factors differ per session; the summary reports the first session's.
    let g = sessions.first().map_or(*reference, |s| geometry_on(set, s));
    out.push(format!(
        "{{{},\"session\":\"all\",\"kind\":\"all\",\"run\":\"all\",{},\"sessions\":{{{per}}}}}",
        set_fields(set, &g, reference),
        eval.overall.json()
    ));
    out
}

fn print_fit(c: &Calibration, calib: &[Session]) {
    let Some(f) = &c.fit else {
        return;
    };
    // Run index → (session, run, start heading error) in the order the observations were built.
    let labels: Vec<(String, usize, Option<f64>)> = calib
        .iter()
        .flat_map(|s| {
            s.runs
                .iter()
                .enumerate()
                .map(move |(i, r)| (s.id.clone(), i + 1, r.start_heading_error(&s.nominal)))
        })
        .collect();
    println!(
        "    per run: residual (truth − fit) x, y [mm], θ [mrad], path RMS [mm], weight, channel weights x y θ, start θ [mrad]{}",
        if f.reweighted {
            ""
        } else {
            " (not reweighted)"
        }
    );
    for r in f.runs() {
        let (sid, run, start) = labels.get(r.index).cloned().unwrap_or_default();
        println!(
            "      {sid} run {run:>2}: {:>8.1} {:>8.1} {:>8} {:>8} {:>6.3}  {:>5.2} {:>5.2} {:>5.2} {:>8}{}",
            r.residual_x_m * 1e3,
            r.residual_y_m * 1e3,
            r.residual_theta_rad
                .map_or_else(|| "-".to_string(), |t| format!("{:.1}", t * 1e3)),
            r.path_rms_m
                .map_or_else(|| "-".to_string(), |v| format!("{:.1}", v * 1e3)),
            r.weight,
            r.channel_weights[0],
            r.channel_weights[1],
            r.channel_weights[2],
            start.map_or_else(|| "-".to_string(), |t| format!("{:+.1}", t * 1e3)),
            if r.outlier { "  outlier" } else { "" }
        );
    }
    if f.run_count > f.runs().len() {
        println!("      ({} more runs)", f.run_count - f.runs().len());
    }
    // The end offsets fitted, one per group of closed paths of one kind and size.
    for o in f.end_offsets() {
        let (sid, run, _) = labels.get(o.first_run).cloned().unwrap_or_default();
        println!(
            "    end offset common to a group of closed paths (truth − fit): x {:+.1} mm, y {:+.1} mm ({sid} run {run} and its peers)",
            o.offset_m[0] * 1e3,
            o.offset_m[1] * 1e3
        );
    }
}

pub(super) fn print_text(
    sets: &[ParamSet],
    evals_of: &[SetEval],
    calib: &[Session],
    evals: &[Session],
    reference: &Geometry,
    fit: &FitOptions,
) {
    let ids = |v: &[Session]| {
        v.iter()
            .map(|s| format!("{} ({})", s.id, s.kind.as_str()))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if !calib.is_empty() {
        println!("calibrated on {}", ids(calib));
        let offsets = calib
            .iter()
            .map(|s| {
                s.truth_offset.map_or_else(
                    || format!("{} not measured (no rows along a path)", s.id),
                    |o| {
                        format!(
                            "{} {:+.1} mrad ({} rows)",
                            s.id,
                            o.heading_rad * 1e3,
                            o.samples
                        )
                    },
                )
            })
            .collect::<Vec<_>>()
            .join(", ");
        println!(
            "  ground truth heading offset (direction of motion − recorded heading): {offsets}; {}",
            if fit.recorded_truth {
                "the fits read the truth as recorded"
            } else {
                "the fits read the truth turned onto the direction of motion"
            }
        );
        let runs = calib.iter().map(|s| s.runs.len()).sum::<usize>();
        let anchored = calib
            .iter()
            .flat_map(|s| &s.runs)
            .filter(|r| r.anchor > 0)
            .count();
        if fit.from_start {
            println!(
                "  every calibration run measured from its recorded start (--from-anchor: from 0.1 m of wheel travel on)"
            );
        } else {
            println!(
                "  {anchored} of {runs} calibration runs measured from {START_TRAVEL_M} m of wheel travel on, leaving their start transient out (runs rolling under {ANCHOR_MIN_TRAVEL_M} m keep their start; --from-anchor)"
            );
        }
        if fit.pool == Pool::Sessions && calib.len() > 1 {
            println!(
                "  exact fits: every session fitted alone, the factors combined by a random-effects mean over sessions (--pool sessions; no per-run listing)"
            );
        }
    }
    println!(
        "evaluated on {} (error = truth − odometry, means over runs)",
        ids(evals)
    );
    let mut listed: Vec<&str> = Vec::new();
    for s in calib.iter().chain(evals) {
        let g = s.truth_gaps;
        if g != TruthGaps::default() && !listed.contains(&s.id.as_str()) {
            listed.push(&s.id);
            println!(
                "  {}: rows without ground truth (motion-capture dropouts): {} interpolated between their neighbours, {} cut from run ends",
                s.id, g.interpolated, g.cut
            );
        }
    }
    println!(
        "  {:<11} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}",
        "method", "E_b", "E_d", "E_s", "sd E_b", "final mm", "head mrad", "rms mm", "max mm"
    );
    for (set, ev) in sets.iter().zip(evals_of) {
        let g = evals.first().map_or(*reference, |s| geometry_on(set, s));
        let (e_d, e_b, e_s) = factors_of(&g, reference);
        let sd = set
            .calibration
            .and_then(|c| c.quality.sigma_e_b)
            .map_or_else(|| "-".to_string(), |s| format!("{s:.5}"));
        let m = &ev.overall;
        println!(
            "  {:<11} {e_b:>9.5} {e_d:>9.5} {e_s:>9.5} {sd:>9} {:>9.1} {:>9.1} {:>9.1} {:>9.1}{}",
            set.method,
            m.final_pos_err_m * 1e3,
            m.final_heading_err_rad * 1e3,
            m.path_rms_m * 1e3,
            m.path_max_m * 1e3,
            if set.method == default_method() {
                "  (default)"
            } else {
                ""
            }
        );
        if evals.len() > 1 || ev.sessions.iter().any(|m| m.e_max_syst_m.is_some()) {
            for (s, m) in evals.iter().zip(&ev.sessions) {
                println!(
                    "      {:<20} {:>49.1} {:>9.1} {:>9.1} {:>9.1}{}",
                    s.id,
                    m.final_pos_err_m * 1e3,
                    m.final_heading_err_rad * 1e3,
                    m.path_rms_m * 1e3,
                    m.path_max_m * 1e3,
                    m.e_max_syst_m
                        .map_or_else(String::new, |e| format!("  E_max,syst {:.1} mm", e * 1e3))
                );
            }
        }
        if let Some(c) = &set.calibration {
            print_fit(c, calib);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_strings_are_escaped() {
        assert_eq!(json_str("a\"b\\c\n"), "\"a\\\"b\\\\c\\u000a\"");
    }
}

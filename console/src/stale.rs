//! Whether a log's last `params` reply still describes the board: a later `reset-params`, `set`
//! of a geometry parameter, `apply` or `apply online` that the board accepted changed the
//! geometry it drives with, so an export from that reply would hand a robot stack a calibration
//! the board no longer holds.

use odocal::protocol::reply::{self, FinalLine};
use odocal::protocol::{Command, ParamGroup, token};

/// A command after the last `params` reply that changed the board's geometry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stale {
    /// Line (1-based) of the command in the log.
    pub line: usize,
    /// The command as sent.
    pub command: String,
    /// Line (1-based) of the final `ok` of the last `params` reply.
    pub params_line: usize,
}

/// Whether `command` (as typed, without a prompt) may change the geometry `params` reports.
fn changes_geometry(command: &str) -> bool {
    match Command::parse(command) {
        Ok(Command::ResetParams { .. } | Command::Apply { .. } | Command::ApplyFactors { .. }) => {
            true
        }
        Ok(Command::Set { name, .. }) => name.spec().group == ParamGroup::Geometry,
        _ => false,
    }
}

/// Finds the first command after the last `params` reply that the board accepted and that
/// changed its geometry. `lines` are the log's lines in order with their line numbers and
/// whether each was sent to the board (`Some(true)`), received (`Some(false)`) or unknown (a
/// terminal capture, where a typed command shows as its echo, perhaps after a `> ` prompt).
pub fn stale_params<'a>(
    lines: impl Iterator<Item = (usize, &'a str, Option<bool>)>,
) -> Option<Stale> {
    let lines: Vec<(usize, &str, Option<bool>)> = lines.collect();
    // The final `ok` of the last `params` reply: the first `ok` after a `d_right` data line.
    let mut params_end = None;
    let mut in_params = false;
    for (i, (_, l, tx)) in lines.iter().enumerate() {
        if *tx == Some(true) {
            continue;
        }
        let l = l.trim_end_matches(['\r', '\n']);
        if reply::data(l).is_some_and(token::is_params_start) {
            in_params = true;
        } else if let Some(last) = FinalLine::parse(l) {
            if in_params && last == FinalLine::Ok("") {
                params_end = Some(i);
            }
            in_params = false;
        }
    }
    let end = params_end?;
    let mut pending: Option<(usize, String)> = None;
    for (n, l, tx) in &lines[end + 1..] {
        let l = l.trim_end_matches(['\r', '\n']);
        if *tx != Some(false) {
            let typed = l.strip_prefix("> ").unwrap_or(l).trim();
            if changes_geometry(typed) {
                pending = Some((*n, typed.to_string()));
                continue;
            }
        }
        // The command's reply: its accepted change makes the last `params` stale.
        if *tx != Some(true)
            && let Some(last) = FinalLine::parse(l)
            && let Some((line, command)) = pending.take()
            && last.is_ok()
            && !l.ends_with(token::UNCHANGED)
        {
            return Some(Stale {
                line,
                command,
                params_line: lines[end].0,
            });
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn capture(text: &str) -> Option<Stale> {
        stale_params(text.lines().enumerate().map(|(i, l)| (i + 1, l, None)))
    }

    const PARAMS: &str = "params\n  d_right 0.150000000 m\n  wheelbase 0.385 m\nok\n";

    #[test]
    fn a_later_accepted_geometry_change_is_named() {
        assert_eq!(capture(PARAMS), None);
        let s = capture(&format!("{PARAMS}status\nok state=idle\nreset-params\nok parameters reset to defaults (not saved; save to keep)\n")).unwrap();
        assert_eq!(
            (s.line, s.command.as_str(), s.params_line),
            (7, "reset-params", 4)
        );
        let s = capture(&format!(
            "{PARAMS}> set wheelbase 0.4\nok wheelbase = 0.400000000 m (not saved; save to keep)\n"
        ))
        .unwrap();
        assert_eq!(s.command, "set wheelbase 0.4");
        assert!(capture(&format!("{PARAMS}apply exact\nok applied exact: E_d=1 E_b=1 E_s=1 (not saved; save to keep)\n")).is_some());
        assert!(capture(&format!("{PARAMS}apply online 0.995 1.01 1\nok applied online: E_d=0.995000000 E_b=1.010000000 E_s=1.000000000 (not saved; save to keep)\n")).is_some());
    }

    #[test]
    fn refused_unchanged_or_other_commands_are_not_stale() {
        assert_eq!(
            capture(&format!("{PARAMS}set wheelbase 9\nerr 6: out of range\n")),
            None
        );
        assert_eq!(
            capture(&format!(
                "{PARAMS}set wheelbase 0.385\nok wheelbase = 0.385000000 m (unchanged)\n"
            )),
            None
        );
        assert_eq!(
            capture(&format!(
                "{PARAMS}set max_speed 0.5\nok max_speed = 0.5 m/s (not saved; save to keep)\n"
            )),
            None
        );
        // A change followed by a new `params`: that reply is the last one.
        assert_eq!(
            capture(&format!("reset-params\nok parameters reset\n{PARAMS}")),
            None
        );
    }
}

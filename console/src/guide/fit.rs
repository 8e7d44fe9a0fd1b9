//! The board's fit check in the guided session: a calibration the runs do not support stops
//! here with the choices (re-read every run under the measuring convention the board names,
//! measure the runs again, declare the noise there really is, or go on to apply, which the
//! board confirms once more), and the measuring noise and convention the board reads its runs
//! with, for a calibration computed on the PC.

use odocal::motion::convention::Convention;
use odocal::protocol::token::TableRow;
use odocal::protocol::{Command, ParamName};
use odocal::session::Reading;
use serde_json::json;

use super::{Guide, Stop};

/// What a poor fit's table says: the convention the board names, if one explains it, and the
/// runs listed with residuals.
fn poor_fit_of(table: &[String]) -> Option<(Option<Convention>, Vec<usize>)> {
    let rows: Vec<TableRow<'_>> = table.iter().filter_map(|l| TableRow::parse(l)).collect();
    if !rows.contains(&TableRow::Fit { poor: true }) {
        return None;
    }
    let named = rows.iter().find_map(|r| match r {
        TableRow::Mistake(Some(name)) => Convention::parse(name),
        _ => None,
    });
    let runs = rows
        .iter()
        .filter_map(|r| match r {
            TableRow::Residual { run, .. } => Some(*run),
            _ => None,
        })
        .collect();
    Some((named, runs))
}

impl Guide {
    /// After `calibrate`: when the board's fit check says the runs fit no geometry within the
    /// measuring noise, asks what to do; returns whether the runs or how they are read changed
    /// (calibrate again).
    pub(super) fn review_poor_fit(&mut self, table: &[String]) -> Result<bool, Stop> {
        let Some((named, runs)) = poor_fit_of(table) else {
            return Ok(false);
        };
        self.ui.warn(
            "the measured runs fit no geometry within the measuring noise (the fit line above): \
             applying a result would make the odometry worse, not better",
        );
        let mut choices: Vec<(String, String)> = Vec::new();
        if let Some(c) = named {
            choices.push((
                "c".into(),
                format!(
                    "convention {}: re-read every run ({})",
                    c.as_str(),
                    c.describe()
                ),
            ));
        }
        choices.push(("m".into(), "measure the runs again".into()));
        choices.push(("n".into(), "declare a larger measuring noise".into()));
        choices.push(("a".into(), "apply anyway (the board asks once more)".into()));
        let pairs: Vec<(&str, &str)> = choices
            .iter()
            .map(|(k, m)| (k.as_str(), m.as_str()))
            .collect();
        let default = if named.is_some() { "c" } else { "m" };
        let choice = self.choose(
            "The fit is poor. Now",
            &pairs,
            default,
            "  c re-reads every measured run as the board suggests (what you typed stays, \
             `convention standard` undoes it); m asks each run's measurement again; n sets \
             measure_sd and heading_sd (a slippery floor or long squares scatter more than a \
             tape measures); a goes on to the method question",
        )?;
        match choice.as_str() {
            "c" => {
                let Some(c) = named else { return Ok(false) };
                let r = self.cmd(Command::Convention { name: Some(c) })?;
                self.ui.say(&format!("  {}", r.last));
                self.link
                    .log
                    .entry("convention", json!({ "name": c.as_str() }), true);
                Ok(r.ok())
            }
            "m" => self.review_runs(&runs, "is part of a poor fit"),
            "n" => self.declare_noise(),
            _ => Ok(false),
        }
    }

    /// Asks for `measure_sd` and `heading_sd` and sets them on the board; whether either
    /// changed.
    fn declare_noise(&mut self) -> Result<bool, Stop> {
        let mut changed = false;
        for (name, example) in [
            (ParamName::MeasureSd, "5mm"),
            (ParamName::HeadingSd, "1deg"),
        ] {
            loop {
                let a = self.ui.ask(
                    &format!(
                        "{} (1 sigma of a measured end, e.g. {example})",
                        name.as_str()
                    ),
                    Some(example),
                )?;
                let line = format!("set {} {a}", name.as_str());
                match Command::parse(&line) {
                    Ok(command) => {
                        let r = self.cmd(command)?;
                        self.ui.say(&format!("  {}", r.last));
                        if r.ok() {
                            changed = true;
                            break;
                        }
                    }
                    Err(e) => self.ui.say(&format!("  {e}")),
                }
            }
        }
        Ok(changed)
    }

    /// How the board reads its runs (its `params`: `measure_sd`, `heading_sd`, `convention`),
    /// for a calibration computed on the PC; the defaults for what it does not say.
    pub(super) fn board_reading(&mut self) -> Result<Reading, Stop> {
        let r = self.cmd(Command::Params)?;
        let mut reading = Reading::DEFAULT;
        crate::log::read_reading(&r.data, &mut reading);
        Ok(reading)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal::calibration::fit_check::MeasuringNoise;

    #[test]
    fn a_poor_fit_names_its_convention_and_runs() {
        let table: Vec<String> = [
            "  run 1  dx=+46.000 mm dy=-3.000 mm weight=1.00",
            "  run 2  dx=-46.000 mm dy=+3.000 mm weight=1.00",
            "  fit exact chi2=970.0 dof=2 p=1.00e-200: POOR FIT, apply needs yes",
            "  mistake y-right: y to the right fits (chi2=1.0 dof=2 p=6.1e-1): convention y-right \
             re-reads the runs",
        ]
        .map(String::from)
        .to_vec();
        assert_eq!(
            poor_fit_of(&table),
            Some((Some(Convention::YRight), vec![1, 2]))
        );
        let good = ["  fit exact chi2=2.0 dof=2 p=3.68e-1: ok".to_string()];
        assert_eq!(poor_fit_of(&good), None);
        assert_eq!(MeasuringNoise::DEFAULT, Reading::DEFAULT.noise);
    }
}

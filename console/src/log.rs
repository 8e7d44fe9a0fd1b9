//! The session log: one JSON object a line, appended and flushed line by line (run records,
//! measurements and results also reach the disk at once), so a crash, a pulled cable or a board
//! reset loses nothing written so far.
//!
//! Every entry has `t` (seconds since the Unix epoch) and `kind`:
//! - `tx` / `rx` with `line`: every line sent to and received from the board (`stream` and
//!   `event` lines included);
//! - `note` with `what`, `text`: the tool's own remarks (connect, disconnect, resume, reboot);
//! - `plan` with `side_m`, `runs_per_direction`; `nominal` with the `params` data lines;
//! - `run` with `slot` (the run's place in the session, kept across board resets), `board` (its
//!   number on the board) and `record` (the data lines of `record <n>`: path, geometry,
//!   odometry end, measurement, tick knots, lossless) and `path` (the stream poses of the run);
//! - `measure` with `slot`, `line` (the `measure` command as sent) and `reply`;
//! - `drop` with `slot`; `calibrate` with `table` (the reply's lines) and `source`
//!   (`board` or `offline`); `apply`, `save`, `verify` with the replies.
//!
//! [`LogContents::read`] rebuilds the session from the file: the runs by slot (each the last
//! record logged for it, read back with the library's [`RecordReader`]), the nominal geometry,
//! the plan, and the tables shown.

use std::fs::{File, OpenOptions};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use odocal::kinematics::geometry::Geometry;
use odocal::motion::convention::Convention;
use odocal::motion::run::RunRecord;
use odocal::protocol::record::RecordReader;
use odocal::protocol::{Command, ParamName};
use odocal::session::Reading;
use serde_json::{Value, json};

/// Appends entries to a session log file.
pub struct SessionLog {
    file: Option<File>,
    /// The file, for messages.
    pub path: PathBuf,
}

/// Seconds since the Unix epoch on the PC's clock: a log entry's `t`, and the bridge's clock.
pub fn now_s() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

impl SessionLog {
    /// Opens `path` for appending (created if missing).
    ///
    /// # Errors
    /// The file cannot be opened, as text.
    pub fn open(path: &Path) -> Result<SessionLog, String> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        }
        let mut file = OpenOptions::new()
            .create(true)
            .append(true)
            .read(true)
            .open(path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        // A log cut in the middle of a line (the tool was killed while writing) gets its line
        // ended, so the next entry starts on a line of its own.
        let len = file.metadata().map(|m| m.len()).unwrap_or(0);
        if len > 0 {
            use std::io::{Read, Seek, SeekFrom};
            let mut last = [0u8; 1];
            let torn = file.seek(SeekFrom::End(-1)).is_ok()
                && file.read_exact(&mut last).is_ok()
                && last[0] != b'\n';
            if torn {
                file.write_all(b"\n")
                    .map_err(|e| format!("{}: {e}", path.display()))?;
            }
        }
        Ok(SessionLog {
            file: Some(file),
            path: path.to_path_buf(),
        })
    }

    /// A log that keeps nothing (a long-running bridge without `--log`).
    pub fn discard() -> SessionLog {
        SessionLog {
            file: None,
            path: PathBuf::new(),
        }
    }

    /// Appends one entry (`t` added); `durable` also waits for the disk.
    pub fn entry(&mut self, kind: &str, mut fields: Value, durable: bool) {
        if let Value::Object(m) = &mut fields {
            m.insert("t".into(), json!(now_s()));
            m.insert("kind".into(), json!(kind));
        }
        if let Some(f) = &mut self.file {
            // One write call per entry: a crash leaves whole lines (or one torn last line).
            let ok = f
                .write_all(format!("{fields}\n").as_bytes())
                .and_then(|()| f.flush());
            if durable {
                let _ = f.sync_data();
            }
            if let Err(e) = ok {
                eprintln!(
                    "console: cannot write the session log {}: {e}",
                    self.path.display()
                );
                self.file = None;
            }
        }
    }

    /// A line sent to the board.
    pub fn tx(&mut self, line: &str) {
        self.entry("tx", json!({ "line": line }), false);
    }

    /// A line received from the board.
    pub fn rx(&mut self, line: &str) {
        self.entry("rx", json!({ "line": line }), false);
    }

    /// A remark of the tool.
    pub fn note(&mut self, what: &str, text: &str) {
        self.entry("note", json!({ "what": what, "text": text }), true);
    }
}

/// A session rebuilt from its log.
#[derive(Debug, Default)]
pub struct LogContents {
    /// Runs by slot; `None` for a slot dropped later.
    pub runs: Vec<Option<RunRecord>>,
    /// The logged stream poses of every slot's run (x, y), for the plot.
    pub paths: Vec<Vec<(f64, f64)>>,
    /// When every slot's run was logged (the entry's `t`, Unix seconds).
    pub run_times_s: Vec<Option<f64>>,
    /// The nominal geometry from the last logged `params`.
    pub nominal: Option<Geometry>,
    /// The plan: square side and runs per direction.
    pub plan: Option<(f64, u32)>,
    /// Every logged `calibrate` table (source, lines).
    pub tables: Vec<(String, Vec<String>)>,
    /// The method applied last, if any.
    pub applied: Option<String>,
    /// Whether the parameters were saved after the last apply.
    pub saved: bool,
    /// How the board read its runs: the measuring noise and convention of the last logged
    /// `params`, changed by every `set measure_sd|heading_sd` and `convention` sent after it.
    pub reading: Reading,
}

/// How a board's `params` (its data lines) say it reads its runs: `measure_sd`, `heading_sd`
/// and `convention` update `reading`; what they do not say stays.
pub fn read_reading(lines: &[String], reading: &mut Reading) {
    if let Some(v) = param(lines, ParamName::MeasureSd.as_str()).filter(|v| v.is_finite()) {
        reading.noise.position_m = v;
    }
    if let Some(v) = param(lines, ParamName::HeadingSd.as_str()).filter(|v| v.is_finite()) {
        reading.noise.heading_rad = v.to_radians();
    }
    let convention = lines.iter().find_map(|l| {
        let mut w = l.split_whitespace();
        (w.next() == Some("convention")).then(|| Convention::parse(w.next()?))?
    });
    if let Some(c) = convention {
        reading.convention = c;
    }
}

/// What a command sent changes of how the board reads its runs.
fn follow_reading(line: &str, reading: &mut Reading) {
    match Command::parse(line) {
        Ok(Command::Convention { name: Some(c) }) => reading.convention = c,
        Ok(Command::Set {
            name: ParamName::MeasureSd,
            value,
        }) => reading.noise.position_m = value,
        Ok(Command::Set {
            name: ParamName::HeadingSd,
            value,
        }) => reading.noise.heading_rad = value.to_radians(),
        _ => {}
    }
}

/// The value of one `params` data line `name value unit`.
pub fn param(lines: &[String], name: &str) -> Option<f64> {
    lines.iter().find_map(|l| {
        let mut w = l.split_whitespace();
        (w.next() == Some(name)).then(|| w.next()?.parse().ok())?
    })
}

/// The `calibration …` data line of a `params` reply, without its keyword (`none` if absent).
pub fn calibration_of(lines: &[String]) -> String {
    lines
        .iter()
        .find_map(|l| l.strip_prefix(odocal::protocol::token::CALIBRATION))
        .unwrap_or("none")
        .to_string()
}

/// The nominal geometry of a `params` reply's data lines.
pub fn nominal_of(lines: &[String]) -> Option<Geometry> {
    Some(Geometry {
        diameter_right_m: param(lines, ParamName::DiameterRight.as_str())?,
        diameter_left_m: param(lines, ParamName::DiameterLeft.as_str())?,
        wheelbase_m: param(lines, ParamName::Wheelbase.as_str())?,
        counts_per_rev: param(lines, ParamName::CountsPerRev.as_str())? as u32,
    })
}

/// Reads `record` data lines back into a run record with the library's reader.
///
/// # Errors
/// A malformed or incomplete record, as text.
pub fn record_of(lines: &[String]) -> Result<RunRecord, String> {
    let mut reader = RecordReader::new();
    for l in lines {
        reader.feed(l).map_err(|e| format!("{e}: `{l}`"))?;
    }
    reader.finish().map_err(|e| e.to_string())
}

fn strings(v: &Value) -> Vec<String> {
    v.as_array()
        .map(|a| {
            a.iter()
                .filter_map(|s| s.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default()
}

impl LogContents {
    /// Reads a session log. A torn last line (the tool died while writing it) is skipped.
    ///
    /// # Errors
    /// The file cannot be read, or a run record in it is corrupt, as text.
    pub fn read(path: &Path) -> Result<LogContents, String> {
        let file = File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut c = LogContents::default();
        for (n, line) in BufReader::new(file).lines().enumerate() {
            let line = line.map_err(|e| format!("{}: {e}", path.display()))?;
            let Ok(v) = serde_json::from_str::<Value>(&line) else {
                eprintln!(
                    "console: {} line {}: not a complete entry, skipped",
                    path.display(),
                    n + 1
                );
                continue;
            };
            let slot = v["slot"].as_u64().map(|s| s as usize);
            match v["kind"].as_str().unwrap_or("") {
                "nominal" => {
                    let params = strings(&v["params"]);
                    c.nominal = nominal_of(&params).or(c.nominal);
                    read_reading(&params, &mut c.reading);
                }
                "tx" => follow_reading(v["line"].as_str().unwrap_or(""), &mut c.reading),
                "plan" => {
                    if let (Some(s), Some(n)) =
                        (v["side_m"].as_f64(), v["runs_per_direction"].as_u64())
                    {
                        c.plan = Some((s, n as u32));
                    }
                }
                "run" => {
                    let Some(slot) = slot else { continue };
                    let record = record_of(&strings(&v["record"]))
                        .map_err(|e| format!("{} line {}: {e}", path.display(), n + 1))?;
                    if c.runs.len() <= slot {
                        c.runs.resize(slot + 1, None);
                        c.paths.resize(slot + 1, Vec::new());
                        c.run_times_s.resize(slot + 1, None);
                    }
                    c.runs[slot] = Some(record);
                    c.run_times_s[slot] = v["t"].as_f64();
                    if let Some(p) = v["path"].as_array() {
                        c.paths[slot] = p
                            .iter()
                            .filter_map(|xy| Some((xy[0].as_f64()?, xy[1].as_f64()?)))
                            .collect();
                    }
                }
                "drop" => {
                    if let Some(r) = slot.and_then(|s| c.runs.get_mut(s)) {
                        *r = None;
                    }
                }
                "calibrate" => c.tables.push((
                    v["source"].as_str().unwrap_or("board").to_string(),
                    strings(&v["table"]),
                )),
                "apply" => {
                    c.applied = v["method"].as_str().map(str::to_string);
                    c.saved = false;
                }
                "save" => c.saved = v["ok"].as_bool().unwrap_or(false),
                _ => {}
            }
        }
        Ok(c)
    }

    /// The live runs in slot order.
    pub fn live_runs(&self) -> Vec<RunRecord> {
        self.runs.iter().flatten().cloned().collect()
    }

    /// When the oldest live run was logged (Unix seconds); `None` without live runs or when one
    /// has no time.
    pub fn oldest_live_run_s(&self) -> Option<f64> {
        let mut oldest: Option<f64> = None;
        for (run, t) in self.runs.iter().zip(&self.run_times_s) {
            if run.is_some() {
                let t = (*t)?;
                oldest = Some(oldest.map_or(t, |o| o.min(t)));
            }
        }
        oldest
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A log read offline calibrates as the board read its runs: the noise and convention of
    /// its `params`, then those the session set.
    #[test]
    fn the_reading_follows_params_and_the_commands_sent() {
        let params: Vec<String> = [
            "  measure_sd 0.002000 m",
            "  heading_sd 0.500 deg",
            "  convention swapped",
        ]
        .map(String::from)
        .to_vec();
        let mut reading = Reading::DEFAULT;
        read_reading(&params, &mut reading);
        assert_eq!(reading.noise.position_m, 0.002);
        assert_eq!(reading.noise.heading_rad, 0.5f64.to_radians());
        assert_eq!(reading.convention, Convention::Swapped);
        follow_reading("convention y-right", &mut reading);
        follow_reading("set measure_sd 5mm", &mut reading);
        follow_reading("set heading_sd 1deg", &mut reading);
        follow_reading("calibrate", &mut reading);
        assert_eq!(reading.convention, Convention::YRight);
        assert!((reading.noise.position_m - 0.005).abs() < 1e-15);
        assert_eq!(reading.noise.heading_rad, 1f64.to_radians());
    }
}

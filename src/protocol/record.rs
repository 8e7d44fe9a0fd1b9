//! The `record` and `version` replies: a run's full record on the wire, lossless, for a host tool
//! that keeps the runs (the console's session log) and recalibrates them with this library.
//!
//! `record <n> [first]` answers with data lines and one final line:
//!
//! ```text
//!   record run 3 square cw 3ff8000000000000
//!   geometry 3fc3333333333333 3fc3333333333333 3fd8a3d70a3d70a4 200000
//!   odometry_end 3f7c5c4f3e4c0000 bf6e8f1a2b3c4d5e 3d10000000000000
//!   measured 3f7c5c4f3e4c0000 bf6e8f1a2b3c4d5e -
//!   knots 97
//!   knot 0 0 0
//!   knot 1 35367 35367
//!   …
//! ok run 3 knots 0..31 of 97
//! ```
//!
//! Every `f64` is its IEEE-754 bit pattern in 16 hex digits, so the host gets exactly the value the
//! board holds (the board formats no floating-point number for it). The path line gives the kind,
//! the direction (square, circle) and the size in metres; `geometry` is `D_R`, `D_L`, `b` in
//! metres and the counts per revolution the robot drove with; `measured` is `x y θ` (θ in radians,
//! `-` when not measured) or `none`. One reply carries at most [`RECORD_PAGE_KNOTS`] knots
//! (`knot <i> <right> <left>`, cumulative ticks since the run start), so it fits the board's
//! transmit queue; the host asks `record <n> <next>` until it has all `knots`. [`RecordReader`]
//! reads the data lines back into a [`RunRecord`].

use core::fmt::{self, Write};

use super::EOL;
use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::geometry::Geometry;
use crate::kinematics::reference::PoseF64;
use crate::motion::run::{Direction, MAX_KNOTS, Measurement, PathKind, RunRecord};

/// Version of the serial protocol that `version` reports. A host tool refuses a board whose
/// protocol it does not know. 1: the command set of `docs/protocol.md` with `record`/`version`.
pub const PROTOCOL_VERSION: u32 = 1;

/// Knots per `record` reply.
pub const RECORD_PAGE_KNOTS: usize = 32;

/// Writes `ok odocal <crate version> protocol <PROTOCOL_VERSION>`.
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_version(out: &mut dyn Write) -> fmt::Result {
    write!(
        out,
        "ok odocal {} protocol {PROTOCOL_VERSION}\r\n",
        env!("CARGO_PKG_VERSION")
    )
}

/// What a `version` reply says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Version<'a> {
    /// The firmware's crate version.
    pub firmware: &'a str,
    /// The protocol it speaks ([`PROTOCOL_VERSION`] for this one); `None` when it does not
    /// say (a firmware older than the protocol number).
    pub protocol: Option<u32>,
}

/// Reads the text of a `version` reply (after `ok `) as [`write_version`] writes it: `None` for
/// a device that is not an odocal board.
pub fn parse_version(text: &str) -> Option<Version<'_>> {
    let mut w = text.split_whitespace();
    if w.next() != Some("odocal") {
        return None;
    }
    let firmware = w.next()?;
    let protocol = match w.next() {
        Some("protocol") => w.next().and_then(|p| p.parse().ok()),
        _ => None,
    };
    Some(Version { firmware, protocol })
}

struct Bits(f64);

impl fmt::Display for Bits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:016x}", self.0.to_bits())
    }
}

/// Writes the data lines of one `record` page of run `number` (1-based) from knot `first`, and
/// the final `ok` line. The caller checks that `first` is a knot of the run (or 0).
///
/// # Errors
/// Only if `out` refuses the text.
pub fn write_record_page(
    out: &mut dyn Write,
    number: usize,
    run: &RunRecord,
    first: usize,
) -> fmt::Result {
    write!(out, "  record run {number} ")?;
    match run.path {
        PathKind::Square { direction, side_m } => {
            write!(out, "square {} {}", direction.as_str(), Bits(side_m))?;
        }
        PathKind::Line { length_m } => write!(out, "line {}", Bits(length_m))?,
        PathKind::Circle {
            direction,
            radius_m,
        } => write!(out, "circle {} {}", direction.as_str(), Bits(radius_m))?,
    }
    out.write_str(EOL)?;
    let g = &run.geometry;
    write!(
        out,
        "  geometry {} {} {} {}\r\n",
        Bits(g.diameter_right_m),
        Bits(g.diameter_left_m),
        Bits(g.wheelbase_m),
        g.counts_per_rev
    )?;
    let o = &run.odometry_end;
    write!(
        out,
        "  odometry_end {} {} {}\r\n",
        Bits(o.x_m),
        Bits(o.y_m),
        Bits(o.theta_rad)
    )?;
    match &run.measured {
        None => write!(out, "  measured none\r\n")?,
        Some(m) => {
            write!(out, "  measured {} {} ", Bits(m.x_m), Bits(m.y_m))?;
            match m.theta_rad {
                Some(t) => write!(out, "{}\r\n", Bits(t))?,
                None => write!(out, "-\r\n")?,
            }
        }
    }
    let total = run.knots.len();
    write!(out, "  knots {total}\r\n")?;
    let end = total.min(first.saturating_add(RECORD_PAGE_KNOTS));
    for (i, k) in run.knots.iter().enumerate().take(end).skip(first) {
        write!(out, "  knot {i} {} {}\r\n", k.right, k.left)?;
    }
    if end > first {
        write!(
            out,
            "ok run {number} knots {first}..{} of {total}\r\n",
            end - 1
        )
    } else {
        write!(out, "ok run {number} knots none of {total}\r\n")
    }
}

/// Why the data lines of a `record` reply could not be read back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum RecordReplyError {
    /// A line is not one of the record's data lines, or a value in it is malformed.
    Malformed,
    /// A page disagrees with an earlier one (another run, path, geometry or knot count).
    Inconsistent,
    /// A knot arrived out of order (a page is missing or repeated).
    KnotOrder,
    /// A header line is missing, or fewer knots arrived than the record has.
    Incomplete,
    /// More knots than a run record holds.
    TooManyKnots,
}

impl fmt::Display for RecordReplyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            RecordReplyError::Malformed => "malformed record line",
            RecordReplyError::Inconsistent => "record pages disagree",
            RecordReplyError::KnotOrder => "record knots out of order",
            RecordReplyError::Incomplete => "record incomplete",
            RecordReplyError::TooManyKnots => "more knots than a run record holds",
        })
    }
}

/// Reads the data lines of one run's `record` pages back into a [`RunRecord`].
///
/// Feed every data line of every page in order ([`RecordReader::feed`]); between pages,
/// [`RecordReader::next_first`] says which knot to ask for next (`None` when complete), and
/// [`RecordReader::finish`] returns the record.
#[derive(Clone, Debug, Default)]
pub struct RecordReader {
    number: Option<usize>,
    path: Option<PathKind>,
    geometry: Option<Geometry>,
    odometry_end: Option<PoseF64>,
    measured: Option<Option<Measurement>>,
    total: Option<usize>,
    knots: heapless::Vec<WheelTicks, MAX_KNOTS>,
}

fn bits(word: Option<&str>) -> Result<f64, RecordReplyError> {
    let w = word.ok_or(RecordReplyError::Malformed)?;
    if w.len() != 16 {
        return Err(RecordReplyError::Malformed);
    }
    u64::from_str_radix(w, 16)
        .map(f64::from_bits)
        .map_err(|_| RecordReplyError::Malformed)
}

fn int<T: core::str::FromStr>(word: Option<&str>) -> Result<T, RecordReplyError> {
    word.ok_or(RecordReplyError::Malformed)?
        .parse()
        .map_err(|_| RecordReplyError::Malformed)
}

fn direction(word: Option<&str>) -> Result<Direction, RecordReplyError> {
    match word {
        Some("cw") => Ok(Direction::Cw),
        Some("ccw") => Ok(Direction::Ccw),
        _ => Err(RecordReplyError::Malformed),
    }
}

/// Sets `slot` to `value`, or checks that a previous page gave the same.
fn same<T: PartialEq>(slot: &mut Option<T>, value: T) -> Result<(), RecordReplyError> {
    match slot {
        Some(old) if *old != value => Err(RecordReplyError::Inconsistent),
        Some(_) => Ok(()),
        None => {
            *slot = Some(value);
            Ok(())
        }
    }
}

impl RecordReader {
    /// An empty reader.
    pub fn new() -> Self {
        Self::default()
    }

    /// Reads one data line of a `record` reply (leading spaces and the line end are ignored).
    ///
    /// # Errors
    /// [`RecordReplyError`]: a malformed line, a page that disagrees with an earlier one, or a knot
    /// out of order.
    pub fn feed(&mut self, line: &str) -> Result<(), RecordReplyError> {
        let mut w = line.split_ascii_whitespace();
        let end = |mut w: core::str::SplitAsciiWhitespace<'_>| match w.next() {
            None => Ok(()),
            Some(_) => Err(RecordReplyError::Malformed),
        };
        match w.next() {
            Some("record") => {
                if w.next() != Some("run") {
                    return Err(RecordReplyError::Malformed);
                }
                same(&mut self.number, int::<usize>(w.next())?)?;
                let path = match w.next() {
                    Some("square") => {
                        let direction = direction(w.next())?;
                        PathKind::Square {
                            direction,
                            side_m: bits(w.next())?,
                        }
                    }
                    Some("line") => PathKind::Line {
                        length_m: bits(w.next())?,
                    },
                    Some("circle") => {
                        let direction = direction(w.next())?;
                        PathKind::Circle {
                            direction,
                            radius_m: bits(w.next())?,
                        }
                    }
                    _ => return Err(RecordReplyError::Malformed),
                };
                same(&mut self.path, path)?;
            }
            Some("geometry") => {
                let g = Geometry {
                    diameter_right_m: bits(w.next())?,
                    diameter_left_m: bits(w.next())?,
                    wheelbase_m: bits(w.next())?,
                    counts_per_rev: int(w.next())?,
                };
                same(&mut self.geometry, g)?;
            }
            Some("odometry_end") => {
                let p = PoseF64 {
                    x_m: bits(w.next())?,
                    y_m: bits(w.next())?,
                    theta_rad: bits(w.next())?,
                };
                same(&mut self.odometry_end, p)?;
            }
            Some("measured") => {
                let m = match w.next() {
                    Some("none") => None,
                    x => {
                        let x_m = bits(x)?;
                        let y_m = bits(w.next())?;
                        let theta_rad = match w.next() {
                            Some("-") => None,
                            t => Some(bits(t)?),
                        };
                        Some(Measurement {
                            x_m,
                            y_m,
                            theta_rad,
                        })
                    }
                };
                same(&mut self.measured, m)?;
            }
            Some("knots") => {
                let n: usize = int(w.next())?;
                if n > MAX_KNOTS {
                    return Err(RecordReplyError::TooManyKnots);
                }
                same(&mut self.total, n)?;
            }
            Some("knot") => {
                let i: usize = int(w.next())?;
                let k = WheelTicks {
                    right: int(w.next())?,
                    left: int(w.next())?,
                };
                if i != self.knots.len() || self.total.is_none_or(|t| i >= t) {
                    return Err(RecordReplyError::KnotOrder);
                }
                self.knots
                    .push(k)
                    .map_err(|_| RecordReplyError::TooManyKnots)?;
            }
            _ => return Err(RecordReplyError::Malformed),
        }
        end(w)
    }

    /// The run number the pages name, once a page arrived.
    pub fn number(&self) -> Option<usize> {
        self.number
    }

    /// The first knot to ask for next (`record <n> <first>`), `None` once every knot arrived.
    pub fn next_first(&self) -> Option<usize> {
        match self.total {
            Some(t) if self.knots.len() >= t => None,
            _ => Some(self.knots.len()),
        }
    }

    /// The record.
    ///
    /// # Errors
    /// [`RecordReplyError::Incomplete`] if a header line or a knot is missing.
    pub fn finish(self) -> Result<RunRecord, RecordReplyError> {
        let (Some(path), Some(geometry), Some(odometry_end), Some(measured), Some(total)) = (
            self.path,
            self.geometry,
            self.odometry_end,
            self.measured,
            self.total,
        ) else {
            return Err(RecordReplyError::Incomplete);
        };
        if self.knots.len() != total {
            return Err(RecordReplyError::Incomplete);
        }
        Ok(RunRecord {
            path,
            geometry,
            knots: self.knots,
            odometry_end,
            measured,
        })
    }
}

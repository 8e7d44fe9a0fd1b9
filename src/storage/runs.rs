//! The session's runs in flash, in the run region (apart from the parameters), power-fail safe.
//!
//! Each stored run is one `sequential-storage` item (its path, the geometry it was driven with,
//! the odometry end pose and its tick knots; [`RUN_ITEM_MAX`] bytes at most) under a key from
//! [`RUN_KEY_FIRST`] on, and one small **index** item ([`RUN_INDEX_KEY`]) lists the stored runs
//! in the session's order with each run's measurement. Writing the index is the commit point of
//! every change:
//!
//! - a finished run: its item is written under a key no committed run uses, then the index;
//! - a measurement entered or replaced: the index alone;
//! - a dropped run (or all of them): the index, then the items no longer listed are removed.
//!
//! A power cut before the index write leaves the old index, which never refers to the new
//! item; a cut after it leaves the new state; a cut during a removal leaves an unlisted item,
//! which is overwritten when its key is used again. Each index entry carries the run item's
//! serial number, so an item that is not the one the index means (a stale or foreign one) is
//! reported and skipped at boot, never restored. The parameter record lives in a region of its
//! own ([`super::params`]); nothing here touches it.
//!
//! Layouts (little-endian, byte 0 = format version):
//!
//! | run item | offset | size |
//! |---|---|---|
//! | version = 1 | 0 | 1 |
//! | serial number | 1 | 4 |
//! | path: 0 square, 1 line, 2 circle | 5 | 1 |
//! | direction: 0 CW, 1 CCW (0 for a line) | 6 | 1 |
//! | side / length / radius, m (f64) | 7 | 8 |
//! | geometry driven with: D_R, D_L, b (f64, m), counts/rev (u32) | 15 | 28 |
//! | odometry end x, y (m), θ (rad), f64 | 43 | 24 |
//! | knot count n (1..=[`MAX_KNOTS`]) | 67 | 1 |
//! | n × (right, left) ticks, i64 | 68 | 16 n |
//!
//! | index | offset | size |
//! |---|---|---|
//! | version = 1 | 0 | 1 |
//! | run count (0..=[`MAX_RUNS`]) | 1 | 1 |
//! | per run: item key, serial (u32), flags (bit 0 measured, bit 1 heading measured), x, y (m), θ (rad) as f64 | 2 + 30 i | 30 |

use core::fmt;

use embedded_storage_async::nor_flash::MultiwriteNorFlash;
use heapless::Vec;
use sequential_storage::map::{SerializationError, Value};

use super::record::{Reader, Writer};
use super::{ParamAndRunStore, StoreError};
use crate::kinematics::encoder::WheelTicks;
use crate::kinematics::reference::PoseF64;
use crate::motion::controller::MotorsStopped;
use crate::motion::run::{Direction, MAX_KNOTS, MAX_RUNS, Measurement, PathKind, RunRecord};

/// Map key of the run index.
pub const RUN_INDEX_KEY: u8 = 2;
/// First map key of a run item.
pub const RUN_KEY_FIRST: u8 = 16;
/// Number of run item keys: twice the store plus one, so a new run always finds a key that
/// neither the committed index nor the one being written uses (even when drops and new runs
/// are stored together).
pub const RUN_KEYS: u8 = 2 * MAX_RUNS as u8 + 1;
/// Run item format version.
pub const RUN_FORMAT_VERSION: u8 = 1;
/// Run index format version.
pub const INDEX_FORMAT_VERSION: u8 = 1;

const RUN_HEADER_LEN: usize = 68;
const KNOT_LEN: usize = 16;
const INDEX_HEADER_LEN: usize = 2;
const INDEX_ENTRY_LEN: usize = 30;
/// Largest run item, bytes (a run with [`MAX_KNOTS`] knots).
pub const RUN_ITEM_MAX: usize = RUN_HEADER_LEN + KNOT_LEN * MAX_KNOTS;
/// Largest index item, bytes.
pub const INDEX_MAX: usize = INDEX_HEADER_LEN + INDEX_ENTRY_LEN * MAX_RUNS;

const _: () = assert!(RUN_KEYS as usize > 2 * MAX_RUNS);
const _: () =
    assert!(RUN_KEY_FIRST > RUN_INDEX_KEY && RUN_KEY_FIRST as usize + RUN_KEYS as usize <= 256);
const _: () = assert!(MAX_KNOTS <= u8::MAX as usize && MAX_RUNS <= 16);

/// Where one run is stored: its item key and serial number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StoredRun {
    /// Map key of the run item.
    pub key: u8,
    /// Serial number written into the item and the index entry.
    pub serial: u32,
}

/// Why stored run bytes could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum RunFormatError {
    /// The item has a format version this firmware does not read.
    Version {
        /// Version byte found.
        found: u8,
    },
    /// The item's length does not match its contents.
    Length,
    /// Unknown path kind or direction, or a path size that is not finite and positive.
    Path,
    /// The geometry the run was driven with is not a valid geometry.
    Geometry,
    /// No knots, too many, or the first knot is not `(0, 0)`.
    Knots,
    /// The odometry end pose is not finite.
    Pose,
    /// A measurement is not finite, or its flags are unknown.
    Measurement,
    /// An index entry names a key outside the run keys, or the same key twice.
    Key,
}

impl fmt::Display for RunFormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunFormatError::Version { found } => write!(f, "format version {found}"),
            RunFormatError::Length => f.write_str("wrong length"),
            RunFormatError::Path => f.write_str("bad path"),
            RunFormatError::Geometry => f.write_str("bad geometry"),
            RunFormatError::Knots => f.write_str("bad tick knots"),
            RunFormatError::Pose => f.write_str("bad odometry end"),
            RunFormatError::Measurement => f.write_str("bad measurement"),
            RunFormatError::Key => f.write_str("bad run key"),
        }
    }
}

impl core::error::Error for RunFormatError {}

/// A run to be written, with its serial number (a write-only view of a [`RunRecord`]).
pub(super) struct EncodeRun<'a> {
    pub(super) run: &'a RunRecord,
    pub(super) serial: u32,
}

fn path_fields(path: &PathKind) -> (u8, u8, f64) {
    let dir = |d: Direction| u8::from(d == Direction::Ccw);
    match *path {
        PathKind::Square { direction, side_m } => (0, dir(direction), side_m),
        PathKind::Line { length_m } => (1, 0, length_m),
        PathKind::Circle {
            direction,
            radius_m,
        } => (2, dir(direction), radius_m),
    }
}

fn write_pose(w: &mut Writer<'_>, p: &PoseF64) {
    w.f64(p.x_m);
    w.f64(p.y_m);
    w.f64(p.theta_rad);
}

impl<'a> Value<'a> for EncodeRun<'a> {
    fn serialize_into(&self, buffer: &mut [u8]) -> Result<usize, SerializationError> {
        let run = self.run;
        let n = run.knots.len();
        let Some(buf) = buffer.get_mut(..RUN_HEADER_LEN + KNOT_LEN * n) else {
            return Err(SerializationError::BufferTooSmall);
        };
        let mut w = Writer { buf, pos: 0 };
        w.bytes(&[RUN_FORMAT_VERSION]);
        w.bytes(&self.serial.to_le_bytes());
        let (kind, dir, size) = path_fields(&run.path);
        w.bytes(&[kind, dir]);
        w.f64(size);
        w.geometry(&run.geometry);
        write_pose(&mut w, &run.odometry_end);
        w.bytes(&[n as u8]);
        for k in &run.knots {
            w.bytes(&k.right.to_le_bytes());
            w.bytes(&k.left.to_le_bytes());
        }
        Ok(w.pos)
    }

    /// Run items are fetched as bytes and checked by [`decode_run`]; this view only writes.
    fn deserialize_from(_: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        Err(SerializationError::InvalidFormat)
    }
}

/// Decodes a stored run item into `(serial, run)` (the run unmeasured: measurements live in the
/// index). Checks the layout and that every value is usable.
///
/// # Errors
/// [`RunFormatError`] saying what is wrong.
pub fn decode_run(bytes: &[u8]) -> Result<(u32, RunRecord), RunFormatError> {
    match bytes.first() {
        Some(&RUN_FORMAT_VERSION) => {}
        Some(&found) => return Err(RunFormatError::Version { found }),
        None => return Err(RunFormatError::Length),
    }
    if bytes.len() < RUN_HEADER_LEN {
        return Err(RunFormatError::Length);
    }
    let mut r = Reader { buf: bytes, pos: 1 };
    let serial = u32::from_le_bytes(r.array());
    let [kind, dir] = r.array::<2>();
    let size = r.f64();
    let direction = match dir {
        0 => Direction::Cw,
        1 if kind != 1 => Direction::Ccw,
        _ => return Err(RunFormatError::Path),
    };
    if !(size.is_finite() && size > 0.0) {
        return Err(RunFormatError::Path);
    }
    let path = match kind {
        0 => PathKind::Square {
            direction,
            side_m: size,
        },
        1 => PathKind::Line { length_m: size },
        2 => PathKind::Circle {
            direction,
            radius_m: size,
        },
        _ => return Err(RunFormatError::Path),
    };
    let geometry = r.geometry();
    if geometry.validate().is_err() {
        return Err(RunFormatError::Geometry);
    }
    let odometry_end = PoseF64 {
        x_m: r.f64(),
        y_m: r.f64(),
        theta_rad: r.f64(),
    };
    if !(odometry_end.x_m.is_finite()
        && odometry_end.y_m.is_finite()
        && odometry_end.theta_rad.is_finite())
    {
        return Err(RunFormatError::Pose);
    }
    let [n] = r.array::<1>();
    let n = usize::from(n);
    if bytes.len() != RUN_HEADER_LEN + KNOT_LEN * n {
        return Err(RunFormatError::Length);
    }
    if n == 0 || n > MAX_KNOTS {
        return Err(RunFormatError::Knots);
    }
    let mut knots = Vec::new();
    for _ in 0..n {
        let right = i64::from_le_bytes(r.array());
        let left = i64::from_le_bytes(r.array());
        knots
            .push(WheelTicks::new(right, left))
            .map_err(|_| RunFormatError::Knots)?;
    }
    if knots.first() != Some(&WheelTicks::new(0, 0)) {
        return Err(RunFormatError::Knots);
    }
    Ok((
        serial,
        RunRecord {
            path,
            geometry,
            knots,
            odometry_end,
            measured: None,
        },
    ))
}

/// The index to be written: the runs in order, each with where it is stored.
pub(super) struct EncodeIndex<'a> {
    pub(super) runs: &'a [RunRecord],
    pub(super) ids: &'a [Option<StoredRun>],
}

impl<'a> Value<'a> for EncodeIndex<'a> {
    fn serialize_into(&self, buffer: &mut [u8]) -> Result<usize, SerializationError> {
        let n = self.runs.len();
        if n > MAX_RUNS || self.ids.len() != n {
            return Err(SerializationError::InvalidData);
        }
        let Some(buf) = buffer.get_mut(..INDEX_HEADER_LEN + INDEX_ENTRY_LEN * n) else {
            return Err(SerializationError::BufferTooSmall);
        };
        let mut w = Writer { buf, pos: 0 };
        w.bytes(&[INDEX_FORMAT_VERSION, n as u8]);
        for (run, id) in self.runs.iter().zip(self.ids) {
            let Some(id) = id else {
                return Err(SerializationError::InvalidData);
            };
            w.bytes(&[id.key]);
            w.bytes(&id.serial.to_le_bytes());
            let m = run.measured.unwrap_or(Measurement {
                x_m: 0.0,
                y_m: 0.0,
                theta_rad: None,
            });
            let flags = u8::from(run.measured.is_some()) | (u8::from(m.theta_rad.is_some()) << 1);
            w.bytes(&[flags]);
            w.f64(m.x_m);
            w.f64(m.y_m);
            w.f64(m.theta_rad.unwrap_or(0.0));
        }
        Ok(w.pos)
    }

    /// The index is fetched as bytes and checked by [`decode_index`]; this view only writes.
    fn deserialize_from(_: &'a [u8]) -> Result<(Self, usize), SerializationError> {
        Err(SerializationError::InvalidFormat)
    }
}

/// One entry of a stored index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexEntry {
    /// Where the run item is.
    pub id: StoredRun,
    /// The run's measurement, if one was entered.
    pub measured: Option<Measurement>,
}

/// Decodes a stored index.
///
/// # Errors
/// [`RunFormatError`] saying what is wrong.
pub fn decode_index(bytes: &[u8]) -> Result<Vec<IndexEntry, MAX_RUNS>, RunFormatError> {
    match bytes.first() {
        Some(&INDEX_FORMAT_VERSION) => {}
        Some(&found) => return Err(RunFormatError::Version { found }),
        None => return Err(RunFormatError::Length),
    }
    let n = usize::from(bytes.get(1).copied().unwrap_or(u8::MAX));
    if n > MAX_RUNS || bytes.len() != INDEX_HEADER_LEN + INDEX_ENTRY_LEN * n {
        return Err(RunFormatError::Length);
    }
    let mut r = Reader { buf: bytes, pos: 2 };
    let mut entries: Vec<IndexEntry, MAX_RUNS> = Vec::new();
    let mut keys = 0u32;
    for _ in 0..n {
        let [key] = r.array::<1>();
        let serial = u32::from_le_bytes(r.array());
        let [flags] = r.array::<1>();
        let (x_m, y_m, theta) = (r.f64(), r.f64(), r.f64());
        let bit = key_bit(key).ok_or(RunFormatError::Key)?;
        if keys & bit != 0 {
            return Err(RunFormatError::Key);
        }
        keys |= bit;
        let measured = match flags {
            0 => None,
            1 | 3 => {
                let theta_rad = (flags == 3).then_some(theta);
                if !(x_m.is_finite() && y_m.is_finite() && theta_rad.is_none_or(f64::is_finite)) {
                    return Err(RunFormatError::Measurement);
                }
                Some(Measurement {
                    x_m,
                    y_m,
                    theta_rad,
                })
            }
            _ => return Err(RunFormatError::Measurement),
        };
        entries
            .push(IndexEntry {
                id: StoredRun { key, serial },
                measured,
            })
            .map_err(|_| RunFormatError::Length)?;
    }
    Ok(entries)
}

/// The bit of run item `key` in a key set, `None` outside the run keys.
pub(super) fn key_bit(key: u8) -> Option<u32> {
    let i = key.checked_sub(RUN_KEY_FIRST)?;
    (i < RUN_KEYS).then(|| 1u32 << i)
}

/// The run item keys of a key set.
pub(super) fn keys_of(set: u32) -> impl Iterator<Item = u8> {
    (0..RUN_KEYS)
        .filter(move |i| set & (1 << i) != 0)
        .map(|i| RUN_KEY_FIRST + i)
}

/// Why a run (or the whole list) was not restored at boot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum RunLoadProblem {
    /// The index could not be read from flash.
    IndexUnreadable(StoreError),
    /// The index is not one this firmware reads.
    IndexMalformed(RunFormatError),
    /// Run `run` (1-based, in the stored order) is listed but its item is gone.
    Missing {
        /// Run number.
        run: usize,
    },
    /// Run `run`'s item could not be read.
    Unreadable {
        /// Run number.
        run: usize,
        /// The storage error.
        error: StoreError,
    },
    /// Run `run`'s item is not one this firmware reads.
    Malformed {
        /// Run number.
        run: usize,
        /// What is wrong.
        error: RunFormatError,
    },
    /// Run `run`'s item is another run than the index means (serial number differs).
    Foreign {
        /// Run number.
        run: usize,
    },
}

impl fmt::Display for RunLoadProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunLoadProblem::IndexUnreadable(e) => write!(f, "run list unreadable: {e}"),
            RunLoadProblem::IndexMalformed(e) => write!(f, "run list malformed: {e}"),
            RunLoadProblem::Missing { run } => write!(f, "run {run}: record missing"),
            RunLoadProblem::Unreadable { run, error } => {
                write!(f, "run {run}: record unreadable: {error}")
            }
            RunLoadProblem::Malformed { run, error } => {
                write!(f, "run {run}: record malformed: {error}")
            }
            RunLoadProblem::Foreign { run } => {
                write!(f, "run {run}: record belongs to another run")
            }
        }
    }
}

/// What boot restored from the stored runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunsLoaded {
    /// A run list was stored (false on a new board: nothing to report).
    pub found: bool,
    /// Runs restored.
    pub restored: usize,
    /// Of those, runs with a measurement.
    pub measured: usize,
    /// Listed runs not restored.
    pub skipped: usize,
    /// The first problem met, if any.
    pub problem: Option<RunLoadProblem>,
}

impl<F: MultiwriteNorFlash> ParamAndRunStore<F> {
    /// Restores the stored runs into `runs` (with their measurements) and where each is stored
    /// into `ids`, both emptied first. Never fails: an unreadable or foreign run is skipped and
    /// reported in [`RunsLoaded::problem`] (also logged); an unreadable list restores nothing.
    /// May repair the run region after an interrupted write (never the parameter region).
    pub async fn load_runs(
        &mut self,
        runs: &mut Vec<RunRecord, MAX_RUNS>,
        ids: &mut Vec<Option<StoredRun>, MAX_RUNS>,
    ) -> RunsLoaded {
        runs.clear();
        ids.clear();
        self.live_run_keys = 0;
        self.runs_wipes = self.wipes;
        let mut loaded = RunsLoaded::default();
        if self.usable().is_err() {
            // Nothing can have been stored (the boot event already says why).
            return loaded;
        }
        let index = match self
            .map
            .fetch_item::<&[u8]>(&mut self.buf.0, &RUN_INDEX_KEY)
            .await
        {
            Ok(None) => return loaded,
            Ok(Some(bytes)) => decode_index(bytes).map_err(RunLoadProblem::IndexMalformed),
            Err(e) => Err(RunLoadProblem::IndexUnreadable(e.into())),
        };
        loaded.found = true;
        let index = match index {
            Ok(index) => index,
            Err(problem) => {
                warn!("stored runs not restored: {}", problem);
                loaded.problem = Some(problem);
                return loaded;
            }
        };
        for (i, entry) in index.iter().enumerate() {
            let run = i + 1;
            self.live_run_keys |= key_bit(entry.id.key).unwrap_or(0);
            self.next_serial = self.next_serial.max(entry.id.serial.wrapping_add(1));
            let fetched = self
                .map
                .fetch_item::<&[u8]>(&mut self.buf.0, &entry.id.key)
                .await;
            let problem = match fetched {
                Ok(Some(bytes)) => match decode_run(bytes) {
                    Ok((serial, _)) if serial != entry.id.serial => RunLoadProblem::Foreign { run },
                    Ok((_, mut record)) => {
                        record.measured = entry.measured;
                        loaded.measured += usize::from(record.measured.is_some());
                        // Both have room: the index holds at most MAX_RUNS entries.
                        let _ = runs.push(record);
                        let _ = ids.push(Some(entry.id));
                        loaded.restored += 1;
                        continue;
                    }
                    Err(error) => RunLoadProblem::Malformed { run, error },
                },
                Ok(None) => RunLoadProblem::Missing { run },
                Err(e) => RunLoadProblem::Unreadable {
                    run,
                    error: e.into(),
                },
            };
            warn!("stored run skipped: {}", problem);
            loaded.skipped += 1;
            loaded.problem.get_or_insert(problem);
        }
        loaded
    }

    /// Stores the session's runs: every run whose id is `None` as a new item (its id is filled
    /// in), then the index with every run's measurement (the commit point), then removes the
    /// items of runs no longer listed, with the motors `stopped` (a page change erases a
    /// sector). A power cut at any byte leaves the previously committed runs or these.
    ///
    /// If the run region's contents are proven bad (corrupted beyond `sequential-storage`'s
    /// own repair, full of garbage, an internal inconsistency), the run region alone is erased
    /// (logged, counted by [`Self::wipes`]) and every run written again, once. The parameter
    /// region is never touched. A flash *driver* error is returned as it is, nothing erased.
    ///
    /// # Errors
    /// [`StoreError::Encoding`] if `runs` and `ids` differ in length, otherwise the flash or
    /// storage failure (the committed runs stay as they were).
    pub async fn save_runs(
        &mut self,
        runs: &[RunRecord],
        ids: &mut [Option<StoredRun>],
        _stopped: MotorsStopped,
    ) -> Result<(), StoreError> {
        self.usable()?;
        if runs.len() != ids.len() || runs.len() > MAX_RUNS {
            return Err(StoreError::Encoding);
        }
        match self.write_runs(runs, ids).await {
            Err(e @ (StoreError::Corrupted | StoreError::Full | StoreError::Internal)) => {
                warn!(
                    "storing the runs failed ({}); erasing the run region and writing them again",
                    e
                );
                self.wipes = self.wipes.saturating_add(1);
                self.map.erase_all().await.map_err(StoreError::from)?;
                self.write_runs(runs, ids).await
            }
            other => other,
        }
    }

    /// One attempt of [`Self::save_runs`].
    async fn write_runs(
        &mut self,
        runs: &[RunRecord],
        ids: &mut [Option<StoredRun>],
    ) -> Result<(), StoreError> {
        if self.runs_wipes != self.wipes {
            // The run region was erased: every run is written again.
            ids.iter_mut().for_each(|id| *id = None);
            self.live_run_keys = 0;
            self.runs_wipes = self.wipes;
        }
        let mut listed = ids
            .iter()
            .flatten()
            .filter_map(|id| key_bit(id.key))
            .fold(0u32, |a, b| a | b);
        for (run, id) in runs.iter().zip(ids.iter_mut()) {
            if id.is_some() {
                continue;
            }
            // A key neither the committed index nor the new one lists: free by construction
            // (RUN_KEYS > 2 × MAX_RUNS); a stale item under it is simply replaced.
            let taken = listed | self.live_run_keys;
            let Some(key) = keys_of(!taken).next() else {
                return Err(StoreError::Internal);
            };
            let serial = self.next_serial;
            self.next_serial = self.next_serial.wrapping_add(1);
            self.map
                .store_item(&mut self.buf.0, &key, &EncodeRun { run, serial })
                .await
                .map_err(StoreError::from)?;
            *id = Some(StoredRun { key, serial });
            listed |= key_bit(key).unwrap_or(0);
        }
        self.map
            .store_item(&mut self.buf.0, &RUN_INDEX_KEY, &EncodeIndex { runs, ids })
            .await
            .map_err(StoreError::from)?;
        let unlisted = self.live_run_keys & !listed;
        self.live_run_keys = listed;
        for key in keys_of(unlisted) {
            // Committed already: an item left behind is unlisted, and replaced when its key is
            // used again.
            if let Err(e) = self.map.remove_item(&mut self.buf.0, &key).await {
                warn!(
                    "removing a dropped run's record failed ({})",
                    StoreError::from(e)
                );
            }
        }
        Ok(())
    }

    /// [`Self::load_runs`], run to completion.
    pub fn load_runs_blocking(
        &mut self,
        runs: &mut Vec<RunRecord, MAX_RUNS>,
        ids: &mut Vec<Option<StoredRun>, MAX_RUNS>,
    ) -> RunsLoaded {
        embassy_futures::block_on(self.load_runs(runs, ids))
    }

    /// [`Self::save_runs`], run to completion.
    ///
    /// # Errors
    /// As [`Self::save_runs`].
    pub fn save_runs_blocking(
        &mut self,
        runs: &[RunRecord],
        ids: &mut [Option<StoredRun>],
        stopped: MotorsStopped,
    ) -> Result<(), StoreError> {
        embassy_futures::block_on(self.save_runs(runs, ids, stopped))
    }
}

//! Persistent parameters: one [`ParamRecord`] in NOR flash, kept by `sequential-storage`.
//!
//! Owns the stored parameter record and its flash map; may use [`crate::motion`]
//! (motion limits), [`crate::kinematics`] (geometry) and [`crate::util`].
//!
//! [`ParamStore`] wraps a `sequential-storage` map over any
//! [`MultiwriteNorFlash`] range of at least two erase pages. Every save appends a new copy of the
//! record (key [`PARAMS_KEY`]); when a page fills, the live record moves to the next page and the
//! old page is erased, so wear spreads over all pages. Each stored item carries a CRC, and a save
//! interrupted at any byte leaves either the old or the new record readable (see
//! `tests/storage_power_cut.rs`, `docs/storage.md`).
//!
//! Loading never fails: a missing, unreadable, corrupt, unknown-version or invalid record gives
//! [`ParamRecord::DEFAULT`] plus a [`LoadWarning`] (also logged with `warn!`). Saving refuses
//! while the motors run, because a flash erase stalls the CPU for up to seconds.
//!
//! `sequential-storage` is async-only; the `*_blocking` methods run the same futures to
//! completion with `embassy_futures::block_on`, for the firmware's `init` and for `host-sim`.
//! Note that `load` may itself write or erase: after an interrupted save, `sequential-storage`
//! repairs the flash on first access. Boot is the place for that (motors stopped).

pub mod ram_flash;
pub mod record;
pub mod runs;

use core::fmt;
use core::ops::Range;

use embedded_storage_async::nor_flash::{MultiwriteNorFlash, NorFlashError, NorFlashErrorKind};
use sequential_storage::cache::{Cache, Uncached};
pub use sequential_storage::map::MapConfig;
use sequential_storage::map::MapStorage;

pub use self::record::{
    AppliedCalibration, FormatError, METHOD_NAME_MAX, MethodName, ParamRecord, RecordError,
};
pub use self::runs::{RunFormatError, RunLoadProblem, RunsLoaded, StoredRun};

/// Map key under which the parameter record is stored.
pub const PARAMS_KEY: u8 = 1;

/// Largest flash word `sequential-storage` supports, bytes (its `MAX_WORD_SIZE`).
const MAX_WORD: usize = 32;

/// Longest item: the parameter record, a run with every knot, or the run index.
const ITEM_MAX: usize = {
    let mut n = ParamRecord::ENCODED_LEN;
    if runs::RUN_ITEM_MAX > n {
        n = runs::RUN_ITEM_MAX;
    }
    if runs::INDEX_MAX > n {
        n = runs::INDEX_MAX;
    }
    n
};

/// Working buffer: key + the longest item, rounded up to any supported word size (1.7 KiB: a
/// run is written straight from the session's record into it, never copied whole elsewhere).
const BUF_LEN: usize = (1 + ITEM_MAX).next_multiple_of(MAX_WORD);

/// The map type used for the parameters.
type Map<F> = MapStorage<u8, F, Cache<Uncached, Uncached, Uncached, u8>>;

/// Word-aligned working buffer (some flash drivers need aligned source data).
#[repr(C, align(4))]
struct AlignedBuf([u8; BUF_LEN]);

/// Kind of low-level flash failure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum FlashFault {
    /// Misaligned access.
    NotAligned,
    /// Access outside the flash or the reserved range.
    OutOfBounds,
    /// Any other driver error (programming, protection, power).
    Other,
}

impl From<NorFlashErrorKind> for FlashFault {
    fn from(kind: NorFlashErrorKind) -> Self {
        match kind {
            NorFlashErrorKind::NotAligned => FlashFault::NotAligned,
            NorFlashErrorKind::OutOfBounds => FlashFault::OutOfBounds,
            _ => FlashFault::Other,
        }
    }
}

impl fmt::Display for FlashFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FlashFault::NotAligned => "misaligned flash access",
            FlashFault::OutOfBounds => "flash access out of bounds",
            FlashFault::Other => "flash driver error",
        })
    }
}

impl core::error::Error for FlashFault {}

/// Why the store could not be created or a save failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum StoreError {
    /// The flash range is not page aligned or shorter than two erase pages.
    BadRange,
    /// Refused: the motors are running (a flash erase would stall the control loop).
    MotorsRunning,
    /// Refused: the record does not validate.
    InvalidRecord(RecordError),
    /// The flash driver failed.
    Flash(FlashFault),
    /// The stored data is corrupted beyond `sequential-storage`'s repair.
    Corrupted,
    /// The flash range is full (cannot happen with one key unless the flash is damaged).
    Full,
    /// The record could not be serialised.
    Encoding,
    /// `sequential-storage` reported an internal inconsistency.
    Internal,
    /// This part's flash is smaller than the storage map needs: nothing is stored.
    FlashTooSmall(FlashTooSmall),
}

/// A part with less flash than the storage map needs (e.g. a 512 KiB STM32F407VE for a map
/// that ends at 1 MiB).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub struct FlashTooSmall {
    /// Flash size the part reports, KiB.
    pub part_kib: u32,
    /// Flash the storage map needs (its end address), KiB.
    pub needed_kib: u32,
}

impl fmt::Display for FlashTooSmall {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "no storage: this part has {} KiB of flash, the storage map needs {} KiB",
            self.part_kib, self.needed_kib
        )
    }
}

impl fmt::Display for StoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StoreError::BadRange => {
                f.write_str("parameter flash range must be page aligned, at least 2 pages")
            }
            StoreError::MotorsRunning => f.write_str("stop the motors before writing flash"),
            StoreError::InvalidRecord(e) => write!(f, "invalid parameters: {e}"),
            StoreError::Flash(e) => write!(f, "flash: {e}"),
            StoreError::Corrupted => f.write_str("parameter flash corrupted"),
            StoreError::Full => f.write_str("parameter flash full"),
            StoreError::Encoding => f.write_str("parameter record could not be encoded"),
            StoreError::Internal => f.write_str("storage internal error"),
            StoreError::FlashTooSmall(t) => write!(f, "{t}"),
        }
    }
}

impl core::error::Error for StoreError {}

impl<E: NorFlashError> From<sequential_storage::Error<E>> for StoreError {
    fn from(e: sequential_storage::Error<E>) -> Self {
        use sequential_storage::Error as S;
        match e {
            S::Storage { value, .. } => StoreError::Flash(value.kind().into()),
            S::FullStorage => StoreError::Full,
            // A buffer too small for a stored item means a garbage header passed its CRC.
            S::Corrupted { .. } | S::BufferTooSmall(_) => StoreError::Corrupted,
            S::SerializationError(_) => StoreError::Encoding,
            _ => StoreError::Internal,
        }
    }
}

/// Why [`ParamStore::load`] fell back to defaults.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
#[non_exhaustive]
pub enum LoadWarning {
    /// No record has been saved (or the flash was wiped).
    Missing,
    /// The flash could not be read or its contents are corrupted.
    Unreadable(StoreError),
    /// The stored record's layout is not one this firmware reads (length, method name).
    Malformed(FormatError),
    /// The stored record has a format version this firmware does not read.
    UnsupportedVersion {
        /// Version byte found.
        found: u8,
    },
    /// The stored record decoded but a value is out of range (NaN, absurd geometry, …).
    Invalid(RecordError),
    /// The part's flash is too small for the storage map: nothing can be stored.
    FlashTooSmall(FlashTooSmall),
}

impl fmt::Display for LoadWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoadWarning::Missing => f.write_str("no stored parameters"),
            LoadWarning::Unreadable(e) => write!(f, "stored parameters unreadable: {e}"),
            LoadWarning::Malformed(e) => write!(f, "stored parameters malformed: {e}"),
            LoadWarning::UnsupportedVersion { found } => write!(
                f,
                "stored parameters have format version {}, this firmware reads {}",
                // Widened: the replies print unsigned numbers through the `u32` formatter only.
                u32::from(*found),
                u32::from(ParamRecord::FORMAT_VERSION)
            ),
            LoadWarning::Invalid(e) => write!(f, "stored parameters invalid: {e}"),
            LoadWarning::FlashTooSmall(t) => write!(f, "{t}"),
        }
    }
}

impl core::error::Error for LoadWarning {}

/// What boot gets: the record to use, and why it is the default one if it is.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOutcome {
    /// The stored record, or [`ParamRecord::DEFAULT`] if `warning` is set.
    pub record: ParamRecord,
    /// `None` when the stored record was used.
    pub warning: Option<LoadWarning>,
}

/// The parameter store over a NOR flash range.
pub struct ParamStore<F: MultiwriteNorFlash> {
    map: Map<F>,
    buf: AlignedBuf,
    wipes: u32,
    /// Run item keys the committed run index lists (bit i = key `RUN_KEY_FIRST + i`).
    live_run_keys: u32,
    /// Serial number of the next run item.
    next_serial: u32,
    /// [`Self::wipes`] when the session's run ids were last valid (a wipe forgets every run).
    runs_wipes: u32,
    /// Set when the part's flash cannot hold the map: the flash is never touched.
    too_small: Option<FlashTooSmall>,
}

impl<F: MultiwriteNorFlash> ParamStore<F> {
    /// A store over `range` (byte offsets in `flash`; page aligned, at least two pages).
    ///
    /// # Errors
    /// [`StoreError::BadRange`] if the range is misaligned or too small.
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, StoreError> {
        let config = MapConfig::<F>::try_new(range).map_err(|_| StoreError::BadRange)?;
        Ok(Self::from_config(flash, config))
    }

    /// A store with a configuration checked at compile time, e.g.
    /// `ParamStore::from_config(flash, const { MapConfig::new(RANGE) })` (an invalid range is
    /// then a build error, so this cannot fail).
    pub fn from_config(flash: F, config: MapConfig<F>) -> Self {
        ParamStore {
            map: MapStorage::new(flash, config, Cache::new_uncached()),
            buf: AlignedBuf([0; BUF_LEN]),
            wipes: 0,
            live_run_keys: 0,
            next_serial: 1,
            runs_wipes: 0,
            too_small: None,
        }
    }

    /// A store that refuses to touch the flash, for a part whose flash is smaller than the
    /// map: loading gives the defaults with [`LoadWarning::FlashTooSmall`], saving fails with
    /// [`StoreError::FlashTooSmall`], no runs are restored or stored.
    pub fn without_flash(flash: F, config: MapConfig<F>, too_small: FlashTooSmall) -> Self {
        let mut store = Self::from_config(flash, config);
        store.too_small = Some(too_small);
        store
    }

    /// Whether a write may go ahead: the part's flash holds the map and the motors are stopped
    /// (an erase stalls the bus for up to seconds).
    fn writable(&self, motors_stopped: bool) -> Result<(), StoreError> {
        if let Some(t) = self.too_small {
            return Err(StoreError::FlashTooSmall(t));
        }
        if !motors_stopped {
            return Err(StoreError::MotorsRunning);
        }
        Ok(())
    }

    /// Why the store cannot use the flash, if it cannot.
    pub fn flash_too_small(&self) -> Option<FlashTooSmall> {
        self.too_small
    }

    /// Loads the stored record; falls back to [`ParamRecord::DEFAULT`] with a logged warning
    /// when it is missing, unreadable, of another version, or invalid. Never panics, never
    /// fails. May repair the flash after an interrupted save (writes/erases).
    pub async fn load(&mut self) -> LoadOutcome {
        if let Some(t) = self.too_small {
            warn!("{}; using default parameters", t);
            return LoadOutcome {
                record: ParamRecord::DEFAULT,
                warning: Some(LoadWarning::FlashTooSmall(t)),
            };
        }
        let warning = match self
            .map
            .fetch_item::<&[u8]>(&mut self.buf.0, &PARAMS_KEY)
            .await
        {
            Ok(Some(bytes)) => match ParamRecord::decode(bytes) {
                Ok(record) => match record.validate() {
                    Ok(()) => {
                        return LoadOutcome {
                            record,
                            warning: None,
                        };
                    }
                    Err(e) => LoadWarning::Invalid(e),
                },
                Err(FormatError::UnsupportedVersion { found }) => {
                    LoadWarning::UnsupportedVersion { found }
                }
                Err(e) => LoadWarning::Malformed(e),
            },
            Ok(None) => LoadWarning::Missing,
            Err(e) => LoadWarning::Unreadable(e.into()),
        };
        warn!("{}; using default parameters", warning);
        LoadOutcome {
            record: ParamRecord::DEFAULT,
            warning: Some(warning),
        }
    }

    /// Saves `record` (validated first). Refuses while the motors run.
    ///
    /// If the stored data is proven bad (corrupted beyond `sequential-storage`'s own repair,
    /// garbage filling the free space, an internal inconsistency), the range is erased (logged)
    /// and the save retried once, so damaged contents never block saving. A flash *driver*
    /// error is returned as it is and nothing is erased: the hardware failed, not the data, and
    /// erasing could destroy the live record and then fail on the next sector too. A power cut
    /// is not an error the code sees: it leaves the old or the new record (see the module docs).
    ///
    /// # Errors
    /// [`StoreError::MotorsRunning`] if `motors_stopped` is false, [`StoreError::InvalidRecord`]
    /// if the record does not validate, otherwise the flash or storage failure.
    pub async fn save(
        &mut self,
        record: &ParamRecord,
        motors_stopped: bool,
    ) -> Result<(), StoreError> {
        self.writable(motors_stopped)?;
        record.validate().map_err(StoreError::InvalidRecord)?;
        let first = self
            .map
            .store_item(&mut self.buf.0, &PARAMS_KEY, record)
            .await
            .map_err(StoreError::from);
        let e = match first {
            Ok(()) => return Ok(()),
            Err(e @ (StoreError::Corrupted | StoreError::Full | StoreError::Internal)) => e,
            Err(e) => {
                warn!(
                    "saving parameters failed ({}); the stored record is unchanged",
                    e
                );
                return Err(e);
            }
        };
        warn!(
            "saving parameters failed ({}); erasing the parameter flash and retrying",
            e
        );
        self.wipes = self.wipes.saturating_add(1);
        self.map.erase_all().await.map_err(StoreError::from)?;
        self.map
            .store_item(&mut self.buf.0, &PARAMS_KEY, record)
            .await
            .map_err(StoreError::from)
    }

    /// Saves [`ParamRecord::DEFAULT`] (forgets the calibration and motion settings); the next
    /// load returns the defaults without a warning.
    ///
    /// # Errors
    /// As [`Self::save`].
    pub async fn reset_to_defaults(&mut self, motors_stopped: bool) -> Result<(), StoreError> {
        self.save(&ParamRecord::DEFAULT, motors_stopped).await
    }

    /// [`Self::load`], run to completion (busy-polls; for `init` and the host).
    pub fn load_blocking(&mut self) -> LoadOutcome {
        embassy_futures::block_on(self.load())
    }

    /// [`Self::save`], run to completion (busy-polls; for the host and low-priority tasks).
    ///
    /// # Errors
    /// As [`Self::save`].
    pub fn save_blocking(
        &mut self,
        record: &ParamRecord,
        motors_stopped: bool,
    ) -> Result<(), StoreError> {
        embassy_futures::block_on(self.save(record, motors_stopped))
    }

    /// [`Self::reset_to_defaults`], run to completion.
    ///
    /// # Errors
    /// As [`Self::save`].
    pub fn reset_to_defaults_blocking(&mut self, motors_stopped: bool) -> Result<(), StoreError> {
        embassy_futures::block_on(self.reset_to_defaults(motors_stopped))
    }

    /// How many saves of this store had to erase the whole range to recover from a failure.
    pub fn wipes(&self) -> u32 {
        self.wipes
    }

    /// The flash, e.g. to inspect a simulated one.
    pub fn flash(&mut self) -> &mut F {
        self.map.flash()
    }

    /// The flash range in use.
    pub fn range(&self) -> Range<u32> {
        self.map.flash_range()
    }

    /// Gives the flash back (a simulated power-down; build a new store to "boot" again).
    pub fn into_flash(self) -> F {
        self.map.destroy().0
    }
}

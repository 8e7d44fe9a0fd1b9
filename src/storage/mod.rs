//! Persistent parameters and the session's runs in NOR flash, in two regions apart.
//!
//! Owns the stored parameter record and its flash map; may use [`crate::motion`]
//! (motion limits, the proof that the motors are stopped), [`crate::kinematics`] (geometry) and
//! [`crate::util`].
//!
//! [`ParamAndRunStore`] keeps the [`ParamRecord`] in the **parameter region**, two erase sectors used
//! A/B ([`params`]: each save appends a copy; the sector holding the newest valid copy is never
//! erased), and the session's runs in the **run region**, a `sequential-storage` map over any
//! [`MultiwriteNorFlash`] range of at least two erase pages ([`runs`]). Nothing done to the run
//! region (a page change, a repair, a wipe after damage) touches the parameter region. Every
//! stored item carries a CRC, and a write interrupted at any byte leaves the old or the new
//! contents readable (see `tests/storage_power_cut.rs`, `docs/storage.md`).
//!
//! Older firmware kept the record in the run region's map (key [`PARAMS_KEY`]); loading moves
//! it to the parameter region ([`ParamAndRunStore::load`]).
//!
//! Loading never fails: a missing, unreadable, corrupt, unknown-version or invalid record gives
//! [`ParamRecord::DEFAULT`] plus a [`LoadWarning`] (also logged with `warn!`). Writing takes the
//! controller's proof that the motors are stopped ([`MotorsStopped`]), because a flash erase
//! stalls the CPU.
//!
//! `sequential-storage` is async-only; the `*_blocking` methods run the same futures to
//! completion with `embassy_futures::block_on`, for the firmware's `init` and for `host-sim`.
//! Loading the parameters writes only to move an older firmware's record; loading the runs may
//! repair the run region after an interrupted write. Boot is the place for both (motors
//! stopped).

pub mod params;
// A test double (flash in RAM, with injected faults) for the host's tests and host-sim: never
// compiled for the board.
#[cfg(not(target_os = "none"))]
pub mod ram_flash;
pub mod record;
pub mod runs;

use core::fmt;
use core::ops::Range;

use embedded_storage_async::nor_flash::{MultiwriteNorFlash, NorFlashError, NorFlashErrorKind};
use sequential_storage::cache::{Cache, Uncached};
pub use sequential_storage::map::MapConfig;
use sequential_storage::map::MapStorage;

pub use self::params::ParamSectors;
pub use self::record::{
    AppliedCalibration, FormatError, METHOD_NAME_MAX, MethodName, ParamRecord, RecordError,
};
pub use self::runs::{RunFormatError, RunLoadProblem, RunsLoaded, StoredRun};
use crate::motion::controller::MotorsStopped;

/// Map key under which older firmware stored the parameter record in the (then shared) map
/// that is now the run region.
pub const PARAMS_KEY: u8 = 1;

/// Longest parameter record the parameter region takes, bytes (today's is
/// [`ParamRecord::ENCODED_LEN`]; the margin is for later versions).
pub const PARAM_DATA_MAX: usize = 512;

const _: () = assert!(ParamRecord::ENCODED_LEN <= PARAM_DATA_MAX);

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
/// run is written straight from the session's record into it, never copied whole elsewhere),
/// and room for a parameter slot.
const BUF_LEN: usize = {
    // A map item may also be fetched from `KEY_AT` on (see `move_old_record`).
    let map = KEY_AT + (1 + ITEM_MAX).next_multiple_of(MAX_WORD);
    let slot = params::slot_len(PARAM_DATA_MAX, MAX_WORD);
    if map > slot { map } else { slot }
};

/// Where an older firmware's record is fetched to in the working buffer: its key byte just
/// before a parameter slot's data, so the value lands where a slot wants it.
const KEY_AT: usize = params::HEADER - 1;

/// The map type used for the runs.
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
    /// The run range is not page aligned or shorter than two erase pages, or the parameter
    /// sectors are misaligned, too small or overlap each other or the run range.
    BadRange,
    /// Refused: the record does not validate.
    InvalidRecord(RecordError),
    /// The flash driver failed.
    Flash(FlashFault),
    /// The stored data is corrupted beyond `sequential-storage`'s repair.
    Corrupted,
    /// The run range is full (cannot happen with the session's runs unless it is damaged).
    Full,
    /// The record could not be serialised.
    Encoding,
    /// `sequential-storage` reported an internal inconsistency.
    Internal,
    /// This part's flash is smaller than the storage map needs: nothing is stored.
    FlashTooSmall(FlashTooSmall),
}

/// A part with less flash than the storage map needs (e.g. a 512 KiB part for a map that ends
/// at 1 MiB).
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

/// The one wording of a store error: what the `err` replies and the boot line say.
impl fmt::Display for StoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let StoreError::InvalidRecord(e) = self {
            return write!(f, "parameters not storable: {e}");
        }
        f.write_str("flash error: ")?;
        match self {
            StoreError::BadRange => f.write_str(
                "storage layout invalid (run range: page aligned, at least 2 pages; parameter sectors apart from it)",
            ),
            StoreError::Flash(e) => write!(f, "{e}"),
            StoreError::Corrupted => f.write_str("flash contents corrupted"),
            StoreError::Full => f.write_str("run flash full"),
            StoreError::Encoding => f.write_str("parameter record could not be encoded"),
            StoreError::Internal => f.write_str("storage internal error"),
            StoreError::FlashTooSmall(_) => {
                f.write_str("no storage: this part's flash is smaller than the storage map")
            }
            StoreError::InvalidRecord(_) => Ok(()),
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

/// Why [`ParamAndRunStore::load`] fell back to defaults.
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
    /// Why the newest stored record was not used, when `record` is the valid one before it.
    pub older: Option<LoadWarning>,
}

/// The parameter and run store over one NOR flash: the parameter region's two sectors and
/// the run region's range (see the module docs).
pub struct ParamAndRunStore<F: MultiwriteNorFlash> {
    map: Map<F>,
    params: ParamSectors,
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
    /// Set when the parameter sectors given to [`Self::from_config`] are unusable.
    bad_layout: bool,
    /// Parameter records moved from the run region since the store was built.
    moved: u32,
}

/// What a stored parameter record's bytes give.
fn decode_record(bytes: &[u8]) -> Result<ParamRecord, LoadWarning> {
    match ParamRecord::decode(bytes) {
        Ok(record) => match record.validate() {
            Ok(()) => Ok(record),
            Err(e) => Err(LoadWarning::Invalid(e)),
        },
        Err(FormatError::UnsupportedVersion { found }) => {
            Err(LoadWarning::UnsupportedVersion { found })
        }
        Err(e) => Err(LoadWarning::Malformed(e)),
    }
}

impl<F: MultiwriteNorFlash> ParamAndRunStore<F> {
    /// A store with the parameter region on `params` and the run region on `runs` (byte
    /// offsets in `flash`; the run range page aligned, at least two pages; the parameter
    /// sectors whole erase units of `flash`, word aligned, apart from each other and the runs).
    ///
    /// # Errors
    /// [`StoreError::BadRange`] if the layout is not that.
    pub fn new(flash: F, params: ParamSectors, runs: Range<u32>) -> Result<Self, StoreError> {
        if !Self::layout_ok(&params, &runs) {
            return Err(StoreError::BadRange);
        }
        let config = MapConfig::<F>::try_new(runs).map_err(|_| StoreError::BadRange)?;
        Ok(Self::from_config(flash, params, config))
    }

    fn layout_ok(params: &ParamSectors, runs: &Range<u32>) -> bool {
        params.valid(params::align_of::<F>(), PARAM_DATA_MAX) && !params.overlaps(runs)
    }

    /// A store with a run map configuration checked at compile time, e.g.
    /// `ParamAndRunStore::from_config(flash, SECTORS, const { MapConfig::new(RANGE) })` (an invalid
    /// range is then a build error). Parameter sectors that [`Self::new`] would refuse give a
    /// store that never touches the flash (loads the defaults, refuses to write, with
    /// [`StoreError::BadRange`]); check them at compile time with [`ParamSectors::valid`].
    pub fn from_config(flash: F, params: ParamSectors, runs: MapConfig<F>) -> Self {
        let map = MapStorage::new(flash, runs, Cache::new_uncached());
        let bad_layout = !Self::layout_ok(&params, &map.flash_range());
        ParamAndRunStore {
            map,
            params,
            buf: AlignedBuf([0; BUF_LEN]),
            wipes: 0,
            live_run_keys: 0,
            next_serial: 1,
            runs_wipes: 0,
            too_small: None,
            bad_layout,
            moved: 0,
        }
    }

    /// A store that refuses to touch the flash, for a part whose flash is smaller than the
    /// map: loading gives the defaults with [`LoadWarning::FlashTooSmall`], saving fails with
    /// [`StoreError::FlashTooSmall`], no runs are restored or stored.
    pub fn without_flash(
        flash: F,
        params: ParamSectors,
        runs: MapConfig<F>,
        too_small: FlashTooSmall,
    ) -> Self {
        let mut store = Self::from_config(flash, params, runs);
        store.too_small = Some(too_small);
        store
    }

    /// Whether the store may use the flash at all.
    ///
    /// # Errors
    /// Why not: [`StoreError::FlashTooSmall`] or [`StoreError::BadRange`].
    pub fn usable(&self) -> Result<(), StoreError> {
        if let Some(t) = self.too_small {
            return Err(StoreError::FlashTooSmall(t));
        }
        if self.bad_layout {
            return Err(StoreError::BadRange);
        }
        Ok(())
    }

    /// Loads the newest valid record of the parameter region; falls back to
    /// [`ParamRecord::DEFAULT`] with a logged warning when it is missing, unreadable, of
    /// another version, or invalid. Never panics, never fails, never erases the parameter
    /// region.
    ///
    /// **Older firmware's record.** When the parameter region holds no valid record, the
    /// record an older firmware kept in the run region's map (key [`PARAMS_KEY`]) is used: its
    /// bytes are copied to the parameter region as they are, read back, and only then removed
    /// from the run region. A power cut in between leaves it in one place or both; with a
    /// record in the parameter region, a copy left in the run region is removed at boot.
    pub async fn load(&mut self) -> LoadOutcome {
        if let Err(e) = self.usable() {
            let warning = match e {
                StoreError::FlashTooSmall(t) => LoadWarning::FlashTooSmall(t),
                e => LoadWarning::Unreadable(e),
            };
            warn!("{}; using default parameters", warning);
            return LoadOutcome {
                record: ParamRecord::DEFAULT,
                warning: Some(warning),
                older: None,
            };
        }
        let found = params::scan(self.map.flash(), &self.params, PARAM_DATA_MAX).await;
        let mut older = None;
        let loaded = match found {
            Err(e) => Err(LoadWarning::Unreadable(e)),
            Ok(found) => match found.newest {
                Some(slot) => {
                    let loaded = match (self.read_record(&slot).await, found.previous) {
                        // The newest record does not decode or validate: the valid one before it.
                        (Err(why), Some(prev)) => match self.read_record(&prev).await {
                            Ok(record) => {
                                warn!("{}; using the record before it", why);
                                older = Some(why);
                                Ok(record)
                            }
                            Err(_) => Err(why),
                        },
                        (newest, _) => newest,
                    };
                    self.remove_old_copy().await;
                    loaded
                }
                None => self.move_old_record(found.never_written()).await,
            },
        };
        match loaded {
            Ok(record) => LoadOutcome {
                record,
                warning: None,
                older,
            },
            Err(warning) => {
                warn!("{}; using default parameters", warning);
                LoadOutcome {
                    record: ParamRecord::DEFAULT,
                    warning: Some(warning),
                    older: None,
                }
            }
        }
    }

    /// The record in `slot`, decoded and validated.
    async fn read_record(&mut self, slot: &params::Slot) -> Result<ParamRecord, LoadWarning> {
        params::read(self.map.flash(), slot, &mut self.buf.0)
            .await
            .map_err(LoadWarning::Unreadable)
            .and_then(decode_record)
    }

    /// The parameter region has no valid record: an older firmware's, from the run region,
    /// decoded and moved (see [`Self::load`]). `never_written`: no slot was ever written to
    /// the parameter region (erased, or an older firmware's program code still in it), so
    /// without an older record nothing is stored.
    async fn move_old_record(&mut self, never_written: bool) -> Result<ParamRecord, LoadWarning> {
        let data_at = self.buf.0.as_ptr() as usize + params::HEADER;
        let fetched = self
            .map
            .fetch_item::<&[u8]>(&mut self.buf.0[KEY_AT..], &PARAMS_KEY)
            .await;
        let (in_place, len) = match fetched {
            Ok(Some(bytes)) => (bytes.as_ptr() as usize == data_at, bytes.len()),
            Ok(None) if never_written => return Err(LoadWarning::Missing),
            // Slots are in the parameter region, and none of them is a valid record.
            Ok(None) => return Err(LoadWarning::Unreadable(StoreError::Corrupted)),
            Err(e) => return Err(LoadWarning::Unreadable(e.into())),
        };
        let data = params::HEADER..params::HEADER + len;
        if !in_place {
            // sequential-storage 8 stores a value right after its key.
            return Err(LoadWarning::Unreadable(StoreError::Internal));
        }
        if len > PARAM_DATA_MAX {
            // Too long for a slot (and for this firmware's decoder): said so, left in place.
            return decode_record(&self.buf.0[data]);
        }
        let record = decode_record(&self.buf.0[data]);
        let copied = self.append_param_slot(len).await;
        match copied {
            Ok(_) => {
                self.moved = self.moved.saturating_add(1);
                info!("parameters moved from the run region to the parameter region");
                self.remove_old_copy().await;
            }
            Err(e) => warn!(
                "moving the parameters to the parameter region failed ({}); read from the run region",
                e
            ),
        }
        record
    }

    /// Appends the `len` record bytes waiting in the working buffer (after the slot header) as
    /// the newest slot of the parameter region ([`params::append`]).
    async fn append_param_slot(&mut self, len: usize) -> Result<params::Slot, StoreError> {
        params::append(
            self.map.flash(),
            &self.params,
            &mut self.buf.0,
            len,
            PARAM_DATA_MAX,
        )
        .await
    }

    /// Removes an older firmware's record from the run region, if one is left there (only
    /// called with a valid record in the parameter region). A failure is logged: the record
    /// in the parameter region wins anyway.
    async fn remove_old_copy(&mut self) {
        if let Err(e) = self.map.remove_item(&mut self.buf.0, &PARAMS_KEY).await {
            warn!(
                "removing the old parameter record from the run region failed ({})",
                StoreError::from(e)
            );
        }
    }

    /// Saves `record` (validated first) as the newest copy in the parameter region, with the
    /// motors `stopped`. Never erases the sector holding the newest valid record, never
    /// touches the run region. A power cut at any byte leaves the old or the new record.
    ///
    /// # Errors
    /// [`StoreError::InvalidRecord`] if the record does not validate, otherwise the flash failure (the stored record is then
    /// unchanged).
    pub async fn save(
        &mut self,
        record: &ParamRecord,
        _stopped: MotorsStopped,
    ) -> Result<(), StoreError> {
        self.usable()?;
        record.validate().map_err(StoreError::InvalidRecord)?;
        let len = record
            .encode(&mut self.buf.0[params::HEADER..])
            .map_err(|_| StoreError::Encoding)?;
        let saved = self.append_param_slot(len).await;
        match saved {
            Ok(_) => Ok(()),
            Err(e) => {
                warn!(
                    "saving parameters failed ({}); the stored record is unchanged",
                    e
                );
                Err(e)
            }
        }
    }

    /// Saves [`ParamRecord::DEFAULT`] (forgets the calibration and motion settings); the next
    /// load returns the defaults without a warning.
    ///
    /// # Errors
    /// As [`Self::save`].
    pub async fn reset_to_defaults(&mut self, stopped: MotorsStopped) -> Result<(), StoreError> {
        self.save(&ParamRecord::DEFAULT, stopped).await
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
        stopped: MotorsStopped,
    ) -> Result<(), StoreError> {
        embassy_futures::block_on(self.save(record, stopped))
    }

    /// [`Self::reset_to_defaults`], run to completion.
    ///
    /// # Errors
    /// As [`Self::save`].
    pub fn reset_to_defaults_blocking(&mut self, stopped: MotorsStopped) -> Result<(), StoreError> {
        embassy_futures::block_on(self.reset_to_defaults(stopped))
    }

    /// How many run saves had to erase the run region to recover from damaged contents (the
    /// parameter region is never wiped).
    pub fn wipes(&self) -> u32 {
        self.wipes
    }

    /// How many older firmware's records this store moved from the run region to the
    /// parameter region (0 or 1 in practice).
    pub fn moved(&self) -> u32 {
        self.moved
    }

    /// The flash, e.g. to inspect a simulated one.
    pub fn flash(&mut self) -> &mut F {
        self.map.flash()
    }

    /// The run region's range.
    pub fn range(&self) -> Range<u32> {
        self.map.flash_range()
    }

    /// The parameter region's sectors.
    pub fn param_sectors(&self) -> &ParamSectors {
        &self.params
    }

    /// Gives the flash back (a simulated power-down; build a new store to "boot" again).
    pub fn into_flash(self) -> F {
        self.map.destroy().0
    }
}

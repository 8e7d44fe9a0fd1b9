//! Store/load round trips, reboots, refusals, version mismatch and invalid records.

mod storage_support;

use odocal::storage::ram_flash::RamFlash;
use odocal::storage::{
    FormatError, LoadWarning, PARAMS_KEY, ParamRecord, ParamStore, RecordError, StoreError,
};
use sequential_storage::cache::Cache;
use sequential_storage::map::{MapConfig, MapStorage};
use storage_support::{BOARD_RANGE, BoardFlash, calibrated};

/// Writes raw bytes under the parameter key, bypassing `ParamStore`'s checks.
fn store_raw(flash: &mut BoardFlash, bytes: &[u8]) {
    let mut map =
        MapStorage::<u8, _, _>::new(flash, MapConfig::new(BOARD_RANGE), Cache::new_uncached());
    let mut buf = [0u8; 256];
    embassy_futures::block_on(map.store_item(&mut buf, &PARAMS_KEY, &bytes)).unwrap();
}

/// The version byte of the record stored under the parameter key, read raw.
fn last_stored_version(flash: &mut BoardFlash) -> Option<u8> {
    let mut map =
        MapStorage::<u8, _, _>::new(flash, MapConfig::new(BOARD_RANGE), Cache::new_uncached());
    let mut buf = [0u8; 256];
    let item: Option<&[u8]> =
        embassy_futures::block_on(map.fetch_item(&mut buf, &PARAMS_KEY)).unwrap();
    item.and_then(|b| b.first().copied())
}

#[test]
fn empty_flash_gives_defaults_with_a_warning() {
    let mut flash = Box::new(BoardFlash::default());
    let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
    let out = store.load_blocking();
    assert_eq!(out.record, ParamRecord::DEFAULT);
    assert_eq!(out.warning, Some(LoadWarning::Missing));
}

#[test]
fn saved_record_survives_a_reboot_bit_exactly() {
    let mut flash = Box::new(BoardFlash::default());
    let rec = calibrated(42);
    {
        let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
        store.save_blocking(&rec, true).unwrap();
    }
    // Reboot: a fresh store (no cached state) over the same flash contents.
    let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
    let out = store.load_blocking();
    // Exact equality: the format stores IEEE bits, so E_d etc. must come back unchanged.
    assert_eq!(out.warning, None);
    assert_eq!(out.record, rec);

    // The latest of several saves wins.
    for n in 0..5 {
        store.save_blocking(&calibrated(100 + n), true).unwrap();
    }
    assert_eq!(store.load_blocking().record, calibrated(104));

    // Reset: defaults, and no warning because a (default) record is stored.
    store.reset_to_defaults_blocking(true).unwrap();
    let out = store.load_blocking();
    assert_eq!(out.record, ParamRecord::DEFAULT);
    assert_eq!(out.warning, None);
}

#[test]
fn works_with_four_byte_words_and_small_pages() {
    let mut flash = RamFlash::<4, 1024, 4>::default();
    let mut store = ParamStore::new(&mut flash, 1024..4096).unwrap();
    for n in 0..40 {
        store.save_blocking(&calibrated(n), true).unwrap();
        assert_eq!(store.load_blocking().record, calibrated(n));
    }
    // Page 0 lies outside the range and must never have been touched.
    assert_eq!(store.flash().erase_counts()[0], 0);
    assert!((0..1024).all(|i| store.flash().byte(i) == Some(0xFF)));
}

#[test]
fn refuses_to_write_while_the_motors_run() {
    let mut flash = Box::new(BoardFlash::default());
    let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
    assert_eq!(
        store.save_blocking(&calibrated(1), false),
        Err(StoreError::MotorsRunning)
    );
    assert_eq!(
        store.reset_to_defaults_blocking(false),
        Err(StoreError::MotorsRunning)
    );
    // Nothing was written.
    assert_eq!(store.flash().bytes_touched(), 0);
}

#[test]
fn refuses_to_save_an_invalid_record() {
    let mut flash = Box::new(BoardFlash::default());
    let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
    let mut bad = calibrated(1);
    bad.calibration.e_b = f64::NAN;
    assert_eq!(
        store.save_blocking(&bad, true),
        Err(StoreError::InvalidRecord(RecordError::Factor))
    );
    assert_eq!(store.flash().bytes_touched(), 0);
}

#[test]
fn stored_nan_record_is_rejected_at_load() {
    let mut flash = Box::new(BoardFlash::default());
    let mut bad = calibrated(7);
    bad.calibration.geometry.diameter_left_m = f64::NAN;
    let mut bytes = [0u8; ParamRecord::ENCODED_LEN];
    bad.encode(&mut bytes).unwrap();
    store_raw(&mut flash, &bytes);
    let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
    let out = store.load_blocking();
    assert_eq!(out.record, ParamRecord::DEFAULT);
    assert!(matches!(
        out.warning,
        Some(LoadWarning::Invalid(RecordError::CalibratedGeometry(_)))
    ));
    // The next save replaces it.
    store.save_blocking(&calibrated(8), true).unwrap();
    assert_eq!(store.load_blocking().warning, None);
}

#[test]
fn other_format_versions_are_rejected_cleanly() {
    let mut bytes = [0u8; ParamRecord::ENCODED_LEN];
    calibrated(3).encode(&mut bytes).unwrap();
    for version in [0u8, 5, 255] {
        let mut flash = Box::new(BoardFlash::default());
        bytes[0] = version;
        store_raw(&mut flash, &bytes);
        let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
        let out = store.load_blocking();
        assert_eq!(out.record, ParamRecord::DEFAULT);
        assert_eq!(
            out.warning,
            Some(LoadWarning::UnsupportedVersion { found: version })
        );
    }
    // A current-version record of the wrong length is malformed, not misread.
    let mut flash = Box::new(BoardFlash::default());
    bytes[0] = ParamRecord::FORMAT_VERSION;
    store_raw(&mut flash, &bytes[..100]);
    let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
    assert_eq!(
        store.load_blocking().warning,
        Some(LoadWarning::Malformed(FormatError::Length {
            expected: ParamRecord::ENCODED_LEN as u16,
            found: 100
        }))
    );
}

/// A board upgraded from a version-3 record (everything but the control rate): it loads
/// through the real flash store with its calibration, wiring and tuning intact and the 1 kHz
/// that firmware ran at; the next save writes a version-4 record that loads back unchanged.
#[test]
fn version_3_records_survive_the_upgrade_at_1_khz() {
    let mut old = calibrated(9);
    old.control_hz = 1_000;
    let mut bytes = [0u8; ParamRecord::ENCODED_LEN];
    old.encode(&mut bytes).unwrap();
    bytes[0] = 3;
    let mut flash = Box::new(BoardFlash::default());
    store_raw(&mut flash, &bytes[..ParamRecord::V3_LEN]);
    let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
    let out = store.load_blocking();
    assert_eq!(out.warning, None);
    assert_eq!(out.record, old);
    // The operator raises the rate and saves: version 4 on flash, read back exactly.
    let mut faster = out.record;
    faster.control_hz = 10_000;
    store.save_blocking(&faster, true).unwrap();
    let again = store.load_blocking();
    assert_eq!(again.warning, None);
    assert_eq!(again.record, faster);
    assert_eq!(last_stored_version(&mut flash), Some(4));
}

/// A board upgraded from an older record format: its stored version-1 record (no wiring byte,
/// no tuning) or version-2 record (no tuning) loads with its calibration intact, the standard
/// wiring (v1) or its own (v2), and the default speed-loop tuning and 1 kHz control rate those
/// firmwares used; the next save writes the current version.
#[test]
fn version_1_and_2_records_survive_the_upgrade() {
    let old = calibrated(5);
    let mut bytes = [0u8; ParamRecord::ENCODED_LEN];
    old.encode(&mut bytes).unwrap();
    for (version, len) in [(1u8, ParamRecord::V1_LEN), (2, ParamRecord::V2_LEN)] {
        bytes[0] = version;
        let mut flash = Box::new(BoardFlash::default());
        store_raw(&mut flash, &bytes[..len]);
        let mut store = ParamStore::new(&mut *flash, BOARD_RANGE).unwrap();
        let out = store.load_blocking();
        assert_eq!(out.warning, None);
        assert_eq!(out.record.calibration, old.calibration);
        assert_eq!(out.record.nominal, old.nominal);
        assert_eq!(out.record.motion, old.motion);
        let wiring = if version == 1 {
            odocal::motion::wiring::Wiring::STANDARD
        } else {
            old.wiring
        };
        assert_eq!(out.record.wiring, wiring);
        assert_eq!(
            out.record.tuning,
            odocal::motion::speed::SpeedTuning::DEFAULT
        );
        assert_eq!(out.record.control_hz, 1_000);
        store.save_blocking(&out.record, true).unwrap();
        let again = store.load_blocking();
        assert_eq!(again.warning, None);
        assert_eq!(again.record, out.record);
    }
}

#[test]
fn bad_ranges_are_refused() {
    let mut flash = Box::new(BoardFlash::default());
    // One sector only: sequential-storage needs two.
    assert!(matches!(
        ParamStore::new(&mut *flash, 0..131_072),
        Err(StoreError::BadRange)
    ));
    // Not sector aligned.
    assert!(matches!(
        ParamStore::new(&mut *flash, 4096..262_144),
        Err(StoreError::BadRange)
    ));
}

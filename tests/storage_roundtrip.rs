//! Store/load round trips, reboots, refusals, version mismatch and invalid records; records
//! of every older format version (fixed bytes those firmwares wrote) read and upgraded.

mod storage_support;

use odocal::motion::controller::{Controller, MotorsRunning};
use odocal::motion::run::{MAX_RUNS, RunRecord};
use odocal::motion::speed::SpeedTuning;
use odocal::motion::wiring::Wiring;
use odocal::storage::ram_flash::RamFlash;
use odocal::storage::runs::{RUN_INDEX_KEY, decode_index, decode_run};
use odocal::storage::{
    FormatError, LoadWarning, PARAMS_KEY, ParamAndRunStore, ParamRecord, ParamSectors, RecordError,
    StoreError, StoredRun,
};
use storage_support::{
    BOARD_PARAMS, BOARD_RUNS, BoardFlash, STOPPED, board_store, calibrated, fetch_raw_in, fixtures,
    newest_param_bytes, store_raw_in,
};

/// Writes raw bytes under the parameter key where older firmware kept the record (the map
/// that is now the run region), bypassing `ParamAndRunStore`'s checks.
fn store_raw(flash: &mut BoardFlash, bytes: &[u8]) {
    store_raw_at(flash, PARAMS_KEY, bytes);
}

/// Writes raw bytes under `key` in the run region's map, bypassing `ParamAndRunStore`'s checks.
fn store_raw_at(flash: &mut BoardFlash, key: u8, bytes: &[u8]) {
    store_raw_in(flash, BOARD_RUNS, key, bytes);
}

/// The version byte of the newest record in the parameter region, read raw.
fn last_stored_version(flash: &mut BoardFlash) -> Option<u8> {
    newest_param_bytes(flash, &BOARD_PARAMS).and_then(|b| b.first().copied())
}

#[test]
fn empty_flash_gives_defaults_with_a_warning() {
    let mut flash = Box::new(BoardFlash::default());
    let mut store = board_store(&mut *flash);
    let out = store.load_blocking();
    assert_eq!(out.record, ParamRecord::DEFAULT);
    assert_eq!(out.warning, Some(LoadWarning::Missing));
}

#[test]
fn saved_record_survives_a_reboot_bit_exactly() {
    let mut flash = Box::new(BoardFlash::default());
    let rec = calibrated(42);
    {
        let mut store = board_store(&mut *flash);
        store.save_blocking(&rec, STOPPED).unwrap();
    }
    // Reboot: a fresh store (no cached state) over the same flash contents.
    let mut store = board_store(&mut *flash);
    let out = store.load_blocking();
    // Exact equality: the format stores IEEE bits, so E_d etc. must come back unchanged.
    assert_eq!(out.warning, None);
    assert_eq!(out.record, rec);

    // The latest of several saves wins.
    for n in 0..5 {
        store.save_blocking(&calibrated(100 + n), STOPPED).unwrap();
    }
    assert_eq!(store.load_blocking().record, calibrated(104));

    // Reset: defaults, and no warning because a (default) record is stored.
    store.reset_to_defaults_blocking(STOPPED).unwrap();
    let out = store.load_blocking();
    assert_eq!(out.record, ParamRecord::DEFAULT);
    assert_eq!(out.warning, None);
}

#[test]
fn works_with_four_byte_words_and_small_pages() {
    let mut flash = RamFlash::<6, 1024, 4>::default();
    let sectors = ParamSectors::new(1024..2048, 2048..3072);
    let mut store = ParamAndRunStore::new(&mut flash, sectors, 3072..6144).unwrap();
    for n in 0..40 {
        store.save_blocking(&calibrated(n), STOPPED).unwrap();
        assert_eq!(store.load_blocking().record, calibrated(n));
    }
    // 40 saves of 180-byte slots change sectors several times.
    assert!(store.flash().erase_counts()[1..3].iter().all(|&e| e >= 3));
    // Page 0 lies outside the layout and the run region was not needed: never touched.
    assert_eq!(store.flash().erase_counts()[0], 0);
    assert!((0..1024).all(|i| store.flash().byte(i) == Some(0xFF)));
    assert!((3072..6144).all(|i| store.flash().byte(i) == Some(0xFF)));
}

/// A write takes the controller's proof that the motors are stopped: a controller that has not
/// confirmed them stopped (no control period has run) gives the refusal instead, and the store
/// is never asked.
#[test]
fn refuses_to_write_while_the_motors_run() {
    let controller = Controller::new(ParamRecord::DEFAULT.controller_config()).unwrap();
    let mut flash = Box::new(BoardFlash::default());
    let mut store = board_store(&mut *flash);
    let saved = controller
        .motors_stopped()
        .map(|stopped| store.save_blocking(&calibrated(1), stopped));
    assert_eq!(saved, Err(MotorsRunning));
    let reset = controller
        .motors_stopped()
        .map(|stopped| store.reset_to_defaults_blocking(stopped));
    assert_eq!(reset, Err(MotorsRunning));
    // Nothing was written.
    assert_eq!(store.flash().bytes_touched(), 0);
}

#[test]
fn refuses_to_save_an_invalid_record() {
    let mut flash = Box::new(BoardFlash::default());
    let mut store = board_store(&mut *flash);
    let mut bad = calibrated(1);
    bad.calibration.as_mut().unwrap().e_b = f64::NAN;
    assert_eq!(
        store.save_blocking(&bad, STOPPED),
        Err(StoreError::InvalidRecord(RecordError::Factor))
    );
    assert_eq!(store.flash().bytes_touched(), 0);
}

#[test]
fn stored_nan_record_is_rejected_at_load() {
    let mut flash = Box::new(BoardFlash::default());
    let mut bad = calibrated(7);
    bad.active.diameter_left_m = f64::NAN;
    let mut bytes = [0u8; ParamRecord::ENCODED_LEN];
    bad.encode(&mut bytes).unwrap();
    store_raw(&mut flash, &bytes);
    let mut store = board_store(&mut *flash);
    let out = store.load_blocking();
    assert_eq!(out.record, ParamRecord::DEFAULT);
    assert!(matches!(
        out.warning,
        Some(LoadWarning::Invalid(RecordError::CalibratedGeometry(_)))
    ));
    // The next save replaces it.
    store.save_blocking(&calibrated(8), STOPPED).unwrap();
    assert_eq!(store.load_blocking().warning, None);
}

#[test]
fn other_format_versions_are_rejected_cleanly() {
    let mut bytes = [0u8; ParamRecord::ENCODED_LEN];
    calibrated(3).encode(&mut bytes).unwrap();
    for version in [0u8, 6, 255] {
        let mut flash = Box::new(BoardFlash::default());
        bytes[0] = version;
        store_raw(&mut flash, &bytes);
        let mut store = board_store(&mut *flash);
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
    let mut store = board_store(&mut *flash);
    assert_eq!(
        store.load_blocking().warning,
        Some(LoadWarning::Malformed(FormatError::Length {
            expected: ParamRecord::ENCODED_LEN as u16,
            found: 100
        }))
    );
}

/// What today's firmware must read from the version-`version` fixture: the fixture's values,
/// with the wiring, tuning and control rate of a version that did not store them as the
/// firmwares of that version used them (standard wiring, default tuning, 1 kHz).
fn migrated(version: u8) -> ParamRecord {
    let mut want = fixtures::param_record();
    if version < 2 {
        want.wiring = Wiring::STANDARD;
    }
    if version < 3 {
        want.tuning = SpeedTuning::DEFAULT;
    }
    if version < 4 {
        want.control_hz = 1_000;
    }
    if version < 5 {
        let d = ParamRecord::DEFAULT;
        want.measure_sd_m = d.measure_sd_m;
        want.heading_sd_rad = d.heading_sd_rad;
        want.convention = d.convention;
    }
    want
}

/// The parameter-record fixtures with their version.
const PARAM_FIXTURES: [(u8, &str); 5] = [
    (1, fixtures::PARAM_RECORD_V1),
    (2, fixtures::PARAM_RECORD_V2),
    (3, fixtures::PARAM_RECORD_V3),
    (4, fixtures::PARAM_RECORD_V4),
    (5, fixtures::PARAM_RECORD_V5),
];

/// Asserts that each listed field of `got` equals that of `want`, naming the first that does
/// not.
macro_rules! assert_fields_eq {
    ($version:expr, $got:expr, $want:expr; $($($field:ident).+),+ $(,)?) => {
        $(
            assert_eq!(
                $got.$($field).+,
                $want.$($field).+,
                "version {}: `{}` misread",
                $version,
                stringify!($($field).+)
            );
        )+
    };
}

/// Records written by each older firmware (fixed bytes, not today's encoder) decode to the
/// values they were written from, field by field.
#[test]
fn stored_records_of_every_version_decode_to_their_values() {
    for (version, hex) in PARAM_FIXTURES {
        let bytes = fixtures::fixture_bytes(hex);
        assert_eq!(bytes[0], version);
        let got = ParamRecord::decode(&bytes).unwrap();
        let want = migrated(version);
        assert_fields_eq!(version, got, want;
            nominal.diameter_right_m,
            nominal.diameter_left_m,
            nominal.wheelbase_m,
            nominal.counts_per_rev,
            active.diameter_right_m,
            active.diameter_left_m,
            active.wheelbase_m,
            active.counts_per_rev,
            motion.max_speed_mps,
            motion.max_accel_mps2,
            motion.max_turn_rate_radps,
            motion.max_turn_accel_radps2,
            square_side_m,
            runs_per_direction,
            wiring.motor_right_reversed,
            wiring.motor_left_reversed,
            wiring.encoder_right_reversed,
            wiring.encoder_left_reversed,
            tuning.right.gain_forward_mps,
            tuning.right.gain_backward_mps,
            tuning.right.time_constant_s,
            tuning.right.deadband,
            tuning.left.gain_forward_mps,
            tuning.left.gain_backward_mps,
            tuning.left.time_constant_s,
            tuning.left.deadband,
            tuning.bandwidth_radps,
            tuning.output_limit,
            control_hz,
            measure_sd_m,
            heading_sd_rad,
            convention,
        );
        let (got_c, want_c) = (got.calibration.clone(), want.calibration.clone());
        let (got_c, want_c) = (got_c.unwrap(), want_c.unwrap());
        assert_fields_eq!(version, got_c, want_c;
            e_d,
            e_b,
            e_s,
            method,
            runs_used,
            e_max_m,
        );
        // Whole-record equality too, so a field added later cannot be left out of the list.
        assert_eq!(got, want, "version {version}");
        assert_eq!(got.validate(), Ok(()), "version {version}");
    }
}

/// The current format has not moved: today's encoder writes the version-5 fixture byte for
/// byte, as the firmware that introduced version 5 did.
#[test]
fn todays_encoder_writes_the_version_5_fixture_byte_for_byte() {
    let mut bytes = [0u8; ParamRecord::ENCODED_LEN];
    assert_eq!(
        fixtures::param_record().encode(&mut bytes),
        Ok(ParamRecord::ENCODED_LEN)
    );
    assert_eq!(
        bytes.as_slice(),
        fixtures::fixture_bytes(fixtures::PARAM_RECORD_V5).as_slice()
    );
}

/// A board upgraded from an older firmware: the record that firmware stored (fixed bytes of
/// each version) loads through the real flash store with its calibration, geometry and motion
/// settings intact, its wiring (v2 on) and tuning (v3 on), and for what a version did not
/// store, the standard wiring, default speed-loop tuning and 1 kHz control rate that firmware
/// used; the next save writes a version-5 record that loads back unchanged.
#[test]
fn records_of_every_older_version_survive_the_upgrade() {
    for (version, hex) in PARAM_FIXTURES {
        let mut flash = Box::new(BoardFlash::default());
        store_raw(&mut flash, &fixtures::fixture_bytes(hex));
        let mut store = board_store(&mut *flash);
        let out = store.load_blocking();
        assert_eq!(out.warning, None, "version {version}");
        assert_eq!(out.record, migrated(version), "version {version}");
        // The operator raises the rate and saves: version 5 on flash, read back exactly.
        let mut faster = out.record;
        faster.control_hz = 10_000;
        store.save_blocking(&faster, STOPPED).unwrap();
        let again = store.load_blocking();
        assert_eq!(again.warning, None);
        assert_eq!(again.record, faster);
        assert_eq!(store.moved(), 1, "version {version}");
        assert_eq!(last_stored_version(&mut flash), Some(5));
    }
}

/// The upgrade to separate regions: a record of every version, in the map older firmware
/// shared with the runs, is copied to the parameter region byte for byte at the first boot and
/// removed from the run region; later boots read it from the parameter region alone.
#[test]
fn records_in_the_old_shared_map_move_to_the_parameter_region() {
    for (version, hex) in PARAM_FIXTURES {
        let bytes = fixtures::fixture_bytes(hex);
        let mut flash = Box::new(BoardFlash::default());
        store_raw(&mut flash, &bytes);
        assert_eq!(newest_param_bytes(&mut *flash, &BOARD_PARAMS), None);
        {
            let mut store = board_store(&mut *flash);
            assert_eq!(store.load_blocking().record, migrated(version));
            assert_eq!(store.moved(), 1);
        }
        assert_eq!(
            newest_param_bytes(&mut *flash, &BOARD_PARAMS).as_deref(),
            Some(bytes.as_slice()),
            "version {version}"
        );
        assert_eq!(fetch_raw_in(&mut *flash, BOARD_RUNS, PARAMS_KEY), None);
        let mut store = board_store(&mut *flash);
        let out = store.load_blocking();
        assert_eq!((out.warning, out.record), (None, migrated(version)));
        assert_eq!(store.moved(), 0, "version {version}: moved once only");
    }
}

/// A parameter region already in use wins over a record left in the run region (a power cut
/// after the copy, before the removal), and that leftover is removed at boot.
#[test]
fn a_leftover_old_record_is_removed_and_never_wins() {
    let mut flash = Box::new(BoardFlash::default());
    board_store(&mut *flash)
        .save_blocking(&calibrated(5), STOPPED)
        .unwrap();
    let mut old = [0u8; ParamRecord::ENCODED_LEN];
    calibrated(4).encode(&mut old).unwrap();
    store_raw(&mut flash, &old);
    let mut store = board_store(&mut *flash);
    let out = store.load_blocking();
    assert_eq!((out.warning, out.record), (None, calibrated(5)));
    assert_eq!(store.moved(), 0);
    assert_eq!(fetch_raw_in(&mut *flash, BOARD_RUNS, PARAMS_KEY), None);
}

/// A board updated from a firmware that never saved: the parameter sectors still hold that
/// firmware's program code and the run region no record. Nothing is stored, and the boot says
/// so (`Missing`, not a corrupted store); the first save erases a sector and is read back. A
/// region whose slots are all damaged stays a corrupted store.
#[test]
fn old_program_code_in_the_parameter_sectors_is_no_record_and_the_first_save_clears_it() {
    let mut flash = Box::new(BoardFlash::default());
    let mut rng = storage_support::Rng(3);
    let params_bytes = (BOARD_PARAMS.sectors[1].end - BOARD_PARAMS.sectors[0].start) as usize;
    for i in 0..params_bytes {
        flash.corrupt_byte(i, rng.next_u64() as u8);
    }
    {
        let mut store = board_store(&mut *flash);
        let out = store.load_blocking();
        assert_eq!(
            (out.warning, out.record),
            (Some(LoadWarning::Missing), ParamRecord::DEFAULT)
        );
        store.save_blocking(&calibrated(8), STOPPED).unwrap();
    }
    let out = board_store(&mut *flash).load_blocking();
    assert_eq!((out.warning, out.record), (None, calibrated(8)));

    // Every slot damaged (its CRC no longer matches): a corrupted store, said so.
    let mut flash = Box::new(BoardFlash::default());
    board_store(&mut *flash)
        .save_blocking(&calibrated(9), STOPPED)
        .unwrap();
    let slot_data = BOARD_PARAMS.sectors[0].start as usize + 20;
    flash.corrupt_byte(slot_data, 0x55);
    let out = board_store(&mut *flash).load_blocking();
    assert_eq!(
        (out.warning, out.record),
        (
            Some(LoadWarning::Unreadable(StoreError::Corrupted)),
            ParamRecord::DEFAULT
        )
    );
}

/// Run items and the run index as the firmware that introduced them wrote them (fixed bytes)
/// decode to the runs, serials, keys and measurements they were written from.
#[test]
fn stored_runs_and_index_decode_to_their_values() {
    let runs = fixtures::run_records();
    let items = [
        fixtures::RUN_ITEM_KEY_16,
        fixtures::RUN_ITEM_KEY_19,
        fixtures::RUN_ITEM_KEY_17,
    ];
    for ((id, run), hex) in runs.iter().zip(items) {
        let (serial, got) = decode_run(&fixtures::fixture_bytes(hex)).unwrap();
        assert_eq!(serial, id.serial, "run at key {}", id.key);
        assert_eq!(got.path, run.path, "run at key {}", id.key);
        assert_eq!(got.geometry, run.geometry, "run at key {}", id.key);
        assert_eq!(got.knots, run.knots, "run at key {}", id.key);
        assert_eq!(got.odometry_end, run.odometry_end, "run at key {}", id.key);
        // The item holds no measurement: it lives in the index.
        assert_eq!(got.measured, None, "run at key {}", id.key);
    }
    let index = decode_index(&fixtures::fixture_bytes(fixtures::RUN_INDEX)).unwrap();
    assert_eq!(index.len(), runs.len());
    for (entry, (id, run)) in index.iter().zip(&runs) {
        assert_eq!(entry.id, *id);
        assert_eq!(entry.measured, run.measured, "run at key {}", id.key);
    }
}

/// A board's flash as the firmware that introduced the run store left it (parameter record
/// v3 of its time, three run items and the index, all fixed bytes): today's firmware restores
/// the parameters and every run with its measurement.
#[test]
fn a_stored_session_of_older_firmware_is_restored() {
    let runs = fixtures::run_records();
    let mut flash = Box::new(BoardFlash::default());
    store_raw(
        &mut flash,
        &fixtures::fixture_bytes(fixtures::PARAM_RECORD_V3),
    );
    let items = [
        fixtures::RUN_ITEM_KEY_16,
        fixtures::RUN_ITEM_KEY_19,
        fixtures::RUN_ITEM_KEY_17,
    ];
    for ((id, _), hex) in runs.iter().zip(items) {
        store_raw_at(&mut flash, id.key, &fixtures::fixture_bytes(hex));
    }
    store_raw_at(
        &mut flash,
        RUN_INDEX_KEY,
        &fixtures::fixture_bytes(fixtures::RUN_INDEX),
    );
    let mut store = board_store(&mut *flash);
    let params = store.load_blocking();
    assert_eq!(params.warning, None);
    assert_eq!(params.record, migrated(3));
    // The record moved to the parameter region; the runs stay where they were.
    assert_eq!(store.moved(), 1);
    let mut got = heapless::Vec::<RunRecord, MAX_RUNS>::new();
    let mut ids = heapless::Vec::<Option<StoredRun>, MAX_RUNS>::new();
    let loaded = store.load_runs_blocking(&mut got, &mut ids);
    assert_eq!(
        (
            loaded.found,
            loaded.restored,
            loaded.measured,
            loaded.skipped
        ),
        (true, 3, 2, 0)
    );
    assert_eq!(loaded.problem, None);
    let want: Vec<RunRecord> = runs.iter().map(|(_, run)| run.clone()).collect();
    let want_ids: Vec<Option<StoredRun>> = runs.iter().map(|(id, _)| Some(*id)).collect();
    assert_eq!(got.as_slice(), want.as_slice());
    assert_eq!(ids.as_slice(), want_ids.as_slice());
}

#[test]
fn bad_layouts_are_refused() {
    let mut flash = Box::new(BoardFlash::default());
    let bad = |flash: &mut BoardFlash, params: ParamSectors, runs: core::ops::Range<u32>| {
        matches!(
            ParamAndRunStore::new(flash, params, runs),
            Err(StoreError::BadRange)
        )
    };
    // The board's layout is accepted.
    assert!(ParamAndRunStore::new(&mut *flash, BOARD_PARAMS, BOARD_RUNS).is_ok());
    // A run region of one page only: sequential-storage needs two.
    assert!(bad(
        &mut flash,
        BOARD_PARAMS,
        BOARD_RUNS.start..BOARD_RUNS.start + 16_384
    ));
    // A run region not page aligned.
    assert!(bad(
        &mut flash,
        BOARD_PARAMS,
        BOARD_RUNS.start + 4096..BOARD_RUNS.end
    ));
    // Parameter sectors overlapping the run region, each other, or too small for a slot.
    assert!(bad(
        &mut flash,
        ParamSectors::new(0..16_384, BOARD_RUNS.start..BOARD_RUNS.start + 16_384),
        BOARD_RUNS
    ));
    assert!(bad(
        &mut flash,
        ParamSectors::new(0..16_384, 8192..24_576),
        BOARD_RUNS
    ));
    assert!(bad(
        &mut flash,
        ParamSectors::new(0..256, 256..512),
        BOARD_RUNS
    ));
}

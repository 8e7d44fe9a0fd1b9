//! The session's runs in the run region, apart from the parameter record: a full store
//! round-trips bit for bit, a corrupted, foreign or absurd run record is reported and skipped at
//! boot without touching the parameters, and a run region damaged beyond repair is erased and
//! written again, the parameter region untouched. (Power cuts: `storage_power_cut.rs`.)

mod storage_support;

use odocal::motion::run::{MAX_KNOTS, MAX_RUNS, RunRecord};
use odocal::session::write_runs_restored;
use odocal::storage::runs::{RunFormatError, decode_run};
use odocal::storage::{ParamAndRunStore, RunLoadProblem, StoredRun};
use storage_support::{
    BOARD_PARAMS, BOARD_RUNS, BoardFlash, Rng, SECTOR, STOPPED, board_store, calibrated,
    measurement, run_record,
};

type Runs = heapless::Vec<RunRecord, MAX_RUNS>;
type Ids = heapless::Vec<Option<StoredRun>, MAX_RUNS>;

/// A full store: `MAX_RUNS` runs of `MAX_KNOTS` knots, every other one measured.
fn full_store() -> Runs {
    let mut runs = Runs::new();
    for n in 0..MAX_RUNS as u32 {
        let mut r = run_record(n, MAX_KNOTS);
        if n % 2 == 0 {
            r.measured = Some(measurement(n));
        }
        runs.push(r).unwrap();
    }
    runs
}

fn boot(flash: &mut BoardFlash) -> (Runs, Ids, odocal::storage::RunsLoaded) {
    let mut store = board_store(flash);
    let (mut runs, mut ids) = (Runs::new(), Ids::new());
    let loaded = store.load_runs_blocking(&mut runs, &mut ids);
    (runs, ids, loaded)
}

fn event(loaded: &odocal::storage::RunsLoaded) -> String {
    let mut s = String::new();
    write_runs_restored(&mut s, loaded).unwrap();
    s
}

/// Saves the parameters and `runs` on a fresh board flash; returns the flash and the ids.
fn stored(runs: &Runs) -> (Box<BoardFlash>, Ids) {
    let mut flash = Box::new(BoardFlash::default());
    let mut store = board_store(&mut *flash);
    store.save_blocking(&calibrated(7), STOPPED).unwrap();
    let mut ids: Ids = runs.iter().map(|_| None).collect();
    store.save_runs_blocking(runs, &mut ids, STOPPED).unwrap();
    (flash, ids)
}

#[test]
fn a_full_run_store_survives_a_reset_bit_for_bit() {
    let runs = full_store();
    let mut flash = Box::new(BoardFlash::default());
    let mut store = board_store(&mut *flash);
    store.save_blocking(&calibrated(7), STOPPED).unwrap();
    let mut ids: Ids = runs.iter().map(|_| None).collect();
    let before = store.flash().bytes_touched();
    store.save_runs_blocking(&runs, &mut ids, STOPPED).unwrap();
    let written = store.flash().bytes_touched() - before;
    // A measurement alone rewrites only the index.
    let mut measured = runs.clone();
    measured[1].measured = Some(measurement(99));
    let before = store.flash().bytes_touched();
    store
        .save_runs_blocking(&measured, &mut ids, STOPPED)
        .unwrap();
    let index_only = store.flash().bytes_touched() - before;
    println!(
        "{MAX_RUNS} runs x {MAX_KNOTS} knots: {written} bytes written; one measurement: \
         {index_only} bytes"
    );
    assert!(index_only < 400, "{index_only}");

    let mut store = board_store(&mut *flash);
    let params = store.load_blocking();
    assert_eq!(params.record, calibrated(7));
    assert_eq!(params.warning, None);
    let (restored, restored_ids, loaded) = boot(&mut flash);
    assert_eq!(restored, measured);
    assert_eq!(restored_ids.as_slice(), ids.as_slice());
    assert_eq!(
        (loaded.restored, loaded.measured, loaded.skipped),
        (12, 7, 0)
    );
    assert_eq!(
        event(&loaded),
        "event runs restored: 12 runs, 7 measured\r\n"
    );
}

/// Offset in the flash of the first occurrence of `needle`.
fn find(flash: &BoardFlash, needle: &[u8]) -> usize {
    let mut image = vec![0u8; BoardFlash::CAPACITY];
    flash.copy_image(&mut image);
    image
        .windows(needle.len())
        .position(|w| w == needle)
        .expect("pattern in flash")
}

#[test]
fn a_corrupted_run_record_is_reported_and_skipped_and_the_parameters_stay() {
    let runs = full_store();
    let (mut flash, _) = stored(&runs);
    // Damage one byte of run 3's last knot (its CRC no longer matches).
    let knot = runs[2].knots.last().unwrap();
    let at = find(&flash, &knot.right.to_le_bytes());
    assert!(flash.corrupt_byte(at, !flash.byte(at).unwrap()));

    let mut store = board_store(&mut *flash);
    let params = store.load_blocking();
    assert_eq!((params.record, params.warning), (calibrated(7), None));
    let (restored, mut ids, loaded) = boot(&mut flash);
    let mut expected = runs.clone();
    expected.remove(2);
    assert_eq!(restored, expected);
    assert_eq!((loaded.restored, loaded.skipped), (11, 1));
    let text = event(&loaded);
    println!("{text}");
    assert!(
        text.starts_with("event runs restored: 11 runs, 5 measured; 1 skipped: run 3: record "),
        "{text}"
    );
    // The store keeps working: the next update stores the 11 runs, and they come back.
    let mut store = board_store(&mut *flash);
    store.load_runs_blocking(&mut Runs::new(), &mut Ids::new());
    store
        .save_runs_blocking(&restored, &mut ids, STOPPED)
        .unwrap();
    let (again, _, loaded) = boot(&mut flash);
    assert_eq!(again, expected);
    assert_eq!(loaded.skipped, 0);
}

#[test]
fn a_foreign_run_record_is_reported_and_skipped() {
    let runs = full_store();
    let (mut flash, mut ids) = stored(&runs);
    // The index names run 5's key with another serial number: the item there is not the run
    // the index means (as after a mix-up of keys), so it must not be restored.
    let mut store = board_store(&mut *flash);
    ids[4].as_mut().unwrap().serial += 1000;
    store.save_runs_blocking(&runs, &mut ids, STOPPED).unwrap();
    let (restored, _, loaded) = boot(&mut flash);
    assert_eq!(restored.len(), 11);
    assert_eq!(loaded.problem, Some(RunLoadProblem::Foreign { run: 5 }));
    assert_eq!(
        event(&loaded),
        "event runs restored: 11 runs, 5 measured; 1 skipped: run 5: record belongs to another \
         run\r\n"
    );
}

#[test]
fn an_absurd_stored_measurement_restores_nothing_and_keeps_the_parameters() {
    let mut runs = full_store();
    runs[0].measured.as_mut().unwrap().x_m = f64::NAN;
    let (mut flash, _) = stored(&runs);
    let mut store = board_store(&mut *flash);
    assert_eq!(store.load_blocking().record, calibrated(7));
    let (restored, _, loaded) = boot(&mut flash);
    assert!(restored.is_empty());
    assert_eq!(
        event(&loaded),
        "event runs restored: 0 runs, 0 measured; run list malformed: bad measurement\r\n"
    );
}

#[test]
fn foreign_or_damaged_run_bytes_are_refused_by_the_decoder() {
    let run = run_record(3, 10);
    // A valid item, as the store writes it: find it in a flash and decode it.
    let mut runs = Runs::new();
    runs.push(run.clone()).unwrap();
    let (flash, ids) = stored(&runs);
    let start = find(&flash, &[1, ids[0].unwrap().serial as u8, 0, 0, 0]);
    let mut image = vec![0u8; BoardFlash::CAPACITY];
    flash.copy_image(&mut image);
    let item = image[start..start + 68 + 16 * 10].to_vec();
    assert_eq!(decode_run(&item), Ok((ids[0].unwrap().serial, run)));

    let with = |offset: usize, value: u8| {
        let mut b = item.clone();
        b[offset] = value;
        decode_run(&b)
    };
    assert_eq!(with(0, 9), Err(RunFormatError::Version { found: 9 }));
    assert_eq!(with(5, 7), Err(RunFormatError::Path));
    assert_eq!(with(67, 11), Err(RunFormatError::Length));
    assert_eq!(with(67, 0), Err(RunFormatError::Length));
    // NaN odometry end (x's top byte).
    let mut nan = item.clone();
    nan[43..51].copy_from_slice(&f64::NAN.to_le_bytes());
    assert_eq!(decode_run(&nan), Err(RunFormatError::Pose));
    // The first knot must be (0, 0).
    assert_eq!(with(68, 1), Err(RunFormatError::Knots));
    // An absurd geometry (wheel diameter 0).
    let mut geo = item.clone();
    geo[15..23].copy_from_slice(&0.0f64.to_le_bytes());
    assert_eq!(decode_run(&geo), Err(RunFormatError::Geometry));
    assert_eq!(decode_run(&item[..60]), Err(RunFormatError::Length));
    assert_eq!(decode_run(&[]), Err(RunFormatError::Length));
}

/// A part whose flash is smaller than the storage map (a 512 KiB STM32F407VE): the store never
/// touches the flash, boots with the defaults and says why, and refuses to save with a clear
/// error; nothing panics.
#[test]
fn a_part_with_too_little_flash_refuses_storage_cleanly() {
    use odocal::session::{Settings, SettingsAndRuns, write_boot_event};
    use odocal::storage::{FlashTooSmall, LoadWarning, MapConfig, ParamRecord, StoreError};

    let mut flash = Box::new(BoardFlash::default());
    let too_small = FlashTooSmall {
        part_kib: 512,
        needed_kib: 1024,
    };
    let mut store = ParamAndRunStore::without_flash(
        &mut *flash,
        BOARD_PARAMS,
        MapConfig::try_new(BOARD_RUNS).unwrap(),
        too_small,
    );
    let loaded = store.load_blocking();
    assert_eq!(loaded.record, ParamRecord::DEFAULT);
    assert_eq!(loaded.warning, Some(LoadWarning::FlashTooSmall(too_small)));
    let mut boot = String::new();
    write_boot_event(&mut boot, &loaded, &[], Some("power-on"), None).unwrap();
    assert_eq!(
        boot,
        "event boot: default parameters (no storage: this part has 512 KiB of flash, the \
         storage map needs 1024 KiB), reset: power-on\r\n"
    );
    assert_eq!(
        store.save_blocking(&calibrated(1), STOPPED),
        Err(StoreError::FlashTooSmall(too_small))
    );
    // Through the session's storage interface: the `err` text of `save`.
    let e = SettingsAndRuns::save(&mut store, &Settings::default(), STOPPED).unwrap_err();
    // The typed store error reaches the reply that names it.
    assert_eq!(e, StoreError::FlashTooSmall(too_small));
    assert_eq!(
        e.to_string(),
        "flash error: no storage: this part's flash is smaller than the storage map"
    );
    let runs = full_store();
    let mut ids: Ids = runs.iter().map(|_| None).collect();
    assert!(store.save_runs_blocking(&runs, &mut ids, STOPPED).is_err());
    let (mut r, mut i) = (Runs::new(), Ids::new());
    assert!(!store.load_runs_blocking(&mut r, &mut i).found);
    assert!(r.is_empty());
    // The flash was never written or erased.
    assert_eq!(store.flash().bytes_touched(), 0);
}

/// The parameter region's bytes and erase counts.
fn param_region(flash: &BoardFlash) -> (Vec<u8>, Vec<u32>) {
    let mut image = vec![0u8; BoardFlash::CAPACITY];
    flash.copy_image(&mut image);
    image.truncate(2 * SECTOR);
    (image, flash.erase_counts()[..2].to_vec())
}

/// The run region overwritten with noise (a stray program, a glitching erase): the parameters
/// still load, the runs are reported lost, and the next run update repairs or erases the run
/// region alone and writes every run again; the parameter region is not written or erased.
#[test]
fn a_damaged_run_region_is_rebuilt_alone() {
    let mut rng = Rng(7);
    // Noise, and every byte programmed to zero (every page looks closed: no free page at all).
    rebuilt_alone(|_| rng.next_u64() as u8, 0);
    rebuilt_alone(|_| 0, 1);
}

fn rebuilt_alone(mut damage: impl FnMut(usize) -> u8, wipes: u32) {
    let runs = full_store();
    let (mut flash, _) = stored(&runs);
    let before = param_region(&flash);
    for i in BOARD_RUNS.start as usize..BOARD_RUNS.end as usize {
        flash.corrupt_byte(i, damage(i));
    }
    let mut store = board_store(&mut *flash);
    let params = store.load_blocking();
    assert_eq!((params.record, params.warning), (calibrated(7), None));
    let (mut restored, mut ids) = (Runs::new(), Ids::new());
    let loaded = store.load_runs_blocking(&mut restored, &mut ids);
    println!("{}", event(&loaded));
    assert!(restored.is_empty());
    // The session still holds its runs in RAM and stores them again.
    let mut ids: Ids = runs.iter().map(|_| None).collect();
    store.save_runs_blocking(&runs, &mut ids, STOPPED).unwrap();
    // sequential-storage's own repair or, failing that, a wipe of the run region.
    assert_eq!(store.wipes(), wipes);
    assert_eq!(param_region(store.flash()), before);
    let (again, _, loaded) = boot(&mut flash);
    assert_eq!(again, runs);
    assert_eq!(loaded.skipped, 0);
    let mut store = board_store(&mut *flash);
    assert_eq!(store.load_blocking().record, calibrated(7));
}

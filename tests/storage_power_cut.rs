//! Power cut at every byte of every write: the next boot must load exactly the old or the new
//! contents, in the parameter region and in the run region.
//!
//! The sweeps use 1 KiB pages instead of the board's 16 KiB parameter and 128 KiB run sectors so
//! that one test run crosses page boundaries several times (a parameter sector filling and the
//! other one erased; a run page closed, its live items moved, the old page erased) while staying
//! fast: the logic does not depend on the page size, only the number of cut points inside an
//! erase does (1 Ki here, 16 Ki and 128 Ki on the board).

mod storage_support;

use odocal::storage::ram_flash::RamFlash;
use odocal::storage::{
    FlashFault, LoadOutcome, LoadWarning, PARAMS_KEY, ParamAndRunStore, ParamRecord, ParamSectors,
    RunsLoaded, StoreError,
};
use std::sync::atomic::AtomicUsize;
use std::sync::atomic::Ordering::Relaxed;
use storage_support::{STOPPED, calibrated, fetch_raw_in, store_raw_in};

const PAGE: usize = 1024;

/// The parameter sweeps' flash: two parameter sectors (pages 0 and 1), then a run region of
/// two pages.
type ParamFlash<const W: usize> = RamFlash<4, PAGE, W>;
const SWEEP_PARAMS: ParamSectors = ParamSectors::new(0..PAGE as u32, PAGE as u32..2 * PAGE as u32);
const SWEEP_RUNS: core::ops::Range<u32> = 2 * PAGE as u32..4 * PAGE as u32;

/// The store the parameter sweeps boot.
fn param_store<const W: usize>(flash: &mut ParamFlash<W>) -> ParamAndRunStore<&mut ParamFlash<W>> {
    ParamAndRunStore::new(flash, SWEEP_PARAMS, SWEEP_RUNS).unwrap()
}

/// The warning of a boot before any record was stored: `Missing` on an erased region, or
/// `Unreadable(Corrupted)` when the first save was cut (a torn slot is there, no record).
fn nothing_stored(warning: &Option<LoadWarning>) -> bool {
    matches!(
        warning,
        Some(LoadWarning::Missing | LoadWarning::Unreadable(StoreError::Corrupted))
    )
}

#[derive(Debug, Default)]
struct Tally {
    /// Cut points tried (one per byte written or erased by the interrupted save).
    cuts: u64,
    /// Cuts that fell inside an erase-containing save.
    cuts_in_saves_with_erase: u64,
    /// Boots that loaded the old record (or "missing" when there was none).
    old: u64,
    /// Boots that loaded the new record.
    new: u64,
    /// Boots that lost the old record (defaults with a warning although one was stored).
    lost: u64,
    /// Boots that loaded anything else.
    garbage: u64,
    /// Saves that did not report the power cut, or recovery saves that failed or had to fall
    /// back to erasing the whole range.
    other_failures: u64,
}

fn sweep<const WORD: usize>(prefills: u32) -> Tally {
    let mut tally = Tally::default();
    let mut base = ParamFlash::<WORD>::default();
    let mut old: Option<ParamRecord> = None;
    for p in 0..prefills {
        let new = calibrated(1000 + p);
        // Length of the operation in bytes: run it once without a cut.
        let mut probe = base.clone();
        let before = probe.bytes_touched();
        let erases_before: u32 = probe.erase_counts().iter().sum();
        param_store(&mut probe)
            .save_blocking(&new, STOPPED)
            .unwrap();
        let len = probe.bytes_touched() - before;
        let with_erase = probe.erase_counts().iter().sum::<u32>() > erases_before;

        for cut in 0..len {
            let mut flash = base.clone();
            flash.cut_power_after(Some(cut as u32));
            let res = param_store(&mut flash).save_blocking(&new, STOPPED);
            if res.is_ok() || flash.is_powered() {
                eprintln!("p={p} cut={cut}/{len}: save returned {res:?}");
                tally.other_failures += 1;
            }
            flash.restore_power();
            tally.cuts += 1;
            if with_erase {
                tally.cuts_in_saves_with_erase += 1;
            }

            // Reboot: loading never writes.
            let mut store = param_store(&mut flash);
            let touched = store.flash().bytes_touched();
            let out = store.load_blocking();
            if store.flash().bytes_touched() != touched {
                eprintln!("p={p} cut={cut}/{len}: the boot wrote");
                tally.other_failures += 1;
            }
            let is_old = match &old {
                Some(o) => out.record == *o && out.warning.is_none(),
                None => out.record == ParamRecord::DEFAULT && nothing_stored(&out.warning),
            };
            if out.record == new && out.warning.is_none() {
                tally.new += 1;
            } else if is_old {
                tally.old += 1;
            } else if out.warning.is_some() {
                tally.lost += 1;
            } else {
                tally.garbage += 1;
            }
            // The flash must stay usable after the cut.
            let again = calibrated(5000 + p);
            let r2 = store.save_blocking(&again, STOPPED);
            let l2 = store.load_blocking();
            if r2.is_err() || l2.record != again || store.wipes() != 0 {
                eprintln!(
                    "p={p} cut={cut}/{len}: recovery save {r2:?}, load {:?}",
                    l2.warning
                );
                tally.other_failures += 1;
            }
        }

        // Advance the base state by one completed save.
        param_store(&mut base).save_blocking(&new, STOPPED).unwrap();
        old = Some(new);
    }
    // The run region was never touched.
    assert!(base.erase_counts()[2..].iter().all(|&e| e == 0));
    assert!(
        (SWEEP_RUNS.start as usize..ParamFlash::<WORD>::CAPACITY)
            .all(|i| base.byte(i) == Some(0xFF))
    );
    tally
}

fn check(tally: &Tally, word: usize) {
    println!(
        "parameter-region power-cut sweep, {word}-byte words, 2 x {PAGE} B sectors: {tally:?}"
    );
    // Exact requirement: no cut may lose the old record or produce anything but old or new.
    assert_eq!(tally.lost, 0, "{tally:?}");
    assert_eq!(tally.garbage, 0, "{tally:?}");
    assert_eq!(tally.other_failures, 0, "{tally:?}");
    assert_eq!(tally.old + tally.new, tally.cuts);
    // The sweep must really have covered saves that change sectors and erase the other one.
    assert!(tally.cuts_in_saves_with_erase >= PAGE as u64, "{tally:?}");
}

/// 24 consecutive saves (each a 178-byte slot, 5 per 1 KiB sector) change sectors four times.
#[test]
fn every_cut_during_a_save_leaves_old_or_new_byte_words() {
    let tally = sweep::<1>(24);
    check(&tally, 1);
}

#[test]
fn every_cut_during_a_save_leaves_old_or_new_word_words() {
    let tally = sweep::<4>(24);
    check(&tally, 4);
}

/// A second cut during the save after an interrupted one: a cut save leaves a torn slot (and,
/// if it was changing sectors, a torn erase); the boot after it writes nothing, and the next save
/// appends after the torn slot or erases the sector without the newest record. Cut that next
/// save too, at every byte, after every first cut of 8 consecutive saves (the 5th and 6th fill
/// the first sector and change to the second, so the next saves after their cuts erase); the
/// boot after it must load the record the first boot loaded or the newer one. Swept on all
/// cores (about 1.9 × 10^6 boots).
#[test]
fn a_second_cut_at_every_byte_of_the_next_save_still_leaves_old_or_new() {
    type F = ParamFlash<1>;
    // The flash before each of the saves, with the record it holds and the one being saved.
    let mut saves: Vec<(u32, F, Option<ParamRecord>, ParamRecord)> = Vec::new();
    let mut base = F::default();
    let mut old: Option<ParamRecord> = None;
    for p in 0..8u32 {
        let new = calibrated(2000 + p);
        saves.push((p, base.clone(), old.clone(), new.clone()));
        param_store(&mut base).save_blocking(&new, STOPPED).unwrap();
        old = Some(new);
    }
    let next = AtomicUsize::new(0);
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(saves.len());
    let tally = std::thread::scope(|s| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                s.spawn(|| {
                    let mut tally = DoubleCut::default();
                    while let Some((p, base, old, new)) = saves.get(next.fetch_add(1, Relaxed)) {
                        double_cut(*p, base, old.clone(), new.clone(), &mut tally);
                    }
                    tally
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap())
            .fold(DoubleCut::default(), DoubleCut::add)
    });
    println!("double cut: {tally:?}");
    assert_eq!(tally.unreported_cuts, 0, "{tally:?}");
    assert_eq!(tally.boot_writes, 0, "{tally:?}");
    assert_eq!(tally.bad, 0, "{tally:?}");
    // Every save was cut at each of its bytes (a save writes at least its record), and the
    // next saves really erased a sector after a torn one.
    assert!(
        tally.first_cuts >= 8 * ParamRecord::ENCODED_LEN as u64,
        "{tally:?}"
    );
    assert!(
        tally.second_cuts_in_erasing_saves >= PAGE as u64 && tally.second_cuts > tally.first_cuts,
        "{tally:?}"
    );
}

/// Counts of the double-cut sweep.
#[derive(Debug, Default)]
struct DoubleCut {
    /// Saves cut (one per byte each save writes or erases).
    first_cuts: u64,
    /// Cut saves that did not report the cut as the flash driver's error.
    unreported_cuts: u64,
    /// Boots after a cut that wrote or erased anything (must be none).
    boot_writes: u64,
    /// Next saves cut (one per byte each writes or erases).
    second_cuts: u64,
    /// Of those, cuts in next saves that erase a sector.
    second_cuts_in_erasing_saves: u64,
    /// Boots that loaded neither the record before the second cut nor the newer one.
    bad: u64,
}

impl DoubleCut {
    fn add(self, o: DoubleCut) -> DoubleCut {
        DoubleCut {
            first_cuts: self.first_cuts + o.first_cuts,
            unreported_cuts: self.unreported_cuts + o.unreported_cuts,
            boot_writes: self.boot_writes + o.boot_writes,
            second_cuts: self.second_cuts + o.second_cuts,
            second_cuts_in_erasing_saves: self.second_cuts_in_erasing_saves
                + o.second_cuts_in_erasing_saves,
            bad: self.bad + o.bad,
        }
    }
}

/// Cuts the save of `new` over `base` (holding `old`) at every byte, and the next save after
/// each such cut at every byte.
fn double_cut(
    p: u32,
    base: &ParamFlash<1>,
    old: Option<ParamRecord>,
    new: ParamRecord,
    tally: &mut DoubleCut,
) {
    let newer = calibrated(3000 + p);
    let mut probe = base.clone();
    let before = probe.bytes_touched();
    param_store(&mut probe)
        .save_blocking(&new, STOPPED)
        .unwrap();
    let len = probe.bytes_touched() - before;
    for cut in 0..len {
        tally.first_cuts += 1;
        let mut cut_once = base.clone();
        cut_once.cut_power_after(Some(cut as u32));
        let res = param_store(&mut cut_once).save_blocking(&new, STOPPED);
        // The cut falls inside the save: the save fails with the driver's power-cut error.
        if res != Err(StoreError::Flash(FlashFault::Other)) || cut_once.is_powered() {
            eprintln!("p={p} cut={cut}/{len}: save returned {res:?}");
            tally.unreported_cuts += 1;
        }
        cut_once.restore_power();
        // The boot writes nothing; it loads old or new (the single-cut sweep checks which).
        let before = cut_once.bytes_touched();
        let first = param_store(&mut cut_once).load_blocking();
        if cut_once.bytes_touched() != before {
            tally.boot_writes += 1;
        }
        // The next save, cut at every byte.
        let mut probe = cut_once.clone();
        let (before, erases) = (probe.bytes_touched(), probe.erase_counts());
        param_store(&mut probe)
            .save_blocking(&newer, STOPPED)
            .unwrap();
        let len2 = probe.bytes_touched() - before;
        let erasing = probe.erase_counts() != erases;
        for cut2 in 0..len2 {
            tally.second_cuts += 1;
            if erasing {
                tally.second_cuts_in_erasing_saves += 1;
            }
            let mut flash = cut_once.clone();
            flash.cut_power_after(Some(cut2 as u32));
            let _ = param_store(&mut flash).save_blocking(&newer, STOPPED);
            flash.restore_power();
            let out = param_store(&mut flash).load_blocking();
            // With nothing stored before, either torn write leaves nothing stored: defaults,
            // and a warning that says so (which of the two depends on where each cut fell).
            let ok_first = (out == first && first.warning.is_none())
                || (old.is_none()
                    && out.record == ParamRecord::DEFAULT
                    && nothing_stored(&out.warning));
            let ok_newer = out.record == newer && out.warning.is_none();
            if !(ok_first || ok_newer) {
                eprintln!("p={p} cut={cut} cut2={cut2}/{len2}: {:?}", out.warning);
                tally.bad += 1;
            }
        }
    }
}

/// The upgrade from the shared map, cut at every byte: a board whose record (and runs) are in
/// the map older firmware shared, with the parameter region erased or holding old program code
/// (sectors 1–2 were program before the upgrade; flashing the new image does not erase them).
/// The first boot copies the record, reads it back and removes it from the run region; a cut at
/// any byte of that boot leaves the record readable at the next boot, the runs untouched, and
/// after one clean boot the record is in the parameter region alone.
#[test]
fn every_cut_while_moving_an_old_record_keeps_it_and_the_runs() {
    let fixture =
        storage_support::fixtures::fixture_bytes(storage_support::fixtures::PARAM_RECORD_V3);
    let want = param_record_v3();
    let mut stats = Vec::new();
    for stale_code in [false, true] {
        let mut base = RunFlash::default();
        if stale_code {
            let mut rng = storage_support::Rng(11);
            for i in 0..2 * RUN_PAGE {
                base.corrupt_byte(i, rng.next_u64() as u8);
            }
        }
        store_raw_in(&mut base, RUN_RANGE, PARAMS_KEY, &fixture);
        // A stored session next to it: three runs, one measured.
        let (mut runs, mut ids) = (Runs::new(), Ids::new());
        {
            let mut store = ParamAndRunStore::new(&mut base, RUN_PARAMS, RUN_RANGE).unwrap();
            for u in [
                Update::Finish(1),
                Update::Finish(2),
                Update::Measure(0, 3),
                Update::Finish(4),
            ] {
                apply(u, &mut runs, &mut ids);
            }
            store.save_runs_blocking(&runs, &mut ids, STOPPED).unwrap();
        }
        // The key-1 item must still be the old record (a run update does not touch it).
        assert_eq!(
            fetch_raw_in(&mut base, RUN_RANGE, PARAMS_KEY),
            Some(fixture.clone())
        );
        let mut probe = base.clone();
        let before = probe.bytes_touched();
        let (_, params, ..) = boot(&mut probe);
        assert_eq!((params.warning, params.record), (None, want.clone()));
        let len = probe.bytes_touched() - before;
        let (mut cuts, mut bad) = (0u64, 0u64);
        for cut in 0..len {
            cuts += 1;
            let mut flash = base.clone();
            flash.cut_power_after(Some(cut as u32));
            let _ = boot(&mut flash);
            flash.restore_power();
            let (_, params, restored, _, loaded) = boot(&mut flash);
            let ok = params.warning.is_none()
                && params.record == want
                && restored == runs
                && loaded.skipped == 0;
            // After that clean boot: moved, and gone from the run region.
            let moved = fetch_raw_in(&mut flash, RUN_RANGE, PARAMS_KEY).is_none()
                && storage_support::newest_param_bytes(&mut flash, &RUN_PARAMS).as_deref()
                    == Some(fixture.as_slice());
            if !(ok && moved) {
                eprintln!(
                    "stale code {stale_code} cut={cut}/{len}: {:?} {} runs, moved {moved}",
                    params.warning,
                    restored.len()
                );
                bad += 1;
            }
        }
        stats.push((stale_code, len, cuts, bad));
    }
    for (stale_code, len, cuts, bad) in &stats {
        println!(
            "moving an old record (parameter region {}): {len} bytes written or erased, {cuts} \
             cuts, {bad} lost",
            if *stale_code {
                "holding old code"
            } else {
                "erased"
            }
        );
    }
    assert!(
        stats.iter().all(|&(_, _, cuts, bad)| bad == 0 && cuts > 0),
        "{stats:?}"
    );
    // With old code in the parameter region, the move erases a sector first.
    assert!(stats[1].1 > PAGE as u64, "{stats:?}");
}

/// The version-3 fixture as today's firmware reads it (1 kHz: v3 stored no rate; the default
/// measuring noise and convention: v3 stored none).
fn param_record_v3() -> ParamRecord {
    let mut want = storage_support::fixtures::param_record();
    want.control_hz = 1000;
    want.measure_sd_m = ParamRecord::DEFAULT.measure_sd_m;
    want.heading_sd_rad = ParamRecord::DEFAULT.heading_sd_rad;
    want.convention = ParamRecord::DEFAULT.convention;
    want
}

// ---- The run store: power cut at every byte of every run-store update ----

use odocal::motion::run::{MAX_RUNS, RunRecord};
use odocal::storage::StoredRun;
use storage_support::{measurement, run_record};

/// Pages of the run-store sweep: two 1 KiB parameter sectors, then a run region of 4 × 1 KiB,
/// so a sequence of ~40 updates closes pages, migrates live runs and erases pages several times
/// while staying fast (the logic of `sequential-storage` does not depend on the page size, only
/// the number of cut points inside an erase does).
const RUN_PAGE: usize = 1024;
type RunFlash = RamFlash<6, RUN_PAGE, 1>;
const RUN_PARAMS: ParamSectors =
    ParamSectors::new(0..RUN_PAGE as u32, RUN_PAGE as u32..2 * RUN_PAGE as u32);
const RUN_RANGE: core::ops::Range<u32> = 2 * RUN_PAGE as u32..6 * RUN_PAGE as u32;
/// Knots per test run: small items (132 B), so that many updates fit the small pages.
const KNOTS: usize = 4;

type Runs = heapless::Vec<RunRecord, MAX_RUNS>;
type Ids = heapless::Vec<Option<StoredRun>, MAX_RUNS>;

/// One change of the session's runs, as the session makes it before storing them.
#[derive(Clone, Copy, Debug)]
enum Update {
    /// A run finished (record `n`).
    Finish(u32),
    /// Run `index` (0-based) measured (or re-measured) with measurement `n`.
    Measure(usize, u32),
    /// Run `index` dropped.
    Drop(usize),
    /// Every run dropped.
    DropAll,
    /// Not a run update: the parameters saved (record `n`), runs unchanged.
    SaveParams(u32),
}

fn apply(update: Update, runs: &mut Runs, ids: &mut Ids) {
    match update {
        Update::Finish(n) => {
            runs.push(run_record(n, KNOTS)).unwrap();
            ids.push(None).unwrap();
        }
        Update::Measure(i, n) => runs[i].measured = Some(measurement(n)),
        Update::Drop(i) => {
            runs.remove(i);
            ids.remove(i);
        }
        Update::DropAll => {
            runs.clear();
            ids.clear();
        }
        Update::SaveParams(_) => {}
    }
}

/// A booted store over `flash`: parameters and runs loaded as `init` loads them.
fn boot(
    flash: &mut RunFlash,
) -> (
    ParamAndRunStore<&mut RunFlash>,
    LoadOutcome,
    Runs,
    Ids,
    RunsLoaded,
) {
    let mut store = ParamAndRunStore::new(flash, RUN_PARAMS, RUN_RANGE).unwrap();
    let params = store.load_blocking();
    let (mut runs, mut ids) = (Runs::new(), Ids::new());
    let loaded = store.load_runs_blocking(&mut runs, &mut ids);
    (store, params, runs, ids, loaded)
}

/// Runs the update on a booted store.
fn perform(
    store: &mut ParamAndRunStore<&mut RunFlash>,
    update: Update,
    runs: &mut Runs,
    ids: &mut Ids,
) -> Result<(), odocal::storage::StoreError> {
    apply(update, runs, ids);
    match update {
        Update::SaveParams(n) => store.save_blocking(&calibrated(n), STOPPED),
        _ => store.save_runs_blocking(runs, ids, STOPPED),
    }
}

/// The session of the sweep: runs finish, are measured and re-measured, dropped one by one and
/// all at once, the store fills to 6 runs, and the parameters are saved in between.
fn run_script() -> Vec<Update> {
    use Update::*;
    let mut script = vec![SaveParams(1)];
    for round in 0..3u32 {
        let b = 10 * round;
        script.extend([
            Finish(b + 1),
            Measure(0, b + 1),
            Finish(b + 2),
            Measure(1, b + 2),
            Finish(b + 3),
            Measure(2, b + 3),
            Measure(0, b + 4),
            Finish(b + 4),
            Drop(1),
            Finish(b + 5),
            Measure(3, b + 5),
            SaveParams(b + 2),
            Finish(b + 6),
            Finish(b + 7),
            Measure(5, b + 6),
            Drop(0),
            DropAll,
        ]);
    }
    script
}

#[derive(Debug, Default)]
struct RunTally {
    /// Cut points tried (one per byte written or erased by the interrupted update).
    cuts: u64,
    /// Cuts inside updates that erased a page.
    cuts_in_updates_with_erase: u64,
    /// Boots that restored the old runs / the new runs.
    old: u64,
    new: u64,
    /// Boots that restored anything else, or reported a run as skipped.
    mixed: u64,
    /// Boots whose parameters were not the last saved ones (old or new for a parameter save).
    params_lost: u64,
    /// Updates that did not report a cut before their commit point, cuts that never happened,
    /// or a next update after the cut that failed.
    other_failures: u64,
}

#[test]
fn every_cut_during_a_run_store_update_leaves_old_or_new_runs_and_the_parameters() {
    let mut base = RunFlash::default();
    let mut tally = RunTally::default();
    let mut params_old: Option<ParamRecord> = None;
    for (step, &update) in run_script().iter().enumerate() {
        // The update once without a cut: its length and the state it commits.
        let mut probe = base.clone();
        let (old_runs, new_runs, params_new, len, with_erase) = {
            let erases_before: u32 = probe.erase_counts().iter().sum();
            let (mut store, _, mut runs, mut ids, _) = boot(&mut probe);
            let old_runs = runs.clone();
            let before = store.flash().bytes_touched();
            perform(&mut store, update, &mut runs, &mut ids).unwrap();
            let len = store.flash().bytes_touched() - before;
            let params_new = match update {
                Update::SaveParams(n) => Some(calibrated(n)),
                _ => params_old.clone(),
            };
            let with_erase = probe.erase_counts().iter().sum::<u32>() > erases_before;
            (old_runs, runs, params_new, len, with_erase)
        };
        // A run update never writes or erases the parameter region.
        let param_bytes = |f: &RunFlash| (0..2 * RUN_PAGE).map(|i| f.byte(i)).collect::<Vec<_>>();
        if !matches!(update, Update::SaveParams(_))
            && (param_bytes(&probe) != param_bytes(&base)
                || probe.erase_counts()[..2] != base.erase_counts()[..2])
        {
            eprintln!("step {step} {update:?}: the parameter region changed");
            tally.other_failures += 1;
        }
        for cut in 0..len {
            let mut flash = base.clone();
            {
                let (mut store, _, mut runs, mut ids, _) = boot(&mut flash);
                store.flash().cut_power_after(Some(cut as u32));
                let res = perform(&mut store, update, &mut runs, &mut ids);
                // A cut while a dropped run's item is removed comes after the commit point:
                // the update reports success (the item left behind is unlisted).
                let removing = res.is_ok() && matches!(update, Update::Drop(_) | Update::DropAll);
                if (res.is_ok() && !removing) || store.flash().is_powered() {
                    eprintln!("step {step} {update:?} cut={cut}/{len}: returned {res:?}");
                    tally.other_failures += 1;
                }
                store.flash().restore_power();
            }
            tally.cuts += 1;
            if with_erase {
                tally.cuts_in_updates_with_erase += 1;
            }
            // Reboot: the runs are the old or the new ones, measurements included, nothing
            // skipped; the parameters are the last saved ones (old or new for a save).
            let (mut store, params, mut runs, mut ids, loaded) = boot(&mut flash);
            let params_ok = match (&params_old, &params_new) {
                (Some(o), Some(n)) => {
                    params.warning.is_none() && (params.record == *o || params.record == *n)
                }
                (None, Some(n)) => {
                    (params.warning.is_none() && params.record == *n)
                        || nothing_stored(&params.warning)
                }
                (_, None) => nothing_stored(&params.warning),
            };
            if !params_ok {
                eprintln!(
                    "step {step} {update:?} cut={cut}: parameters {:?}",
                    params.warning
                );
                tally.params_lost += 1;
            }
            if loaded.skipped != 0 || loaded.problem.is_some() {
                eprintln!("step {step} {update:?} cut={cut}: {loaded:?}");
                tally.mixed += 1;
            } else if runs == new_runs {
                tally.new += 1;
            } else if runs == old_runs {
                tally.old += 1;
            } else {
                eprintln!(
                    "step {step} {update:?} cut={cut}: {} runs restored",
                    runs.len()
                );
                tally.mixed += 1;
            }
            // The flash stays usable: the next update from the restored state succeeds and
            // is restored.
            let next = Update::Finish(900 + step as u32);
            let stored = perform(&mut store, next, &mut runs, &mut ids);
            let (_, _, again, _, _) = boot(&mut flash);
            if stored.is_err() || again != runs {
                eprintln!("step {step} {update:?} cut={cut}: next update {stored:?}");
                tally.other_failures += 1;
            }
        }
        base = probe;
        params_old = params_new;
    }
    println!("run-region power-cut sweep, 4 x {RUN_PAGE} B pages, 1-byte words: {tally:?}");
    assert_eq!(tally.mixed, 0, "{tally:?}");
    assert_eq!(tally.params_lost, 0, "{tally:?}");
    assert_eq!(tally.other_failures, 0, "{tally:?}");
    assert_eq!(tally.old + tally.new, tally.cuts);
    // The sweep must really have covered updates that move live runs and erase a page.
    assert!(
        tally.cuts_in_updates_with_erase >= RUN_PAGE as u64,
        "{tally:?}"
    );
    // And both outcomes must occur: cuts before and after the commit point.
    assert!(tally.old > 0 && tally.new > 0, "{tally:?}");
}

//! Shared pieces of the storage integration tests: flash types, records, a small PRNG.
#![allow(dead_code)]

use embedded_storage_async::nor_flash::MultiwriteNorFlash;
use odocal::kinematics::geometry::Geometry;
use odocal::motion::controller::MotorsStopped;
use odocal::motion::profile::MotionLimits;
use odocal::storage::ram_flash::RamFlash;
use odocal::storage::{AppliedCalibration, ParamAndRunStore, ParamRecord, ParamSectors};

/// Sector size of the STM32F407's sectors 1 and 2 (the parameter region), bytes, and the page
/// of [`BoardFlash`].
pub const SECTOR: usize = 16 * 1024;

/// The proof every write takes that the motors are stopped: these tests drive no motors.
pub const STOPPED: MotorsStopped = MotorsStopped::without_controller();

/// The board's storage: the two 16 KiB parameter sectors, then the 256 KiB run region (paged by
/// 16 KiB here), byte-programmable (as the HAL drives it); host-sim's `SimFlash`.
pub type BoardFlash = RamFlash<18, SECTOR, 1>;

/// The parameter sectors of a [`BoardFlash`] (pages 0 and 1).
pub const BOARD_PARAMS: ParamSectors =
    ParamSectors::new(0..SECTOR as u32, SECTOR as u32..2 * SECTOR as u32);

/// The run region of a [`BoardFlash`]: the map older firmware kept the parameters in too.
pub const BOARD_RUNS: core::ops::Range<u32> = (2 * SECTOR) as u32..(18 * SECTOR) as u32;

/// The store over a [`BoardFlash`] (or anything laid out as one), as the board builds it.
pub fn board_store<F: MultiwriteNorFlash>(flash: F) -> ParamAndRunStore<F> {
    ParamAndRunStore::new(flash, BOARD_PARAMS, BOARD_RUNS).unwrap()
}

/// The parameter record bytes of the newest valid slot of the parameter region, read raw.
pub fn newest_param_bytes<F: MultiwriteNorFlash>(
    flash: &mut F,
    sectors: &ParamSectors,
) -> Option<Vec<u8>> {
    use odocal::storage::params;
    let found = embassy_futures::block_on(params::scan(
        flash,
        sectors,
        odocal::storage::PARAM_DATA_MAX,
    ))
    .unwrap();
    let slot = found.newest?;
    let mut buf = vec![0u8; 1024];
    Some(
        embassy_futures::block_on(params::read(flash, &slot, &mut buf))
            .unwrap()
            .to_vec(),
    )
}

/// Writes raw bytes under `key` into the map at `range` (the old shared map, or the run
/// region), bypassing `ParamAndRunStore`'s checks.
pub fn store_raw_in<F: MultiwriteNorFlash>(
    flash: &mut F,
    range: core::ops::Range<u32>,
    key: u8,
    bytes: &[u8],
) {
    use sequential_storage::cache::Cache;
    use sequential_storage::map::{MapConfig, MapStorage};
    let mut map = MapStorage::<u8, _, _>::new(flash, MapConfig::new(range), Cache::new_uncached());
    let mut buf = [0u8; 2048];
    embassy_futures::block_on(map.store_item(&mut buf, &key, &bytes)).unwrap();
}

/// The raw item under `key` in the map at `range`, if any.
pub fn fetch_raw_in<F: MultiwriteNorFlash>(
    flash: &mut F,
    range: core::ops::Range<u32>,
    key: u8,
) -> Option<Vec<u8>> {
    use sequential_storage::cache::Cache;
    use sequential_storage::map::{MapConfig, MapStorage};
    let mut map = MapStorage::<u8, _, _>::new(flash, MapConfig::new(range), Cache::new_uncached());
    let mut buf = [0u8; 2048];
    let item: Option<&[u8]> = embassy_futures::block_on(map.fetch_item(&mut buf, &key)).unwrap();
    item.map(<[u8]>::to_vec)
}

/// A valid, calibrated record that differs from every other `n` in every calibration field.
pub fn calibrated(n: u32) -> ParamRecord {
    let k = f64::from(n % 1000);
    let e_d = 0.99 + 1e-5 * k;
    let e_b = 1.01 - 7e-6 * k;
    let e_s = 1.0 + 3e-6 * k;
    let nominal = Geometry::PAPER_NOMINAL;
    let methods = ["exact", "lee-x", "umbmark-x"];
    ParamRecord {
        nominal,
        active: nominal.with_factors(e_d, e_b, e_s),
        calibration: Some(AppliedCalibration {
            method: methods[(n % 3) as usize].try_into().unwrap(),
            e_d,
            e_b,
            e_s,
            runs_used: 10 + (n % 7) as u16,
            e_max_m: 1e-4 * (1.0 + k),
        }),
        motion: MotionLimits {
            max_speed_mps: 0.2 + 0.0001 * (n % 1000) as f32,
            ..MotionLimits::DEFAULT
        },
        square_side_m: 2.0,
        runs_per_direction: 1 + (n % 6) as u8,
        wiring: odocal::motion::wiring::Wiring::from_bits((n % 16) as u8)
            .unwrap_or(odocal::motion::wiring::Wiring::STANDARD),
        tuning: {
            let mut t = odocal::motion::speed::SpeedTuning::DEFAULT;
            t.right.gain_forward_mps = 0.5 + 0.001 * (n % 500) as f32;
            t.left.time_constant_s = 0.02 + 0.0001 * (n % 1000) as f32;
            t
        },
        control_hz: odocal::motion::controller::RATES_HZ
            [(n as usize) % odocal::motion::controller::RATES_HZ.len()],
        measure_sd_m: 0.001 + 1e-5 * (n % 100) as f32,
        heading_sd_rad: 0.0035 + 1e-5 * (n % 100) as f32,
        convention: odocal::motion::convention::Convention::ALL
            [(n as usize) % odocal::motion::convention::Convention::ALL.len()],
    }
}

/// SplitMix64: a tiny deterministic PRNG so every failure is reproducible from its seed.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
}

/// A run record that differs from every other `n` (path, knots, odometry end); `knots` knots,
/// unmeasured.
pub fn run_record(n: u32, knots: usize) -> odocal::motion::run::RunRecord {
    use odocal::kinematics::encoder::WheelTicks;
    use odocal::kinematics::reference::PoseF64;
    use odocal::motion::run::{Direction, PathKind, RunRecord};
    let k = f64::from(n);
    let path = match n % 4 {
        0 => PathKind::Square {
            direction: Direction::Cw,
            side_m: 1.0 + 0.25 * k,
        },
        1 => PathKind::Square {
            direction: Direction::Ccw,
            side_m: 1.0 + 0.25 * k,
        },
        2 => PathKind::Line { length_m: 0.5 + k },
        _ => PathKind::Circle {
            direction: Direction::Ccw,
            radius_m: 0.3 + 0.1 * k,
        },
    };
    let mut record = RunRecord {
        path,
        geometry: Geometry::PAPER_NOMINAL.with_factors(1.0 + 1e-4 * k, 1.0 - 2e-4 * k, 1.0),
        knots: heapless::Vec::new(),
        odometry_end: PoseF64::new(0.01 * k, -0.02 * k, 1e-3 * k),
        measured: None,
    };
    for i in 0..knots as i64 {
        let right = i * (1_000_003 + i64::from(n)) - i64::from(n) * i * i;
        let left = i * (999_983 - 7 * i64::from(n));
        record.knots.push(WheelTicks::new(right, left)).unwrap();
    }
    record
}

/// A measurement that differs from every other `n` (with a heading for odd `n`).
pub fn measurement(n: u32) -> odocal::motion::run::Measurement {
    let k = f64::from(n);
    odocal::motion::run::Measurement {
        x_m: 0.001 * k - 0.3,
        y_m: 0.4 - 0.002 * k,
        theta_rad: (n % 2 == 1).then_some(0.01 * k),
    }
}

/// Stored records as the firmware of their time wrote them, and the values they hold (see
/// `tests/fixtures/storage_records.rs`).
pub mod fixtures {
    use odocal::kinematics::encoder::WheelTicks;
    use odocal::kinematics::geometry::Geometry;
    use odocal::kinematics::reference::PoseF64;
    use odocal::motion::convention::Convention;
    use odocal::motion::profile::MotionLimits;
    use odocal::motion::run::{Direction, Measurement, PathKind, RunRecord};
    use odocal::motion::speed::{MotorParams, SpeedTuning};
    use odocal::motion::wiring::Wiring;
    use odocal::storage::{AppliedCalibration, ParamRecord, StoredRun};

    include!("../fixtures/storage_records.rs");
}

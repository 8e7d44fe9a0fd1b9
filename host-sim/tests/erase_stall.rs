//! A flash erase stalls the board's CPU (the F407's single flash bank: no instruction fetch, no
//! interrupt, no control period) while the operator rolls the robot back to its start mark and
//! types the next command. After the stall: no fault, the pose includes the roll, and every
//! byte typed meanwhile is received — the console's DMA ring kept them
//! ([`odocal::app::rx_ring`]), the control task counts the periods the stall took
//! ([`odocal::app::control::MissedPeriods`] on the simulated board's cycle counter, handed to
//! the controller by the app core's period) and takes the counts
//! that arrived as motion (a stall while idle is expected, not a missed period).

use host_sim::sim::board::Board;
use host_sim::sim::flash::SimParamFlash;
use host_sim::sim::robot::sim_config;
use odocal::app::rx_ring::{RingCursor, RingRead};
use odocal::protocol::rx::RxRead;

/// The F407's console ring (`board::f407::console_rx::RX_RING_BYTES`, a target-only module).
const RING: usize = 512;

/// DMA1 stream 5 into the console ring: writes every received byte, sets its half and
/// complete flags as it crosses them.
struct Dma {
    buf: [u8; RING],
    write: usize,
    half: bool,
    full: bool,
    /// Bytes received since the cursor's last call (what the board's cycle counter bounds).
    arrived: usize,
}

impl Dma {
    fn new() -> Self {
        Dma {
            buf: [0; RING],
            write: 0,
            half: false,
            full: false,
            arrived: 0,
        }
    }

    fn receive(&mut self, byte: u8) {
        self.arrived += 1;
        self.buf[self.write] = byte;
        self.write = (self.write + 1) % RING;
        self.half |= self.write == RING / 2;
        self.full |= self.write == 0;
    }

    /// What the console's receive half reads, as `read_console` turns it into reads.
    fn drain(&mut self, cursor: &mut RingCursor<RING>) -> Vec<RxRead> {
        let mut reads = Vec::new();
        loop {
            let (half, full) = (
                std::mem::take(&mut self.half),
                std::mem::take(&mut self.full),
            );
            let arrived = std::mem::take(&mut self.arrived);
            match cursor.next(self.write, half, full, arrived) {
                RingRead::Byte(i) => reads.push(RxRead::Byte(self.buf[i])),
                RingRead::Empty => return reads,
                RingRead::Overrun => reads.push(RxRead::Error),
            }
        }
    }
}

#[test]
fn a_robot_rolled_back_and_keys_typed_during_an_erase_stall_lose_nothing() {
    const RATE_HZ: u32 = 10_000;
    let mut flash = SimParamFlash::default();
    let mut out = String::new();
    let mut board =
        Board::boot(sim_config(1.0, 1.0, 0.0, 1, RATE_HZ), &mut flash, &mut out).expect("boot");
    // A few ordinary periods at rest: on time, nothing missed.
    for _ in 0..10 {
        board.step(&mut out);
        assert_eq!(board.last_missed(), 0);
    }
    let x0 = board.controller.pose().to_f64().x_m;
    let true_x0 = board.sim.true_pose().x_m;

    // A 0.3 s stall (a 16 KiB sector's typical erase): the robot is rolled back at 0.1 m/s and
    // `status` typed, a key every 20 ms, while no period runs.
    const STALL_PERIODS: u32 = 3_000;
    let mut dma = Dma::new();
    let typed = b"status\r";
    board.sim.set_push(Some(-0.1));
    for p in 0..STALL_PERIODS {
        board.sim.advance();
        if p % 200 == 0
            && let Some(&key) = typed.get((p / 200) as usize)
        {
            dma.receive(key);
        }
    }
    board.sim.set_push(None);
    board.stall(STALL_PERIODS);

    // The first period after the stall: the cycle counter shows the periods that never ran,
    // and the app core's period hands them to the controller.
    let step = board.step(&mut out);
    let late = board.last_missed();
    assert_eq!(late, STALL_PERIODS);
    assert_eq!(step.fault, None, "the roll is motion, not a glitch");
    let rolled = board.sim.true_pose().x_m - true_x0;
    let moved = board.controller.pose().to_f64().x_m - x0;
    // Up to 0.1 m/s for 0.3 s (the hand's push takes the wheels up to speed): 20–30 mm back.
    // The odometry sees the whole roll, to one period's motion at 0.1 m/s (10 µm) plus its
    // integration rounding.
    assert!((-0.030..-0.020).contains(&rolled), "rolled {rolled} m");
    assert!(
        (moved - rolled).abs() < 2e-5,
        "odometry moved {moved} m, the robot {rolled} m"
    );
    assert!(!board.controller.pose_lost());

    // The serial receive drains the ring: every key, in order, and the command runs.
    let mut cursor = RingCursor::<RING>::new();
    let reads = dma.drain(&mut cursor);
    let bytes: Vec<u8> = reads
        .iter()
        .map(|r| match r {
            RxRead::Byte(b) => *b,
            other => panic!("a lost byte: {other:?}"),
        })
        .collect();
    assert_eq!(bytes, typed);
    let mut echo = String::new();
    board.receive_reads(reads, &mut echo);
    let mut reply = String::new();
    board.process(&mut reply, false);
    // `status` answers whole: no fault, the rolled pose, and no missed periods (a stall while
    // idle is what an erase does: expected, not counted) nor a lost pose.
    assert!(reply.starts_with("ok state=idle fault=none "), "{reply}");
    let x: f64 = reply
        .split_whitespace()
        .find_map(|w| w.strip_prefix("x="))
        .and_then(|v| v.parse().ok())
        .expect("x in status");
    assert!((x - moved).abs() < 1e-6, "status x={x}, odometry {moved}");
    assert!(!reply.contains("missed_periods"), "{reply}");
    assert!(!reply.contains("pose=lost"), "{reply}");
}

/// 770 bytes of pasted commands arrive during an erase stall, with the ring's last read at
/// index 255: the write position ends at index 1, 258 bytes on as far as it can tell, and that
/// path crosses both the middle and the end, so the DMA's flags alone look like no lap.
/// The bytes the line can have delivered meanwhile (770) hold a whole extra lap: an overrun.
/// The line in progress is discarded and answered `err 21` once; no line spliced from two
/// commands runs, and the next command is answered normally.
#[test]
fn a_lap_during_an_erase_stall_is_one_err_21_and_no_spliced_line() {
    let mut flash = SimParamFlash::default();
    let mut out = String::new();
    let mut board =
        Board::boot(sim_config(1.0, 1.0, 0.0, 1, 1000), &mut flash, &mut out).expect("boot");
    let mut dma = Dma::new();
    let mut cursor = RingCursor::<RING>::new();
    // 255 bytes read before the stall: `pose` lines (5 bytes each) make 255.
    for _ in 0..51 {
        for &b in b"pose\r" {
            dma.receive(b);
        }
    }
    let reads = dma.drain(&mut cursor);
    assert_eq!(reads.len(), 255);
    let mut echo = String::new();
    board.receive_reads(reads, &mut echo);
    let mut reply = String::new();
    board.process(&mut reply, false);
    assert_eq!(reply.matches("ok x=").count(), 51, "{reply}");

    // 110 × `status\r` (770 bytes) while the CPU is stalled.
    for _ in 0..110 {
        for &b in b"status\r" {
            dma.receive(b);
        }
    }
    let reads = dma.drain(&mut cursor);
    assert_eq!(
        reads.iter().filter(|r| matches!(r, RxRead::Error)).count(),
        1,
        "{reads:?}"
    );
    assert!(
        !reads.iter().any(|r| matches!(r, RxRead::Byte(_))),
        "{reads:?}"
    );
    board.receive_reads(reads, &mut echo);
    for &b in b"status\r" {
        dma.receive(b);
    }
    let reads = dma.drain(&mut cursor);
    board.receive_reads(reads, &mut echo);
    for &b in b"status\r" {
        dma.receive(b);
    }
    let reads = dma.drain(&mut cursor);
    board.receive_reads(reads, &mut echo);
    let mut reply = String::new();
    board.process(&mut reply, false);
    assert_eq!(reply.matches("err 21").count(), 1, "{reply}");
    assert_eq!(reply.matches("ok state=").count(), 1, "{reply}");
    assert!(
        !reply.contains("err 1:") && !reply.contains("unknown"),
        "{reply}"
    );
}

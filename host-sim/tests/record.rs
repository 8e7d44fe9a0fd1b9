//! `record` and `version` on the simulated board: a run's record read back over the protocol by
//! the library's [`RecordReader`] is the board's record, bit for bit (knots, geometry, odometry
//! end, measurement), page by page; bad page requests are refused.

use host_sim::sim::board::{Board, measure_line};
use host_sim::sim::flash::SimParamFlash;
use host_sim::sim::robot::sim_config;
use odocal::protocol::record::{
    PROTOCOL_VERSION, RECORD_PAGE_KNOTS, RecordReader, RecordReplyError,
};

/// Reads run `n` page by page with `record n [first]`; returns the pages' final lines too.
fn read_record(b: &mut Board<'_>, n: usize) -> (odocal::motion::run::RunRecord, Vec<String>) {
    let mut reader = RecordReader::new();
    let mut finals = Vec::new();
    while let Some(first) = reader.next_first() {
        let reply = b.send(&format!("record {n} {first}"));
        let mut lines = reply.lines();
        let last = lines.next_back().expect("a final line").to_string();
        for l in lines {
            reader.feed(l).unwrap_or_else(|e| panic!("{e}: {l}"));
        }
        assert!(last.starts_with("ok "), "{reply}");
        finals.push(last);
        assert!(finals.len() < 10, "pages do not end: {finals:?}");
    }
    assert_eq!(reader.number(), Some(n));
    (reader.finish().expect("complete"), finals)
}

#[test]
fn record_pages_read_back_to_the_boards_run_record() {
    let mut flash = SimParamFlash::erased();
    let mut out = String::new();
    let mut b = Board::boot(sim_config(0.995, 1.010, 0.0, 1, 1000), &mut flash, &mut out).unwrap();
    assert_eq!(
        b.send("version"),
        format!(
            "ok odocal {} protocol {PROTOCOL_VERSION}\r\n",
            env!("CARGO_PKG_VERSION")
        )
    );
    assert_eq!(b.send("record 1"), "err 14: no run 1 (0 stored)\r\n");
    b.send("set square_side 1");
    b.send("run ccw");
    b.run_until_rest(120_000, &mut out);
    let line = measure_line(&b).unwrap();
    assert!(b.send(&line).starts_with("ok run 1"));
    b.send("run cw");
    b.run_until_rest(120_000, &mut out);

    for n in 1..=2 {
        let (record, finals) = read_record(&mut b, n);
        let board = &b.session.runs()[n - 1];
        assert_eq!(&record, board, "run {n}");
        // The bit patterns survive: PartialEq on f64 would accept -0.0 for 0.0.
        assert_eq!(
            record.odometry_end.theta_rad.to_bits(),
            board.odometry_end.theta_rad.to_bits()
        );
        let knots = board.knots.len();
        assert!(knots > RECORD_PAGE_KNOTS, "{knots} knots fit one page");
        assert_eq!(finals.len(), knots.div_ceil(RECORD_PAGE_KNOTS));
        assert_eq!(
            finals[0],
            format!("ok run {n} knots 0..{} of {knots}", RECORD_PAGE_KNOTS - 1)
        );
    }
    assert!(b.session.runs()[0].measured.is_some());
    assert!(b.session.runs()[1].measured.is_none());

    let knots = b.session.runs()[0].knots.len();
    assert_eq!(
        b.send(&format!("record 1 {knots}")),
        format!("err 6: run 1 has {knots} knots\r\n")
    );
    assert_eq!(b.send("record 0"), "err 6: <n> must be within 1..65535\r\n");

    // A page out of order or from another run is refused by the reader.
    let page1 = b.send("record 1 32");
    let mut reader = RecordReader::new();
    let first = page1.lines().find(|l| l.contains("knot 32")).unwrap();
    for l in page1.lines().take_while(|l| !l.contains("knot ")) {
        reader.feed(l).unwrap();
    }
    assert_eq!(reader.feed(first), Err(RecordReplyError::KnotOrder));
    let other = b.send("record 2");
    let header = other.lines().next().unwrap();
    assert_eq!(reader.feed(header), Err(RecordReplyError::Inconsistent));
    assert_eq!(
        reader.feed("  knot x 1 2"),
        Err(RecordReplyError::Malformed)
    );
    assert_eq!(reader.finish(), Err(RecordReplyError::Incomplete));
}

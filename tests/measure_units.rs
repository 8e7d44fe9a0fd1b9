//! The units declared for `measure`'s bare values (`set measure_unit`, `set heading_unit`) are
//! the ones the session reads them in, each unit: the stored measurement is the typed number
//! times the declared unit, never the reply's echo of the typed word.

#[path = "support/bench.rs"]
mod bench;

use bench::Bench;

/// The true end of the run: x = 12.3 mm, y = -4.5 mm, heading -1.5°.
const X_M: f64 = 0.0123;
const Y_M: f64 = -0.0045;
const THETA_DEG: f64 = -1.5;

/// A session with one finished square whose odometry ends at the true end.
fn one_run() -> Bench {
    let mut b = Bench::new();
    assert!(b.send("run cw").starts_with("ok run 1 started"));
    b.robot.finish(X_M, Y_M);
    assert!(b.poll().starts_with("event run 1 finished"));
    b
}

#[test]
fn every_declared_length_and_heading_unit_is_stored_as_declared() {
    let mut b = one_run();
    let lengths = [("mm", 1e-3), ("cm", 1e-2), ("m", 1.0)];
    let headings = [("deg", 1.0), ("rad", 180.0 / std::f64::consts::PI)];
    for (length, metres) in lengths {
        for (heading, degrees) in headings {
            let set = b.send(&format!("set measure_unit {length}"));
            assert!(
                set.starts_with(&format!("ok measure_unit = {length}:")),
                "{set}"
            );
            let set = b.send(&format!("set heading_unit {heading}"));
            assert!(
                set.starts_with(&format!("ok heading_unit = {heading}:")),
                "{set}"
            );
            // The true end written bare in the declared units.
            let (x, y, t) = (X_M / metres, Y_M / metres, THETA_DEG / degrees);
            let reply = b.send(&format!("measure #1 {x} {y} {t}"));
            assert!(
                reply.starts_with("ok run 1 "),
                "{length}/{heading}: {reply}"
            );
            let m = b.session.runs()[0].measured.expect("run 1 measured");
            // One multiplication by the unit on each side: 1e-15 m, 1e-12 rad.
            assert!(
                (m.x_m - X_M).abs() < 1e-15 && (m.y_m - Y_M).abs() < 1e-15,
                "{length}: typed {x} {y}, stored x={} y={} m, want {X_M} {Y_M}",
                m.x_m,
                m.y_m
            );
            let theta = m.theta_rad.expect("a heading was measured");
            assert!(
                (theta - THETA_DEG.to_radians()).abs() < 1e-12,
                "{heading}: typed {t}, stored {theta} rad, want {} rad",
                THETA_DEG.to_radians()
            );
        }
    }
}

#[test]
fn set_heading_unit_rad_reads_a_bare_heading_in_radians() {
    // The declaration alone, the way the mistake would show: -0.02618 typed after `set
    // heading_unit rad` is -1.5°, not -0.02618° (which would be 57 times smaller).
    let mut b = one_run();
    b.send("set measure_unit mm");
    assert_eq!(
        b.send("set heading_unit rad"),
        "ok heading_unit = rad: bare heading values are rad (this session only, not saved)\r\n"
    );
    let reply = b.send("measure 12.3 -4.5 -0.0261799");
    assert!(reply.contains("theta=-1.50 deg"), "{reply}");
    let theta = b.session.runs()[0].measured.unwrap().theta_rad.unwrap();
    // -0.0261799 rad as typed (7 significant digits): 1e-12 rad.
    assert!((theta + 0.0261799).abs() < 1e-12, "stored {theta} rad");
}

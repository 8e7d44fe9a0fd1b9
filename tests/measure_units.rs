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

/// `set` takes the unit suffixes `measure` takes for every length parameter, and a bare number
/// stays the parameter's listed unit (metres), where the range catches a factor of 1000. The
/// stored value is the typed number times its unit (one multiplication: within 1e-16 m).
#[test]
fn set_takes_units() {
    use odocal::protocol::{Command, ParamName, ParseError};
    fn set(line: &str) -> Result<Command<'_>, ParseError> {
        Command::parse(line)
    }
    for (typed, metres) in [
        ("151mm", 0.151),
        ("15.1cm", 0.151),
        ("0.151m", 0.151),
        ("0.151", 0.151),
        ("151 ", 151.0),
    ] {
        let line = format!("set d_right {typed}");
        let parsed = set(&line);
        if metres > 5.0 {
            assert!(
                matches!(parsed, Err(ParseError::OutOfRange { unit: "m", .. })),
                "`{typed}`: {parsed:?}"
            );
            continue;
        }
        let Ok(Command::Set { name, value }) = parsed else {
            panic!("`{typed}`: {parsed:?}");
        };
        assert_eq!(name, ParamName::DiameterRight);
        assert!((value - metres).abs() < 1e-16, "`{typed}`: {value}");
    }
    for name in ["d_left", "wheelbase", "square_side"] {
        let line = format!("set {name} 385mm");
        assert!(matches!(set(&line), Ok(Command::Set { .. })), "{name}");
    }
    // A length's unit only where the parameter is a length; an angle unit is not a length's.
    assert!(matches!(
        set("set d_right 151deg"),
        Err(ParseError::BadNumber { .. })
    ));
    assert!(matches!(
        set("set max_speed 0.3mm"),
        Err(ParseError::BadNumber { .. })
    ));
    // Through the session: the stored nominal diameter.
    let mut b = Bench::new();
    let reply = b.send("set d_right 151mm");
    assert!(reply.starts_with("ok d_right = 0.151"), "{reply}");
    let d = b.session.settings().nominal.diameter_right_m;
    assert!((d - 0.151).abs() < 1e-16, "{d}");
}

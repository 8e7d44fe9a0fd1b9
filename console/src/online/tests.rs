//! The windows and the estimate on a simulated robot: the true factors known, the reference
//! noisy, late and once relocalised.

use odocal::kinematics::geometry::Geometry;
use odocal::kinematics::reference::PoseF64;

use super::window::compose;
use super::{Online, OnlineArgs};

/// The online calibration as the bridge runs it, with these command-line options.
fn online(args: &[&str]) -> Online {
    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        online: OnlineArgs,
    }
    let cli = <Cli as clap::Parser>::parse_from(
        ["online", "--reference", "reference"].iter().chain(args),
    );
    Online::new(&cli.online, nominal(), nominal()).unwrap()
}

/// A small deterministic generator (xorshift64*) with normal draws (Box–Muller).
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

fn nominal() -> Geometry {
    Geometry {
        diameter_right_m: 0.1,
        diameter_left_m: 0.1,
        wheelbase_m: 0.3,
        counts_per_rev: 200_000,
    }
}

/// The mixed path: lines, arcs both ways, spins both ways; (v m/s, ω rad/s, seconds).
const PATH: [(f64, f64, f64); 8] = [
    (0.3, 0.0, 6.0),
    (0.0, 1.0, 6.0),
    (0.25, 0.5, 8.0),
    (0.0, -1.0, 6.0),
    (0.3, 0.0, 5.0),
    (0.25, -0.5, 8.0),
    (0.2, 0.3, 6.0),
    (0.0, 0.0, 2.0),
];

/// Drives the path for `seconds` of board time with true factors (`e_d`, `e_b`, changed to
/// `wear` at its time) and the nominal geometry on the board; a reference at 10 Hz with 20 mm
/// and 1° of noise in its covariance, 50 ms late, relocalised by 0.5 m once at `jump_s`, into
/// `o`.
fn drive(
    o: &mut Online,
    seconds: f64,
    truth: (f64, f64),
    wear: Option<(f64, f64, f64)>,
    jump_s: f64,
) {
    let board = nominal();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut true_g = board.with_factors(truth.0, truth.1, 1.0);
    let mut pose = PoseF64::new(1.0, 2.0, 0.3);
    let dt = 0.001;
    let mut pending: Vec<(f64, PoseF64)> = Vec::new();
    let steps = (seconds / dt).round() as usize;
    let (mut travel_r, mut travel_l) = (0.0, 0.0);
    let cycle: f64 = PATH.iter().map(|p| p.2).sum();
    for i in 1..=steps {
        let t = i as f64 * dt;
        if let Some((tw, ed, eb)) = wear
            && (t - tw).abs() < dt / 2.0
        {
            true_g = board.with_factors(ed, eb, 1.0);
        }
        let mut at = t % cycle;
        let (v, w) = PATH
            .iter()
            .find_map(|&(v, w, d)| {
                if at < d {
                    Some((v, w))
                } else {
                    at -= d;
                    None
                }
            })
            .unwrap_or((0.0, 0.0));
        // The commanded wheel speeds from the board's (nominal) geometry; the true motion from the
        // true one (the wheels turn as commanded, each tick is the true wheel's).
        let (wr, wl) = (
            v + w * board.wheelbase_m / 2.0,
            v - w * board.wheelbase_m / 2.0,
        );
        let ticks_r = wr * dt / board.meters_per_tick_right();
        let ticks_l = wl * dt / board.meters_per_tick_left();
        let (sr, sl) = (
            ticks_r * true_g.meters_per_tick_right(),
            ticks_l * true_g.meters_per_tick_left(),
        );
        let ds = 0.5 * (sr + sl);
        let dth = (sr - sl) / true_g.wheelbase_m;
        let mid = pose.theta_rad + dth / 2.0;
        pose = PoseF64::new(
            pose.x_m + ds * mid.cos(),
            pose.y_m + ds * mid.sin(),
            pose.theta_rad + dth,
        );
        travel_r += ticks_r;
        travel_l += ticks_l;
        if i % 10 == 0 {
            // A stream line at 100 Hz: the mean board speeds over its interval.
            let vr = travel_r * board.meters_per_tick_right() / 0.01;
            let vl = travel_l * board.meters_per_tick_left() / 0.01;
            travel_r = 0.0;
            travel_l = 0.0;
            let vr = (vr * 1e4).round() / 1e4;
            let vl = (vl * 1e4).round() / 1e4;
            o.stream(t, vr, vl);
        }
        if i % 100 == 0 {
            let shift = if t >= jump_s { 0.5 } else { 0.0 };
            pending.push((
                t,
                compose(
                    &PoseF64::new(shift, 0.0, 0.0),
                    &PoseF64::new(
                        pose.x_m + 0.02 * rng.normal(),
                        pose.y_m + 0.02 * rng.normal(),
                        pose.theta_rad + 1f64.to_radians() * rng.normal(),
                    ),
                ),
            ));
        }
        // 50 ms late.
        while pending.first().is_some_and(|r| t - r.0 >= 0.05 - 1e-9) {
            let (ts, p) = pending.remove(0);
            let (vxy, vth) = (0.02f64.powi(2), 1f64.to_radians().powi(2));
            o.reference(ts, p, Some((vxy, vxy, vth)));
        }
    }
}

/// Ten minutes of the mixed path with the reference of the bridge's test: the estimate is within
/// 3σ of the truth on both factors, its 1σ below 1e-3, and the relocalisation's window rejected.
#[test]
fn ten_minutes_find_the_true_factors() {
    let log = std::env::temp_dir().join(format!("odocal-online-unit-{}.jsonl", std::process::id()));
    let mut o = online(&["--horizon", "200", "--reference-log", log.to_str().unwrap()]);
    drive(&mut o, 600.0, (0.995, 1.010), None, 300.0);
    let e = &o.estimator;
    let est = e.estimate().expect("an estimate");
    eprintln!("{est:?} used {} rejected {}", e.used, e.rejected);
    assert_eq!(e.rejected, 1, "the relocalisation is one rejected window");
    assert!(est.sd_e_d < 1e-3 && est.sd_e_b < 1e-3, "{est:?}");
    assert!((est.e_d - 0.995).abs() < 3.0 * est.sd_e_d, "{est:?}");
    assert!((est.e_b - 1.010).abs() < 3.0 * est.sd_e_b, "{est:?}");
    // The offline twin fits the logged windows to the very same estimate.
    let replayed = super::log::replay(&log).unwrap();
    let _ = std::fs::remove_file(&log);
    assert_eq!(replayed.estimate, Some(est));
    assert_eq!(replayed.logged, Some(est));
    assert_eq!((replayed.used, replayed.rejected), (e.used, e.rejected));
}

/// A worn tyre at 5 minutes: one horizon later the estimate has followed it.
#[test]
fn the_estimate_follows_wear_within_the_horizon() {
    let mut o = online(&["--horizon", "60"]);
    drive(
        &mut o,
        600.0,
        (0.995, 1.010),
        Some((200.0, 0.990, 1.010)),
        1e9,
    );
    let e = &o.estimator;
    let est = e.estimate().expect("an estimate");
    eprintln!("{est:?} used {} rejected {}", e.used, e.rejected);
    assert!((est.e_d - 0.990).abs() < 3.0 * est.sd_e_d, "{est:?}");
}

/// `--apply`: never by default; `auto` only at rest, with a 1σ below `--max-sd`, and when the
/// board's calibration is more than `--min-change` σ from the estimate.
#[test]
fn apply_rules() {
    let mut o = online(&["--horizon", "200", "--apply", "auto", "--max-sd", "2e-3"]);
    drive(&mut o, 300.0, (0.995, 1.010), None, 1e9);
    let e = o.estimator.estimate().expect("an estimate");
    assert!(e.sd_e_d.max(e.sd_e_b) < 2e-3, "{e:?}");
    // Still moving: not applied.
    o.stream(300.01, 0.1, 0.1);
    assert_eq!(o.to_apply((1.0, 1.0)), None);
    // At rest for a second: applied, unless the board's calibration is the estimate.
    for i in 1..=101 {
        o.stream(300.01 + f64::from(i) * 0.01, 0.0, 0.0);
    }
    assert_eq!(o.to_apply((1.0, 1.0)), Some(e));
    assert_eq!(o.to_apply((e.e_d, e.e_b)), None);
    // A stricter --max-sd: not sure enough.
    o.args.max_sd = e.sd_e_d.max(e.sd_e_b) / 2.0;
    assert_eq!(o.to_apply((1.0, 1.0)), None);
    // --apply never: never.
    o.args.max_sd = 1.0;
    o.args.apply = super::ApplyMode::Never;
    assert_eq!(o.to_apply((1.0, 1.0)), None);
}

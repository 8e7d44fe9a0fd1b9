//! What a board boots with: the controller made from the stored settings (`ParamRecord::for_boot`,
//! `controller_config`, `Controller::new`, as `main.rs` and host-sim do) keeps in counts what
//! the stored geometry and limits ask for, not what the configuration's defaults held: the
//! encoder glitch limit is derived again at boot.

use odocal::motion::controller::{Controller, Fault};
use odocal::session::Settings;

/// Stored settings of a fast robot: 2,048-count encoders on 100 mm wheels, a 1 m wheelbase,
/// pivoting at 8 rad/s (4 m/s at the wheels, twice the defaults' 2 m/s).
fn fast_robot() -> Settings {
    let mut s = Settings::default();
    s.nominal.diameter_right_m = 0.1;
    s.nominal.diameter_left_m = 0.1;
    s.nominal.counts_per_rev = 2048;
    s.nominal.wheelbase_m = 1.0;
    s.active = s.nominal;
    s.calibration = None;
    s.motion.max_turn_rate_radps = 8.0;
    s
}

/// The controller a board boots with from `stored`.
fn boot(stored: &Settings) -> Controller {
    let (settings, refused) = stored.for_boot();
    assert!(refused.is_empty(), "{refused:?}");
    Controller::new(settings.controller_config()).expect("the stored settings boot")
}

#[test]
fn the_glitch_limit_is_derived_again_at_boot_from_the_stored_limits() {
    // 4 m/s / (π · 0.1 m) · 2,048 counts / 1 kHz = 26.1 counts a period, +50 % = 39.1: 40
    // counts a period (the defaults' 2 m/s floor would give 20).
    let c = boot(&fast_robot());
    let cfg = c.config();
    assert_eq!(cfg.rate_hz, 1000);
    assert_eq!(
        (cfg.right_encoder.max_step, cfg.left_encoder.max_step),
        (40, 40)
    );
    // The defaults boot with the floor: 2 m/s on 150 mm wheels of 200,000 counts at 1 kHz is
    // 849 counts a period, +50 % = 1,274 (the controller's own note: 1,273 at the floor).
    let d = boot(&Settings::default());
    let step = d.config().right_encoder.max_step;
    assert!((1_273..=1_274).contains(&step), "{step}");
}

#[test]
fn a_booted_fast_robot_counts_its_top_speed_and_faults_beyond_its_glitch_limit() {
    // The right counter counts up on a 32-bit timer, the left one down on a 16-bit timer (the
    // board's wiring). 39 counts a period on each wheel (3.8 m/s: within the 40-count limit,
    // beyond the defaults' 20) is counted; 41 on the right wheel is a glitch.
    let mut c = boot(&fast_robot());
    let (mut right, mut left) = (0u32, 0u32);
    c.step(right, left);
    for period in 0..20 {
        right = right.wrapping_add(39);
        left = (left + 65_536 - 39) % 65_536;
        c.step(right, left);
        assert_eq!(c.fault(), None, "period {period}: 39 counts");
    }
    right = right.wrapping_add(41);
    left = (left + 65_536 - 39) % 65_536;
    c.step(right, left);
    assert!(
        matches!(c.fault(), Some(Fault::EncoderGlitch { .. })),
        "{:?}",
        c.fault()
    );
}

//! Motor identification: each wheel's plant for the speed loop ([`MotorParams`]), measured on
//! the robot.
//!
//! Driven by the controller at the control rate, open loop (no speed loop), inside the robot's
//! limits. First a *probe*: a slow duty staircase ([`PROBE_START_DUTY`], +[`PROBE_STEP_DUTY`]
//! every [`PROBE_STAIR_MS`]) until every driven wheel has moved at two stairs and reached
//! [`PROBE_END_FRACTION`] of the speed cap (the operator's `max_speed`), then a brake to rest.
//! The last two stairs give a line `|v| = K (duty − d₀)` per wheel, and from it the three duty
//! steps that aim at [`LEVEL_FRACTIONS`] of the cap: a weak motor gets high duties, a strong
//! one low ones, a large dead-band is found instead of failing the first step. Per direction
//! (forward, then backward) a *pass* applies the three steps ([`LEVEL_MS`] each), then lets the
//! wheel coast ([`COAST_MS`]) and brakes it to rest ([`BRAKE_MS`]). With the wheels off the
//! ground ([`IdentifyMode::Lifted`]) each wheel has its own probe and passes, right first, and
//! the other wheel must stay still; on the floor ([`IdentifyMode::Floor`]) both wheels get the
//! same duty (the smaller of the two wheels' choices, so the faster one stays within the cap),
//! so the robot drives forward and back.
//!
//! **Supervision**, every period and block: a wheel faster than the cap + [`SPEED_MARGIN`] over a
//! block (or [`MAX_SPEED_MPS`] in one period), on the floor the robot's centre farther than
//! [`TRAVEL_LIMIT_M`] from its start, and at the end of each step a speed more than
//! [`RESPONSE_TOLERANCE`] away from what the probe's line predicts (the open loop's following
//! error: the load changed — a lifted wheel that touches the ground, a floor run on a wheel that
//! slips or is blocked) each stop the motors with a failure; the controller's stall and
//! encoder-glitch checks stay on. Where the robot is (lifted or on the floor) is the operator's
//! word: one wheel's response alone cannot tell a free wheel from one that pushes the robot,
//! except when it changes during the identification (the response check) or the other wheel
//! moves (lifted: [`IdentifyProblem::CrossWired`]). The tuning is applied only from a fit that
//! passes every check below.
//!
//! **Fit, online, decimated.** The encoder is read every period and its counts are summed over
//! blocks of [`BLOCK_MS`] (10 periods at 1 kHz); nothing is logged: the segment being driven
//! keeps exact integer sums of the pairs `(s_j, s_{j+1})` of successive block counts, and a
//! finished duty step only its means and centred moments, so the RAM is fixed (0.3 KiB for both
//! wheels) whatever the rate and length. For a
//! first-order motor with the duty held (zero-order hold), the block counts obey exactly
//! `s_{j+1} = a·s_j + (1 − a)·v_ss` within a step (blocks start with the step, so none mixes two
//! duties), with `a = e^{−T/τ}` for the block length `T` and `v_ss` the step's steady count per
//! block. Blocks rather than single periods: the encoder's quantisation makes successive counts
//! anti-correlated, which biases the slope by about `1/(12·var(s))`; at one period that is 20 %
//! of `1 − a` for a 120 ms motor, over 10-period blocks it is below 1e-4 of it. One common slope `a` is fitted to all six steps of a wheel (least
//! squares with one intercept per step), which gives `τ`, each step's `v_ss`, and the
//! residual. The steady speeds against the duty are then a straight line per direction,
//! `|v_ss| = K·(|duty| − d₀)`: its slope is the gain `K` of that direction, its zero crossing
//! the dead-band `d₀`. The coast is fitted the same way (`s_{k+1} = a_c·s_k + c`, a viscous and
//! a constant friction term) and reported as the deceleration from the top step's speed.
//!
//! **Fit, outside the control period.** The period in which the last segment ends only closes
//! it and returns [`IdentifyStep::Finished`]: the statistics stay where they are, frozen, and the
//! motors stop. The fit ([`Identify::fit`]: a few `log`, `sqrt` and divisions per wheel in `f64`,
//! about 52,000 instructions of soft-float on the Cortex-M4F, more than three 10 kHz periods) runs when the
//! report is taken ([`crate::motion::controller::Controller::take_check_report`]), in the task
//! that takes it, at a lower priority than the control task.
//!
//! **Plausibility.** The routine stops the motors and reports a [`IdentifyFailure`] (the
//! controller latches it as a fault) when a step shows no motion, counts against the duty (a
//! reversed motor or encoder: the bring-up check's finding), motion of the other wheel's
//! encoder instead (lifted: swapped wiring), a speed beyond the cap, a top step that
//! gains less than 70 % of the speed the lower steps predict (saturation: supply or current
//! limit), or a fit that does not describe the response (residual above 5 % of the top speed,
//! `a` outside (0, 1), parameters outside [`MotorParams::validate`]'s ranges).
//!
//! Parts: `plan` (the passes and segments, stepped each control period, with the per-period
//! plausibility checks), `stats` (the online sums and moments kept per wheel), `estimator` (the
//! fit of the frozen statistics) and `report` (what an identification ends with).
//!
//! [`MotorParams`]: crate::motion::speed::MotorParams
//! [`MotorParams::validate`]: crate::motion::speed::MotorParams::validate

mod estimator;
mod plan;
mod report;
mod stats;

pub use self::plan::{Identify, IdentifyStep};
pub use self::report::{IdentifyFailure, IdentifyProblem, IdentifyReport, MotorFit};

/// Fractions of the speed cap (the operator's `max_speed`) the three duty steps of a pass aim
/// for, in order. The probe's speeds lag the duty (they are read at the end of a stair of about
/// two time constants), so the steps reach a little more than aimed: the top one stays below
/// the cap.
pub const LEVEL_FRACTIONS: [f64; 3] = [0.25, 0.5, 0.75];
/// The probe's first duty.
pub const PROBE_START_DUTY: f32 = 0.04;
/// The probe's duty increment per stair (and the smallest spacing of the steps).
pub const PROBE_STEP_DUTY: f32 = 0.02;
/// Length of one probe stair, ms (two time constants of a 150 ms motor).
pub const PROBE_STAIR_MS: u32 = 300;
/// The probe ends when every driven wheel has reached this fraction of the cap (and moved at
/// the stair before).
pub const PROBE_END_FRACTION: f64 = 0.25;
/// Margin over the speed cap before the routine stops with [`IdentifyProblem::TooFast`].
pub const SPEED_MARGIN: f64 = 0.1;
/// Largest distance from the start on the floor, m (the reply asks for about 1 m free): a
/// bound, stopping distance included.
pub const TRAVEL_LIMIT_M: f64 = 1.0;
/// Time a wheel rolls on at most, at the speed it had, once its motor is stopped, s: the
/// slowest motor time constant the routine is sized for (150 ms, see [`PROBE_STAIR_MS`]); a
/// stopped first-order motor travels `v·τ` more. On the floor the routine stops when the
/// distance from the start plus this much would pass [`TRAVEL_LIMIT_M`].
pub const STOP_TIME_S: f64 = 0.15;
/// Distance from the start after which the floor probe ends at the next stair that moved (its
/// line then comes from lower speeds), m: a weak motor's probe would otherwise use the whole
/// travel budget before it reaches [`PROBE_END_FRACTION`] of the cap.
pub const PROBE_TRAVEL_M: f64 = 0.25;
/// Largest deviation of a step's speed from what the probe predicted, as a fraction: beyond it
/// the load changed (a wheel touched or left the ground, something blocks it).
pub const RESPONSE_TOLERANCE: f64 = 0.5;
/// Length of one duty step, ms (2.7 time constants of a 150 ms motor; the fit needs the
/// transient, not the steady state).
pub const LEVEL_MS: u32 = 400;
/// Coasting after the steps, ms.
pub const COAST_MS: u32 = 500;
/// Braking to rest before the next pass, ms.
pub const BRAKE_MS: u32 = 300;
/// Length of the blocks the counts are summed over for the fit, ms.
pub const BLOCK_MS: u32 = 10;
/// Fastest wheel speed the routine ever allows, m/s (the encoder glitch limit is 3 m/s); the
/// cap is the operator's `max_speed` below it.
pub const MAX_SPEED_MPS: f64 = 2.0;
/// Largest fit residual (RMS of the one-period prediction) against the top step's speed.
pub const MAX_RELATIVE_RESIDUAL: f64 = 0.05;
/// Smallest gain of the top step against the lower steps' slope (below: saturation).
pub const MIN_TOP_SLOPE_RATIO: f64 = 0.7;

/// Where the robot is during the identification (the operator's choice).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum IdentifyMode {
    /// Wheels off the ground: each wheel in turn, the other one must stay still.
    Lifted,
    /// On the floor: both wheels at once, the robot drives forward and back.
    Floor,
}

impl IdentifyMode {
    /// Passes (forward and backward per wheel, or per robot on the floor).
    pub fn passes(self) -> usize {
        match self {
            IdentifyMode::Lifted => 4,
            IdentifyMode::Floor => 2,
        }
    }

    /// Length of the steps, ms, without the probes (each probe adds one stair of
    /// [`PROBE_STAIR_MS`] per [`PROBE_STEP_DUTY`] of duty it needs, and a brake).
    pub fn duration_ms(self) -> u32 {
        self.passes() as u32 * (LEVEL_FRACTIONS.len() as u32 * LEVEL_MS + COAST_MS + BRAKE_MS)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motion::motor::StopMode;
    use crate::motion::wheel::Wheel;

    const M_PER_TICK: f64 = core::f64::consts::PI * 0.15 / 200_000.0;

    /// A lifted wheel pair with first-order motors `(K_fwd, K_back, τ, d0)` per wheel (m/s per
    /// duty), integrated exactly over each period (10 sub-steps are not needed: the duty is
    /// constant over a period), encoder floor-quantised; `sign` = −1 reverses a wheel's counts.
    /// The result: the fit of the finished identification, or the failure a period reported.
    fn run(
        mode: IdentifyMode,
        motors: [(f64, f64, f64, f64); 2],
        sign: [i64; 2],
    ) -> Result<IdentifyReport, IdentifyFailure> {
        run_capped(mode, motors, sign, 2.0).map(|(r, _, _)| r)
    }

    /// [`run`] with the speed cap `cap` (m/s); also returns the largest wheel speed (m/s, over
    /// 10 ms) and the largest distance of the robot's centre from the start (m).
    fn run_capped(
        mode: IdentifyMode,
        motors: [(f64, f64, f64, f64); 2],
        sign: [i64; 2],
        cap: f64,
    ) -> Result<(IdentifyReport, f64, f64), IdentifyFailure> {
        run_at(mode, motors, sign, cap, 1000)
    }

    /// [`run_capped`] at `rate` Hz.
    fn run_at(
        mode: IdentifyMode,
        motors: [(f64, f64, f64, f64); 2],
        sign: [i64; 2],
        cap: f64,
        rate: u32,
    ) -> Result<(IdentifyReport, f64, f64), IdentifyFailure> {
        let dt = 1.0 / f64::from(rate);
        let mut id = Identify::new(mode, rate, (M_PER_TICK, M_PER_TICK), cap);
        let mut v = [0.0f64; 2];
        let mut pos = [0.0f64; 2];
        let mut counted = [0i64; 2];
        let (mut dr, mut dl) = (0, 0);
        let (mut fastest, mut farthest) = (0.0f64, 0.0f64);
        let per_block = rate as usize / 100;
        let mut window = [[0.0f64; 100]; 2];
        for k in 0..40 * rate as usize {
            let step = id.step(dr, dl);
            let (duty, tau_scale) = match step {
                IdentifyStep::Duty(r, l) => ([f64::from(r), f64::from(l)], 1.0),
                IdentifyStep::Stop(StopMode::Coast) => ([0.0; 2], 4.0),
                IdentifyStep::Stop(StopMode::Brake) => ([0.0; 2], 0.5),
                IdentifyStep::Failed(f) => return Err(f),
                IdentifyStep::Finished => {
                    assert!(id.is_finished());
                    // Frozen: stepping again changes nothing.
                    let frozen = id;
                    assert_eq!(id.step(dr, dl), IdentifyStep::Finished);
                    assert_eq!(id, frozen);
                    return id.fit().map(|r| (r, fastest, farthest));
                }
            };
            let mut d = [0i64; 2];
            for w in 0..2 {
                let (kf, kb, tau, d0) = motors[w];
                let u = duty[w];
                let eff = if u.abs() > d0 {
                    u - d0.copysign(u)
                } else {
                    0.0
                };
                let target = eff * if eff >= 0.0 { kf } else { kb } / M_PER_TICK;
                let tau = tau * tau_scale;
                let e = (-dt / tau).exp();
                pos[w] += target * dt + (v[w] - target) * tau * (1.0 - e);
                v[w] = target + (v[w] - target) * e;
                let c = pos[w].floor() as i64;
                d[w] = (c - counted[w]) * sign[w];
                counted[w] = c;
            }
            (dr, dl) = (d[0], d[1]);
            for w in 0..2 {
                window[w][k % per_block] = v[w] * M_PER_TICK;
                let mean = window[w][..per_block].iter().sum::<f64>() / per_block as f64;
                fastest = fastest.max(mean.abs());
            }
            farthest = farthest.max((0.5 * (pos[0] + pos[1]) * M_PER_TICK).abs());
        }
        panic!("the identification did not end");
    }

    #[test]
    fn the_floor_identification_stays_within_max_speed_and_one_metre_for_weak_and_strong_motors() {
        // Default-like motors (1 m/s at full duty above a 5 % dead-band, τ 80 ms), half and
        // twice as strong; the operator's max_speed 0.3 m/s. The bound: the cap + 10 % (the
        // routine's own margin), and 1 m from the start (its travel bound); the fit must still
        // recover the motor within 5 %: the steps are lower than the fixed ones were, so the
        // encoder's quantisation weighs more.
        for gain in [0.5, 1.0, 2.0] {
            let m = (gain, gain, 0.08, 0.05);
            let (r, fastest, farthest) =
                run_capped(IdentifyMode::Floor, [m, m], [1, 1], 0.3).expect("a plausible fit");
            assert!(fastest <= 0.33, "gain {gain}: {fastest} m/s");
            assert!(farthest <= 1.0, "gain {gain}: {farthest} m");
            for fit in [r.right, r.left] {
                let p = fit.params;
                let close = |est: f32, truth: f64| (f64::from(est) - truth).abs() <= 0.05 * truth;
                assert!(close(p.gain_forward_mps, gain), "gain {gain}: {p:?}");
                assert!(close(p.time_constant_s, 0.08), "gain {gain}: {p:?}");
            }
        }
    }

    #[test]
    fn the_same_motors_at_10_khz() {
        let m = (0.5, 0.45, 0.025, 0.05);
        let (r, fastest, _) =
            run_at(IdentifyMode::Floor, [m, m], [1, 1], 0.3, 10_000).expect("a plausible fit");
        assert!(fastest <= 0.33, "{fastest} m/s");
        let p = r.right.params;
        assert!(
            (f64::from(p.gain_forward_mps) - 0.5).abs() < 0.01 * 0.5,
            "{p:?}"
        );
    }

    #[test]
    fn a_large_dead_band_is_found_by_the_probe() {
        // 30 % dead-band: the fixed steps of 20/35/50 % would have seen no motion at the first.
        let m = (1.0, 1.0, 0.06, 0.3);
        let (r, fastest, _) =
            run_capped(IdentifyMode::Floor, [m, m], [1, 1], 0.3).expect("a plausible fit");
        assert!(fastest <= 0.33, "{fastest} m/s");
        let p = r.right.params;
        assert!((f64::from(p.deadband) - 0.3).abs() < 0.01, "{p:?}");
        assert!((f64::from(p.gain_forward_mps) - 1.0).abs() < 0.05, "{p:?}");
    }

    #[test]
    fn lifted_identification_recovers_both_motors() {
        let motors = [(0.5, 0.45, 0.12, 0.05), (2.0, 2.1, 0.025, 0.08)];
        let (r, _, _) =
            run_capped(IdentifyMode::Lifted, motors, [1, 1], 0.4).expect("a plausible fit");
        for (fit, (kf, kb, tau, d0)) in [(r.right, motors[0]), (r.left, motors[1])] {
            let p = fit.params;
            // Exact plant, 1 kHz, only the encoder's quantisation (2.4 µm) as noise: every
            // parameter within 1 % (the bound is 5 %).
            let close = |est: f32, truth: f64| (f64::from(est) - truth).abs() <= 0.01 * truth;
            assert!(close(p.gain_forward_mps, kf), "{p:?}");
            assert!(close(p.gain_backward_mps, kb), "{p:?}");
            assert!(close(p.time_constant_s, tau), "{p:?}");
            assert!(close(p.deadband, d0), "{p:?}");
            // Coasting with τ_c = 4τ from the top speed v: v/τ_c (no constant friction here).
            let decel = f64::from(fit.coast_from_mps) / (4.0 * tau);
            assert!(
                (f64::from(fit.coast_decel_mps2) - decel).abs() < 0.02 * decel,
                "{fit:?}"
            );
        }
    }

    #[test]
    fn reversed_and_silent_wheels_fail() {
        let ok = (1.0, 1.0, 0.05, 0.0);
        let f = run(IdentifyMode::Floor, [ok, ok], [1, -1]);
        assert_eq!(
            f,
            Err(IdentifyFailure {
                wheel: Wheel::Left,
                problem: IdentifyProblem::Reversed
            })
        );
        // No motion at any duty: the probe climbs to full duty and gives up.
        let dead = (0.0, 0.0, 0.05, 0.0);
        let f = run(IdentifyMode::Lifted, [dead, ok], [1, 1]);
        assert_eq!(
            f,
            Err(IdentifyFailure {
                wheel: Wheel::Right,
                problem: IdentifyProblem::NoMotion
            })
        );
        // 40 m/s at full duty: the probe's first stairs (4 %, 6 %) already pass the cap of
        // 2 m/s + 10 %.
        let fast = (40.0, 40.0, 0.05, 0.0);
        let f = run(IdentifyMode::Lifted, [fast, ok], [1, 1]);
        assert!(
            matches!(
                f,
                Err(IdentifyFailure {
                    problem: IdentifyProblem::TooFast,
                    ..
                })
            ),
            "{f:?}"
        );
    }

    #[test]
    fn a_saturating_motor_is_refused() {
        // A line through the first two steps, then almost no gain: the supply limits.
        // 1 m/s per unit duty up to 19 % duty: the top step (aimed at 0.225 m/s, 22.5 %)
        // gains little.
        let mut id = Identify::new(IdentifyMode::Floor, 1000, (M_PER_TICK, M_PER_TICK), 0.3);
        let (mut dr, mut dl) = (0i64, 0i64);
        let mut v = 0.0f64;
        for _ in 0..40_000 {
            let duty = match id.step(dr, dl) {
                IdentifyStep::Duty(r, _) => f64::from(r),
                IdentifyStep::Stop(_) => 0.0,
                // Saturation is the fit's finding: every duty step moved the wheel.
                IdentifyStep::Finished => {
                    let f = id.fit();
                    assert!(
                        matches!(
                            f,
                            Err(IdentifyFailure {
                                problem: IdentifyProblem::Saturated,
                                ..
                            })
                        ),
                        "{f:?}"
                    );
                    return;
                }
                other => panic!("{other:?}"),
            };
            // Until the last segment ends the statistics are incomplete: no fit.
            assert_eq!(
                id.fit(),
                Err(IdentifyFailure {
                    wheel: Wheel::Right,
                    problem: IdentifyProblem::Implausible
                })
            );
            let capped = duty.clamp(-0.19, 0.19);
            let target = capped / M_PER_TICK;
            v = target + (v - target) * (-1e-3f64 / 0.05).exp();
            dr = (v * 1e-3).round() as i64;
            dl = dr;
        }
        panic!("the identification did not end");
    }
}

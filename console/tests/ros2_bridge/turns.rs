//! Step 3, turns: a counter-clockwise pivot and a clockwise arc, driven by Cyclone's `cmd_vel`.
//! Between two rests, the board's own `pose` says how far the robot turned (Δθ) and moved; the
//! bridge's messages must say the same:
//! - `odom`'s turn rate has the turn's sign, and summed over the samples' stamps it gives Δθ;
//! - the joints of `joint_states` (by their names) turned by what the wheels travelled:
//!   `r_R·Δq_R − r_L·Δq_L = b·Δθ` with the board's active radii and wheelbase, the right joint
//!   ahead in a CCW pivot and the left one in a CW arc, and on the arc their mean travel is the
//!   path from the start pose to the end pose (at least the chord between them).

use super::{Joints, Peer, Proc, World, number_after};

/// The board's active geometry (its `params` reply's `active` line): radii and wheelbase, m.
struct Active {
    r_right: f64,
    r_left: f64,
    wheelbase: f64,
}

fn active(bridge: &mut Proc) -> Active {
    bridge.send("params");
    let mut found = None;
    loop {
        let l = bridge.next();
        if let Some(a) = l.trim_start().strip_prefix("active ") {
            found = Some(Active {
                r_right: 0.5 * number_after(a, "d_right"),
                r_left: 0.5 * number_after(a, "d_left"),
                wheelbase: number_after(a, "wheelbase"),
            });
        } else if l == "ok" {
            return found.expect("an `active` line in the params reply");
        }
    }
}

/// The board's `pose`: x, y (m) and θ (rad).
fn board_pose(bridge: &mut Proc) -> (f64, f64, f64) {
    bridge.send("pose");
    let pose = bridge.until(|l| l.starts_with("ok x="));
    (
        number_after(&pose, "x"),
        number_after(&pose, "y"),
        number_after(&pose, "theta_deg").to_radians(),
    )
}

/// Waits for `n` odometry samples in a row with the same pose and zero speeds.
fn at_rest(peer: &mut Peer, n: usize) {
    let mut still = 0;
    let mut last = peer.odom();
    while still < n {
        let o = peer.odom();
        let same = (o.x, o.y, o.yaw) == (last.x, last.y, last.yaw) && o.v == 0.0 && o.w == 0.0;
        still = if same { still + 1 } else { 0 };
        last = o;
    }
}

/// The joints after 10 more joint samples (at rest: any of them), checked to be at rest.
fn joints_at_rest(peer: &mut Peer) -> Joints {
    let have = peer.joints.len();
    while peer.joints.len() < have + 10 {
        peer.next();
    }
    let j = *peer.joints.last().unwrap();
    assert_eq!((j.left_rate, j.right_rate), (0.0, 0.0), "{j:?}");
    j
}

/// An angle difference in (−π, π].
fn wrap(a: f64) -> f64 {
    let t = a.rem_euclid(std::f64::consts::TAU);
    if t > std::f64::consts::PI {
        t - std::f64::consts::TAU
    } else {
        t
    }
}

pub(super) fn a_ccw_pivot_and_a_cw_arc_match_the_boards_pose(w: &mut World) {
    let World { bridge, peer, .. } = w;
    let g = active(bridge);
    // (what, v m/s, ω rad/s, seconds of commands at 20 Hz): within the default limits
    // (0.3 m/s, 1 rad/s); the deadman adds 0.5 s after the last command.
    for (what, v, turn) in [("CCW pivot", 0.0, 0.8), ("CW arc", 0.15, -0.5)] {
        let p0 = board_pose(bridge);
        let j0 = joints_at_rest(peer);
        let first = peer.samples.len().max(1);
        peer.proc.send(&format!("cmd_vel {v} {turn} 1.5 20"));
        while peer.next()["k"] != "cmd_vel_done" {}
        at_rest(peer, 30);
        let p1 = board_pose(bridge);
        let j1 = joints_at_rest(peer);
        let d_theta = wrap(p1.2 - p0.2);

        // odom's turn rate: the turn's sign at its peak (the commanded rate within 5 %), and
        // its sum over the stamps (each sample's rate is the mean over the interval before it)
        // the board's Δθ: the 4 printed decimals of the wheel speeds and a stamp offset that
        // moves by under a millisecond keep it within 1 % + 5 mrad.
        let s = &peer.samples;
        let peak = s[first..]
            .iter()
            .map(|o| o.w)
            .max_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap();
        assert!(
            (peak - turn).abs() < 0.05 * turn.abs(),
            "{what}: odom's peak turn rate {peak} rad/s, commanded {turn}"
        );
        let summed: f64 = (first..s.len())
            .map(|i| s[i].w * (s[i].t - s[i - 1].t))
            .sum();
        println!(
            "{what}: board Δθ {d_theta:.5} rad, odom's turn rate summed {summed:.5} rad, peak \
             {peak:.4} rad/s"
        );
        assert!(
            d_theta * turn > 0.3 * turn * turn,
            "{what}: turned {d_theta} rad"
        );
        assert!(
            (summed - d_theta).abs() < 0.01 * d_theta.abs() + 0.005,
            "{what}: odom's turn rate sums to {summed} rad, the board turned {d_theta} rad"
        );

        // The joints: each wheel's travel is its joint's turn times its radius. The speeds'
        // 4 decimals: 0.5 µm a wheel a line, under 0.2 mm a wheel over these 3 s: 1 mrad on
        // the wheelbase; bound 3 mrad.
        let travel_r = g.r_right * (j1.right - j0.right);
        let travel_l = g.r_left * (j1.left - j0.left);
        let joint_theta = (travel_r - travel_l) / g.wheelbase;
        println!(
            "{what}: joints turned right {:.4} left {:.4} rad: wheels {travel_r:.5} {travel_l:.5} \
             m, Δθ {joint_theta:.5} rad",
            j1.right - j0.right,
            j1.left - j0.left
        );
        assert!(
            (joint_theta - d_theta).abs() < 0.003,
            "{what}: the joints say Δθ = {joint_theta} rad, the board's pose {d_theta} rad"
        );
        let chord = (p1.0 - p0.0).hypot(p1.1 - p0.1);
        let mean = 0.5 * (travel_r + travel_l);
        if v == 0.0 {
            // A pivot: the right wheel forward, the left back, the robot where it was (the
            // speed loops' small mismatch: under 5 mm).
            assert!(
                travel_r > 0.0 && travel_l < 0.0,
                "{what}: {travel_r} {travel_l}"
            );
            assert!(
                mean.abs() < 0.005 && chord < 0.005,
                "{what}: {mean} {chord}"
            );
        } else {
            // A CW arc: both wheels forward, the left one further; the path at least the chord
            // and at most the constant-curvature arc through the same turn, +10 % for the ramps.
            assert!(
                travel_l > travel_r && travel_r > 0.0,
                "{what}: {travel_r} {travel_l}"
            );
            let arc = chord * (0.5 * d_theta) / (0.5 * d_theta).sin();
            assert!(
                mean > chord - 0.001 && mean < 1.1 * arc,
                "{what}: the wheels' mean travel {mean} m, chord {chord} m, arc {arc} m"
            );
        }
    }
}

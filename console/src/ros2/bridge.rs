//! The bridge at work: the board's lines in (odometry out, events printed, a board reset
//! followed), `cmd_vel` and typed commands out (through [`Guard`]'s rules), `/diagnostics` once
//! a second, and the board's port reopened when it comes back after a disconnect.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use odocal::protocol::Command;
use odocal::protocol::token::EventTag;

use super::guard::{self, Guard};
use super::msgs::tf2_msgs::TFMessage;
use super::odometry::Wheels;
use super::odometry::{Odometer, StreamLine};
use super::reference::Reference;
use super::status::{self, Stats};
use super::{Aging, Board, CmdVel, DEADMAN_S, Network, Options, drive_line, now_s, session_log};
use crate::link::{Link, LinkError};
use crate::online::{ApplyMode, Online, estimator::Estimate};

/// How long the bridge waits for the board's reply to `drive`, `stop`, `status`: the board
/// answers within milliseconds; a board that reset under a command never does, and the bridge
/// must be back at its lines to see the boot event.
const COMMAND_WAIT: Duration = Duration::from_millis(300);

/// The bridge's state between the board's lines.
pub(super) struct Bridge<'a> {
    pub opts: &'a Options,
    pub net: &'a Network,
    pub board: Board,
    pub link: Link,
    /// `stream on` at the bridge's rate.
    pub stream_on: Command<'static>,
    pub odometer: Odometer,
    pub stats: Stats,
    pub guard: Guard,
    /// The last stream line published.
    pub prev: Option<StreamLine>,
    /// The stream line current when the latest command was sent, while commands come.
    pub commanding: Option<StreamLine>,
    pub last_drive_reply: String,
    /// The pose `odom` went on from at the last board reset.
    pub carried: Option<(f64, f64, f64)>,
    pub next_status: Instant,
    /// The online calibration and its reference topic (`--reference`).
    pub online: Option<(Online, Reference)>,
    /// A calibration of today: when its covariance widens to the between-session drift.
    pub aging: Option<Aging>,
}

impl Bridge<'_> {
    /// Runs until Ctrl-C (or a lost port with `--exit-on-disconnect`); then stops the robot,
    /// turns the stream off and prints the summary.
    ///
    /// # Errors
    /// A lost port with `--exit-on-disconnect`, or one that cannot be reopened.
    pub fn run(mut self, typed: &mpsc::Receiver<String>) -> Result<(), LinkError> {
        let result = loop {
            match self.serve(typed) {
                Err(LinkError::Disconnected(why)) if !self.opts.exit_on_disconnect => {
                    eprintln!(
                        "ros2: board disconnected: {} ({why}): no odometry; waiting for the port \
                         to come back",
                        self.opts.port
                    );
                    self.guard.disconnected();
                    self.commanding = None;
                    match reconnect(self.opts, self.net, self.stream_on) {
                        Ok(Some(l)) => {
                            eprintln!("ros2: {} is back: the stream is on again", self.opts.port);
                            self.link = l;
                        }
                        Ok(None) => break Ok(()),
                        Err(e) => break Err(LinkError::Disconnected(e)),
                    }
                }
                other => break other,
            }
        };
        // The board's own deadman stops a robot the bridge no longer commands; Ctrl-C stops it
        // now.
        let _ = self.link.stop_key();
        let _ = self
            .link
            .send_line(&Command::Stream { on: None }.to_string());
        for (k, v) in self.stats.summary(self.odometer.clock()) {
            println!("ros2: {k} {v}");
        }
        result
    }

    /// The bridge's loop on one open port, until Ctrl-C (`Ok`) or a link error.
    fn serve(&mut self, typed: &mpsc::Receiver<String>) -> Result<(), LinkError> {
        loop {
            if crate::interrupted() {
                return Ok(());
            }
            // The board's lines, as they come (a stream line every period).
            if let Some(line) = self.link.next_unsolicited(Duration::from_millis(5))? {
                self.board_line(&line);
                continue;
            }
            self.restart_if_stale()?;
            self.forward_cmd_vel()?;
            self.take_reference();
            // Commands typed on stdin.
            while let Ok(cmd) = typed.try_recv() {
                if self.answer_offer(cmd.trim())? {
                    continue;
                }
                match self.link.command(cmd.trim(), Duration::from_secs(10)) {
                    Ok(r) => {
                        for d in &r.data {
                            println!("  {d}");
                        }
                        println!("{}", r.last);
                        // The board's pose is at the origin again: so is `odom`, and its
                        // covariance restarts with it.
                        if r.ok() && matches!(Command::parse(cmd.trim()), Ok(Command::OdomReset)) {
                            self.odometer.odom_reset();
                        }
                    }
                    Err(LinkError::Timeout(c)) => println!("no reply to `{c}`"),
                    Err(e) => return Err(e),
                }
            }
            if Instant::now() >= self.next_status {
                self.next_status += Duration::from_secs(1);
                self.age_calibration();
                self.publish_status()?;
                self.apply_online()?;
            }
        }
    }

    /// Once the calibration's runs are a day old, the pose covariance takes the between-session
    /// drift (said on stderr once).
    fn age_calibration(&mut self) {
        if self.aging.as_ref().is_some_and(|a| now_s() >= a.at_s)
            && let Some(a) = self.aging.take()
        {
            self.odometer.set_uncertainty(a.u);
            eprintln!(
                "ros2: the calibration's runs are a day old: the pose covariance now takes {}",
                a.source
            );
        }
    }

    /// A line from the board: a stream line's odometry published, an event printed (a boot
    /// event followed: see [`Guard`] and [`Odometer::board_reset`]).
    fn board_line(&mut self, line: &str) {
        let arrived = now_s();
        let Some(m) = self.odometer.messages(line, arrived) else {
            // Events (a run finished, a fault, the button) for the operator.
            println!("{line}");
            if matches!(EventTag::parse(line), Some((EventTag::Boot, _))) {
                self.guard.board_reset();
                self.stats.board_reset();
                let (x, y, th) = self.odometer.board_reset();
                self.carried = Some((x, y, th));
                self.commanding = None;
                // `/diagnostics` says it now, not at the next second.
                self.next_status = Instant::now();
                eprintln!(
                    "ros2: the board was reset: no cmd_vel is forwarded until its odometry flows \
                     again; odom goes on from x={x:.6} y={y:.6} theta={th:.6}"
                );
            }
            return;
        };
        self.guard.line(arrived);
        let s = m.line;
        self.prev = Some(s);
        if let Some(c) = self.commanding
            && s.t_s - c.t_s >= DEADMAN_S
        {
            self.commanding = None;
            println!(
                "ros2: cmd_vel: none since board t={:.6} at x={:.6} y={:.6} (the board's \
                 deadman stops the robot {DEADMAN_S} s after it)",
                c.t_s, c.x_m, c.y_m
            );
        }
        let net = self.net;
        let _ = net.odom.publish(m.odom);
        if let Some(tf) = &net.tf {
            let _ = tf.publish(TFMessage {
                transforms: vec![m.tf],
            });
        }
        let _ = net.joints.publish(m.joints);
        if let Some((o, _)) = &mut self.online {
            o.stream(s.t_s, s.v_right, s.v_left);
        }
        let done = now_s();
        self.stats.line(s.t_s, arrived);
        self.stats.handling.push(done - arrived);
        self.stats.latency.push(done - m.stamp_s);
    }

    /// The stream again after a reset or a gap (the board's echo off first: a reset turns it
    /// on).
    fn restart_if_stale(&mut self) -> Result<(), LinkError> {
        if !self.guard.restart_stream(now_s()) {
            return Ok(());
        }
        eprintln!(
            "ros2: no odometry ({}): turning the board's stream on again",
            self.guard.stale().map_or("", guard::Stale::as_str)
        );
        // A short wait: a board that does not answer (no power) must not hold `/diagnostics`;
        // the next attempt comes a second later.
        for c in [Command::Echo { on: false }, self.stream_on] {
            match self.link.command(&c.to_string(), COMMAND_WAIT) {
                Ok(_) | Err(LinkError::Timeout(_)) => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// The latest `cmd_vel` from the network, once, by [`Guard`]'s rules.
    fn forward_cmd_vel(&mut self) -> Result<(), LinkError> {
        let Some(t) = self.net.cmd_vel.as_ref().and_then(CmdVel::latest) else {
            return Ok(());
        };
        let (v, w) = match self.guard.cmd_vel(t.linear.x, t.angular.z) {
            guard::Verdict::Forward(v, w) => (v, w),
            guard::Verdict::Refuse { say, stop } => {
                if let Some(say) = say {
                    eprintln!("{say}");
                }
                if stop {
                    match self
                        .link
                        .command(&Command::Stop.to_string(), Duration::from_secs(2))
                    {
                        Ok(_) | Err(LinkError::Timeout(_)) => {}
                        Err(e) => return Err(e),
                    }
                }
                return Ok(());
            }
        };
        let cmd = drive_line(v, w);
        // No reply: the board may have reset under the command (its boot event follows). The
        // board answers `drive` at once: a short wait keeps a reset from holding the odometry.
        let r = match self.link.command(&cmd, COMMAND_WAIT) {
            Ok(r) => r,
            Err(LinkError::Timeout(c)) => {
                eprintln!("ros2: cmd_vel: no reply to `{c}`");
                return Ok(());
            }
            Err(e) => return Err(e),
        };
        self.stats.commands += 1;
        // Driving only once the board accepted the command.
        if let Some(p) = self.prev.filter(|_| r.ok()) {
            if self.commanding.is_none() {
                println!(
                    "ros2: cmd_vel: driving from board t={:.6} at x={:.6} y={:.6}",
                    p.t_s, p.x_m, p.y_m
                );
            }
            self.commanding = Some(p);
        }
        if r.last != self.last_drive_reply && !(r.ok() && r.text().is_empty()) {
            eprintln!("ros2: cmd_vel: `{cmd}`: {}", r.last);
        }
        self.last_drive_reply = r.last;
        Ok(())
    }

    /// The board's state and faults and the bridge's own figures on `/diagnostics`.
    fn publish_status(&mut self) -> Result<(), LinkError> {
        // No reply: the board may have reset under it, or it has no power: said, and the next
        // second asks again.
        let reply = match self
            .link
            .command(&Command::Status.to_string(), COMMAND_WAIT)
        {
            Ok(r) => Some(r),
            Err(LinkError::Timeout(_)) => None,
            Err(e) => return Err(e),
        };
        let mut array = status::diagnostics(
            reply.as_ref().map(|r| r.text()),
            &status::Context {
                node_name: &self.opts.node_name,
                port: &self.opts.port,
                calibration: &self.board.calibration,
                last_drive_reply: &self.last_drive_reply,
                odometer: &self.odometer,
                stats: &self.stats,
                guard: &self.guard,
                carried: self.carried,
            },
            now_s(),
        );
        if let Some((o, r)) = &self.online {
            let applied = self.applied_factors();
            array
                .status
                .push(status::online(&self.opts.node_name, o, r, applied));
        }
        let _ = self.net.diag.publish(array);
        Ok(())
    }

    /// The board's calibration factors `(E_d, E_b, E_s)` against its nominal geometry.
    fn applied_factors(&self) -> (f64, f64, f64) {
        odocal::calibration::factors_of(&self.board.active(), &self.board.nominal)
    }

    /// The reference's new samples into the online calibration, their stamps on the board's
    /// clock (the topic subscribed once it is known).
    fn take_reference(&mut self) {
        let Some((o, r)) = &mut self.online else {
            return;
        };
        if r.kind().is_none()
            && Instant::now() >= self.next_status
            && let Err(e) = r.resolve()
        {
            eprintln!("online: {e}");
        }
        let clock = self.odometer.clock();
        for (stamp, pose, var) in r.take() {
            if let Some(board_s) = clock.board_time_of(stamp) {
                o.reference(board_s, pose, var);
            }
        }
    }

    /// `yes` or `no` typed to an estimate offered with `--apply ask`; `true` when it was one.
    fn answer_offer(&mut self, typed: &str) -> Result<bool, LinkError> {
        let Some((o, _)) = &mut self.online else {
            return Ok(false);
        };
        let Some(e) = o.offered else {
            return Ok(false);
        };
        if typed.eq_ignore_ascii_case("yes") {
            o.offered = None;
            self.apply(&e)?;
            Ok(true)
        } else if typed.eq_ignore_ascii_case("no") {
            o.offered = None;
            println!("online: not applied; asked again when the estimate changes by --min-change");
            Ok(true)
        } else {
            Ok(false)
        }
    }

    /// `--apply ask|auto`: offers or applies the estimate when its rules allow.
    fn apply_online(&mut self) -> Result<(), LinkError> {
        let (e_d, e_b, _) = self.applied_factors();
        // At rest: no command coming (the board's `drive` mode ends with its deadman).
        if self.commanding.is_some() {
            return Ok(());
        }
        let Some((o, _)) = &mut self.online else {
            return Ok(());
        };
        let Some(e) = o.to_apply((e_d, e_b)) else {
            return Ok(());
        };
        match o.args.apply {
            ApplyMode::Never => Ok(()),
            ApplyMode::Ask => {
                if o.offered
                    .is_none_or(|old| old.distance_sigma(e.e_d, e.e_b) > o.args.min_change)
                {
                    o.offered = Some(e);
                    println!(
                        "online: the board's calibration (E_d={e_d:.6} E_b={e_b:.6}) is {:.1} sigma \
                         from {}: type `yes` to apply and save it, `no` to keep it",
                        e.distance_sigma(e_d, e_b),
                        crate::online::log::describe(&e)
                    );
                }
                Ok(())
            }
            ApplyMode::Auto => self.apply(&e),
        }
    }

    /// Applies and saves `e` through the board's commands (`apply online …`, `save`); the board's
    /// pose goes on from where it is, and so does `odom`.
    fn apply(&mut self, e: &Estimate) -> Result<(), LinkError> {
        let apply = Command::ApplyFactors {
            e_d: e.e_d as f32,
            e_b: e.e_b as f32,
            e_s: e.e_s as f32,
        };
        for c in [apply, Command::Save] {
            let line = c.to_string();
            let r = self.link.command(&line, Duration::from_secs(5))?;
            if !r.ok() {
                eprintln!("online: the board refused `{line}`: {}", r.last);
                return Ok(());
            }
        }
        match super::read_board(&mut self.link) {
            Ok(b) => self.board = b,
            Err(why) => {
                eprintln!("online: applied, but the board's `params` cannot be read: {why}");
                return Ok(());
            }
        }
        let active = self.board.active();
        self.odometer.set_wheels(Wheels {
            d_right: active.diameter_right_m,
            d_left: active.diameter_left_m,
            wheelbase: active.wheelbase_m,
        });
        if let Some((o, _)) = &mut self.online {
            o.applied(e, active);
        }
        println!(
            "online: applied and saved {} (method online)",
            crate::online::log::describe(e)
        );
        Ok(())
    }
}

/// Waits for the board's port to come back at the same path (a `/dev/serial/by-id/` path
/// survives the adapter's re-enumeration) and reopens it with the echo off and the stream on;
/// meanwhile `/diagnostics` says ERROR, `board disconnected: PORT`, once a second, and no
/// odometry is published. `None` on Ctrl-C.
fn reconnect(
    opts: &Options,
    net: &Network,
    stream_on: Command<'_>,
) -> Result<Option<Link>, String> {
    let mut next_diag = Instant::now();
    loop {
        if crate::interrupted() {
            return Ok(None);
        }
        if Instant::now() >= next_diag {
            next_diag += Duration::from_secs(1);
            let _ = net
                .diag
                .publish(status::disconnected(&opts.node_name, &opts.port, now_s()));
        }
        if std::path::Path::new(&opts.port).exists()
            && let Ok(mut link) = Link::open(&opts.port, session_log(opts)?)
            && link.handshake().is_ok()
            && link
                .command(&stream_on.to_string(), Duration::from_secs(5))
                .is_ok_and(|r| r.ok())
        {
            return Ok(Some(link));
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

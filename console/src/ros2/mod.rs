//! `cargo console ros2 --port PORT`: the board on a robot's ROS 2 network.
//!
//! A ROS 2 node in pure Rust (`ros2-client` over RustDDS: no ROS installation, the standard DDS
//! topic and type names and CDR, so any ROS 2 node on any DDS vendor talks to it). It turns the
//! board's pose stream into `nav_msgs/Odometry` on `odom`, the `odom → base_link` transform on
//! `/tf`, the wheels on `joint_states` and the board's state and faults on `/diagnostics`, and
//! forwards `cmd_vel` to the board's `drive` command, whose own 500 ms deadman stops the robot
//! when commands stop (nothing here repeats a command). Lines typed on the bridge's stdin go to
//! the board as commands (`line 1`, `pose`, `stop`), their replies to stdout.
//!
//! The stream line is the board's existing one (`stream t x y θ v_R v_L`, up to 100 Hz): the
//! wheels' joint positions are the sums of the mean wheel speeds times the line intervals
//! (exact up to the speeds' 4 printed decimals, 0.5 µm a line at 100 Hz).

mod bridge;
pub mod clock;
mod guard;
pub mod msgs;
pub mod odometry;
mod reference;
mod status;

use std::io::BufRead;
use std::path::PathBuf;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use odocal::kinematics::geometry::Geometry;
use odocal::motion::controller::DEFAULT_DEADMAN_MS;
use odocal::protocol::Command;
use odocal::protocol::command::{DRIVE_LIMIT_MPS, DRIVE_LIMIT_RADPS, STREAM_RANGE_HZ};
use ros2_client::dds::rustdds::DomainParticipantBuilder;
use ros2_client::qos::{Durability, History, QosProfile, Reliability, WhenFull};
use ros2_client::{
    Context, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher, Subscription,
};

use crate::covariance::{self, Floor, PoseCovariance, RandomError, Uncertainty};
use crate::export::Export;
use crate::link::Link;
use crate::log::{SessionLog, calibration_of, nominal_of, now_s, param};
use bridge::Bridge;
use clock::ClockMap;
use guard::Guard;
use msgs::diagnostic_msgs::{self, DiagnosticArray};
use msgs::geometry_msgs::{self, Twist, TwistStamped};
use msgs::nav_msgs::{self, Odometry};
use msgs::sensor_msgs::{self, JointState};
use msgs::tf2_msgs::{self, TFMessage};
use msgs::{Covariance, TypeName};
use odometry::{Names, Odometer, Wheels};
use status::Stats;

/// The board's deadman: it stops the motors when no `drive` came for this long
/// (docs/protocol.md).
const DEADMAN_S: f64 = DEFAULT_DEADMAN_MS as f64 / 1000.0;

/// Options of `ros2`.
#[derive(clap::Args, Debug, Clone)]
pub struct Options {
    /// Serial port of the board (its USB-UART, or the pty `cargo sim serial --pty` prints).
    #[arg(long)]
    pub port: String,
    /// Pose stream rate, Hz (the board's `stream on`, 1..100): odometry, tf and joint states
    /// are published at this rate.
    #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u32)
        .range(i64::from(STREAM_RANGE_HZ.0)..=i64::from(STREAM_RANGE_HZ.1)))]
    pub rate_hz: u32,
    /// Frame of the odometry (Odometry.header.frame_id, the transform's parent).
    #[arg(long, default_value = "odom")]
    pub odom_frame: String,
    /// Frame of the robot (Odometry.child_frame_id, the transform's child).
    #[arg(long, default_value = "base_link")]
    pub base_frame: String,
    /// Name of the left wheel's joint in `joint_states`.
    #[arg(long, default_value = "left_wheel_joint")]
    pub left_joint: String,
    /// Name of the right wheel's joint in `joint_states`.
    #[arg(long, default_value = "right_wheel_joint")]
    pub right_joint: String,
    /// The node's name.
    #[arg(long, default_value = "odocal_bridge")]
    pub node_name: String,
    /// Subscribe `cmd_vel` as `geometry_msgs/TwistStamped` (Jazzy's diff_drive_controller
    /// default) instead of `geometry_msgs/Twist`.
    #[arg(long)]
    pub stamped: bool,
    /// Odometry out only: no `cmd_vel` subscription, nothing on the network can drive the robot.
    #[arg(long)]
    pub read_only: bool,
    /// Do not publish `/tf` (when another node, e.g. an EKF, publishes odom → base_link).
    #[arg(long)]
    pub no_tf: bool,
    /// Session log of the calibration the board holds: the 1σ of E_d and E_b in the pose
    /// covariance come from it (without it: stated defaults, see docs/operator.md).
    #[arg(long)]
    pub calibration: Option<PathBuf>,
    /// Random travel error of each wheel after one metre (1σ, m) in the pose covariance
    /// (default: the scatter of the `--calibration` log's runs, or 2 mm without one).
    #[arg(long)]
    pub slip: Option<f64>,
    /// Keep the `--calibration` log's own 1σ of E_d and E_b in the pose covariance, even below
    /// the drift measured between sessions of one robot (docs/calibration.md).
    #[arg(long)]
    pub trust_session_sd: bool,
    /// Log every line to and from the board to this file (JSON lines, as the guided session).
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Put every topic (and the node) under this namespace, as multi-robot setups do:
    /// `--namespace robot1` publishes `/robot1/odom`, `/robot1/tf`, `/robot1/joint_states`,
    /// `/robot1/diagnostics` and takes `/robot1/cmd_vel`.
    #[arg(long)]
    pub namespace: Option<String>,
    /// Prefix the frames (`robot1/` gives `robot1/odom` → `robot1/base_link`).
    #[arg(long, default_value = "")]
    pub frame_prefix: String,
    /// End (exit status 1) when the board's port goes away, for a launch file that respawns
    /// the bridge; without it the bridge waits for the same port path to come back.
    #[arg(long)]
    pub exit_on_disconnect: bool,
    /// Stamp every message with the board's own time (seconds since its boot) in place of the
    /// PC's clock: the ROS time of a simulation (`use_sim_time`), for a simulated board that
    /// runs faster than real time (`cargo sim serial --speed`); the reference's stamps are then
    /// read on the same clock.
    #[arg(long)]
    pub use_sim_time: bool,
    /// The online calibration (`--reference TOPIC`).
    #[command(flatten)]
    pub online: crate::online::OnlineArgs,
}

/// Which peers discovery reaches: `ROS_AUTOMATIC_DISCOVERY_RANGE` (Jazzy) or, without it,
/// `ROS_LOCALHOST_ONLY=1` (Humble).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Range {
    /// Every interface (the ROS 2 default).
    Subnet,
    /// This machine only.
    Localhost,
    /// No discovery at all.
    Off,
}

/// The discovery range and domain the environment asks for.
///
/// # Errors
/// A value ROS 2 does not define, as text.
pub fn ros_environment(get: impl Fn(&str) -> Option<String>) -> Result<(u16, Range), String> {
    let domain = match get("ROS_DOMAIN_ID").filter(|v| !v.trim().is_empty()) {
        None => 0,
        Some(v) => v
            .trim()
            .parse::<u16>()
            .ok()
            .filter(|d| *d <= 232)
            .ok_or_else(|| format!("ROS_DOMAIN_ID={v}: a number 0..232 (ROS 2 uses 0..101)"))?,
    };
    let range = match get("ROS_AUTOMATIC_DISCOVERY_RANGE")
        .filter(|v| !v.trim().is_empty())
        .map(|v| v.trim().to_ascii_uppercase())
    {
        Some(v) => match v.as_str() {
            "SUBNET" | "SYSTEM_DEFAULT" => Range::Subnet,
            "LOCALHOST" => Range::Localhost,
            "OFF" => Range::Off,
            other => {
                return Err(format!(
                    "ROS_AUTOMATIC_DISCOVERY_RANGE={other}: one of SUBNET, LOCALHOST, OFF, \
                     SYSTEM_DEFAULT"
                ));
            }
        },
        None if get("ROS_LOCALHOST_ONLY").is_some_and(|v| v.trim() == "1") => Range::Localhost,
        None => Range::Subnet,
    };
    Ok((domain, range))
}

/// ROS 2's default QoS (`rmw_qos_profile_default`): reliable, volatile, keep last `depth`.
pub(super) fn default_qos(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability(Reliability::Reliable {
            when_full: WhenFull::DEFAULT,
        })
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// The node's namespace: `/` or `/NS` (`--namespace NS`, leading and trailing slashes
/// dropped).
fn namespace(ns: Option<&str>) -> String {
    match ns.map(|n| n.trim_matches('/')).filter(|n| !n.is_empty()) {
        Some(n) => format!("/{n}"),
        None => "/".to_string(),
    }
}

/// A topic in the node's namespace `ns` (`namespace`): `odom` and `/odom` are one topic, `/odom`
/// (`rt/odom` in DDS) at the root, `/robot1/odom` (`rt/robot1/odom`) under `--namespace robot1`.
pub(super) fn topic_name(ns: &str, name: &str) -> Result<Name, String> {
    let base = name.trim_start_matches('/');
    Name::new(ns, base).map_err(|e| format!("topic `{name}` in `{ns}`: {e:?}"))
}

fn publisher<M: serde::Serialize>(
    node: &mut Node,
    ns: &str,
    name: &str,
    ty: TypeName,
    qos: &QosProfile,
) -> Result<Publisher<M>, String> {
    let topic = node
        .create_topic(
            &topic_name(ns, name)?,
            MessageTypeName::new(ty.0, ty.1),
            qos,
        )
        .map_err(|e| format!("topic {name}: {e:?}"))?;
    node.create_publisher::<M>(&topic, Some(qos.clone()))
        .map_err(|e| format!("publisher {name}: {e:?}"))
}

/// The subscription to `cmd_vel` in either message type.
enum CmdVel {
    Plain(Subscription<Twist>),
    Stamped(Subscription<TwistStamped>),
}

impl CmdVel {
    /// The latest command received since the last call, if any.
    fn latest(&self) -> Option<Twist> {
        let mut last = None;
        loop {
            let next = match self {
                CmdVel::Plain(s) => s.take().ok().flatten().map(|(t, _)| t),
                CmdVel::Stamped(s) => s.take().ok().flatten().map(|(t, _)| t.twist),
            };
            match next {
                Some(t) => last = Some(t),
                None => return last,
            }
        }
    }
}

/// The board's geometry and limits from its `params` reply.
struct Board {
    nominal: Geometry,
    d_right: f64,
    d_left: f64,
    wheelbase: f64,
    counts_per_rev: u32,
    max_accel: f64,
    calibration: String,
}

impl Board {
    /// The geometry the board drives with.
    fn active(&self) -> Geometry {
        Geometry {
            diameter_right_m: self.d_right,
            diameter_left_m: self.d_left,
            wheelbase_m: self.wheelbase,
            counts_per_rev: self.counts_per_rev,
        }
    }
}

fn read_board(link: &mut Link) -> Result<Board, String> {
    let reply = link
        .command(&Command::Params.to_string(), Duration::from_secs(5))
        .map_err(|e| e.to_string())?;
    let nominal = nominal_of(&reply.data).ok_or("the board's `params` reply has no geometry")?;
    let active = crate::export::active_of(&reply.data, nominal.counts_per_rev)
        .ok_or("the board's `params` reply has no `active` line: update its firmware")?;
    Ok(Board {
        nominal,
        d_right: active.diameter_right_m,
        d_left: active.diameter_left_m,
        wheelbase: active.wheelbase_m,
        counts_per_rev: nominal.counts_per_rev,
        max_accel: param(&reply.data, "max_accel").unwrap_or(0.5),
        calibration: calibration_of(&reply.data),
    })
}

/// The pose covariance's inputs now, and where they come from: the `--calibration` log's
/// ([`crate::export::Export::uncertainty`], its floor for the calibration's age), or the
/// defaults of a calibrated or an uncalibrated board; and, for a calibration of today, when its
/// same-day floor ends and the inputs from then on.
fn uncertainty(
    opts: &Options,
    board: &Board,
) -> Result<(Uncertainty, String, Option<Aging>), String> {
    if let Some(log) = &opts.calibration {
        let e = Export::read(log)?;
        if e.sd.is_none() {
            return Err(format!(
                "{}: no 1-sigma of the calibration in it (no `calibrate` table, no runs)",
                log.display()
            ));
        }
        let board_method = board
            .calibration
            .split_whitespace()
            .next()
            .unwrap_or("none");
        if e.method.as_deref() != Some(board_method) {
            return Err(format!(
                "{}: its calibration ({}) is not the board's ({board_method})",
                log.display(),
                e.method.as_deref().unwrap_or("none")
            ));
        }
        let now = now_s();
        let (u, source) = e.uncertainty(opts.slip, opts.trust_session_sd, Some(now));
        let aging = aging_of(&e, opts.slip, opts.trust_session_sd, now);
        return Ok((u, format!("{source} from {}", log.display()), aging));
    }
    let mut random = RandomError::DEFAULT;
    if let Some(m) = opts.slip {
        random.slip_m2_per_m = m * m;
    }
    if board.calibration.starts_with("none") {
        Ok((
            Uncertainty::nominal(random),
            "defaults for an uncalibrated board".into(),
            None,
        ))
    } else {
        Ok((
            Uncertainty::calibrated(None, None, random, Floor::BetweenSessions),
            "the between-session drift for a calibrated board (no --calibration log)".into(),
            None,
        ))
    }
}

/// For a calibration whose runs are less than a day old at `now` (Unix seconds): when they turn
/// a day old, and the inputs from then on; `None` otherwise.
fn aging_of(e: &Export, slip: Option<f64>, trust_session: bool, now: f64) -> Option<Aging> {
    let logged = e.runs_logged_s?;
    if Floor::for_age(Some(now - logged), trust_session) != Floor::SameDay {
        return None;
    }
    let at_s = logged + covariance::SAME_DAY_S;
    let (u, source) = e.uncertainty(slip, trust_session, Some(at_s));
    Some(Aging { at_s, u, source })
}

/// A calibration of today: when (Unix seconds) it is a day old, and the pose covariance's
/// inputs from then on (the between-session floor).
pub(super) struct Aging {
    /// When the calibration's oldest run is a day old, Unix seconds.
    pub at_s: f64,
    /// The inputs from then on.
    pub u: Uncertainty,
    /// Where they come from.
    pub source: String,
}

/// The session log `--log` names (appended to), or none.
fn session_log(opts: &Options) -> Result<SessionLog, String> {
    match &opts.log {
        Some(p) => SessionLog::open(p),
        None => Ok(SessionLog::discard()),
    }
}

/// The `drive` line of a finite command, within the protocol's ranges.
fn drive_line(v: f64, w: f64) -> String {
    let drive = Command::Drive {
        v_mps: v.clamp(-DRIVE_LIMIT_MPS, DRIVE_LIMIT_MPS) as f32,
        w_radps: w.clamp(-DRIVE_LIMIT_RADPS, DRIVE_LIMIT_RADPS) as f32,
    };
    drive.to_string()
}

/// The bridge's node on the ROS 2 network: its publishers and its `cmd_vel` subscription (the
/// node and its context kept alive with them).
struct Network {
    odom: Publisher<Odometry>,
    tf: Option<Publisher<TFMessage>>,
    joints: Publisher<JointState>,
    diag: Publisher<DiagnosticArray>,
    cmd_vel: Option<CmdVel>,
    _node: Node,
    context: Context,
}

/// Joins `domain` within `range` as the node `opts` names, with its topics.
fn network(opts: &Options, domain: u16, range: Range) -> Result<Network, String> {
    // DDS: the domain and discovery range of the environment.
    let mut builder = DomainParticipantBuilder::new(domain);
    builder = match range {
        Range::Subnet => builder,
        Range::Localhost => builder.with_only_networks([std::net::Ipv4Addr::LOCALHOST]),
        Range::Off => builder
            .with_only_networks(Vec::<std::net::IpAddr>::new())
            .same_host_loopback(false),
    };
    let participant = builder
        .build()
        .map_err(|e| format!("DDS participant on domain {domain}: {e:?}"))?;
    let context = Context::from_domain_participant(participant)
        .map_err(|e| format!("ROS 2 context: {e:?}"))?;
    let ns = &namespace(opts.namespace.as_deref());
    let mut node = context
        .new_node(
            NodeName::new(ns, &opts.node_name).map_err(|e| format!("node name: {e:?}"))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| format!("ROS 2 node: {e:?}"))?;
    let odom_pub: Publisher<Odometry> =
        publisher(&mut node, ns, "odom", nav_msgs::ODOMETRY, &default_qos(10))?;
    let tf_pub: Option<Publisher<TFMessage>> = if opts.no_tf {
        None
    } else {
        Some(publisher(
            &mut node,
            ns,
            "/tf",
            tf2_msgs::TF_MESSAGE,
            &default_qos(100),
        )?)
    };
    let joints_pub: Publisher<JointState> = publisher(
        &mut node,
        ns,
        "joint_states",
        sensor_msgs::JOINT_STATE,
        &default_qos(10),
    )?;
    let diag_pub: Publisher<DiagnosticArray> = publisher(
        &mut node,
        ns,
        "/diagnostics",
        diagnostic_msgs::DIAGNOSTIC_ARRAY,
        &default_qos(10),
    )?;
    let cmd_vel = if opts.read_only {
        None
    } else {
        let (ty, name) = if opts.stamped {
            (geometry_msgs::TWIST_STAMPED, "TwistStamped")
        } else {
            (geometry_msgs::TWIST, "Twist")
        };
        let qos = default_qos(10);
        let topic = node
            .create_topic(
                &topic_name(ns, "cmd_vel")?,
                MessageTypeName::new(ty.0, ty.1),
                &qos,
            )
            .map_err(|e| format!("topic cmd_vel: {e:?}"))?;
        let sub = if opts.stamped {
            CmdVel::Stamped(
                node.create_subscription(&topic, Some(qos.clone()))
                    .map_err(|e| format!("cmd_vel ({name}): {e:?}"))?,
            )
        } else {
            CmdVel::Plain(
                node.create_subscription(&topic, Some(qos.clone()))
                    .map_err(|e| format!("cmd_vel ({name}): {e:?}"))?,
            )
        };
        Some(sub)
    };
    Ok(Network {
        odom: odom_pub,
        tf: tf_pub,
        joints: joints_pub,
        diag: diag_pub,
        cmd_vel,
        _node: node,
        context,
    })
}

/// The line that says what the bridge publishes and subscribes.
fn banner(opts: &Options, version: &str, (domain, range): (u16, Range), sd_source: &str) -> String {
    format!(
        "ros2: {version} on {}; node {}{} on domain {domain}, discovery {range:?}; publishing odom \
         ({}{} -> {}{}){}, joint_states ({}, {}), /diagnostics at {} Hz; {}; pose covariance from {}",
        opts.port,
        match namespace(opts.namespace.as_deref()).as_str() {
            "/" => "/".to_string(),
            ns => format!("{ns}/"),
        },
        opts.node_name,
        opts.frame_prefix,
        opts.odom_frame,
        opts.frame_prefix,
        opts.base_frame,
        if opts.no_tf { "" } else { ", /tf" },
        opts.left_joint,
        opts.right_joint,
        opts.rate_hz,
        if opts.read_only {
            "read-only: no cmd_vel".to_string()
        } else {
            format!(
                "cmd_vel ({}) drives the board",
                if opts.stamped {
                    "TwistStamped"
                } else {
                    "Twist"
                }
            )
        },
        sd_source
    )
}

/// The odometer of the bridge's messages for `board`: its names from `opts`, the pose
/// covariance from `u`, the twist covariance from
/// the encoders and the speed loop's acceleration over one stream period, the clock map with
/// the wire's time per byte (none on a pseudo-terminal).
fn odometer(opts: &Options, board: &Board, u: Uncertainty) -> Odometer {
    let period = 1.0 / f64::from(opts.rate_hz);
    let (var_v, var_w) = covariance::twist_variance(
        0.5 * (board.d_right + board.d_left),
        board.counts_per_rev,
        board.wheelbase,
        period,
        board.max_accel,
    );
    let twist_cov = Covariance(covariance::twist_ros(var_v, var_w));
    let wire_baud = (!crate::link::is_pty(&opts.port)).then_some(crate::link::BAUD);
    Odometer::new(
        Names {
            odom_frame: format!("{}{}", opts.frame_prefix, opts.odom_frame),
            base_frame: format!("{}{}", opts.frame_prefix, opts.base_frame),
            left_joint: opts.left_joint.clone(),
            right_joint: opts.right_joint.clone(),
        },
        Wheels {
            d_right: board.d_right,
            d_left: board.d_left,
            wheelbase: board.wheelbase,
        },
        if opts.use_sim_time {
            ClockMap::board()
        } else {
            ClockMap::new(wire_baud, 10.0)
        },
        PoseCovariance::new(board.wheelbase, u),
        twist_cov,
    )
}

/// The lines typed on stdin, read on a thread of their own.
fn stdin_lines() -> mpsc::Receiver<String> {
    let (stdin_tx, stdin_rx) = mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines().map_while(Result::ok) {
            if stdin_tx.send(line).is_err() {
                return;
            }
        }
    });
    stdin_rx
}

/// Runs the bridge until Ctrl-C or a lost connection.
///
/// # Errors
/// The port, the board or the DDS participant cannot be set up, or the board is lost, as text.
pub fn run(opts: &Options) -> Result<(), String> {
    let (domain, range) = ros_environment(|k| std::env::var(k).ok())?;
    let mut link = Link::open(&opts.port, session_log(opts)?)?;
    let version = link.handshake()?;
    let board = read_board(&mut link)?;
    let (u, sd_source, aging) = uncertainty(opts, &board)?;
    let net = network(opts, domain, range)?;

    let stream_on = Command::Stream {
        on: Some(Some(opts.rate_hz)),
    };
    let on = link
        .command(&stream_on.to_string(), Duration::from_secs(5))
        .map_err(|e| e.to_string())?;
    if !on.ok() {
        return Err(format!("the board refused `stream on`: {}", on.last));
    }
    println!("{}", banner(opts, &version, (domain, range), &sd_source));
    let online = match &opts.online.reference {
        Some(topic) => {
            let o = crate::online::Online::new(&opts.online, board.nominal, board.active())?;
            let r = reference::Reference::new(
                net.context.clone(),
                &namespace(opts.namespace.as_deref()),
                topic,
                &opts.node_name,
                opts.online.reference_type,
            );
            println!(
                "ros2: online calibration from {topic} (windows of {} m, horizon {} m, E_s {}, \
                 apply {:?})",
                opts.online.window,
                opts.online.horizon,
                if opts.online.fit_scale {
                    "fitted"
                } else {
                    "held"
                },
                opts.online.apply
            );
            Some((o, r))
        }
        None => None,
    };

    let odometer = odometer(opts, &board, u);
    let bridge = Bridge {
        opts,
        net: &net,
        board,
        link,
        stream_on,
        odometer,
        stats: Stats::default(),
        guard: Guard::new(opts.rate_hz),
        prev: None,
        commanding: None,
        last_drive_reply: String::new(),
        carried: None,
        next_status: Instant::now(),
        online,
        aging,
    };
    // Lines typed on stdin go to the board.
    bridge.run(&stdin_lines()).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_environment_sets_domain_and_range() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| {
                pairs
                    .iter()
                    .find(|(n, _)| *n == k)
                    .map(|(_, v)| v.to_string())
            }
        };
        assert_eq!(ros_environment(env(&[])), Ok((0, Range::Subnet)));
        assert_eq!(
            ros_environment(env(&[("ROS_DOMAIN_ID", "42")])),
            Ok((42, Range::Subnet))
        );
        assert_eq!(
            ros_environment(env(&[("ROS_LOCALHOST_ONLY", "1")])),
            Ok((0, Range::Localhost))
        );
        // Jazzy's variable wins over Humble's.
        assert_eq!(
            ros_environment(env(&[
                ("ROS_LOCALHOST_ONLY", "1"),
                ("ROS_AUTOMATIC_DISCOVERY_RANGE", "off")
            ])),
            Ok((0, Range::Off))
        );
        assert!(ros_environment(env(&[("ROS_DOMAIN_ID", "300")])).is_err());
        assert!(ros_environment(env(&[("ROS_AUTOMATIC_DISCOVERY_RANGE", "LAN")])).is_err());
    }

    /// `--namespace` puts every topic under it, whatever slashes are typed; without it they
    /// stay at the root (DDS names as Cyclone sees them: `rt/…`).
    #[test]
    fn the_namespace_prefixes_every_topic() {
        let dds = |ns: Option<&str>, t: &str| {
            topic_name(&namespace(ns), t).unwrap().to_dds_name(
                "rt",
                &NodeName::new("/", "n").unwrap(),
                "",
            )
        };
        assert_eq!(dds(None, "odom"), "rt/odom");
        assert_eq!(dds(None, "/tf"), "rt/tf");
        for ns in ["robot1", "/robot1", "/robot1/"] {
            assert_eq!(dds(Some(ns), "odom"), "rt/robot1/odom");
            assert_eq!(dds(Some(ns), "/tf"), "rt/robot1/tf");
            assert_eq!(dds(Some(ns), "cmd_vel"), "rt/robot1/cmd_vel");
        }
    }

    /// A calibration logged an hour ago widens to the between-session drift a day after its
    /// runs; one logged two days ago, or trusted as it is, never changes.
    #[test]
    fn a_calibration_of_today_ages_a_day_after_its_runs() {
        let nominal = odocal::kinematics::geometry::Geometry::PAPER_NOMINAL;
        let logged = 1.7e9;
        let e = Export {
            nominal,
            applied: nominal,
            method: Some("exact".into()),
            factors: (1.0, 1.0, 1.0),
            sd: Some((1e-4, 2e-4)),
            source: String::new(),
            side_m: 1.0,
            max_accel: 0.3,
            runs: Vec::new(),
            runs_logged_s: Some(logged),
            table: Vec::new(),
        };
        let a = aging_of(&e, None, false, logged + 3_600.0).unwrap();
        assert_eq!(a.at_s, logged + covariance::SAME_DAY_S);
        assert_eq!(
            (a.u.sd_d, a.u.sd_b),
            odocal::calibration::covariance::BETWEEN_SESSION_FLOOR
        );
        assert!(aging_of(&e, None, false, logged + 2.0 * 86_400.0).is_none());
        assert!(aging_of(&e, None, true, logged + 3_600.0).is_none());
    }

    #[test]
    fn commands_stay_in_the_protocols_ranges() {
        assert_eq!(drive_line(0.2, -0.5), "drive 0.2 -0.5");
        assert_eq!(drive_line(9.0, -40.0), "drive 2 -10");
    }
}

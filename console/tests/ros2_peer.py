#!/usr/bin/env python3
"""An independent ROS 2 peer for the `ros2_bridge` test: Eclipse Cyclone DDS (the DDS behind
rmw_cyclonedds_cpp) through its Python binding, with the ROS 2 messages declared here from their
.msg definitions under their standard DDS type names.

It subscribes `rt/odom` (nav_msgs/msg/Odometry) and prints every sample as a JSON line
(`{"k": "odom", ...}`: the stamp, the receive time on this machine's clock, x, y, yaw, v, w
and the x variance), and `rt/joint_states` (sensor_msgs/msg/JointState: `{"k": "joints", ...}`
with the stamp, the joint names, positions and velocities in the message's order), and
`rt/diagnostics` (diagnostic_msgs/msg/DiagnosticArray: `{"k": "diag", ...}` with the receive time,
the level, the message and the key-values of each status). Commands on stdin, one a line:
- `cmd_vel V W SECONDS HZ`: publishes geometry_msgs/msg/Twist on `rt/cmd_vel` (V m/s, W rad/s)
  at HZ for SECONDS, once the bridge's subscription is matched; then prints
  `{"k": "cmd_vel_done", "first": t, "last": t, "n": n}` (times on this machine's clock);
- `quit`.
Exits with status 3 and a message on stderr when cyclonedds cannot be imported.
"""

import json
import math
import sys
import threading
import time
from dataclasses import dataclass, field

try:
    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.idl import IdlStruct
    from cyclonedds.idl.types import array, byte, float64, int32, sequence, uint32
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration
except ImportError as e:  # the test fails with this message
    print(
        f"cyclonedds is not importable ({e}): install it with `pip install cyclonedds`",
        file=sys.stderr,
    )
    sys.exit(3)

@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0

@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""

@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0

@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0

@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)

@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)

@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0

@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)

@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)

@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)

@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    header: Header = field(default_factory=Header)
    name: sequence[str] = field(default_factory=list)
    position: sequence[float64] = field(default_factory=list)
    velocity: sequence[float64] = field(default_factory=list)
    effort: sequence[float64] = field(default_factory=list)

# ROS 2's default QoS (reliable, volatile, keep last 10), XCDR1 as every ROS 2 middleware writes.
QOS = Qos(
    Policy.Reliability.Reliable(duration(milliseconds=100)),
    Policy.Durability.Volatile,
    Policy.History.KeepLast(10),
    Policy.DataRepresentation(use_cdrv0_representation=True),
)

@dataclass
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    key: str = ""
    value: str = ""

@dataclass
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    level: byte = 0
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: sequence[KeyValue] = field(default_factory=list)

@dataclass
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    header: Header = field(default_factory=Header)
    status: sequence[DiagnosticStatus] = field(default_factory=list)

out_lock = threading.Lock()

def emit(obj):
    with out_lock:
        sys.stdout.write(json.dumps(obj) + "\n")
        sys.stdout.flush()

def main():
    dp = DomainParticipant()
    odom = DataReader(dp, Topic(dp, "rt/odom", Odometry), qos=QOS)
    joints = DataReader(dp, Topic(dp, "rt/joint_states", JointState), qos=QOS)
    cmd_vel = DataWriter(dp, Topic(dp, "rt/cmd_vel", Twist), qos=QOS)
    diagnostics = DataReader(dp, Topic(dp, "rt/diagnostics", DiagnosticArray), qos=QOS)

    def read_diagnostics():
        for s in diagnostics.take_iter():
            rx = time.time()
            for st in s.status:
                level = st.level if isinstance(st.level, int) else int.from_bytes(st.level, "little")
                emit(
                    {
                        "k": "diag",
                        "rx": rx,
                        "level": level,
                        "message": st.message,
                        "values": {kv.key: kv.value for kv in st.values},
                    }
                )

    def read_joints():
        for s in joints.take_iter():
            emit(
                {
                    "k": "joints",
                    "t": s.header.stamp.sec + s.header.stamp.nanosec * 1e-9,
                    "name": list(s.name),
                    "position": list(s.position),
                    "velocity": list(s.velocity),
                }
            )

    def read():
        for s in odom.take_iter():
            rx = time.time()
            q = s.pose.pose.orientation

            yaw = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
            emit(
                {
                    "k": "odom",
                    "t": s.header.stamp.sec + s.header.stamp.nanosec * 1e-9,
                    "rx": rx,
                    "frame": s.header.frame_id,
                    "child": s.child_frame_id,
                    "x": s.pose.pose.position.x,
                    "y": s.pose.pose.position.y,
                    "yaw": yaw,
                    "v": s.twist.twist.linear.x,
                    "w": s.twist.twist.angular.z,
                    "cxx": s.pose.covariance[0],
                    "cyy": s.pose.covariance[7],
                    "cvv": s.twist.covariance[0],
                }
            )

    emit({"k": "ready"})
    threading.Thread(target=read, daemon=True).start()
    threading.Thread(target=read_joints, daemon=True).start()
    threading.Thread(target=read_diagnostics, daemon=True).start()
    for line in sys.stdin:
        w = line.split()
        if not w:
            continue
        if w[0] == "quit":
            break
        if w[0] == "cmd_vel":
            v, wz, seconds, hz = float(w[1]), float(w[2]), float(w[3]), float(w[4])
            while not cmd_vel.get_matched_subscriptions():
                time.sleep(0.01)
            n = int(round(seconds * hz))
            first = last = time.time()
            for i in range(n):
                last = time.time()
                if i == 0:
                    first = last
                cmd_vel.write(Twist(linear=Vector3(x=v), angular=Vector3(z=wz)))
                if i + 1 < n:
                    # The command's own timing (a teleop's publishing period), not a wait for
                    # anything.
                    time.sleep(1.0 / hz)
            emit({"k": "cmd_vel_done", "first": first, "last": last, "n": n})

if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The robot's side of the `online_calibration` test: Eclipse Cyclone DDS through its Python
binding, independent of the bridge's RustDDS. It publishes the robot's reference pose
(geometry_msgs/msg/PoseWithCovarianceStamped on `rt/reference`, as AMCL does) and `cmd_vel`
(geometry_msgs/msg/Twist), and prints every `/diagnostics` status as a JSON line
(`{"k": "diag", "name": ..., "level": ..., "message": ..., "values": {...}}`).

Commands on stdin, one a line:
- `cmd off`: no more `cmd_vel` (a planner at its goal);
- `cmd V W`: from now on `cmd_vel` is V m/s, W rad/s, published every 10 ms of the wall clock
  (the board's deadman counts its own time, which a simulated board runs faster) until the next
  `cmd`;
- `pose T X Y YAW SXY SYAW`: one reference sample stamped T seconds, with standard deviations
  SXY (m) and SYAW (rad) in its covariance;
- `quit`.
Exits with status 3 and a message on stderr when cyclonedds cannot be imported.
"""

import json
import math
import sys
import threading
import time

try:
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
except ImportError as e:
    print(
        f"cyclonedds is not importable ({e}): install it with `pip install cyclonedds`",
        file=sys.stderr,
    )
    sys.exit(3)

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from ros2_peer import (  # noqa: E402  (the message declarations, shared with the other peer)
    QOS,
    DiagnosticArray,
    Header,
    Point,
    Pose,
    PoseWithCovariance,
    Quaternion,
    Time,
    Twist,
    Vector3,
    emit,
)
from dataclasses import dataclass, field  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402


@dataclass
class PoseWithCovarianceStamped(
    IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"
):
    header: Header = field(default_factory=Header)
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)


def main():
    dp = DomainParticipant()
    reference = DataWriter(
        dp, Topic(dp, "rt/reference", PoseWithCovarianceStamped), qos=QOS
    )
    cmd_vel = DataWriter(dp, Topic(dp, "rt/cmd_vel", Twist), qos=QOS)
    diagnostics = DataReader(dp, Topic(dp, "rt/diagnostics", DiagnosticArray), qos=QOS)
    command = [0.0, 0.0, False]
    lock = threading.Lock()

    def read_diagnostics():
        while True:
            for s in diagnostics.take_iter():
                for st in s.status:
                    level = (
                        st.level
                        if isinstance(st.level, int)
                        else int.from_bytes(st.level, "little")
                    )
                    emit(
                        {
                            "k": "diag",
                            "name": st.name,
                            "level": level,
                            "message": st.message,
                            "values": {kv.key: kv.value for kv in st.values},
                        }
                    )

    def drive():
        while True:
            with lock:
                v, w, on = command
            if on:
                cmd_vel.write(Twist(linear=Vector3(x=v), angular=Vector3(z=w)))
            # The command's own period, not a wait for anything.
            time.sleep(0.01)

    threading.Thread(target=read_diagnostics, daemon=True).start()
    threading.Thread(target=drive, daemon=True).start()
    emit({"k": "ready"})
    for line in sys.stdin:
        w = line.split()
        if not w:
            continue
        if w[0] == "quit":
            break
        if w[0] == "cmd" and w[1] == "off":
            with lock:
                command[2] = False
        elif w[0] == "cmd":
            with lock:
                command[0], command[1], command[2] = float(w[1]), float(w[2]), True
        elif w[0] == "pose":
            t, x, y, yaw, sxy, syaw = (float(v) for v in w[1:7])
            cov = [0.0] * 36
            cov[0] = cov[7] = sxy * sxy
            cov[35] = syaw * syaw
            sec = math.floor(t)
            reference.write(
                PoseWithCovarianceStamped(
                    header=Header(
                        stamp=Time(sec=sec, nanosec=min(999_999_999, int(round((t - sec) * 1e9)))),
                        frame_id="map",
                    ),
                    pose=PoseWithCovariance(
                        pose=Pose(
                            position=Point(x=x, y=y),
                            orientation=Quaternion(
                                z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0)
                            ),
                        ),
                        covariance=cov,
                    ),
                )
            )


if __name__ == "__main__":
    main()

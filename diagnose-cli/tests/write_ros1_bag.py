"""Writes a run (commands.csv, poses.csv) as a ROS 1 bag (rosbag format
2.0), as a lab that recorded with ROS 1 Noetic has it, with the third-party
`rosbags` writer: /cmd_vel as geometry_msgs/Twist, /odom as
nav_msgs/Odometry stamped on the recorder's wall clock, each message
logged a few milliseconds after it was made.

Usage: write_ros1_bag.py RUN_DIR OUT.bag
"""

import csv
import math
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

WALL_EPOCH_NS = 1_764_000_000 * 1_000_000_000


def rows(path):
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            yield {k: float(v) for k, v in row.items()}


def main(run_dir, out):
    store = get_typestore(Stores.ROS1_NOETIC)
    t = store.types
    Twist, Vector3 = t["geometry_msgs/msg/Twist"], t["geometry_msgs/msg/Vector3"]
    Odometry, Header, Time = t["nav_msgs/msg/Odometry"], t["std_msgs/msg/Header"], t["builtin_interfaces/msg/Time"]
    PoseWithCovariance, TwistWithCovariance = t["geometry_msgs/msg/PoseWithCovariance"], t["geometry_msgs/msg/TwistWithCovariance"]
    Pose, Point, Quaternion = t["geometry_msgs/msg/Pose"], t["geometry_msgs/msg/Point"], t["geometry_msgs/msg/Quaternion"]

    def ns(seconds):
        return WALL_EPOCH_NS + round(seconds * 1e9)

    messages = []
    for r in rows(f"{run_dir}/commands.csv"):
        twist = Twist(linear=Vector3(x=r["v"], y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=r["omega"]))
        messages.append((ns(r["t"]) + 2_000_000, "/cmd_vel", twist))
    zero36 = np.zeros(36)
    still = Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0))
    for seq, r in enumerate(rows(f"{run_dir}/poses.csv")):
        made = ns(r["t"])
        half = 0.5 * r["theta"]
        odometry = Odometry(
            header=Header(seq=seq, stamp=Time(sec=made // 1_000_000_000, nanosec=made % 1_000_000_000), frame_id="odom"),
            child_frame_id="base_link",
            pose=PoseWithCovariance(
                pose=Pose(position=Point(x=r["x"], y=r["y"], z=0.0),
                          orientation=Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))),
                covariance=zero36),
            twist=TwistWithCovariance(twist=still, covariance=zero36),
        )
        messages.append((made + 4_000_000, "/odom", odometry))
    messages.sort(key=lambda m: m[0])
    path = Path(out)
    if path.exists():
        path.unlink()
    with Writer(path) as writer:
        connections = {
            "/cmd_vel": writer.add_connection("/cmd_vel", Twist.__msgtype__, typestore=store),
            "/odom": writer.add_connection("/odom", Odometry.__msgtype__, typestore=store),
        }
        for log_ns, topic, message in messages:
            writer.write(connections[topic], log_ns, store.serialize_ros1(message, connections[topic].msgtype))


if __name__ == "__main__":
    main(*sys.argv[1:])

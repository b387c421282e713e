"""Writes a run (commands.csv, poses.csv) as a Gazebo user's ROS 2 bag would
hold it, with the third-party `rosbags` writer (rosbag2's own file layouts).

Usage: write_gazebo_bag.py RUN_DIR OUT_BAG_DIR OPTIONS...

As `ros2 bag record` under `use_sim_time` records a TurtleBot3 in Gazebo:
/cmd_vel is geometry_msgs/msg/Twist (no header: only the bag's log time);
/odom is nav_msgs/msg/Odometry stamped in simulation time, which starts near
zero; /clock is rosgraph_msgs/msg/Clock every 10 ms of simulation time; log
times are the recorder's wall clock (Unix time), each message arriving a
few milliseconds after it was made. OPTIONS, any of:

  storage=sqlite3|mcap   the storage plugin (default sqlite3: .db3)
  rtf=R                  simulation speed against real time (default 1.0)
  clock=yes|no           record /clock (default yes)
  split=N                cut the bag into N files, listed by metadata.yaml
  compression=none|file|message   rosbag2's zstd compression
  version=8|9            rosbag2 metadata version (default 8)
  poses=odom|vicon|model_states|gz_pose|turtlesim|gps
                         /odom in simulation time (default), or a motion-
                         capture bridge's /vicon/robot/robot
                         (geometry_msgs/msg/TransformStamped) stamped by a
                         robot clock 2.5 s ahead of the recorder's (with
                         vicon there is no simulation and no /clock), or
                         Gazebo Classic's ground truth /gazebo/model_states
                         (gazebo_msgs/msg/ModelStates, no header: the
                         robot "burger" beside two static models), or
                         ros_gz_bridge's /model/burger/pose
                         (geometry_msgs/msg/Pose, no header), or
                         turtlesim's /turtle1/pose (turtlesim/msg/Pose:
                         float32 x, y, theta, no header; ROS 2's
                         `ros2 bag record` tutorial bag; wall clock, no
                         /clock), or a Gazebo GPS plugin's /gps/fix
                         (sensor_msgs/msg/NavSatFix stamped in simulation
                         time: latitude and longitude about write_bag.py's
                         origin, no heading)
  command=twist|stamped|stamped-wall
                         /cmd_vel as geometry_msgs/msg/Twist (default) or
                         TwistStamped stamped in simulation time (ROS 2
                         Jazzy's controllers take stamped commands), or
                         stamped by a teleop node left on the wall clock
                         (no use_sim_time)
  recorder=wall|sim      the recorder's clock: the wall clock (default), or
                         simulation time (`ros2 bag record --use-sim-time`,
                         Humble on), so that log times and header stamps
                         are both simulation time
  camera=no|yes          also /camera/image_raw (sensor_msgs/msg/Image,
                         640 x 480 rgb8, 15 Hz): 0.9 MB a message, as a
                         robot's bag is mostly images
"""

import csv
import math
import shutil
import sys
from pathlib import Path

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from write_bag import latitude_longitude

WALL_EPOCH_NS = 1_764_000_000 * 1_000_000_000
# Simulation time at the run's 0 s: Gazebo had been running a little.
SIM_START_NS = 3_250_000_000
COMMAND_TRANSPORT_NS = 2_000_000
POSE_TRANSPORT_NS = 4_000_000


def rows(path):
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            yield {k: float(v) for k, v in row.items()}


def main(run_dir, out_dir, *options):
    opts = dict(o.split("=", 1) for o in options)
    storage = opts.get("storage", "sqlite3")
    rtf = float(opts.get("rtf", "1.0"))
    with_clock = opts.get("clock", "yes") == "yes"
    split = int(opts.get("split", "1"))
    compression = opts.get("compression", "none")
    version = int(opts.get("version", "8"))
    poses_from = opts.get("poses", "odom")
    vicon = poses_from == "vicon"
    with_clock = with_clock and poses_from not in ("vicon", "turtlesim")

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    # Not among rosbags' stored types: registered from its .msg, as a user
    # of rosbags does for any package it lacks.
    typestore.register(get_types_from_msg(
        "string[] name\ngeometry_msgs/Pose[] pose\ngeometry_msgs/Twist[] twist\n",
        "gazebo_msgs/msg/ModelStates",
    ))
    typestore.register(get_types_from_msg(
        "float32 x\nfloat32 y\nfloat32 theta\nfloat32 linear_velocity\nfloat32 angular_velocity\n",
        "turtlesim/msg/Pose",
    ))
    TurtlesimPose = typestore.types["turtlesim/msg/Pose"]
    NavSatFix = typestore.types["sensor_msgs/msg/NavSatFix"]
    NavSatStatus = typestore.types["sensor_msgs/msg/NavSatStatus"]
    ModelStates = typestore.types["gazebo_msgs/msg/ModelStates"]
    Twist = typestore.types["geometry_msgs/msg/Twist"]
    TwistStamped = typestore.types["geometry_msgs/msg/TwistStamped"]
    stamped_commands = opts.get("command", "twist") in ("stamped", "stamped-wall")
    wall_stamped = opts.get("command", "twist") == "stamped-wall"
    Vector3 = typestore.types["geometry_msgs/msg/Vector3"]
    Odometry = typestore.types["nav_msgs/msg/Odometry"]
    Header = typestore.types["std_msgs/msg/Header"]
    Time = typestore.types["builtin_interfaces/msg/Time"]
    PoseWithCovariance = typestore.types["geometry_msgs/msg/PoseWithCovariance"]
    TwistWithCovariance = typestore.types["geometry_msgs/msg/TwistWithCovariance"]
    Pose = typestore.types["geometry_msgs/msg/Pose"]
    Point = typestore.types["geometry_msgs/msg/Point"]
    Quaternion = typestore.types["geometry_msgs/msg/Quaternion"]
    Clock = typestore.types["rosgraph_msgs/msg/Clock"]
    Transform = typestore.types["geometry_msgs/msg/Transform"]
    TransformStamped = typestore.types["geometry_msgs/msg/TransformStamped"]
    poses_topic, pose_type = {
        "odom": ("/odom", Odometry),
        "vicon": ("/vicon/robot/robot", TransformStamped),
        "model_states": ("/gazebo/model_states", ModelStates),
        "gz_pose": ("/model/burger/pose", Pose),
        "turtlesim": ("/turtle1/pose", TurtlesimPose),
        "gps": ("/gps/fix", NavSatFix),
    }[poses_from]

    def sim_ns(t):
        return SIM_START_NS + round(t * 1e9)

    sim_recorder = opts.get("recorder", "wall") == "sim"

    def wall_ns(t):
        # Wall time runs 1/rtf as fast as simulation time. A recorder on
        # simulation time logs each message at the simulation time it came.
        if sim_recorder:
            return sim_ns(t)
        return WALL_EPOCH_NS + round(t * 1e9 / rtf)

    def stamp(ns):
        return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    messages = []  # (log_ns, topic, message)
    types = {}
    for r in rows(f"{run_dir}/commands.csv"):
        msg = Twist(linear=Vector3(x=r["v"], y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=r["omega"]))
        if stamped_commands:
            made = wall_ns(r["t"]) if wall_stamped else sim_ns(r["t"])
            msg = TwistStamped(header=Header(stamp=stamp(made), frame_id="base_link"), twist=msg)
        messages.append((wall_ns(r["t"]) + COMMAND_TRANSPORT_NS, "/cmd_vel", msg))
    zero36 = [0.0] * 36
    import numpy as np

    end = 0.0
    for r in rows(f"{run_dir}/poses.csv"):
        end = max(end, r["t"])
        half = 0.5 * r["theta"]
        pose = Pose(
            position=Point(x=r["x"], y=r["y"], z=0.0),
            orientation=Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half)),
        )
        if vicon:
            robot_clock_ns = wall_ns(r["t"]) + 2_500_000_000
            msg = TransformStamped(
                header=Header(stamp=stamp(robot_clock_ns), frame_id="world"),
                child_frame_id="robot",
                transform=Transform(translation=Vector3(x=r["x"], y=r["y"], z=0.0), rotation=pose.orientation),
            )
            messages.append((wall_ns(r["t"]) + POSE_TRANSPORT_NS, poses_topic, msg))
            continue
        if poses_from == "gps":
            latitude, longitude = latitude_longitude(r["x"], r["y"])
            msg = NavSatFix(
                header=Header(stamp=stamp(sim_ns(r["t"])), frame_id="gps_link"),
                status=NavSatStatus(status=0, service=1),
                latitude=latitude,
                longitude=longitude,
                altitude=76.0,
                position_covariance=np.array([0.0004, 0, 0, 0, 0.0004, 0, 0, 0, 0.0016]),
                position_covariance_type=2,
            )
            messages.append((wall_ns(r["t"]) + POSE_TRANSPORT_NS, poses_topic, msg))
            continue
        if poses_from == "turtlesim":
            msg = TurtlesimPose(x=r["x"], y=r["y"], theta=r["theta"], linear_velocity=0.0, angular_velocity=0.0)
            messages.append((wall_ns(r["t"]) + POSE_TRANSPORT_NS, poses_topic, msg))
            continue
        if poses_from in ("model_states", "gz_pose"):
            # No header: the bag's log time is all that times them.
            if poses_from == "model_states":
                still = Pose(
                    position=Point(x=0.0, y=0.0, z=0.0),
                    orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                )
                rest = Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0))
                msg = ModelStates(
                    name=["ground_plane", "turtlebot3_world", "burger"],
                    pose=[still, still, pose],
                    twist=[rest, rest, rest],
                )
            else:
                msg = pose
            messages.append((wall_ns(r["t"]) + POSE_TRANSPORT_NS, poses_topic, msg))
            continue
        msg = Odometry(
            header=Header(stamp=stamp(sim_ns(r["t"])), frame_id="odom"),
            child_frame_id="base_footprint",
            pose=PoseWithCovariance(pose=pose, covariance=np.array(zero36)),
            twist=TwistWithCovariance(
                twist=Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)),
                covariance=np.array(zero36),
            ),
        )
        messages.append((wall_ns(r["t"]) + POSE_TRANSPORT_NS, "/odom", msg))
    if with_clock:
        t = 0.0
        while t <= end + 0.5:
            messages.append((wall_ns(t) + 1_000_000, "/clock", Clock(clock=stamp(sim_ns(t)))))
            t += 0.01
    if opts.get("camera", "no") == "yes":
        Image = typestore.types["sensor_msgs/msg/Image"]
        # One frame's bytes, shared by every message: noise, so a
        # compressed bag stays as large.
        frame = np.frombuffer(np.random.default_rng(0).bytes(640 * 480 * 3), dtype=np.uint8)
        t = 0.0
        while t <= end:
            header = Header(stamp=stamp(sim_ns(t)), frame_id="camera")
            image = Image(header=header, height=480, width=640, encoding="rgb8", is_bigendian=0, step=1920, data=frame)
            messages.append((wall_ns(t) + 3_000_000, "/camera/image_raw", image))
            t += 1 / 15
        types["/camera/image_raw"] = Image.__msgtype__
    messages.sort(key=lambda m: m[0])

    command_type = TwistStamped if stamped_commands else Twist
    types.update({"/cmd_vel": command_type.__msgtype__, poses_topic: pose_type.__msgtype__, "/clock": Clock.__msgtype__})
    out = Path(out_dir)
    if out.exists():
        shutil.rmtree(out)
    parts = []
    per_part = math.ceil(len(messages) / split)
    for k in range(split):
        part_dir = out if split == 1 else out.parent / f"{out.name}.part{k}"
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(part_dir, version=version, storage_plugin=plugin)
        if compression != "none":
            mode = CompressionMode.FILE if compression == "file" else CompressionMode.MESSAGE
            writer.set_compression(mode, CompressionFormat.ZSTD)
        with writer:
            connections = {}
            for topic, msgtype in types.items():
                if topic == "/clock" and not with_clock:
                    continue
                connections[topic] = writer.add_connection(topic, msgtype, typestore=typestore)
            for log_ns, topic, msg in messages[k * per_part:(k + 1) * per_part]:
                writer.write(connections[topic], log_ns, typestore.serialize_cdr(msg, types[topic]))
        parts.append(part_dir)
    if split > 1:
        # One bag folder holding every part, as rosbag2 splits one: the
        # files side by side, listed in order by one metadata.yaml.
        out.mkdir(parents=True)
        names = []
        for k, part in enumerate(parts):
            for f in sorted(part.iterdir()):
                if f.name == "metadata.yaml":
                    continue
                name = f.name.replace(part.name, f"{out.name}_{k}")
                shutil.move(str(f), out / name)
                names.append(name)
            shutil.rmtree(part)
        listed = "\n".join(f"    - {n}" for n in names)
        (out / "metadata.yaml").write_text(
            "rosbag2_bagfile_information:\n"
            f"  version: {version}\n"
            f"  storage_identifier: {storage}\n"
            f"  relative_file_paths:\n{listed}\n"
            f"  message_count: {len(messages)}\n"
        )


if __name__ == "__main__":
    main(*sys.argv[1:])

"""Writes a run (commands.csv, poses.csv) as a ROS 2 bag with the official
Python writer (mcap-ros2-support, which encodes CDR as ROS 2 does).

Usage: write_bag.py RUN_DIR OUT.mcap {pose,tf,tf_chain,amcl,odometry,nav2,gps,point}

Commands go to /cmd_vel as geometry_msgs/msg/Twist (no header: the bag's
log times). Poses go, by the last argument, to /mocap/pose as
geometry_msgs/msg/PoseStamped, to /tf as tf2_msgs/msg/TFMessage (odom ->
base_link, beside a camera transform that must be ignored), or to /odom as
nav_msgs/msg/Odometry. With tf_chain, /tf holds a localised robot's tree
as navigation stacks publish it and no transform from map to the robot:
map -> odom at 5 Hz (a localisation that corrects a drifting odometry),
odom -> base_footprint at every pose (the drifting odometry), and
/tf_static base_footprint -> base_link, 5 cm ahead and 1 cm left; base_link
in map, composed, is the run's pose. With amcl, the tree as a localised
robot's really is: odom -> base_link integrates the run's motion with
strides 3% long and a heading drift of 0.02 rad per metre (wheel
odometry's errors), and map -> odom is re-estimated every 0.5 s, 1.5 cm
and 0.01 rad off at random (seeded), and held between estimates (as AMCL
publishes it): base_link in map jumps back towards the truth at each
estimate. Times start at 1.7e9 s, as a wall clock would.
With odometry, the schemas are registered by their ROS 1 spelling
(`nav_msgs/Odometry`, `geometry_msgs/Twist`), as mcap-ros2-support's own
README does: the same layouts, named as many writers outside ROS name them.
With nav2, the bag holds what a navigation stack's robot with motion
capture records: the commands on /cmd_vel_nav (the planner's) and /cmd_vel
(the base's, here the same), the poses on /mocap/pose and /odom.
With gps, the poses are a GPS receiver's: sensor_msgs/msg/NavSatFix on
/gps/fix, the run's x and y as metres east and north of 43.6629 N,
79.3957 W on the WGS 84 ellipsoid, no heading; one message in 200 has no
fix (status -1, NaN latitude and longitude), as a receiver sends them.
With point, the poses are a tracked point's (a UWB tag, one marker):
geometry_msgs/msg/PointStamped on /tag/position, no heading.
"""

import csv
import math
import random
import sys

from mcap_ros2.writer import Writer

SEPARATOR = "=" * 80 + "\n"

VECTOR3 = "float64 x\nfloat64 y\nfloat64 z\n"
POINT = "float64 x\nfloat64 y\nfloat64 z\n"
QUATERNION = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
TIME = "int32 sec\nuint32 nanosec\n"
POSE = "Point position\nQuaternion orientation\n"
TWIST = "Vector3 linear\nVector3 angular\n"


def definition(main: str, *deps: tuple) -> str:
    text = main
    for name, body in deps:
        text += SEPARATOR + f"MSG: {name}\n" + body
    return text


TWIST_DEF = definition(TWIST, ("geometry_msgs/Vector3", VECTOR3))
POSE_STAMPED_DEF = definition(
    "std_msgs/Header header\nPose pose\n",
    ("std_msgs/Header", HEADER),
    ("builtin_interfaces/Time", TIME),
    ("geometry_msgs/Pose", POSE),
    ("geometry_msgs/Point", POINT),
    ("geometry_msgs/Quaternion", QUATERNION),
)
TF_DEF = definition(
    "geometry_msgs/TransformStamped[] transforms\n",
    ("geometry_msgs/TransformStamped", "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"),
    ("std_msgs/Header", HEADER),
    ("builtin_interfaces/Time", TIME),
    ("geometry_msgs/Transform", "Vector3 translation\nQuaternion rotation\n"),
    ("geometry_msgs/Vector3", VECTOR3),
    ("geometry_msgs/Quaternion", QUATERNION),
)
ODOMETRY_DEF = definition(
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n",
    ("std_msgs/Header", HEADER),
    ("builtin_interfaces/Time", TIME),
    ("geometry_msgs/PoseWithCovariance", "Pose pose\nfloat64[36] covariance\n"),
    ("geometry_msgs/Pose", POSE),
    ("geometry_msgs/Point", POINT),
    ("geometry_msgs/Quaternion", QUATERNION),
    ("geometry_msgs/TwistWithCovariance", "Twist twist\nfloat64[36] covariance\n"),
    ("geometry_msgs/Twist", TWIST),
    ("geometry_msgs/Vector3", VECTOR3),
)

POINT_STAMPED_DEF = definition(
    "std_msgs/Header header\nPoint point\n",
    ("std_msgs/Header", HEADER),
    ("builtin_interfaces/Time", TIME),
    ("geometry_msgs/Point", POINT),
)
NAV_SAT_FIX_DEF = definition(
    "std_msgs/Header header\nNavSatStatus status\nfloat64 latitude\nfloat64 longitude\nfloat64 altitude\n"
    "float64[9] position_covariance\nuint8 position_covariance_type\n",
    ("std_msgs/Header", HEADER),
    ("builtin_interfaces/Time", TIME),
    ("sensor_msgs/NavSatStatus", "int8 status\nuint16 service\n"),
)

# Where the gps mode's run lies, and the WGS 84 ellipsoid's radii there.
ORIGIN = (43.6629, -79.3957)
_A, _E2 = 6378137.0, 6.69437999014e-3
_SIN = math.sin(math.radians(ORIGIN[0]))
NORTH_M_PER_RAD = _A * (1 - _E2) / (1 - _E2 * _SIN**2) ** 1.5
EAST_M_PER_RAD = _A / math.sqrt(1 - _E2 * _SIN**2) * math.cos(math.radians(ORIGIN[0]))


def latitude_longitude(x: float, y: float) -> tuple:
    """Degrees at x metres east and y metres north of ORIGIN."""
    return ORIGIN[0] + math.degrees(y / NORTH_M_PER_RAD), ORIGIN[1] + math.degrees(x / EAST_M_PER_RAD)


def fix(r: dict, k: int) -> dict:
    """The gps mode's message for pose row r, the k-th."""
    lost = k % 200 == 199
    latitude, longitude = (math.nan, math.nan) if lost else latitude_longitude(r["x"], r["y"])
    return {
        "header": {"stamp": stamp(r["t"]), "frame_id": "gps"},
        "status": {"status": -1 if lost else 0, "service": 1},
        "latitude": latitude,
        "longitude": longitude,
        "altitude": 76.0,
        "position_covariance": [0.0004, 0, 0, 0, 0.0004, 0, 0, 0, 0.0016],
        "position_covariance_type": 2,
    }


EPOCH_S = 1_700_000_000


def rows(path: str):
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            yield {k: float(v) for k, v in row.items()}


def nanos(t: float) -> int:
    # In integers: (EPOCH_S + t) as a float is a quarter-microsecond coarse.
    return EPOCH_S * 1_000_000_000 + round(t * 1e9)


def stamp(t: float) -> dict:
    ns = nanos(t)
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def quaternion(theta: float) -> dict:
    return {"x": 0.0, "y": 0.0, "z": math.sin(theta / 2), "w": math.cos(theta / 2)}


def compose(a, b):
    """Planar pose b, given in a's frame, in a's parent's frame."""
    (ax, ay, at), (bx, by, bt) = a, b
    c, s = math.cos(at), math.sin(at)
    return (ax + c * bx - s * by, ay + s * bx + c * by, at + bt)


def inverse(a):
    ax, ay, at = a
    c, s = math.cos(at), math.sin(at)
    return (-(c * ax + s * ay), s * ax - c * ay, -at)


def odometry_drift(t: float):
    """map -> odom at time t: linear in t, so that tf2's interpolation
    between its 5 Hz samples is exact."""
    return (0.3 + 0.002 * t, -0.1 - 0.001 * t, 0.2 + 0.0005 * t)


FOOTPRINT_TO_LINK = (0.05, 0.01, 0.0)


def transform(parent: str, child: str, t: float, pose) -> dict:
    x, y, theta = pose
    return {
        "header": {"stamp": stamp(t), "frame_id": parent},
        "child_frame_id": child,
        "transform": {"translation": {"x": x, "y": y, "z": 0.0}, "rotation": quaternion(theta)},
    }


def amcl_transforms(run: str, schema) -> list:
    """The amcl mode's /tf messages, (t, topic, schema, message)."""
    rng = random.Random(1)
    messages, previous, odometry, next_estimate = [], None, None, 0.0
    for r in rows(f"{run}/poses.csv"):
        truth = (r["x"], r["y"], r["theta"])
        if previous is None:
            odometry = truth
        else:
            step = compose(inverse(previous), truth)
            walked = math.hypot(step[0], step[1])
            odometry = compose(odometry, (1.03 * step[0], 1.03 * step[1], step[2] + 0.02 * walked))
        previous = truth
        if r["t"] >= next_estimate:
            exact = compose(truth, inverse(odometry))
            estimate = (
                exact[0] + rng.gauss(0, 0.015),
                exact[1] + rng.gauss(0, 0.015),
                exact[2] + rng.gauss(0, 0.01),
            )
            messages.append((r["t"], "/tf", schema, {"transforms": [transform("map", "odom", r["t"], estimate)]}))
            next_estimate += 0.5
        messages.append((r["t"], "/tf", schema, {"transforms": [transform("odom", "base_link", r["t"], odometry)]}))
    return messages


def main(run: str, out: str, poses_as: str) -> None:
    with open(out, "wb") as f:
        writer = Writer(f)
        short = poses_as == "odometry"
        nav2 = poses_as == "nav2"
        twist = writer.register_msgdef("geometry_msgs/Twist" if short else "geometry_msgs/msg/Twist", TWIST_DEF)
        # Messages are written in time order, as a recorder would.
        messages = []
        for r in rows(f"{run}/commands.csv"):
            message = {
                "linear": {"x": r["v"], "y": 0.0, "z": 0.0},
                "angular": {"x": 0.0, "y": 0.0, "z": r["omega"]},
            }
            messages.append((r["t"], "/cmd_vel", twist, message))
            if nav2:
                messages.append((r["t"], "/cmd_vel_nav", twist, message))
        if nav2:
            odometry_schema = writer.register_msgdef("nav_msgs/msg/Odometry", ODOMETRY_DEF)
        if poses_as == "gps":
            schema = writer.register_msgdef("sensor_msgs/msg/NavSatFix", NAV_SAT_FIX_DEF)
            topic = "/gps/fix"
        elif poses_as == "point":
            schema = writer.register_msgdef("geometry_msgs/msg/PointStamped", POINT_STAMPED_DEF)
            topic = "/tag/position"
        elif poses_as in ("pose", "nav2"):
            schema = writer.register_msgdef("geometry_msgs/msg/PoseStamped", POSE_STAMPED_DEF)
            topic = "/mocap/pose"
        elif poses_as in ("tf", "tf_chain", "amcl"):
            schema = writer.register_msgdef("tf2_msgs/msg/TFMessage", TF_DEF)
            topic = "/tf"
        else:
            schema = writer.register_msgdef("nav_msgs/Odometry", ODOMETRY_DEF)
            topic = "/odom"
        if poses_as == "amcl":
            messages.extend(amcl_transforms(run, schema))
        if poses_as == "tf_chain":
            # Latched once at the start, as robot_state_publisher does.
            static = {"transforms": [transform("base_footprint", "base_link", 0.0, FOOTPRINT_TO_LINK)]}
            messages.append((0.0, "/tf_static", schema, static))
            last = max(r["t"] for r in rows(f"{run}/poses.csv"))
            for k in range(int(last / 0.2) + 2):
                t = 0.2 * k
                localisation = {"transforms": [transform("map", "odom", t, odometry_drift(t))]}
                messages.append((t, "/tf", schema, localisation))
        # A localised robot's poses are only its transforms (above).
        pose_rows = [] if poses_as == "amcl" else rows(f"{run}/poses.csv")
        for k, r in enumerate(pose_rows):
            if poses_as == "gps":
                messages.append((r["t"], topic, schema, fix(r, k)))
                continue
            position = {"x": r["x"], "y": r["y"], "z": 0.0}
            if poses_as == "point":
                point = {"header": {"stamp": stamp(r["t"]), "frame_id": "map"}, "point": position}
                messages.append((r["t"], topic, schema, point))
                continue
            if poses_as == "tf_chain":
                truth = (r["x"], r["y"], r["theta"])
                odometry = compose(inverse(odometry_drift(r["t"])), compose(truth, inverse(FOOTPRINT_TO_LINK)))
                message = {"transforms": [transform("odom", "base_footprint", r["t"], odometry)]}
                messages.append((r["t"], topic, schema, message))
                continue
            header = {"stamp": stamp(r["t"]), "frame_id": "odom"}
            zero = [0.0] * 36
            odometry_message = {
                "header": header,
                "child_frame_id": "base_link",
                "pose": {"pose": {"position": position, "orientation": quaternion(r["theta"])}, "covariance": zero},
                "twist": {
                    "twist": {"linear": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
                    "covariance": zero,
                },
            }
            if poses_as in ("pose", "nav2"):
                message = {"header": header, "pose": {"position": position, "orientation": quaternion(r["theta"])}}
                if nav2:
                    messages.append((r["t"], "/odom", odometry_schema, odometry_message))
            elif poses_as == "tf":
                robot = {
                    "header": header,
                    "child_frame_id": "base_link",
                    "transform": {"translation": position, "rotation": quaternion(r["theta"])},
                }
                camera = {
                    "header": {"stamp": stamp(r["t"]), "frame_id": "base_link"},
                    "child_frame_id": "camera",
                    "transform": {"translation": {"x": 0.1, "y": 0.0, "z": 0.3}, "rotation": quaternion(0.0)},
                }
                message = {"transforms": [camera, robot]}
            else:
                message = odometry_message
            messages.append((r["t"], topic, schema, message))
        messages.sort(key=lambda m: m[0])
        for t, topic, schema, message in messages:
            writer.write_message(topic=topic, schema=schema, message=message, log_time=nanos(t), publish_time=nanos(t))
        writer.finish()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3])

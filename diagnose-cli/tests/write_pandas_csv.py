"""Rewrites a run's commands.csv and poses.csv as pandas writes them on a
Windows desktop: a byte-order mark, CRLF line ends, the frame's index as a
first unnamed column, columns in another order, an extra column each, and
poses in scientific notation. `shoal diagnose` must read them as it reads
its own. With `odometry`, the poses are written instead as a bag's
nav_msgs/Odometry messages flattened into a data frame (`timestamp` and
the message's fields, `pose.pose.orientation.x` ... `.w` a quaternion, no
heading column), as a user exporting `/odom` to pandas has them.

Usage: python3 write_pandas_csv.py FROM_FOLDER TO_FOLDER [odometry]
"""

import sys

import numpy as np
import pandas as pd


def main():
    source, target = sys.argv[1], sys.argv[2]
    commands = pd.read_csv(f"{source}/commands.csv")
    poses = pd.read_csv(f"{source}/poses.csv")
    commands["frame_id"] = "base_link"
    poses["quality"] = 1.0
    commands[["omega", "t", "v", "frame_id"]].to_csv(
        f"{target}/commands.csv", lineterminator="\r\n", encoding="utf-8-sig")
    if sys.argv[3:] == ["odometry"]:
        odometry = pd.DataFrame({
            "timestamp": poses["t"],
            "header.frame_id": "odom",
            "child_frame_id": "base_link",
            "pose.pose.position.x": poses["x"],
            "pose.pose.position.y": poses["y"],
            "pose.pose.position.z": 0.0,
            "pose.pose.orientation.x": 0.0,
            "pose.pose.orientation.y": 0.0,
            "pose.pose.orientation.z": np.sin(poses["theta"] / 2),
            "pose.pose.orientation.w": np.cos(poses["theta"] / 2),
            "twist.twist.linear.x": 0.0,
            "twist.twist.angular.z": 0.0,
        })
        odometry.to_csv(f"{target}/poses.csv", index=False)
        return
    poses[["t", "theta", "x", "y", "quality"]].to_csv(
        f"{target}/poses.csv", lineterminator="\r\n", encoding="utf-8-sig",
        float_format="%.9e")


if __name__ == "__main__":
    main()

"""Rewrites a run's commands.csv and poses.csv as pandas writes them on a
Windows desktop: a byte-order mark, CRLF line ends, the frame's index as a
first unnamed column, columns in another order, an extra column each, and
poses in scientific notation. `shoal diagnose` must read them as it reads
its own. With `odometry`, the poses are written instead as a bag's
nav_msgs/Odometry messages flattened into a data frame (`timestamp` and
the message's fields, `pose.pose.orientation.x` ... `.w` a quaternion, no
heading column), as a user exporting `/odom` to pandas has them. With
`odometry-ns`, both files are timed as a bag's messages are: `timestamp`
in integer nanoseconds of Unix time (pandas' int64), commands included.
With `datetime`, each file is indexed by the time as a pandas datetime:
the commands' naive (`2023-11-14 22:13:20.011100160`), the poses' in UTC
(`...+00:00`), as a user who parsed a log's times writes them.
With `tracking-lost`, the poses are written as a motion capture that lost
the body now and then leaves them: every frame's time, and NaN (which
pandas writes as an empty field) for the position and heading of about
2% of frames, in stretches of 1 to 30 frames.

With `excel-eu`, both files are written as a spreadsheet in most of
Europe's locales keeps them: fields separated by semicolons, decimal
commas (pandas' `sep=';', decimal=','`), a byte-order mark.

Usage: python3 write_pandas_csv.py FROM_FOLDER TO_FOLDER [odometry|odometry-ns|datetime|tracking-lost|excel-eu]
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
    mode = sys.argv[3] if len(sys.argv) > 3 else ""
    epoch_ns = 1_700_000_000 * 10**9

    def nanoseconds(t):
        return (t * 1e9).round().astype("int64") + epoch_ns

    if mode == "datetime":
        commands.index = pd.to_datetime(nanoseconds(commands["t"]).to_numpy(), unit="ns")
        commands.index.name = "time"
        commands[["v", "omega"]].to_csv(f"{target}/commands.csv")
        poses.index = pd.to_datetime(nanoseconds(poses["t"]).to_numpy(), unit="ns", utc=True)
        poses.index.name = "time"
        poses[["x", "y", "theta"]].to_csv(f"{target}/poses.csv")
        return
    if mode == "excel-eu":
        for frame, name in ((commands[["t", "v", "omega"]], "commands"), (poses[["t", "x", "y", "theta"]], "poses")):
            frame.to_csv(f"{target}/{name}.csv", sep=";", decimal=",", index=False, encoding="utf-8-sig")
        return
    if mode == "tracking-lost":
        commands[["t", "v", "omega"]].to_csv(f"{target}/commands.csv", index=False)
        rng = np.random.default_rng(7)
        lost = np.zeros(len(poses), dtype=bool)
        for start in rng.choice(len(poses), size=len(poses) // 750, replace=False):
            lost[start:start + rng.integers(1, 31)] = True
        poses.loc[lost, ["x", "y", "theta"]] = np.nan
        poses[["t", "x", "y", "theta"]].to_csv(f"{target}/poses.csv", index=False)
        return
    if mode == "odometry-ns":
        pd.DataFrame({
            "timestamp": nanoseconds(commands["t"]),
            "linear.x": commands["v"],
            "angular.z": commands["omega"],
        }).to_csv(f"{target}/commands.csv", index=False)
    else:
        commands[["omega", "t", "v", "frame_id"]].to_csv(
            f"{target}/commands.csv", lineterminator="\r\n", encoding="utf-8-sig")
    if mode.startswith("odometry"):
        odometry = pd.DataFrame({
            "timestamp": nanoseconds(poses["t"]) if mode == "odometry-ns" else poses["t"],
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

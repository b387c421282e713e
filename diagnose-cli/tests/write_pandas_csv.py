"""Rewrites a run's commands.csv and poses.csv as pandas writes them on a
Windows desktop: a byte-order mark, CRLF line ends, the frame's index as a
first unnamed column, columns in another order, an extra column each, and
poses in scientific notation. `shoal diagnose` must read them as it reads
its own.

Usage: python3 write_pandas_csv.py FROM_FOLDER TO_FOLDER
"""

import sys

import pandas as pd


def main():
    source, target = sys.argv[1], sys.argv[2]
    commands = pd.read_csv(f"{source}/commands.csv")
    poses = pd.read_csv(f"{source}/poses.csv")
    commands["frame_id"] = "base_link"
    poses["quality"] = 1.0
    commands[["omega", "t", "v", "frame_id"]].to_csv(
        f"{target}/commands.csv", lineterminator="\r\n", encoding="utf-8-sig")
    poses[["t", "theta", "x", "y", "quality"]].to_csv(
        f"{target}/poses.csv", lineterminator="\r\n", encoding="utf-8-sig",
        float_format="%.9e")


if __name__ == "__main__":
    main()

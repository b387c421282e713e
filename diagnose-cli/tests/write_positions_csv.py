"""Writes one robot of an MRCLAM dataset folder as a run of positions only,
as a user whose tracker follows one marker (or a GPS) has it: pandas reads
the dataset's whitespace-separated files and writes `commands.csv` (`t,v,omega`)
and `poses.csv` with a time and a position in millimetres and no heading
(`time,x_mm,y_mm`). `shoal diagnose` must take each heading from the track.

Usage: python3 write_positions_csv.py MRCLAM_FOLDER ROBOT TO_FOLDER
"""

import sys

import pandas as pd


def main():
    source, robot, target = sys.argv[1], sys.argv[2], sys.argv[3]

    def read(name, columns):
        return pd.read_csv(f"{source}/Robot{robot}_{name}.dat", sep=r"\s+", comment="#",
                           header=None, names=columns)

    commands = read("Odometry", ["t", "v", "omega"])
    commands.to_csv(f"{target}/commands.csv", index=False)
    poses = read("Groundtruth", ["time", "x", "y", "theta"])
    pd.DataFrame({
        "time": poses["time"],
        "x_mm": (poses["x"] * 1000).round(2),
        "y_mm": (poses["y"] * 1000).round(2),
    }).to_csv(f"{target}/poses.csv", index=False)


if __name__ == "__main__":
    main()

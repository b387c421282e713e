"""Writes a run's poses (poses.csv) as a TUM trajectory with evo's own
writer (`evo.tools.file_interface.write_tum_trajectory_file`), as a SLAM
researcher's ground truth or estimate is kept: `timestamp tx ty tz qx qy
qz qw` per line, space-separated, no header, the heading as a quaternion.

Usage: python3 write_tum.py RUN_DIR OUT_FILE
"""

import csv
import sys

import numpy as np
from evo.core.trajectory import PoseTrajectory3D
from evo.tools import file_interface


def main(run_dir, out_file):
    with open(f"{run_dir}/poses.csv", newline="") as f:
        rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
    t = np.array([r["t"] for r in rows])
    xyz = np.array([[r["x"], r["y"], 0.0] for r in rows])
    half = np.array([r["theta"] / 2.0 for r in rows])
    wxyz = np.stack([np.cos(half), np.zeros_like(half), np.zeros_like(half), np.sin(half)], axis=1)
    trajectory = PoseTrajectory3D(positions_xyz=xyz, orientations_quat_wxyz=wxyz, timestamps=t)
    file_interface.write_tum_trajectory_file(out_file, trajectory)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(*sys.argv[1:])

"""Writes a run (commands.csv and poses.csv of a folder) as a Rerun
recording with the official Rerun Python SDK, in the layout Shoal's recorder
uses for each robot's motion (`robots/motion` on the `sim_time` timeline:
agent_id, x, y, theta, command_v, command_omega; `period_s` static), so
`shoal diagnose run.rrd --robot N` is tried on a file another tool wrote.

Usage: python3 write_rrd.py RUN_FOLDER OUT.rrd ROBOT_ID
"""

import csv
import sys

import numpy as np
import rerun as rr


def rows(path):
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def main():
    folder, out, robot = sys.argv[1], sys.argv[2], int(sys.argv[3])
    commands = rows(f"{folder}/commands.csv")
    poses = rows(f"{folder}/poses.csv")
    rr.init("another-tool", recording_id="written-by-the-python-sdk")
    rr.save(out)
    # Each pose carries the command held over the period that ended at it.
    period = 0.1
    rr.log("robots/motion", rr.AnyValues(period_s=np.array([period])), static=True)
    held = 0
    for pose in poses:
        while held + 1 < len(commands) and commands[held + 1]["t"] <= pose["t"] - period:
            held += 1
        command = commands[held]
        rr.set_time("sim_time", duration=pose["t"])
        rr.log(
            "robots/motion",
            rr.AnyValues(
                agent_id=np.array([robot], dtype=np.uint32),
                x=np.array([pose["x"]]),
                y=np.array([pose["y"]]),
                theta=np.array([pose["theta"]]),
                command_v=np.array([command["v"]]),
                command_omega=np.array([command["omega"]]),
            ),
        )


if __name__ == "__main__":
    main()

"""Writes one robot of an MRCLAM dataset folder as a lab with Vicon has it
(MRCLAM's ground truth came from a Vicon system): the trial exported from
Nexus as CSV (a `Segments` section, then a `Trajectories` section of
markers, each a name line, the rate, a row of subjects over their columns,
`Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ`, the units, then a frame a row; CRLF
line ends), and the commands logged on the trial's clock (`commands.csv`,
`t,v,omega`, seconds from its first frame).

As Nexus writes it: Z up, millimetres, a segment's rotation as helical
angles in degrees (its axis scaled by its angle). Frames are numbered at
the capture's 100 Hz from 1, each pose interpolated to its frame's time
between the dataset's poses either side (the dataset's times are a PC's,
a few milliseconds off the capture's frames).
The robot's segment was defined with the robot facing Vicon's -X, so the
segment's X axis points behind the robot (its heading in the file is half a
turn off the way it drives). Beside it: a second subject (a dock that
stands still), and frames where the robot was lost written with empty
cells.

Usage: python3 write_vicon_csv.py MRCLAM_FOLDER ROBOT TO_FOLDER
"""

import csv
import math
import sys

from write_motive_csv import truth_and_commands

RATE = 100


def helical(yaw, roll):
    """The rotation `yaw` about Z after a small `roll` about the body's X,
    as its axis scaled by its angle, in degrees."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    # (0, 0, sy, cy) * (sr, 0, 0, cr), as x, y, z, w.
    x, y, z, w = cy * sr, sy * sr, sy * cr, cy * cr
    angle = 2 * math.atan2(math.sqrt(x * x + y * y + z * z), w)
    norm = math.sqrt(x * x + y * y + z * z) or 1.0
    return [math.degrees(angle) * c / norm for c in (x, y, z)]


def main():
    source, robot, target = sys.argv[1], sys.argv[2], sys.argv[3]
    truth, start = truth_and_commands(source, robot, target)

    subject = f"Robot{robot}:Robot{robot}"
    with open(f"{target}/trial.csv", "w", newline="") as f:
        out = csv.writer(f, lineterminator="\r\n")
        out.writerow(["Segments"])
        out.writerow([RATE])
        out.writerow(["", "", "Dock:Dock", "", "", "", "", "", subject, "", "", "", "", ""])
        out.writerow(["Frame", "Sub Frame"] + ["RX", "RY", "RZ", "TX", "TY", "TZ"] * 2)
        out.writerow(["", ""] + ["deg", "deg", "deg", "mm", "mm", "mm"] * 2)
        dock = ["0", "0", "12.5", "500", "-400", "85"]
        frames = int((truth[-1][0] - start) * RATE) + 1
        j = 0
        theta_unwrapped = [truth[0][3]]
        for k in range(1, len(truth)):
            step = (truth[k][3] - truth[k - 1][3] + math.pi) % (2 * math.pi) - math.pi
            theta_unwrapped.append(theta_unwrapped[-1] + step)
        for k in range(frames):
            t = start + k / RATE
            while j + 2 < len(truth) and truth[j + 1][0] <= t:
                j += 1
            (t0, x0, y0, _), (t1, x1, y1, _) = truth[j], truth[j + 1]
            share = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
            x, y = x0 + share * (x1 - x0), y0 + share * (y1 - y0)
            theta = theta_unwrapped[j] + share * (theta_unwrapped[j + 1] - theta_unwrapped[j])
            if k % 997 == 500:
                # Occluded: the robot's cells empty, as Nexus leaves them.
                robot_cells = [""] * 6
            else:
                rotation = helical(theta + math.pi, 0.004 * math.sin(k / 50))
                robot_cells = [f"{v:.5f}" for v in rotation] + [
                    f"{x * 1000:.5f}",
                    f"{y * 1000:.5f}",
                    f"{120 + 0.3 * math.sin(k / 70):.5f}",
                ]
            out.writerow([k + 1, 0] + dock + robot_cells)
        out.writerow([])
        out.writerow(["Trajectories"])
        out.writerow([RATE])
        out.writerow(["", "", f"Robot{robot}:M1", "", ""])
        out.writerow(["Frame", "Sub Frame", "X", "Y", "Z"])
        out.writerow(["", "", "mm", "mm", "mm"])
        for frame in range(1, 101):
            out.writerow([frame, 0, "1510.2", "2.1", "150.0"])


if __name__ == "__main__":
    main()

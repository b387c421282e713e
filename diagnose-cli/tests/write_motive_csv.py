"""Writes one robot of an MRCLAM dataset folder as a lab with OptiTrack has
it: the take exported from Motive as CSV (format 1.23, the layout Motive
writes: a line of the take's settings, a blank line, rows naming each
column's type, body, ID and measure, the axis row, then a frame a row, CRLF
line ends), and the commands logged on the take's clock (`commands.csv`,
`t,v,omega`, seconds from the take's start).

The export is as Motive writes it by default: Y up (the floor is X and Z;
the dataset's y is Motive's -Z), millimetres, quaternions. The robot's rigid
body was defined with the robot facing Motive's -X, so the body's X axis
points to the robot's right (its heading in the file is a quarter turn off
the way it drives). Beside it: a second rigid body (a charging dock that
stands still), the robot's three rigid-body markers, one unlabelled marker,
and the frames where the robot was not tracked written with empty cells.

Usage: python3 write_motive_csv.py MRCLAM_FOLDER ROBOT TO_FOLDER
"""

import csv
import math
import sys


def rows(path):
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                yield [float(v) for v in line.split()]


def truth_and_commands(source, robot, target):
    """The robot's ground truth rows, and their first time; its commands
    written to `commands.csv` in seconds from that time (the capture's
    clock)."""
    truth = list(rows(f"{source}/Robot{robot}_Groundtruth.dat"))
    start = truth[0][0]
    with open(f"{target}/commands.csv", "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["t", "v", "omega"])
        for t, v, omega in rows(f"{source}/Robot{robot}_Odometry.dat"):
            out.writerow([f"{t - start:.3f}", v, omega])
    return truth, start


def quaternion_about_y(angle, roll):
    """A turn of `angle` about Y (up), after a small `roll` about the body's X."""
    cy, sy = math.cos(angle / 2), math.sin(angle / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    # (0, sy, 0, cy) * (sr, 0, 0, cr), as x, y, z, w.
    return (cy * sr, sy * cr, -sy * sr, cy * cr)


def main():
    source, robot, target = sys.argv[1], sys.argv[2], sys.argv[3]
    truth, start = truth_and_commands(source, robot, target)

    body = f"Robot{robot}"
    columns = (
        [("Rigid Body", "Dock", "1", "Rotation", a) for a in "XYZW"]
        + [("Rigid Body", "Dock", "1", "Position", a) for a in "XYZ"]
        + [("Rigid Body", "Dock", "1", "Mean Marker Error", "")]
        + [("Rigid Body", body, "2", "Rotation", a) for a in "XYZW"]
        + [("Rigid Body", body, "2", "Position", a) for a in "XYZ"]
        + [("Rigid Body", body, "2", "Mean Marker Error", "")]
        + [
            ("Rigid Body Marker", f"{body}:Marker{m}", f"2:{m}", "Position", a)
            for m in (1, 2, 3)
            for a in "XYZ"
        ]
        + [("Marker", "Unlabeled 1001", "1001", "Position", a) for a in "XYZ"]
    )
    with open(f"{target}/take.csv", "w", newline="") as f:
        out = csv.writer(f, lineterminator="\r\n")
        out.writerow([
            "Format Version", "1.23", "Take Name", "Take 2009-07-24 02.09.35 PM",
            "Take Notes", "", "Capture Frame Rate", "100.000000",
            "Export Frame Rate", "100.000000", "Capture Start Time",
            "2009-07-24 02.09.35.103 PM", "Total Frames in Take", str(len(truth)),
            "Total Exported Frames", str(len(truth)), "Rotation Type", "Quaternion",
            "Length Units", "Millimeters", "Coordinate Space", "Global",
        ])
        out.writerow([])
        for k, label in ((0, "Type"), (1, "Name"), (2, "ID")):
            out.writerow(["", label] + [c[k] for c in columns])
        out.writerow(["", ""] + [c[3] for c in columns])
        out.writerow(["Frame", "Time (Seconds)"] + [c[4] for c in columns])
        dock = ["0.000000", "0.000000", "0.000000", "1.000000", "500.000000", "85.000000", "-400.000000", "0.000210"]
        for frame, (t, x, y, theta) in enumerate(truth):
            row = [str(frame), f"{t - start:.6f}"] + dock
            if frame % 997 == 500:
                # Occluded: the robot's cells empty, as Motive leaves them.
                row += [""] * 8 + [""] * 9
            else:
                q = quaternion_about_y(theta - math.pi / 2, 0.004 * math.sin(frame / 50))
                position = (x * 1000, 120.0 + 0.3 * math.sin(frame / 70), -y * 1000)
                row += [f"{v:.6f}" for v in q] + [f"{v:.6f}" for v in position] + ["0.000350"]
                for m in range(3):
                    angle = theta + 2 * math.pi * m / 3
                    row += [
                        f"{position[0] + 60 * math.cos(angle):.6f}",
                        f"{position[1] + 30:.6f}",
                        f"{position[2] - 60 * math.sin(angle):.6f}",
                    ]
            row += ["" if frame % 3 else "1510.2", "" if frame % 3 else "2.1", "" if frame % 3 else "-880.7"]
            out.writerow(row)


if __name__ == "__main__":
    main()

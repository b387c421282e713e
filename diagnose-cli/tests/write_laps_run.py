"""Writes a run as another lab records one: a differential-drive robot
driving laps of a taped course (a figure eight or an oval) under a
pure-pursuit controller that slows in the curves, tracked by motion
capture. The physics is written here, wheel by wheel, and none of it is
Shoal's code: on a course the robot turns at the same places every lap, so
what it does in turns and what the floor there does to it are confounded
unless the method keeps them apart.

Usage: python3 write_laps_run.py OUT_FOLDER SEED [key=value ...]
  course=eight       eight (two 1.2 m circles, both turn directions) or
                     oval (3 m straights, 1 m ends, always to the left)
  duration=600       seconds
  delay=0            the drive acts on the command of this long ago, s
  lag=0              each wheel follows its set speed as a first-order
                     lag with this time constant, s (motor dynamics)
  radius_scale=1     both wheels' true radius over the nominal
  track_scale=1      the wheels' effective track over the nominal (tyres
                     that scrub turn less: the turn rate over this)
  wheel_ratio=1      the right wheel's radius over the left's (the body
                     turns a little per metre driven)
  fade=0             both wheels lose this share of speed per minute
  mud=x0,y0,x1,y1,f  inside the rectangle both wheels turn f times as
                     fast (a patch of carpet across the course)
  marker=f,l         the tracked marker sits f m ahead of and l m left of
                     the axle's middle
  slow_noise=0.04    each wheel's slow noise (0.5 s), a share of its speed
  fast_noise=0.05    each wheel's fast noise, a share of its speed per 10 ms
  steer=closed       closed: the controller steers on where the robot is;
                     open: on where its commands alone would take it
  pose_phase=random  the first frame's time, s (0: frames at the commands'
                     times, so that no segment end is interpolated)
"""

import math
import random
import sys

from write_euler_run import write_run

TRACK_M = 0.2
STEP_S = 0.002
COMMAND_PERIOD_S = 0.05
POSE_PERIOD_S = 0.01
LOOKAHEAD_M = 0.45


def course_points(course):
    """The taped course as a closed polyline, 1 cm apart."""
    points = []
    if course == "eight":
        r = 1.2
        # Two circles tangent at the origin: the left one counter-clockwise,
        # the right one clockwise, so the robot turns both ways every lap.
        n = int(2 * math.pi * r / 0.01)
        for i in range(n):
            a = 2 * math.pi * i / n
            points.append((-r + r * math.cos(a), r * math.sin(a)))
        for i in range(n):
            a = math.pi - 2 * math.pi * i / n
            points.append((r + r * math.cos(a), r * math.sin(a)))
    elif course == "oval":
        half, r = 1.5, 1.0
        for i in range(int(2 * half / 0.01)):
            points.append((-half + 0.01 * i, -r))
        n = int(math.pi * r / 0.01)
        for i in range(n):
            a = -math.pi / 2 + math.pi * i / n
            points.append((half + r * math.cos(a), r * math.sin(a)))
        for i in range(int(2 * half / 0.01)):
            points.append((half - 0.01 * i, r))
        for i in range(n):
            a = math.pi / 2 + math.pi * i / n
            points.append((-half + r * math.cos(a), r * math.sin(a)))
    else:
        sys.exit(f"write_laps_run.py: unknown course {course!r} (eight or oval)")
    return points


def pursue(points, nearest, x, y, theta):
    """Pure pursuit: the index nearest the robot (searched forward from the
    last), and the curvature of the arc to the point a lookahead ahead."""
    n = len(points)
    best, best_d = nearest, float("inf")
    for k in range(nearest, nearest + 60):
        px, py = points[k % n]
        d = (px - x) ** 2 + (py - y) ** 2
        if d < best_d:
            best, best_d = k % n, d
    goal = best
    while True:
        gx, gy = points[goal % n]
        if math.hypot(gx - x, gy - y) >= LOOKAHEAD_M:
            break
        goal += 1
    dx, dy = gx - x, gy - y
    local_y = -math.sin(theta) * dx + math.cos(theta) * dy
    return best, 2 * local_y / (dx * dx + dy * dy)


def arc(pose, speed, turn, dt=STEP_S):
    """The pose after driving `speed` and `turn` for `dt`, on the exact arc."""
    x, y, theta = pose
    if abs(turn) > 1e-9:
        x += speed / turn * (math.sin(theta + turn * dt) - math.sin(theta))
        y -= speed / turn * (math.cos(theta + turn * dt) - math.cos(theta))
    else:
        x += speed * math.cos(theta) * dt
        y += speed * math.sin(theta) * dt
    return [x, y, theta + turn * dt]


def main():
    out, seed = sys.argv[1], int(sys.argv[2])
    opts = dict(a.split("=", 1) for a in sys.argv[3:])
    course = opts.get("course", "eight")
    duration = float(opts.get("duration", "600"))
    delay = float(opts.get("delay", "0"))
    lag = float(opts.get("lag", "0"))
    radius_scale = float(opts.get("radius_scale", "1"))
    track_scale = float(opts.get("track_scale", "1"))
    wheel_ratio = float(opts.get("wheel_ratio", "1"))
    fade = float(opts.get("fade", "0"))
    mud = [float(v) for v in opts["mud"].split(",")] if "mud" in opts else None
    marker = [float(v) for v in opts["marker"].split(",")] if "marker" in opts else [0.0, 0.0]
    slow_noise = float(opts.get("slow_noise", "0.04"))
    fast_noise = float(opts.get("fast_noise", "0.05"))
    open_loop = opts.get("steer", "closed") == "open"
    rng = random.Random(seed)

    points = course_points(course)
    start = rng.randrange(len(points))
    x, y = points[start]
    nx, ny = points[(start + 1) % len(points)]
    theta = math.atan2(ny - y, nx - x) + rng.gauss(0, 0.1)
    nearest = start
    # Where the commands alone take the robot: what an open-loop controller
    # steers on.
    plan = [x, y, theta]

    # Each lap at its own pace; now and then the operator stops the robot.
    lap_speed = rng.uniform(0.15, 0.4)
    travelled_on_lap = 0.0
    lap_length = 0.01 * len(points)
    pause_until = 0.0

    commands = []
    poses = []
    left = right = 0.0
    # Wheel noise: a slow part (the floor under each wheel, 0.5 s) and a
    # fast one, both in proportion to the wheel's speed.
    slow = [0.0, 0.0]
    next_pose = rng.uniform(0, POSE_PERIOD_S)
    if "pose_phase" in opts:
        next_pose = float(opts["pose_phase"])
    for i in range(int(duration / STEP_S)):
        t = i * STEP_S
        if len(commands) * COMMAND_PERIOD_S <= t + 1e-9:
            now = len(commands) * COMMAND_PERIOD_S
            seen = plan if open_loop else (x, y, theta)
            nearest, curvature = pursue(points, nearest, *seen)
            if now < pause_until:
                v = w = 0.0
            else:
                v = lap_speed / (1 + 0.8 * abs(curvature))
                w = v * curvature
            commands.append((now, v, w))
        # The drive acts on the command of `delay` ago.
        k = min(int(max(0.0, t - delay) / COMMAND_PERIOD_S + 1e-9), len(commands) - 1)
        _, v_set, w_set = commands[k]
        set_left = (v_set - w_set * TRACK_M / 2) * (1 - fade * t / 60)
        set_right = (v_set + w_set * TRACK_M / 2) * (1 - fade * t / 60)
        if lag > 0:
            keep = math.exp(-STEP_S / lag)
            left = keep * left + (1 - keep) * set_left
            right = keep * right + (1 - keep) * set_right
        else:
            left, right = set_left, set_right
        if mud and mud[0] <= x <= mud[2] and mud[1] <= y <= mud[3]:
            floor = mud[4]
        else:
            floor = 1.0
        noisy = []
        for wheel, speed in enumerate((left, right)):
            keep = math.exp(-STEP_S / 0.5)
            slow[wheel] = keep * slow[wheel] + math.sqrt(1 - keep * keep) * slow_noise * rng.gauss(0, 1)
            fast = fast_noise * math.sqrt(0.01 / STEP_S) * rng.gauss(0, 1)
            noisy.append(speed * (1 + slow[wheel] + fast) * floor)
        rl = radius_scale * 2 / (1 + wheel_ratio)
        rr = rl * wheel_ratio
        vl, vr = noisy[0] * rl, noisy[1] * rr
        speed = (vl + vr) / 2
        turn = (vr - vl) / (TRACK_M * track_scale)
        plan = arc(plan, (set_left + set_right) / 2, (set_right - set_left) / TRACK_M)
        before = (x, y, theta)
        x, y, theta = arc(before, speed, turn)
        travelled_on_lap += abs(speed) * STEP_S
        if travelled_on_lap > lap_length:
            travelled_on_lap = 0.0
            lap_speed = rng.uniform(0.15, 0.4)
            if rng.random() < 0.3:
                pause_until = t + rng.uniform(1.0, 4.0)
        while next_pose <= t + STEP_S:
            if rng.random() > 0.01:
                # The body where it was at the frame's instant, within the step.
                bx, by, bt = arc(before, speed, turn, next_pose - t)
                mx = bx + marker[0] * math.cos(bt) - marker[1] * math.sin(bt)
                my = by + marker[0] * math.sin(bt) + marker[1] * math.cos(bt)
                heading = (bt + 0.004 * rng.gauss(0, 1) + math.pi) % (2 * math.pi) - math.pi
                poses.append((next_pose, mx + 0.001 * rng.gauss(0, 1),
                              my + 0.001 * rng.gauss(0, 1), heading))
            next_pose += POSE_PERIOD_S

    write_run(out, commands, poses)


if __name__ == "__main__":
    main()

"""Writes a run as another lab's simulator would: a differential-drive
robot integrated by forward Euler (x += v cos(theta) dt), noise on each
wheel's speed, a teleoperator whose commands ramp, and the simulator's
state published at 30 Hz, stamped with the state's time. None of it is
Shoal's code: `shoal diagnose` must tell how this recording was made
(a simulator's step) from the body's physics.

Usage: python3 write_euler_run.py OUT_FOLDER SEED [key=value ...]
  step=0.05          the simulator's integration step, seconds
  radius_scale=1.0   true wheel radius over the nominal (speed and turn)
  delay=0.0          actuation delay, seconds
  scheme=forward     forward (x by the old heading, then turn) or
                     semi-implicit (turn, then x by the new heading)
  duration=600       seconds
  teleop=steady      steady (a command every 50 ms) or sparse (only when
                     the command changes, as a keyboard teleop publishes)
  timeout=0          the drive stops when no command has come for this
                     long (ros2_control's cmd_vel_timeout); 0: it holds
  top_speed=0        the drive clamps commanded speeds above this, m/s
                     (a TurtleBot3 Burger's firmware: 0.22); 0: none
"""

import bisect
import math
import os
import random
import sys

WHEEL_BASE_M = 0.16
COMMAND_PERIOD_S = 0.05
POSE_HZ = 30.0
WHEEL_NOISE = 0.03  # relative, per 10 ms


def main():
    out, seed = sys.argv[1], int(sys.argv[2])
    opts = dict(a.split("=", 1) for a in sys.argv[3:])
    step = float(opts.get("step", "0.05"))
    radius_scale = float(opts.get("radius_scale", "1.0"))
    delay = float(opts.get("delay", "0.0"))
    duration = float(opts.get("duration", "600"))
    semi_implicit = opts.get("scheme", "forward") == "semi-implicit"
    sparse = opts.get("teleop", "steady") == "sparse"
    timeout = float(opts.get("timeout", "0"))
    top_speed = float(opts.get("top_speed", "0"))
    rng = random.Random(seed)

    x = y = 0.0
    theta = rng.uniform(-math.pi, math.pi)
    target_v = target_w = v_cmd = w_cmd = 0.0
    change_at = 0.0
    commands, poses = [], []
    # What the recorder saw: every command, or only the changes.
    published = []
    next_pose = 0.0
    for i in range(int(duration / step)):
        t = i * step
        # The teleoperator: a new target every 1-4 s, pauses, a way home.
        while len(commands) * COMMAND_PERIOD_S <= t + 1e-9:
            now = len(commands) * COMMAND_PERIOD_S
            pressed = now >= change_at
            if pressed:
                if math.hypot(x, y) > 2.0:
                    home = math.atan2(-y, -x)
                    error = (home - theta + math.pi) % (2 * math.pi) - math.pi
                    target_v, target_w = 0.15, max(-1.0, min(1.0, 2.0 * error))
                    change_at = now + 0.5
                elif rng.random() < 0.1:
                    target_v = target_w = 0.0
                    change_at = now + rng.uniform(1, 3)
                else:
                    target_v, target_w = rng.uniform(0.05, 0.35), rng.uniform(-1, 1)
                    change_at = now + rng.uniform(1, 4)
            v_cmd += max(-0.02, min(0.02, target_v - v_cmd))
            w_cmd += max(-0.1, min(0.1, target_w - w_cmd))
            # A sparse teleop publishes on a key press and while the
            # command ramps, not while it holds.
            if not sparse or pressed or published[-1][1:] != (v_cmd, w_cmd):
                published.append((now, v_cmd, w_cmd))
            commands.append((now, v_cmd, w_cmd))
        # The drive executes the command of `delay` ago, wheel by wheel.
        k = min(int(max(0.0, t - delay) / COMMAND_PERIOD_S + 1e-9), len(commands) - 1)
        _, v, w = commands[k]
        heard = bisect.bisect_right(published, (commands[k][0] + 1e-9,))
        if timeout > 0 and t - delay - published[heard - 1][0] > timeout:
            v = w = 0.0
        if top_speed > 0:
            v = max(-top_speed, min(top_speed, v))
        noise = WHEEL_NOISE / math.sqrt(step / 0.01)
        left = (v - w * WHEEL_BASE_M / 2) * (1 + noise * rng.gauss(0, 1)) * radius_scale
        right = (v + w * WHEEL_BASE_M / 2) * (1 + noise * rng.gauss(0, 1)) * radius_scale
        speed, turn = (left + right) / 2, (right - left) / WHEEL_BASE_M
        if semi_implicit:
            theta += turn * step
        x += speed * math.cos(theta) * step
        y += speed * math.sin(theta) * step
        if not semi_implicit:
            theta += turn * step
        if t + step >= next_pose - 1e-9:
            poses.append((t + step, x + 0.003 * rng.gauss(0, 1),
                          y + 0.003 * rng.gauss(0, 1), theta + 0.01 * rng.gauss(0, 1)))
            next_pose = max(next_pose + 1 / POSE_HZ, t + step + 1e-9)

    write_run(out, published, poses)


def write_run(out, commands, poses):
    """Writes `commands` (t, v, omega) and `poses` (t, x, y, theta) as the
    run folder `shoal diagnose` reads: commands.csv and poses.csv."""
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "commands.csv"), "w") as f:
        f.write("t,v,omega\n")
        f.writelines(f"{t:.3f},{v:.6f},{w:.6f}\n" for t, v, w in commands)
    with open(os.path.join(out, "poses.csv"), "w") as f:
        f.write("t,x,y,theta\n")
        f.writelines(f"{t:.4f},{a:.6f},{b:.6f},{c:.6f}\n" for t, a, b, c in poses)


if __name__ == "__main__":
    main()

"""Reads a running swarm's roster with the official Python iceoryx2 client.

Usage: read_roster.py SWARM SECONDS -> prints {"robots": {id: [x, y, tick]}} as JSON.
"""

import json
import pathlib
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "python"))

import iceoryx2 as iox2  # noqa: E402
from shoal_wire import Pose  # noqa: E402


def main(swarm: str, seconds: float) -> None:
    iox2.set_log_level_from_env_or(iox2.LogLevel.Error)
    node = iox2.NodeBuilder.new().create(iox2.ServiceType.Ipc)
    service = (
        node.service_builder(iox2.ServiceName.new(f"shoal/{swarm}/roster"))
        .publish_subscribe(Pose)
        .open()
    )
    subscriber = service.subscriber_builder().create()
    robots = {}
    deadline = time.time() + seconds
    while time.time() < deadline:
        while True:
            sample = subscriber.receive()
            if sample is None:
                break
            pose = sample.payload().contents
            robots[pose.agent_id] = [pose.x, pose.y, pose.tick]
        time.sleep(0.02)
    print(json.dumps({"robots": robots}))


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))

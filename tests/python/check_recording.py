"""Reads a Shoal recording with the official Rerun reader and prints what it holds as JSON.

Usage: check_recording.py RECORDING.rrd

Prints {"entities": [...], "ticks": N, "max_sim_time": S, "robots": [...],
"poses": {"<id>@<tick>": [x, y], ...}, "events": [...],
"slam_rows": {"<entity>": rows logged},
"motion": {"<id>@<tick>": [x, y, theta, command_v, command_omega]}, "period_s": P,
"hosts": {"<id>": host it was last tagged with}}
(motion: the rows `shoal diagnose run.rrd --robot N` reads).
"""

import json
import sys

import rerun.experimental as rrx


def main(path: str) -> None:
    entities = set()
    ticks = set()
    robots = set()
    poses = {}
    events = []
    max_sim_time = 0.0
    slam_rows = {}
    motion = {}
    period_s = None
    hosts = {}
    for chunk in rrx.RrdReader(path).stream().to_chunks():
        entities.add(chunk.entity_path)
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if chunk.entity_path == "/world/robots/true":
            tick_column = batch.column(names.index("tick")).to_pylist()
            sim_times = batch.column(names.index("sim_time")).to_pylist()
            positions = batch.column(names.index("Points2D:positions")).to_pylist()
            labels = batch.column(names.index("Points2D:labels")).to_pylist()
            for tick, sim_time, row_positions, row_labels in zip(tick_column, sim_times, positions, labels):
                ticks.add(tick)
                if sim_time is not None:
                    # Durations come back as timedelta-like or nanoseconds depending on pyarrow.
                    seconds = sim_time.total_seconds() if hasattr(sim_time, "total_seconds") else sim_time / 1e9
                    max_sim_time = max(max_sim_time, seconds)
                for position, label in zip(row_positions, row_labels):
                    robots.add(int(label))
                    poses[f"{label}@{tick}"] = position
        if chunk.entity_path == "/robots/motion":
            if "period_s" in names:
                period_s = batch.column(names.index("period_s")).to_pylist()[0][0]
            if "agent_id" in names:
                columns = [batch.column(names.index(n)).to_pylist() for n in ("tick", "agent_id", "x", "y", "theta", "command_v", "command_omega")]
                for tick, ids, xs, ys, thetas, vs, omegas in zip(*columns):
                    for i, robot in enumerate(ids):
                        motion[f"{robot}@{tick}"] = [xs[i], ys[i], thetas[i], vs[i], omegas[i]]
        if chunk.entity_path.startswith("/world/slam/") or chunk.entity_path.startswith("/slam/"):
            slam_rows[chunk.entity_path] = slam_rows.get(chunk.entity_path, 0) + batch.num_rows
        parts = chunk.entity_path.strip("/").split("/")
        if len(parts) == 3 and parts[0] == "robots" and parts[2] == "host":
            texts = [n for n in names if n.endswith(":text")]
            for row in batch.column(names.index(texts[0])).to_pylist():
                hosts[parts[1]] = row[0] if isinstance(row, list) else row
        if chunk.entity_path == "/events":
            texts = [n for n in names if n.endswith(":text")]
            if texts:
                for row in batch.column(names.index(texts[0])).to_pylist():
                    events.extend(row if isinstance(row, list) else [row])
    print(
        json.dumps(
            {
                "entities": sorted(entities),
                "ticks": len(ticks),
                "max_sim_time": max_sim_time,
                "robots": sorted(robots),
                "poses": poses,
                "events": [e for e in events if e is not None],
                "slam_rows": slam_rows,
                "motion": motion,
                "period_s": period_s,
                "hosts": hosts,
            }
        )
    )


if __name__ == "__main__":
    main(sys.argv[1])

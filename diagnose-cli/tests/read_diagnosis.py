"""Reads a `shoal diagnose --rrd` recording with the official Rerun reader.

Usage: read_diagnosis.py RECORDING.rrd

Prints {"entities": {path: rows}, "scalars": {path: [values]},
"report": text, "strip_points": {path: points in its first row}} as JSON.
"""

import json
import sys

import rerun.experimental as rrx


def main(path: str) -> None:
    entities = {}
    scalars = {}
    strip_points = {}
    report = ""
    for chunk in rrx.RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        names = batch.schema.names
        entity = chunk.entity_path
        entities[entity] = entities.get(entity, 0) + batch.num_rows
        if "Scalars:scalars" in names:
            for row in batch.column(names.index("Scalars:scalars")).to_pylist():
                if row:
                    scalars.setdefault(entity, []).extend(row)
        if "LineStrips2D:strips" in names and entity not in strip_points:
            rows = batch.column(names.index("LineStrips2D:strips")).to_pylist()
            if rows and rows[0]:
                strip_points[entity] = len(rows[0][0])
        if "TextDocument:text" in names:
            for row in batch.column(names.index("TextDocument:text")).to_pylist():
                if row:
                    report += "".join(row)
    print(json.dumps({"entities": entities, "scalars": scalars, "report": report, "strip_points": strip_points}))


if __name__ == "__main__":
    main(sys.argv[1])

"""Leaves a rosbag2 sqlite3 bag as a recorder in WAL mode (rosbag2's
"resilient" storage preset) leaves it when killed: the last messages
written and committed, but only into the `-wal` file beside the bag, never
checkpointed into it.

Usage: kill_wal_recorder.py BAG.db3 OUT.db3 SHARE

Copies BAG.db3 to OUT.db3 without its last SHARE of messages (by time),
then writes them back in WAL mode and exits without closing the database,
as a killed process does.
"""

import os
import shutil
import sqlite3
import sys


def main(bag, out, share):
    shutil.copy(bag, out)
    db = sqlite3.connect(out)
    total = db.execute("SELECT COUNT(*) FROM messages").fetchone()[0]
    kept = total - int(total * float(share))
    last = db.execute(
        "SELECT id, topic_id, timestamp, data FROM messages ORDER BY timestamp, id LIMIT -1 OFFSET ?",
        (kept,),
    ).fetchall()
    db.execute("DELETE FROM messages WHERE id IN (SELECT id FROM messages ORDER BY timestamp, id LIMIT -1 OFFSET ?)", (kept,))
    db.commit()
    db.execute("VACUUM")
    db.execute("PRAGMA journal_mode=WAL")
    db.execute("PRAGMA wal_autocheckpoint=0")
    db.executemany("INSERT INTO messages (id, topic_id, timestamp, data) VALUES (?, ?, ?, ?)", last)
    db.commit()
    sys.stdout.flush()
    # Killed: no close, no checkpoint; the rows are only in OUT.db3-wal.
    os._exit(0)


if __name__ == "__main__":
    main(*sys.argv[1:])

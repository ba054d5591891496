"""Reading a mission record: the file opened read-only and checked to be one (docs/record.md)."""

from __future__ import annotations

import sqlite3
from pathlib import Path

APPLICATION_ID = 0x45563352  # "EV3R", PRAGMA application_id of a record
SCHEMA = 3                   # the schema this package reads
TABLES = ("robots", "states", "commands", "reports", "reports_missing", "epochs")


class NotARecord(Exception):
    """The file is not a mission record this package can read (the message says why)."""


def open_record(path: str | Path) -> sqlite3.Connection:
    """The record at @path, read-only (the master may be writing it: WAL lets both run)."""
    p = Path(path)
    if not p.is_file():
        raise NotARecord(f"{p}: no such file")
    try:
        db = sqlite3.connect(f"file:{p}?mode=ro", uri=True)
        app = db.execute("PRAGMA application_id").fetchone()[0]
        version = db.execute("PRAGMA user_version").fetchone()[0]
    except sqlite3.DatabaseError as e:
        raise NotARecord(f"{p} is not a record: {e}") from None
    if app != APPLICATION_ID:
        db.close()
        raise NotARecord(f"{p} is not an ev3-master record (application_id {app}, not {APPLICATION_ID})")
    if version != SCHEMA:
        db.close()
        hint = " (an ev3-master of this version migrates it: run it once with --db on the file)" \
            if version < SCHEMA else ""
        raise NotARecord(f"{p} has schema {version}; this ev3-fleet reads schema {SCHEMA}{hint}")
    return db

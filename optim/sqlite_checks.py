"""SQLite files checked before they are trusted: row checksums, link checks, time-limited read-only
connections (issue 37). Shared by the run recorder and the evaluation cache."""

from __future__ import annotations

import hashlib
import json
import sqlite3
import time
from pathlib import Path
from typing import Any

from hapticopt.design import paths

#: the SQLite files beside a database (all opened by SQLite with links followed)
SIDE_FILES = ("", "-wal", "-shm", "-journal")
#: longest time a reading query may run [s] (a recursive view must not hang a reader)
READ_LIMIT_S = 5.0


def row_checksum(*fields: Any) -> str:
    """SHA-256 of a row's stored fields (the texts as stored: exact, no float re-serialisation)."""
    return hashlib.sha256(json.dumps(list(fields), separators=(",", ":")).encode()).hexdigest()


def check_db_paths(path: str | Path) -> None:
    """Refuse a database whose file or SQLite side files (``-wal``, ``-shm``, ``-journal``) are links."""
    for suffix in SIDE_FILES:
        paths.no_links(str(path) + suffix)


def connect_readonly(path: str | Path, *, limit_s: float = READ_LIMIT_S) -> sqlite3.Connection:
    """A read-only connection (``mode=ro``: never writes, never creates tables) whose statements are
    interrupted (``sqlite3.OperationalError: interrupted``) once the connection has run SQL for
    ``limit_s`` since :func:`restart_clock` (called here and by readers before each query)."""
    db = sqlite3.connect(f"{Path(path).resolve().as_uri()}?mode=ro", uri=True, timeout=5.0, check_same_thread=False,
                         factory=_TimedConnection)
    db.limit_s = limit_s
    restart_clock(db)
    db.set_progress_handler(lambda: int(time.monotonic() > db.deadline), 10_000)
    return db


class _TimedConnection(sqlite3.Connection):
    limit_s = READ_LIMIT_S
    deadline = 0.0


def restart_clock(db: sqlite3.Connection) -> None:
    """Give the next queries of a :func:`connect_readonly` connection their full time limit again."""
    if isinstance(db, _TimedConnection):
        db.deadline = time.monotonic() + db.limit_s

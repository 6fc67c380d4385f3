"""The run recorder: every evaluation written as it happens to SQLite in the run directory.

``DIR/evaluations.sqlite`` in WAL mode, one transaction per evaluation (design vector,
metrics JSON, gradients, timings, outcome). ``--resume`` re-opens it: because the optimiser is
deterministic (same problem, same seed), it asks the same points in the same order, and each
one found here under its exact key (the float64 bit patterns of the vector, the fidelity and
whether a gradient was computed) is replayed without running an evaluator.

A run is never destroyed silently: opening an existing record without ``resume`` is refused
unless ``force`` (:func:`check_run_dir`). ``search_fingerprint`` leaves the budget out (max_evals,
max_time_s), so ``--resume --max-evals N`` extends a run: nlopt asks the same points first
(replayed), then continues; the recorder counts any point evaluated again (``repeated``).

The record describes itself (additive tables, created ``IF NOT EXISTS``): ``run_info`` (kind,
problem text, variables with units and bounds, objectives and constraints with senses and
bounds, software versions, status), ``designs`` (baseline and final-fidelity rows) and
``session_counts`` (per session: budget, evaluated, replayed, repeated). Read it with
:class:`hapticopt.optim.runs.RunReader`, which never writes.

A record is checked before it is trusted (issue 37): ``meta`` names the application and the schema
version (:data:`APPLICATION`, :data:`SCHEMA`) beside the run's fingerprint (the problem/design
hash); every evaluation and stage row carries the SHA-256 of its content (:func:`row_checksum`).
``--resume`` first opens the file read-only (:func:`inspect_record`): a foreign database (no
hapticopt ``meta``, views or triggers, a newer schema) or a row whose checksum does not match is
refused in one line and left unmodified. Rows of records older than the checksums carry none.
Every path the record opens (the file, ``-wal``, ``-shm``, ``-journal``, the lock) is checked for
links first (:mod:`hapticopt.design.paths`).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import sqlite3
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from hapticopt.analysis.status import upgrade
from hapticopt.design import paths
from hapticopt.design.errors import InputFileError, InvalidInput
from hapticopt.optim.evaluation import Outcome, PointResult
from hapticopt.optim.sqlite_checks import check_db_paths, connect_readonly, row_checksum

FILENAME = "evaluations.sqlite"
#: ``meta.application`` of a hapticopt run record
APPLICATION = "hapticopt run record"
#: ``meta.schema``: 2 = rows carry checksums (records without ``schema`` are version 1)
SCHEMA = 2


#: FULL: a commit is on disk (WAL fsynced) before :meth:`Recorder.record` returns, so an evaluation
#: recorded survives power loss as well as a killed process (NORMAL survives only the latter).
SYNCHRONOUS = "FULL"


class RecorderError(OSError):
    """The run database could not be written (disk full, read-only, I/O error): the SQLite reason."""

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS stages (name TEXT PRIMARY KEY, payload TEXT NOT NULL, created REAL NOT NULL,
                                   checksum TEXT);
CREATE TABLE IF NOT EXISTS sessions (id INTEGER PRIMARY KEY, started REAL NOT NULL, resumed INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS evaluations (
    id INTEGER PRIMARY KEY,
    key TEXT NOT NULL UNIQUE,
    session INTEGER NOT NULL,
    start INTEGER NOT NULL,
    stage TEXT NOT NULL,
    fidelity TEXT NOT NULL,
    x TEXT NOT NULL,
    outcome TEXT NOT NULL,
    message TEXT NOT NULL,
    vals TEXT NOT NULL,
    gradients TEXT,
    gradient_source TEXT NOT NULL,
    metrics TEXT NOT NULL,
    statuses TEXT NOT NULL,
    timings TEXT NOT NULL,
    created REAL NOT NULL,
    checksum TEXT
);
CREATE TABLE IF NOT EXISTS run_info (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS designs (
    id INTEGER PRIMARY KEY,
    session INTEGER NOT NULL,
    role TEXT NOT NULL,
    fidelity TEXT NOT NULL,
    x TEXT NOT NULL,
    design TEXT NOT NULL,
    metrics TEXT NOT NULL,
    statuses TEXT NOT NULL,
    created REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS session_counts (
    session INTEGER PRIMARY KEY,
    max_evals INTEGER,
    evaluated INTEGER NOT NULL,
    replayed INTEGER NOT NULL,
    repeated INTEGER NOT NULL,
    status TEXT NOT NULL,
    finished REAL NOT NULL
);
"""


def point_key(x: Sequence[float], fidelity: str, gradient: bool) -> str:
    """Exact key of an evaluation: hex float64 bit patterns, fidelity, gradient flag."""
    return ",".join(float(v).hex() for v in x) + f"|{fidelity}|{'g' if gradient else '-'}"


#: the evaluation fields a checksum covers, in order
CHECKED_FIELDS = ("key", "x", "outcome", "message", "vals", "gradients", "gradient_source", "metrics", "statuses",
                  "timings")


def inspect_record(path: str | Path, what: str = "--resume", *, resume: bool = True) -> None:
    """Refuse (one line, :class:`InputFileError`; the file is only read) a database that is not a
    hapticopt run record or whose rows do not match their checksums. ``resume=False`` (a reader, which
    may read a record being created) does not require the fingerprint yet."""
    def refuse(why: str) -> InputFileError:
        return InputFileError(f"{what}: {path} {why}: refused, not modified" + (" (choose another --out)" if resume else ""))

    try:
        db = connect_readonly(path)
    except sqlite3.Error as exc:
        raise refuse(f"cannot be read as a run record ({exc})") from None
    try:
        objects = db.execute("SELECT type, name FROM sqlite_master").fetchall()
        if not objects and resume:
            # no schema at all: a run killed before its first transaction committed (SQLite rolls the
            # journal back when the recorder opens it); nothing in it to protect, the recorder creates its tables
            return
        foreign = sorted(f"{t} {n}" for t, n in objects if t in ("view", "trigger"))
        if foreign:
            raise refuse(f"holds {', '.join(foreign[:3])}: not a hapticopt run record")
        tables = {n for t, n in objects if t == "table"}
        if not ({"meta", "evaluations"} if resume else {"evaluations"}) <= tables:
            raise refuse("is not a hapticopt run record (no meta and evaluations tables)")
        meta = dict(db.execute("SELECT key, value FROM meta").fetchall()) if "meta" in tables else {}
        if ("fingerprint" not in meta and resume) or meta.get("application", APPLICATION) != APPLICATION:
            raise refuse("is not a hapticopt run record (its meta table names no hapticopt run)")
        try:
            schema = int(meta.get("schema", "1"))
        except ValueError:
            schema = -1
        if not 1 <= schema <= SCHEMA:
            raise refuse(f"has record schema {short_text(meta.get('schema'))}: this version reads 1 to {SCHEMA}")
        cols = {r[1] for r in db.execute("PRAGMA table_info(evaluations)")}
        if "checksum" in cols:
            for row in db.execute(f"SELECT id, {', '.join(CHECKED_FIELDS)}, checksum FROM evaluations "
                                  "WHERE checksum IS NOT NULL"):
                if row_checksum(*row[1:-1]) != row[-1]:
                    raise refuse(f"has evaluation {row[0]} whose content does not match its checksum (edited)")
        if "stages" in tables and "checksum" in {r[1] for r in db.execute("PRAGMA table_info(stages)")}:
            for name, payload, checksum in db.execute("SELECT name, payload, checksum FROM stages "
                                                      "WHERE checksum IS NOT NULL"):
                if row_checksum(name, payload) != checksum:
                    raise refuse(f"has stage {short_text(name)} whose content does not match its checksum (edited)")
    except sqlite3.Error as exc:
        raise refuse(f"cannot be read as a run record ({exc})") from None
    finally:
        db.close()


def short_text(value: object) -> str:
    text = str(value)
    return text if len(text) <= 40 else text[:37] + "..."


def check_run_dir(run_dir: str | Path, *, resume: bool, force: bool) -> None:
    """Refuse to start a new run over a recorded one unless ``force`` (one line, nothing touched)."""
    path = Path(run_dir) / FILENAME
    if resume and force:
        raise InvalidInput("--resume and --force contradict each other: --resume continues the run, "
                           "--force replaces it")
    if not resume and not force and path.is_file():
        raise InvalidInput(f"--out {run_dir} already holds a run ({path}): give --resume to continue it "
                           "or --force to replace it, or choose another --out")


class Recorder:
    """SQLite recorder (thread-safe: the driver may evaluate several starts at once)."""

    def __init__(self, run_dir: str | Path, *, fingerprint: str, resume: bool, force: bool = False,
                 search_fingerprint: str | None = None) -> None:
        self.path = Path(run_dir) / FILENAME
        check_run_dir(run_dir, resume=resume, force=force)
        paths.make_dirs(self.path.parent)
        check_db_paths(self.path)
        if resume and self.path.is_file():
            inspect_record(self.path)
        if not resume:
            for suffix in ("", "-wal", "-shm"):
                Path(str(self.path) + suffix).unlink(missing_ok=True)
        elif not self.path.is_file():
            raise InvalidInput(f"--resume: {self.path} does not exist: there is no run to resume in {run_dir}")
        self._lock = threading.Lock()
        try:
            self._open(run_dir, fingerprint=fingerprint, resume=resume, search_fingerprint=search_fingerprint)
        except sqlite3.Error as exc:
            raise RecorderError(f"cannot open the run database {self.path}: {exc}") from None

    def _open(self, run_dir: str | Path, *, fingerprint: str, resume: bool, search_fingerprint: str | None) -> None:
        self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None, timeout=30.0)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute(f"PRAGMA synchronous={SYNCHRONOUS}")
        # the schema, the meta rows and the session row commit together: a run killed in between leaves
        # either no schema (resumable) or a whole record, never a meta table without its fingerprint
        self._db.executescript("BEGIN IMMEDIATE;" + _SCHEMA)
        try:
            self._create(run_dir, fingerprint=fingerprint, resume=resume, search_fingerprint=search_fingerprint)
            self._db.execute("COMMIT")
        except BaseException:
            if self._db.in_transaction:
                self._db.execute("ROLLBACK")
            raise
        self._previous: dict[str, PointResult] = {}
        for key, x, outcome, message, vals, grads, gsrc, metrics, statuses, timings in self._db.execute(
                "SELECT key, x, outcome, message, vals, gradients, gradient_source, metrics, statuses, timings "
                "FROM evaluations WHERE session < ? ORDER BY id", (self.session,)):
            self._previous[key] = PointResult(
                x=tuple(json.loads(x)), outcome=Outcome(outcome), message=message,
                values=tuple(json.loads(vals)),
                gradients=None if grads is None else tuple(tuple(r) for r in json.loads(grads)),
                gradient_source=gsrc, metrics=json.loads(metrics), statuses=upgrade(json.loads(statuses)),
                timings_s=json.loads(timings))
        self.n_repeated = 0  # evaluations of a point this run had already recorded (should stay 0)

    def _create(self, run_dir: str | Path, *, fingerprint: str, resume: bool, search_fingerprint: str | None) -> None:
        for table in ("evaluations", "stages"):  # a record older than the checksums gains the column
            if "checksum" not in {r[1] for r in self._db.execute(f"PRAGMA table_info({table})")}:
                self._db.execute(f"ALTER TABLE {table} ADD COLUMN checksum TEXT")
        self._db.execute("INSERT OR IGNORE INTO meta(key, value) VALUES ('application', ?)", (APPLICATION,))
        self._db.execute("INSERT OR REPLACE INTO meta(key, value) VALUES ('schema', ?)", (str(SCHEMA),))
        row = self._db.execute("SELECT value FROM meta WHERE key='fingerprint'").fetchone()
        srow = self._db.execute("SELECT value FROM meta WHERE key='search_fingerprint'").fetchone()
        if row is None:
            self._db.execute("INSERT INTO meta(key, value) VALUES ('fingerprint', ?)", (fingerprint,))
            if search_fingerprint is not None:
                self._db.execute("INSERT INTO meta(key, value) VALUES ('search_fingerprint', ?)",
                                 (search_fingerprint,))
        elif srow is not None and search_fingerprint is not None:
            if srow[0] != search_fingerprint:
                raise InvalidInput(f"--resume: the run in {run_dir} was made with a different problem or optimiser "
                                   f"settings (fingerprint {srow[0]} ≠ {search_fingerprint}; the budget may differ): "
                                   "use the same settings or a new --out")
        elif row[0] != fingerprint:
            raise InvalidInput(f"--resume: the run in {run_dir} was made with a different problem or optimiser "
                               f"settings (fingerprint {row[0]} ≠ {fingerprint}): use the same settings or a new --out")
        cur = self._db.execute("INSERT INTO sessions(started, resumed) VALUES (?, ?)", (time.time(), int(resume)))
        self.session = int(cur.lastrowid or 0)

    def lookup_stage(self, name: str) -> dict[str, Any] | None:
        """The recorded result of a whole stage (e.g. the baseline evaluation), or None."""
        with self._lock:
            row = self._db.execute("SELECT payload FROM stages WHERE name = ?", (name,)).fetchone()
        return None if row is None else json.loads(row[0])

    def record_stage(self, name: str, payload: dict[str, Any]) -> None:
        """Record a stage's result (JSON values), on disk once this returns."""
        with self._lock:
            text = json.dumps(payload)
            try:
                self._db.execute("INSERT OR REPLACE INTO stages(name, payload, created, checksum) VALUES (?, ?, ?, ?)",
                                 (name, text, time.time(), row_checksum(name, text)))
            except sqlite3.Error as exc:
                raise RecorderError(f"cannot record stage {name} in {self.path}: {exc}") from exc

    @property
    def n_previous(self) -> int:
        return len(self._previous)

    def lookup(self, key: str) -> PointResult | None:
        """A result recorded by an earlier session of this run (replay), or None."""
        return self._previous.get(key)

    def record(self, key: str, result: PointResult, *, start: int, stage: str, fidelity: str) -> None:
        """Write one evaluation in its own transaction, on disk once this returns (WAL fsynced,
        :data:`SYNCHRONOUS` = FULL: ~0.2 ms more per evaluation than NORMAL)."""
        row = (key, self.session, start, stage, fidelity, json.dumps([float(v) for v in result.x]),
               str(result.outcome), result.message, json.dumps(list(result.values)),
               None if result.gradients is None else json.dumps([list(r) for r in result.gradients]),
               result.gradient_source, json.dumps(result.metrics), json.dumps(result.statuses),
               json.dumps(result.timings_s), time.time())
        row = (*row, row_checksum(*row[:1], *row[5:14]))
        with self._lock:
            try:
                self._db.execute("BEGIN IMMEDIATE")
                cur = self._db.execute(
                    "INSERT OR IGNORE INTO evaluations(key, session, start, stage, fidelity, x, outcome, message, vals,"
                    " gradients, gradient_source, metrics, statuses, timings, created, checksum)"
                    " VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)", row)
                if cur.rowcount == 0:
                    self.n_repeated += 1
                self._db.execute("COMMIT")
            except BaseException as exc:
                # SQLite may already have rolled back (e.g. SQLITE_FULL): roll back only an open
                # transaction, and report the error that happened, not a failed ROLLBACK
                if self._db.in_transaction:
                    try:
                        self._db.execute("ROLLBACK")
                    except sqlite3.Error:
                        pass
                if isinstance(exc, sqlite3.Error):
                    raise RecorderError(f"cannot record an evaluation in {self.path}: {exc}") from exc
                raise

    def rows(self) -> list[dict[str, Any]]:
        """Every recorded evaluation (all sessions), in insertion order."""
        with self._lock:
            cur = self._db.execute("SELECT id, key, session, start, stage, outcome, x, timings FROM evaluations ORDER BY id")
            cols = [c[0] for c in cur.description]
            return [dict(zip(cols, r)) for r in cur.fetchall()]

    # ------------------------------------------------------------ the self-describing record
    def _write(self, sql: str, params: Sequence[Any] | Sequence[Sequence[Any]], *, many: bool = False) -> None:
        with self._lock:
            try:
                self._db.execute("BEGIN IMMEDIATE")
                (self._db.executemany if many else self._db.execute)(sql, params)
                self._db.execute("COMMIT")
            except BaseException as exc:
                if self._db.in_transaction:  # SQLite may have rolled back already (SQLITE_FULL)
                    try:
                        self._db.execute("ROLLBACK")
                    except sqlite3.Error:
                        pass
                if isinstance(exc, sqlite3.Error):
                    raise RecorderError(f"cannot write the run record {self.path}: {exc}") from exc
                raise

    def describe(self, info: dict[str, Any]) -> None:
        """Store what the run is (kind, problem, variables, objectives, versions …): JSON per key."""
        self._write("INSERT OR REPLACE INTO run_info(key, value) VALUES (?, ?)",
                    [(k, json.dumps(v, default=str)) for k, v in info.items()], many=True)

    def set_status(self, status: str) -> None:
        """``running``, ``finished`` or ``interrupted`` (what ``hapticopt runs`` lists)."""
        self.describe({"status": status})

    def record_design(self, role: str, *, fidelity: str, x: Sequence[float], design_toml: str,
                      metrics: dict[str, Any], statuses: dict[str, str]) -> None:
        """A whole design evaluated outside the loop: ``baseline``, ``final``, ``chosen`` …"""
        self._write("INSERT INTO designs(session, role, fidelity, x, design, metrics, statuses, created)"
                    " VALUES (?,?,?,?,?,?,?,?)",
                    (self.session, role, fidelity, json.dumps([float(v) for v in x]), design_toml,
                     json.dumps(metrics, default=str), json.dumps(statuses), time.time()))

    def end_session(self, *, status: str, n_evaluated: int, n_replayed: int, max_evals: int | None) -> None:
        """This session's counts (``repeated`` is the recorder's own count of re-evaluated points)."""
        self._write("INSERT OR REPLACE INTO session_counts(session, max_evals, evaluated, replayed, repeated,"
                    " status, finished) VALUES (?,?,?,?,?,?,?)",
                    (self.session, max_evals, n_evaluated, n_replayed, self.n_repeated, status, time.time()))
        self.set_status(status)

    def close(self) -> None:
        with self._lock:
            self._db.close()

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


LOCKFILE = ".hapticopt.lock"


@contextlib.contextmanager
def run_lock(run_dir: str | Path) -> Iterator[Path]:
    """Hold the run directory for this process (``flock`` on ``DIR/.hapticopt.lock``).

    Every command that writes a run directory takes it (optimise, sweep, ``compare --report``,
    export). The lock file is opened with ``O_NOFOLLOW``: a link planted there is refused, its target
    untouched. A second run or ``--resume`` of the same directory while one is alive gets one line
    (:class:`InvalidInput`, exit 2) instead of repeating evaluations. The kernel drops the lock
    when the holder dies, however it dies, so a killed run never blocks its resume.
    """
    path = Path(run_dir) / LOCKFILE
    paths.make_dirs(run_dir)
    fd = paths.open_nofollow(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
            raise InvalidInput(f"--out {run_dir} is in use by another hapticopt run (pid {holder}): wait for it to "
                               "finish or use another --out") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield path
    finally:
        os.close(fd)  # releases the lock

"""The evaluation cache: a design's evaluation at one fidelity, computed once and reused across runs.

A whole evaluation (every evaluator the registry runs on a design at a fidelity: metrics,
statuses, messages, the evaluator module of each metric, the timings of the run that computed it)
is stored in SQLite under a key that is the SHA-256 of

- the design's **canonical frozen values** (:func:`canonical`: every field of the frozen
  dataclasses, floats by their exact bit pattern, the name and description included — an
  evaluator may quote the name in a message),
- the **fidelity** and the **evaluator set** (``only``; ``None`` = all registered for the device),
- the **code version** (:func:`code_version`): a hash of the source (``*.py``) and bundled data
  (``*.toml``) of ``hapticopt.design`` and ``hapticopt.analysis`` — everything an evaluator can
  depend on: the registry loads evaluators by name and they read bundled tables, so an
  import-graph walk could miss a dependency; any edit there misses every entry (a recomputation),
  never reuses a stale one — plus the versions of the numerical libraries, the Python version, the
  CPU architecture and ``OPENBLAS_CORETYPE`` (the BLAS kernel moves the last digits).

Invalidation is by key only, never by time. An evaluation in which an evaluator raised
(``failed``) is not stored: the failure may be transient (memory, a killed solver); every other
status (ok, singular, unstable …) is a result and is stored.

Storage. ``FILE`` (by default ``evaluation-cache.sqlite`` beside the run record, in the run
directory; ``--cache FILE`` shares one among runs, ``--no-cache`` switches it off) in WAL mode:
readers never block, two processes write through SQLite's lock (``BEGIN IMMEDIATE``, 30 s busy
timeout), and each entry is one transaction, so a killed writer leaves the entries committed
before it and nothing half-written. ``synchronous=NORMAL``: a power loss may drop the last entries
(a miss later), never corrupt the file. A file that is not a readable cache (corrupt, another
format, unreadable, on a read-only disk) is ignored with one warning line on stderr: the cache is
an optimisation and never stops a run.

Trust (issue 37). Each entry carries the SHA-256 of its key and payload (``checksum``); ``meta``
names the application and the format. Before a file is used it is opened read-only and checked
(:func:`inspect`): a foreign SQLite database (no cache ``meta``, views or triggers) or an entry
whose content does not match its checksum (edited by hand) is refused with one line
(:class:`~hapticopt.design.errors.InputFileError`, exit 2) and left unmodified; a link at the file or
its SQLite side files is refused the same way. An entry read later that fails its checksum is a miss
with a warning.

Provenance: a value served from the cache says so (:attr:`CachedEvaluation.provenance`: the file,
the key, when and by what it was written); the pipeline puts it in the stage message, the record
and the report.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import hashlib
import json
import os
import platform
import sqlite3
import sys
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import hapticopt.analysis
import hapticopt.design
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.registry import EVALUATORS, evaluate_all
from hapticopt.analysis.status import Status
from hapticopt.design import paths
from hapticopt.design.errors import InputFileError
from hapticopt.optim.sqlite_checks import check_db_paths, connect_readonly, row_checksum
from hapticopt.optim.versions import package_versions

#: default file name, in the run directory beside ``evaluations.sqlite``
FILENAME = "evaluation-cache.sqlite"
#: layout of the file and of the key; a file of another format is ignored (with a warning). 2: checksums
FORMAT = 2
#: ``meta.application`` of a cache file
APPLICATION = "hapticopt evaluation cache"
#: third-party distributions whose version enters the code version (the numbers depend on them)
NUMERIC_LIBRARIES = ("numpy", "scipy", "jax", "jaxlib", "manifold3d", "gmsh", "scikit-fem", "pyamg", "mujoco",
                     "build123d", "cadquery-ocp-novtk")
#: the payload keys of an entry
PAYLOAD_KEYS = ("metrics", "statuses", "messages", "modules", "timings_s")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS evaluations (
    key TEXT PRIMARY KEY,
    device TEXT NOT NULL,
    design TEXT NOT NULL,
    fidelity TEXT NOT NULL,
    only TEXT,
    code_version TEXT NOT NULL,
    payload TEXT NOT NULL,
    written_by TEXT NOT NULL,
    created REAL NOT NULL,
    checksum TEXT NOT NULL
);
"""


# ------------------------------------------------------------------------------------ the key
def canonical(value: Any) -> Any:
    """A JSON value that identifies ``value`` exactly (floats by bit pattern, types by name).

    Frozen dataclasses (designs and their sections), enums, numbers, strings, tuples, lists,
    mappings and numpy arrays; anything else raises :class:`TypeError` (no guessing from repr).
    """
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        cls = type(value)
        return {"type": f"{cls.__module__}.{cls.__qualname__}",
                "fields": {f.name: canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}}
    if isinstance(value, enum.Enum):
        return ["enum", f"{type(value).__module__}.{type(value).__qualname__}", canonical(value.value)]
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return ["int", str(int(value))]
    if isinstance(value, (float, np.floating)):
        return ["float", float(value).hex()]
    if isinstance(value, np.ndarray):
        return ["array", value.dtype.str, list(value.shape), np.ascontiguousarray(value).tobytes().hex()]
    if isinstance(value, (tuple, list)):
        return [type(value).__name__, [canonical(v) for v in value]]
    if isinstance(value, Mapping):
        return ["map", sorted(([str(k), canonical(v)] for k, v in value.items()), key=lambda kv: kv[0])]
    raise TypeError(f"cannot key a {type(value).__name__} value for the evaluation cache")


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """SHA-256 of what an evaluation's numbers depend on besides the design (see the module text).

    Reads every ``*.py`` and ``*.toml`` file of ``hapticopt.design`` and ``hapticopt.analysis``
    (about 1.2 MB, a few ms) once per process."""
    h = hashlib.sha256(f"hapticopt evaluation cache format {FORMAT}\n".encode())
    for pkg in (hapticopt.design, hapticopt.analysis):
        for root in pkg.__path__:
            base = Path(root)
            files = sorted(p for p in base.rglob("*") if p.suffix in (".py", ".toml") and p.is_file()
                           and "__pycache__" not in p.parts)
            for path in files:
                h.update(f"{pkg.__name__}/{path.relative_to(base).as_posix()}\n".encode())
                h.update(path.read_bytes())
                h.update(b"\0")
    env = {"python": sys.version, "implementation": platform.python_implementation(),
           "machine": platform.machine(), "OPENBLAS_CORETYPE": os.environ.get("OPENBLAS_CORETYPE", ""),
           **package_versions(NUMERIC_LIBRARIES)}
    h.update(json.dumps(env, sort_keys=True).encode())
    return h.hexdigest()


def cache_key(design: Any, fidelity: Fidelity, only: tuple[str, ...] | None = None,
              code: str | None = None) -> str:
    """The key of ``design``'s evaluation at ``fidelity`` by the evaluators ``only`` (None: all)."""
    payload = {"format": FORMAT, "design": canonical(design), "fidelity": str(Fidelity(fidelity)),
               "only": None if only is None else sorted(only), "code": code_version() if code is None else code}
    return hashlib.sha256(json.dumps(payload, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


# ------------------------------------------------------------------------------------ the file
def warn_stderr(message: str) -> None:
    """The default warning sink: one line on stderr."""
    print(f"warning: {message}", file=sys.stderr, flush=True)


def inspect(path: str | Path) -> str:
    """Check an existing cache file read-only; '' when it is a cache of this format, else why it is of
    another format (ignored with a warning). A foreign database or an edited entry raises
    :class:`InputFileError` (the file is not modified). A file that is not a database raises
    :class:`sqlite3.DatabaseError` (ignored with a warning by :class:`EvaluationCache`)."""
    def refuse(why: str) -> InputFileError:
        return InputFileError(f"evaluation cache {path} {why}: refused, not modified (remove it, or give "
                              "--cache with another file or --no-cache)")

    db = connect_readonly(path)
    try:
        objects = db.execute("SELECT type, name FROM sqlite_master").fetchall()
        foreign = sorted(f"{t} {n}" for t, n in objects if t in ("view", "trigger"))
        if foreign:
            raise refuse(f"holds {', '.join(foreign[:3])}: not an evaluation cache")
        tables = {n for t, n in objects if t == "table"}
        if not tables:
            return ""  # an empty database: it becomes a cache
        meta = dict(db.execute("SELECT key, value FROM meta").fetchall()) if "meta" in tables else {}
        if "format" not in meta or "evaluations" not in tables:
            raise refuse(f"is another SQLite database (tables {', '.join(sorted(tables)[:4])}): not an evaluation cache")
        if meta["format"] != str(FORMAT):
            return f"it has cache format {meta['format'][:20]}, this version reads {FORMAT}"
        if meta.get("application") != APPLICATION:
            raise refuse("names no hapticopt evaluation cache in its meta table")
        for key, payload, checksum in db.execute("SELECT key, payload, checksum FROM evaluations"):
            if row_checksum(key, payload) != checksum:
                raise refuse(f"has entry {str(key)[:12]} whose content does not match its checksum (edited)")
        return ""
    finally:
        db.close()


@dataclass(frozen=True, kw_only=True)
class CacheHit:
    payload: dict[str, Any]
    created: float  # when it was written [s since the epoch]
    written_by: str

    def provenance(self, path: Path, key: str) -> str:
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(self.created))
        return f"from the evaluation cache {path} (key {key[:12]}, written {when} by {self.written_by})"


class EvaluationCache:
    """One cache file; every fault becomes a warning and a miss (the caller then computes)."""

    def __init__(self, path: str | Path, *, warn: Callable[[str], None] = warn_stderr) -> None:
        self.path = Path(path)
        self._warn = warn
        self._lock = threading.Lock()
        self._db: sqlite3.Connection | None = None
        self.disabled = ""  # why the cache is off ('' while it works)
        self.hits = self.misses = self.stored = 0
        check_db_paths(self.path)  # a link: refused (InputFileError), not a warning
        try:
            paths.make_dirs(self.path.parent)
            if self.path.is_file() and self.path.stat().st_size > 0:
                other = inspect(self.path)
                if other:
                    self._disable(other)
                    return
            db = sqlite3.connect(self.path, timeout=30.0, isolation_level=None, check_same_thread=False)
            self._db = db
            db.execute("PRAGMA journal_mode=WAL")  # the first read: a file that is not a database fails here
            db.execute("PRAGMA synchronous=NORMAL")
            db.executescript(_SCHEMA)
            db.execute("INSERT OR IGNORE INTO meta(key, value) VALUES ('format', ?)", (str(FORMAT),))
            db.execute("INSERT OR IGNORE INTO meta(key, value) VALUES ('application', ?)", (APPLICATION,))
        except InputFileError:
            raise
        except (sqlite3.Error, OSError) as exc:
            self._disable(str(exc) or type(exc).__name__)

    @property
    def enabled(self) -> bool:
        return not self.disabled

    def _disable(self, reason: str) -> None:
        if self.disabled:
            return
        self.disabled = reason
        self._warn(f"evaluation cache {self.path} ignored ({reason}); evaluating without it "
                   "(remove the file to start a new cache)")
        if self._db is not None:
            try:
                self._db.close()
            except sqlite3.Error:
                pass
            self._db = None

    def lookup(self, key: str) -> CacheHit | None:
        """The entry stored under ``key``, or None (a miss, or the cache is off)."""
        with self._lock:
            if self._db is None:
                return None
            try:
                row = self._db.execute("SELECT payload, created, written_by, checksum FROM evaluations WHERE key = ?",
                                       (key,)).fetchone()
            except sqlite3.Error as exc:
                self._disable(str(exc))
                return None
        if row is None:
            self.misses += 1
            return None
        try:
            if row_checksum(key, row[0]) != row[3]:
                raise ValueError("its content does not match its checksum (edited)")
            payload = json.loads(row[0])
            if not isinstance(payload, dict) or any(k not in payload for k in PAYLOAD_KEYS):
                raise ValueError(f"missing {[k for k in PAYLOAD_KEYS if k not in payload]}")
        except (ValueError, TypeError) as exc:
            self._warn(f"evaluation cache {self.path}: entry {key[:12]} is unreadable ({exc}); recomputing it")
            self.misses += 1
            return None
        self.hits += 1
        return CacheHit(payload=payload, created=float(row[1]), written_by=str(row[2]))

    def store(self, key: str, payload: dict[str, Any], *, device: str, design: str, fidelity: str,
              only: tuple[str, ...] | None, written_by: str) -> None:
        """Store one entry in its own transaction (a key already there is kept: same key, same value)."""
        text = json.dumps(payload, allow_nan=True)
        with self._lock:
            if self._db is None:
                return
            try:
                self._db.execute("BEGIN IMMEDIATE")
                self._db.execute(
                    "INSERT OR IGNORE INTO evaluations(key, device, design, fidelity, only, code_version, payload,"
                    " written_by, created, checksum) VALUES (?,?,?,?,?,?,?,?,?,?)",
                    (key, device, design, fidelity, None if only is None else ",".join(sorted(only)), code_version(),
                     text, written_by, time.time(), row_checksum(key, text)))
                self._db.execute("COMMIT")
                self.stored += 1
            except sqlite3.Error as exc:
                if self._db.in_transaction:
                    try:
                        self._db.execute("ROLLBACK")
                    except sqlite3.Error:
                        pass
                self._disable(f"cannot write: {exc}")

    def close(self) -> None:
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None

    def __enter__(self) -> "EvaluationCache":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ------------------------------------------------------------------------------ the evaluation
@dataclass(frozen=True, kw_only=True)
class CachedEvaluation:
    """Every evaluator on one design at one fidelity, computed here or served from the cache."""

    fidelity: Fidelity
    metrics: dict[str, Any]
    statuses: dict[str, str]
    messages: dict[str, str]
    modules: dict[str, str]  # metric -> evaluator module
    timings_s: dict[str, float]  # of the run that computed it
    results: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)  # empty when cached
    provenance: str = ""  # '' computed in this process; else where it came from

    def payload(self) -> dict[str, Any]:
        return {"metrics": self.metrics, "statuses": self.statuses, "messages": self.messages,
                "modules": self.modules, "timings_s": self.timings_s}


def cached(design: Any, fidelity: Fidelity, cache: EvaluationCache | None,
           only: tuple[str, ...] | None = None) -> CachedEvaluation | None:
    """``design``'s evaluation at ``fidelity`` (by the evaluators ``only``) from ``cache``, or None."""
    if cache is None or not cache.enabled:
        return None
    key = cache_key(design, fidelity, only)
    hit = cache.lookup(key)
    if hit is None:
        return None
    p = hit.payload
    return CachedEvaluation(fidelity=Fidelity(fidelity), metrics=p["metrics"], statuses=p["statuses"],
                            messages=p["messages"], modules=p["modules"], timings_s=p["timings_s"],
                            provenance=hit.provenance(cache.path, key))


def evaluate(design: Any, fidelity: Fidelity, *, cache: EvaluationCache | None, only: tuple[str, ...] | None = None,
             written_by: str = "hapticopt", reuse: bool = True,
             progress: Callable[[str, int, int], None] | None = None, compute: Compute = DEFAULT) -> CachedEvaluation:
    """The registry's evaluation of ``design`` (:func:`hapticopt.analysis.registry.evaluate_all`),
    served from ``cache`` when it holds this key, else computed and stored (unless an evaluator raised).
    ``reuse=False`` always computes (the caller needs the evaluators' result objects, e.g. for
    pictures) and still stores the values for later callers. ``progress(what, done, total)`` is
    :func:`~hapticopt.analysis.registry.evaluate_all`'s (called only when the evaluators run)."""
    found = cached(design, fidelity, cache, only) if reuse else None
    if found is not None:
        return found
    ev = evaluate_all(design, fidelity=fidelity, only=only, progress=progress, compute=compute)
    out = CachedEvaluation(fidelity=Fidelity(fidelity), metrics=ev.metrics(),
                           statuses={k: str(v) for k, v in ev.statuses.items()}, messages=dict(ev.messages),
                           modules=dict(ev.sources), timings_s=dict(ev.timings_s), results=dict(ev.results))
    store(cache, design, out, only=only, written_by=written_by)
    return out


def store(cache: EvaluationCache | None, design: Any, ev: CachedEvaluation, *, only: tuple[str, ...] | None = None,
          written_by: str = "hapticopt") -> None:
    """Store the computed evaluation ``ev`` of ``design`` (by the evaluators ``only``; None: all) in
    ``cache`` under its key — unless an evaluator raised (``failed``) or there is no cache."""
    if cache is None or not cache.enabled or str(Status.FAILED) in ev.statuses.values():
        return
    cache.store(cache_key(design, ev.fidelity, only), ev.payload(), device=design.device, design=design.name,
                fidelity=str(ev.fidelity), only=only, written_by=written_by)


def merge(design: Any, parts: list[CachedEvaluation]) -> CachedEvaluation:
    """One evaluation of ``design`` from ``parts`` computed by disjoint sets of its device's evaluators
    (e.g. in two processes): every dict in the registry's order, as :func:`evaluate_all` gives them,
    so that the merged values equal one evaluation by all of them (results are kept where present).
    A metric is found by the module that produced it: the evaluators of a device name distinct metrics."""
    fidelities = {p.fidelity for p in parts}
    if len(fidelities) != 1:
        raise ValueError(f"cannot merge evaluations at different fidelities {sorted(map(str, fidelities))}")
    owner: dict[str, CachedEvaluation] = {}
    for part in parts:
        for name in part.statuses:
            if name in owner:
                raise ValueError(f"evaluator {name} is in two parts of the evaluation")
            owner[name] = part
    metrics: dict[str, Any] = {}
    modules: dict[str, str] = {}
    statuses: dict[str, str] = {}
    messages: dict[str, str] = {}
    timings: dict[str, float] = {}
    results: dict[str, Any] = {}
    for entry in EVALUATORS[design.device]:
        part = owner.get(entry.name)
        if part is None:
            continue
        statuses[entry.name] = part.statuses[entry.name]
        messages[entry.name] = part.messages[entry.name]
        timings[entry.name] = part.timings_s[entry.name]
        if entry.name in part.results:
            results[entry.name] = part.results[entry.name]
        for metric, module in part.modules.items():  # this entry's metrics (evaluate_all: in entry order)
            if module == entry.module:
                metrics[metric] = part.metrics[metric]
                modules[metric] = module
    return CachedEvaluation(fidelity=fidelities.pop(), metrics=metrics, statuses=statuses, messages=messages,
                            modules=modules, timings_s=timings, results=results)

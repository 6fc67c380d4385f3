"""Recorder: SQLite in WAL mode, one row per evaluation, exact-key replay, SIGKILL then --resume."""

from __future__ import annotations

import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hapticopt.design.errors import InvalidInput
from hapticopt.optim import driver
from hapticopt.optim.evaluation import Outcome, PointResult, evaluate_point
from hapticopt.optim.problem import load_problem
from hapticopt.optim.recorder import FILENAME, Recorder, point_key

DATA = Path(__file__).parent / "data"
ONLY = ("statics",)  # the problem's metrics all come from hapticopt.analysis.prrr.structure.statics
PROBLEM = DATA / "resume-problem.toml"


def test_point_key_is_exact():
    x = (35.264389682754654, 0.1)
    assert point_key(x, "draft", False) == point_key(list(x), "draft", False)
    assert point_key(x, "draft", False) != point_key((math.nextafter(x[0], 99), 0.1), "draft", False)
    assert point_key(x, "draft", False) != point_key(x, "fine", False) != point_key(x, "draft", True)


def test_record_roundtrip_wal_and_one_row_per_evaluation(tmp_path):
    r = PointResult(x=(1.5, 2.0), outcome=Outcome.NONFINITE, message="nan", values=(math.nan, 1.25),
                    gradients=((0.1, 0.2), (0.3, 0.4)), gradient_source="jax",
                    metrics={"a": [1.0, 2.0], "b": math.inf}, statuses={"statics": "ok"}, timings_s={"statics": 1e-4})
    with Recorder(tmp_path, fingerprint="f1", resume=False) as rec:
        rec.record("k1", r, start=0, stage="search", fidelity="draft")
        rec.record("k1", r, start=0, stage="search", fidelity="draft")  # the same key twice: one row
    db = sqlite3.connect(tmp_path / FILENAME)
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert db.execute("SELECT COUNT(*) FROM evaluations").fetchone()[0] == 1
    db.close()
    with Recorder(tmp_path, fingerprint="f1", resume=True) as rec:
        back = rec.lookup("k1")
    assert back.x == r.x and back.outcome is Outcome.NONFINITE and back.gradients == r.gradients
    assert math.isnan(back.values[0]) and back.values[1] == 1.25
    assert back.metrics["a"] == [1.0, 2.0] and back.metrics["b"] == math.inf


def test_resume_checks_fingerprint_and_existence(tmp_path):
    with pytest.raises(InvalidInput, match="no run to resume"):
        Recorder(tmp_path / "nothing", fingerprint="f", resume=True)
    Recorder(tmp_path, fingerprint="f1", resume=False).close()
    with pytest.raises(InvalidInput, match="different problem or optimiser settings"):
        Recorder(tmp_path, fingerprint="f2", resume=True)


class _Counting:
    """evaluate_point that records which points it really evaluated."""

    def __init__(self):
        self.keys: list[str] = []

    def __call__(self, task):
        self.keys.append(point_key(task.x, str(task.fidelity), task.gradient != "none"))
        return evaluate_point(task)


def test_interrupted_run_resumes_without_repeating(tmp_path):
    problem = load_problem(PROBLEM)
    full = driver.run(problem, only=ONLY)

    class Crash(BaseException):
        pass

    def crash_after(n):
        def progress(rec, best, n_eval):
            if n_eval >= n:
                raise Crash
        return progress

    first = _Counting()
    with Recorder(tmp_path, fingerprint=problem.fingerprint(), resume=False) as rec:
        with pytest.raises(Crash):
            driver.run(problem, only=ONLY, recorder=rec, evaluate_fn=first, progress=crash_after(37))
    second = _Counting()
    with Recorder(tmp_path, fingerprint=problem.fingerprint(), resume=True) as rec:
        res = driver.run(problem, only=ONLY, recorder=rec, evaluate_fn=second)
    assert len(first.keys) == 37 and not set(first.keys) & set(second.keys)
    assert res.n_replayed == 37 and res.n_evaluated == full.n_evaluated - 37
    assert [(r.x, r.f) for r in res.history] == [(r.x, r.f) for r in full.history]
    assert res.best.x == full.best.x


def test_sigkill_mid_run_then_resume(tmp_path):
    run_dir = tmp_path / "run"
    script = DATA / "slow_run.py"
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    proc = subprocess.Popen([sys.executable, str(script), str(run_dir), "--delay", "0.05"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    db_path = run_dir / FILENAME
    n_killed = 0
    deadline = time.monotonic() + 60
    try:
        while time.monotonic() < deadline:
            if db_path.exists():
                try:
                    with sqlite3.connect(db_path, timeout=1) as db:
                        n_killed = db.execute("SELECT COUNT(*) FROM evaluations").fetchone()[0]
                    db.close()
                except sqlite3.OperationalError:
                    n_killed = 0
                if n_killed >= 20:
                    break
            assert proc.poll() is None, "the run finished before it could be killed"
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    with sqlite3.connect(db_path) as db:
        recorded = {k for (k,) in db.execute("SELECT key FROM evaluations")}
    db.close()
    assert 20 <= len(recorded) < 100  # killed mid-run
    out = subprocess.run([sys.executable, str(script), str(run_dir), "--resume"], env=env, capture_output=True,
                         text=True, check=True)
    resumed = json.loads(out.stdout)
    with sqlite3.connect(db_path) as db:
        rows = db.execute("SELECT key, session FROM evaluations").fetchall()
    db.close()
    keys = [k for k, _ in rows]
    assert len(keys) == len(set(keys))  # no evaluation recorded twice
    assert {k for k, s in rows if s == 2}.isdisjoint(recorded)  # the resumed session computed only new points
    assert resumed["n_replayed"] == len(recorded)
    reference = driver.run(load_problem(PROBLEM), only=ONLY)  # uninterrupted, same seed
    assert resumed["history"] == [[list(r.x), r.f] for r in reference.history]
    assert tuple(resumed["best_x"]) == reference.best.x


def test_the_resume_fingerprint_holds_no_module_path(monkeypatch):
    """A run resumes across a re-layout of the code (the modules moved into device columns, issue 13):
    the fingerprint hashes the problem's values and the design's TOML text, never a module path.
    (A run recorded before the move, commit 99f7fb3, was checked to resume after it; a later change
    of the design schema changes the design's TOML and so, rightly, the fingerprint.)"""
    import hashlib

    from hapticopt.optim import problem as problem_module

    hashed: list[bytes] = []
    monkeypatch.setattr(problem_module, "hashlib", type("H", (), {
        "sha256": staticmethod(lambda data: hashed.append(data) or hashlib.sha256(data))}))
    problem = load_problem(PROBLEM)
    problem.fingerprint(), problem.search_fingerprint()
    assert len(hashed) == 2
    for payload in (h.decode() for h in hashed):
        assert "hapticopt" not in payload and "analysis." not in payload and "optim." not in payload

def _point(i: float) -> PointResult:
    return PointResult(x=(float(i), 2.0), outcome=Outcome.OK, message="", values=(1.0,), gradients=None,
                       gradient_source="none", metrics={"m": "x" * 4000}, statuses={"statics": "ok"},
                       timings_s={"statics": 1e-4})


def test_a_full_database_reports_the_sqlite_reason_not_a_failed_rollback(tmp_path):
    """Issue 14: on a full disk the message was 'cannot rollback - no transaction is active'.
    A page limit makes SQLite answer SQLITE_FULL exactly as a full disk does."""
    from hapticopt.optim.recorder import RecorderError

    with Recorder(tmp_path, fingerprint="f", resume=False) as rec:
        pages = rec._db.execute("PRAGMA page_count").fetchone()[0]
        rec._db.execute(f"PRAGMA max_page_count = {pages + 2}")
        with pytest.raises(RecorderError, match="database or disk is full"):
            for i in range(50):
                rec.record(f"k{i}", _point(i), start=0, stage="search", fidelity="draft")
        assert not rec._db.in_transaction
    with Recorder(tmp_path, fingerprint="f", resume=True) as rec:  # what was committed is intact
        assert 1 <= rec.n_previous < 50


def test_commits_are_fsynced(tmp_path):
    """The recorder promises durability on power loss: synchronous=FULL (2) on its connection
    (pitfalls: NORMAL may lose the last transactions)."""
    with Recorder(tmp_path, fingerprint="f", resume=False) as rec:
        assert rec._db.execute("PRAGMA synchronous").fetchone()[0] == 2


def test_a_second_process_cannot_take_a_locked_run_directory(tmp_path):
    """Two resumes of one run at once repeated 50 evaluations (issue 14): the second is refused."""
    from hapticopt.optim.recorder import run_lock

    code = ("import sys; from hapticopt.optim.recorder import run_lock\n"
            "from hapticopt.design.errors import InvalidInput\n"
            "try:\n    run_lock(sys.argv[1]).__enter__()\nexcept InvalidInput as e:\n    print(e); sys.exit(2)\n")
    with run_lock(tmp_path):
        other = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True)
        assert other.returncode == 2 and f"pid {os.getpid()}" in other.stdout and "in use" in other.stdout
    free = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True)
    assert free.returncode == 0, free.stdout  # released when the holder lets go (or dies)


def test_stale_temp_files_are_removed(tmp_path):
    import tempfile

    from hapticopt.design.atomic import remove_stale_temp_files, write_text

    (tmp_path / "parts").mkdir()
    stale = [tempfile.mkstemp(prefix=".a.step.", suffix=".tmp.step", dir=tmp_path)[1],
             tempfile.mkstemp(prefix=".l.stl.", suffix=".tmp.stl", dir=tmp_path / "parts")[1]]
    write_text(tmp_path / "keep.json", "{}")
    (tmp_path / ".hapticopt.lock").write_text("1")
    assert sorted(map(str, remove_stale_temp_files(tmp_path))) == sorted(stale)
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == [".hapticopt.lock", "keep.json"]


# ------------------------------------------------------------------ records checked before they are trusted
def _sha(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("sql", [
    "CREATE TABLE evaluations (id INTEGER PRIMARY KEY, x TEXT); CREATE TABLE other (a)",  # no hapticopt meta
    "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT); INSERT INTO meta VALUES ('fingerprint', 'f1');"
    "CREATE TABLE evaluations (id INTEGER PRIMARY KEY); CREATE VIEW v AS SELECT 1",  # a view: not ours
    "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT); INSERT INTO meta VALUES ('fingerprint', 'f1');"
    "INSERT INTO meta VALUES ('schema', '99'); CREATE TABLE evaluations (id INTEGER PRIMARY KEY)",  # newer schema
])
def test_resume_refuses_a_foreign_database_and_leaves_it_unmodified(tmp_path, sql):
    """Issue 37: ``--resume`` adopted a foreign SQLite file and added its tables to it."""
    from hapticopt.design.errors import InputFileError

    path = tmp_path / FILENAME
    with sqlite3.connect(path) as db:
        db.executescript(sql)
    before = _sha(path)
    with pytest.raises(InputFileError, match="refused, not modified"):
        Recorder(tmp_path, fingerprint="f1", resume=True)
    assert _sha(path) == before


def test_resume_takes_a_record_killed_before_its_tables_were_committed(tmp_path):
    """A run killed while it created its record leaves a database without any table (its first
    transaction rolled back from the journal): ``--resume`` takes it as an empty record, never refuses it
    as foreign (tests/optim/test_pipeline.py::test_killed_at_random_moments_then_resumed kills there)."""
    path = tmp_path / FILENAME
    path.write_bytes(b"")  # SQLite's empty database
    with Recorder(tmp_path, fingerprint="f1", resume=True) as rec:
        assert rec.path == path
    with sqlite3.connect(path) as db:
        assert {"meta", "evaluations"} <= {n for (n,) in db.execute("SELECT name FROM sqlite_master")}


def test_a_record_is_created_in_one_transaction(tmp_path, monkeypatch):
    """Schema, meta rows (application, schema, fingerprint) and the first session commit together: a
    run stopped anywhere in between leaves no table at all, which --resume takes; never a meta table
    without a fingerprint, which it must refuse as foreign (the fresh clone's CI killed a run there)."""
    def stop(self, *a, **k):
        self._db.execute("INSERT INTO meta(key, value) VALUES ('application', 'hapticopt')")
        raise KeyboardInterrupt  # the SIGKILL's moment: schema and part of meta written, not committed

    monkeypatch.setattr(Recorder, "_create", stop)
    with pytest.raises(KeyboardInterrupt):
        Recorder(tmp_path, fingerprint="f1", resume=False)
    with sqlite3.connect(tmp_path / FILENAME) as db:
        assert db.execute("SELECT name FROM sqlite_master").fetchall() == []
    monkeypatch.undo()
    with Recorder(tmp_path, fingerprint="f1", resume=True) as rec:
        assert rec.session == 1


@pytest.mark.parametrize("edit", ["UPDATE evaluations SET vals = '[9.0]'",
                                  "UPDATE stages SET payload = '{\"objective\": 1.0}'"])
def test_resume_refuses_an_edited_row(tmp_path, edit):
    from hapticopt.design.errors import InputFileError

    with Recorder(tmp_path, fingerprint="f1", resume=False) as rec:
        rec.record("k1", _point(1.0), start=0, stage="search", fidelity="draft")
        rec.record_stage("baseline|draft", {"objective": 2.449})
    with sqlite3.connect(tmp_path / FILENAME) as db:
        db.execute(edit)
    before = _sha(tmp_path / FILENAME)
    with pytest.raises(InputFileError, match="does not match its checksum"):
        Recorder(tmp_path, fingerprint="f1", resume=True)
    assert _sha(tmp_path / FILENAME) == before


def test_a_record_states_its_schema_and_application(tmp_path):
    from hapticopt.optim.recorder import APPLICATION, SCHEMA

    Recorder(tmp_path, fingerprint="f1", resume=False).close()
    with sqlite3.connect(tmp_path / FILENAME) as db:
        meta = dict(db.execute("SELECT key, value FROM meta"))
    assert meta["application"] == APPLICATION and meta["schema"] == str(SCHEMA) and meta["fingerprint"] == "f1"

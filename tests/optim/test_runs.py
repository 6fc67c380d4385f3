"""RunReader: read-only (checksums unchanged), reads a run while another process writes it,
reads records older than the self-describing tables, and the self-describing record itself."""

from __future__ import annotations

import hashlib
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hapticopt.design.errors import InvalidInput
from hapticopt.optim import driver
from hapticopt.optim.problem import load_problem
from hapticopt.optim.recorder import FILENAME, Recorder
from hapticopt.optim.runs import RunReader, find_runs, problem_info

DATA = Path(__file__).parent / "data"
ONLY = ("statics",)  # the problem's metrics all come from hapticopt.analysis.prrr.structure.statics
PROBLEM = DATA / "resume-problem.toml"


def _checksums(run_dir: Path) -> dict[str, str]:
    """The record and its write-ahead log, where they hold data. SQLite's -shm is a shared-memory
    index, not data; a WAL reader may create an empty -wal where the writer removed it."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(run_dir.glob(FILENAME + "*"))
            if not p.name.endswith("-shm") and p.stat().st_size > 0}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("run")
    problem = load_problem(PROBLEM).with_optimiser(max_evals=40)
    with Recorder(run_dir, fingerprint=problem.fingerprint(), resume=False,
                  search_fingerprint=problem.search_fingerprint()) as rec:
        rec.describe({**problem_info(problem), "status": "running"})
        res = driver.run(problem, only=ONLY, recorder=rec)
        rec.end_session(status="finished", n_evaluated=res.n_evaluated, n_replayed=res.n_replayed, max_evals=40)
    return run_dir, problem, res


def test_reader_never_writes_and_agrees_with_the_driver(recorded):
    run_dir, problem, res = recorded
    before = _checksums(run_dir)
    assert FILENAME in before
    with RunReader(run_dir) as r:
        cases = r.cases()
        best = r.best()
        cols, rows = r.history_table()
        summary = r.summary()
    assert _checksums(run_dir) == before
    assert len(cases) == res.n_evaluated and summary.status == "finished" and summary.repeated == 0
    # the reader's best (from the self-described objective and constraint) is the driver's best
    assert best.x == res.best.x and summary.best == res.best.objective and summary.feasible is res.feasible
    assert cols[5:7] == ["geometry.beta_deg [deg]", "actuator.spring_N_per_mm [N/mm]"]
    assert [v["key"] for v in r.variables] == [v.key for v in problem.variables]
    assert r.objectives == [{"metric": "jacobian_condition", "sense": "minimise"}]
    assert r.constraints == [{"metric": "stiffness_limit_N_per_mm[0]", "op": ">=", "value": 40.0}]
    assert r.info["versions"]["nlopt"] and r.info["problem_text"] == problem.source_text
    found = list(find_runs(run_dir.parent))
    assert run_dir in found and all((p / FILENAME).is_file() and not p.is_symlink() for p in found)


def test_reader_reads_while_another_process_writes(tmp_path):
    run_dir = tmp_path / "run"
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    proc = subprocess.Popen([sys.executable, str(DATA / "slow_run.py"), str(run_dir), "--delay", "0.03"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    seen: list[int] = []
    deadline = time.monotonic() + 60
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if (run_dir / FILENAME).exists():
                try:
                    with RunReader(run_dir) as r:
                        n = len(r)
                        assert len(r.cases()) >= n  # a consistent snapshot per query, never fewer rows
                except InvalidInput:  # the writer has created the file but not yet its tables
                    n = 0
                seen.append(n)
                if n >= 30:
                    break
            time.sleep(0.02)
    finally:
        proc.kill()
        proc.wait()
    assert seen == sorted(seen) and seen[-1] >= 30 and len(set(seen)) > 3  # watched it grow


def test_a_record_from_before_run_info_is_read_without_change(tmp_path):
    """tests/optim/data/pre-layout-run (29 evaluations, no run_info/designs tables)."""
    shutil.copy(DATA / "pre-layout-run" / FILENAME, tmp_path / FILENAME)
    before = _checksums(tmp_path)
    with RunReader(tmp_path) as r:
        assert len(r) == 29 and r.variables is None and r.best() is None and r.designs() == []
        s = r.summary()
        assert s.status == "unknown" and math.isnan(s.best) and s.feasible is None
        cols, rows = r.history_table()
        assert len(rows) == 29 and "x" in cols
    assert _checksums(tmp_path) == before


def test_reader_errors_are_one_line(tmp_path):
    with pytest.raises(InvalidInput, match="is not a run: no evaluations.sqlite"):
        RunReader(tmp_path)
    (tmp_path / FILENAME).write_text("not sqlite")
    with pytest.raises(InvalidInput, match="not a readable run record"):
        RunReader(tmp_path)


def test_an_older_status_word_reads_back_as_todays(tmp_path):
    """Records written before issue 21 say ``infeasible`` where ``not-met`` is now written
    (analysis/status.py LEGACY); the file itself is not changed by reading it."""
    import json
    import sqlite3

    shutil.copy(DATA / "pre-layout-run" / FILENAME, tmp_path / FILENAME)
    with sqlite3.connect(tmp_path / FILENAME) as db:  # the word an old free_workspace evaluator wrote
        db.execute("UPDATE evaluations SET statuses = ? WHERE id = (SELECT MIN(id) FROM evaluations)",
                   (json.dumps({"statics": "ok", "free_workspace": "infeasible"}),))
    before = _checksums(tmp_path)
    with RunReader(tmp_path) as r:
        first = r.cases()[0]
    assert first.statuses == {"statics": "ok", "free_workspace": "not-met"}
    assert _checksums(tmp_path) == before

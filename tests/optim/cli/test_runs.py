"""``hapticopt runs`` and ``hapticopt show``: list and show recorded runs (read-only)."""

from __future__ import annotations

import csv
import hashlib
import io
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim import driver
from hapticopt.optim.cli import app
from hapticopt.optim.problem import load_problem
from hapticopt.optim.recorder import FILENAME, Recorder
from hapticopt.optim.runs import problem_info

runner = CliRunner()
DATA = Path(__file__).parents[1] / "data"


@pytest.fixture(scope="module")
def runs_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("runs")
    problem = load_problem(DATA / "resume-problem.toml").with_optimiser(max_evals=30)
    with Recorder(root / "opt", fingerprint=problem.fingerprint(), resume=False) as rec:
        rec.describe({**problem_info(problem), "status": "running"})
        res = driver.run(problem, only=("statics",), recorder=rec)
        rec.end_session(status="finished", n_evaluated=res.n_evaluated, n_replayed=0, max_evals=30)
    out = runner.invoke(app, ["sweep", "--preset", "prrr-paper", "geometry.beta_deg=40:60:3", "--only", "statics",
                              "--scheduler", "inline", "--no-plots", "--quiet", "--out", str(root / "nested" / "sw")])
    assert out.exit_code == 0, out.output
    return root, res


def test_runs_lists_every_run(runs_dir):
    root, res = runs_dir
    listed = json.loads(runner.invoke(app, ["runs", str(root), "--json"]).stdout)
    by_path = {Path(r["path"]).name: r for r in listed}
    assert set(by_path) == {"opt", "sw"}
    assert by_path["opt"]["problem"] == "resume" and by_path["opt"]["evaluations"] == res.n_evaluated
    assert by_path["opt"]["best"] == res.best.objective and by_path["opt"]["feasible"] is res.feasible
    assert by_path["sw"]["kind"] == "sweep" and by_path["sw"]["evaluations"] == 3 and by_path["sw"]["best"] is None
    table = runner.invoke(app, ["runs", str(root)], env={"COLUMNS": "80"})
    assert table.exit_code == 0 and "opt" in table.stdout and "sweep" in table.stdout
    assert all(len(line) <= 80 for line in table.stdout.splitlines())


def test_show_table_csv_json_and_read_only(runs_dir):
    root, res = runs_dir
    db = root / "opt" / FILENAME
    before = hashlib.sha256(db.read_bytes()).hexdigest()
    table = runner.invoke(app, ["show", str(root / "opt")], env={"COLUMNS": "80"})
    assert table.exit_code == 0, table.output
    assert "best: evaluation" in table.stdout and "geometry.beta_deg" in table.stdout
    rows = list(csv.reader(io.StringIO(runner.invoke(app, ["show", str(root / "opt"), "--csv"]).stdout)))
    assert rows[0][5:7] == ["geometry.beta_deg [deg]", "actuator.spring_N_per_mm [N/mm]"]
    assert len(rows) == 1 + res.n_evaluated
    payload = json.loads(runner.invoke(app, ["show", str(root / "opt"), "--json"]).stdout)
    assert payload["best_case"]["x"] == list(res.best.x) and payload["sessions"][0]["evaluated"] == res.n_evaluated
    assert hashlib.sha256(db.read_bytes()).hexdigest() == before


@pytest.mark.parametrize("args, match", [
    (["show", "no/such/run"], "is not a run: no evaluations.sqlite"),
    (["runs", "no/such/dir"], "is not a folder"),
    (["show", ".", "--json", "--csv"], "at most one of --json and --csv"),
    (["show", ".", "--last", "-1"], "--last = -1 must be ≥ 0"),
])
def test_bad_input_one_line_exit_2(args, match):
    res = runner.invoke(app, args)
    assert res.exit_code == 2
    (line,) = res.stderr.strip().splitlines()
    assert match in line


def test_runs_skips_a_bad_record_with_a_warning_and_lists_the_rest(runs_dir, tmp_path):
    """Issue 37: one bad record under DIR made ``runs`` list nothing (exit 4)."""
    import shutil
    import sqlite3

    root, _ = runs_dir
    copy = tmp_path / "runs"
    shutil.copytree(root, copy)
    bad = copy / "bad"
    bad.mkdir()
    (bad / FILENAME).write_bytes(b"not a database" * 100)
    edited = copy / "edited"
    shutil.copytree(copy / "opt", edited)
    with sqlite3.connect(edited / FILENAME) as db:
        db.execute("UPDATE evaluations SET vals = '[1.0]' WHERE id = 1")
    res = runner.invoke(app, ["runs", str(copy), "--json"])
    assert res.exit_code == 0, res.output
    assert sorted(Path(r["path"]).name for r in json.loads(res.stdout)) == ["opt", "sw"]
    warnings = res.stderr.strip().splitlines()
    assert len(warnings) == 2 and all(w.startswith("warning: skipped ") for w in warnings)
    assert any("checksum" in w for w in warnings)


def test_show_on_a_recursive_view_returns_within_5_s(runs_dir, tmp_path):
    """Issue 37: a recursive SQLite view made ``show`` hang (> 120 s)."""
    import shutil
    import sqlite3
    import time

    root, _ = runs_dir
    run = tmp_path / "run"
    shutil.copytree(root / "opt", run)
    with sqlite3.connect(run / FILENAME) as db:
        db.executescript("DROP TABLE sessions; CREATE VIEW sessions AS WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL "
                         "SELECT x + 1 FROM c) SELECT x AS id, 0.0 AS started, 0 AS resumed FROM c;")
    t0 = time.monotonic()
    res = runner.invoke(app, ["show", str(run)])
    assert time.monotonic() - t0 < 5.0
    assert res.exit_code == 2, res.output
    (line,) = res.stderr.strip().splitlines()
    assert "view sessions" in line and "refused" in line


#: a problem whose start and neighbours cannot be assembled (failed evaluations in its record)
FAILING = (Path(__file__).parents[1] / "data" / "failing-start.toml").read_text()


def test_show_keeps_each_failure_reason_and_counts_them(tmp_path):
    """issue 33: `show` said evaluator_failed and the reason needed a re-evaluation. d2 = 290 mm and its
    neighbours cannot be assembled (tests/optim/cli/test_evaluate.py: d2 = 300 mm, no pose closes the chain)."""
    (tmp_path / "p.toml").write_text(FAILING)
    out = runner.invoke(app, ["optimise", str(tmp_path / "p.toml"), "--out", str(tmp_path / "run"), "--scheduler",
                              "inline", "--no-export", "--no-verify", "--quiet"])
    assert out.exit_code == 0, out.output
    shown = runner.invoke(app, ["show", str(tmp_path / "run")], env={"COLUMNS": "200"})
    assert shown.exit_code == 0, shown.output
    assert "failed evaluations: 4 of 4; by reason:" in shown.stdout
    assert "4 × evaluator_failed: statics: not-assemblable" in shown.stdout
    assert "statics: not-assemblable — " in shown.stdout and "does not close" in shown.stdout  # the message kept
    payload = json.loads(runner.invoke(app, ["show", str(tmp_path / "run"), "--json"]).stdout)
    assert payload["failures"]["count_by_reason"] == {"evaluator_failed: statics: not-assemblable": 4}
    assert all("does not close" in f["message"] and f["statuses"] == {"statics": "not-assemblable"}
               for f in payload["failures"]["evaluations"])
    assert payload["failed"] == 4


def test_runs_and_show_say_at_which_fidelity_the_best_holds(tmp_path):
    """issue 33: `runs` showed the draft best where the report showed the final (standard here) value."""
    data = Path(__file__).parents[1] / "data" / "beta-isotropic.toml"
    out = runner.invoke(app, ["optimise", str(data), "--out", str(tmp_path / "run"), "--scheduler", "inline",
                              "--no-export", "--no-verify", "--quiet", "--max-evals", "8"])
    assert out.exit_code == 0, out.output
    result = json.loads((tmp_path / "run" / "result.json").read_text())
    (row,) = json.loads(runner.invoke(app, ["runs", str(tmp_path), "--json"]).stdout)
    assert row["best_fidelity"] == "draft" and row["final_fidelity"] == "standard"
    assert row["final"] == result["objective"]["optimum"]  # the report's number, at the report's fidelity
    table = runner.invoke(app, ["runs", str(tmp_path)], env={"COLUMNS": "200"}).stdout
    assert "(draft); final" in table and "(standard)" in table
    shown = runner.invoke(app, ["show", str(tmp_path / "run")], env={"COLUMNS": "200"}).stdout
    assert "at draft fidelity" in shown and "final design (the optimum re-evaluated) at standard fidelity" in shown

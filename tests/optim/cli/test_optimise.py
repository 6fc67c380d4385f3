"""``hapticopt optimise`` / ``problems``: a run, --resume replays everything, bad problems exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app

runner = CliRunner()
DATA = Path(__file__).parents[1] / "data"


def invoke(*args: str):
    return runner.invoke(app, list(args))


def test_problems_lists_bundled():
    res = invoke("problems")
    assert res.exit_code == 0
    assert "prrr-workspace" in res.stdout and "master-transparency" in res.stdout


def test_optimise_then_resume_replays_everything(tmp_path):
    args = ["optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path), "--scheduler", "inline",
            "--no-export", "--no-verify", "--quiet", "--max-evals", "40"]
    first = invoke(*args)
    assert first.exit_code == 0, first.output
    assert "jacobian_condition baseline 2.44949 -> optimum 1.0" in first.stdout  # cond(J) at 60°: √6 (seed digest)
    assert "(improved)" in first.stdout
    r1 = json.loads((tmp_path / "result.json").read_text())
    again = invoke(*args, "--resume")
    assert again.exit_code == 0, again.output
    r2 = json.loads((tmp_path / "result.json").read_text())
    assert r2["n_evaluated"] == 0 and r2["n_replayed"] == r1["n_evaluated"]
    assert r2["best_x"] == r1["best_x"]
    # a different budget is a different run: resuming it is refused with one line
    bad = invoke(*args[:-2], "--max-evals", "30", "--resume")
    assert bad.exit_code == 2 and "different problem or optimiser settings" in bad.stderr


def _write(tmp_path, text):
    p = tmp_path / "p.toml"
    p.write_text(text)
    return str(p)


HEAD = 'name = "x"\nbase = "prrr-paper"\n'
VAR = '[[variables]]\nkey = "geometry.beta_deg"\nlower = 20.0\nupper = 70.0\n'
OBJ = '[objective]\nmetric = "jacobian_condition"\n'


@pytest.mark.parametrize("text, match", [
    (HEAD + VAR + '[objective]\nmetric = "no_such_metric_N"\n', "metric 'no_such_metric_N' is not computed"),
    (HEAD + '[[variables]]\nkey = "geometry.beta_deg"\nlower = 70.0\nupper = 20.0\n' + OBJ, "must be below upper"),
    (HEAD + '[[variables]]\nkey = "geometry.gamma_deg"\n' + OBJ, "is not a variable of the design"),
    (HEAD + '[[variables]]\nkey = "geometry.beta_deg"\nlower = 20.0\nupper = 50.0\n' + OBJ, "infeasible start"),
    (HEAD + VAR + OBJ + '[[constraints]]\nmetric = "max_force_N"\nmin = 3.0\n', "give a component index"),
    ("name = [\n", "is not valid TOML"),
])
def test_bad_problem_files_one_line_exit_2(tmp_path, text, match):
    res = invoke("optimise", _write(tmp_path, text), "--out", str(tmp_path / "run"), "--quiet",
                 "--scheduler", "inline")
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert match in lines[0]


def test_missing_problem_and_bad_options(tmp_path):
    res = invoke("optimise", "no-such-problem", "--quiet")
    assert res.exit_code == 2 and "allowed problems are" in res.stderr
    res = invoke("optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path), "--scheduler", "ftp://x",
                 "--quiet", "--no-export", "--no-verify")
    assert res.exit_code == 2 and "--scheduler" in res.stderr
    res = invoke("optimise", str(DATA / "beta-isotropic.toml"), "--max-evals", "1", "--quiet")
    assert res.exit_code == 2 and "--max-evals = 1" in res.stderr

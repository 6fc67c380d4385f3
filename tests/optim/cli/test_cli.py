"""The ``hapticopt`` application: every command has ``--json``, and it is machine-readable."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import typer.main
from typer.testing import CliRunner

from hapticopt.optim.cli import app

runner = CliRunner()
DATA = Path(__file__).parents[1] / "data"
COMMANDS = sorted(typer.main.get_command(app).commands)


def test_the_command_list_is_the_one_documented():
    assert COMMANDS == sorted(["evaluate", "presets", "export", "optimise", "problems", "verify", "runs", "show",
                               "sweep", "compare", "design-map", "metrics", "sensitivity", "tolerance"])


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_json(command):
    res = runner.invoke(app, [command, "--help"])
    assert res.exit_code == 0 and "--json" in res.stdout, command


@pytest.mark.parametrize("argv", [["presets", "--json"], ["problems", "--json"], ["metrics", "--json"]])
def test_listing_commands_print_json_lists(argv):
    res = runner.invoke(app, argv)
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    assert isinstance(rows, list) and rows and all("device" in r for r in rows)


def test_optimise_json_is_the_runs_result(tmp_path):
    res = runner.invoke(app, ["optimise", str(DATA / "beta-isotropic.toml"), "--out", str(tmp_path), "--scheduler",
                              "inline", "--max-evals", "12", "--no-export", "--no-verify", "--quiet", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout) == json.loads((tmp_path / "result.json").read_text())

"""Every ``--json`` of the README's commands is RFC 8259 JSON (issue 33): a strict parser — one that
raises on ``NaN``/``Infinity`` as ``JSON.parse`` does — reads it, including a design whose evaluators
fail (NaN metrics) and a run whose history holds such failures; each null number is named under
``null_numbers`` with what it stands for."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.optim.cli import app
from hapticopt.optim.strict_json import NULL_NUMBERS, dumps, loads

runner = CliRunner()
README = Path(__file__).parents[3] / "README.md"
PRESETS = Path(__file__).parents[3] / "design" / "presets"

#: a problem whose start (d2 = 290 mm) and neighbours cannot be assembled: its history holds NaN values
FAILING_PROBLEM = (Path(__file__).parents[1] / "data" / "failing-start.toml").read_text()
SCENE = ('name = "short"\nduration_s = 0.5\n[environment]\nkind = "spring"\nstiffness_N_per_mm = [25.0, 0, 0]\n'
         '[motion]\namplitude_mm = [4.0, 0, 0]\n')


def readme_commands() -> set[str]:
    """The commands the README's Commands block runs."""
    block = README.read_text(encoding="utf-8").split("## Commands", 1)[1].split("```sh", 1)[1].split("```", 1)[0]
    return set(re.findall(r"hapticopt ([a-z-]+)", block))


def _argvs(tmp: Path) -> dict[str, list[list[str]]]:
    (tmp / "p.toml").write_text(FAILING_PROBLEM)
    (tmp / "scene.toml").write_text(SCENE)
    paper = (PRESETS / "prrr-paper.toml").read_text(encoding="utf-8")
    (tmp / "d2-300.toml").write_text(re.sub(r"(?m)^d2_mm = .*$", "d2_mm = 300.0", paper)
                                     .replace('name = "prrr-paper"', 'name = "d2-300"'))
    run = str(tmp / "run")
    return {  # in order: optimise writes the run that runs, show and compare read
        "presets": [["presets", "--json"]],
        "problems": [["problems", "--json"]],
        "metrics": [["metrics", "--device", "prrr", "--json"]],
        "evaluate": [["evaluate", "--preset", "prrr-paper", "--fidelity", "draft", "--json"],
                     ["evaluate", "--preset", "prrr-paper", "--set", "geometry.d2_mm=300", "--fidelity", "draft",
                      "--json"]],
        "optimise": [["optimise", str(tmp / "p.toml"), "--out", run, "--scheduler", "inline", "--no-export",
                      "--no-verify", "--quiet", "--json"]],
        "runs": [["runs", str(tmp), "--json"]],
        "show": [["show", run, "--json"]],
        "compare": [["compare", "prrr-paper", str(tmp / "d2-300.toml"), "--fidelity", "draft", "--json"]],
        "sweep": [["sweep", "--preset", "prrr-paper", "geometry.d2_mm=100:300:3", "--only", "statics", "--scheduler",
                   "inline", "--no-plots", "--quiet", "--out", str(tmp / "sw"), "--json"]],
        "verify": [["verify", "--preset", "prrr-paper", "--scene", str(tmp / "scene.toml"), "--json"]],
        "design-map": [["design-map", "--preset", "prrr-paper", "--periods-ms", "1", "--force-gains", "45",
                        "--duration-s", "0.6", "--json"]],
        "sensitivity": [["sensitivity", "--preset", "prrr-paper", "--evaluator", "statics", "--fidelity", "draft",
                         "--json"]],
        "tolerance": [["tolerance", "--preset", "prrr-paper", "--samples", "4", "--json"]],
        "export": [["export", "--preset", "prrr-paper", "--out", str(tmp / "export"), "--json"]],
    }


def test_the_strict_parser_refuses_nan_and_dumps_writes_null():
    with pytest.raises(ValueError, match="NaN is not JSON"):
        loads('{"a": NaN}')
    with pytest.raises(ValueError, match="Infinity is not JSON"):
        loads("[-Infinity]")
    text = dumps({"metrics": {"a": float("nan"), "b": [1.5, float("inf")]}, "status": {"x": "failed"}})
    assert loads(text) == {"metrics": {"a": None, "b": [1.5, None]}, "status": {"x": "failed"},
                           NULL_NUMBERS: {"/metrics/a": "NaN", "/metrics/b/1": "Infinity"}}
    assert loads(dumps([{"v": float("-inf")}, {"v": 1}])) == [{"v": None, NULL_NUMBERS: {"/v": "-Infinity"}},
                                                              {"v": 1}]
    assert loads(dumps({"v": 0.1 + 0.2})) == {"v": 0.1 + 0.2}  # finite numbers read back bit-equal


def test_every_readme_command_prints_strict_json(tmp_path):
    argvs = _argvs(tmp_path)
    missing = readme_commands() - set(argvs)
    assert not missing, f"README commands without a strict-JSON case here: {sorted(missing)}"
    out = {}
    for command, cases in argvs.items():
        for argv in cases:
            res = runner.invoke(app, argv)
            assert res.exit_code in (0, 3), f"{argv}: {res.output}"
            try:
                out[" ".join(argv)] = loads(res.stdout)
            except ValueError as exc:
                pytest.fail(f"{command} --json is not RFC 8259 JSON: {exc}")
    failing = out["evaluate --preset prrr-paper --set geometry.d2_mm=300 --fidelity draft --json"]
    assert failing["metrics"]["jacobian_condition"] is None
    assert failing[NULL_NUMBERS]["/metrics/jacobian_condition"] == "NaN"
    assert failing["status"]["statics"] == "not-assemblable"  # the status says why it is null
    shown = out[f"show {tmp_path / 'run'} --json"]
    assert any(k.startswith("/history/rows/") for k in shown[NULL_NUMBERS])  # the failed points' values

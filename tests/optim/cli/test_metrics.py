"""``hapticopt metrics``: the glossary from the registry; docs/metrics.md is its generated copy."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from hapticopt.analysis.registry import EVALUATORS
from hapticopt.optim.cli import app
from hapticopt.optim.cli.metrics import markdown

runner = CliRunner()
DOC = Path(__file__).resolve().parents[3] / "docs" / "metrics.md"


def test_docs_metrics_md_is_generated_from_the_registry():
    assert DOC.read_text(encoding="utf-8") == markdown(), \
        "docs/metrics.md is stale: run scripts/gen_metrics_doc.py and commit the result"


def test_json_lists_every_registered_metric_once_per_device():
    res = runner.invoke(app, ["metrics", "--json"])
    assert res.exit_code == 0, res.output
    rows = json.loads(res.stdout)
    assert [(r["device"], r["metric"]) for r in rows] == [(d, m.name) for d, es in EVALUATORS.items()
                                                          for e in es for m in e.metrics]
    stiff = next(r for r in rows if r["device"] == "prrr" and r["metric"] == "stiffness_limit_N_per_mm")
    assert stiff["unit"] == "N/mm" and stiff["evaluator"] == "statics" and stiff["fidelities"] == [
        "draft", "standard", "fine"] and "eq 14" in stiff["description"]


def test_device_filter_and_table():
    res = runner.invoke(app, ["metrics", "--device", "handle"])
    assert res.exit_code == 0, res.output
    assert "zwidth_stable_fraction" in res.stdout and "N/mm" in res.stdout
    assert "max_force_N" not in res.stdout  # a 3-PRRR metric


def test_unknown_device_is_one_line_exit_2():
    res = runner.invoke(app, ["metrics", "--device", "robot"])
    assert res.exit_code == 2
    assert res.output.strip() == "error: --device = 'robot' is not a device: allowed prrr, master, handle"

"""``hapticopt compare``: prrr-paper against the prrr-workspace optimum shows every metric with its
delta; presets, files and run directories resolve; bad input is one line, exit 2."""

from __future__ import annotations

import html
import json
import math
import re
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.analysis.registry import evaluate_all, metric_unit
from hapticopt.design import io
from hapticopt.optim.cli import app
from hapticopt.optim.sweep import scalars

runner = CliRunner()
#: Regression snapshot: the optimum.toml of `hapticopt optimise prrr-workspace --no-export --no-verify`
#: (issue 20 branch, 2026-11-26); regenerate with that command and copy cad_out/prrr-workspace/optimum.toml.
OPTIMUM = Path(__file__).parents[1] / "data" / "prrr-workspace-optimum.toml"


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("prrr-workspace")
    shutil.copy(OPTIMUM, d / "optimum.toml")
    return d


def test_compare_prrr_paper_and_the_prrr_workspace_optimum(run_dir, tmp_path):
    res = runner.invoke(app, ["compare", "prrr-paper", str(run_dir), "--fidelity", "draft", "--json",
                              "--report", str(tmp_path / "c.md")])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert [d["source"] for d in out["designs"]] == ["preset prrr-paper", f"run {run_dir} (optimum.toml)"]
    # every metric component of both designs, each with its delta from prrr-paper
    paper = evaluate_all(io.load_preset("prrr-paper"), fidelity=Fidelity.DRAFT)
    opt = evaluate_all(io.load_design(OPTIMUM), fidelity=Fidelity.DRAFT)
    expected = [k for name, v in paper.metrics().items() for k, _ in scalars(name, v)]
    rows = {r["metric"]: r for r in out["metrics"]}
    assert list(rows) == expected and len(expected) >= 30
    flat_p = dict(kv for n, v in paper.metrics().items() for kv in scalars(n, v))
    flat_o = dict(kv for n, v in opt.metrics().items() for kv in scalars(n, v))
    def same(json_value, value):  # JSON has no NaN: a metric that does not hold is null there
        return (json_value is None and math.isnan(value)) or json_value == value

    for name, r in rows.items():
        assert same(r["values"][0], flat_p[name]) and same(r["values"][1], flat_o[name])
        assert same(r["deltas"][1], flat_o[name] - flat_p[name])  # Δ = optimum − reference, every metric
    assert rows["workspace_free_footprint_ratio"]["deltas"][1] > 0  # the problem's objective improved
    assert rows["stiffness_limit_N_per_mm[0]"]["unit"] == "N/mm" and rows["jacobian_condition"]["unit"] == "-"
    # every evaluator's status is reported, by its name (a value that does not hold is null beside it)
    assert all(set(d["statuses"]) == set(paper.statuses) for d in out["designs"])
    assert all(s in {str(v) for v in Status} for d in out["designs"] for s in d["statuses"].values())
    md = (tmp_path / "c.md").read_text()
    assert md.count("\n| ") >= len(expected) and "| workspace_footprint_ratio | - |" in md


def test_compare_table_at_80_columns(run_dir):
    res = runner.invoke(app, ["compare", "prrr-paper", str(run_dir), "--fidelity", "draft"], env={"COLUMNS": "80"})
    assert res.exit_code == 0, res.output
    assert all(len(line) <= 80 for line in res.stdout.splitlines())
    assert "Δ" in res.stdout and "all evaluators ok" in res.stdout


@pytest.mark.parametrize("args, match", [
    (["prrr-paper"], "at least 2 designs"),
    (["prrr-paper", "no-such-design"], "is not a file, a run directory or a preset"),
    (["prrr-paper", "master-paper", "--fidelity", "coarse"], "--fidelity = 'coarse'"),
    (["prrr-paper", "master-paper", "--renders"], "--renders needs --report"),
    (["prrr-paper", "master-paper", "--report", "x.pdf"], "must end in .md or .html"),
])
def test_bad_compare_one_line_exit_2(args, match, tmp_path):
    res = runner.invoke(app, ["compare", *args])
    assert res.exit_code == 2
    (line,) = res.stderr.strip().splitlines()
    assert match in line


def test_compare_a_run_without_optimum_toml_uses_the_recorded_final_design(tmp_path):
    from hapticopt.optim import compare as cmp

    res = runner.invoke(app, ["optimise", str(Path(__file__).parents[1] / "data" / "beta-isotropic.toml"), "--out",
                              str(tmp_path), "--scheduler", "inline", "--no-export", "--no-verify", "--quiet",
                              "--max-evals", "12"])
    assert res.exit_code == 0, res.output
    (tmp_path / "optimum.toml").unlink()
    named = cmp.resolve(str(tmp_path))
    assert named.source.endswith("(recorded final design)")
    assert math.isclose(math.degrees(named.design.geometry.beta), json.loads(
        (tmp_path / "result.json").read_text())["best_x"]["geometry.beta_deg"], rel_tol=1e-12)


def test_compare_reuses_the_evaluation_cache_and_says_so(run_dir, tmp_path):
    cache = tmp_path / "c.sqlite"
    args = ["compare", "prrr-paper", str(run_dir), "--fidelity", "draft", "--json", "--cache", str(cache)]
    first = runner.invoke(app, args)
    again = runner.invoke(app, args)
    assert first.exit_code == 0 and again.exit_code == 0, first.output + again.output
    a, b = json.loads(first.stdout), json.loads(again.stdout)
    assert [d["evaluation"] for d in a["designs"]] == ["computed", "computed"]
    assert all(d["evaluation"].startswith(f"from the evaluation cache {cache}") for d in b["designs"])
    assert a["metrics"] == b["metrics"]
    off = runner.invoke(app, args[:-2] + ["--no-cache"])
    assert off.exit_code == 0 and [d["evaluation"] for d in json.loads(off.stdout)["designs"]] == ["computed"] * 2


def _delta_classes(page: str, metric: str) -> list[str]:
    """The verdict class of each Δ cell of ``metric``'s row in the compare HTML."""
    row = re.search(rf"<tr data-metric='{re.escape(metric)}'>(.*?)</tr>", page)
    assert row, metric
    return re.findall(r"<td class='n (\w*)' title=", row.group(1))


def test_compare_colours_by_better_or_worse_not_by_sign(run_dir, tmp_path):
    """issue 33: a heavier device and a worse Jacobian condition were green (the delta was positive).
    The prrr-workspace optimum is heavier (mass +0.7 %) with a better cond(J) (β 60° → nearer the isotropic
    35.26°, seed 002 eq 2); against the optimum, prrr-paper has the worse (larger) cond(J). (β beyond 60° is
    not a buildable prrr-paper: the R3 lugs hit the stem.)"""
    def page_of(*designs: str) -> tuple[str, dict[str, list[float]]]:
        out = tmp_path / f"c{len(list(tmp_path.iterdir()))}.html"
        res = runner.invoke(app, ["compare", *designs, "--fidelity", "draft", "--report", str(out)])
        assert res.exit_code == 0, res.output
        page = out.read_text(encoding="utf-8")
        return page, {m: [float(v) for v in re.findall(r"<td class='n'>([-+0-9.e]+)</td>", re.search(
            rf"<tr data-metric='{m}'>(.*?)</tr>", page).group(1))] for m in ("device_mass_kg", "jacobian_condition")}

    page, values = page_of("prrr-paper", str(run_dir))
    assert values["device_mass_kg"][1] > values["device_mass_kg"][0]  # the optimum is heavier …
    assert _delta_classes(page, "device_mass_kg") == ["worse"]  # … and that is worse
    assert values["jacobian_condition"][1] < values["jacobian_condition"][0]  # its cond(J) is smaller: better
    assert _delta_classes(page, "jacobian_condition") == ["better"]
    assert _delta_classes(page, "workspace_required_diameter_mm") == ["same"]  # a design input: equal
    assert _delta_classes(page, "elastic_centre_mm")[0] == "changed"  # neutral: neither colour
    assert "rounding and shown as =" in page  # the tolerance is stated
    units = re.findall(r"<tr data-metric='([^']+)'><td>[^<]*</td><td>([^<]*)</td>", page)
    assert len(units) > 50
    for name, unit in units:  # issue 33: units from the registry (von Mises per newton was "N")
        assert html.unescape(unit) == (metric_unit(name) or "-"), (name, unit)
    page, values = page_of(str(run_dir), "prrr-paper")  # the other way round: a larger cond(J) is worse
    assert values["jacobian_condition"][1] > values["jacobian_condition"][0]
    assert _delta_classes(page, "jacobian_condition") == ["worse"]
    assert _delta_classes(page, "device_mass_kg") == ["better"]


def test_a_named_choice_that_differs_is_shown_as_text(tmp_path):
    """A design key that is a name (``structure.material``) compared as text, not as a number (the
    compare of prrr-paper against any design ended in an internal error once designs carried a material)."""
    other = io.apply_overrides(io.load_preset("prrr-paper"), ["structure.material=7075-T6", "name=prrr-7075"])
    io.save_design(other, tmp_path / "d.toml")
    res = runner.invoke(app, ["compare", "prrr-paper", str(tmp_path / "d.toml"), "--fidelity", "draft", "--json"])
    assert res.exit_code == 0, res.output
    rows = {r["key"]: r["values"] for r in json.loads(res.stdout)["design_differences"]}
    assert rows["structure.material"] == ["6061-T6", "7075-T6"]

"""The sweep's overview page: files written, every plotted metric named on the page with its unit from the
registry, points that are not ok (no numbers) or not met (a requirement fails) classed and listed, 2-D sweeps
drawn as heat maps, constant metrics named instead of plotted."""

from __future__ import annotations

import html
import re

import numpy as np
import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import metric_unit
from hapticopt.design import io
from hapticopt.optim import sweep_overview as ov
from hapticopt.optim.evaluation import Outcome, PointResult
from hapticopt.optim.executor import InlineExecutor
from hapticopt.optim.sweep import Sweep, parse_axis, run_sweep, write_outputs

BASE = io.load_preset("prrr-paper")


def _run(*axes: str, only=("statics",)):
    spec = Sweep(base=BASE, axes=tuple(parse_axis(a, BASE) for a in axes), fidelity=Fidelity.DRAFT, only=only)
    return run_sweep(spec, executor=InlineExecutor())


@pytest.fixture(scope="module")
def one_d(tmp_path_factory):
    # beta = 70 deg cannot be laid out with prrr-paper's b5 (statics: not-assemblable): one point is not ok
    result = _run("geometry.beta_deg=40:70:4")
    out = tmp_path_factory.mktemp("sweep1d")
    return result, out, write_outputs(result, out)


def _metrics_on_page(page: str) -> dict[str, str]:
    return {html.unescape(m): html.unescape(u) for m, u in
            re.findall(r"<tr data-metric='([^']*)'><td>[^<]*</td><td>([^<]*)</td>", page)}


def test_the_overview_files_are_written_and_listed(one_d):
    result, out, written = one_d
    assert out / "overview.png" in written and out / "overview.html" in written
    assert (out / "overview.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "overview.png").stat().st_size > 10_000
    assert "src='overview.png'" in (out / "overview.html").read_text()


def test_the_page_names_each_plotted_metric_with_its_registry_unit(one_d):
    result, out, _ = one_d
    page = (out / "overview.html").read_text()
    shown = _metrics_on_page(page)
    # what varies over beta among statics' scalar columns (the CSV's columns minus the constant ones)
    cols = (out / "sweep.csv").read_text().splitlines()[0].split(",")[2:]  # after the key and the outcome
    assert set(shown) <= set(cols) and shown
    assert "max_force_N[0]" in shown and "jacobian_condition" in shown and "stiffness_limit_N_per_mm[0]" in shown
    for name, unit in shown.items():
        assert unit == (metric_unit(name) or "-"), name
    assert shown["max_force_N[0]"] == "N" and shown["stiffness_limit_N_per_mm[0]"] == "N/mm"
    # max_force_N[2] (the z force) does not depend on beta: named as constant, not plotted
    assert "max_force_N[2]" not in shown and re.search(r"Constant over the sweep \(not plotted\): [^<]*max_force_N\[2\]",
                                                       page)


def test_the_point_that_is_not_ok_is_classed_and_listed_with_its_reason(one_d):
    result, out, _ = one_d
    classes = [ov.point_class(r) for r in result.results]
    assert classes == [ov.OK, ov.OK, ov.OK, ov.NOT_OK]  # 40, 50, 60 deg build; 70 deg does not
    page = (out / "overview.html").read_text()
    assert "4 points, 3 ok (0 of them with a requirement not met), 1 not ok" in page
    assert re.search(r"<td class='n'>70</td><td>evaluator_failed</td><td>statics: not-assemblable", page)


def test_not_met_is_an_ok_outcome_with_a_status_that_is_not_ok():
    met = PointResult(x=(1.0,), outcome=Outcome.OK, statuses={"statics": "ok", "interference": "ok"})
    unmet = PointResult(x=(1.0,), outcome=Outcome.OK, statuses={"statics": "ok", "interference": "collides"})
    failed = PointResult(x=(1.0,), outcome=Outcome.INVALID_DESIGN, message="bore ≥ boss; more")
    assert [ov.point_class(r) for r in (met, unmet, failed)] == [ov.OK, ov.NOT_MET, ov.NOT_OK]
    assert ov.reason(unmet) == "interference: collides" and ov.reason(failed) == "invalid_design: bore ≥ boss"


def test_constant_and_empty_columns_are_not_plotted():
    data = np.array([[1.0, 5.0, np.nan, 2.0], [2.0, 5.0 * (1 + 1e-15), np.nan, np.nan]])
    plotted, constant, empty = ov.chosen(["a", "b", "c", "d"], data)
    assert plotted == [0] and constant == ["b", "d"] and empty == ["c"]


def test_shaded_spans_are_runs_of_points_that_are_not_ok():
    assert ov._runs(np.array([0, 1, 1, 0, 2, 1])) == [(1, 2, 1), (4, 4, 2), (5, 5, 1)]
    # the span of point i reaches halfway to its neighbours, a half step past the ends
    assert ov._edges(np.array([0.0, 1.0, 3.0])).tolist() == [-0.5, 0.5, 2.0, 4.0]


def test_a_2d_sweep_draws_heat_maps(tmp_path):
    result = _run("geometry.beta_deg=45:75:3", "actuator.spring_N_per_mm=40:60:2")
    written = write_outputs(result, tmp_path)
    assert tmp_path / "overview.png" in written
    page = (tmp_path / "overview.html").read_text()
    assert "geometry.beta_deg (3) × actuator.spring_N_per_mm (2)" in page and "6 points, 4 ok (0 of them with a requirement not met), 2 not ok" in page
    shown = _metrics_on_page(page)
    assert shown["stiffness_limit_N_per_mm[0]"] == "N/mm"  # varies with the spring and with beta

"""Problem TOML: parsing, defaults from the design metadata, metric references, one-line errors."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from hapticopt.design.errors import InputFileError, InvalidInput, UnknownName
from hapticopt.optim.problem import (
    Algorithm,
    MetricRef,
    Op,
    Sense,
    check_metrics,
    load_problem,
    problem_from_dict,
    problem_names,
)

DATA = Path(__file__).parent / "data"


def base_problem(**changes):
    d = {"name": "t", "base": "prrr-paper",
         "variables": [{"key": "geometry.beta_deg", "lower": 10.0, "upper": 80.0}],
         "objective": {"metric": "jacobian_condition", "sense": "minimise"},
         "constraints": [{"metric": "max_force_N[2]", "min": 1000.0}]}
    d.update(changes)
    return d


def test_bundled_problems_load():
    assert {"prrr-workspace", "master-transparency"} <= set(problem_names())
    p = load_problem("prrr-workspace")
    assert p.device == "prrr" and p.objective.sense is Sense.MAXIMISE
    assert p.objective.metric.name == "workspace_free_device_ratio"  # issue 30: the whole device, links included
    assert {v.key for v in p.variables} >= {"geometry.r_p_mm", "geometry.theta_1p_deg"}
    # issue 30 item 3: both bundled 3-PRRR problems bound the whole device and steer on collision-free metrics
    for name in ("prrr-workspace", "prrr-pareto"):
        q = load_problem(name)
        limits = {c.metric.name: (c.op, c.value) for c in q.constraints}
        assert limits["device_diameter_mm"][0] is Op.LE and limits["device_height_mm"][0] is Op.LE, name
        assert limits["workspace_free_height_at_diameter_mm"] == (Op.GE, 89.0), name
        assert "interference_overlap_fraction" not in limits, name
    assert [o.metric.name for o in load_problem("prrr-pareto").objectives][0] == "workspace_free_device_ratio"
    m = load_problem("master-transparency")
    assert m.device == "master"
    assert m.constraints[0].op is Op.LE and m.constraints[0].value == 0.1  # seed 003: 0.1 N unbalance


def test_problem_file_path_and_fields():
    p = load_problem(DATA / "beta-isotropic.toml")
    assert p.name == "beta-isotropic"
    (v,) = p.variables
    assert (v.key, v.lower, v.upper, v.start) == ("geometry.beta_deg", 10.0, 80.0, 60.0)  # start: prrr-paper β
    assert p.optimiser.algorithm is Algorithm.LN_COBYLA and p.optimiser.starts == 2
    assert str(p.fidelity_optimise) == "draft" and str(p.fidelity_final) == "standard"


def test_default_bounds_come_from_the_field_metadata():
    p = problem_from_dict(base_problem(variables=[{"key": "geometry.d3_mm"}]))
    (v,) = p.variables
    # design/prrr/params.py: d3_mm is 0 < d3 ≤ 2000 mm (open at 0: kept strictly inside)
    assert v.upper == 2000.0 and 0.0 < v.lower < 1e-2
    b = problem_from_dict(base_problem(variables=[{"key": "geometry.beta_deg"}])).variables[0]
    assert 0.0 < b.lower < 1e-3 and 90.0 - 1e-3 < b.upper < 90.0  # 0 < β < 90° (open)


def test_metric_refs_pick_components():
    metrics = {"a": 2.0, "v": [1.0, 5.0, 3.0], "m": [[1.0, 2.0], [3.0, 4.0]], "flag": True}
    assert MetricRef.parse("a", "x").value(metrics) == 2.0
    assert MetricRef.parse("v[1]", "x").value(metrics) == 5.0
    assert MetricRef.parse("m[1][0]", "x").value(metrics) == 3.0
    assert MetricRef.parse("m[0, 1]", "x").value(metrics) == 2.0
    assert MetricRef.parse("min(v)", "x").value(metrics) == 1.0
    assert MetricRef.parse("max(m)", "x").value(metrics) == 4.0
    assert math.isnan(MetricRef.parse("v", "x").value(metrics))  # a vector is not a scalar
    assert math.isnan(MetricRef.parse("v[7]", "x").value(metrics))
    assert math.isnan(MetricRef.parse("missing", "x").value(metrics))
    with pytest.raises(InvalidInput, match="not a metric reference"):
        MetricRef.parse("v[", "objective.metric")


def test_check_metrics_names_unknown_metric_and_missing_index():
    with pytest.raises(UnknownName, match="no_such_metric.*is not a metric of a prrr design; no metric name is close"):
        problem_from_dict(base_problem(objective={"metric": "no_such_metric"}))  # found before any evaluation
    p = problem_from_dict(base_problem(objective={"metric": "max_force_N"}))
    with pytest.raises(InvalidInput, match=r"give a component index such as max_force_N\[0\]"):
        check_metrics(p, {"jacobian_condition": 1.0, "max_force_N": [1.0, 2.0, 3.0]})


@pytest.mark.parametrize("changes, match", [
    ({"variables": [{"key": "geometry.beta_deg", "lower": 70.0, "upper": 20.0}]}, "lower = 70 must be below upper = 20"),
    ({"variables": [{"key": "geometry.no_such_mm"}]}, "is not a variable of the design"),
    ({"variables": [{"key": "wheels.beta_deg"}]}, "wheels is not a section"),
    ({"variables": [{"key": "geometry.beta_deg", "lower": 10.0, "upper": 40.0}]}, "infeasible start.*60"),
    ({"variables": [{"key": "geometry.beta_deg", "lower": 10.0, "upper": 40.0, "start": 45.0}]}, "infeasible start: start 45"),
    ({"variables": [{"key": "geometry.beta_deg", "lower": -5.0, "upper": 40.0}]}, "outside the field's range"),
    ({"variables": [{"key": "structure.bore_diameter_mm", "lower": 1.0, "upper": 40.0, "start": 30.0}]},
     "infeasible start: .*bore_diameter_mm = 30 must be smaller"),
    ({"variables": []}, "at least one design variable"),
    ({"objective": {"metric": "jacobian_condition", "sense": "maximize"}}, "allowed minimise, maximise"),
    ({"constraints": [{"metric": "max_force_N[0]"}]}, "needs min"),
    ({"constraints": [{"metric": "max_force_N[0]", "min": 5.0, "max": 1.0}]}, "must not exceed max"),
    ({"optimiser": {"algorithm": "LN_NELDERMEAD"}}, "is not allowed: allowed LN_COBYLA"),
    ({"optimiser": {"algorithm": "LN_BOBYQA"}}, "cannot handle constraints"),
    ({"optimiser": {"local": "GN_ISRES"}}, "must be a local algorithm"),
    ({"optimiser": {"starts": 0}}, "whole number: allowed 1 ≤ starts ≤ 1000"),
    ({"optimiser": {"tolerance": 1}}, "optimiser.tolerance is not a known key"),
    ({"base": "no-such-preset"}, "preset 'no-such-preset' does not exist"),
    ({"colour": "red"}, "colour is not a known key"),
    ({"fidelity": {"optimise": "ultra"}}, "allowed draft, standard, fine"),
    # issue 33: did-you-mean for metric names, keys and values; fidelity of a metric; all before any work
    ({"constraints": [{"metric": "workspace_volum_mm3", "min": 1.0}]},
     r"constraints \(workspace_volum_mm3 >= 1\)\.metric = 'workspace_volum_mm3': .*did you mean workspace_volume_mm3\?"),
    ({"objective": {"metric": "max_forse_N[0]", "sense": "maximise"}}, "did you mean max_force_N"),
    ({"objective": {"metric": "jacobian_condition", "sense": "minimize"}}, "did you mean minimise"),
    ({"optimiser": {"max_eval": 10}}, "optimiser.max_eval is not a known key.*did you mean max_evals"),
    ({"constraints": [{"metric": "max_force_N[0]", "minimum": 1.0}]}, "did you mean min"),
    ({"variables": [{"key": "geometry.beta_dg"}]}, "did you mean beta_deg"),
    ({"fidelity": {"optimise": "darft"}}, "did you mean draft"),
    ({"objective": {"metric": "structural_fea_max_von_mises_MPa_per_N"}},
     "reported only at fine fidelity, but the problem evaluates it at draft"),
])
def test_bad_problems_raise_one_line_errors(changes, match):
    with pytest.raises((InvalidInput, UnknownName, InputFileError)) as info:
        problem_from_dict(base_problem(**changes), source="bad.toml")
    assert "\n" not in str(info.value)
    assert info.match(match)


def test_unknown_problem_name_and_bad_toml(tmp_path):
    with pytest.raises(UnknownName, match="allowed problems are .*prrr-workspace"):
        load_problem("no-such-problem")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(InputFileError, match="bad.toml is not valid TOML"):
        load_problem(bad)


def test_base_file_relative_to_problem(tmp_path):
    from hapticopt.design import io

    io.save_design(io.load_preset("prrr-paper"), tmp_path / "mine.toml")
    d = base_problem()
    del d["base"]
    d["base_file"] = "mine.toml"
    p = problem_from_dict(d, base_dir=tmp_path)
    assert p.base.geometry == io.load_preset("prrr-paper").geometry
    assert p.base_source.endswith("mine.toml")


def test_design_at_sets_edge_unit_values_and_fingerprint_tracks_settings():
    p = problem_from_dict(base_problem())
    d = p.design_at([35.0])
    assert d.geometry.beta == pytest.approx(math.radians(35.0), rel=1e-15)
    assert p.fingerprint() == problem_from_dict(base_problem()).fingerprint()
    assert p.fingerprint() != p.with_optimiser(seed=5).fingerprint()

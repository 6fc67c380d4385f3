"""Design points: a result whose evaluator status says its numbers do not hold is a failed point."""

from __future__ import annotations

import math

import pytest

from hapticopt.analysis.compute import Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.optim import evaluation as E
from hapticopt.optim.evaluation import GradientMode, Outcome, PointTask, evaluate_point
from hapticopt.optim.problem import problem_from_text

PROBLEM = '''
name = "bore"
base = "prrr-paper"
[[variables]]
key = "structure.bore_diameter_mm"
lower = 0.0005
upper = 12.0
[[variables]]
key = "geometry.beta_deg"
lower = 1e-9
upper = 89.9
[objective]
metric = "structural_stiffness_N_per_mm[0]"
sense = "maximise"
[[constraints]]
metric = "stiffness_limit_N_per_mm[0]"
min = 1.0
'''


@pytest.mark.hardcase
@pytest.mark.parametrize("bore_mm, beta_deg, outcome, why", [
    (8.0, 60.0, Outcome.OK, ""),
    # issue 14: a 1 µm bore gave k_x = −2.4e-11 N/mm to the optimiser (frame condition ~9e17: singular)
    (0.001, 60.0, Outcome.EVALUATOR_FAILED, "structural_stiffness: singular"),
    # β = 1e-7°: the chain does not close (|ρ| ≈ 1.7e10 mm at home), so no evaluator runs and each says
    # not-assemblable (the statics' own ill-conditioned status at small β: tests/analysis/prrr/structure/test_statics.py)
    (8.0, 1e-7, Outcome.EVALUATOR_FAILED, "statics: not-assemblable"),
])
def test_a_point_with_a_non_ok_status_is_failed_not_a_number(bore_mm, beta_deg, outcome, why):
    p = problem_from_text(PROBLEM, source="bore.toml", base_dir=None)
    refs = (p.objective.metric,) + tuple(c.metric for c in p.constraints)
    r = evaluate_point(PointTask(base=p.base, variables=p.variables, x=(bore_mm, beta_deg), fidelity=Fidelity.DRAFT,
                                 refs=refs, only=("statics", "structural_stiffness")))
    assert r.outcome is outcome, r.message
    assert why in r.message
    assert all(math.isnan(v) for v in r.values) == (outcome is not Outcome.OK)


def _task(p, compute, x=(8.0, 60.0), gradient=GradientMode.NONE):
    refs = tuple(c.metric for c in p.constraints)  # the statics' stiffness limit
    return PointTask(base=p.base, variables=p.variables, x=x, fidelity=Fidelity.DRAFT, refs=refs,
                     only=("statics",), compute=compute, gradient=gradient)


def test_a_point_hands_its_route_to_the_registry(monkeypatch):
    """The task's Compute reaches ``evaluate_all`` (one point) and ``evaluate_batch`` (many points, grouped
    by route; the finite-difference designs of a point)."""
    p = problem_from_text(PROBLEM, source="bore.toml", base_dir=None)
    seen = []
    real_all, real_batch = E.evaluate_all, E.evaluate_batch
    monkeypatch.setattr(E, "evaluate_all", lambda d, **kw: seen.append(("all", kw["compute"])) or real_all(d, **kw))
    monkeypatch.setattr(E, "evaluate_batch",
                        lambda ds, **kw: seen.append(("batch", kw["compute"], len(ds))) or real_batch(ds, **kw))
    one, two = Compute(backend="numpy", threads=1), Compute(threads=2)
    assert evaluate_point(_task(p, one)).outcome is Outcome.OK
    assert seen == [("all", one)]
    seen.clear()
    out = E.evaluate_points([_task(p, one), _task(p, two, x=(7.0, 60.0)), _task(p, one, x=(6.0, 60.0))])
    assert [r.x for r in out] == [(8.0, 60.0), (7.0, 60.0), (6.0, 60.0)]
    assert seen == [("batch", one, 2), ("batch", two, 1)]
    seen.clear()
    r = evaluate_point(_task(p, two, gradient=GradientMode.FD))
    assert r.gradient_source == "fd" and ("batch", two, 4) in seen

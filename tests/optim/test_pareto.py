"""Pareto fronts by the ε-constraint method: the 3-PRRR front over β alone lies on its closed form
and covers its hypervolume; front helpers; problem-file validation; the bundled problems load."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import pytest

from hapticopt.design.errors import InvalidInput
from hapticopt.optim.pareto import FrontPoint, choose, keeps_constraints, non_dominated, run_front
from hapticopt.optim.problem import Choice, Sense, load_problem, problem_from_text
from hapticopt.optim.recorder import Recorder
from hapticopt.optim.runs import RunReader


def hypervolume_2d(points: Sequence[Sequence[float]], ref: Sequence[float]) -> float:
    """Area dominated by ``points`` and bounded by ``ref`` (both objectives maximised)."""
    pts = sorted((p for p in points if p[0] > ref[0] and p[1] > ref[1]), key=lambda p: -p[0])
    area, top = 0.0, ref[1]
    for f1, f2 in pts:
        if f2 > top:
            area += (f1 - ref[0]) * (f2 - top)
            top = f2
    return area

DATA = Path(__file__).parent / "data"
ONLY = ("statics", "workspace")  # stiffness_limit_N_per_mm from statics, the height from workspace


@pytest.fixture(scope="module")
def beta_front(tmp_path_factory):
    problem = load_problem(DATA / "beta-front.toml")
    run_dir = tmp_path_factory.mktemp("front")
    with Recorder(run_dir, fingerprint=problem.fingerprint(), resume=False) as rec:
        result = run_front(problem, recorder=rec, only=ONLY)
        repeated = rec.n_repeated
    return problem, result, repeated


def test_front_lies_on_the_closed_form_and_covers_its_hypervolume(beta_front):
    """The 3-PRRR (seed 002) at angle β with spring k, stroke L and required workspace diameter
    D = 2R: x-axis rendered-stiffness limit k_x = 3k/(2 tan²β) (eq 15; k/2 = 28.135 N/mm at 60°),
    workspace height at the diameter h = L − 2R cot β (the cylinder of diameter D fits between the
    slider ends; 89.17 mm at 60°: preset note). Eliminating β (cot β = √(2k_x/(3k))):
    h(k_x) = L − 2R √(2k_x/(3k)), for β ∈ [52°, 60°] where no other workspace limit binds and the parts lay out."""
    problem, result, repeated = beta_front
    base = problem.base
    k = base.actuator.spring * 1e-3  # N/mm
    L = base.geometry.stroke * 1e3  # mm
    two_r = 140.0  # mm: workspace_required_diameter_mm of prrr-paper (seed 002 Table 1, φ140)

    def kx(beta_deg):
        return 3.0 * k / (2.0 * math.tan(math.radians(beta_deg)) ** 2)

    def h(beta_deg):
        return L - two_r / math.tan(math.radians(beta_deg))

    def h_of_kx(f1):
        return L - two_r * math.sqrt(2.0 * f1 / (3.0 * k))

    assert len(result.front) == 41 and repeated == 0
    for p in result.front:
        (beta,) = p.x
        f1, f2 = p.objectives
        assert f1 == pytest.approx(kx(beta), rel=5e-3) and f2 == pytest.approx(h(beta), rel=5e-3)
        assert f2 == pytest.approx(h_of_kx(f1), rel=5e-3)  # on the curve, whatever β the optimiser found
    # hypervolume against the nadir of the curve: ∫ (h(k_x) − h_min) dk_x over [k_x(60°), k_x(52°)],
    # ∫ √k_x dk_x = ⅔ k_x^{3/2}
    a, b = kx(60.0), kx(52.0)
    r1, r2 = a, h(52.0)
    hv_curve = (L - r2) * (b - a) - two_r * math.sqrt(2.0 / (3.0 * k)) * (2.0 / 3.0) * (b ** 1.5 - a ** 1.5)
    hv = hypervolume_2d([p.objectives for p in result.front], (r1, r2))
    assert hv / hv_curve >= 0.95
    assert hv <= hv_curve * (1 + 1e-6)  # a front cannot dominate more than the true front does
    # anchors at the bounds: β = 52° maximises k_x, β = 60° maximises h
    betas = sorted(p.x[0] for p in result.front)
    assert betas[0] == pytest.approx(52.0, abs=1e-3) and betas[-1] == pytest.approx(60.0, abs=1e-3)


def test_front_is_recorded_like_a_run_and_resumes(beta_front, tmp_path):
    problem, result, _ = beta_front
    small = problem.with_optimiser(max_evals=200)
    small = dataclasses.replace(small, pareto=dataclasses.replace(small.pareto, points=5))
    with Recorder(tmp_path, fingerprint=small.fingerprint(), resume=False) as rec:
        first = run_front(small, recorder=rec, only=ONLY)
    with Recorder(tmp_path, fingerprint=small.fingerprint(), resume=True) as rec:
        again = run_front(small, recorder=rec, only=ONLY)
        assert rec.n_repeated == 0
    assert again.n_evaluated == 0 and again.n_replayed > 0
    assert [p.x for p in again.front] == [p.x for p in first.front]
    with RunReader(tmp_path) as r:
        assert len(r) == first.n_evaluated


def _pt(a, b, feasible=True):
    return FrontPoint(run="t", epsilon=math.nan, x=(a,), objectives=(a, b), feasible=feasible, metrics={})


def test_non_dominated_hypervolume_and_choice():
    pts = [_pt(1, 3), _pt(2, 2), _pt(3, 1), _pt(1.5, 1.5), _pt(4, 4, feasible=False)]
    front = non_dominated(pts, [Sense.MAXIMISE, Sense.MAXIMISE])
    assert [p.objectives for p in front] == [(1, 3), (2, 2), (3, 1)]
    # staircase area above (0, 0): 1·3 + 1·2 + 1·1 = 6
    assert hypervolume_2d([p.objectives for p in front], (0.0, 0.0)) == pytest.approx(6.0)
    assert choose(front, [Sense.MAXIMISE] * 2, Choice.KNEE).objectives == (2, 2)  # nearest the utopia (3, 3)
    assert choose(front, [Sense.MAXIMISE] * 2, Choice.WEIGHTS, (1.0, 0.0)).objectives == (3, 1)
    mixed = non_dominated([_pt(1, 1), _pt(2, 2)], [Sense.MAXIMISE, Sense.MINIMISE])
    assert [p.objectives for p in mixed] == [(1, 1), (2, 2)]  # a trade-off when the second is minimised


HEAD = 'name = "x"\nbase = "prrr-paper"\n[[variables]]\nkey = "geometry.beta_deg"\nlower = 50.0\nupper = 70.0\n'
OBJ = '[[objectives]]\nmetric = "stiffness_limit_N_per_mm[0]"\nsense = "maximise"\n'
OBJ2 = '[[objectives]]\nmetric = "workspace_height_at_diameter_mm"\nsense = "maximise"\n'


@pytest.mark.parametrize("text, match", [
    (HEAD + OBJ, "must list exactly 2 objectives"),
    (HEAD + OBJ + OBJ2 + OBJ2, "must list exactly 2 objectives"),
    (HEAD + OBJ + OBJ, "repeats objectives\\[0\\]"),
    (HEAD + OBJ + OBJ2 + '[objective]\nmetric = "jacobian_condition"\n', "give exactly one of \\[objective\\]"),
    (HEAD + OBJ + OBJ2 + "[pareto]\npoints = 2\n", "pareto.points = 2 must be a whole number of front points, 3 ≤"),
    (HEAD + OBJ + OBJ2 + '[pareto]\nchoose = "weights"\nweights = [1.0]\n', "must be two numbers ≥ 0"),
    (HEAD + OBJ + OBJ2 + '[pareto]\nchoose = "middle"\n', "allowed knee, weights"),
    (HEAD + '[objective]\nmetric = "jacobian_condition"\n[pareto]\npoints = 5\n', "\\[pareto\\] needs two"),
])


def test_bad_pareto_problems(text, match):
    with pytest.raises(InvalidInput, match=match):
        problem_from_text(text, source="p.toml", base_dir=None)


@pytest.mark.parametrize("name, device", [("prrr-pareto", "prrr"), ("master-pareto", "master")])
def test_bundled_pareto_problems_load(name, device):
    p = load_problem(name)
    assert p.is_multi_objective and p.device == device and p.pareto is not None


def test_master_pareto_carries_the_unbalance_limit_and_its_choice_keeps_it():
    """Issue 31: master-pareto carries seed 003's 0.1 N unbalance limit (10 % JND of the 1 N mean
    surgeon force) as a constraint, and a point breaking it — the old knee at 0.177 N — is never a
    candidate for the choice; 0.1 N exactly is kept, 0.1 N + 1e-12 is not (no constraint_tol slack)."""
    p = load_problem("master-pareto")
    assert [(c.metric.text, c.op.value, c.value) for c in p.constraints] == [("max_unbalance_force_N", "<=", 0.1)]

    def point(force):
        return FrontPoint(run="t", epsilon=math.nan, x=(0.05,), objectives=(8.0, force), feasible=True,
                          metrics={"max_unbalance_force_N": force, "transparency_bandwidth_Hz": [8.0, 7.8]})

    assert keeps_constraints(p, point(0.05)) and keeps_constraints(p, point(0.1))
    assert not keeps_constraints(p, point(0.177)) and not keeps_constraints(p, point(0.1 + 1e-12))
    assert not keeps_constraints(p, point(math.nan))


def test_master_pareto_at_a_reduced_budget_chooses_inside_the_limit():
    """`optimise master-pareto`'s front at 5 points and 5 evaluations per run (draft fidelity): every
    front point and the chosen knee have unbalance ≤ 0.1 N; the knee is interior (not an anchor) on
    this nearly straight front."""
    p = load_problem("master-pareto").with_optimiser(max_evals=25)
    p = dataclasses.replace(p, pareto=dataclasses.replace(p.pareto, points=5))
    result = run_front(p)
    assert len(result.front) >= 3
    assert all(pt.metrics["max_unbalance_force_N"] <= 0.1 for pt in result.front)
    assert result.chosen is not None and result.chosen.metrics["max_unbalance_force_N"] <= 0.1
    assert not result.chosen.run.startswith("anchor")

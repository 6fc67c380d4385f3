"""Optimiser benchmarks: driver overhead per evaluation (target ≤ 1 ms), evaluations per second on
the bundled problem at draft fidelity, and the recorder's cost per evaluation.

Run: ``make bench`` (or ``.venv/bin/python -m pytest benchmarks/bench_optim.py --benchmark-enable``).
Figures in docs/optimisation.md.
"""

from __future__ import annotations

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import pytest

from hapticopt.optim import driver
from hapticopt.optim.evaluation import Outcome, PointResult, PointTask
from hapticopt.optim.problem import load_problem, problem_from_dict
from hapticopt.optim.recorder import Recorder
from hapticopt.optim.pipeline import evaluate_design, evaluators_for

N_EVALS = 200


def _free_evaluate(task: PointTask) -> PointResult:
    """A zero-cost evaluator (a quadratic): what remains is the optimiser's own overhead."""
    x = task.x
    v = sum((xi - 0.3 * (i + 1)) ** 2 for i, xi in enumerate(x))
    return PointResult(x=x, outcome=Outcome.OK, values=(v,) + tuple(0.0 for _ in task.refs[1:]),
                       metrics={}, timings_s={})


def _overhead_problem():
    return problem_from_dict({
        "name": "overhead", "base": "prrr-paper",
        "variables": [{"key": f"geometry.{k}", "lower": 0.01, "upper": 5.0, "start": 2.5}
                      for k in ("d1_mm", "d2_mm", "d3_mm", "d4_mm")],
        "objective": {"metric": "jacobian_condition"},
        "constraints": [{"metric": "max_force_N[0]", "min": -1.0}],
        "optimiser": {"algorithm": "LN_COBYLA", "xtol_rel": 0.0, "ftol_rel": 0.0, "max_evals": N_EVALS}})


def test_driver_overhead_per_evaluation(benchmark, tmp_path):
    """Driver + nlopt + guard + history + recorder per point, evaluator excluded (≤ 1 ms)."""
    problem = _overhead_problem()
    counter = iter(range(10**6))

    def run():
        with Recorder(tmp_path / str(next(counter)), fingerprint="b", resume=False) as rec:
            return driver.run(problem, recorder=rec, evaluate_fn=_free_evaluate)

    res = benchmark.pedantic(run, rounds=5, iterations=1)
    n = len(res.history)
    benchmark.extra_info["points"] = n
    benchmark.extra_info["ms_per_point_median"] = 1e3 * benchmark.stats.stats.median / n
    assert n == N_EVALS


def test_driver_overhead_without_recorder(benchmark):
    problem = _overhead_problem()
    res = benchmark.pedantic(lambda: driver.run(problem, evaluate_fn=_free_evaluate), rounds=5, iterations=1)
    benchmark.extra_info["ms_per_point_median"] = 1e3 * benchmark.stats.stats.median / len(res.history)


@pytest.fixture(scope="module")
def bundled():
    p = load_problem("prrr-workspace").with_optimiser(max_evals=100, starts=1)
    base = evaluate_design(p.base, p.fidelity_optimise)
    only = evaluators_for(p, base)
    driver.run(p.with_optimiser(max_evals=3), metric_modules=base.modules, only=only)  # warm the jit caches
    return p, base.modules, only


def test_bundled_problem_evaluations_per_second(benchmark, bundled):
    """prrr-workspace at draft fidelity, inline (one core): evaluations per second."""
    p, modules, only = bundled
    res = benchmark.pedantic(lambda: driver.run(p, metric_modules=modules, only=only), rounds=3, iterations=1)
    benchmark.extra_info["evaluations"] = res.n_evaluated
    benchmark.extra_info["evals_per_s_median"] = res.n_evaluated / benchmark.stats.stats.median

"""Issue 20 benchmarks: a 1-D sweep of 1000 draft 3-PRRR designs and a Pareto front of 2000
evaluations, each against the single-design evaluation (time per design, median).

Run: ``.venv/bin/python -m pytest benchmarks/bench_sweep_pareto.py --benchmark-enable -s``
(``make bench`` runs every benchmark). Figures in docs/runs.md.
"""

from __future__ import annotations

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)

import statistics
import time

import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import evaluate_all
from hapticopt.design import io
from hapticopt.optim.executor import InlineExecutor, make_executor
from hapticopt.optim.pareto import run_front
from hapticopt.optim.problem import problem_from_dict
from hapticopt.optim.sweep import Sweep, parse_axis, run_sweep

BASE = io.load_preset("prrr-paper")
N_SWEEP = 1000
FRONT_EVALS = 2000
FRONT_ONLY = ("statics", "workspace")


def _single(only, n=21) -> float:
    """Median wall time [s] of one draft evaluation of prrr-paper (the registry's one loop)."""
    evaluate_all(BASE, fidelity=Fidelity.DRAFT, only=only)
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        evaluate_all(BASE, fidelity=Fidelity.DRAFT, only=only)
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


@pytest.mark.parametrize("scheduler", ["inline", "local"])
def test_sweep_1000_draft_designs(benchmark, scheduler):
    """All evaluators of the 3-PRRR at draft fidelity, β from 45° to 65° in 1000 steps."""
    sweep = Sweep(base=BASE, axes=(parse_axis(f"geometry.beta_deg=45:65:{N_SWEEP}", BASE),), fidelity=Fidelity.DRAFT)
    single = _single(None)

    def run():
        if scheduler == "inline":
            return run_sweep(sweep, executor=InlineExecutor())
        with make_executor("local", workers=2) as pool:
            return run_sweep(sweep, executor=pool)

    res = benchmark.pedantic(run, rounds=1, iterations=1)
    wall = benchmark.stats.stats.median
    benchmark.extra_info.update(points=N_SWEEP, ok=res.n_ok, wall_s=wall, single_design_ms=1e3 * single,
                                ms_per_design=1e3 * wall / N_SWEEP, ratio_to_single=wall / N_SWEEP / single)
    print(f"\nsweep {scheduler}: {N_SWEEP} designs in {wall:.1f} s = {1e3 * wall / N_SWEEP:.1f} ms/design; "
          f"single design {1e3 * single:.1f} ms; ratio {wall / N_SWEEP / single:.2f}")
    assert len(res.results) == N_SWEEP


def test_pareto_front_2000_evaluations(benchmark):
    """β and stroke, stiffness limit vs workspace height, 38 ε-constraint runs of up to 100
    evaluations (xtol = ftol = 0; COBYLA still stops early where its trust region collapses).
    Against two single-design figures: prrr-paper evaluated alone (median), and the evaluators'
    own time per point inside the front (mean of the recorded timings: the wall time is a mean too)."""
    problem = problem_from_dict({
        "name": "bench-front", "base": "prrr-paper",
        "variables": [{"key": "geometry.beta_deg", "lower": 52.0, "upper": 70.0},
                      {"key": "geometry.stroke_mm", "lower": 160.0, "upper": 200.0}],
        "objectives": [{"metric": "stiffness_limit_N_per_mm[0]", "sense": "maximise"},
                       {"metric": "workspace_height_at_diameter_mm", "sense": "maximise"}],
        "pareto": {"points": 38},
        "optimiser": {"algorithm": "LN_COBYLA", "xtol_rel": 0.0, "ftol_rel": 0.0, "max_evals": 3800}})
    single = _single(FRONT_ONLY)
    res = benchmark.pedantic(lambda: run_front(problem, only=FRONT_ONLY), rounds=1, iterations=1)
    wall = benchmark.stats.stats.median
    asked = len(res.history)
    inside = statistics.fmean(sum(r.timings_s.values()) for r in res.history if str(r.source) == "evaluated")
    per = wall / res.n_evaluated
    benchmark.extra_info.update(points_asked=asked, evaluated=res.n_evaluated, front=len(res.front), wall_s=wall,
                                single_design_ms=1e3 * single, evaluators_in_front_ms=1e3 * inside,
                                ms_per_evaluation=1e3 * per, ratio_to_single=per / single,
                                ratio_to_evaluators_in_front=per / inside)
    print(f"\npareto: {asked} points asked, {res.n_evaluated} evaluated, {len(res.front)} on the front, "
          f"{wall:.1f} s = {1e3 * per:.2f} ms/evaluation; single design {1e3 * single:.2f} ms (ratio {per / single:.2f}); "
          f"evaluators per point in the front {1e3 * inside:.2f} ms (ratio {per / inside:.2f})")
    assert res.n_evaluated >= 0.9 * FRONT_EVALS


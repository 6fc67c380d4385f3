"""NLopt driver: recovery of the isotropic β with every algorithm family, jax gradients vs finite
differences, guarded values (NaN, failures, invalid designs), statuses, seeded multi-start."""

from __future__ import annotations

import dataclasses
import math
from concurrent.futures import Executor

import nlopt
import numpy as np
import pytest

from hapticopt.analysis.compute import Compute
from hapticopt.optim import driver
from hapticopt.optim.driver import StartStatus
from hapticopt.optim.evaluation import (
    GradientMode,
    Outcome,
    PointTask,
    evaluate_point,
    fd_gradients,
    jax_gradients,
)
from hapticopt.optim.executor import InlineExecutor
from hapticopt.optim.problem import MetricRef, problem_from_dict

#: seed 002 / seed digest: cond(J) = 1 at the isotropic angle β* = atan(1/√2) = 35.264°
BETA_ISO_DEG = math.degrees(math.atan(1.0 / math.sqrt(2.0)))
STATICS = "hapticopt.analysis.prrr.structure.statics"
MODULES = {m: STATICS for m in ("jacobian_condition", "jacobian_condition_frobenius", "max_force_N",
                                "max_pure_force_N", "stiffness_limit_N_per_mm", "effective_mass_kg")}


def run(problem, **kw):
    """driver.run with only the statics evaluator per point (as the pipeline does for these metrics)."""
    kw.setdefault("only", ("statics",))
    return driver.run(problem, **kw)


def beta_problem(algorithm: str, *, local: str = "LN_BOBYQA", constrained: bool = False, starts: int = 1,
                 seed: int = 0, max_evals: int = 300, metric: str = "jacobian_condition",
                 bounds: tuple[float, float] = (25.0, 60.0)):
    d = {"name": "beta", "base": "prrr-paper",
         # 25…60°: prrr-paper can be built there; outside, analysis.prrr.geometry.assembly.check_built refuses it
         # (below ≈ 21° no carriage face carries the R1 clevis, above 60° the R3 lugs meet the stem), so those
         # points are not-assemblable, not evaluator answers
         "variables": [{"key": "geometry.beta_deg", "lower": bounds[0], "upper": bounds[1]}],
         "objective": {"metric": metric, "sense": "minimise"},
         "optimiser": {"algorithm": algorithm, "local": local, "starts": starts, "seed": seed,
                       "xtol_rel": 1e-8, "ftol_rel": 0.0, "max_evals": max_evals}}
    if constrained:
        # F_z max = 3 F_max = 3581 N for every β (seed 002 / digest): always satisfied, exercises the path
        d["constraints"] = [{"metric": "max_force_N[2]", "min": 3000.0}]
    return problem_from_dict(d)


@pytest.mark.parametrize("algorithm, local, constrained", [
    ("LN_COBYLA", "LN_BOBYQA", True),  # local derivative-free, constrained
    ("LN_BOBYQA", "LN_BOBYQA", False),  # local derivative-free
    ("LD_SLSQP", "LN_BOBYQA", True),  # gradient (jax), constrained
    ("LD_MMA", "LN_BOBYQA", False),  # gradient (jax)
    ("GN_DIRECT_L", "LN_BOBYQA", False),  # global + local polish
    ("GN_ISRES", "LN_COBYLA", True),  # global (stochastic, seeded) + polish, constrained
    ("AUGLAG", "LD_SLSQP", True),  # augmented Lagrangian around a gradient method
    ("AUGLAG", "LN_BOBYQA", True),  # augmented Lagrangian around a derivative-free method
])
def test_recovers_isotropic_beta(algorithm, local, constrained):
    res = run(beta_problem(algorithm, local=local, constrained=constrained), metric_modules=MODULES)
    assert res.best is not None and res.feasible
    assert abs(res.best.x[0] - BETA_ISO_DEG) <= 0.01
    assert res.best.metrics["jacobian_condition"] == pytest.approx(1.0, abs=1e-6)
    assert all(r.outcome is Outcome.OK for r in res.history)
    if algorithm.startswith("LD_") or local.startswith("LD_"):
        # the kinked 2-norm condition is replaced by the smooth Frobenius form where gradients are needed
        assert res.objective_metric == "jacobian_condition_frobenius"
        assert any("jax" in n for n in res.notes)


def test_jax_gradients_match_central_differences():
    rng = np.random.default_rng(7)
    p = problem_from_dict({
        "name": "g", "base": "prrr-paper",
        "variables": [{"key": k, "lower": lo, "upper": hi} for k, lo, hi in (
            ("geometry.beta_deg", 15.0, 75.0), ("actuator.spring_N_per_mm", 20.0, 100.0),
            ("actuator.force_limit_N", 500.0, 2000.0), ("end_effector.mass_kg", 0.2, 2.0))],
        "objective": {"metric": "jacobian_condition_frobenius"},
        "constraints": [{"metric": "max_force_N[0]", "min": 1.0}, {"metric": "stiffness_limit_N_per_mm[1]", "min": 1.0},
                        {"metric": "effective_mass_kg[0][1]", "max": 1.0}, {"metric": "jacobian_condition", "max": 9.0},
                        {"metric": "min(max_pure_force_N)", "min": 1.0}]})
    refs = p.metric_refs()
    sources = tuple(sorted({(r.name, STATICS) for r in refs}))
    worst = 0.0
    for _ in range(8):
        x = tuple(float(v) for v in rng.uniform(p.lower, p.upper))
        g = jax_gradients(p.base, p.variables, refs, sources, x)
        # central differences on the evaluator itself (no jax), step 1e-4 of each variable's range
        task = PointTask(base=p.base, variables=p.variables, x=x, fidelity=p.fidelity_optimise, refs=refs)
        base_vals = evaluate_point(task).values
        fd = fd_gradients(task, x, base_vals, rel_step=1e-4)
        scale = np.maximum(np.abs(g), 1e-8 * np.max(np.abs(g), axis=1, keepdims=True))
        worst = max(worst, float(np.max(np.abs(g - fd) / scale)))
    assert worst <= 1e-6


def test_fd_fallback_when_no_jax_twin_is_known():
    # no metric_modules: the driver cannot find jax twins and says it uses finite differences
    res = run(beta_problem("LD_SLSQP", metric="jacobian_condition_frobenius"))
    assert any("finite differences" in n for n in res.notes)
    assert abs(res.best.x[0] - BETA_ISO_DEG) <= 0.01


def _nan_above_40(task: PointTask):
    """The statics evaluator, but the objective is NaN for β > 40° (and raises for β > 75°)."""
    if task.x[0] > 75.0:
        raise RuntimeError("evaluator crashed")
    r = evaluate_point(task)
    if task.x[0] > 40.0:
        return dataclasses.replace(r, values=(math.nan,) + r.values[1:], outcome=Outcome.NONFINITE, message="nan")
    return r


@pytest.mark.parametrize("algorithm", ["LN_COBYLA", "LN_BOBYQA", "GN_DIRECT_L"])
def test_nan_and_failures_are_guarded(algorithm):
    # 15…80°: the points outside 25…60° that cannot be built (beta_problem) are failures the guard handles too
    p = beta_problem(algorithm, bounds=(15.0, 80.0))
    p = dataclasses.replace(p, variables=(dataclasses.replace(p.variables[0], start=30.0),))
    res = run(p, evaluate_fn=_nan_above_40)
    outcomes = {r.outcome for r in res.history}
    assert Outcome.NONFINITE in outcomes
    assert all(math.isfinite(r.f) and all(math.isfinite(c) for c in r.constraints) for r in res.history)
    assert abs(res.best.x[0] - BETA_ISO_DEG) <= 0.01
    if algorithm == "GN_DIRECT_L":
        assert Outcome.EVALUATOR_FAILED in outcomes  # DIRECT samples β > 75° too


def test_nan_at_the_start_is_not_a_silent_success():
    # seed of the pitfall: NaN at the start point makes COBYLA stop there and return normally.
    # Guarded, the run says no valid point was found; a second seeded start escapes the plateau.
    res = run(beta_problem("LN_COBYLA"), evaluate_fn=_nan_above_40)
    assert res.best is None and res.status == "no_valid_point"
    res = run(beta_problem("LN_COBYLA", starts=3, seed=2), evaluate_fn=_nan_above_40)
    assert res.status == "converged" and abs(res.best.x[0] - BETA_ISO_DEG) <= 0.01


def test_invalid_design_is_a_handled_outcome():
    p = problem_from_dict({
        "name": "bore", "base": "prrr-paper",
        "variables": [{"key": "structure.bore_diameter_mm", "lower": 2.0, "upper": 40.0}],
        "objective": {"metric": "jacobian_condition"},  # flat in the bore: stops quickly
        "optimiser": {"algorithm": "GN_DIRECT_L", "max_evals": 30}})
    res = run(p)
    bad = [r for r in res.history if r.outcome is Outcome.INVALID_DESIGN]
    assert bad and all("bore_diameter_mm" in r.message for r in bad)  # bore ≥ boss (24 mm)
    assert res.best.x[0] < 24.0


def test_statuses_forced_stop_and_roundoff_are_reported():
    def stop_after(n, exc):
        def progress(rec, best, n_eval):
            if n_eval >= n:
                raise exc
        return progress

    res = run(beta_problem("LN_COBYLA"), progress=stop_after(5, nlopt.ForcedStop()))
    assert res.starts[0].status is StartStatus.FORCED_STOP
    assert res.best is not None and len(res.history) == 5
    res = run(beta_problem("LN_BOBYQA"), progress=stop_after(3, nlopt.RoundoffLimited()))
    assert res.starts[0].status is StartStatus.ROUNDOFF_LIMITED and "roundoff" in res.starts[0].message
    res = run(beta_problem("LN_COBYLA", max_evals=4))
    assert res.starts[0].status is StartStatus.MAXEVAL_REACHED and len(res.history) == 4


def test_multistart_is_seeded_and_deterministic():
    a = run(beta_problem("LN_COBYLA", starts=3, seed=11, max_evals=150))
    b = run(beta_problem("LN_COBYLA", starts=3, seed=11, max_evals=150))
    c = run(beta_problem("LN_COBYLA", starts=3, seed=12, max_evals=150))
    assert [(r.x, r.f) for r in a.history] == [(r.x, r.f) for r in b.history]
    assert a.starts[0].x0 == (60.0,)  # start 0: the base design
    assert a.starts[1].x0 != c.starts[1].x0
    assert {s.start for s in a.starts} == {0, 1, 2} and sum(s.n_points for s in a.starts) == len(a.history)


def test_maximise_flips_the_sign():
    p = problem_from_dict({"name": "m", "base": "prrr-paper",
                           "variables": [{"key": "geometry.beta_deg", "lower": 25.0, "upper": 60.0}],  # buildable
                           "objective": {"metric": "max_force_N[0]", "sense": "maximise"},
                           "optimiser": {"algorithm": "LN_BOBYQA", "xtol_rel": 1e-8, "max_evals": 100}})
    res = run(p)
    # F_x max = 2 F_max / tan β (seed digest) grows as β falls: the optimum is the lower bound
    assert res.best.x[0] == pytest.approx(25.0, abs=1e-6)
    assert res.best.f == -res.best.objective


def test_penalty_rule_is_deterministic():
    # first failure before any finite value: FIRST_PENALTY; later: worst + max(1, |worst|)
    def fail_band(task: PointTask):
        r = evaluate_point(task)
        return dataclasses.replace(r, outcome=Outcome.EVALUATOR_FAILED) if task.x[0] >= 59.0 or 40 < task.x[0] < 50 else r

    res = run(beta_problem("LN_COBYLA", max_evals=40), evaluate_fn=fail_band)
    first = res.history[0]
    assert first.outcome is Outcome.EVALUATOR_FAILED and first.f == driver.FIRST_PENALTY
    res = run(beta_problem("GN_DIRECT_L", max_evals=60), evaluate_fn=fail_band)
    later = [r for r in res.history if r.outcome is not Outcome.OK
             and any(h.outcome is Outcome.OK for h in res.history[: r.index])]
    assert later
    for r in later:
        worst = max(h.f for h in res.history[: r.index] if h.outcome is Outcome.OK)
        assert r.f == worst + max(1.0, abs(worst))


def test_gradient_mode_none_for_derivative_free():
    task = PointTask(base=beta_problem("LN_COBYLA").base, variables=beta_problem("LN_COBYLA").variables, x=(40.0,),
                     fidelity=beta_problem("LN_COBYLA").fidelity_optimise,
                     refs=(MetricRef.parse("jacobian_condition", "o"),), gradient=GradientMode.NONE)
    assert evaluate_point(task).gradients is None


def test_master_counterweight_on_unbalance_boundary_beats_balanced():
    """Seed 003's lesson: with the counterweights free, the optimum sits on the 0.1 N unbalance
    boundary (active constraint) and has a higher transparency bandwidth than the perfectly
    balanced design (master-paper is balanced: max_unbalance_force_N ≈ 0)."""
    from hapticopt.optim.pipeline import evaluate_design, evaluators_for
    from hapticopt.optim.problem import load_problem

    p = load_problem("master-transparency")
    base = evaluate_design(p.base, p.fidelity_optimise)
    assert base.metrics["max_unbalance_force_N"] < 1e-9  # the balanced reference
    res = driver.run(p, metric_modules=base.modules, only=evaluators_for(p, base))
    assert res.feasible
    unbalance = res.best.metrics["max_unbalance_force_N"]
    # near the boundary, never past it: the bundled problem (4 variables, ISRES then COBYLA polish, 400
    # evaluations) ends 16 % inside (0.0839 N, the recorded optimum of
    # tests/snapshots/master_transparency_optimum.json; in-process here as from the CLI, OpenBLAS Haswell);
    # docs/master.md says why it is not active. An earlier fidelity of the problem ended 0.11 % inside
    assert 0.08 <= unbalance <= 0.1 * (1 + 1e-3)
    assert res.best.objective > p.objective.metric.value(base.metrics)  # beats the balanced bandwidth


class _OtherProcessExecutor(Executor):  # stands for a pool: an Executor that is not the inline one
    def submit(self, fn, /, *args, **kwargs):
        return InlineExecutor().submit(fn, *args, **kwargs)


@pytest.mark.parametrize(("executor", "expected_threads"), [(InlineExecutor(), 2), (_OtherProcessExecutor(), 1)])
def test_each_point_gets_the_runs_route(executor, expected_threads):
    """The run's Compute reaches every point's task: as given where points run inline, with one kernel
    thread where they run in other processes (``executor.worker_compute``)."""
    seen = []

    def evaluate(task: PointTask):
        seen.append(task.compute)
        return evaluate_point(task)

    run(beta_problem("LN_BOBYQA", max_evals=4), executor=executor, evaluate_fn=evaluate,
        compute=Compute(backend="numba", threads=2))
    assert seen and set(seen) == {Compute(backend="numba", threads=expected_threads)}


def test_starts_are_drawn_from_designs_that_can_be_built():
    """Issue 30 item 4: beta over 10…88°, where prrr-paper can be built only within ≈ 22.5…60° (assembly.check_built):
    every drawn start's design can be built, the rejected draws are counted, and the run says so."""
    from hapticopt.analysis.registry import not_built

    p = beta_problem("LN_COBYLA", starts=6, seed=3, max_evals=12, bounds=(10.0, 88.0))
    draws = driver.start_draws(p)
    assert len(draws) == 6 and draws[0][1] == 0
    lo, hi = p.lower[0], p.upper[0]
    for u, _ in draws[1:]:
        assert not_built(p.design_at((lo + u[0] * (hi - lo),))) == ""
    # about half of the range cannot be built: with 5 seeded draws some are rejected
    assert sum(n for _, n in draws) > 0
    res = run(p)
    assert [s.rejected_draws for s in res.starts] == [n for _, n in draws]
    assert any("rejected and redrawn" in n for n in res.notes)

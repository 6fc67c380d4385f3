"""Pareto fronts of two-objective problems by the ε-constraint method (a series of NLopt runs).

For objectives f₁ (the primary) and f₂: two **anchor** runs optimise f₁ alone and f₂ alone
(with the problem's constraints); then for ``points − 2`` levels ε evenly spaced strictly
between f₂ at the two anchors, a run optimises f₁ subject to ``f₂ ≥ ε`` (``≤`` when f₂ is
minimised), warm-started at the previous level's optimum. Each run is
:func:`hapticopt.optim.driver.run` — the same guarded, seeded, recorded loop as a single
optimisation — so every point of the front is an optimum of a well-posed problem (exact up to
the optimiser's tolerances), not a sample of a population. The front is the non-dominated
subset of the runs' best feasible points.

Why ε-constraint and not NSGA-II (pymoo): no new dependency; each front point is an exact
constrained optimum, so it lies on the true front within the optimiser's tolerance, not merely
near it; the evaluations are the same guarded, recorded, resumable ones; the cost is
``points × (evaluations per run)``, which for smooth low-dimensional problems (tens of
evaluations per run) is far below a genetic algorithm's population × generations. Its limit:
points on non-convex *and* disconnected parts of a front are found only where an ε level falls.

Evaluations are shared between the runs of a front: a point asked by a later run is served
from the earlier one (its objective and constraint values re-picked from the recorded metrics),
never evaluated twice; the recorder counts any repeat.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.optim import driver
from hapticopt.optim.driver import EvalRecord, RunResult
from hapticopt.optim.evaluation import Outcome, PointResult
from hapticopt.optim.problem import Choice, Constraint, MetricRef, Objective, Op, Problem, Sense
from hapticopt.optim.recorder import Recorder


@dataclass(frozen=True, kw_only=True)
class FrontPoint:
    """One point of the front: where it came from and its objective values (edge units)."""

    run: str  # "anchor 1", "anchor 2", "eps 3"
    epsilon: float  # the ε level of its run (NaN for anchors)
    x: tuple[float, ...]
    objectives: tuple[float, float]
    feasible: bool
    metrics: dict[str, Any] = dataclasses.field(compare=False, repr=False)


@dataclass(frozen=True, kw_only=True)
class FrontResult:
    problem_name: str
    runs: tuple[tuple[str, float, RunResult], ...]  # (label, ε, result) in the order run
    front: tuple[FrontPoint, ...]  # non-dominated, sorted by the first objective
    candidates: tuple[FrontPoint, ...]  # every run's best (before the non-dominated filter)
    chosen: FrontPoint | None
    n_evaluated: int
    n_replayed: int
    wall_s: float

    @property
    def history(self) -> tuple[EvalRecord, ...]:
        return tuple(r for _, _, res in self.runs for r in res.history)


class SharedPoints:
    """The recorder as the driver sees it, shared by the runs of a front.

    ``lookup`` serves a point evaluated by an earlier run of this front (or an earlier session),
    with its values re-picked for the asking run's references; ``record`` remembers and records.
    """

    def __init__(self, recorder: Recorder | None) -> None:
        self.recorder = recorder
        self.seen: dict[str, PointResult] = {}
        self.refs: tuple[MetricRef, ...] = ()
        self.lock = threading.Lock()

    def lookup(self, key: str) -> PointResult | None:
        with self.lock:
            hit = self.seen.get(key)
        if hit is None and self.recorder is not None:
            hit = self.recorder.lookup(key)
        return None if hit is None else self._for_refs(hit)

    def _for_refs(self, r: PointResult) -> PointResult | None:
        if r.gradients is not None:
            return None  # gradient rows belong to the refs they were computed for: evaluate again
        values = tuple(ref.value(r.metrics) for ref in self.refs)
        outcome, message = r.outcome, r.message
        if outcome in (Outcome.OK, Outcome.NONFINITE):
            bad = [ref.text for ref, v in zip(self.refs, values) if not math.isfinite(v)]
            outcome, message = (Outcome.NONFINITE, "non-finite " + ", ".join(bad)) if bad else (Outcome.OK, "")
        return dataclasses.replace(r, values=values, outcome=outcome, message=message)

    def record(self, key: str, result: PointResult, **kw: Any) -> None:
        with self.lock:
            self.seen[key] = result
        if self.recorder is not None:
            self.recorder.record(key, result, **kw)


def _sign(sense: Sense) -> float:
    return 1.0 if sense is Sense.MAXIMISE else -1.0


def dominates(a: Sequence[float], b: Sequence[float]) -> bool:
    """a dominates b (both oriented so that larger is better)."""
    return all(x >= y for x, y in zip(a, b)) and any(x > y for x, y in zip(a, b))


def non_dominated(points: Sequence[FrontPoint], senses: Sequence[Sense]) -> list[FrontPoint]:
    """The feasible points no other feasible point dominates (duplicates kept once)."""
    oriented = [(p, tuple(_sign(s) * v for s, v in zip(senses, p.objectives))) for p in points
                if p.feasible and all(math.isfinite(v) for v in p.objectives)]
    out: list[FrontPoint] = []
    seen: set[tuple[float, ...]] = set()
    for p, o in oriented:
        if o in seen or any(dominates(q, o) for _, q in oriented):
            continue
        seen.add(o)
        out.append(p)
    return sorted(out, key=lambda p: p.objectives[0])


def choose(front: Sequence[FrontPoint], senses: Sequence[Sense], how: Choice,
           weights: Sequence[float] = ()) -> FrontPoint | None:
    """The chosen design of a front. Objectives are normalised over the front to [0, 1], 1 = best.

    * ``knee``: the point nearest the utopia point (1, 1) in the normalised objectives. (The other
      common definition, farthest from the line through the two anchors, picks an anchor on a front
      that bows towards the nadir, as the 3-PRRR's stiffness/height front does; the utopia distance
      is defined on any front. On a straight front it is the midpoint.)
    * ``weights``: the point maximising w₁·n₁ + w₂·n₂ (the problem's ``[pareto] choose``/``weights``
      are how a user changes the rule).

    ``front`` holds only points that keep every constraint of their problem (:func:`run_front`
    filters them), so the chosen design never breaks one.
    """
    if not front:
        return None
    o = [[_sign(s) * v for s, v in zip(senses, p.objectives)] for p in front]
    lo = [min(r[i] for r in o) for i in range(2)]
    hi = [max(r[i] for r in o) for i in range(2)]
    n = [[(r[i] - lo[i]) / (hi[i] - lo[i]) if hi[i] > lo[i] else 1.0 for i in range(2)] for r in o]
    if how is Choice.WEIGHTS:
        scores = [weights[0] * a + weights[1] * b for a, b in n]
    else:
        scores = [-math.hypot(1.0 - a, 1.0 - b) for a, b in n]
    best = max(range(len(front)), key=lambda i: (scores[i], -i))
    return front[best]


def keeps_constraints(problem: Problem, point: FrontPoint) -> bool:
    """Whether ``point`` keeps every constraint of ``problem`` exactly (normalised violation ≤ 0, not
    the optimiser's ``constraint_tol``), on the metrics recorded for it."""
    return all(math.isfinite(v := c.metric.value(point.metrics)) and c.normalised(v) <= 0.0
               for c in problem.constraints)


def _epsilon_constraint(obj: Objective, eps: float) -> Constraint:
    return Constraint(metric=obj.metric, op=Op.GE if obj.sense is Sense.MAXIMISE else Op.LE, value=eps)


def _front_point(label: str, eps: float, res: RunResult, objectives: Sequence[Objective]) -> FrontPoint | None:
    b = res.best
    if b is None:
        return None
    vals = tuple(o.metric.value(b.metrics) for o in objectives)
    return FrontPoint(run=label, epsilon=eps, x=b.x, objectives=(vals[0], vals[1]), feasible=res.feasible,
                      metrics=b.metrics)


def _with_start(problem: Problem, x: Sequence[float]) -> Problem:
    vs = tuple(dataclasses.replace(v, start=min(max(float(s), v.lower), v.upper)) for v, s in zip(problem.variables, x))
    return dataclasses.replace(problem, variables=vs)


def run_front(problem: Problem, *, executor: Executor | None = None, recorder: Recorder | None = None,
              metric_modules: dict[str, str] | None = None, only: tuple[str, ...] | None = None,
              progress: Callable[[str, int], None] | None = None, compute: Compute = DEFAULT) -> FrontResult:
    """Trace the front of a two-objective ``problem`` (budget: ``max_evals`` per front, shared evenly);
    ``compute``: the route of the points' evaluations (:func:`driver.run`'s)."""
    if not problem.is_multi_objective or problem.pareto is None:
        raise ValueError(f"problem {problem.name} has one objective: use driver.run")
    t0 = time.perf_counter()
    cfg = problem.pareto
    f1, f2 = problem.objectives
    per_run = max(problem.optimiser.starts, problem.optimiser.max_evals // cfg.points)
    shared = SharedPoints(recorder)
    runs: list[tuple[str, float, RunResult]] = []
    n_eval = n_repl = 0

    def one(label: str, sub: Problem, eps: float) -> RunResult:
        nonlocal n_eval, n_repl
        sub = sub.with_optimiser(max_evals=per_run)
        shared.refs = sub.metric_refs()
        res = driver.run(sub, executor=executor, recorder=shared, metric_modules=metric_modules, only=only,  # type: ignore[arg-type]
                         compute=compute)
        runs.append((label, eps, res))
        n_eval += res.n_evaluated
        n_repl += res.n_replayed
        if progress is not None:
            progress(label, n_eval)
        return res

    base = dataclasses.replace(problem, objectives=(), pareto=None)
    a1 = one("anchor 1", dataclasses.replace(base, objective=f1), math.nan)
    a2 = one("anchor 2", dataclasses.replace(base, objective=f2), math.nan)
    p1, p2 = _front_point("anchor 1", math.nan, a1, problem.objectives), _front_point("anchor 2", math.nan, a2,
                                                                                        problem.objectives)
    candidates = [p for p in (p1, p2) if p is not None]
    if p1 is not None and p2 is not None:
        lo, hi = p1.objectives[1], p2.objectives[1]  # f₂ at the f₁ anchor, f₂ at its own optimum
        k = cfg.points - 2
        start = p1.x
        for i in range(1, k + 1):
            eps = lo + (hi - lo) * i / (k + 1)
            sub = dataclasses.replace(base, objective=f1, constraints=base.constraints + (_epsilon_constraint(f2, eps),))
            res = one(f"eps {i}", _with_start(sub, start), eps)
            fp = _front_point(f"eps {i}", eps, res, problem.objectives)
            if fp is not None:
                candidates.append(fp)
                if fp.feasible:
                    start = fp.x
    front = non_dominated([p for p in candidates if keeps_constraints(problem, p)], [f1.sense, f2.sense])
    chosen = choose(front, [f1.sense, f2.sense], cfg.choose, cfg.weights)
    return FrontResult(problem_name=problem.name, runs=tuple(runs), front=tuple(front), candidates=tuple(candidates),
                       chosen=chosen, n_evaluated=n_eval, n_replayed=n_repl, wall_s=time.perf_counter() - t0)

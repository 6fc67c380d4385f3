"""The NLopt outer loop: seeded multi-start, guarded values, statuses, full history.

The optimiser works on normalised variables u ∈ [0, 1]ⁿ (x = lower + u·(upper − lower)), so
every algorithm sees a well-scaled box; ``xtol_rel`` is applied to u (a fraction of each
variable's range). The objective handed to nlopt is ``±metric`` (− to maximise); each
constraint ``metric ≥ v`` becomes ``(v − metric)/|v| ≤ 0`` (``≤`` likewise).

Guard. Every value handed to nlopt is finite. A point whose design is invalid, whose
evaluator fails, or whose picked metric is NaN/inf gets the **penalty**
``f = worst finite f seen so far in this start + max(1, |worst|)`` (``1e6`` before any finite
value), every constraint ``+1`` (violated by 100 %), and zero gradients. The penalty depends
only on the start's own history, so it is deterministic and replays identically.

Gradients. LD_* algorithms (and AUGLAG/polish with an LD_* local algorithm) get jax
gradients when every evaluator involved has a jax twin (:mod:`optim.evaluation`), else
central finite differences — the run's ``notes`` say which. Where a gradient is needed, a
metric with a kink is replaced by its smooth form (:data:`SMOOTH_SURROGATES`; the 2-norm
condition number by the Frobenius one, which has the same minimiser).

Statuses. nlopt's return codes and its exceptions (RoundoffLimited, ForcedStop, generic
failure) are reported per start as :class:`StartStatus`; nothing raises out of :func:`run`
except programming errors.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import nlopt
import numpy as np

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.registry import not_built
from hapticopt.design.errors import HapticoptError
from hapticopt.optim.evaluation import GradientMode, Outcome, PointResult, PointTask, evaluate_point, jax_twin
from hapticopt.optim.executor import InlineExecutor, worker_compute, worker_count
from hapticopt.optim.problem import Algorithm, MetricRef, Problem, Sense
from hapticopt.optim.recorder import Recorder, point_key

#: metric -> smooth metric with the same minimiser, used where a gradient is needed
SMOOTH_SURROGATES: dict[str, str] = {"jacobian_condition": "jacobian_condition_frobenius"}
#: penalty before any finite objective value has been seen in a start
FIRST_PENALTY = 1e6
#: constraint value handed to nlopt for a failed point (normalised: violated by 100 %)
FAILED_CONSTRAINT = 1.0
#: share of a global algorithm's budget; the rest polishes locally
GLOBAL_SHARE = 0.7


class StartStatus(StrEnum):
    SUCCESS = "success"
    STOPVAL_REACHED = "stopval_reached"
    FTOL_REACHED = "ftol_reached"
    XTOL_REACHED = "xtol_reached"
    MAXEVAL_REACHED = "maxeval_reached"
    MAXTIME_REACHED = "maxtime_reached"
    ROUNDOFF_LIMITED = "roundoff_limited"
    FORCED_STOP = "forced_stop"
    FAILURE = "failure"
    INVALID_ARGS = "invalid_args"

    @property
    def converged(self) -> bool:
        return self in (StartStatus.SUCCESS, StartStatus.STOPVAL_REACHED, StartStatus.FTOL_REACHED,
                        StartStatus.XTOL_REACHED)


_CODES = {1: StartStatus.SUCCESS, 2: StartStatus.STOPVAL_REACHED, 3: StartStatus.FTOL_REACHED,
          4: StartStatus.XTOL_REACHED, 5: StartStatus.MAXEVAL_REACHED, 6: StartStatus.MAXTIME_REACHED,
          -1: StartStatus.FAILURE, -2: StartStatus.INVALID_ARGS, -4: StartStatus.ROUNDOFF_LIMITED,
          -5: StartStatus.FORCED_STOP}

_NLOPT_ALG = {
    Algorithm.LN_COBYLA: nlopt.LN_COBYLA, Algorithm.LN_BOBYQA: nlopt.LN_BOBYQA, Algorithm.LD_SLSQP: nlopt.LD_SLSQP,
    Algorithm.LD_MMA: nlopt.LD_MMA, Algorithm.GN_ISRES: nlopt.GN_ISRES, Algorithm.GN_DIRECT_L: nlopt.GN_DIRECT_L,
    Algorithm.AUGLAG: nlopt.AUGLAG,
}


class Source(StrEnum):
    EVALUATED = "evaluated"  # an evaluator ran in this session
    REPLAYED = "replayed"  # taken from the recorder (an earlier session of this run)
    CACHED = "cached"  # the same point asked again in this session


@dataclass(frozen=True, kw_only=True)
class EvalRecord:
    """One point asked by the optimiser, in order."""

    index: int  # position in the run's history
    start: int
    stage: str  # "search" or "polish"
    x: tuple[float, ...]  # edge units
    objective: float  # the objective metric (NaN if unavailable)
    f: float  # value handed to nlopt (guarded, minimised)
    constraints: tuple[float, ...]  # normalised (≤ 0 satisfied)
    feasible: bool
    outcome: Outcome
    message: str
    source: Source
    metrics: dict[str, Any] = field(default_factory=dict, compare=False)
    timings_s: dict[str, float] = field(default_factory=dict, compare=False)
    elapsed_s: float = field(default=0.0, compare=False)

    @property
    def max_violation(self) -> float:
        return max(self.constraints, default=0.0)


@dataclass(frozen=True, kw_only=True)
class StartResult:
    start: int
    x0: tuple[float, ...]
    x: tuple[float, ...]  # nlopt's returned point (edge units)
    f: float
    status: StartStatus
    message: str
    n_points: int
    rejected_draws: int = 0  # start points drawn and rejected before this one: their design cannot be built


@dataclass(frozen=True, kw_only=True)
class RunResult:
    """What a run returns: per-start statuses, the best point and the full history."""

    problem_name: str
    objective_metric: str  # the metric optimised (a smooth surrogate where noted)
    starts: tuple[StartResult, ...]
    history: tuple[EvalRecord, ...]
    best: EvalRecord | None  # best feasible point (or least infeasible when none is feasible)
    feasible: bool
    n_evaluated: int
    n_replayed: int
    n_cached: int
    notes: tuple[str, ...]
    wall_s: float

    @property
    def status(self) -> str:
        """``no_valid_point`` if no point evaluated cleanly (e.g. every start fails: a plateau of
        penalties stalls any local method), ``converged`` if any start converged, else the first
        start's status."""
        if self.best is None:
            return "no_valid_point"
        if any(s.status.converged for s in self.starts):
            return "converged"
        return str(self.starts[0].status) if self.starts else "no_starts"


ProgressFn = Callable[[EvalRecord, "EvalRecord | None", int], None]


def smooth_objective(problem: Problem, needs_gradient: bool) -> tuple[Problem, str | None]:
    """Swap a kinked objective for its smooth surrogate when a gradient is needed."""
    name = problem.objective.metric.name
    if needs_gradient and name in SMOOTH_SURROGATES and not problem.objective.metric.index:
        new_ref = MetricRef.parse(SMOOTH_SURROGATES[name], "objective")
        note = (f"objective {name} has a kink at its optimum: gradients use its smooth form "
                f"{new_ref.name} (same minimiser)")
        return dataclasses.replace(problem, objective=dataclasses.replace(problem.objective, metric=new_ref)), note
    return problem, None


def needs_gradient(cfg: Any) -> bool:
    alg: Algorithm = cfg.algorithm
    if alg.needs_gradient:
        return True
    if alg is Algorithm.AUGLAG or alg.is_global:
        return cfg.local.needs_gradient
    return False


def metric_sources(metric_modules: dict[str, str], refs: Sequence[MetricRef]) -> tuple[tuple[str, str], ...] | None:
    """(metric, module) for every ref when each has a jax twin, else None (finite differences)."""
    out = []
    for ref in refs:
        module = metric_modules.get(ref.name)
        if module is None or jax_twin(module) is None:
            return None
        out.append((ref.name, module))
    return tuple(sorted(set(out)))


#: draws per start at most before a start is taken as drawn (every one rejected: it says so)
MAX_DRAWS = 1000


def _buildable(problem: Problem, u: np.ndarray) -> bool:
    """Whether the design at normalised ``u`` is valid and can be built (:func:`registry.not_built`)."""
    lo, hi = np.asarray(problem.lower), np.asarray(problem.upper)
    try:
        design = problem.design_at(tuple(lo + u * (hi - lo)))
    except HapticoptError:
        return False
    return not not_built(design)


def start_draws(problem: Problem) -> list[tuple[np.ndarray, int]]:
    """Normalised start points and, per start, the draws rejected before it: start 0 is the problem's start
    (never redrawn, 0); the others uniform from the seed, each redrawn while its design cannot be built
    (invalid, or :func:`hapticopt.analysis.registry.not_built`: a start there fails at every point nearby,
    issue 30: a third of a run's budget was spent on such a start), at most :data:`MAX_DRAWS` draws."""
    lo, hi = np.asarray(problem.lower), np.asarray(problem.upper)
    u0 = (np.asarray(problem.start) - lo) / (hi - lo)
    rng = np.random.default_rng(problem.optimiser.seed)
    out = [(np.clip(u0, 0.0, 1.0), 0)]
    for _ in range(problem.optimiser.starts - 1):
        for rejected in range(MAX_DRAWS):
            u = rng.uniform(0.0, 1.0, size=len(lo))
            if _buildable(problem, u):
                break
        else:
            rejected = MAX_DRAWS
        out.append((u, rejected))
    return out


def start_points(problem: Problem) -> list[np.ndarray]:
    """Normalised start points (:func:`start_draws`)."""
    return [u for u, _ in start_draws(problem)]


def _budgets(total: int, starts: int) -> list[int]:
    base, extra = divmod(total, starts)
    return [base + (1 if i < extra else 0) for i in range(starts)]


class _Run:
    """State shared by the starts of one run (history, best, recorder, executor)."""

    def __init__(self, problem: Problem, *, executor: Executor, recorder: Recorder | None,
                 evaluate_fn: Callable[[PointTask], PointResult], only: tuple[str, ...] | None,
                 gradient: GradientMode, jax_sources: tuple[tuple[str, str], ...], progress: ProgressFn | None,
                 deadline: float, compute: Compute = DEFAULT) -> None:
        self.problem = problem
        self.executor = executor
        self.compute = worker_compute(executor, compute)  # the route handed to each point's task
        self.recorder = recorder
        self.evaluate_fn = evaluate_fn
        self.only = only
        self.gradient = gradient
        self.jax_sources = jax_sources
        self.progress = progress
        self.deadline = deadline
        self.refs = problem.metric_refs()
        self.lo = np.asarray(problem.lower, dtype=float)
        self.span = np.asarray(problem.upper, dtype=float) - self.lo
        self.lock = threading.Lock()
        self.history: list[EvalRecord] = []
        self.cache: dict[str, PointResult] = {}
        self.counts = {s: 0 for s in Source}
        self.best: EvalRecord | None = None
        self.t0 = time.perf_counter()

    def x_of(self, u: np.ndarray) -> tuple[float, ...]:
        return tuple(float(v) for v in self.lo + np.clip(u, 0.0, 1.0) * self.span)

    def point(self, x: tuple[float, ...], start: int, stage: str) -> tuple[PointResult, Source]:
        fid = str(self.problem.fidelity_optimise)
        grad = self.gradient is not GradientMode.NONE
        key = point_key(x, fid, grad)
        with self.lock:
            hit = self.cache.get(key)
        if hit is not None:
            return hit, Source.CACHED
        if self.recorder is not None:
            prev = self.recorder.lookup(key)
            if prev is not None:
                with self.lock:
                    self.cache[key] = prev
                return prev, Source.REPLAYED
        task = PointTask(base=self.problem.base, variables=self.problem.variables, x=x,
                         fidelity=self.problem.fidelity_optimise, refs=self.refs, only=self.only,
                         gradient=self.gradient, jax_sources=self.jax_sources, compute=self.compute)
        try:
            result = self.executor.submit(self.evaluate_fn, task).result()
        except Exception as exc:  # a worker crash is a handled outcome too
            result = PointResult(x=x, outcome=Outcome.EVALUATOR_FAILED, message=f"{type(exc).__name__}: {exc}",
                                 values=tuple(math.nan for _ in self.refs))
        if self.recorder is not None:
            self.recorder.record(key, result, start=start, stage=stage, fidelity=fid)
        with self.lock:
            self.cache[key] = result
        return result, Source.EVALUATED

    def add(self, rec_kw: dict[str, Any]) -> EvalRecord:
        with self.lock:
            rec = EvalRecord(index=len(self.history), elapsed_s=time.perf_counter() - self.t0, **rec_kw)
            self.history.append(rec)
            self.counts[rec.source] += 1
            if rec.outcome is Outcome.OK and _better(rec, self.best, self.problem.optimiser.constraint_tol):
                self.best = rec
            best = self.best
            n_eval = self.counts[Source.EVALUATED]
        if self.progress is not None:
            self.progress(rec, best, n_eval)
        return rec


def _better(a: EvalRecord, b: EvalRecord | None, tol: float) -> bool:
    if b is None:
        return True
    fa, fb = a.max_violation <= tol, b.max_violation <= tol
    if fa != fb:
        return fa
    if not fa:
        return a.max_violation < b.max_violation
    return a.f < b.f


class _Start:
    """One nlopt run (possibly two stages: global search then local polish)."""

    def __init__(self, run: _Run, index: int, u0: np.ndarray, budget: int) -> None:
        self.run = run
        self.index = index
        self.u0 = u0
        self.budget = budget
        self.worst_f: float | None = None
        self.memo: dict[bytes, tuple[float, np.ndarray | None, np.ndarray, np.ndarray | None]] = {}
        self.stage = "search"
        self.n_points = 0

    # --------------------------------------------------------------- the guarded value at u
    def values(self, u: np.ndarray) -> tuple[float, np.ndarray | None, np.ndarray, np.ndarray | None]:
        key = u.tobytes() + self.stage.encode()
        if key in self.memo:
            return self.memo[key]
        run, problem = self.run, self.run.problem
        x = run.x_of(u)
        result, source = run.point(x, self.index, self.stage)
        sign = -1.0 if problem.objective.sense is Sense.MAXIMISE else 1.0
        m = len(problem.constraints)
        ok = result.outcome is Outcome.OK and all(math.isfinite(v) for v in result.values)
        if ok:
            obj = result.values[0]
            f = sign * obj
            cons = np.array([c.normalised(v) for c, v in zip(problem.constraints, result.values[1:])])
            if self.worst_f is None or f > self.worst_f:
                self.worst_f = f
        else:
            obj = result.values[0] if result.values else math.nan
            f = FIRST_PENALTY if self.worst_f is None else self.worst_f + max(1.0, abs(self.worst_f))
            cons = np.full(m, FAILED_CONSTRAINT)
        grad_f = grad_c = None
        if run.gradient is not GradientMode.NONE:
            n = len(u)
            if ok and result.gradients is not None:
                g = np.asarray(result.gradients) * run.span  # d/du = d/dx · (upper − lower)
                grad_f = sign * g[0]
                grad_c = np.array([(-1.0 if c.op.value == ">=" else 1.0) * g[1 + i] / c.scale
                                   for i, c in enumerate(problem.constraints)]).reshape(m, n)
            else:
                grad_f = np.zeros(n)
                grad_c = np.zeros((m, n))
        feasible = ok and (float(np.max(cons, initial=0.0)) <= problem.optimiser.constraint_tol)
        run.add(dict(start=self.index, stage=self.stage, x=x, objective=float(obj), f=float(f),
                     constraints=tuple(float(c) for c in cons), feasible=bool(feasible), outcome=result.outcome,
                     message=result.message, source=source, metrics=result.metrics, timings_s=result.timings_s))
        self.n_points += 1
        out = (float(f), grad_f, cons, grad_c)
        self.memo[key] = out
        return out

    def objective(self, u: np.ndarray, grad: np.ndarray) -> float:
        f, gf, _, _ = self.values(np.array(u, dtype=float))
        if grad.size > 0:
            grad[:] = gf if gf is not None else 0.0
        return f

    def constraints(self, result: np.ndarray, u: np.ndarray, grad: np.ndarray) -> None:
        _, _, c, gc = self.values(np.array(u, dtype=float))
        result[:] = c
        if grad.size > 0:
            grad[:] = gc if gc is not None else 0.0

    # --------------------------------------------------------------- one nlopt stage
    def _make(self, alg: Algorithm, budget: int) -> nlopt.opt:
        cfg = self.run.problem.optimiser
        n = len(self.u0)
        opt = nlopt.opt(_NLOPT_ALG[alg], n)
        opt.set_lower_bounds(np.zeros(n))
        opt.set_upper_bounds(np.ones(n))
        opt.set_min_objective(self.objective)
        if self.run.problem.constraints:
            opt.add_inequality_mconstraint(self.constraints, [1e-9] * len(self.run.problem.constraints))
        opt.set_xtol_abs(cfg.xtol_rel)
        opt.set_ftol_rel(cfg.ftol_rel)
        opt.set_maxeval(max(1, budget))
        remaining = self.run.deadline - time.monotonic()
        opt.set_maxtime(max(1e-3, remaining))
        if alg is Algorithm.AUGLAG:
            local = nlopt.opt(_NLOPT_ALG[cfg.local], n)
            local.set_xtol_abs(cfg.xtol_rel)
            local.set_ftol_rel(cfg.ftol_rel)
            opt.set_local_optimizer(local)
        if alg.is_global:
            nlopt.srand(cfg.seed * 1009 + self.index)  # nlopt's RNG is thread-local
            if alg is Algorithm.GN_ISRES:
                opt.set_population(max(20, 10 * (n + 1)))
        return opt

    def _optimize(self, alg: Algorithm, u0: np.ndarray, budget: int) -> tuple[np.ndarray, float, StartStatus, str]:
        opt = self._make(alg, budget)
        message = ""
        try:
            u = opt.optimize(u0.copy())
            code = opt.last_optimize_result()
        except nlopt.RoundoffLimited:
            u, code, message = None, -4, "roundoff limited: the last steps could not improve (result usually usable)"
        except nlopt.ForcedStop:
            u, code, message = None, -5, "forced stop"
        except (RuntimeError, ValueError) as exc:
            u, code, message = None, -1, f"nlopt failure: {exc}"
        status = _CODES.get(code, StartStatus.FAILURE)
        f = float(opt.last_optimum_value())
        if u is None:  # nlopt raised: take the best point this start has seen
            u = self._best_u(default=u0)
        return np.asarray(u, dtype=float), float(f), status, message

    def run_start(self) -> StartResult:
        cfg = self.run.problem.optimiser
        alg = cfg.algorithm
        if alg.is_global:
            n_global = max(1, int(self.budget * GLOBAL_SHARE))
            u, f, status, msg = self._optimize(alg, self.u0, n_global)
            best_u = self._best_u(default=u)
            polish = cfg.local
            if self.run.problem.constraints and not polish.handles_constraints:
                polish = Algorithm.LN_COBYLA
            self.stage = "polish"
            u, f, status, msg2 = self._optimize(polish, best_u, max(1, self.budget - n_global))
            msg = "; ".join(m for m in (msg, msg2) if m)
        else:
            u, f, status, msg = self._optimize(alg, self.u0, self.budget)
        return StartResult(start=self.index, x0=self.run.x_of(self.u0), x=self.run.x_of(u), f=f, status=status,
                           message=msg, n_points=self.n_points)

    def _best_u(self, default: np.ndarray) -> np.ndarray:
        tol = self.run.problem.optimiser.constraint_tol
        best = None
        for rec in self.run.history:
            if rec.start == self.index and rec.outcome is Outcome.OK and _better(rec, best, tol):
                best = rec
        if best is None:
            return default
        return (np.asarray(best.x) - self.run.lo) / self.run.span


def run(problem: Problem, *, executor: Executor | None = None, recorder: Recorder | None = None,
        metric_modules: dict[str, str] | None = None, only: tuple[str, ...] | None = None,
        evaluate_fn: Callable[[PointTask], PointResult] = evaluate_point,
        progress: ProgressFn | None = None, compute: Compute = DEFAULT) -> RunResult:
    """Optimise ``problem``; every start is an independent, seeded nlopt run; ``compute`` is the route of
    the points' evaluations (one kernel thread each in a pool's worker).

    ``metric_modules`` maps metric names to the evaluator module producing them (from a
    baseline evaluation; needed for jax gradients). ``only`` restricts the evaluators run per
    point. With a parallel executor the starts run concurrently (one thread each submitting
    its points); the history is then ordered by arrival, each start's own sequence unchanged.
    """
    t0 = time.perf_counter()
    executor = executor or InlineExecutor()
    cfg = problem.optimiser
    notes: list[str] = []
    grad_needed = needs_gradient(cfg)
    problem, note = smooth_objective(problem, grad_needed)
    if note:
        notes.append(note)
    gradient = GradientMode.NONE
    jax_sources: tuple[tuple[str, str], ...] = ()
    if grad_needed:
        sources = metric_sources(metric_modules or {}, problem.metric_refs())
        if sources is None:
            gradient = GradientMode.FD
            notes.append("gradients by central finite differences (an evaluator has no jax twin): 2n extra "
                         "evaluations per point")
        else:
            gradient, jax_sources = GradientMode.JAX, sources
            notes.append("gradients from jax (evaluators' jax twins)")
    state = _Run(problem, executor=executor, recorder=recorder, evaluate_fn=evaluate_fn, only=only,
                 gradient=gradient, jax_sources=jax_sources, progress=progress,
                 deadline=time.monotonic() + cfg.max_time_s, compute=compute)
    draws = start_draws(problem)
    starts = [_Start(state, i, u0, b) for i, ((u0, _), b) in enumerate(zip(draws, _budgets(cfg.max_evals, cfg.starts)))]
    rejected = [n for _, n in draws]
    if any(rejected):
        notes.append("start points drawn from designs that can be built: rejected and redrawn "
                     + ", ".join(f"{n} for start {i}" for i, n in enumerate(rejected) if n)
                     + (f" (start(s) {', '.join(str(i) for i, n in enumerate(rejected) if n >= MAX_DRAWS)}: "
                        f"none of {MAX_DRAWS} draws could be built)" if any(n >= MAX_DRAWS for n in rejected) else ""))
    parallel = min(worker_count(executor), len(starts))
    if parallel > 1:
        with ThreadPoolExecutor(max_workers=parallel) as threads:
            results = list(threads.map(lambda s: s.run_start(), starts))
    else:
        results = [s.run_start() for s in starts]
    results = [dataclasses.replace(r, rejected_draws=n) for r, n in zip(results, rejected)]
    best = state.best
    feasible = best is not None and best.max_violation <= cfg.constraint_tol
    return RunResult(problem_name=problem.name, objective_metric=problem.objective.metric.text,
                     starts=tuple(results), history=tuple(state.history), best=best, feasible=feasible,
                     n_evaluated=state.counts[Source.EVALUATED], n_replayed=state.counts[Source.REPLAYED],
                     n_cached=state.counts[Source.CACHED], notes=tuple(notes), wall_s=time.perf_counter() - t0)

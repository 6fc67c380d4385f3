"""One design point: run the evaluators, pick the problem's scalars, and their gradients.

This is the unit of work handed to an executor (process pool, Dask worker or inline), so
everything here is picklable and module-level. Failures are values (:class:`Outcome`), never
exceptions.

Gradients. An evaluator module may provide a differentiable twin of its metrics::

    def jax_metrics(design, values: Mapping[str, jax.Array]) -> Mapping[str, jax.Array]

where ``values`` maps TOML keys (``"geometry.beta_deg"``, edge units) to jax scalars that
override the design's fields, and the result holds metrics with the same names and
engineering units as ``Result.metrics()``. :data:`JAX_ADAPTERS` supplies the twin for
evaluators that do not define one (``hapticopt.analysis.prrr.structure.statics``). A metric without a jax twin
gets central finite differences (2n extra evaluations; reported as ``gradient_source = "fd"``).
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import numpy as np

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import evaluate_all, evaluate_batch
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.units import TO_SI
from hapticopt.analysis.status import Status
from hapticopt.optim import cache as evaluation_cache
from hapticopt.optim.cache import EvaluationCache
from hapticopt.optim.problem import MetricRef, Variable, design_at
from hapticopt.design.schema import specs
import importlib


class Outcome(StrEnum):
    OK = "ok"
    INVALID_DESIGN = "invalid_design"  # the variables violate a design rule (e.g. bore ≥ boss)
    EVALUATOR_FAILED = "evaluator_failed"  # an evaluator raised, or returned a status whose numbers do not
    # hold (failed, not-assemblable, singular, ill-conditioned, not-positive-definite, unstable, inconclusive:
    # Status.metrics_hold; not-met and collides keep their numbers, the optimiser steers on them)
    NONFINITE = "nonfinite"  # a picked metric is NaN/inf


class GradientMode(StrEnum):
    NONE = "none"
    JAX = "jax"
    FD = "fd"


@dataclass(frozen=True, kw_only=True)
class PointTask:
    base: Any
    variables: tuple[Variable, ...]
    x: tuple[float, ...]  # edge units
    fidelity: Fidelity
    refs: tuple[MetricRef, ...]  # objective first, then constraints
    only: tuple[str, ...] | None = None  # evaluator names to run (None: all for the device)
    gradient: GradientMode = GradientMode.NONE
    jax_sources: tuple[tuple[str, str], ...] = ()  # metric name -> evaluator module with a jax twin
    cache: str | None = None  # evaluation cache file (hapticopt.optim.cache) for the design's evaluation, or None
    compute: Compute = DEFAULT  # the route (one kernel thread in a pool's worker: executor.worker_compute)


@dataclass(frozen=True, kw_only=True)
class PointResult:
    x: tuple[float, ...]
    outcome: Outcome
    message: str = ""
    values: tuple[float, ...] = ()  # one per ref (NaN when unavailable)
    gradients: tuple[tuple[float, ...], ...] | None = None  # d value / d x (edge units), one row per ref
    gradient_source: str = "none"
    metrics: dict[str, Any] = field(default_factory=dict)
    statuses: dict[str, str] = field(default_factory=dict)
    timings_s: dict[str, float] = field(default_factory=dict)
    provenance: str = ""  # '' evaluated here; else where the metrics came from (the evaluation cache)


#: open evaluation caches of this process, by (file, pid): a forked worker opens its own connection
_CACHES: dict[tuple[str, int], EvaluationCache] = {}


def _cache(path: str) -> EvaluationCache:
    key = (path, os.getpid())
    if key not in _CACHES:
        _CACHES[key] = EvaluationCache(path)
    return _CACHES[key]


def run_evaluators(design: Any, fidelity: Fidelity, only: tuple[str, ...] | None, compute: Compute = DEFAULT
                   ) -> tuple[dict[str, Any], dict[str, str], dict[str, float], dict[str, str]]:
    """metrics, statuses, timings, each evaluator's message: the registry's one loop, flattened
    to plain values for the record (exceptions are already statuses there)."""
    ev = evaluate_all(design, fidelity=fidelity, only=only, compute=compute)
    return ev.metrics(), {k: str(v) for k, v in ev.statuses.items()}, dict(ev.timings_s), dict(ev.messages)


def evaluate_point(task: PointTask) -> PointResult:
    """Evaluate one design point (the function executors run)."""
    x = tuple(float(v) for v in task.x)
    try:
        design = design_at(task.base, task.variables, x)
    except InvalidDesign as exc:
        return PointResult(x=x, outcome=Outcome.INVALID_DESIGN, message=str(exc),
                           values=tuple(math.nan for _ in task.refs))
    provenance = ""
    if task.cache is not None:
        ev = evaluation_cache.evaluate(design, task.fidelity, cache=_cache(task.cache), only=task.only,
                                       written_by="hapticopt sweep", compute=task.compute)
        metrics, statuses, timings, provenance = ev.metrics, ev.statuses, dict(ev.timings_s), ev.provenance
        messages = dict(ev.messages)
    else:
        metrics, statuses, timings, messages = run_evaluators(design, task.fidelity, task.only, task.compute)
    return _point(task, x, metrics, statuses, timings, messages, provenance)


def evaluate_points(tasks: Sequence[PointTask]) -> list[PointResult]:
    """:func:`evaluate_point` of many tasks in this process, equal results: the designs go through
    :func:`hapticopt.analysis.registry.evaluate_batch` together (3-PRRR draft designs: one batched
    pass), grouped by fidelity, evaluator selection and route."""
    out: list[PointResult | None] = [None] * len(tasks)
    groups: dict[tuple, list[tuple[int, Any]]] = {}
    for i, task in enumerate(tasks):
        x = tuple(float(v) for v in task.x)
        try:
            design = design_at(task.base, task.variables, x)
        except InvalidDesign as exc:
            out[i] = PointResult(x=x, outcome=Outcome.INVALID_DESIGN, message=str(exc),
                                 values=tuple(math.nan for _ in task.refs))
            continue
        groups.setdefault((task.fidelity, task.only, task.compute), []).append((i, design))
    for (fidelity, only, compute), members in groups.items():
        evs = evaluate_batch([d for _, d in members], fidelity=fidelity, only=only, compute=compute)
        for (i, _), ev in zip(members, evs):
            task = tasks[i]
            out[i] = _point(task, tuple(float(v) for v in task.x), ev.metrics(),
                            {k: str(v) for k, v in ev.statuses.items()}, dict(ev.timings_s), dict(ev.messages))
    return [r for r in out if r is not None]


def failure_message(statuses: Mapping[str, str], messages: Mapping[str, str]) -> str:
    """``evaluator: status — message`` of every evaluator whose numbers do not hold, joined by '; ' ('' when
    all hold): the reason the record keeps for a failed point (``hapticopt show`` counts them)."""
    return "; ".join(f"{name}: {st}" + (f" — {messages[name]}" if messages.get(name) else "")
                     for name, st in statuses.items() if not Status(st).metrics_hold)


def _point(task: PointTask, x: tuple[float, ...], metrics: dict[str, Any], statuses: dict[str, str],
           timings: dict[str, float], messages: Mapping[str, str], provenance: str = "") -> PointResult:
    """The outcome, picked values and (if asked) gradients of one evaluated design point; a point whose
    evaluators' numbers do not hold keeps each one's status and message as its message."""
    values = tuple(ref.value(metrics) for ref in task.refs)
    failure = failure_message(statuses, messages)
    if failure:
        outcome, message = Outcome.EVALUATOR_FAILED, failure
        values = tuple(math.nan for _ in task.refs)  # a singular or unstable point is never a number
    elif not all(math.isfinite(v) for v in values):
        bad = [r.text for r, v in zip(task.refs, values) if not math.isfinite(v)]
        outcome, message = Outcome.NONFINITE, "non-finite " + ", ".join(bad)
    else:
        outcome, message = Outcome.OK, ""
    gradients = None
    source = "none"
    if outcome is Outcome.OK and task.gradient is not GradientMode.NONE:
        t0 = time.perf_counter()
        if task.gradient is GradientMode.JAX:
            g = jax_gradients(task.base, task.variables, task.refs, task.jax_sources, x)
            source = "jax"
        else:
            g = fd_gradients(task, x, values)
            source = "fd"
        timings["gradient"] = time.perf_counter() - t0
        if g is not None and np.all(np.isfinite(g)):
            gradients = tuple(tuple(float(v) for v in row) for row in g)
        else:
            outcome, message = Outcome.NONFINITE, "non-finite gradient"
    return PointResult(x=x, outcome=outcome, message=message, values=values, gradients=gradients,
                       gradient_source=source, metrics=metrics, statuses=statuses, timings_s=timings,
                       provenance=provenance)


# ------------------------------------------------------------------------------------ jax twins
def _si(design: Any, values: Mapping[str, Any], key: str) -> Any:
    """The field ``section.toml_key`` of ``design`` in SI, overridden by ``values`` (edge units)."""

    section, tkey = key.split(".")
    sec = getattr(design, section)
    for name, spec in specs(sec).items():
        if spec.key == tkey:
            if key in values:
                return values[key] * TO_SI[spec.unit]
            return float(getattr(sec, name))
    raise KeyError(key)


def _prrr_statics_jax(design: Any, values: Mapping[str, Any]) -> dict[str, Any]:
    """Differentiable twin of :func:`hapticopt.analysis.prrr.structure.statics.evaluate` (same names and units)."""
    # jax-based modules, imported where used: a process that never asks for a gradient pays no jax import
    from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
    from hapticopt.analysis.prrr.structure.statics import statics_arrays
    from hapticopt.design.prrr.kinematics import PrrrParams

    g = "geometry."
    params = PrrrParams(*(_si(design, values, g + k) for k in
                          ("beta_deg", "d1_mm", "d2_mm", "d3_mm", "d4_mm", "r4_mm", "b5_mm", "stroke_mm")))
    out = statics_arrays(params, _si(design, values, "actuator.spring_N_per_mm"),
                         _si(design, values, "actuator.force_limit_N"), _si(design, values, "end_effector.mass_kg"))
    return {
        "jacobian_condition": out["condition"],
        "jacobian_condition_frobenius": out["condition_frobenius"],
        "max_force_N": out["max_force"],
        "max_pure_force_N": out["max_pure_force"],
        "stiffness_limit_N_per_mm": out["stiffness_limit"] * 1e-3,
        "effective_mass_kg": out["effective_mass"],
    }


#: evaluator module -> jax twin, for evaluators that do not define ``jax_metrics`` themselves
JAX_ADAPTERS: dict[str, Callable[[Any, Mapping[str, Any]], Mapping[str, Any]]] = {
    "hapticopt.analysis.prrr.structure.statics": _prrr_statics_jax,
}


def jax_twin(module_name: str) -> Callable[[Any, Mapping[str, Any]], Mapping[str, Any]] | None:

    module = importlib.import_module(module_name)
    fn = getattr(module, "jax_metrics", None)
    return fn if callable(fn) else JAX_ADAPTERS.get(module_name)


def _pick_jax(raw: Any, ref: MetricRef) -> Any:
    from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
    import jax.numpy as jnp

    if ref.reduce == "min":
        return jnp.min(jnp.asarray(raw))
    if ref.reduce == "max":
        return jnp.max(jnp.asarray(raw))
    value = jnp.asarray(raw)
    for i in ref.index:
        value = value[i]
    return value


@functools.lru_cache(maxsize=16)
def _jacobian_fn(base: Any, variables: tuple[Variable, ...], refs: tuple[MetricRef, ...],
                 jax_sources: tuple[tuple[str, str], ...]) -> Callable[[np.ndarray], np.ndarray]:
    from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
    import jax
    import jax.numpy as jnp

    sources = dict(jax_sources)
    twins = {name: jax_twin(module) for name, module in sources.items()}

    def picked(xv: Any) -> Any:
        values = {v.key: xv[i] for i, v in enumerate(variables)}
        cache: dict[str, Mapping[str, Any]] = {}
        out = []
        for ref in refs:
            module = sources[ref.name]
            if module not in cache:
                cache[module] = twins[ref.name](base, values)  # type: ignore[misc]
            out.append(_pick_jax(cache[module][ref.name], ref))
        return jnp.stack(out)

    return jax.jit(jax.jacfwd(picked))


def jax_gradients(base: Any, variables: tuple[Variable, ...], refs: tuple[MetricRef, ...],
                  jax_sources: tuple[tuple[str, str], ...], x: Sequence[float]) -> np.ndarray:
    """d ref / d x (edge units), shape (len(refs), len(x)), from the evaluators' jax twins."""
    fn = _jacobian_fn(base, variables, refs, jax_sources)
    return np.asarray(fn(np.asarray(x, dtype=float)))


def fd_gradients(task: PointTask, x: Sequence[float], values: Sequence[float], *, rel_step: float = 1e-6
                 ) -> np.ndarray:
    """Central finite differences (one-sided at a bound), step rel_step × variable range."""
    n = len(x)
    g = np.full((len(task.refs), n), np.nan)
    # the 2n shifted designs are evaluated together (registry.evaluate_batch: one batched pass
    # for 3-PRRR draft designs, the registry loop otherwise)
    shifted: dict[tuple[int, float], Any] = {}
    for i, var in enumerate(task.variables):
        h = rel_step * (var.upper - var.lower)
        for sgn, ok in ((1.0, x[i] + h <= var.upper), (-1.0, x[i] - h >= var.lower)):
            if ok:
                xp = list(x)
                xp[i] = x[i] + sgn * h
                try:
                    shifted[(i, sgn)] = design_at(task.base, task.variables, xp)
                except InvalidDesign:
                    pass
    evs = dict(zip(shifted, evaluate_batch(list(shifted.values()), fidelity=task.fidelity, only=task.only,
                                           compute=task.compute)))
    for i, var in enumerate(task.variables):
        h = rel_step * (var.upper - var.lower)
        pts = []
        for sgn in (1.0, -1.0):
            ev = evs.get((i, sgn))
            pts.append(None if ev is None or ev.failures() else [ref.value(ev.metrics()) for ref in task.refs])
        fp, fm = pts
        if fp is not None and fm is not None:
            g[:, i] = (np.asarray(fp) - np.asarray(fm)) / (2 * h)
        elif fp is not None:
            g[:, i] = (np.asarray(fp) - np.asarray(values)) / h
        elif fm is not None:
            g[:, i] = (np.asarray(values) - np.asarray(fm)) / h
    return g

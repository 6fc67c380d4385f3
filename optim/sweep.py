"""Parameter sweeps over any numeric design key, 1-D or 2-D, on the executor, recorded like a run.

``KEY=lo:hi:n`` (TOML key ``section.key`` in its edge unit, ``n ≥ 2`` evenly spaced values, both
ends included). A sweep is the full grid of its axes (the first axis varies slowest). Each point
is :func:`hapticopt.optim.evaluation.evaluate_point` — the same unit of work as an optimiser
point — submitted to the executor (process pool, inline or Dask); results do not depend on the
executor. Every point is recorded in ``DIR/evaluations.sqlite`` under its exact key as it
completes, so an interrupted sweep resumes (``--resume``) and recomputes nothing it recorded.

Outputs (written by :func:`write_outputs`): ``sweep.csv`` (one row per point: the keys with
units, the outcome, every scalar metric and every component ``name[i]`` of a vector metric),
``plots/sweep_<metric>.png`` (1-D: metric against the key; 2-D: a filled contour map), the
unit on each axis, and one overview page (:mod:`hapticopt.optim.sweep_overview`: ``overview.png``, every
metric that varies on one sheet with the points that are not ok shaded, and ``overview.html`` around it).
"""

from __future__ import annotations

import csv
import hashlib
import io as _io
import itertools
import math
import re
from collections.abc import Callable, Sequence
from concurrent.futures import Executor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np

from hapticopt.analysis import registry
from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import EVALUATORS
from hapticopt.design import io
from hapticopt.design import paths
from hapticopt.design.atomic import atomic_path, write_text
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design.units import pretty
from hapticopt.optim.evaluation import Outcome, PointResult, PointTask, evaluate_point, evaluate_points
from hapticopt.optim.executor import worker_compute
from hapticopt.optim.problem import Variable, numeric_key
from hapticopt.optim.recorder import Recorder, point_key
from hapticopt.optim.runs import software_versions
from hapticopt.optim import sweep_overview
from hapticopt.design.errors import short

#: at most this many points in one sweep (a typo such as n = 10000 × 10000 is refused). The sweep holds
#: every point's result (≈ 8 kB each for a 3-PRRR draft design) until it writes its table: at 200,000
#: points the process passed 2.1 GB (scripts/bounds_rss.py); 100,000 keeps it near 1.2 GB
MAX_POINTS = 100_000
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_AXIS_RE = re.compile(rf"^\s*([^=\s]+)\s*=\s*({_NUMBER})\s*:\s*({_NUMBER})\s*:\s*(\S+)\s*$")


@dataclass(frozen=True, kw_only=True)
class Axis:
    """One swept key: ``n`` evenly spaced values from ``lo`` to ``hi`` (edge unit)."""

    variable: Variable
    n: int

    @property
    def key(self) -> str:
        return self.variable.key

    @property
    def unit(self) -> str:
        return self.variable.unit

    @property
    def values(self) -> tuple[float, ...]:
        lo, hi, n = self.variable.lower, self.variable.upper, self.n
        # lo + i·(hi − lo)/(n − 1), with both ends exact
        return tuple(lo if i == 0 else hi if i == n - 1 else lo + i * (hi - lo) / (n - 1) for i in range(n))

    @property
    def label(self) -> str:
        return f"{self.key} [{pretty(self.unit)}]"


def parse_axis(text: str, base: Any) -> Axis:
    """``section.key=lo:hi:n`` for a numeric key of ``base``; one-line errors name what is allowed."""
    m = _AXIS_RE.match(text)
    if m is None:
        raise InvalidInput(f"sweep axis {short(text)} must have the form section.key=lo:hi:n, e.g. geometry.beta_deg=30:70:9")
    key, lo_s, hi_s, n_s = m.groups()
    if key.count(".") != 1:
        raise InvalidInput(f"sweep axis {short(key)} is not a numeric design key: give section.key, e.g. geometry.beta_deg "
                           f"(sections of a {base.device} design: {', '.join(base.SECTIONS)})")
    section, fname, spec = numeric_key(base, key, f"sweep axis {key}", role="a numeric key")
    lo, hi = float(lo_s), float(hi_s)
    try:
        n = int(n_s)
    except ValueError:
        raise InvalidInput(f"sweep axis {key}: n = {short(n_s)} must be a whole number of points ≥ 2") from None
    if not 2 <= n <= MAX_POINTS:  # before any value of the axis is made
        raise InvalidInput(f"sweep axis {key}: n = {n} is out of range: allowed 2 ≤ n ≤ {MAX_POINTS} "
                           "(points, both ends included)")
    if not lo < hi:
        raise InvalidInput(f"sweep axis {key}: lo = {lo:g} must be below hi = {hi:g} ({pretty(spec.unit)})")
    for value, name in ((lo, "lo"), (hi, "hi")):
        try:
            spec.check(f"sweep axis {key}: {name}", value)
        except InvalidDesign as exc:
            raise InvalidInput(str(exc)) from None
    axis = Axis(variable=Variable(key=key, section=section, field=fname, unit=spec.unit, lower=lo, upper=hi,
                                  start=lo), n=n)
    if spec.integer and not (lo == int(lo) and ((hi - lo) / (n - 1)) == int((hi - lo) / (n - 1))):
        raise InvalidInput(f"sweep axis {key} takes whole numbers: {lo:g}:{hi:g}:{n} gives fractions "
                           f"(choose n so that (hi − lo)/(n − 1) is whole)")
    return axis


@dataclass(frozen=True, kw_only=True)
class Sweep:
    """What to sweep: the base design, one or two axes, the fidelity, the evaluators run per point."""

    base: Any
    axes: tuple[Axis, ...]
    fidelity: Fidelity = Fidelity.DRAFT
    only: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        if not 1 <= len(self.axes) <= 2:
            raise InvalidInput(f"a sweep takes 1 or 2 axes KEY=lo:hi:n, not {len(self.axes)}")
        keys = [a.key for a in self.axes]
        if len(set(keys)) != len(keys):
            raise InvalidInput(f"sweep axis {keys[0]} is given twice")
        if self.n_points > MAX_POINTS:
            raise InvalidInput(f"the sweep has {self.n_points} points: allowed at most {MAX_POINTS}")
        if self.only is not None:
            names = [e.name for e in EVALUATORS[self.base.device]]
            if not self.only:  # issue 37: `--only ""` reported every point ok while evaluating nothing
                raise InvalidInput(f"--only names no evaluator: allowed one or more of {', '.join(names)}")
            for name in self.only:
                if name not in names:
                    raise InvalidInput(f"--only {short(name)} is not an evaluator of a {self.base.device} design: "
                                       f"allowed {', '.join(names)}")

    @property
    def variables(self) -> tuple[Variable, ...]:
        return tuple(a.variable for a in self.axes)

    @property
    def n_points(self) -> int:
        return math.prod(a.n for a in self.axes)

    def points(self) -> list[tuple[float, ...]]:
        """The grid, first axis slowest (row-major)."""
        return [tuple(p) for p in itertools.product(*(a.values for a in self.axes))]

    def fingerprint(self) -> str:
        payload = repr(("sweep", io.dumps(self.base), self.variables, tuple(a.n for a in self.axes),
                        str(self.fidelity), self.only))
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    def info(self) -> dict[str, Any]:
        """The record's ``run_info`` for this sweep."""
        return {"kind": "sweep", "problem": f"{self.base.name} sweep",
                "description": f"{self.base.name}: " + ", ".join(f"{a.key}={a.variable.lower:g}:{a.variable.upper:g}:"
                                                                 f"{a.n}" for a in self.axes),
                "device": self.base.device, "base_design": io.dumps(self.base),
                "variables": [{"key": a.key, "unit": a.unit, "lower": a.variable.lower, "upper": a.variable.upper,
                               "start": a.variable.lower, "n": a.n} for a in self.axes],
                "objectives": [], "constraints": [], "fidelity": {"optimise": str(self.fidelity)},
                "only": list(self.only) if self.only is not None else None, "versions": software_versions()}


@dataclass(frozen=True, kw_only=True)
class SweepResult:
    sweep: Sweep
    points: tuple[tuple[float, ...], ...]
    results: tuple[PointResult, ...]  # one per point, in grid order
    n_evaluated: int
    n_replayed: int

    @property
    def n_cached(self) -> int:
        """Points whose metrics came from the evaluation cache (counted in ``n_evaluated``)."""
        return sum(bool(r.provenance) for r in self.results)

    @property
    def n_ok(self) -> int:
        return sum(r.outcome is Outcome.OK for r in self.results)


ProgressFn = Callable[[int, int], None]  # (done, total)

#: evaluators with a batched form at any fidelity, by device (3-PRRR draft sweeps batch every evaluator)
BATCHED: dict[str, tuple[str, ...]] = {"prrr": ("statics",)}
#: designs per batched call (the batched evaluator pads each call to a power of two)
BATCH_CHUNK = 256


def batch_supported(sweep: "Sweep") -> bool:
    """True at the fidelity of the device's batch evaluator (:data:`hapticopt.analysis.registry.BATCHED`:
    the 3-PRRR's draft, every evaluator), or when ``--only`` names evaluators of :data:`BATCHED` only."""
    whole = registry.BATCHED.get(sweep.base.device)
    if whole is not None and Fidelity(sweep.fidelity) is whole.fidelity:
        return True
    allowed = BATCHED.get(sweep.base.device, ())
    return sweep.only is not None and len(sweep.only) > 0 and all(name in allowed for name in sweep.only)


def _run_batched(sweep: "Sweep", xs: Sequence[tuple[float, ...]], compute: Compute) -> list[PointResult]:
    """The batched twin of :func:`evaluate_point` for ``xs`` (no objective references): equal results."""
    return evaluate_points([PointTask(base=sweep.base, variables=sweep.variables, x=tuple(x), fidelity=sweep.fidelity,
                                      refs=(), only=sweep.only, compute=compute) for x in xs])


def run_sweep(sweep: Sweep, *, executor: Executor, recorder: Recorder | None = None,
              progress: ProgressFn | None = None,
              evaluate_fn: Callable[[PointTask], PointResult] = evaluate_point,
              timeout_s: float | None = None, batch: bool = False, cache: str | Path | None = None,
              compute: Compute = DEFAULT) -> SweepResult:
    """Evaluate every grid point (recorded points are replayed); results in grid order.
    ``timeout_s`` bounds the wait for the executor (:class:`TimeoutError` past it). ``batch``
    evaluates in this process with the evaluators' batched jax forms (:func:`batch_supported`).
    ``cache``: the evaluation cache file (:mod:`hapticopt.optim.cache`) the workers consult and fill
    (not the batched forms); a point served from it is recorded with stage ``sweep (evaluation cache)``.
    ``compute``: the route (batched: this process's; on the executor: :func:`executor.worker_compute`)."""
    if batch and not batch_supported(sweep):
        allowed = BATCHED.get(sweep.base.device, ())
        raise InvalidInput(f"--batch needs a 3-PRRR draft sweep, or --only naming evaluators with a batched form: "
                           f"for a {sweep.base.device} design at {sweep.fidelity} "
                           f"design allowed {', '.join(allowed) if allowed else 'none'}")
    points = sweep.points()
    fid = str(sweep.fidelity)
    results: list[PointResult | None] = [None] * len(points)
    keys = [point_key(x, fid, False) for x in points]
    n_replayed = 0
    todo: list[int] = []
    for i, key in enumerate(keys):
        prev = recorder.lookup(key) if recorder is not None else None
        if prev is not None:
            results[i] = prev
            n_replayed += 1
        else:
            todo.append(i)
    done = n_replayed
    if progress is not None:
        progress(done, len(points))
    if batch:
        for c in range(0, len(todo), BATCH_CHUNK):
            idx = todo[c:c + BATCH_CHUNK]
            for i, res in zip(idx, _run_batched(sweep, [points[i] for i in idx], compute)):
                if recorder is not None:
                    recorder.record(keys[i], res, start=0, stage="sweep", fidelity=fid)
                results[i] = res
            done += len(idx)
            if progress is not None:
                progress(done, len(points))
        todo = []
    futures = {executor.submit(evaluate_fn, PointTask(base=sweep.base, variables=sweep.variables, x=points[i],
                                                      fidelity=sweep.fidelity, refs=(), only=sweep.only,
                                                      cache=None if cache is None else str(cache),
                                                      compute=worker_compute(executor, compute))): i
               for i in todo}
    for fut in as_completed(futures, timeout=timeout_s):
        i = futures[fut]
        try:
            res = fut.result()
        except Exception as exc:  # a worker crash is a handled outcome
            res = PointResult(x=points[i], outcome=Outcome.EVALUATOR_FAILED, message=f"{type(exc).__name__}: {exc}")
        if recorder is not None:
            recorder.record(keys[i], res, start=0, stage="sweep (evaluation cache)" if res.provenance else "sweep",
                            fidelity=fid)
        results[i] = res
        done += 1
        if progress is not None:
            progress(done, len(points))
    return SweepResult(sweep=sweep, points=tuple(points), results=tuple(r for r in results if r is not None),
                       n_evaluated=len(points) - n_replayed, n_replayed=n_replayed)


# ------------------------------------------------------------------------------ outputs
def unit_label(name: str) -> str:
    """The printed unit of a metric or a component ``name[i]``, from the registry
    (:func:`hapticopt.analysis.registry.metric_unit`: ``…_MPa_per_N`` → ``MPa/N``); ``-`` when dimensionless."""
    return registry.metric_unit(name) or "-"


def metric_label(name: str) -> str:
    """An axis label: ``name [unit]``."""
    return f"{name} [{unit_label(name)}]"


def scalar_columns(results: Sequence[PointResult]) -> list[str]:
    """Every scalar metric and every component ``name[i]`` of a vector metric, in first-seen order."""
    cols: dict[str, None] = {}
    for r in results:
        for name, value in r.metrics.items():
            for col, _ in scalars(name, value):
                cols.setdefault(col, None)
    return list(cols)


def scalars(name: str, value: Any) -> list[tuple[str, float]]:
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return []
    if isinstance(value, (int, float)):
        return [(name, float(value))]
    if isinstance(value, (list, tuple)) and value and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                          for v in value):
        return [(f"{name}[{i}]", float(v)) for i, v in enumerate(value)]
    return []  # matrices and records: in the record, not in the table


def table(result: SweepResult) -> tuple[list[str], list[list[Any]]]:
    cols = scalar_columns(result.results)
    header = [a.label for a in result.sweep.axes] + ["outcome"] + cols
    rows = []
    for x, r in zip(result.points, result.results):
        values = dict(itertools.chain.from_iterable(scalars(k, v) for k, v in r.metrics.items()))
        rows.append([*x, str(r.outcome), *(values.get(c, math.nan) for c in cols)])
    return header, rows


def rows_csv(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    """CSV text of a table: floats written exactly (repr), NaN as an empty cell."""
    buf = _io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    for row in rows:
        w.writerow(["" if isinstance(v, float) and math.isnan(v) else (repr(v) if isinstance(v, float) else v)
                    for v in row])
    return buf.getvalue()


def csv_text(result: SweepResult) -> str:
    return rows_csv(*table(result))


def write_outputs(result: SweepResult, out_dir: Path, *, plots: bool = True) -> list[Path]:
    """``sweep.csv``; with ``plots`` also one plot per scalar metric column (PNG, units on both axes) and the
    overview page (:func:`write_overview`: ``overview.html`` and ``overview.png``)."""
    out_dir = Path(out_dir)
    written = [out_dir / "sweep.csv"]
    with paths.output_root(out_dir):  # no write follows a link planted below out_dir
        write_text(written[0], csv_text(result))
        if plots:
            written += write_plots(result, out_dir / "plots")
            written += write_overview(result, out_dir)
    return written


def write_overview(result: SweepResult, out_dir: Path) -> list[Path]:
    """``overview.png`` and ``overview.html`` in ``out_dir`` (:mod:`hapticopt.optim.sweep_overview`)."""
    return sweep_overview.write(result, *table(result), out_dir)


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_")


def write_plots(result: SweepResult, plot_dir: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    header, rows = table(result)
    axes = result.sweep.axes
    n_ax = len(axes)
    cols = header[n_ax + 1:]
    data = np.array([[float(v) for v in r[n_ax + 1:]] for r in rows], dtype=float).reshape(len(rows), len(cols))
    paths.make_dirs(plot_dir)
    written = []
    title = f"{result.sweep.base.name} ({result.sweep.fidelity} fidelity)"
    for j, col in enumerate(cols):
        y = data[:, j]
        if not np.any(np.isfinite(y)):
            continue
        fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=100)
        if n_ax == 1:
            ax.plot(axes[0].values, y, "o-", ms=3 if len(y) <= 200 else 0)
            ax.set_xlabel(axes[0].label)
            ax.set_ylabel(metric_label(col))
            ax.grid(True, alpha=0.3)
        else:
            z = y.reshape(axes[0].n, axes[1].n)
            xs, ys = np.asarray(axes[1].values), np.asarray(axes[0].values)
            finite = z[np.isfinite(z)]
            if finite.max() > finite.min():
                cs = ax.contourf(xs, ys, np.ma.masked_invalid(z), levels=12)
            else:
                cs = ax.pcolormesh(xs, ys, np.ma.masked_invalid(z), shading="nearest")
            fig.colorbar(cs, ax=ax, label=metric_label(col))
            ax.set_xlabel(axes[1].label)
            ax.set_ylabel(axes[0].label)
        ax.set_title(title, fontsize=10)
        fig.tight_layout()
        path = plot_dir / f"sweep_{_safe(col)}.png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png")
        plt.close(fig)
        written.append(path)
    return written

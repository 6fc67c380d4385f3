"""Which evaluators apply to which device, in report order; the one loop that runs them.

Each evaluator module exposes ``evaluate(design, *, fidelity) -> Result`` where ``Result`` is
frozen and has ``metrics() -> dict`` (engineering units, unit in the name), ``status`` and
``message``. Pictures are not drawn by evaluators: an entry names a function of its device's
``plots`` module (``"module:function"``, called as ``fn(design, result, out_dir)``). Modules are
imported lazily so that a CLI call pays only for what it runs.

One failure policy for every caller (``hapticopt evaluate``, the optimiser's design points and
the pipeline): an evaluator that raises is reported as :attr:`Status.FAILED` with the
exception's type, message and location (file:line); the other evaluators still run.
"""

from __future__ import annotations

import importlib
import time
import traceback
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidDesign
from hapticopt.design import offscreen
from hapticopt.design.paths import check_name, inside


@dataclass(frozen=True, kw_only=True)
class EvaluatorEntry:
    name: str  # short name used in reports and timings
    module: str  # dotted module path exposing evaluate()
    plot: str | None = None  # "module:function" drawing this evaluator's result, or None

    def load(self) -> Any:
        return importlib.import_module(self.module)

    def plotter(self) -> Any:
        if self.plot is None:
            return None
        module, _, function = self.plot.partition(":")
        return getattr(importlib.import_module(module), function)


_A = "hapticopt.analysis."

#: device -> evaluators in report order. Add a line here to plug an evaluator into
#: ``hapticopt evaluate``, the optimiser and the pipeline.
EVALUATORS: dict[str, tuple[EvaluatorEntry, ...]] = {
    "prrr": (
        EvaluatorEntry(name="statics", module=_A + "prrr.statics"),
        EvaluatorEntry(name="structural_stiffness", module=_A + "prrr.structure",
                       plot=_A + "prrr.plots:structure_plots"),
        EvaluatorEntry(name="workspace", module=_A + "prrr.workspace", plot=_A + "prrr.plots:workspace_plots"),
        EvaluatorEntry(name="interference", module=_A + "prrr.interference"),
        EvaluatorEntry(name="free_workspace", module=_A + "prrr.free_workspace"),
        EvaluatorEntry(name="device_size", module=_A + "prrr.device_size"),
        EvaluatorEntry(name="joint_limits", module=_A + "prrr.joint_limits"),
        EvaluatorEntry(name="stability", module=_A + "prrr.stability"),
    ),
    "master": (
        EvaluatorEntry(name="workspace", module=_A + "master.workspace", plot=_A + "master.plots:workspace_plots"),
        EvaluatorEntry(name="balance", module=_A + "master.balance", plot=_A + "master.plots:balance_plots"),
        EvaluatorEntry(name="transparency", module=_A + "master.transparency",
                       plot=_A + "master.plots:transparency_plots"),
    ),
    "handle": (
        EvaluatorEntry(name="stability", module=_A + "handle.stability"),
        EvaluatorEntry(name="upsampling", module=_A + "handle.upsampled"),
        EvaluatorEntry(name="zwidth", module=_A + "handle.zwidth", plot=_A + "handle.plots:zwidth_plots"),
    ),
}


def jsonable(value: Any) -> Any:
    """A metric value as plain JSON types (numpy scalars and arrays become floats and lists)."""
    if isinstance(value, (bool, str)) or value is None:
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    return str(value)


def describe_failure(exc: BaseException) -> str:
    """``Type: message (file.py:line)`` of the innermost frame that raised."""
    frames = traceback.extract_tb(exc.__traceback__) if exc.__traceback__ else []
    where = f" ({frames[-1].filename.rsplit('/', 1)[-1]}:{frames[-1].lineno})" if frames else ""
    return f"{type(exc).__name__}: {exc}{where}"


@dataclass(frozen=True, kw_only=True)
class Evaluation:
    """Results of every evaluator for one design at one fidelity."""

    fidelity: Fidelity
    results: dict[str, Any]  # evaluator name -> frozen result (evaluators that did not raise)
    timings_s: dict[str, float]
    statuses: dict[str, Status] = field(default_factory=dict)
    messages: dict[str, str] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)  # metric name -> evaluator module

    def metrics(self) -> dict[str, Any]:
        """Every metric of every evaluator, as plain JSON values."""
        out: dict[str, Any] = {}
        for result in self.results.values():
            out.update(jsonable(result.metrics()))
        return out

    def failures(self) -> str:
        """``name: message`` of every failed evaluator, joined by '; ' ('' when none failed)."""
        return "; ".join(f"{name}: {self.messages.get(name) or 'failed'}"
                         for name, st in self.statuses.items() if st is Status.FAILED)


def evaluate_all(design: Any, *, fidelity: Fidelity = Fidelity.STANDARD,
                 only: tuple[str, ...] | None = None) -> Evaluation:
    """Run every evaluator registered for the design's device (or those named in ``only``)."""
    results: dict[str, Any] = {}
    timings: dict[str, float] = {}
    statuses: dict[str, Status] = {}
    messages: dict[str, str] = {}
    sources: dict[str, str] = {}
    for entry in EVALUATORS[design.device]:
        if only is not None and entry.name not in only:
            continue
        t0 = time.perf_counter()
        try:
            result = entry.load().evaluate(design, fidelity=fidelity)
            names = list(result.metrics())
        except Exception as exc:  # noqa: BLE001 - the one failure policy: a status, not a crash
            statuses[entry.name] = Status.FAILED
            messages[entry.name] = describe_failure(exc)
        else:
            results[entry.name] = result
            statuses[entry.name] = Status(result.status)
            messages[entry.name] = result.message
            sources.update({name: entry.module for name in names})
        timings[entry.name] = time.perf_counter() - t0
    return Evaluation(fidelity=fidelity, results=results, timings_s=timings, statuses=statuses,
                      messages=messages, sources=sources)


def run_plotter(entry: EvaluatorEntry, design: Any, result: Any, out_dir: Path) -> list[Path]:
    """The pictures of one evaluator's ``result`` in ``out_dir`` (the files written).

    Plotters name their files ``<design name>_<what>.png`` in ``out_dir``: the name is checked
    (:func:`design.paths.check_name`) before, and every returned path is checked to lie inside
    ``out_dir``.
    """
    check_name(design.name, "design name", error=InvalidDesign)
    out_dir = Path(out_dir)
    plotter = entry.plotter()
    if plotter is None:
        return []
    offscreen.configure()  # the plotters draw with pyvista: no X probe, no VTK warning
    return [inside(out_dir, p) for p in plotter(design, result, out_dir)]


def write_plots(design: Any, evaluation: Evaluation, out_dir: Path) -> list[Path]:
    """Every registered picture of the evaluators that produced a result; the files written."""
    check_name(design.name, "design name", error=InvalidDesign)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for entry in EVALUATORS[design.device]:
        if entry.name in evaluation.results:
            written.extend(run_plotter(entry, design, evaluation.results[entry.name], out_dir))
    return written

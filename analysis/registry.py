"""Which evaluators apply to which device, in report order.

Each evaluator module exposes ``evaluate(design, *, fidelity) -> Result`` where ``Result`` is
frozen and has ``metrics() -> dict`` (engineering units, unit in the name), ``status`` and
``message``. Optional ``plot(design, result, out_dir) -> list[Path]`` writes pictures (CLI
``--plots``). Modules are imported lazily so that a CLI call pays only for what it runs.
"""

from __future__ import annotations

import importlib
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status


@dataclass(frozen=True, kw_only=True)
class EvaluatorEntry:
    name: str  # short name used in reports and timings
    module: str  # dotted module path exposing evaluate() (and optionally plot())

    def load(self) -> Any:
        return importlib.import_module(self.module)


#: device -> evaluators in report order. Add a line here to plug an evaluator into
#: ``hapticopt evaluate`` and the optimiser.
EVALUATORS: dict[str, tuple[EvaluatorEntry, ...]] = {
    "prrr": (
        EvaluatorEntry(name="statics", module="hapticopt.analysis.prrr.statics"),
        EvaluatorEntry(name="structural_stiffness", module="hapticopt.analysis.prrr.structure"),
        EvaluatorEntry(name="workspace", module="hapticopt.analysis.prrr.workspace"),
        EvaluatorEntry(name="interference", module="hapticopt.analysis.prrr.interference"),
        EvaluatorEntry(name="stability", module="hapticopt.analysis.prrr.stability"),
    ),
    "master": (
        EvaluatorEntry(name="workspace", module="hapticopt.analysis.master.workspace"),
        EvaluatorEntry(name="balance", module="hapticopt.analysis.master.balance"),
        EvaluatorEntry(name="transparency", module="hapticopt.analysis.master.transparency"),
    ),
}


@dataclass(frozen=True, kw_only=True)
class Evaluation:
    """Results of every evaluator for one design."""

    results: dict[str, Any]
    timings_s: dict[str, float]
    statuses: dict[str, Status] = field(default_factory=dict)
    messages: dict[str, str] = field(default_factory=dict)

    def metrics(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for result in self.results.values():
            out.update(result.metrics())
        return out


def evaluate_all(design: Any, *, fidelity: Fidelity = Fidelity.STANDARD,
                 only: tuple[str, ...] | None = None) -> Evaluation:
    """Run every evaluator registered for the design's device (or those named in ``only``)."""
    results: dict[str, Any] = {}
    timings: dict[str, float] = {}
    statuses: dict[str, Status] = {}
    messages: dict[str, str] = {}
    for entry in EVALUATORS[design.device]:
        if only is not None and entry.name not in only:
            continue
        module = entry.load()
        t0 = time.perf_counter()
        result = module.evaluate(design, fidelity=fidelity)
        timings[entry.name] = time.perf_counter() - t0
        results[entry.name] = result
        statuses[entry.name] = Status(result.status)
        messages[entry.name] = result.message
    return Evaluation(results=results, timings_s=timings, statuses=statuses, messages=messages)


def write_plots(design: Any, evaluation: Evaluation, out_dir: Path) -> list[Path]:
    """Ask every evaluator that can draw for its pictures; returns the files written."""
    written: list[Path] = []
    for entry in EVALUATORS[design.device]:
        if entry.name not in evaluation.results:
            continue
        module = entry.load()
        if hasattr(module, "plot"):
            written.extend(module.plot(design, evaluation.results[entry.name], out_dir))
    return written

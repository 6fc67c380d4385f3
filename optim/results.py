"""What a pipeline run produces, as frozen records: the evaluation of a design at one fidelity,
each stage's outcome, each scene's verdict and the run as a whole. The report reads these."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.optim.driver import RunResult
from hapticopt.optim.problem import Problem


@dataclass(frozen=True, kw_only=True)
class DesignEvaluation:
    """All evaluators on one design at one fidelity."""

    fidelity: Fidelity
    metrics: dict[str, Any]
    modules: dict[str, str]  # metric -> evaluator module
    statuses: dict[str, str]
    messages: dict[str, str]
    timings_s: dict[str, float]
    results: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    provenance: str = ""  # '' computed in this run; else where the values came from (the evaluation cache)


@dataclass(frozen=True, kw_only=True)
class StageOutcome:
    name: str
    status: str  # "ok", "skipped", "failed", or a verdict summary
    message: str = ""
    wall_s: float = 0.0
    files: tuple[str, ...] = ()  # relative to the run dir


#: most samples a verification's time history keeps for the report (every k-th controller tick)
HISTORY_MAX_POINTS = 2000


@dataclass(frozen=True, kw_only=True)
class TimeHistory:
    """A closed-loop run's time histories for the report, in engineering units: every ``stride``-th
    controller tick of batch element 0 up to the tick where the run stopped.

    ``t`` (n,) [s]; ``position`` (n, 3) [mm]; ``hand_force``, ``actuator_force``,
    ``force_reference`` (n, 3) [N] (``None`` where the plant does not record them).
    """

    t: np.ndarray
    position: np.ndarray
    hand_force: np.ndarray | None = None
    actuator_force: np.ndarray | None = None
    force_reference: np.ndarray | None = None
    stride: int = 1
    period_s: float = 0.0
    stopped_at_s: float | None = None  # the run stopped early (instability detected) at this time

    @staticmethod
    def from_traces(traces: Any, *, max_points: int = HISTORY_MAX_POINTS) -> "TimeHistory | None":
        """From :class:`hapticopt.analysis.loop.traces.Traces` (``None`` when it holds no positions)."""
        if traces is None or getattr(traces, "position", None) is None:
            return None
        n_all = int(traces.position.shape[0])
        stop = int(np.asarray(traces.stop_tick).reshape(-1)[0]) if traces.stop_tick is not None else -1
        end = n_all if stop < 0 else max(1, stop)
        stride = max(1, -(-end // max_points))
        idx = np.arange(0, end, stride)

        def pick(a: Any, scale: float) -> np.ndarray | None:
            return None if a is None else np.asarray(a)[idx, 0, :3].astype(float) * scale

        return TimeHistory(t=idx * float(traces.period), position=pick(traces.position, 1e3),
                           hand_force=pick(traces.hand_force, 1.0), actuator_force=pick(traces.actuator_force, 1.0),
                           force_reference=pick(traces.force_reference, 1.0), stride=stride,
                           period_s=float(traces.period), stopped_at_s=None if stop < 0 else stop * float(traces.period))


@dataclass(frozen=True, kw_only=True)
class Verdict:
    scene: str
    passed: bool
    metrics: dict[str, Any]
    message: str = ""
    history: TimeHistory | None = field(default=None, repr=False, compare=False)


@dataclass(frozen=True, kw_only=True)
class PipelineResult:
    problem: Problem
    out_dir: Path
    run: RunResult
    baseline: DesignEvaluation  # base design at the final fidelity
    optimum_design: Any
    optimum: DesignEvaluation  # best design at the final fidelity
    constraints_final: tuple[tuple[str, float, bool], ...]  # (text, metric value, satisfied) at final fidelity
    feasible_final: bool
    improved: bool
    verdicts: tuple[Verdict, ...]
    stages: tuple[StageOutcome, ...]
    files: dict[str, str]  # role -> path relative to out_dir

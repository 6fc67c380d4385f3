"""What a pipeline run produces, as frozen records: the evaluation of a design at one fidelity,
each stage's outcome, each scene's verdict and the run as a whole. The report reads these."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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


@dataclass(frozen=True, kw_only=True)
class Verdict:
    scene: str
    passed: bool
    metrics: dict[str, Any]
    message: str = ""


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

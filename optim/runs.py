"""Reading recorded runs: :class:`RunReader` (read-only, like OpenMDAO's ``CaseReader``).

A run directory holds ``evaluations.sqlite`` (:mod:`hapticopt.optim.recorder`). The record
describes itself — ``run_info`` (kind, problem text, variables with units and bounds,
objectives and constraints, software versions, status), ``designs`` (baseline and
final-fidelity rows), ``evaluations`` and ``session_counts`` — so this module needs neither
the problem file nor the code that wrote it.

The reader opens the database with ``mode=ro``: it never writes, never checkpoints and never
deletes, so it may read a run while another process is writing it (SQLite WAL readers see the
last committed evaluation). A record made before the self-describing tables existed is read
too: its variables and objectives are then unknown (``None``) and no best point is picked.

A record is checked before it is read (:func:`hapticopt.optim.recorder.inspect_record`: no views or
triggers, rows matching their checksums), every query runs under a time limit
(:data:`~hapticopt.optim.sqlite_checks.READ_LIMIT_S`), and any fault reading it — SQLite, a JSON
field that does not parse, a value of the wrong type — is one :class:`InvalidInput` line naming the
file, never an internal error.
"""

from __future__ import annotations

import json
import math
import re
import platform
import sqlite3
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hapticopt.analysis.status import upgrade
from hapticopt.design import io
from hapticopt.design.errors import InvalidInput
from hapticopt.design.units import pretty
from hapticopt.optim.problem import Constraint, MetricRef, Op, Problem
from hapticopt.optim.recorder import FILENAME, inspect_record
from hapticopt.optim.sqlite_checks import connect_readonly, restart_clock
from hapticopt.optim.versions import package_versions

#: packages whose versions a record states
VERSIONED = ("hapticopt", "numpy", "scipy", "jax", "nlopt", "dask")


def software_versions() -> dict[str, str]:
    return {"python": platform.python_version(), **package_versions(VERSIONED)}


def problem_info(problem: Problem, *, kind: str = "optimise") -> dict[str, Any]:
    """The ``run_info`` entries describing ``problem`` (JSON-ready; edge units)."""
    return {
        "kind": kind,
        "problem": problem.name,
        "description": problem.description,
        "device": problem.device,
        "base_source": problem.base_source,
        "base_design": io.dumps(problem.base),
        "problem_text": problem.source_text,
        "variables": [{"key": v.key, "unit": v.unit, "lower": v.lower, "upper": v.upper, "start": v.start}
                      for v in problem.variables],
        "objectives": [{"metric": problem.objective.metric.text, "sense": str(problem.objective.sense)}],
        "constraints": [{"metric": c.metric.text, "op": c.op.value, "value": c.value} for c in problem.constraints],
        "constraint_tol": problem.optimiser.constraint_tol,
        "fidelity": {"optimise": str(problem.fidelity_optimise), "final": str(problem.fidelity_final)},
        "optimiser": problem.optimiser.fingerprint(),
        "versions": software_versions(),
    }


@dataclass(frozen=True, kw_only=True)
class Case:
    """One recorded evaluation."""

    id: int
    session: int
    start: int
    stage: str
    fidelity: str
    x: tuple[float, ...]  # edge units, in the order of :attr:`RunReader.variables`
    outcome: str
    message: str
    metrics: dict[str, Any] = field(compare=False, repr=False)
    statuses: dict[str, str] = field(compare=False, repr=False)
    timings_s: dict[str, float] = field(compare=False, repr=False)


@dataclass(frozen=True, kw_only=True)
class RecordedDesign:
    """A whole design evaluated outside the loop (``baseline``, ``final``, ``chosen``)."""

    session: int
    role: str
    fidelity: str
    x: tuple[float, ...]
    design_toml: str
    metrics: dict[str, Any] = field(compare=False, repr=False)
    statuses: dict[str, str] = field(compare=False, repr=False)


@dataclass(frozen=True, kw_only=True)
class RunSummary:
    """One line of ``hapticopt runs``."""

    path: Path
    kind: str
    problem: str
    status: str
    n_evaluations: int
    best: float  # the first objective at the best point (NaN if none or unknown)
    objective: str  # its metric reference ('' if unknown)
    feasible: bool | None  # None: the record does not say what feasible means
    repeated: int  # evaluations of a point already recorded (counted by the recorder)
    best_fidelity: str = ""  # the fidelity at which ``best`` holds (the optimisation's: draft, usually)
    final: float = math.nan  # the first objective of the recorded final design (the optimum re-evaluated)
    final_fidelity: str = ""  # its fidelity ('' when no final design is recorded)
    n_failed: int = 0  # evaluations whose outcome is not ok


class RunReader:
    """Read-only access to a run directory (or its ``evaluations.sqlite``)."""

    def __init__(self, run: str | Path) -> None:
        path = Path(run)
        if path.is_dir():
            path = path / FILENAME
        if not path.is_file():
            raise InvalidInput(f"RUN = {str(run)!r} is not a run: no {FILENAME} there")
        self.path = path
        self.run_dir = path.parent
        self._run = str(run)
        try:
            self._db = connect_readonly(path)
            self._tables = {r[0] for r in self._db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        except sqlite3.DatabaseError as exc:
            raise InvalidInput(f"RUN = {str(run)!r}: {path} is not a readable run record ({exc})") from None
        if "evaluations" not in self._tables:
            self._db.close()
            raise InvalidInput(f"RUN = {str(run)!r}: {path} has no evaluations table: not a hapticopt run record")
        try:
            inspect_record(path, what=f"RUN = {str(run)!r}", resume=False)
            self.info = {}
            if "run_info" in self._tables:
                self.info = {k: _json(v, f"run_info {k}") for k, v in self._rows("SELECT key, value FROM run_info")}
            self.meta = dict(self._rows("SELECT key, value FROM meta")) if "meta" in self._tables else {}
        except BaseException:
            self._db.close()
            raise

    # ----------------------------------------------------------------------- description
    @property
    def kind(self) -> str:
        return str(self.info.get("kind", "optimise"))

    @property
    def problem(self) -> str:
        return str(self.info.get("problem", "?"))

    @property
    def status(self) -> str:
        return str(self.info.get("status", "unknown"))

    @property
    def variables(self) -> list[dict[str, Any]] | None:
        return self.info.get("variables")

    @property
    def objectives(self) -> list[dict[str, Any]] | None:
        return self.info.get("objectives")

    @property
    def constraints(self) -> list[dict[str, Any]]:
        return list(self.info.get("constraints", []))

    # ----------------------------------------------------------------------- rows
    def _rows(self, sql: str, params: Sequence[Any] = ()) -> list[tuple[Any, ...]]:
        restart_clock(self._db)
        try:
            return self._db.execute(sql, params).fetchall()
        except sqlite3.Error as exc:
            why = "a query ran past its time limit" if "interrupted" in str(exc) else str(exc)
            raise InvalidInput(f"RUN = {self._run!r}: {self.path} is not a readable run record ({why})") from None

    def cases(self) -> list[Case]:
        """Every recorded evaluation, in the order they were recorded."""
        return [Case(id=i, session=s, start=st, stage=stg, fidelity=fid, x=_floats(x, f"evaluation {i} x"), outcome=o,
                     message=msg, metrics=_json(m, f"evaluation {i} metrics", dict),
                     statuses=upgrade(_json(sts, f"evaluation {i} statuses", dict)),
                     timings_s=_json(t, f"evaluation {i} timings", dict))
                for i, s, st, stg, fid, x, o, msg, m, sts, t in self._rows(
                    "SELECT id, session, start, stage, fidelity, x, outcome, message, metrics, statuses, timings "
                    "FROM evaluations ORDER BY id")]

    def __len__(self) -> int:
        return int(self._rows("SELECT COUNT(*) FROM evaluations")[0][0])

    def designs(self) -> list[RecordedDesign]:
        if "designs" not in self._tables:
            return []
        return [RecordedDesign(session=s, role=r, fidelity=f, x=_floats(x, f"design {r} x"), design_toml=d,
                               metrics=_json(m, f"design {r} metrics", dict),
                               statuses=upgrade(_json(st, f"design {r} statuses", dict)))
                for s, r, f, x, d, m, st in self._rows(
                    "SELECT session, role, fidelity, x, design, metrics, statuses FROM designs ORDER BY id")]

    def design(self, role: str) -> RecordedDesign | None:
        """The latest recorded design of ``role`` (``baseline``, ``final`` …), or None."""
        found = [d for d in self.designs() if d.role == role]
        return found[-1] if found else None

    def sessions(self) -> list[dict[str, Any]]:
        """Each session: when it started, whether it resumed, and its counts where recorded."""
        counts: dict[int, dict[str, Any]] = {}
        if "session_counts" in self._tables:
            cols = ["session", "max_evals", "evaluated", "replayed", "repeated", "status", "finished"]
            counts = {r[0]: dict(zip(cols, r)) for r in self._rows(f"SELECT {', '.join(cols)} FROM session_counts")}
        n_rows = dict(self._rows("SELECT session, COUNT(*) FROM evaluations GROUP BY session"))
        return [{"session": s, "started": t, "resumed": bool(r), "recorded": int(n_rows.get(s, 0)),
                 **{k: v for k, v in counts.get(s, {}).items() if k != "session"}}
                for s, t, r in self._rows("SELECT id, started, resumed FROM sessions ORDER BY id")]

    @property
    def n_repeated(self) -> int:
        return sum(int(s.get("repeated", 0) or 0) for s in self.sessions())

    # ----------------------------------------------------------------------- values
    def _refs(self) -> tuple[list[tuple[MetricRef, str]], list[Constraint]]:
        try:
            objs = [(MetricRef.parse(o["metric"], "objective"), str(o["sense"])) for o in (self.objectives or [])]
            cons = [Constraint(metric=MetricRef.parse(c["metric"], "constraint"), op=Op(c["op"]),
                               value=float(c["value"])) for c in self.constraints]
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InvalidInput(f"RUN = {self._run!r}: {self.path}: its objectives or constraints are not readable "
                               f"({type(exc).__name__}: {str(exc)[:60]})") from None
        return objs, cons

    def objective_values(self, case: Case | RecordedDesign) -> tuple[float, ...]:
        """Each objective's value at ``case`` (NaN where unavailable)."""
        return tuple(ref.value(case.metrics) for ref, _ in self._refs()[0])

    def violation(self, case: Case | RecordedDesign) -> float:
        """Largest normalised constraint violation (≤ 0 satisfied; inf when a value is missing)."""
        worst = 0.0
        for c in self._refs()[1]:
            v = c.metric.value(case.metrics)
            worst = max(worst, c.normalised(v) if math.isfinite(v) else math.inf)
        return worst

    def feasible(self, case: Case | RecordedDesign) -> bool:
        ok = getattr(case, "outcome", "ok") == "ok"
        return ok and self.violation(case) <= float(self.info.get("constraint_tol", 1e-4))

    def best(self) -> Case | None:
        """The best evaluation by the first objective: feasible first, then least violation.
        None when the record names no objective (a sweep, or a record older than ``run_info``)."""
        objs, _ = self._refs()
        if not objs:
            return None
        ref, sense = objs[0]
        sign = -1.0 if sense == "maximise" else 1.0
        best, best_key = None, None
        for case in self.cases():
            v = ref.value(case.metrics)
            if case.outcome != "ok" or not math.isfinite(v):
                continue
            feas = self.feasible(case)
            key = (0, sign * v) if feas else (1, self.violation(case))
            if best_key is None or key < best_key:
                best, best_key = case, key
        return best

    def summary(self) -> RunSummary:
        best = self.best()
        objs = self.objectives or []
        final = self.design("final") if objs else None
        return RunSummary(path=self.run_dir, kind=self.kind, problem=self.problem, status=self.status,
                          n_evaluations=len(self), objective=objs[0]["metric"] if objs else "",
                          best=self.objective_values(best)[0] if best is not None else math.nan,
                          feasible=None if best is None else self.feasible(best), repeated=self.n_repeated,
                          best_fidelity=best.fidelity if best is not None else "",
                          final=self.objective_values(final)[0] if final is not None else math.nan,
                          final_fidelity=final.fidelity if final is not None else "",
                          n_failed=int(self._rows("SELECT COUNT(*) FROM evaluations WHERE outcome != 'ok'")[0][0]))

    def failures(self) -> list[Case]:
        """Every recorded evaluation whose outcome is not ok, in order: its outcome, message (each
        evaluator's status and message) and statuses."""
        return [c for c in self.cases() if c.outcome != "ok"]

    def history_table(self) -> tuple[list[str], list[list[Any]]]:
        """Columns and rows of the history: id, session, start, stage, outcome, each variable (edge
        units), each objective and constraint metric, feasible."""
        var_cols = [f"{v['key']} [{pretty(v['unit'])}]" for v in (self.variables or [])]
        objs, cons = self._refs()
        metric_cols = [r.text for r, _ in objs] + [c.metric.text for c in cons if c.metric.text not in
                                                   {r.text for r, _ in objs}]
        refs = {r.text: r for r, _ in objs} | {c.metric.text: c.metric for c in cons}
        cols = ["id", "session", "start", "stage", "outcome"] + (var_cols or ["x"]) + metric_cols + ["feasible"]
        rows = []
        for c in self.cases():
            xs: list[Any] = list(c.x) if var_cols else [json.dumps(list(c.x))]
            rows.append([c.id, c.session, c.start, c.stage, c.outcome, *xs,
                         *(refs[m].value(c.metrics) for m in metric_cols), self.feasible(c) if objs else ""])
        return cols, rows

    # ----------------------------------------------------------------------- lifetime
    def close(self) -> None:
        self._db.close()

    def __enter__(self) -> "RunReader":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _json(text: Any, what: str, kind: type | None = None) -> Any:
    try:
        value = json.loads(text)
    except (TypeError, ValueError, RecursionError):
        raise InvalidInput(f"the run record's {what} is not valid JSON: {str(text)[:40]!r}") from None
    if kind is not None and not isinstance(value, kind):
        raise InvalidInput(f"the run record's {what} is a {type(value).__name__}, not a {kind.__name__}")
    return value


def _floats(text: Any, what: str) -> tuple[float, ...]:
    value = _json(text, what, list)
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise InvalidInput(f"the run record's {what} holds a value that is not a number")
    return tuple(float(v) for v in value)


def find_runs(root: str | Path, *, depth: int = 3) -> Iterator[Path]:
    """Run directories at or below ``root`` (those holding ``evaluations.sqlite``), sorted."""
    root = Path(root)
    found: list[Path] = []
    level = [root]
    for _ in range(depth + 1):
        nxt = []
        for d in level:
            if (d / FILENAME).is_file():
                found.append(d)
            try:
                nxt.extend(sorted(p for p in d.iterdir() if p.is_dir() and not p.is_symlink() and not p.name.startswith(".")))
            except OSError:
                continue
        level = nxt
    yield from sorted(found)


def as_dict(summary: RunSummary) -> Mapping[str, Any]:
    return {"path": str(summary.path), "kind": summary.kind, "problem": summary.problem, "status": summary.status,
            "evaluations": summary.n_evaluations, "objective": summary.objective,
            "best": None if math.isnan(summary.best) else summary.best, "best_fidelity": summary.best_fidelity,
            "final": None if math.isnan(summary.final) else summary.final, "final_fidelity": summary.final_fidelity,
            "feasible": summary.feasible, "repeated": summary.repeated, "failed": summary.n_failed}


_EVALUATOR_STATUS = re.compile(r"(?:^|; )(\w+): ([a-z][a-z-]*)(?= — |;|$)")
_NUMBER = re.compile(r"(?<![\w.])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def failure_reason(outcome: str, message: str) -> str:
    """What a failed evaluation's reasons have in common with others: its outcome and, per evaluator,
    ``name: status`` (an evaluator failure), else the message with its numbers as ``#``."""
    parts = [f"{name}: {status}" for name, status in _EVALUATOR_STATUS.findall(message)]
    if outcome == "evaluator_failed" and parts:
        return f"{outcome}: " + "; ".join(dict.fromkeys(parts))
    text = _NUMBER.sub("#", message.strip())
    return f"{outcome}: {text[:160]}" if text else outcome


def failure_counts(cases: Sequence[Case]) -> dict[str, int]:
    """Failed evaluations per :func:`failure_reason`, most frequent first."""
    counts: dict[str, int] = {}
    for c in cases:
        reason = failure_reason(c.outcome, c.message)
        counts[reason] = counts.get(reason, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: -kv[1]))

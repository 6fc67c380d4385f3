"""Optimisation problems: a TOML file naming a base design, variables, objective and constraints.

A problem is a frozen value. The TOML layout (every key and its range: ``docs/problems.md``;
examples: ``optim/problems/*.toml``)::

    name = "prrr-workspace"
    description = "..."
    device = "prrr"
    base = "prrr-paper"            # a bundled preset, or base_file = "my-design.toml"

    [[variables]]                  # one table per design variable, by TOML key (edge units)
    key = "geometry.beta_deg"
    lower = 20.0                   # optional: default is the field's allowed range
    upper = 70.0
    start = 45.0                   # optional: default is the base design's value

    [objective]
    metric = "workspace_footprint_ratio"   # name, name[i], name[i][j], min(name), max(name)
    sense = "maximise"                     # or "minimise"

    [[constraints]]
    metric = "stiffness_limit_N_per_mm[0]"
    min = 20.0                             # metric ≥ 20 (and/or max = … for metric ≤ …)

    [optimiser]
    algorithm = "LN_COBYLA"        # LN_COBYLA LN_BOBYQA LD_SLSQP LD_MMA GN_ISRES GN_DIRECT_L AUGLAG
    local = "LN_BOBYQA"            # AUGLAG's subsidiary / polish after a global algorithm
    starts = 4                     # multi-start count (start 0 is the base design)
    seed = 1
    xtol_rel = 1e-6
    ftol_rel = 1e-9
    max_evals = 400                # in total over all starts
    max_time_s = 120

    [fidelity]
    optimise = "draft"             # used inside the loop
    final = "fine"                 # the optimum is re-evaluated and checked at this level
    verify = "standard"            # closed-loop verification of the optimum

    [verify]
    scenes = ["free-space", "stiffness-25"]
    max_time_s = 60                # per scene: a slower simulation is stopped, its verdict fails

Every error is one line naming the field, the value and what is allowed
(:class:`design.errors.InputFileError`, :class:`~design.errors.InvalidInput`,
:class:`~design.errors.UnknownName`); the CLI turns them into exit code 2.
"""

from __future__ import annotations

import dataclasses
import hashlib
import difflib
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

from hapticopt.design import bundled
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import EVALUATORS
from hapticopt.analysis.loop.scene import load_scene
from hapticopt.design import io, tomlsafe
from hapticopt.design.errors import InputFileError, InvalidDesign, InvalidInput, UnknownName, short, short_key
from hapticopt.design.paths import NAME_MAX, check_name
from hapticopt.design.schema import specs
from hapticopt.design.units import from_si, pretty, to_si

OPTIMUM_SUFFIX = "-optimum"
PROBLEM_NAME_MAX = NAME_MAX - len(OPTIMUM_SUFFIX)
_TOP_KEYS = {"name", "description", "device", "base", "base_file", "variables", "objective", "objectives",
             "constraints", "optimiser", "fidelity", "verify", "pareto"}
#: the keys each table of a problem file accepts (docs/problems.md documents every one; a test compares)
TABLE_KEYS: dict[str, frozenset[str]] = {
    "": frozenset(_TOP_KEYS),
    "variables": frozenset({"key", "lower", "upper", "start"}),
    "objective": frozenset({"metric", "sense"}),
    "objectives": frozenset({"metric", "sense"}),
    "constraints": frozenset({"metric", "min", "max"}),
    "optimiser": frozenset({"algorithm", "local", "starts", "seed", "xtol_rel", "ftol_rel", "max_evals", "max_time_s",
                            "constraint_tol"}),
    "fidelity": frozenset({"optimise", "final", "verify"}),
    "verify": frozenset({"scenes", "max_time_s"}),
    "pareto": frozenset({"points", "choose", "weights"}),
}


class Sense(StrEnum):
    MINIMISE = "minimise"
    MAXIMISE = "maximise"


class Algorithm(StrEnum):
    """The NLopt algorithms hapticopt drives (families: local DF, gradient, global, AUGLAG)."""

    LN_COBYLA = "LN_COBYLA"
    LN_BOBYQA = "LN_BOBYQA"
    LD_SLSQP = "LD_SLSQP"
    LD_MMA = "LD_MMA"
    GN_ISRES = "GN_ISRES"
    GN_DIRECT_L = "GN_DIRECT_L"
    AUGLAG = "AUGLAG"

    @property
    def needs_gradient(self) -> bool:
        return self.value.startswith("LD_")

    @property
    def is_global(self) -> bool:
        return self.value.startswith("GN_")

    @property
    def handles_constraints(self) -> bool:
        return self in (Algorithm.LN_COBYLA, Algorithm.LD_SLSQP, Algorithm.LD_MMA, Algorithm.GN_ISRES,
                        Algorithm.AUGLAG)


#: local algorithms allowed as AUGLAG's subsidiary or as the polish after a global search
LOCAL_ALGORITHMS = (Algorithm.LN_COBYLA, Algorithm.LN_BOBYQA, Algorithm.LD_SLSQP, Algorithm.LD_MMA)


class Op(StrEnum):
    GE = ">="
    LE = "<="


_REF_RE = re.compile(r"^\s*(?:(min|max)\(\s*([A-Za-z_][A-Za-z0-9_]*)\s*\)|([A-Za-z_][A-Za-z0-9_]*)((?:\s*\[\s*\d+\s*(?:,\s*\d+\s*)*\])*))\s*$")


@dataclass(frozen=True, kw_only=True)
class MetricRef:
    """A scalar picked from an evaluator metric: ``name``, ``name[i]``, ``name[i][j]``, ``min(name)``."""

    text: str
    name: str
    index: tuple[int, ...] = ()
    reduce: str | None = None  # "min" or "max" over every component

    @staticmethod
    def parse(text: str, where: str) -> "MetricRef":
        if not isinstance(text, str):
            raise InvalidInput(f"{where} = {short(text)} must be a metric name string, e.g. \"max_force_N[0]\"")
        m = _REF_RE.match(text)
        if m is None:
            raise InvalidInput(f"{where} = {short(text)} is not a metric reference: allowed name, name[i], name[i][j], "
                               "min(name), max(name)")
        if m.group(1):
            return MetricRef(text=text.strip(), name=m.group(2), reduce=m.group(1))
        index = tuple(int(i) for i in re.findall(r"\d+", m.group(4) or ""))
        return MetricRef(text=text.strip(), name=m.group(3), index=index)

    def value(self, metrics: Mapping[str, Any]) -> float:
        """The scalar value in ``metrics`` (NaN if missing or not numeric: a handled outcome)."""
        raw = metrics.get(self.name)
        try:
            return float(_pick(raw, self.index, self.reduce))
        except (TypeError, ValueError, IndexError, KeyError):
            return math.nan

    def check(self, metrics: Mapping[str, Any], where: str) -> None:
        """Raise a one-line error unless this reference picks a number from ``metrics``."""
        if self.name not in metrics:
            known = ", ".join(sorted(metrics)) or "(none)"
            raise UnknownName(f"{where} = {short(self.text)}: metric {short(self.name)} is not computed for this device: "
                              f"known metrics are {known}")
        raw = metrics[self.name]
        try:
            float(_pick(raw, self.index, self.reduce))
        except (TypeError, ValueError, IndexError, KeyError):
            raise InvalidInput(f"{where} = {short(self.text)} does not pick one number from {self.name} = {short(raw)}: "
                               f"give a component index such as {self.name}[0] or min({self.name})") from None


def _pick(raw: Any, index: tuple[int, ...], reduce: str | None) -> float:
    if isinstance(raw, bool):
        raise TypeError
    if reduce is not None:
        flat = list(_flatten(raw))
        if not flat:
            raise ValueError
        return min(flat) if reduce == "min" else max(flat)
    value = raw
    for i in index:
        if not isinstance(value, (list, tuple)):
            raise TypeError
        value = value[i]
    if isinstance(value, (list, tuple, dict, str, bool)) or value is None:
        raise TypeError
    return float(value)


def _flatten(raw: Any):
    if isinstance(raw, (list, tuple)):
        for item in raw:
            yield from _flatten(item)
    elif isinstance(raw, (int, float)) and not isinstance(raw, bool):
        yield float(raw)
    else:
        raise TypeError


@dataclass(frozen=True, kw_only=True)
class Variable:
    """A design variable by TOML key ``section.key``; bounds and start in the key's (edge) unit."""

    key: str
    section: str
    field: str  # dataclass field name (SI inside the design)
    unit: str
    lower: float
    upper: float
    start: float

    @property
    def label(self) -> str:
        return f"{self.key} [{pretty(self.unit)}]"


@dataclass(frozen=True, kw_only=True)
class Objective:
    metric: MetricRef
    sense: Sense


class Choice(StrEnum):
    KNEE = "knee"  # the front point farthest from the line through the two anchors (normalised)
    WEIGHTS = "weights"  # the front point maximising Σ wᵢ · (normalised objective i, 1 = best)


@dataclass(frozen=True, kw_only=True)
class ParetoConfig:
    """How a two-objective problem's front is traced (ε-constraint series, :mod:`optim.pareto`)."""

    points: int = 11  # front points: 2 anchors + points − 2 ε levels
    choose: Choice = Choice.KNEE
    weights: tuple[float, ...] = ()


@dataclass(frozen=True, kw_only=True)
class Constraint:
    """``metric op value``; nlopt sees c(x) = ±(value − metric)/scale ≤ 0."""

    metric: MetricRef
    op: Op
    value: float

    @property
    def scale(self) -> float:
        return max(abs(self.value), 1e-12)

    def normalised(self, metric_value: float) -> float:
        """Violation in units of |value| (≤ 0 satisfied)."""
        if self.op is Op.GE:
            return (self.value - metric_value) / self.scale
        return (metric_value - self.value) / self.scale

    @property
    def text(self) -> str:
        return f"{self.metric.text} {self.op.value} {self.value:g}"


@dataclass(frozen=True, kw_only=True)
class OptimiserConfig:
    """How to search: a frozen value (see the module docstring for the TOML keys)."""

    algorithm: Algorithm = Algorithm.LN_COBYLA
    local: Algorithm = Algorithm.LN_BOBYQA
    starts: int = 1
    seed: int = 0
    xtol_rel: float = 1e-6
    ftol_rel: float = 1e-9
    max_evals: int = 200
    max_time_s: float = 600.0
    constraint_tol: float = 1e-4  # normalised violation accepted as feasible

    def fingerprint(self) -> dict[str, Any]:
        return {k: str(v) if isinstance(v, StrEnum) else v for k, v in dataclasses.asdict(self).items()}


@dataclass(frozen=True, kw_only=True)
class Problem:
    name: str
    description: str
    device: str
    base_source: str  # "preset NAME" or a file path
    base: Any  # the base design (frozen)
    variables: tuple[Variable, ...]
    objective: Objective
    constraints: tuple[Constraint, ...] = ()
    optimiser: OptimiserConfig = OptimiserConfig()
    fidelity_optimise: Fidelity = Fidelity.DRAFT
    fidelity_final: Fidelity = Fidelity.FINE
    fidelity_verify: Fidelity = Fidelity.STANDARD  # closed-loop verification of the optimum
    scenes: tuple[str, ...] = ()
    verify_max_time_s: float = 60.0  # per scene; a slower simulation is stopped and fails its verdict
    source_text: str = ""
    #: every objective (``objective`` is the first); two make a Pareto problem (:mod:`optim.pareto`)
    objectives: tuple[Objective, ...] = ()
    pareto: ParetoConfig | None = None

    @property
    def is_multi_objective(self) -> bool:
        return len(self.objectives) > 1

    @property
    def lower(self) -> list[float]:
        return [v.lower for v in self.variables]

    @property
    def upper(self) -> list[float]:
        return [v.upper for v in self.variables]

    @property
    def start(self) -> list[float]:
        return [v.start for v in self.variables]

    def metric_refs(self) -> tuple[MetricRef, ...]:
        return (self.objective.metric,) + tuple(c.metric for c in self.constraints)

    def all_metric_refs(self) -> tuple[MetricRef, ...]:
        """Every objective's and constraint's metric (the evaluators a point needs)."""
        objs = self.objectives or (self.objective,)
        return tuple(o.metric for o in objs) + tuple(c.metric for c in self.constraints)

    def with_optimiser(self, **changes: Any) -> "Problem":
        return dataclasses.replace(self, optimiser=dataclasses.replace(self.optimiser, **changes))

    def design_at(self, x: Sequence[float]) -> Any:
        """The base design with the variables set to ``x`` (edge units). Raises :class:`InvalidDesign`."""
        return design_at(self.base, self.variables, x)

    def fingerprint(self) -> str:
        """Hash of everything that decides the sequence of evaluated points (for ``--resume``)."""
        payload = repr((self.name, io.dumps(self.base), self.variables, self.objective, self.constraints,
                        self.optimiser.fingerprint(), str(self.fidelity_optimise))
                       + ((self.objectives, self.pareto) if self.is_multi_objective else ()))
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    def search_fingerprint(self) -> str:
        """:meth:`fingerprint` without the budget (max_evals, max_time_s): nlopt asks the same points
        in the same order whatever its budget, so ``--resume --max-evals N`` may extend a run."""
        opt = {k: v for k, v in self.optimiser.fingerprint().items() if k not in ("max_evals", "max_time_s")}
        payload = repr(("search", self.name, io.dumps(self.base), self.variables, self.objectives or self.objective,
                        self.constraints, opt, str(self.fidelity_optimise), self.pareto))
        return hashlib.sha256(payload.encode()).hexdigest()[:16]


def design_at(base: Any, variables: Sequence[Variable], x: Sequence[float]) -> Any:
    """``base`` with each variable's field set to x[i] (edge units), validated by the constructor."""
    by_section: dict[str, dict[str, float]] = {}
    for var, value in zip(variables, x, strict=True):
        by_section.setdefault(var.section, {})[var.field] = to_si(float(value), var.unit)
    changes = {}
    for section, values in by_section.items():
        changes[section] = dataclasses.replace(getattr(base, section), **values)
    return dataclasses.replace(base, **changes)  # the design's constructor validates every field


# ------------------------------------------------------------------------------------ loading
PROBLEMS = "hapticopt.optim.problems"


def problem_names() -> list[str]:
    """Names of the bundled problems."""
    return bundled.names(PROBLEMS)


def load_problem(name_or_path: str | Path) -> Problem:
    """A bundled problem by name, or a problem TOML file by path."""
    found = bundled.read(PROBLEMS, "problem", name_or_path)
    return problem_from_text(found.text, source=found.source, base_dir=found.base_dir)


def problem_from_text(text: str, *, source: str, base_dir: Path | None) -> Problem:
    data = tomlsafe.loads(text, source=source)
    return problem_from_dict(data, source=source, base_dir=base_dir, source_text=text)


def did_you_mean(word: Any, choices: Any) -> str:
    """``"; did you mean X?"`` for the closest of ``choices`` to ``word`` (difflib), '' when none is close."""
    if not isinstance(word, str):
        return ""
    close = difflib.get_close_matches(word, [str(c) for c in choices], n=1, cutoff=0.6)
    return f"; did you mean {close[0]}?" if close else ""


def _unknown_key(where: str, key: Any, allowed: Any) -> InvalidInput:
    allowed = sorted(allowed)
    return InvalidInput(f"{where}{short_key(key)} is not a known key: allowed {', '.join(allowed)}"
                        f"{did_you_mean(key, allowed)}")


def _table(data: Mapping[str, Any], key: str, source: str, allowed: set[str]) -> dict[str, Any]:
    table = data.get(key, {})
    if not isinstance(table, Mapping):
        raise InvalidInput(f"{source}: [{key}] must be a table")
    for k in table:
        if k not in allowed:
            raise _unknown_key(f"{source}: {key}.", k, allowed)
    return dict(table)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise InvalidInput(f"{where} = {short(value)} must be a finite number")
    return float(value)


def _enum(cls: type, value: Any, where: str) -> Any:
    try:
        return cls(value)
    except ValueError:
        allowed = ", ".join(m.value for m in cls)  # type: ignore[attr-defined]
        raise InvalidInput(f"{where} = {short(value)} is not allowed: allowed {allowed}"
                           f"{did_you_mean(value, [m.value for m in cls])}") from None  # type: ignore[attr-defined]


def problem_from_dict(data: Mapping[str, Any], *, source: str = "problem", base_dir: Path | None = None,
                      source_text: str = "") -> Problem:
    """Build and validate a :class:`Problem` completely, before any work: every key (with a did-you-mean),
    range, constraint bound, fidelity level and metric name (against the registry's metrics of the device,
    at both fidelities the problem evaluates them at); the baseline evaluation still checks that each
    reference picks one number (:func:`check_metrics`)."""
    if not isinstance(data, Mapping):
        raise InvalidInput(f"{source}: a problem must be a table of keys, got {short(data)}")
    for key in data:
        if key not in _TOP_KEYS:
            raise _unknown_key(f"{source}: ", key, _TOP_KEYS)
    # the optimum is named NAME-optimum, and both become file names
    name = data.get("name")
    if isinstance(name, str) and len(name) > PROBLEM_NAME_MAX:
        raise InvalidInput(f"{source}: name = {short(name)} is {len(name)} characters long: allowed at most "
                           f"{PROBLEM_NAME_MAX} (the optimum is named NAME{OPTIMUM_SUFFIX})")
    check_name(name, f"{source}: name")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise InvalidInput(f"{source}: description = {short(description)} must be a string")
    # base design
    if ("base" in data) == ("base_file" in data):
        raise InvalidInput(f"{source}: give exactly one of base = \"PRESET\" or base_file = \"design.toml\"")
    for key in ("base", "base_file"):
        if key in data and (not isinstance(data[key], str) or not data[key] or "\0" in data[key]):
            raise InvalidInput(f"{source}: {key} = {short(data[key])} must be a preset name or a file path string")
    if "base" in data:
        try:
            base = io.load_preset(data["base"])
        except UnknownName as exc:
            raise UnknownName(f"{source}: base = {short(data['base'])}: {exc}") from None
        base_source = f"preset {data['base']}"
    else:
        p = Path(data["base_file"])
        if not p.is_absolute() and base_dir is not None:
            p = base_dir / p
        base = io.load_design(p)
        base_source = str(p)
    device = data.get("device", base.device)
    if device != base.device:
        raise InvalidInput(f"{source}: device = {short(device)} but the base design is a {short(base.device)} design")
    variables = _variables(data.get("variables"), base, source)
    if ("objective" in data) == ("objectives" in data):
        raise InvalidInput(f"{source}: give exactly one of [objective] (one objective) or [[objectives]] (two, for a "
                           "Pareto front)")
    if "objective" in data:
        objective = _objective(data.get("objective"), source)
        objectives: tuple[Objective, ...] = (objective,)
        if "pareto" in data:
            raise InvalidInput(f"{source}: [pareto] needs two [[objectives]]")
        pareto = None
    else:
        raw = data["objectives"]
        if not isinstance(raw, list) or len(raw) != 2:
            n = len(raw) if isinstance(raw, list) else raw
            raise InvalidInput(f"{source}: [[objectives]] must list exactly 2 objectives (a Pareto front), got {n}")
        objectives = tuple(_objective(t, f"{source}: objectives[{i}]") for i, t in enumerate(raw))
        if objectives[0].metric.text == objectives[1].metric.text:
            raise InvalidInput(f"{source}: objectives[1].metric = {objectives[1].metric.text!r} repeats objectives[0]")
        objective = objectives[0]
        pareto = _pareto(_table(data, "pareto", source, set(TABLE_KEYS["pareto"])), source)
    constraints = _constraints(data.get("constraints", []), source)
    optimiser = _optimiser(_table(data, "optimiser", source, set(TABLE_KEYS["optimiser"])),
                           source, bool(constraints))
    fid = _table(data, "fidelity", source, set(TABLE_KEYS["fidelity"]))
    fidelity_optimise = _enum(Fidelity, fid.get("optimise", "draft"), f"{source}: fidelity.optimise")
    fidelity_final = _enum(Fidelity, fid.get("final", "fine"), f"{source}: fidelity.final")
    fidelity_verify = _enum(Fidelity, fid.get("verify", "standard"), f"{source}: fidelity.verify")
    refs = [(f"{source}: objective.metric" if len(objectives) == 1 else f"{source}: objectives[{i}].metric", o.metric)
            for i, o in enumerate(objectives)]
    refs += [(f"{source}: constraints ({clip(c.text)}).metric", c.metric) for c in constraints]
    check_metric_names(device, refs, (fidelity_optimise, fidelity_final))
    ver = _table(data, "verify", source, set(TABLE_KEYS["verify"]))
    verify_max_time_s = _number(ver.get("max_time_s", 60.0), f"{source}: verify.max_time_s")
    if not 0 < verify_max_time_s <= MAX_TIME_S:
        raise InvalidInput(f"{source}: verify.max_time_s = {verify_max_time_s:g} is out of range: allowed "
                           f"0 < max_time_s ≤ {MAX_TIME_S:g} (s)")
    scenes = ver.get("scenes", [])
    if not isinstance(scenes, list) or not all(isinstance(s, str) for s in scenes):
        raise InvalidInput(f"{source}: verify.scenes = {short(scenes)} must be a list of scene names")
    for i, scene_name in enumerate(scenes):  # a misspelt scene fails here, not after the optimisation
        try:
            sc = load_scene(scene_name)
        except (InvalidInput, InputFileError, UnknownName) as exc:
            raise InvalidInput(f"{source}: verify.scenes[{i}] = {short(scene_name)}: {exc}") from None
        scene_device = "master" if base.device == "master" else "prrr"
        if sc.device != scene_device:
            raise InvalidInput(f"{source}: verify.scenes[{i}] = {short(scene_name)} is a {sc.device} scene; the "
                               f"base design is a {base.device}: allowed scenes of the {scene_device} device")
    return Problem(name=name.strip(), description=str(description), device=device, base_source=base_source,
                   base=base, variables=variables, objective=objective, constraints=constraints,
                   optimiser=optimiser, fidelity_optimise=fidelity_optimise, fidelity_final=fidelity_final,
                   fidelity_verify=fidelity_verify, verify_max_time_s=verify_max_time_s,
                   scenes=tuple(scenes), source_text=source_text, objectives=objectives, pareto=pareto)


def _pareto(table: dict[str, Any], source: str) -> ParetoConfig:
    where = f"{source}: pareto"
    points = table.get("points", 11)
    if isinstance(points, bool) or not isinstance(points, int) or not 3 <= points <= 1000:
        raise InvalidInput(f"{where}.points = {points!r} must be a whole number of front points, 3 ≤ points ≤ 1000")
    choose = _enum(Choice, table.get("choose", "weights" if "weights" in table else "knee"), f"{where}.choose")
    weights: tuple[float, ...] = ()
    if choose is Choice.WEIGHTS:
        raw = table.get("weights")
        if not isinstance(raw, list) or len(raw) != 2:
            raise InvalidInput(f"{where}.weights = {raw!r} must be two numbers ≥ 0, one per objective")
        weights = tuple(_number(w, f"{where}.weights") for w in raw)
        if min(weights) < 0 or sum(weights) <= 0:
            raise InvalidInput(f"{where}.weights = {raw!r} must be ≥ 0 with a positive sum")
    elif "weights" in table:
        raise InvalidInput(f"{where}.weights is given but choose = \"knee\": use choose = \"weights\"")
    return ParetoConfig(points=points, choose=choose, weights=weights)


def numeric_key(base: Any, key: str, where: str, *, role: str) -> tuple[str, str, Any]:
    """(section, field name, spec) of the numeric design key ``section.key`` of ``base``; one line naming
    ``where`` and the allowed sections/keys otherwise (``role``: what the key is for, e.g. "a variable")."""
    section, tkey = key.split(".")
    if section not in base.SECTIONS:
        raise InvalidInput(f"{where}: {section} is not a section of a {base.device} design: "
                           f"allowed {', '.join(base.SECTIONS)}{did_you_mean(section, base.SECTIONS)}")
    by_key = {s.key: (fname, s) for fname, s in specs(getattr(base, section)).items()}
    if tkey not in by_key:
        raise InvalidInput(f"{where} is not {role} of the design: allowed keys in [{section}] are "
                           f"{', '.join(sorted(by_key))}{did_you_mean(tkey, by_key)}")
    fname, spec = by_key[tkey]
    return section, fname, spec


def _variables(raw: Any, base: Any, source: str) -> tuple[Variable, ...]:
    if not isinstance(raw, list) or not raw:
        raise InvalidInput(f"{source}: [[variables]] must list at least one design variable, e.g. key = \"geometry.beta_deg\"")
    out: list[Variable] = []
    seen: set[str] = set()
    for i, table in enumerate(raw):
        where = f"{source}: variables[{i}]"
        if not isinstance(table, Mapping):
            raise InvalidInput(f"{where} must be a table with key, lower, upper")
        for k in table:
            if k not in TABLE_KEYS["variables"]:
                raise _unknown_key(f"{where}.", k, TABLE_KEYS["variables"])
        key = table.get("key")
        if not isinstance(key, str) or key.count(".") != 1:
            raise InvalidInput(f"{where}.key = {short(key)} must name section.key, e.g. \"geometry.beta_deg\"")
        section, fname, spec = numeric_key(base, key, f"{where}.key = {short(key)}", role="a variable")
        if key in seen:
            raise InvalidInput(f"{where}.key = {short(key)} appears twice")
        seen.add(key)
        lower = _number(table["lower"], f"{where}.lower") if "lower" in table else spec.lo
        upper = _number(table["upper"], f"{where}.upper") if "upper" in table else spec.hi
        if not (math.isfinite(lower) and math.isfinite(upper)):
            raise InvalidInput(f"{where} ({key}): the field's range {spec.allowed()} is unbounded: give lower and upper")
        if lower >= upper:
            raise InvalidInput(f"{where} ({key}): lower = {lower:g} must be below upper = {upper:g} "
                               f"({pretty(spec.unit)})")
        for bound, bname in ((lower, "lower"), (upper, "upper")):
            if bound < spec.lo or bound > spec.hi:
                raise InvalidInput(f"{where}.{bname} = {bound:g} is outside the field's range: allowed {spec.allowed()}")
        # open field ends: keep the variable strictly inside
        span = upper - lower
        if spec.lo_open and lower <= spec.lo:
            lower = spec.lo + 1e-6 * span
        if spec.hi_open and upper >= spec.hi:
            upper = spec.hi - 1e-6 * span
        # 15 significant digits, as design.schema writes TOML: 60° stays 60, not 59.99999999999999
        base_value = float(f"{from_si(float(getattr(getattr(base, section), fname)), spec.unit):.15g}")
        start = _number(table["start"], f"{where}.start") if "start" in table else base_value
        if not lower <= start <= upper:
            what = "start" if "start" in table else "the base design's value"
            raise InvalidInput(f"{where} ({key}): infeasible start: {what} {start:g} is outside "
                               f"[{lower:g}, {upper:g}] ({pretty(spec.unit)})")
        out.append(Variable(key=key, section=section, field=fname, unit=spec.unit, lower=lower, upper=upper,
                            start=start))
    # the start design itself must be valid (cross-field rules)
    try:
        design_at(base, out, [v.start for v in out])
    except InvalidDesign as exc:
        raise InvalidInput(f"{source}: infeasible start: {exc}") from None
    return tuple(out)


def _objective(raw: Any, source: str) -> Objective:
    if not isinstance(raw, Mapping):
        raise InvalidInput(f"{source}: [objective] must be a table with metric and sense")
    for k in raw:
        if k not in TABLE_KEYS["objective"]:
            raise _unknown_key(f"{source}: objective.", k, TABLE_KEYS["objective"])
    if "metric" not in raw:
        raise InvalidInput(f"{source}: objective.metric is missing, e.g. metric = \"jacobian_condition\"")
    metric = MetricRef.parse(raw["metric"], f"{source}: objective.metric")
    sense = _enum(Sense, raw.get("sense", "minimise"), f"{source}: objective.sense")
    return Objective(metric=metric, sense=sense)


def _constraints(raw: Any, source: str) -> tuple[Constraint, ...]:
    if not isinstance(raw, list):
        raise InvalidInput(f"{source}: [[constraints]] must be an array of tables")
    out: list[Constraint] = []
    for i, table in enumerate(raw):
        where = f"{source}: constraints[{i}]"
        if not isinstance(table, Mapping):
            raise InvalidInput(f"{where} must be a table with metric and min and/or max")
        for k in table:
            if k not in TABLE_KEYS["constraints"]:
                raise _unknown_key(f"{where}.", k, TABLE_KEYS["constraints"])
        if "metric" not in table:
            raise InvalidInput(f"{where}.metric is missing")
        metric = MetricRef.parse(table["metric"], f"{where}.metric")
        if "min" not in table and "max" not in table:
            raise InvalidInput(f"{where} ({metric.text}) needs min = … (metric ≥ min) and/or max = … (metric ≤ max)")
        lo = _number(table["min"], f"{where}.min") if "min" in table else None
        hi = _number(table["max"], f"{where}.max") if "max" in table else None
        if lo is not None and hi is not None and lo > hi:
            raise InvalidInput(f"{where} ({metric.text}): min = {lo:g} must not exceed max = {hi:g}")
        if lo is not None:
            out.append(Constraint(metric=metric, op=Op.GE, value=lo))
        if hi is not None:
            out.append(Constraint(metric=metric, op=Op.LE, value=hi))
    return tuple(out)


#: longest allowed time limit [s] (one week)
MAX_TIME_S = 7 * 86400.0
#: allowed ranges of the optimiser's whole numbers (nlopt takes C ints; seed is an unsigned 32-bit value)
INT_RANGES: dict[str, tuple[int, int]] = {"starts": (1, 1000), "seed": (0, 2**32 - 1), "max_evals": (1, 10**6)}


def _optimiser(table: dict[str, Any], source: str, constrained: bool) -> OptimiserConfig:
    kw: dict[str, Any] = {}
    where = f"{source}: optimiser"
    if "algorithm" in table:
        kw["algorithm"] = _enum(Algorithm, table["algorithm"], f"{where}.algorithm")
    if "local" in table:
        kw["local"] = _enum(Algorithm, table["local"], f"{where}.local")
        if kw["local"] not in LOCAL_ALGORITHMS:
            raise InvalidInput(f"{where}.local = {short(table['local'])} must be a local algorithm: allowed "
                               f"{', '.join(a.value for a in LOCAL_ALGORITHMS)}")
    for key, (lo, hi) in INT_RANGES.items():
        if key in table:
            v = table[key]
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise InvalidInput(f"{where}.{key} = {short(v)} must be a whole number: allowed {lo} ≤ {key} ≤ {hi}")
            kw[key] = v
    for key in ("xtol_rel", "ftol_rel", "max_time_s", "constraint_tol"):
        if key in table:
            v = _number(table[key], f"{where}.{key}")
            if v < 0 or (key == "max_time_s" and not 0 < v <= MAX_TIME_S):
                raise InvalidInput(f"{where}.{key} = {short(v)} is out of range: allowed "
                                   + (f"0 < {key} ≤ {MAX_TIME_S:g} (s)" if key == "max_time_s" else f"{key} ≥ 0"))
            kw[key] = v
    cfg = OptimiserConfig(**kw)
    if constrained and not cfg.algorithm.handles_constraints:
        raise InvalidInput(f"{where}.algorithm = {short(cfg.algorithm.value)} cannot handle constraints: use LN_COBYLA, "
                           "LD_SLSQP, LD_MMA, GN_ISRES or AUGLAG")
    if cfg.starts > cfg.max_evals:
        raise InvalidInput(f"{where}.starts = {cfg.starts} exceeds max_evals = {cfg.max_evals}")
    return cfg


def clip(text: str, n: int = 60) -> str:
    """``text`` cut to ``n`` characters for a one-line message (a constraint's own text may be long)."""
    return text if len(text) <= n else text[:n - 3] + "..."


def check_metric_names(device: str, refs: Sequence[tuple[str, MetricRef]], levels: Sequence[Fidelity]) -> None:
    """One line (exit 2) for a metric reference the device's evaluators never report (with the closest
    name), or report only at other fidelity levels than ``levels`` (the optimisation's and the final one)."""
    docs = {m.name: m for e in EVALUATORS.get(device, ()) for m in e.metrics}
    for where, ref in refs:
        doc = docs.get(ref.name)
        if doc is None:
            raise UnknownName(f"{where} = {short(ref.text)}: {short(ref.name)} is not a metric of a {device} design"
                              f"{did_you_mean(ref.name, docs) or '; no metric name is close'} "
                              f"(`hapticopt metrics --device {device}` lists them)")
        missing = [str(f) for f in dict.fromkeys(levels) if f not in doc.fidelities]
        if missing:
            raise InvalidInput(f"{where} = {short(ref.text)} is reported only at {', '.join(map(str, doc.fidelities))} "
                               f"fidelity, but the problem evaluates it at {', '.join(missing)}: allowed "
                               "[fidelity] optimise and final at those levels")


def check_metrics(problem: Problem, metrics: Mapping[str, Any]) -> None:
    """Raise a one-line error for any objective/constraint metric the evaluators do not produce."""
    problem.objective.metric.check(metrics, "objective.metric")
    for i, o in enumerate(problem.objectives[1:], start=1):
        o.metric.check(metrics, f"objectives[{i}].metric")
    for i, c in enumerate(problem.constraints):
        c.metric.check(metrics, f"constraints ({clip(c.text)})")

"""Declarative parameter fields for frozen design sections.

A section is a frozen, keyword-only dataclass whose fields are declared with :func:`param`.
Each field stores its value in SI; its metadata carries the TOML key (with the unit suffix),
the unit, the allowed range (also the default optimisation bounds) and a docstring. Parsing
from TOML, validation with one-line messages, and writing back all derive from that metadata,
so a parameter is described in exactly one place.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from hapticopt.design.errors import InvalidDesign, short, short_key
from hapticopt.design.units import from_si, pretty, to_si


@dataclass(frozen=True, kw_only=True)
class ParamSpec:
    """Metadata of one numeric design parameter (range given in the edge unit)."""

    key: str  # TOML key, unit suffix included, e.g. "beta_deg"
    unit: str  # unit label of the key, e.g. "deg"
    lo: float  # lower bound in `unit`
    hi: float  # upper bound in `unit`
    lo_open: bool = False  # True: lo itself is not allowed
    hi_open: bool = False
    integer: bool = False
    doc: str = ""

    def allowed(self) -> str:
        lo_op = "<" if self.lo_open else "≤"
        hi_op = "<" if self.hi_open else "≤"
        lo = _fmt(self.lo)
        hi = _fmt(self.hi)
        return f"{lo} {lo_op} {self.key} {hi_op} {hi} ({pretty(self.unit)})"

    def check(self, where: str, value_edge: float) -> None:
        """Raise :class:`InvalidDesign` unless ``value_edge`` (in the edge unit) is allowed."""
        if not math.isfinite(value_edge):
            raise InvalidDesign(f"{where} = {short(value_edge)} is not a finite number: allowed {self.allowed()}")
        too_low = value_edge <= self.lo if self.lo_open else value_edge < self.lo
        too_high = value_edge >= self.hi if self.hi_open else value_edge > self.hi
        if too_low or too_high:
            raise InvalidDesign(f"{where} = {_fmt(value_edge)} is out of range: allowed {self.allowed()}")
        if self.integer and value_edge != int(value_edge):
            raise InvalidDesign(f"{where} = {_fmt(value_edge)} must be a whole number: allowed {self.allowed()}")


def _fmt(x: float) -> str:
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:g}"


def param(
    key: str,
    unit: str,
    *,
    default: float,
    lo: float,
    hi: float,
    lo_open: bool = False,
    hi_open: bool = False,
    integer: bool = False,
    doc: str = "",
) -> Any:
    """Declare a numeric field. ``default``, ``lo`` and ``hi`` are given in ``unit``."""
    spec = ParamSpec(key=key, unit=unit, lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open, integer=integer, doc=doc)
    return field(default=to_si(default, unit), metadata={"spec": spec})


@dataclass(frozen=True, kw_only=True)
class ChoiceSpec:
    """Metadata of one categorical design parameter (a name from a fixed list, e.g. a material).

    ``check(value, where)`` raises :class:`InvalidDesign` (one line naming ``where`` and the allowed
    names) unless ``value`` is allowed; ``fills(value)`` gives the numeric fields (field name -> SI
    value) the choice sets where the table does not give them (a material's density and moduli)."""

    key: str
    check: Callable[[Any, str], None]
    fills: Callable[[str], dict[str, float]] | None = None
    doc: str = ""


def choice(key: str, *, default: str, check: Callable[[Any, str], None],
           fills: Callable[[str], dict[str, float]] | None = None, doc: str = "") -> Any:
    """Declare a categorical field (a string from a fixed list; not a continuous optimisation variable)."""
    return field(default=default, metadata={"choice": ChoiceSpec(key=key, check=check, fills=fills, doc=doc)})


def choices(section_cls: type) -> dict[str, ChoiceSpec]:
    """Field name -> :class:`ChoiceSpec` for a section class (or instance)."""
    return {f.name: f.metadata["choice"] for f in dataclasses.fields(section_cls) if "choice" in f.metadata}


def specs(section_cls: type) -> dict[str, ParamSpec]:
    """Field name -> :class:`ParamSpec` for a section class (or instance)."""
    return {f.name: f.metadata["spec"] for f in dataclasses.fields(section_cls) if "spec" in f.metadata}


def validate_section(section: Any, prefix: str) -> None:
    """Check every field of a constructed section against its range."""
    for name, spec in specs(section).items():
        value = getattr(section, name)
        spec.check(f"{prefix}.{spec.key}", from_si(float(value), spec.unit))
    for name, cspec in choices(section).items():
        cspec.check(getattr(section, name), f"{prefix}.{cspec.key}")


def _as_number(where: str, raw: Any, spec: ParamSpec) -> float:
    if isinstance(raw, bool) or not isinstance(raw, (int, float)):
        raise InvalidDesign(f"{where} = {short(raw)} is not a number: allowed {spec.allowed()}")
    return float(raw)


def section_from_table(section_cls: type, table: Any, prefix: str) -> Any:
    """Build a section from its TOML table (values in edge units), validating every key."""
    if not isinstance(table, Mapping):
        raise InvalidDesign(f"{prefix} = {short(table)} must be a table of parameters")
    by_key = {spec.key: (name, spec) for name, spec in specs(section_cls).items()}
    by_choice = {c.key: (name, c) for name, c in choices(section_cls).items()}
    values: dict[str, Any] = {}
    for key, raw in table.items():
        where = f"{prefix}.{key}"
        if key in by_choice:
            name, cspec = by_choice[key]
            cspec.check(raw, where)
            values[name] = raw
            continue
        if key not in by_key:
            known = ", ".join(sorted(set(by_key) | set(by_choice)))
            raise InvalidDesign(f"{prefix}.{short_key(key)} is not a known parameter: allowed keys in [{prefix}] are {known}")
        name, spec = by_key[key]
        value = _as_number(where, raw, spec)
        spec.check(where, value)
        values[name] = to_si(value, spec.unit)
    for key, (name, cspec) in by_choice.items():  # a named choice fills the fields the table leaves out
        if key in table and cspec.fills is not None:
            for fname, v in cspec.fills(table[key]).items():
                values.setdefault(fname, v)
    return section_cls(**values)


def section_to_table(section: Any) -> dict[str, Any]:
    """The TOML table of a section, in edge units (inverse of :func:`section_from_table`)."""
    out: dict[str, Any] = {}
    for name, spec in specs(section).items():
        value = from_si(float(getattr(section, name)), spec.unit)
        # 15 significant digits: deg/rad round trips must not print 59.99999999999999
        out[spec.key] = int(round(value)) if spec.integer else float(f"{value:.15g}")
    for name, cspec in choices(section).items():
        out[cspec.key] = getattr(section, name)
    return out

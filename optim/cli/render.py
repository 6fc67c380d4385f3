"""How the CLI shows values to a person: numbers with units and sensible digits, short vectors in
full and long arrays summarised, no Python reprs, tables that wrap instead of cutting.

The unit comes from the metric name's suffix (:func:`hapticopt.analysis.registry.metric_unit`).
Machine-readable output is ``--json`` (every command has it), never this module.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from rich.console import Console
from rich.table import Table

from hapticopt.analysis.registry import metric_unit

#: significant digits of a number shown to a person
DIGITS = 4
#: a flat vector up to this length is shown in full; a matrix up to this many entries too
SHORT = 9
#: shown for a value that is not a number (NaN, a missing value)
MISSING = "—"


def number(x: float | int, digits: int = DIGITS) -> str:
    """``digits`` significant digits, no trailing zeros; integers in full; NaN as '—', ±inf as '±inf'."""
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if math.isnan(x):
        return MISSING
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0.0:
        return "0"
    text = f"{x:.{digits}g}"
    if "e" in text:  # 2.207e+06 -> 2.207e6, 1e-05 -> 1e-5
        mant, exp = text.split("e")
        text = f"{mant}e{int(exp)}"
    return text


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _flat(value: Any) -> list[Any]:
    if isinstance(value, (list, tuple)):
        return [x for v in value for x in _flat(v)]
    return [value]


def _with_unit(text: str, unit: str) -> str:
    if not unit or text == MISSING:
        return text
    return f"{text}{unit}" if unit == "%" else f"{text} {unit}"


def value(v: Any, unit: str = "") -> str:
    """One value for a person: ``1378 N``, ``[28.14, 28.14, 168.8] N/mm``, ``yes``, ``—``,
    ``50 values: min 2.606, max 353.7 N/mm (3 undefined)``, ``a, b, c`` for a list of words."""
    if v is None:
        return MISSING
    if isinstance(v, bool):
        return "yes" if v else "no"
    if _is_number(v):
        return _with_unit(number(v), unit)
    if isinstance(v, str):
        return v if v else MISSING
    if isinstance(v, Mapping):
        return ", ".join(f"{k} {value(x, unit)}" for k, x in v.items()) or MISSING
    if isinstance(v, (list, tuple)):
        flat = _flat(v)
        if not flat:
            return "none"
        if all(isinstance(x, str) for x in flat):
            return ", ".join(flat)
        if len(flat) <= SHORT:
            return _with_unit(_nested(v), unit)
        nums = [float(x) for x in flat if _is_number(x) and math.isfinite(float(x))]
        undefined = len(flat) - len(nums)
        if not nums:
            return f"{len(flat)} values, none defined"
        text = f"{len(flat)} values: min {number(min(nums))}, max {_with_unit(number(max(nums)), unit)}"
        return text + (f" ({undefined} undefined)" if undefined else "")
    return str(v)


def _nested(v: Any) -> str:
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_nested(x) for x in v) + "]"
    return value(v)


def metric(name: str, v: Any) -> str:
    """A metric's value with the unit its name carries."""
    return value(v, metric_unit(name))


def table(title: str | None, columns: Sequence[str], rows: Iterable[Sequence[str]], *,
          numbers: bool = False) -> Table:
    """A table whose cells wrap (long names fold onto the next line) instead of being cut.

    ``numbers``: every cell is a number, kept whole on one line (the column is at least as wide
    as its widest cell, right-aligned); only the headers fold.
    """
    rows = [list(r) for r in rows]
    t = Table(title=title, title_justify="left")
    for j, c in enumerate(columns):
        widest = max((len(r[j]) for r in rows), default=0) if numbers else None
        t.add_column(c, overflow="fold", justify="right" if numbers else "left", min_width=widest)
    for r in rows:
        t.add_row(*r)
    return t


#: narrowest a folded header column is allowed to get [characters]
HEADER_MIN = 8


def number_tables(title: str | None, columns: Sequence[str], rows: Iterable[Sequence[str]], *,
                  width: int) -> list[Table]:
    """A table of numbers too wide for ``width`` columns, split into blocks of columns that fit,
    each repeating the first (key) column — the numbers are never cut or folded."""
    rows = [list(r) for r in rows]
    need = [max(HEADER_MIN, *(len(r[j]) for r in rows)) + 3 for j in range(len(columns))]  # + borders, padding
    groups: list[list[int]] = []
    used = 1 + need[0]
    for j in range(1, len(columns)):
        if not groups or used + need[j] > width:
            groups.append([])
            used = 1 + need[0]
        groups[-1].append(j)
        used += need[j]
    if not groups:
        groups = [[]]
    out = []
    for k, group in enumerate(groups):
        cols = [0, *group]
        part = f" ({k + 1}/{len(groups)})" if len(groups) > 1 else ""
        out.append(table(f"{title}{part}" if title else None, [columns[j] for j in cols],
                         ([r[j] for j in cols] for r in rows), numbers=True))
    return out


def metrics_table(title: str | None, metrics: Mapping[str, Any], *, skip: Iterable[str] = ()) -> Table:
    """Metric | value (with its unit), one row per metric."""
    skipped = set(skip)
    return table(title, ("metric", "value"), ((k, metric(k, v)) for k, v in metrics.items() if k not in skipped))


def console(*, stderr: bool = False, quiet: bool = False) -> Console:
    """A console for people: colour and live displays only on a terminal; 80 columns when piped."""
    return Console(stderr=stderr, quiet=quiet)

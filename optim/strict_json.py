"""JSON as RFC 8259 defines it, for every ``--json`` output and every JSON file a run writes.

RFC 8259 has no NaN or Infinity: Python's ``json.dumps`` writes them as bare ``NaN``/``Infinity``
tokens that ``JSON.parse`` and other strict parsers refuse. Here a non-finite number is written as
``null``; the payload says which numbers those were and why they are null:

* a dict payload (``evaluate``, ``show``, ``compare`` …) gains ``"null_numbers"``: JSON path
  (``/metrics/jacobian_condition``) → the number it stands for (``"NaN"``, ``"Infinity"``,
  ``"-Infinity"``), only when there is one; the status beside the value says why (an evaluator's
  ``failed`` or ``not-assemblable`` status and its message, a constraint that does not hold …);
* a list payload (``runs``, ``presets`` …): each dict row gains its own ``"null_numbers"``.

A number that is finite is written unchanged (``repr`` of the float, so it reads back bit-equal).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

#: the key naming the non-finite numbers written as null
NULL_NUMBERS = "null_numbers"


def _name(x: float) -> str:
    return "NaN" if math.isnan(x) else ("Infinity" if x > 0 else "-Infinity")


def finite(obj: Any, path: str = "", found: dict[str, str] | None = None) -> Any:
    """``obj`` as plain JSON types with every non-finite number as None; ``found`` (when given) gets
    path → ``"NaN"``/``"Infinity"``/``"-Infinity"`` of each one."""
    if isinstance(obj, (bool, str)) or obj is None:
        return obj
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        if math.isfinite(x):
            return x
        if found is not None:
            found[path or "/"] = _name(x)
        return None
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    if isinstance(obj, (list, tuple)):
        return [finite(v, f"{path}/{i}", found) for i, v in enumerate(obj)]
    if isinstance(obj, Mapping):
        return {str(k): finite(v, f"{path}/{k}", found) for k, v in obj.items()}
    return str(obj)


def _annotated(obj: Any) -> Any:
    found: dict[str, str] = {}
    out = finite(obj, "", found)
    if found and isinstance(out, dict):
        out[NULL_NUMBERS] = found
    return out


def strict(payload: Any) -> Any:
    """The payload in JSON types, non-finite numbers as null and named under ``null_numbers``
    (at the top of a dict, in each dict row of a list)."""
    if isinstance(payload, (list, tuple)):
        return [_annotated(row) if isinstance(row, Mapping) else finite(row) for row in payload]
    return _annotated(payload)


def dumps(payload: Any, *, indent: int | None = 2, ensure_ascii: bool = True) -> str:
    """:func:`strict` of the payload as RFC 8259 text (``allow_nan=False``: a bare NaN can never leave)."""
    return json.dumps(strict(payload), indent=indent, ensure_ascii=ensure_ascii, allow_nan=False)


def loads(text: str) -> Any:
    """Parse JSON strictly: a ``NaN``/``Infinity`` token raises ``ValueError`` (what ``JSON.parse`` does)."""

    def refuse(token: str) -> Any:
        raise ValueError(f"{token} is not JSON (RFC 8259)")

    return json.loads(text, parse_constant=refuse)

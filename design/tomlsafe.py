"""The one TOML parser for user input, bounded before anything is converted.

:func:`loads` turns every way a text can fail into :class:`~hapticopt.design.errors.InputFileError`
with one line: invalid TOML (``tomllib.TOMLDecodeError``), an integer literal too long to convert
(``ValueError`` past Python's digit limit), nesting deep enough to exhaust the recursion limit
(``RecursionError``), a text larger than :data:`MAX_BYTES`. After parsing, every integer must fit
in 64 bits (the TOML specification's range; a 400-digit integer is refused here, before any
``float()`` can overflow) and no array or table may nest deeper than :data:`MAX_DEPTH`.
"""

from __future__ import annotations

import os
import re
import tomllib
from typing import Any

from hapticopt.design.errors import InputFileError

#: largest accepted input text [bytes] (our largest bundled file is ~3 kB)
MAX_BYTES = 1_000_000
#: deepest accepted nesting of arrays/tables (our files use 3)
MAX_DEPTH = 16
#: TOML integers are 64-bit signed (toml.io, "Integer")
INT_MIN, INT_MAX = -(2**63), 2**63 - 1


def read_text(path: str | os.PathLike[str], *, source: str) -> str:
    """The UTF-8 text of input file ``path``, its size checked (``fstat``) before anything is read and
    at most :data:`MAX_BYTES` + 1 bytes read (a file that grows meanwhile is still bounded); raises
    :class:`InputFileError` with one line."""
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            if size > MAX_BYTES:
                raise InputFileError(f"{source} is {size} bytes long: allowed at most {MAX_BYTES} bytes")
            data = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise InputFileError(f"{source} cannot be read: {exc.strerror or exc}") from None
    if len(data) > MAX_BYTES:
        raise InputFileError(f"{source} is more than {MAX_BYTES} bytes long: allowed at most {MAX_BYTES} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputFileError(f"{source} is not UTF-8 text: {exc.reason} at byte {exc.start}") from None


def loads(text: str, *, source: str) -> dict[str, Any]:
    """Parse ``text`` (from ``source``, named in messages); raise :class:`InputFileError`."""
    if len(text) > MAX_BYTES:
        raise InputFileError(f"{source} is {len(text)} characters long: allowed at most {MAX_BYTES}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputFileError(f"{source} is not valid TOML: {exc}") from None
    except RecursionError:
        raise InputFileError(f"{source} nests arrays or tables too deeply: allowed depth {MAX_DEPTH}") from None
    except ValueError as exc:  # e.g. "Exceeds the limit (4300 digits) for integer string conversion"
        key = _key_of_long_number(text)
        if key is not None:
            raise InputFileError(f"{source}: {key} = an integer of more than 4300 digits is outside the 64-bit range "
                                 f"TOML allows: allowed {INT_MIN} ≤ value ≤ {INT_MAX}") from None
        raise InputFileError(f"{source} has a value TOML cannot hold: {str(exc)[:120]}") from None
    _check(data, source, "", 0)
    return data


_LONG_NUMBER = re.compile(r"\d[\d_]{4299,}")


def _key_of_long_number(text: str) -> str | None:
    """``section.key`` of the first line holding a number too long for Python to convert (tomllib names
    neither line nor key), or None."""
    section = ""
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("[") and "=" not in s.split("]")[0]:
            section = s.strip("[]").strip()
            continue
        if "=" in s and _LONG_NUMBER.search(s.split("=", 1)[1]):
            key = s.split("=", 1)[0].strip()
            key = key if len(key) <= 40 else key[:37] + "..."
            return f"{section}.{key}" if section else key
    return None


def _check(value: Any, source: str, where: str, depth: int) -> None:
    if depth > MAX_DEPTH:
        raise InputFileError(f"{source}: {where or 'a value'} nests arrays or tables too deeply: "
                             f"allowed depth {MAX_DEPTH}")
    if isinstance(value, bool):
        return
    if isinstance(value, int):
        if not INT_MIN <= value <= INT_MAX:
            digits = int(value.bit_length() * 0.30103) + 1
            raise InputFileError(f"{source}: {where} = an integer of about {digits} digits is outside the 64-bit range "
                                 f"TOML allows: allowed {INT_MIN} ≤ value ≤ {INT_MAX}")
    elif isinstance(value, dict):
        for k, v in value.items():
            key = k if len(k) <= 40 else k[:37] + "..."
            _check(v, source, f"{where}.{key}" if where else key, depth + 1)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _check(v, source, f"{where}[{i}]", depth + 1)

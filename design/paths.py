"""Names that become file names, and output paths that must stay inside the output folder.

A design or problem ``name`` ends up in file names (``<name>.step``, ``<name>_workspace.png``,
``cad_out/<name>/``). It is checked where it enters (:func:`check_name`, called by the design
and problem loaders and ``--set name=…``): no path separator, no ``..``, no NUL or other control
character, at most :data:`NAME_MAX` characters. Independently, every writer asks
:func:`inside` for its target, which resolves it (symlinks included) and refuses a path that is
not inside the output folder: a name that slipped past the first check still cannot write
anywhere else.
"""

from __future__ import annotations

import os
import tempfile
import unicodedata
from pathlib import Path

from hapticopt.design.errors import InvalidInput, short

#: longest allowed name, in characters (file names stay far below the usual 255-byte limit)
NAME_MAX = 64


def name_problem(value: object) -> str | None:
    """Why ``value`` is not a safe name (None when it is one)."""
    if not isinstance(value, str):
        return "must be a string"
    if not value.strip():
        return "must be a non-empty string"
    if "/" in value or "\\" in value:
        return "must not contain a path separator (/ or \\)"
    if ".." in value:
        return "must not contain '..'"
    if value in (".",) or value.startswith("."):
        return "must not start with '.'"
    for ch in value:
        if unicodedata.category(ch) in ("Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp"):
            return f"must not contain the control character U+{ord(ch):04X}"
    if len(value) > NAME_MAX:
        return f"is {len(value)} characters long"
    return None


def check_name(value: object, where: str, *, error: type[Exception] = InvalidInput) -> str:
    """``value`` if it is a safe name, else raise ``error`` naming ``where`` and what is allowed."""
    why = name_problem(value)
    if why is not None:
        raise error(f"{where} = {short(value)} {why}: allowed 1–{NAME_MAX} characters without /, \\, '..', "
                    "a leading '.' or control characters")
    return value  # type: ignore[return-value]


def inside(root: str | os.PathLike[str], target: str | os.PathLike[str]) -> Path:
    """``target`` (absolute, or relative to ``root``) if it resolves inside ``root``; else raise.

    Symlinks are resolved on both sides, so a link inside ``root`` that points out is refused.
    """
    root_r = Path(root).resolve()
    t = Path(target)
    if not t.is_absolute():
        t = Path(root) / t
    t_r = t.resolve()
    if t_r != root_r and root_r not in t_r.parents:
        raise InvalidInput(f"output path {short(str(t))} resolves to {short(str(t_r))}, outside the output folder "
                           f"{short(str(root_r))}: refused")
    return t


def writable_dir(path: str | os.PathLike[str], what: str = "--out") -> Path:
    """Prove that ``path`` can take a file (create and remove one there); else raise one line.

    Called before expensive work, so a read-only disk or an ``--out`` that is a file fails in
    the first second with the OS reason, not after the baseline. Folders it had to create for
    the probe are removed again: a run that then fails on its input leaves nothing behind.
    """
    p = Path(path)
    missing = [a for a in [p, *p.parents] if not a.exists()]
    try:
        p.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-probe.", dir=p)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise InvalidInput(f"{what} = {short(str(p))} is not a writable folder: {reason}") from None
    finally:
        for folder in missing:  # deepest first
            try:
                folder.rmdir()
            except OSError:
                pass
    return p

"""Names that become file names, and output paths that must stay inside the output folder.

A design or problem ``name`` ends up in file names (``<name>.step``, ``<name>_workspace.png``,
``cad_out/<name>/``). It is checked where it enters (:func:`check_name`, called by the design
and problem loaders and ``--set name=…``): no path separator, no ``..``, no NUL or other control
character, at most :data:`NAME_MAX` characters. Independently, every writer asks
:func:`inside` for its target, which resolves it (symlinks included) and refuses a path that is
not inside the output folder: a name that slipped past the first check still cannot write
anywhere else.

No write follows a link planted inside the output folder (issue 37): :func:`make_dirs` creates
folders one component at a time and ``lstat``-checks each, :func:`no_links` checks every component
of a target below the output root, :func:`open_nofollow` opens with ``O_NOFOLLOW``. The root is
the ``root`` argument, else the one a command set with :func:`output_root`; without either, only
the target itself is checked. The root itself may be a link (the user's choice of ``--out``).
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import os
import stat
import tempfile
import unicodedata
from collections.abc import Iterator
from pathlib import Path

from hapticopt.design.errors import InputFileError, InvalidInput, short

#: longest allowed name, in characters (file names stay far below the usual 255-byte limit)
NAME_MAX = 64
#: longest allowed name in UTF-8 bytes (a file name holds 255 bytes; ``<name>_workspace.png`` adds 14)
NAME_MAX_BYTES = 200

#: the output folder of the running command (:func:`output_root`); None outside one
_ROOT: contextvars.ContextVar[Path | None] = contextvars.ContextVar("hapticopt_output_root", default=None)


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
    if len(value.encode("utf-8", "surrogatepass")) > NAME_MAX_BYTES:
        return f"is {len(value.encode('utf-8', 'surrogatepass'))} bytes long in UTF-8 (at most {NAME_MAX_BYTES})"
    return None


def check_name(value: object, where: str, *, error: type[Exception] = InvalidInput) -> str:
    """``value`` if it is a safe name, else raise ``error`` naming ``where`` and what is allowed."""
    why = name_problem(value)
    if why is not None:
        raise error(f"{where} = {short(value)} {why}: allowed 1–{NAME_MAX} characters ({NAME_MAX_BYTES} bytes in "
                    "UTF-8) without /, \\, '..', a leading '.' or control characters")
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


# ------------------------------------------------------------------------- no write follows a link
@contextlib.contextmanager
def output_root(root: str | os.PathLike[str]) -> Iterator[Path]:
    """While the body runs, :func:`no_links` and :func:`make_dirs` check every component below ``root``."""
    token = _ROOT.set(Path(os.path.abspath(root)))
    try:
        yield Path(root)
    finally:
        _ROOT.reset(token)


def _below(target: Path, root: str | os.PathLike[str] | None) -> list[Path] | None:
    """Each component of ``target`` below the output root ([] for the root itself), or None when
    ``target`` is under no root (then only the target itself is checked: the folders above are the
    user's choice, as ``--out`` itself is)."""
    t = Path(os.path.abspath(target))
    r = Path(os.path.abspath(root)) if root is not None else _ROOT.get()
    if r is not None and (t == r or r in t.parents):
        parts = t.relative_to(r).parts
        return [r.joinpath(*parts[: i + 1]) for i in range(len(parts))]
    return None


def _refuse(path: Path) -> InputFileError:
    try:
        to = f" (to {short(os.readlink(path))})"
    except OSError:
        to = ""
    name = str(path) if len(str(path)) <= 300 else short(str(path))  # the whole path: the user must find it
    return InputFileError(f"{name} is a symbolic link{to} inside the output folder: refused, nothing "
                          "written there (remove the link or choose another --out)")


def no_links(target: str | os.PathLike[str], root: str | os.PathLike[str] | None = None) -> Path:
    """``target`` if no component of it below the output root is a symbolic link (missing ones are
    fine: they will be created); else raise :class:`InputFileError` naming the link."""
    checked = _below(Path(target), root)
    for p in [Path(os.path.abspath(target))] if checked is None else checked:
        try:
            st = os.lstat(p)
        except FileNotFoundError:
            break
        except OSError:
            continue
        if stat.S_ISLNK(st.st_mode):
            raise _refuse(p)
    return Path(target)


def make_dirs(path: str | os.PathLike[str], root: str | os.PathLike[str] | None = None) -> Path:
    """Create folder ``path`` one component at a time (the root and above as ``mkdir -p``), each
    ``lstat``-checked: a symbolic link (or a file) among the components below the root is refused."""
    checked = _below(Path(path), root)
    if not checked:  # the root itself, or a folder under no root (the user's choice, e.g. --plots DIR)
        Path(path).mkdir(parents=True, exist_ok=True)
        return Path(path)
    first = checked[0]
    if not os.path.lexists(first.parent):
        first.parent.mkdir(parents=True, exist_ok=True)
    for p in checked:
        try:
            os.mkdir(p)
        except FileExistsError:
            pass
        st = os.lstat(p)
        if stat.S_ISLNK(st.st_mode):
            raise _refuse(p)
        if not stat.S_ISDIR(st.st_mode):
            raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(p))
    return Path(path)


def open_nofollow(path: str | os.PathLike[str], flags: int, mode: int = 0o644,
                  root: str | os.PathLike[str] | None = None) -> int:
    """``os.open(path, flags | O_NOFOLLOW)`` after :func:`no_links` on its folders: a link at ``path``
    or above it (below the root) is refused with one line; a hard link to a file elsewhere too."""
    no_links(path, root)
    try:
        fd = os.open(path, flags | os.O_NOFOLLOW | getattr(os, "O_CLOEXEC", 0), mode)
    except OSError as exc:
        if os.path.islink(path):
            raise _refuse(Path(path)) from None
        raise exc
    st = os.fstat(fd)
    if stat.S_ISREG(st.st_mode) and st.st_nlink > 1:
        os.close(fd)
        raise InputFileError(f"{short(str(path))} has {st.st_nlink} hard links (one may be outside the output folder): "
                             "refused, nothing written there")
    return fd

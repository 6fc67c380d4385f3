"""Bundled TOML files (presets, scenes, problems): one loader for the three kinds.

A bundled file is named by its stem (``prrr-paper``); anything else is read as a path. A name
that is both (a file of that name in the working directory) is read as the file, so a user's
file is never shadowed silently. Unknown names get one line listing what is bundled.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from hapticopt.design import tomlsafe
from hapticopt.design.errors import InputFileError, UnknownName, short

#: longest accepted file path [characters] (Linux PATH_MAX)
MAX_PATH = 4096


@dataclass(frozen=True, kw_only=True)
class TomlText:
    text: str
    source: str  # "scene stiffness-25" or the file name, for messages
    base_dir: Path | None  # the file's folder (relative paths inside it), None when bundled


def names(package: str) -> list[str]:
    """Stems of the ``*.toml`` files bundled in ``package`` (e.g. ``hapticopt.analysis.scenes``)."""
    return sorted(p.name[: -len(".toml")] for p in resources.files(package).iterdir() if p.name.endswith(".toml"))


def read(package: str, kind: str, name_or_path: str | Path, *, allow_path: bool = True) -> TomlText:
    """The text of bundled ``kind`` ``name_or_path`` from ``package``, or of that file."""
    arg = str(name_or_path)
    bundled = names(package)
    if "\0" in arg or len(arg) > MAX_PATH:
        raise InputFileError(f"{kind} {short(arg)} is not a usable name or path: allowed a bundled {kind} or a path "
                             f"of at most {MAX_PATH} characters without NUL")
    path = Path(arg)
    try:
        is_file = path.is_file()
    except OSError as exc:  # e.g. a path component longer than the filesystem allows
        raise InputFileError(f"{kind} file {short(arg)} cannot be read: {exc.strerror}") from None
    if arg in bundled and not (allow_path and is_file):
        text = (resources.files(package) / f"{arg}.toml").read_text(encoding="utf-8")
        return TomlText(text=text, source=f"{kind} {arg}", base_dir=None)
    if not allow_path:
        raise UnknownName(f"{kind} {short(arg)} does not exist: allowed {kind}s are {', '.join(bundled)}")
    if not is_file:
        if path.suffix == ".toml" or path.exists():
            raise InputFileError(f"{kind} file {short(arg)} does not exist: give a .toml path or a bundled {kind} "
                                 f"({', '.join(bundled)})")
        raise UnknownName(f"{kind} {short(arg)} does not exist: allowed {kind}s are {', '.join(bundled)} "
                          "or a path to a .toml file")
    text = tomlsafe.read_text(path, source=f"{kind} file {short(arg)}")
    return TomlText(text=text, source=path.name, base_dir=path.parent)

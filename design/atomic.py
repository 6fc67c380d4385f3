"""Atomic file writes: a temp file in the target directory, fsync, then rename.

A failure at any point leaves the target untouched and no partial file behind. No write follows a
link: folders are made and checked by :func:`hapticopt.design.paths.make_dirs`, a target (or a folder
above it, below the output root) that is a symbolic link is refused before anything is written.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from hapticopt.design import paths

_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``target``; on success rename it onto ``target``.

    For writers that insist on a file name (OCCT's STEP writer, VTK screenshots).
    """
    target = Path(target)
    paths.make_dirs(target.parent)
    paths.no_links(target)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp" + target.suffix, dir=target.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    os.chmod(tmp_path, 0o666 & ~_UMASK)  # mkstemp makes 0600; outputs get the usual permissions
    try:
        try:
            yield tmp_path
        except OSError:
            raise
        except Exception as exc:
            # writers of foreign libraries (OCCT's STEP, VTK) hide the OS reason ("Failed to write STEP
            # file"): if the folder no longer takes data, report that reason instead (probed while the
            # partial output still holds its space)
            reason = _write_probe_error(target.parent)
            if reason is not None:
                raise reason from exc
            raise
        if not tmp_path.exists() or tmp_path.stat().st_size == 0:
            reason = _write_probe_error(target.parent)
            if reason is not None:
                raise reason
            raise OSError(f"writer produced no output for {target}")
        os.replace(tmp_path, target)
    finally:
        tmp_path.unlink(missing_ok=True)


def _write_probe_error(folder: Path, size: int = 1 << 16) -> OSError | None:
    """The OSError a 64 KiB write (fsynced) into ``folder`` meets, or None if it succeeds."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".write-probe.", dir=folder)
    except OSError as exc:
        return exc
    try:
        os.write(fd, b"\0" * size)
        os.fsync(fd)
    except OSError as exc:
        if exc.filename is None:
            exc.filename = str(folder)
        return exc
    finally:
        os.close(fd)
        os.unlink(probe)
    return None


def write_bytes(target: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``target`` atomically."""
    with atomic_path(target) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


def write_text(target: str | os.PathLike[str], text: str) -> None:
    """Write UTF-8 ``text`` to ``target`` atomically."""
    write_bytes(target, text.encode("utf-8"))


#: names of this module's temporary files (``.<target>.<random>.tmp<suffix>``) and of write probes
_TEMP_RE = re.compile(r"^\.(.+\.[A-Za-z0-9_]{6,}\.tmp(\.[A-Za-z0-9]+)?|write-probe\.[A-Za-z0-9_]+)$")
#: names of :func:`file_set` staging folders
_STAGE_RE = re.compile(r"^\.set\.[A-Za-z0-9_]{6,}\.tmp$")


@contextlib.contextmanager
def file_set(root: str | os.PathLike[str]) -> Iterator[Path]:
    """Write a set of files as one: yield a staging folder inside ``root``; on success move each
    file to the same relative path under ``root``.

    Everything that can fail for lack of space or permission (creating and writing the files)
    happens in the staging folder; a fault there removes it and leaves ``root`` as it was — the
    previous set intact, none of the new one. Moving in is renames only (same filesystem: no data
    written), after a :data:`COMPLETE` marker is written in the staging folder: a process killed while
    moving leaves a complete set that :func:`remove_stale_temp_files` moves in (rolls forward) on the
    next run, so a kill never leaves half of the new set beside half of the old. A staging folder
    without the marker (killed while writing) is removed.
    """
    root = Path(root)
    created = [a for a in [root, *root.parents] if not a.exists()]
    paths.make_dirs(root)
    stage = Path(tempfile.mkdtemp(prefix=".set.", suffix=".tmp", dir=root))
    try:
        try:
            yield stage
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            for folder in created:  # folders made for this set only: gone with it (deepest first)
                try:
                    folder.rmdir()
                except OSError:
                    pass
            raise
        _move_in(stage, root)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


#: the marker of a staging folder whose set is complete (moved in even if the mover was killed)
COMPLETE = ".complete"


def _move_in(stage: Path, root: Path) -> None:
    """Mark ``stage`` complete, then rename each of its files to the same path under ``root``."""
    files = sorted(p for p in stage.rglob("*") if p.is_file() and p.name != COMPLETE)
    for f in files:  # folders first, so a missing folder cannot stop the renames half-way
        paths.make_dirs((root / f.relative_to(stage)).parent, root)
        paths.no_links(root / f.relative_to(stage), root)
    for f in files:
        _fsync_file(f)
    marker = os.open(stage / COMPLETE, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
    os.fsync(marker)
    os.close(marker)
    _fsync_dir(stage)
    for f in files:
        os.replace(f, root / f.relative_to(stage))
    _fsync_dir(root)


def _move_in_rest(stage: Path, root: Path) -> None:
    """Finish moving in a complete set whose mover was killed (the files it had not moved yet)."""
    for f in sorted(p for p in stage.rglob("*") if p.is_file() and not p.is_symlink() and p.name != COMPLETE):
        target = root / f.relative_to(stage)
        paths.make_dirs(target.parent, root)
        paths.no_links(target, root)
        os.replace(f, target)
    _fsync_dir(root)


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def remove_stale_temp_files(root: str | os.PathLike[str], *, depth: int = 2) -> list[Path]:
    """Delete temp files left by killed writers in ``root`` and its subfolders (to ``depth``).

    Call only while holding the folder (no live writer can own one): the pipeline does it under
    its run lock. Returns the files removed.
    """
    removed: list[Path] = []
    folders = [(Path(root), 0)]
    while folders:
        folder, level = folders.pop()
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for entry in entries:
            if entry.is_dir(follow_symlinks=False) and _STAGE_RE.match(entry.name):
                if os.path.lexists(os.path.join(entry.path, COMPLETE)):  # killed while moving in: finish it
                    _move_in_rest(Path(entry.path), folder)
                shutil.rmtree(entry.path, ignore_errors=True)
                removed.append(Path(entry.path))
            elif entry.is_dir(follow_symlinks=False):
                if level < depth:
                    folders.append((Path(entry.path), level + 1))
            elif entry.is_file(follow_symlinks=False) and _TEMP_RE.match(entry.name):
                Path(entry.path).unlink(missing_ok=True)
                removed.append(Path(entry.path))
    return removed

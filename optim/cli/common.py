"""Shared pieces of the CLI: loading a design from FILE or --preset, the one error boundary.

Every command is wrapped in :func:`one_line_errors`, the only place where an exception becomes
text for the user: one line on stderr and an exit code, never a traceback (``hapticopt --debug
COMMAND`` adds the traceback). Exit codes (:data:`EXIT_CODES_HELP`, every command's ``--help``):

* 0 — done, and every requirement the command reports holds;
* 2 — bad input or an operating-system fault (unreadable file, read-only or full disk, ``--out``
  is a file — the OS reason is in the line);
* 3 — done, but the result breaks a requirement or constraint (:func:`not_met`): ``evaluate`` with
  an evaluator status other than ``ok``, ``optimise`` whose final point (or Pareto choice) is
  infeasible at the final fidelity, ``verify`` with a verdict other than ``ok``; every output is
  still written;
* 4 — an internal error (a bug: the line names the exception and where it was raised);
* 5 — ``optimise`` finished and wrote its record, optimum and report, but a stage after the
  optimisation failed (export, a plot): :func:`stage_failed` prints one line naming the stage and why.
"""

from __future__ import annotations

import contextvars
import functools
import sqlite3
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Optional, TypeVar

import typer

from hapticopt.analysis.compute import MAX_THREADS, Backend, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.errors import HapticoptError, InvalidInput, short
from hapticopt.design import io
from hapticopt.optim.cache import FILENAME as CACHE_FILENAME, inspect
from hapticopt.optim.sqlite_checks import check_db_paths

F = TypeVar("F", bound=Callable[..., Any])

EXIT_OK = 0
EXIT_BAD_INPUT = 2
EXIT_NOT_MET = 3
EXIT_INTERNAL = 4
EXIT_STAGE_FAILED = 5

#: the exit codes, as every command's ``--help`` epilog states them (``\b``: click keeps the lines)
EXIT_CODES_HELP = (
    "\b\nExit codes:\n"
    "  0  done; every requirement the command reports holds\n"
    "  2  bad input or an operating-system fault (one stderr line says which)\n"
    "  3  done, but the result breaks a requirement or constraint\n"
    "     (evaluate: a status other than ok; optimise: an infeasible final\n"
    "     point, written as best_infeasible.toml, or Pareto choice, written as\n"
    "     chosen_infeasible.toml, or a verification scene that did not pass;\n"
    "     verify: a verdict other than ok); outputs are still written.\n"
    "     Other commands never exit 3.\n"
    "  4  internal error (a bug; hapticopt --debug shows the traceback)\n"
    "  5  optimise: a stage after the optimisation failed (export, a plot);\n"
    "     the record, the optimum and the report are written\n"
    "\b\n--json prints strict RFC 8259 JSON: a non-finite number is null, and\n"
    "the payload's null_numbers names each one by its JSON path (NaN, Infinity);\n"
    "the status beside it says why."
)
#: most processes of the local pool (``--workers``)
MAX_WORKERS = 256
#: longest error line printed [characters]; values inside are already shortened with reprlib
MAX_LINE = 1000


def _one_line(text: str) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= MAX_LINE else line[: MAX_LINE - 3] + "..."


def fail(message: str, code: int = EXIT_BAD_INPUT) -> None:
    """Print one error line to stderr and exit with ``code`` (2 by default)."""
    typer.echo(f"error: {_one_line(message)}", err=True)
    raise typer.Exit(code=code)


def not_met(what: str) -> None:
    """The command is done but its result breaks a requirement: one ``not met:`` line on stderr
    (stdout, e.g. ``--json``, stays as printed) and exit code 3."""
    typer.echo(f"not met: {_one_line(what)}", err=True)
    raise typer.Exit(code=EXIT_NOT_MET)


def stage_failed(what: str) -> None:
    """A stage after the optimisation failed: one ``error:`` line on stderr and exit code 5."""
    fail(what, EXIT_STAGE_FAILED)


def statuses_not_ok(statuses: dict[str, str]) -> str:
    """``name (status), …`` of the statuses other than ``ok`` ('' when all are ok)."""
    return ", ".join(f"{name} ({status})" for name, status in statuses.items() if status != "ok")


#: set by the root command's ``--debug`` option for this invocation
DEBUG: contextvars.ContextVar[bool] = contextvars.ContextVar("hapticopt_debug", default=False)
#: typer's own control-flow exceptions (exit, abort, usage errors): they pass the boundary untouched
_CLICK_EXCEPTION = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")
_PASS_THROUGH = (typer.Exit, typer.Abort, _CLICK_EXCEPTION)


def debug_requested() -> bool:
    """Whether ``hapticopt --debug …`` was given."""
    return DEBUG.get()


def describe_os_error(exc: OSError) -> str:
    """``strerror: filename`` of an OS error (the OS reason first), or its text."""
    reason = exc.strerror or str(exc) or type(exc).__name__
    name = exc.filename if exc.filename is not None else ""
    where = f": {name}" if name != "" else ""
    if exc.filename2 is not None:
        where += f" -> {exc.filename2}"
    return f"{reason}{where}"


def _where(exc: BaseException) -> str:
    tb = traceback.extract_tb(exc.__traceback__)
    if not tb:
        return ""
    frame = tb[-1]
    return f" ({Path(frame.filename).name}:{frame.lineno})"


def one_line_errors(func: F) -> F:
    """The error boundary: every exception leaves as one stderr line and an exit code."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except _PASS_THROUGH:
            raise
        except Exception as exc:  # noqa: BLE001 - this is the one boundary
            if debug_requested():
                traceback.print_exc(file=sys.stderr)
            if isinstance(exc, HapticoptError):
                fail(str(exc))
            if isinstance(exc, OSError):
                fail(f"{describe_os_error(exc)} ({type(exc).__name__})")
            if isinstance(exc, MemoryError):
                fail("out of memory: the input asks for more than this machine has", EXIT_BAD_INPUT)
            fail(f"internal error: {type(exc).__name__}: {exc}{_where(exc)} (hapticopt --debug shows the traceback)",
                 EXIT_INTERNAL)

    return wrapper  # type: ignore[return-value]


def load_design_arg(file: Path | None, preset: str | None, assignments: list[str] | None) -> Any:
    """The design named by FILE or --preset (exactly one), with --set overrides applied."""

    if (file is None) == (preset is None):
        raise InvalidInput("give exactly one of FILE or --preset NAME (see `hapticopt presets`)")
    design = io.load_design(file) if file is not None else io.load_preset(preset)  # type: ignore[arg-type]
    return io.apply_overrides(design, list(assignments or []))


CACHE_HELP = ("Evaluation cache file: a design's whole evaluation at a fidelity, reused when the same design, "
              "fidelity and code meet again (default: DIR/" + CACHE_FILENAME + "; give one FILE to share it "
              "among runs and commands).")
NO_CACHE_HELP = "Neither read nor write the evaluation cache: every evaluation is computed."


def cache_file(cache: Path | None, no_cache: bool, default_dir: Path | None) -> Path | None:
    """The evaluation cache file of ``--cache FILE`` / ``--no-cache`` (None: no cache); ``default_dir``
    holds the default file (None: no default)."""
    if no_cache and cache is not None:
        raise InvalidInput("--cache and --no-cache contradict each other: give one")
    if no_cache:
        return None
    if cache is None:
        return None if default_dir is None else check_cache(Path(default_dir) / CACHE_FILENAME)
    if cache.is_dir():
        raise InvalidInput(f"--cache = {str(cache)!r} is a directory: give a file, e.g. {Path(cache) / CACHE_FILENAME}")
    return check_cache(cache)


def check_cache(path: Path) -> Path:
    """Refuse a cache file that is a link, a foreign database or holds an edited entry (one line, exit 2;
    the file only read), before any work; a file of another format or not a database stays a warning."""
    check_db_paths(path)
    if path.is_file() and path.stat().st_size > 0:
        try:
            inspect(path)
        except sqlite3.DatabaseError:
            pass  # not a database: EvaluationCache ignores it with a warning
    return path


def parse_fidelity(text: str) -> Fidelity:
    """``--fidelity`` as a level; one line naming the allowed levels otherwise."""
    try:
        return Fidelity(text)
    except ValueError:
        allowed = ", ".join(f.value for f in Fidelity)
        raise InvalidInput(f"--fidelity = {short(text)} is not a fidelity level: allowed {allowed}") from None


#: ``--compute``: the route of the kernels that have more than one (every command that evaluates, verifies,
#: optimises or sweeps; :class:`hapticopt.analysis.compute.Compute`). Not ``--backend``: ``verify``'s
#: ``--backend`` already names the plant (lumped or multibody).
ComputeOption = Annotated[str, typer.Option(
    "--compute", metavar="|".join(b.value for b in Backend),
    help="Route of the kernels that have more than one: auto (decided by the size of each call), numpy, numba "
         "or jax. Results are the same on every route.")]
#: ``--threads``: the kernel threads a batch may use (a run's pool workers use one each)
ThreadsOption = Annotated[Optional[int], typer.Option(
    "--threads", show_default=False,
    help=f"Kernel threads a batch may use, 1 to {MAX_THREADS} (default: the CPUs of this process; a run's "
         "worker processes use one each).")]


def parse_compute(backend: str, threads: int | None) -> Compute:
    """``--compute`` and ``--threads`` as the route value; one line naming the flag, its value and what is
    allowed otherwise."""
    allowed = ", ".join(b.value for b in Backend)
    if backend not in {b.value for b in Backend}:
        raise InvalidInput(f"--compute = {short(backend)} is not allowed: one of {allowed}")
    if threads is not None and not 1 <= threads <= MAX_THREADS:
        raise InvalidInput(f"--threads = {threads} is not allowed: an integer from 1 to {MAX_THREADS}")
    return Compute(backend=backend, threads=threads)

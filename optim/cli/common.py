"""Shared pieces of the CLI: loading a design from FILE or --preset, one-line errors."""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import typer

from hapticopt.design.errors import HapticoptError, InvalidInput
from hapticopt.design import io

F = TypeVar("F", bound=Callable[..., Any])

EXIT_BAD_INPUT = 2


def fail(message: str) -> None:
    """Print one error line to stderr and exit with code 2."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code=EXIT_BAD_INPUT)


def one_line_errors(func: F) -> F:
    """Turn every deliberate hapticopt error into one line on stderr and exit code 2."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except HapticoptError as exc:
            fail(str(exc))

    return wrapper  # type: ignore[return-value]


def load_design_arg(file: Path | None, preset: str | None, assignments: list[str] | None) -> Any:
    """The design named by FILE or --preset (exactly one), with --set overrides applied."""

    if (file is None) == (preset is None):
        raise InvalidInput("give exactly one of FILE or --preset NAME (see `hapticopt presets`)")
    design = io.load_design(file) if file is not None else io.load_preset(preset)  # type: ignore[arg-type]
    return io.apply_overrides(design, list(assignments or []))


def is_tty() -> bool:
    return sys.stdout.isatty()

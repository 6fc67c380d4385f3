"""One progress line for long work: stage, bar, count, elapsed time, then what is happening now.

The columns are laid out so that the count and the elapsed time are never cut: the stage name
and the bar have fixed widths, count and elapsed keep their natural width, and only the last
column (the free text: the evaluator running, the best objective so far) is shortened with an
ellipsis when the terminal is narrow (80 columns is the design width). The line goes to stderr;
it is drawn live only on a terminal (``--quiet`` or a pipe: nothing while running; a pipe gets
the final state once, without ANSI codes).
"""

from __future__ import annotations

import time
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Column

#: width of the stage column [characters] ("baseline", "optimise", "final", "export", "verify" …)
STAGE_WIDTH = 8
#: width of the bar [characters]
BAR_WIDTH = 12


def make_progress(console: Console, *, transient: bool = False, disable: bool = False) -> Progress:
    """The progress display; one task per long job (:class:`StageLine` drives it)."""
    return Progress(
        TextColumn("[bold]{task.fields[stage]}", table_column=Column(width=STAGE_WIDTH, no_wrap=True,
                                                                      overflow="ellipsis")),
        BarColumn(bar_width=BAR_WIDTH),
        MofNCompleteColumn(table_column=Column(no_wrap=True, justify="right")),
        TimeElapsedColumn(table_column=Column(no_wrap=True)),
        TextColumn("{task.description}", table_column=Column(ratio=1, no_wrap=True, overflow="ellipsis")),
        console=console, transient=transient, disable=disable, expand=True,
    )


class StageLine:
    """A job shown as one line of named stages, each with its own count; elapsed time runs over the
    whole job. ``stage(name, total)`` starts a stage, ``step(what, done, total)`` moves inside it,
    ``note(text)`` sets the free text."""

    def __init__(self, progress: Progress, first_stage: str = "start", total: int = 1) -> None:
        self.progress = progress
        self.task = progress.add_task("", total=total, stage=first_stage)
        self.started = time.monotonic()

    def stage(self, name: str, total: int = 1, text: str = "") -> None:
        """Start stage ``name`` of ``total`` steps (1 for a stage without steps of its own)."""
        self.progress.update(self.task, stage=name, total=total, completed=0, description=text)
        self.progress.refresh()  # a new stage is drawn at once, however short it is

    def step(self, what: str, done: int, total: int) -> None:
        fields: dict[str, Any] = {"total": total, "completed": done}
        if what:
            fields["description"] = what
        self.progress.update(self.task, **fields)
        self.progress.refresh()  # steps are few (evaluators, export steps, scenes): each one is drawn

    def note(self, text: str) -> None:
        self.progress.update(self.task, description=text)

    def count(self, done: int, total: int | None = None) -> None:
        if total is None:
            self.progress.update(self.task, completed=done)
        else:
            self.progress.update(self.task, completed=done, total=total)

"""The ``hapticopt`` command line. Each subcommand lives in its own module of this package."""

from __future__ import annotations

from importlib.metadata import version
import sys
from typing import Annotated, Any

import typer
import typer.core

from hapticopt.optim.cli import compare as cli_compare
from hapticopt.optim.cli import common
from hapticopt.design import offscreen
from hapticopt.optim.executor import skip_teardown_at_exit
from hapticopt.optim.cli import evaluate as cli_evaluate
from hapticopt.optim.cli import export as cli_export
from hapticopt.optim.cli import metrics as cli_metrics
from hapticopt.optim.cli import optimise as cli_optimise
from hapticopt.optim.cli import runs as cli_runs
from hapticopt.optim.cli import sensitivity as cli_sensitivity
from hapticopt.optim.cli import sweep as cli_sweep
from hapticopt.optim.cli import tolerance as cli_tolerance
from hapticopt.optim.cli import verify as cli_verify

class _Commands(typer.core.TyperGroup):
    """The command group, with click's usage errors (unknown option, missing argument, bad choice)
    as one line on stderr naming the command's help, exit 2, like every other input error, instead
    of a usage box."""

    def main(self, args: Any = None, prog_name: str | None = None, complete_var: str | None = None,
             standalone_mode: bool = True, **extra: Any) -> Any:
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        try:
            rv = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except typer.TyperException as exc:  # click's errors (typer vendors click)
            ctx = getattr(exc, "ctx", None)
            code = getattr(exc, "exit_code", 2)
            if type(exc).__name__ == "NoArgsIsHelpError":
                typer.echo(ctx.get_help() if ctx is not None else exc.format_message())
                sys.exit(code)
            message = " ".join(exc.format_message().split()).rstrip(".")
            where = f" (see `{ctx.command_path} --help`)" if ctx is not None and code == 2 else ""
            typer.echo(f"error: {message[:1].lower() + message[1:]}{where}", err=True)
            sys.exit(code)
        except typer.Abort:
            typer.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)


app = typer.Typer(
    cls=_Commands,
    name="hapticopt",
    help="Design optimisation of haptic mechanisms: describe, evaluate, optimise, export, verify.",
    epilog=common.EXIT_CODES_HELP,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _show_version(value: bool) -> None:
    if value:
        typer.echo(f"hapticopt {version('hapticopt')}")
        raise typer.Exit()


@app.callback()
def _root(
    show_version: Annotated[bool, typer.Option("--version", help="Print the version and exit.", callback=_show_version,
                                               is_eager=True)] = False,
    debug: Annotated[bool, typer.Option("--debug", help="On an error, also print the traceback.")] = False,
) -> None:
    """Design optimisation of haptic mechanisms: describe, evaluate, optimise, export, verify."""
    common.DEBUG.set(debug)
    offscreen.configure()  # every picture off screen, in this process and the workers it starts


for _name, _command in (("evaluate", cli_evaluate.evaluate), ("presets", cli_evaluate.presets),
                         ("export", cli_export.export), ("optimise", cli_optimise.optimise),
                         ("problems", cli_optimise.problems), ("verify", cli_verify.verify), ("runs", cli_runs.runs),
                         ("show", cli_runs.show), ("sweep", cli_sweep.sweep), ("compare", cli_compare.compare),
                         ("design-map", cli_verify.design_map), ("metrics", cli_metrics.metrics),
                         ("sensitivity", cli_sensitivity.sensitivity), ("tolerance", cli_tolerance.tolerance)):
    app.command(_name, epilog=common.EXIT_CODES_HELP)(_command)


def main() -> None:
    """Console-script entry point (the ``__main__`` guard that Dask's LocalCluster needs). It owns the
    process: once the command has ended (typer ends every command with ``SystemExit``), the process
    ends with that status without the interpreter's module teardown (≈ 2 s after build123d was
    imported: :func:`hapticopt.optim.executor.end_process`); a crash ends as usual. In-process
    callers (tests) use ``app``."""
    status: list[int] = []
    skip_teardown_at_exit(lambda: status[0] if status else None)  # first: every other exit handler runs
    try:
        app()
    except SystemExit as exc:
        if exc.code is None or isinstance(exc.code, int):  # a message as the code: the interpreter prints it
            status.append(exc.code or 0)
        raise


if __name__ == "__main__":
    main()

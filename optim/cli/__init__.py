"""The ``hapticopt`` command line. Each subcommand lives in its own module of this package."""

from __future__ import annotations

from importlib.metadata import version
from typing import Annotated

import typer

from hapticopt.optim.cli import compare as cli_compare
from hapticopt.optim.cli import common
from hapticopt.design import offscreen
from hapticopt.optim.cli import evaluate as cli_evaluate
from hapticopt.optim.cli import export as cli_export
from hapticopt.optim.cli import metrics as cli_metrics
from hapticopt.optim.cli import optimise as cli_optimise
from hapticopt.optim.cli import runs as cli_runs
from hapticopt.optim.cli import sweep as cli_sweep
from hapticopt.optim.cli import verify as cli_verify

app = typer.Typer(
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


app.command("evaluate", epilog=common.EXIT_CODES_HELP)(cli_evaluate.evaluate)
app.command("presets", epilog=common.EXIT_CODES_HELP)(cli_evaluate.presets)
app.command("export", epilog=common.EXIT_CODES_HELP)(cli_export.export)
app.command("optimise", epilog=common.EXIT_CODES_HELP)(cli_optimise.optimise)
app.command("problems", epilog=common.EXIT_CODES_HELP)(cli_optimise.problems)
app.command("verify", epilog=common.EXIT_CODES_HELP)(cli_verify.verify)
app.command("runs", epilog=common.EXIT_CODES_HELP)(cli_runs.runs)
app.command("show", epilog=common.EXIT_CODES_HELP)(cli_runs.show)
app.command("sweep", epilog=common.EXIT_CODES_HELP)(cli_sweep.sweep)
app.command("compare", epilog=common.EXIT_CODES_HELP)(cli_compare.compare)
app.command("design-map", epilog=common.EXIT_CODES_HELP)(cli_verify.design_map)
app.command("metrics", epilog=common.EXIT_CODES_HELP)(cli_metrics.metrics)


def main() -> None:
    """Console-script entry point (the ``__main__`` guard that Dask's LocalCluster needs)."""
    app()


if __name__ == "__main__":
    main()

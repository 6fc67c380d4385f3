"""``hapticopt evaluate`` and ``hapticopt presets``."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from hapticopt.optim import strict_json

from hapticopt.optim.cli.common import (
    ComputeOption, ThreadsOption, load_design_arg, not_met, one_line_errors, parse_compute, parse_fidelity,
    statuses_not_ok,
)
from hapticopt.analysis.registry import EVALUATORS, evaluate_all, write_plots
from hapticopt.optim.cli import render
from hapticopt.optim.cli.progress import StageLine, make_progress
from hapticopt.design import io
from hapticopt.design.paths import writable_dir
from hapticopt.optim.cli.sweep import run_sweep


@one_line_errors
def evaluate(
    file: Annotated[Optional[Path], typer.Argument(help="Design TOML file (or use --preset).", show_default=False)] = None,
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name (see `hapticopt presets`).")] = None,
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a TOML key, e.g. --set geometry.beta_deg=50 (repeatable).")] = None,
    fidelity: Annotated[str, typer.Option("--fidelity", help="draft, standard or fine.")] = "standard",
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON {design, metrics, status, timings_s}.")] = False,
    plots: Annotated[Optional[Path], typer.Option("--plots", help="Write pictures of the evaluators' results to this directory.")] = None,
    sweep: Annotated[Optional[str], typer.Option("--sweep", help="Named trade-off sweep (master: counterweight, the seed-003 trade-off of bandwidth and unbalance force against counterweight mass); writes a plot and a CSV table to --plots DIR or the current directory. Any numeric key: `hapticopt sweep`.")] = None,
    compute: ComputeOption = "auto",
    threads: ThreadsOption = None,
) -> None:
    """Evaluate a design and print its metrics (units in the metric names) and each evaluator's status (exit 3 unless every status is ok)."""
    t_start = time.perf_counter()

    level = parse_fidelity(fidelity)
    route = parse_compute(compute, threads)
    t_import = time.perf_counter()
    design = load_design_arg(file, preset, set_)
    if plots is not None:
        writable_dir(plots, "--plots")
    if sweep is not None:
        writable_dir(plots if plots is not None else Path("."), "--plots")
    err = render.console(stderr=True)
    with make_progress(err, transient=True, disable=as_json or not err.is_terminal) as bar:
        line = StageLine(bar, "evaluate", len(EVALUATORS[design.device]))
        line.note(f"{design.name} at {level} fidelity")
        evaluation = evaluate_all(design, fidelity=level, compute=route,
                                  progress=lambda what, done, total: line.step(
                                      f"{level}: {what}" if what else "", done, total))
    timings = {"imports": t_import - t_start, **evaluation.timings_s}
    written = write_plots(design, evaluation, plots) if plots is not None else []
    if sweep is not None:
        written += run_sweep(design, sweep, plots if plots is not None else Path("."), level)
    timings["total"] = time.perf_counter() - t_start
    metrics = evaluation.metrics()
    status = {k: str(v) for k, v in evaluation.statuses.items()}
    if as_json:
        payload = {
            "design": io.design_to_dict(design),
            "fidelity": str(level),
            "metrics": metrics,
            "status": status,
            "messages": {k: v for k, v in evaluation.messages.items() if v},
            "timings_s": timings,
            "plots": [str(p) for p in written],
        }
        typer.echo(strict_json.dumps(payload, indent=2))
        if statuses_not_ok(status):
            not_met(statuses_not_ok(status))
        return

    console = render.console()
    console.print(render.metrics_table(f"{design.name} ({design.device}, {level} fidelity)", metrics))
    bad = {k: v for k, v in status.items() if v != "ok"}
    if not bad:
        console.print(f"evaluators: all {len(status)} ok")
    for name, st in status.items():
        message = evaluation.messages.get(name, "")
        if st != "ok" or message:
            console.print(f"{name}: {st}" + (f" — {message}" if message else ""))
    for path in written:
        console.print(f"wrote {path}")
    slow = sorted(((v, k) for k, v in timings.items() if k not in ("imports", "total")), reverse=True)[:3]
    console.print(f"time: {render.number(timings['total'], 3)} s"
                  + (" (slowest: " + ", ".join(f"{k} {render.number(v, 2)} s" for v, k in slow) + ")" if slow else "")
                  + "; --json has every timing")
    if statuses_not_ok(status):
        not_met(statuses_not_ok(status))


@one_line_errors
def presets(
    as_json: Annotated[bool, typer.Option("--json", help="Print a JSON list [{name, device, description}].")] = False,
) -> None:
    """List the bundled design presets."""
    rows = []
    for name in io.preset_names():
        design = io.load_preset(name)
        rows.append({"name": name, "device": design.device, "description": design.description})
    if as_json:
        typer.echo(strict_json.dumps(rows, indent=2))
        return
    render.console().print(render.table(None, ("preset", "device", "description"),
                                        ((r["name"], r["device"], r["description"]) for r in rows)))

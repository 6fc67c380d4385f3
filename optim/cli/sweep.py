"""``hapticopt sweep (FILE | --preset NAME) KEY=lo:hi:n [KEY2=lo:hi:n]`` (any numeric key, on the
executor, recorded like a run: :mod:`hapticopt.optim.sweep`) and ``hapticopt evaluate --sweep NAME``
(the master's counterweight trade-off of seed 003)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Optional

import typer

from hapticopt.optim import strict_json

from hapticopt.design.atomic import write_text
from hapticopt.design.errors import InvalidInput
from hapticopt.optim.cli import render
from hapticopt.optim.cli.common import (
    CACHE_HELP, MAX_WORKERS, NO_CACHE_HELP, ComputeOption, ThreadsOption, cache_file, load_design_arg,
    one_line_errors, parse_compute, parse_fidelity,
)
from hapticopt.optim.cli.progress import StageLine, make_progress
from hapticopt.optim.executor import check_scheduler, make_executor
from hapticopt.optim.recorder import Recorder, check_run_dir, run_lock
from hapticopt.design import paths
from hapticopt.design.paths import check_name, inside

SWEEPS = {"master": ("counterweight",)}


def run_sweep(design: Any, name: str, out_dir: Path, fidelity: Any) -> list[Path]:
    """Run the sweep ``name`` for ``design``; returns the files written (table, plot)."""
    allowed = SWEEPS.get(design.device, ())
    if name not in allowed:
        raise InvalidInput(f"--sweep = {name!r} is not a sweep for a {design.device} design: "
                           f"allowed {', '.join(allowed) if allowed else 'none'} (any numeric key: "
                           "`hapticopt sweep KEY=lo:hi:n`)")

    from hapticopt.analysis.master import plots as master_plots, tradeoff as master_tradeoff

    rows = master_tradeoff.counterweight_sweep(design, fidelity=fidelity)
    out_dir = Path(out_dir)
    check_name(design.name, "design name")
    table_path = inside(out_dir, f"{design.name}_sweep_counterweight.csv")
    plot_target = inside(out_dir, f"{design.name}_sweep_counterweight.png")
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text(table_path, master_tradeoff.rows_to_csv(rows))
    mu, mf = rows[0]["upper_counterweight_kg"], rows[0]["forearm_counterweight_kg"]
    boundary = master_tradeoff.unbalance_boundary(design, fidelity=fidelity) * (mu + mf)
    plot_path = master_plots.sweep_plot(rows, plot_target, boundary_mass=boundary)
    err = render.console(stderr=True)
    for t in render.number_tables(f"{design.name}: counterweight sweep (seed 003 trade-off; units in the names)",
                                  list(rows[0]), ([render.number(v) for v in r.values()] for r in rows),
                                  width=err.width):
        err.print(t)
    return [table_path, plot_path]


# ------------------------------------------------------------------ hapticopt sweep (any numeric key)
@one_line_errors
def sweep(
    args: Annotated[list[str], typer.Argument(help="An optional design TOML file (or --preset), then one or two axes "
                                                   "section.key=lo:hi:n (n ≥ 2 values, both ends included), e.g. "
                                                   "geometry.beta_deg=30:70:41.",
                                              show_default=False, metavar="[FILE] KEY=lo:hi:n [KEY2=lo:hi:n]")],
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name (see `hapticopt presets`).")] = None,
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a TOML key of the base design (repeatable).")] = None,
    fidelity: Annotated[str, typer.Option("--fidelity", help="draft, standard or fine.")] = "draft",
    only: Annotated[Optional[str], typer.Option("--only", help="Evaluators to run, comma-separated (default: all for the device).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Run directory (default cad_out/sweep-<design>-<keys>/).")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Continue the sweep in --out: recorded points are replayed.")] = False,
    force: Annotated[bool, typer.Option("--force", help="Replace the run already recorded in --out.")] = False,
    scheduler: Annotated[str, typer.Option("--scheduler", help="local (process pool), inline, or a Dask scheduler address tcp://HOST:PORT.")] = "local",
    workers: Annotated[Optional[int], typer.Option("--workers", help="Processes of the local pool (default: min(4, CPUs)).")] = None,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="One PNG per metric under DIR/plots/ and the overview "
                                                           "page DIR/overview.html (+ overview.png).")] = True,
    batch: Annotated[bool, typer.Option("--batch", help="Evaluate in one process with the batched evaluators (3-PRRR at draft: every evaluator; other fidelities: --only statics).")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", help="No progress display.")] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON {design, axes, fidelity, points, ok, evaluated, "
                                                         "replayed, out_dir, files} instead of the summary.")] = False,
    cache: Annotated[Optional[Path], typer.Option("--cache", help=CACHE_HELP.replace("DIR", "OUT"))] = None,
    no_cache: Annotated[bool, typer.Option("--no-cache", help=NO_CACHE_HELP)] = False,
    compute: ComputeOption = "auto",
    threads: ThreadsOption = None,
) -> None:
    """Sweep one or two numeric design keys over a grid; writes sweep.csv, a plot per metric, an overview page
    (overview.html, overview.png) and the record."""
    from hapticopt.optim import sweep as sw  # heavy (evaluators, jax): imported when the command runs

    level = parse_fidelity(fidelity)
    route = parse_compute(compute, threads)
    file = None
    axes_text = list(args)
    if axes_text and "=" not in axes_text[0]:
        file = Path(axes_text.pop(0))
    if not axes_text:
        raise InvalidInput("give one or two axes KEY=lo:hi:n after the design, e.g. geometry.beta_deg=30:70:41")
    check_scheduler(scheduler)  # before the run directory is made: a bad value leaves nothing behind
    if workers is not None and not 1 <= workers <= MAX_WORKERS:
        raise InvalidInput(f"--workers = {workers} is out of range: allowed 1 ≤ --workers ≤ {MAX_WORKERS}")
    design = load_design_arg(file, preset, set_)
    axes = tuple(sw.parse_axis(t, design) for t in axes_text)
    only_t = tuple(s.strip() for s in only.split(",") if s.strip()) if only is not None else None
    spec = sw.Sweep(base=design, axes=axes, fidelity=level, only=only_t)
    if batch and not sw.batch_supported(spec):
        allowed = sw.BATCHED.get(design.device, ())
        raise InvalidInput(f"--batch needs a 3-PRRR draft sweep, or --only naming evaluators with a batched form: "
                           f"for a {design.device} design at {level} allowed {', '.join(allowed) if allowed else 'none'}")
    out_dir = out if out is not None else Path("cad_out") / f"sweep-{design.name}-{'-'.join(a.key for a in axes)}"
    check_run_dir(out_dir, resume=resume, force=force)  # nothing written before this
    cache_path = cache_file(cache, no_cache, out_dir)
    console = render.console(stderr=True, quiet=quiet)
    with paths.output_root(out_dir), run_lock(out_dir):  # one sweep per run directory at a time
        written, result = _run_locked(spec, out_dir, resume=resume, force=force, quiet=quiet, scheduler=scheduler,
                                      workers=workers, batch=batch, cache_path=cache_path, plots=plots,
                                      console=console, level=level, route=route)
    n_fail = spec.n_points - result.n_ok
    if as_json:
        typer.echo(strict_json.dumps({"design": design.name, "axes": [{"key": a.key, "n": a.n} for a in axes],
                               "fidelity": str(level), "points": spec.n_points, "ok": result.n_ok,
                               "evaluated": result.n_evaluated, "replayed": result.n_replayed,
                               "out_dir": str(out_dir), "files": [str(p) for p in written]}, indent=2))
        return
    typer.echo(f"sweep of {design.name} over {' × '.join(f'{a.key} ({a.n})' for a in axes)} at {level} fidelity: "
               f"{spec.n_points} points, {result.n_ok} ok, {n_fail} not ok; {result.n_evaluated} evaluated, "
               f"{result.n_replayed} replayed" + (f" ({result.n_cached} from the evaluation cache {cache_path})"
                                                   if result.n_cached else ""))
    n_plots = sum(p.parent == out_dir / "plots" for p in written)
    typer.echo(f"table: {written[0]}" + (f"; {n_plots} plots in {out_dir / 'plots'}" if n_plots else ""))
    overview = [p for p in written if p.suffix == ".html"]  # the one page a sweep writes
    if overview:
        typer.echo(f"overview: {overview[0]} (every metric against the swept key{'s' if len(axes) > 1 else ''})")


def _run_locked(spec: Any, out_dir: Path, *, resume: bool, force: bool, quiet: bool, scheduler: str,
                workers: int | None, batch: bool, cache_path: Path | None, plots: bool, console: Any,
                level: Any, route: Any) -> tuple[list[Path], Any]:
    """The sweep, recorded, and its outputs; the caller holds the run lock of ``out_dir``."""
    from hapticopt.optim import sweep as sw

    axes = spec.axes
    with Recorder(out_dir, fingerprint=spec.fingerprint(), resume=resume, force=force,
                  search_fingerprint=spec.fingerprint()) as rec:
        rec.describe({**spec.info(), "status": "running"})
        with make_progress(console, disable=quiet) as bar:
            line = StageLine(bar, "sweep", spec.n_points)
            line.note(f"{' × '.join(a.key for a in axes)} at {level} fidelity")
            try:
                with make_executor(scheduler, workers=workers) as executor:
                    result = sw.run_sweep(spec, executor=executor, recorder=rec,
                                          progress=lambda done, total: line.count(done, total), batch=batch,
                                          cache=cache_path, compute=route)
            except BaseException:
                rec.set_status("interrupted")
                raise
        rec.end_session(status="finished", n_evaluated=result.n_evaluated, n_replayed=result.n_replayed,
                        max_evals=spec.n_points)
    return sw.write_outputs(result, out_dir, plots=plots), result

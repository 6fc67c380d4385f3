"""``hapticopt verify``: the design in closed loop with the firmware controller, in a scene."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
from pathlib import Path
from typing import Annotated, Any, Optional

import typer

from hapticopt.optim import strict_json

from hapticopt.optim.cli import render
from hapticopt.optim.cli.common import (
    ComputeOption, ThreadsOption, load_design_arg, not_met, one_line_errors, parse_compute, parse_fidelity,
)
from hapticopt.optim.cli.progress import StageLine, make_progress
import numpy as np
from hapticopt.design.atomic import atomic_path
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.scene import Backend, StabilityCriterion, load_scene
from hapticopt.design.errors import InvalidInput
from hapticopt.design.paths import check_name, inside, writable_dir
from hapticopt.design.errors import short


def _plot(result: Any, out_dir: Path, name: str) -> list[Path]:
    """The run's time histories as the report draws them (:func:`hapticopt.optim.report.history_figure`):
    the scene, the verdict and the stop time in the title, the traces only up to the tick where an
    unstable run stopped, that tick marked (matplotlib if installed; otherwise nothing)."""
    from hapticopt.optim import report
    from hapticopt.optim.results import TimeHistory, Verdict

    if importlib.util.find_spec("matplotlib") is None:
        return []
    history = TimeHistory.from_traces(result.traces)
    if history is None:
        return []
    status = str(result.status)
    verdict = Verdict(scene=name, passed=status == "ok", metrics={}, message=status, history=history)
    fig = report.history_figure(verdict)
    target = inside(out_dir, f"verify-{check_name(name, 'scene name')}.png")
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    report._pyplot().close(fig)
    return [target]


@one_line_errors
def verify(
    file: Annotated[Optional[Path], typer.Argument(help="Design TOML file (or use --preset).", show_default=False)] = None,
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name.")] = None,
    scene: Annotated[Optional[str], typer.Option("--scene", help="Bundled scene name (free-space, free-space-x, free-space-x-2hz, free-space-y, free-space-y-2hz, force-tracking, force-circle-xy, force-circle-xz, stiffness-25, stiffness-25-links, virtual-box, z-width, prrr-ioic; master-transparency, master-protocol-x, master-protocol-z, master-wall, master-ioic; handle-wall, handle-ball) or a .toml path [default: stiffness-25, master-wall for a master, handle-wall for a handle].", show_default=False)] = None,
    period_ms: Annotated[Optional[float], typer.Option("--period-ms", help="Override the scene's controller period T, in ms.", show_default=False)] = None,
    force_gain: Annotated[Optional[float], typer.Option("--force-gain", help="Override the scene's force-loop gain K_p (dimensionless).", show_default=False)] = None,
    backend: Annotated[str, typer.Option("--backend", help="auto (the scene resolver picks), lumped or multibody.")] = "auto",
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a design TOML key (repeatable).")] = None,
    fidelity: Annotated[str, typer.Option("--fidelity", help="draft, standard or fine.")] = "standard",
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON {design, scene, metrics, status, message}.")] = False,
    plots: Annotated[Optional[Path], typer.Option("--plots", help="Write pictures of the run to this directory.")] = None,
    compute: ComputeOption = "auto",
    threads: ThreadsOption = None,
) -> None:
    """Simulate the design in closed loop with the firmware controller in a scene (exit 3 unless the verdict is ok)."""
    from hapticopt.analysis import verify as closed_loop_verify  # heavy (plants, jax): when the command runs
    from hapticopt.analysis.prrr.loop import zwidth
    level = parse_fidelity(fidelity)
    route = parse_compute(compute, threads)
    if backend not in ("auto", "lumped", "multibody"):
        raise InvalidInput(f"--backend = {short(backend)} is not a backend: allowed auto, lumped, multibody")
    force = None if backend == "auto" else Backend(backend)
    design = load_design_arg(file, preset, set_)
    device = design.device if design.device in ("master", "handle") else "prrr"
    sc = load_scene(scene or {"master": "master-wall", "handle": "handle-wall"}.get(device, "stiffness-25"))
    if sc.device != device:
        raise InvalidInput(f"--scene {sc.name} is written for the {sc.device} device; design {design.name!r} is a "
                           f"{design.device}: pick a {device} scene")
    sc = _override_controller(sc, period_ms, force_gain)
    if plots is not None:
        writable_dir(plots, "--plots")
    err = render.console(stderr=True)
    with make_progress(err, transient=True, disable=as_json or not err.is_terminal) as bar:
        line = StageLine(bar, "simulate")
        line.note(f"{design.name} in {sc.name} at {level} fidelity")
        result = closed_loop_verify.simulate(design, sc, fidelity=level, backend=force, compute=route)
        metrics = result.metrics()
        metrics["resolution_reason"] = metrics.get("backend_reason", "")  # its older name, kept for --json users
        metrics["notes"] = list(result.notes)
        if sc.stability == StabilityCriterion.DECAY and metrics["backend"] == "lumped":  # also map its Z-width
            line.stage("z-width", 1, "stable region over wall stiffness × damping")
            metrics.update(zwidth.zwidth_map(design, sc, fidelity=level).metrics())
    written = _plot(result, plots, sc.name) if plots is not None else []
    if as_json:
        typer.echo(strict_json.dumps({"design": design.name, "scene": sc.name, "metrics": metrics,
                               "status": str(result.status), "message": result.message,
                               "plots": [str(p) for p in written]}, indent=2))
        _exit_on_verdict(result, sc.name)
        return
    _print_verify(design.name, sc.name, level, metrics, str(result.status), result.message, written)
    _exit_on_verdict(result, sc.name)


#: verify keys shown as lines of their own, not in the metric table (resolution_reason: backend_reason's
#: older name, kept in --json only)
_OWN_LINES = ("backend", "backend_reason", "resolution_reason", "effects", "notes", "paper_quantity", "paper_axes",
              "paper_metric", "paper_value", "paper_source", "assumptions")


def _print_verify(design: str, scene: str, level: Fidelity, metrics: dict[str, Any], status: str, message: str,
                  written: list[Path]) -> None:
    console = render.console()
    console.print(f"{design} in scene {scene} ({level} fidelity, {metrics.get('backend', '?')} backend)")
    if metrics.get("backend_reason"):
        console.print(f"backend: {metrics['backend_reason']}")
    if metrics.get("effects"):
        console.print(f"effects: {render.value(metrics['effects'])}")
    shown = {k: v for k, v in metrics.items() if k not in _OWN_LINES
             and not (k.startswith("zwidth_stable") and isinstance(v, list))}  # the map's cells: --json
    console.print(render.metrics_table(None, shown))
    if "paper_quantity" in metrics:
        q = str(metrics["paper_quantity"])
        axes = f" along {metrics['paper_axes']}" if metrics.get("paper_axes") else ""
        console.print(f"paper: {q}{axes} = {render.metric(q, metrics.get('paper_metric'))} here, "
                      f"{render.metric(q, metrics.get('paper_value'))} in {metrics.get('paper_source', 'the paper')}")
    for a in metrics.get("assumptions") or []:  # the values the paper does not give (analysis.loop.assumptions)
        console.print(f"assumed: {a['key']} = {render.value(a['value'])} — {a['source']}")
    for note in metrics.get("notes") or []:
        console.print(f"note: {note}")
    console.print(f"status: {status}" + (f" — {message}" if message else ""))
    for p in written:
        console.print(f"wrote {p}")


def _exit_on_verdict(result: Any, scene: str) -> None:
    """Exit 3 unless the closed-loop verdict is ok (unstable, inconclusive, failed)."""
    if str(result.status) != "ok":
        not_met(f"verify {scene}: {result.status}" + (f" — {result.message}" if result.message else ""))


#: most controller ticks one verification simulates (bounds its memory and time; the bundled scenes use ≤ 30,000)
MAX_TICKS = 1_000_000
#: the controller period's range [s], as the design map's (analysis.prrr.loop.design_map.PERIOD_RANGE)
PERIOD_RANGE = (1e-6, 0.1)


def _override_controller(sc: Any, period_ms: float | None, force_gain: float | None) -> Any:
    """The scene with --period-ms / --force-gain applied (same ranges as the scene TOML keys)."""
    c = sc.controller
    if period_ms is not None:
        lo, hi = (v * 1e3 for v in PERIOD_RANGE)
        if not (math.isfinite(period_ms) and lo <= period_ms <= hi):
            raise InvalidInput(f"--period-ms = {period_ms:g} is out of range: allowed {lo:g} ≤ period_ms ≤ {hi:g} ms")
        ticks = sc.duration / (period_ms * 1e-3)
        if ticks > MAX_TICKS:
            raise InvalidInput(f"--period-ms = {period_ms:g} gives {ticks:.3g} controller ticks over the scene's "
                               f"{sc.duration:g} s: allowed at most {MAX_TICKS:g} (period_ms ≥ "
                               f"{sc.duration / MAX_TICKS * 1e3:g} ms for this scene)")
        c = dataclasses.replace(c, period=period_ms * 1e-3)
    if force_gain is not None:
        if not (math.isfinite(force_gain) and 0.0 <= force_gain <= 1e9):
            raise InvalidInput(f"--force-gain = {force_gain:g} is out of range: allowed 0 ≤ force_gain ≤ 1e+09 (-)")
        c = dataclasses.replace(c, force_gain=force_gain)
    return dataclasses.replace(sc, controller=c)


def _grid(text: str, option: str, unit: str, scale: float) -> np.ndarray:
    """"a:b:n" (n log-spaced values from a to b; a linear start at 0) or "v1,v2,…" → values × scale."""
    try:
        if ":" in text:
            a, b, n = text.split(":")
            lo, hi, count = float(a), float(b), int(n)
            if count < 1 or count > 200 or not (0 <= lo <= hi):
                raise ValueError
            vals = (np.geomspace(lo, hi, count) if lo > 0 else np.concatenate([[0.0], np.geomspace(
                max(hi * 1e-3, 1e-12), hi, count - 1)]) if count > 1 else np.array([lo]))
        else:
            vals = np.array([float(v) for v in text.split(",")])
        if vals.size == 0 or not np.all(np.isfinite(vals)):
            raise ValueError
    except ValueError:
        raise InvalidInput(f"{option} = {short(text)} must be \"start:stop:count\" (log-spaced, count 1–200) or "
                           f"\"v1,v2,…\" in {unit}") from None
    return vals * scale


@one_line_errors
def design_map(
    file: Annotated[Optional[Path], typer.Argument(help="Design TOML file (or use --preset).", show_default=False)] = None,
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name.")] = None,
    scene: Annotated[str, typer.Option("--scene", help="Scene whose report quantity (the scene TOML's report table) is mapped (free-space-x, free-space-y, or a .toml path).")] = "free-space-x",
    periods_ms: Annotated[str, typer.Option("--periods-ms", help="Controller periods T in ms: \"start:stop:count\" (log-spaced) or \"v1,v2,…\".")] = "0.05:2:10",
    force_gains: Annotated[str, typer.Option("--force-gains", help="Force-loop gains K_p (dimensionless): \"start:stop:count\" (log-spaced; start 0 adds K_p = 0) or \"v1,v2,…\".")] = "10:1000:10",
    duration_s: Annotated[float, typer.Option("--duration-s", help="Simulated time per point, in s.")] = 2.0,
    simulate_limits: Annotated[bool, typer.Option("--simulate-limits", help="Also find each K limit by bisection on simulated decay runs (slow).")] = False,
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a design TOML key (repeatable).")] = None,
    fidelity: Annotated[str, typer.Option("--fidelity", help="draft, standard or fine.")] = "standard",
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON {design, scene, metrics}.")] = False,
    plots: Annotated[Optional[Path], typer.Option("--plots", help="Write the design-map figure to this directory.")] = None,
) -> None:
    """Map the firmware over (controller period T, force-loop gain K_p): free-space residual, K limit, bandwidth."""
    from hapticopt.analysis.prrr.loop import design_map as firmware_map  # heavy (jax): when the command runs

    level = parse_fidelity(fidelity)
    if not (math.isfinite(duration_s) and 0.6 <= duration_s <= 60.0):
        raise InvalidInput(f"--duration-s = {duration_s:g} is out of range: allowed 0.6 ≤ duration_s ≤ 60 s")
    Ts = _grid(periods_ms, "--periods-ms", "ms", 1e-3)
    kps = _grid(force_gains, "--force-gains", "(-)", 1.0)
    design = load_design_arg(file, preset, set_)
    if design.device != "prrr":
        raise InvalidInput(f"design {design.name!r} is a {design.device}: the design map is the 3-PRRR's SEA force loop")
    sc = load_scene(scene)
    dmap = firmware_map.design_map(design, sc, periods=Ts, force_gains=kps, fidelity=level,
                                   simulate_limits=simulate_limits, duration=duration_s)
    written: list[Path] = []
    if plots is not None:
        if importlib.util.find_spec("matplotlib") is None:
            raise InvalidInput("--plots needs matplotlib (not installed): pip install matplotlib, or leave --plots out")
        from hapticopt.analysis.prrr.plots import design_map_plots

        written = design_map_plots(dmap, plots)
    metrics = dmap.metrics()
    if as_json:
        typer.echo(strict_json.dumps({"design": design.name, "scene": sc.name, "metrics": metrics,
                               "plots": [str(p) for p in written]}, indent=2))
        return
    typer.echo(f"design map of {design.name} in {sc.name} ({sc.report.quantity}, axis {metrics['map_axis']}); "
               f"{dmap.wall_time:.1f} s")
    head = "T [ms] \\ K_p".ljust(14) + "".join(f"{k:>22.4g}" for k in kps)
    typer.echo("cells: residual [N] / K limit [N/mm] / bandwidth [Hz]; '-' where unstable or undefined")
    typer.echo(head)
    for i, T in enumerate(Ts):
        cells = []
        for j in range(len(kps)):
            r, K, bw = dmap.residual[i, j], dmap.stiffness_limit[i, j] * 1e-3, dmap.bandwidth[i, j]
            f = lambda v, spec: format(v, spec) if math.isfinite(v) else ("inf" if v == math.inf else "-")  # noqa: E731
            cells.append(f"{f(r, '.3g')}/{f(K, '.4g')}/{f(bw, '.3g')}".rjust(22))
        typer.echo(f"{T * 1e3:<14.4g}" + "".join(cells))
    for p in written:
        typer.echo(f"wrote {p}")

"""``hapticopt sensitivity``: local sensitivities of a design's metrics to its continuous keys, ranked."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Optional

import typer

from hapticopt.optim import strict_json

from hapticopt.analysis.registry import EVALUATORS
from hapticopt.design.errors import InvalidInput
from hapticopt.design.paths import check_name, inside, writable_dir
from hapticopt.optim.cli import render
from hapticopt.optim import sensitivity as sens
from hapticopt.optim.cli.common import load_design_arg, one_line_errors, parse_fidelity


def _finite(x: float | None) -> float | None:
    return x if x is not None and math.isfinite(x) else None


def rows_json(rows) -> list[dict]:
    """Strict JSON rows: a non-finite number is null (the row's status says why)."""
    out = []
    for r in rows:
        d = r.as_dict()
        for k in ("value", "derivative", "elasticity", "step", "uncertainty", "key_value"):
            d[k] = _finite(d[k])
        out.append(d)
    return out


def tornado(rows, path: Path, title: str, top: int = 15) -> Path:
    """A tornado plot of the ``top`` largest |elasticities| (the relative change of each metric per
    relative change of each key)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    best = [r for r in rows if r.elasticity is not None and math.isfinite(r.elasticity)][:top][::-1]
    fig, ax = plt.subplots(figsize=(8, 0.35 * len(best) + 1.5))
    ax.barh([f"{r.metric} / {r.key}" for r in best], [r.elasticity for r in best],
            color=["tab:red" if r.elasticity < 0 else "tab:blue" for r in best])
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xlabel("elasticity (∂metric/∂key · key/metric)")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


@one_line_errors
def sensitivity(
    file: Annotated[Optional[Path], typer.Argument(help="Design TOML file (or use --preset).", show_default=False)] = None,
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name (see `hapticopt presets`).")] = None,
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a TOML key, e.g. --set geometry.beta_deg=50 (repeatable).")] = None,
    metrics: Annotated[Optional[list[str]], typer.Option("--metrics", help="Metric names to differentiate (repeatable; default: every numeric metric).")] = None,
    keys: Annotated[Optional[list[str]], typer.Option("--key", help="Continuous design keys, e.g. geometry.beta_deg (repeatable; default: all).")] = None,
    evaluators: Annotated[Optional[list[str]], typer.Option("--evaluator", help="Run only these registry evaluators (repeatable; default: all).")] = None,
    fidelity: Annotated[str, typer.Option("--fidelity", help="draft (the batched path), standard or fine.")] = "draft",
    top: Annotated[int, typer.Option("--top", help="Rows of the ranked table (the JSON has all).")] = 25,
    as_json: Annotated[bool, typer.Option("--json", help="Print strict JSON {design, fidelity, sensitivities}.")] = False,
    plots: Annotated[Optional[Path], typer.Option("--plots", help="Write a tornado plot PNG to this directory.")] = None,
) -> None:
    """∂metric/∂key of a design's metrics w.r.t. its continuous keys (metric and key units), ranked by elasticity: jax through the closed forms, central differences with a measured step elsewhere."""
    level = parse_fidelity(fidelity)
    if top < 1:
        raise InvalidInput(f"--top = {top} must be at least 1")
    design = load_design_arg(file, preset, set_)
    if evaluators:
        known = [e.name for e in EVALUATORS[design.device]]
        unknown = [e for e in evaluators if e not in known]
        if unknown:
            raise InvalidInput(f"--evaluator {', '.join(unknown)}: allowed for a {design.device} design: {', '.join(known)}")
    if plots is not None:
        writable_dir(plots, "--plots")
    rows = sens.sensitivities(design, fidelity=level, metrics=list(metrics) if metrics else None,
                              keys=list(keys) if keys else None, only=tuple(evaluators) if evaluators else None)
    written = []
    if plots is not None:
        check_name(design.name, "design name")
        path = plots / f"{design.name}_sensitivity_tornado.png"
        inside(plots, path.absolute())
        written.append(tornado(rows, path, f"{design.name}: largest elasticities ({level})"))
    if as_json:
        typer.echo(strict_json.dumps({"design": design.name, "device": design.device, "fidelity": str(level),
                               "sensitivities": rows_json(rows), "plots": [str(p) for p in written]},
                              indent=2))
        return
    shown = [r for r in rows if r.status != "zero"][:top]
    table = render.table(f"{design.name}: sensitivities at {level} fidelity (largest |elasticity| first)",
                         ("metric", "key", "∂metric/∂key", "elasticity", "method", "status"),
                         ((r.metric, r.key, render.value(r.derivative) + f" {r.metric_unit or '-'}/{r.key_unit or '-'}"
                           if r.derivative is not None else "-",
                           render.number(r.elasticity) if r.elasticity is not None else "-", r.method, r.status)
                          for r in shown))
    console = render.console()
    console.print(table)
    zero = sum(r.status == "zero" for r in rows)
    console.print(f"{len(rows)} pairs; {zero} with a zero derivative not shown; --json has all")
    for p in written:
        console.print(f"wrote {p}")

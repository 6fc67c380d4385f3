"""``hapticopt verify``: the design in closed loop with the firmware controller, in a scene."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any, Optional

import typer

from hapticopt.analysis import verify as closed_loop_verify
from hapticopt.optim.cli.common import load_design_arg, one_line_errors
import numpy as np
from hapticopt.design.atomic import atomic_path
from hapticopt.analysis.prrr import zwidth
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.scene import Backend, StabilityCriterion, load_scene
from hapticopt.design.errors import InvalidInput
from hapticopt.design.paths import check_name, inside, writable_dir


def _plot(result: Any, out_dir: Path, name: str) -> list[Path]:
    """Position and hand force over time (matplotlib if installed; otherwise nothing)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []


    tr = result.traces
    if tr is None or tr.position is None:
        return []
    t = np.arange(tr.position.shape[0]) * tr.period
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
    for i, lab in enumerate("xyz"):
        a1.plot(t, tr.position[:, 0, i] * 1e3, label=lab)
        a2.plot(t, tr.hand_force[:, 0, i], label=lab)
    a1.set_ylabel("p [mm]")
    a2.set_ylabel("hand force [N]")
    a2.set_xlabel("t [s]")
    a1.legend()
    target = inside(out_dir, f"verify-{check_name(name, 'scene name')}.png")
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    return [target]


@one_line_errors
def verify(
    file: Annotated[Optional[Path], typer.Argument(help="Design TOML file (or use --preset).", show_default=False)] = None,
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name.")] = None,
    scene: Annotated[Optional[str], typer.Option("--scene", help="Bundled scene name (free-space, stiffness-25, stiffness-25-links, virtual-box, z-width; master-transparency, master-wall) or a .toml path [default: stiffness-25, master-wall for a master].", show_default=False)] = None,
    backend: Annotated[str, typer.Option("--backend", help="auto (the scene resolver picks), lumped or multibody.")] = "auto",
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a design TOML key (repeatable).")] = None,
    fidelity: Annotated[str, typer.Option("--fidelity", help="draft, standard or fine.")] = "standard",
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON {design, scene, metrics, status, message}.")] = False,
    plots: Annotated[Optional[Path], typer.Option("--plots", help="Write pictures of the run to this directory.")] = None,
) -> None:
    """Simulate the design in closed loop with the firmware controller in a scene."""

    try:
        level = Fidelity(fidelity)
    except ValueError:
        raise InvalidInput(f"--fidelity = {fidelity!r} is not a fidelity level: allowed draft, standard, fine") from None
    if backend not in ("auto", "lumped", "multibody"):
        raise InvalidInput(f"--backend = {backend!r} is not a backend: allowed auto, lumped, multibody")
    force = None if backend == "auto" else Backend(backend)
    design = load_design_arg(file, preset, set_)
    device = "master" if design.device == "master" else "prrr"
    sc = load_scene(scene or ("master-wall" if device == "master" else "stiffness-25"))
    if sc.device != device:
        raise InvalidInput(f"--scene {sc.name} is written for the {sc.device} device; design {design.name!r} is a "
                           f"{design.device}: pick a {device} scene")
    if plots is not None:
        writable_dir(plots, "--plots")
    result = closed_loop_verify.simulate(design, sc, fidelity=level, backend=force)
    metrics = result.metrics()
    metrics["resolution_reason"] = metrics.get("backend_reason", "")
    metrics["notes"] = list(result.notes)
    if sc.stability == StabilityCriterion.DECAY and metrics["backend"] == "lumped":  # also map its Z-width
        metrics.update(zwidth.zwidth_map(design, sc, fidelity=level).metrics())
    written = _plot(result, plots, sc.name) if plots is not None else []
    if as_json:
        typer.echo(json.dumps({"design": design.name, "scene": sc.name, "metrics": metrics,
                               "status": str(result.status), "message": result.message,
                               "plots": [str(p) for p in written]}, indent=2))
        return
    for k, v in metrics.items():
        if k.startswith("zwidth_stable") and isinstance(v, list):
            continue
        typer.echo(f"{k:32s} {v}")
    typer.echo(f"status: {result.status}" + (f" — {result.message}" if result.message else ""))
    for p in written:
        typer.echo(f"wrote {p}")

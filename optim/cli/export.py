"""``hapticopt export``: STEP, STL, MJCF, mass properties and a picture of a design."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from hapticopt.optim.cli.common import load_design_arg, one_line_errors
import math
import numpy as np
from hapticopt.design.errors import InvalidInput
from hapticopt.design.paths import writable_dir
from hapticopt.analysis import interference


def parse_pose_mm(text: str):
    """``"X,Y,Z"`` in mm -> (3,) array [m]; raises :class:`InvalidInput`."""



    parts = [s.strip() for s in text.split(",")]
    try:
        values = [float(s) for s in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise InvalidInput(f"--pose = {text!r} must be three numbers X,Y,Z in mm, e.g. --pose 10,0,-20")
    return np.asarray(values) * 1e-3


@one_line_errors
def export(
    file: Annotated[Optional[Path], typer.Argument(help="Design TOML file (or use --preset).", show_default=False)] = None,
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name (see `hapticopt presets`).")] = None,
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a TOML key, e.g. --set structure.link_width_mm=16 (repeatable).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Output directory [default: cad_out/<design-name>/].")] = None,
    pose: Annotated[Optional[str], typer.Option("--pose", help="End-effector position X,Y,Z in mm [default: home].")] = None,
    render: Annotated[bool, typer.Option("--render", help="Also write <name>.png (pyvista, off-screen).")] = False,
) -> None:
    """Export the CAD of a design: DIR/<name>.step, DIR/parts/*.stl, DIR/<name>.xml, DIR/mass_properties.json."""
    t0 = time.perf_counter()
    design = load_design_arg(file, preset, set_)
    p = parse_pose_mm(pose) if pose is not None else None
    from hapticopt.design.export import export as run_export

    out_dir = writable_dir(out if out is not None else Path("cad_out") / design.name)
    result = run_export(design, out_dir, p=p, render=render)
    check = interference.check_pose(design, result_pose(design, p))
    for f in result.files:
        typer.echo(f"wrote {f}")
    typer.echo(f"total mass {result.total_mass_kg:.4g} kg; interference: "
               + ("none" if check.ok else check.message))
    typer.echo("timings_s: " + ", ".join(f"{k} {v:.2f}" for k, v in result.timings_s.items())
               + f", wall {time.perf_counter() - t0:.2f}")


def result_pose(design, p):
    if p is not None:
        return p
    from hapticopt.design.export import _cad

    return _cad(design).home_point(design)

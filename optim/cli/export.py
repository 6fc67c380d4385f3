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
from hapticopt.analysis.status import Status


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
    poses: Annotated[int, typer.Option("--poses", help="Check interference (manifold3d) at N workspace poses "
                                       "instead of only the exported pose (3-PRRR: the reach-and-stroke "
                                       "workspace samples).", min=0)] = 0,
) -> None:
    """Export the CAD of a design: DIR/<name>.step, DIR/parts/*.stl, DIR/<name>.xml, DIR/mass_properties.json."""
    t0 = time.perf_counter()
    from hapticopt.analysis import interference  # heavy (CAD, jax): imported when the command runs
    from hapticopt.design.export import export as run_export

    design = load_design_arg(file, preset, set_)
    p = parse_pose_mm(pose) if pose is not None else None

    out_dir = writable_dir(out if out is not None else Path("cad_out") / design.name)
    result = run_export(design, out_dir, p=p, render=render)
    where = "the home pose" if p is None else f"the pose ({pose}) mm"
    if poses > 0:
        message = _check_many(design, poses)
    else:
        check = interference.check_pose(design, result_pose(design, p))
        message = (f"none at {where}" if check.ok else f"{check.message} (at {where})") + \
            " — only this pose was checked; --poses N checks the workspace"
    for f in result.files:
        typer.echo(f"wrote {f}")
    typer.echo(f"total mass {result.total_mass_kg:.4g} kg; interference: {message}")
    typer.echo("timings_s: " + ", ".join(f"{k} {v:.2f}" for k, v in result.timings_s.items())
               + f", wall {time.perf_counter() - t0:.2f}")


def _check_many(design, n: int) -> str:
    """Interference (manifold3d) at about ``n`` workspace poses: one line naming how many collide."""
    from hapticopt.analysis import interference

    if design.device != "prrr":
        from hapticopt.design.master import cad as cad_master

        pts = np.atleast_2d(cad_master.home_point(design))
    else:
        from hapticopt.analysis.prrr.workspace import sample_points, workspace_params

        k = max(1, round((n / 3) ** (1 / 3)))  # 3·k_phi·k_r·k_z ≈ n
        pts = sample_points(workspace_params(design), n_phi=k, n_r=k, n_z=max(1, round(n / (3 * k * k))))
    res = interference.check_poses(design, pts)
    bad = [r for r in res if r.status == Status.FAILED]
    if not bad:
        return f"none at {len(res)} workspace poses"
    pairs = sorted({f"{a} × {b}" for r in bad for a, b in r.pairs})
    return f"{len(bad)} of {len(res)} workspace poses collide ({', '.join(pairs[:4])}{', …' if len(pairs) > 4 else ''})"


def result_pose(design, p):
    if p is not None:
        return p
    from hapticopt.design.export import _cad

    return _cad(design).home_point(design)

"""``hapticopt export``: STEP, STL, MJCF, mass properties and a picture of a design."""

from __future__ import annotations

import dataclasses
import hashlib

import contextlib
import time
from pathlib import Path
from typing import Annotated, Optional

import typer

from hapticopt.optim import strict_json

from hapticopt.optim.cli import render
from hapticopt.optim.cli.common import load_design_arg, one_line_errors
from hapticopt.optim.cli.progress import StageLine, make_progress
import math
import numpy as np
from hapticopt.design.errors import InvalidInput
from hapticopt.design import paths
from hapticopt.design import io
from hapticopt.design.paths import NAME_MAX, writable_dir
from hapticopt.optim.recorder import run_lock
from hapticopt.analysis.status import Status


#: most workspace poses ``--poses`` checks (each a manifold3d boolean of every part pair)
MAX_POSES = 1000


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


def exported_name(design, assignments: list[str]):
    """The design named after what is exported: with ``--set`` overrides (and no ``--set name=…``), its name
    plus ``-`` and the first 8 hex digits of the SHA-256 of its TOML without the name (the same design:
    the same name; ``prrr-paper-1a2b3c4d.step`` is not mistaken for the preset)."""
    if not assignments or any(a.split("=", 1)[0].strip() == "name" for a in assignments):
        return design
    digest = hashlib.sha256(io.dumps(dataclasses.replace(design, name="")).encode()).hexdigest()[:8]
    return dataclasses.replace(design, name=f"{design.name[:NAME_MAX - 9]}-{digest}")


@one_line_errors
def export(
    file: Annotated[Optional[Path], typer.Argument(help="Design TOML file (or use --preset).", show_default=False)] = None,
    preset: Annotated[Optional[str], typer.Option("--preset", help="Bundled preset name (see `hapticopt presets`).")] = None,
    set_: Annotated[Optional[list[str]], typer.Option("--set", help="Override a TOML key, e.g. --set structure.link_width_mm=16 (repeatable).")] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Output directory [default: cad_out/<design-name>/].")] = None,
    pose: Annotated[Optional[str], typer.Option("--pose", help="End-effector position X,Y,Z in mm [default: home].")] = None,
    render_png: Annotated[bool, typer.Option("--render", help="Also write <name>.png (pyvista, off-screen).")] = False,
    drawings_2d: Annotated[bool, typer.Option("--drawings", help="Also write DIR/drawings/<part>.svg|dxf: a "
                                              "dimensioned drawing per manufactured part (slow: ~20 s a part).")] = False,
    poses: Annotated[int, typer.Option("--poses", help="Check interference (manifold3d) at N workspace poses "
                                       "instead of only the exported pose (3-PRRR: the reach-and-stroke "
                                       "workspace samples; 0 to 1000).")] = 0,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON {design, device, out_dir, files, total_mass_kg, "
                                                         "interference, timings_s}.")] = False,
) -> None:
    """Export the CAD of a design: DIR/<name>.step, DIR/parts/*.stl, DIR/<name>.xml, DIR/mass_properties.json, and
    with --drawings DIR/drawings/*.svg|dxf (a dimensioned drawing per manufactured part)."""
    t0 = time.perf_counter()
    from hapticopt.analysis import interference  # heavy (CAD, jax): imported when the command runs
    from hapticopt.design.export import export as run_export

    if not 0 <= poses <= MAX_POSES:
        raise InvalidInput(f"--poses = {poses} is out of range: allowed 0 ≤ --poses ≤ {MAX_POSES} (poses)")
    design = exported_name(load_design_arg(file, preset, set_), set_ or [])
    p = parse_pose_mm(pose) if pose is not None else None

    target = out if out is not None else Path("cad_out") / design.name
    existed = target.is_dir()  # an existing folder may hold another export: one writer at a time
    out_dir = writable_dir(target)
    err = render.console(stderr=True)
    with paths.output_root(out_dir), run_lock(out_dir) if existed else contextlib.nullcontext(), make_progress(err, transient=True, disable=as_json or not err.is_terminal) as bar:
        line = StageLine(bar, "export")
        limits = None
        if design.device == "prrr":  # the MJCF's R-joint ranges from the joint-limits evaluator (fine: parts' stops)
            from hapticopt.analysis.prrr.loop.mujoco_model import export_joint_limits
            limits = export_joint_limits(design)
        result = run_export(design, out_dir, p=p, render=render_png, drawings_2d=drawings_2d, on_step=line.step,
                            joint_limits=limits)
        where = "the home pose" if p is None else f"the pose ({pose}) mm"
        line.stage("check", 1, f"interference at {poses} workspace poses" if poses > 0 else f"interference at {where}")
        if poses > 0:
            message = _check_many(design, poses)
        else:
            check = interference.check_pose(design, result_pose(design, p))
            message = (f"none at {where}" if check.ok else f"{check.message} (at {where})") + \
                " — only this pose was checked; --poses N checks the workspace"
    wall = time.perf_counter() - t0
    if as_json:
        typer.echo(strict_json.dumps({"design": design.name, "device": design.device, "out_dir": str(out_dir),
                               "files": [str(f) for f in result.files], "total_mass_kg": result.total_mass_kg,
                               "interference": message, "timings_s": {**result.timings_s, "wall": wall}}, indent=2))
        return
    stl = [f for f in result.files if f.suffix == ".stl"]
    others = [f for f in result.files if f.suffix != ".stl"]
    for f in others:
        typer.echo(f"wrote {f}")
    if stl:
        typer.echo(f"wrote {len(stl)} part STLs in {stl[0].parent}")
    typer.echo(f"total mass {render.number(result.total_mass_kg)} kg; interference: {message}")
    typer.echo(f"time: {render.number(wall, 3)} s (" + ", ".join(
        f"{k} {render.number(v, 2)} s" for k, v in result.timings_s.items() if k != "total") + ")")


def _check_many(design, n: int) -> str:
    """Interference (manifold3d) at about ``n`` workspace poses: one line naming how many collide."""
    from hapticopt.analysis import interference

    if design.device != "prrr":
        from hapticopt.design.master import cad as cad_master

        pts = np.atleast_2d(cad_master.home_point(design))
        why = f"{len(pts)} checked of the {n} asked: the {design.device} export checks its home pose only"
    else:
        from hapticopt.analysis.prrr.geometry.workspace import sample_points, workspace_params

        k = max(1, round((n / 3) ** (1 / 3)))  # 3·k_phi·k_r·k_z ≈ n
        kz = max(1, round(n / (3 * k * k)))
        pts = sample_points(workspace_params(design), n_phi=k, n_r=k, n_z=kz)
        why = (f"{len(pts)} checked of the {n} asked: the workspace samples form a grid of 3 × {k} angles × {k} radii × {kz} "
               "heights, the nearest to the number asked" if len(pts) != n else "")
    res = interference.check_poses(design, pts)
    bad = [r for r in res if r.status == Status.COLLIDES]
    note = f" ({why})" if why else ""
    if not bad:
        return f"none at {len(res)} workspace poses{note}"
    pairs = sorted({f"{a} × {b}" for r in bad for a, b in r.pairs})
    return (f"{len(bad)} of {len(res)} workspace poses collide ({', '.join(pairs[:4])}"
            f"{', …' if len(pairs) > 4 else ''}){note}")


def result_pose(design, p):
    if p is not None:
        return p
    from hapticopt.design.export import _cad

    return _cad(design).home_point(design)

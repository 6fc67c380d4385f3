"""Export a design's CAD: STEP assembly, per-part STL, MJCF, mass properties, optional picture.

Writes into ``out_dir``::

    <name>.step            one flat assembly of the posed parts, each solid named after its part
    parts/<part>.stl       every posed part, mm, binary STL
    <name>.xml             MJCF (inertias from the CAD)
    mass_properties.json   per part and per body, CAD volume integrals (SI values in mm/kg units)
    drawings/<part>.svg    a dimensioned 2-D drawing per manufactured part (and .dxf; design.drawings):
                           parts that name a material, the legs' identical copies on one drawing
    <name>.png             with ``render=True``: off-screen pyvista picture

Everything is computed in memory first (a design that cannot be built raises before any file
is touched); the files are then written into a staging folder and moved in together
(:func:`design.atomic.file_set`), so a failure (a full disk, a writer that fails) leaves the
previous export set as it was and no partial set behind.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hapticopt.design import atomic, cad_import, drawings, offscreen
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.paths import check_name, inside
from hapticopt.design import mass_properties as mp
from hapticopt.design.master import cad as cad_master
from hapticopt.design.master import mjcf as mjcf_master
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.prrr import mjcf as mjcf_prrr


@dataclass(frozen=True, kw_only=True)
class ExportResult:
    out_dir: Path
    files: tuple[Path, ...]
    timings_s: dict[str, float]
    total_mass_kg: float


def _cad(design: Any):
    cads = {"prrr": cad_prrr, "master": cad_master}
    if design.device not in cads:
        raise InvalidDesign(f"device = {design.device!r} of design {design.name!r} has no CAD model to export: "
                            f"allowed {', '.join(cads)}")
    return cads[design.device]


def _mjcf(design: Any, p, masses, joint_limits: Any = None) -> str:
    if design.device == "prrr":
        # the drivable model (SEA motors with ξ and η, stroke, force and R-joint limits, R-joint friction,
        # CAD geoms and contacts), built at home with a keyframe "pose" at p
        return mjcf_prrr.prrr_mjcf(design, mjcf_prrr.export_options(joint_limits), mass_properties=masses,
                                   pose=None if p is None else p)
    # the master's MJCF carries the mass model that evaluate and verify use (design.master.mass:
    # the design's link, counterweight and handle data), not the CAD solids'
    return mjcf_master.master_mjcf(design)


#: the steps of :func:`export`, in order (``on_step(step, done, total)`` names them)
STEPS = ("cad", "mass properties + MJCF", "STEP", "STL", "drawings", "render")


def export(design: Any, out_dir: str | Path, *, p=None, render: bool = False, drawings_2d: bool = False,
           on_step: Callable[[str, int, int], None] | None = None, joint_limits: Any = None) -> ExportResult:
    """Write the export set of ``design`` posed at end-effector position ``p`` [m] into ``out_dir``.

    ``drawings_2d``: also the dimensioned drawings (SVG + DXF per manufactured part). Off unless asked:
    build123d's hidden-line projection and its SVG/DXF writers take 5–35 s per part (≈ 100 s for the
    3-PRRR's five drawings, four times the rest of the export), which the optimiser's export and a
    quick look at the CAD should not pay.

    ``joint_limits``: the 3-PRRR's R-joint ranges for its MJCF (:class:`hapticopt.design.prrr.mjcf.RJointLimits`,
    from the joint-limits evaluator: ``hapticopt.analysis.prrr.loop.mujoco_model.export_joint_limits``; None:
    the R joints unlimited).

    ``on_step(step, done, total)`` is called before each step of :data:`STEPS` (the render only
    with ``render``) and once at the end with ``('', total, total)``.
    """
    steps = tuple(s for s in STEPS if (s != "render" or render) and (s != "drawings" or drawings_2d))

    def step(name: str) -> None:
        if on_step is not None:
            on_step(name, steps.index(name) if name else len(steps), len(steps))

    step("cad")  # importing build123d (OpenCASCADE) is part of it: seconds in a cold process
    cad_import.build123d()  # imported without scikit-learn (0.55 s)
    from build123d import Compound, export_step, export_stl

    out_dir = Path(out_dir)
    # every target is named and checked before anything is built or written
    check_name(design.name, "design name", error=InvalidDesign)
    step_path = inside(out_dir, f"{design.name}.step")
    xml_path = inside(out_dir, f"{design.name}.xml")
    json_path = inside(out_dir, "mass_properties.json")
    png_path = inside(out_dir, f"{design.name}.png")
    cad = _cad(design)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    specs = cad.part_specs(design)
    p = cad.home_point(design) if p is None else np.asarray(p, dtype=float)
    pose = cad.solve_pose(design, p)
    frames = cad.part_frames(design, pose)
    solids = cad.build_parts(design)
    placed = cad.posed(solids, frames)
    timings["cad"] = time.perf_counter() - t0
    t = time.perf_counter()
    step("mass properties + MJCF")
    masses = mp.from_cad(design, solids=solids, specs=specs)
    mjcf = _mjcf(design, p, masses, joint_limits)
    timings["mass_properties+mjcf"] = time.perf_counter() - t
    # the set is written into a staging folder and moved in at the end (design.atomic.file_set):
    # a full disk or a failing writer leaves the previous export as it was
    files: list[Path] = []
    with atomic.file_set(out_dir) as stage:
        def staged(target: Path) -> Path:
            return stage / target.relative_to(out_dir)

        t = time.perf_counter()
        step("STEP")
        assembly = Compound(children=list(placed.values()), label=design.name)
        with atomic.atomic_path(staged(step_path)) as tmp:
            export_step(assembly, tmp)
        files.append(step_path)
        timings["step"] = time.perf_counter() - t
        t = time.perf_counter()
        step("STL")
        for name, solid in placed.items():
            target = inside(out_dir, Path("parts") / f"{name}.stl")
            with atomic.atomic_path(staged(target)) as tmp:
                export_stl(solid, tmp, tolerance=0.01, angular_tolerance=0.1)
            files.append(target)
        timings["stl"] = time.perf_counter() - t
        if drawings_2d:
            t = time.perf_counter()
            step("drawings")
            for name, parts in drawings.groups(specs).items():
                svg, dxf = (inside(out_dir, Path("drawings") / f"{name}.{ext}") for ext in ("svg", "dxf"))
                spec = specs[parts[0]]
                mass = spec.density * solids[parts[0]].volume * 1e-9  # the CAD solid is in mm
                with atomic.atomic_path(staged(svg)) as tmp_svg, atomic.atomic_path(staged(dxf)) as tmp_dxf:
                    drawings.draw(solids[parts[0]], name, parts, spec.material, mass, Path(tmp_svg), Path(tmp_dxf))
                files += [svg, dxf]
            timings["drawings"] = time.perf_counter() - t
        atomic.write_text(staged(xml_path), mjcf)
        files.append(xml_path)
        atomic.write_text(staged(json_path), masses.to_json())
        files.append(json_path)
        if render:
            t = time.perf_counter()
            step("render")
            render_png([staged(f) for f in files if f.suffix == ".stl"], staged(png_path), title=design.name)
            files.append(png_path)
            timings["render"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t0
    step("")
    return ExportResult(out_dir=out_dir, files=tuple(files), timings_s=timings, total_mass_kg=masses.total_mass)


def render_png(stl_files: list[Path], target: Path, *, title: str = "") -> None:
    """Off-screen pyvista picture of the given STL parts, written atomically."""
    offscreen.configure()  # before the first render window: no X probe, no VTK warning
    import pyvista as pv

    plotter = pv.Plotter(off_screen=True, window_size=(1024, 768))
    colours = ["#8c9bab", "#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#ccb974"]
    for k, f in enumerate(sorted(stl_files)):
        plotter.add_mesh(pv.read(str(f)), color=colours[k % len(colours)], smooth_shading=True)
    if title:
        plotter.add_text(title, font_size=12)
    plotter.camera_position = "iso"
    plotter.camera.elevation = 15
    with atomic.atomic_path(target) as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()


def mass_properties(design: Any, *, method: mp.Method = mp.Method.ANALYTIC) -> mp.MassProperties:
    """Mass properties of any device's parts: closed forms (default) or the CAD's volume integrals."""
    return _cad(design).mass_properties(design, method=method)

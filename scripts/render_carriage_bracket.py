"""Render docs/img/prrr_carriage_bracket.png: prrr-paper's carriage 1 with its R1 bracket and link1
at the home pose, two views (off-screen pyvista, manifold3d meshes of the part tables).

The bracket (arm and root plate) lies in the clevis layer; link1 lies in the next layer along the
R1 axis (docs/cad.md, "R1 bracket").

    .venv/bin/python scripts/render_carriage_bracket.py [OUT.png]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from hapticopt.design import io, offscreen, parts
from hapticopt.design.prrr import cad

ROOT = Path(__file__).resolve().parents[1]
COLOURS = {"carriage_1": "#dd8452", "link1_1": "#4c72b0"}


def _polydata(spec, T):
    import pyvista as pv

    M = np.zeros((3, 4))
    M[:, :3] = T[:3, :3]
    M[:, 3] = T[:3, 3] * 1e3  # manifold meshes are in mm
    mesh = parts.manifold_of(spec).transform(M).to_mesh()
    v = np.asarray(mesh.vert_properties)[:, :3]
    f = np.asarray(mesh.tri_verts)
    return pv.PolyData(v, np.hstack([np.full((len(f), 1), 3), f]).ravel())


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "docs" / "img" / "prrr_carriage_bracket.png"
    offscreen.configure()
    import pyvista as pv

    design = io.load_preset("prrr-paper")
    specs = cad.part_specs(design)
    frames = cad.part_frames(design, cad.solve_pose(design, (0.0, 0.0, 0.0)))
    meshes = {name: _polydata(specs[name], frames[name]) for name in COLOURS}
    b = cad.carriage_bracket(design)
    Tc = frames["carriage_1"]
    focus = (Tc[:3, :3] @ b.root_centre + Tc[:3, 3]) * 1e3
    e_l, N, ez = Tc[:3, :3] @ b.e_l, Tc[:3, :3] @ b.normal, np.array([0.0, 0.0, 1.0])
    # left: from outside the side face, above; right: along the arm (e_l), the clevis and link1 layers
    # seen edge-on (the bracket stays in the lower one)
    views = ((focus + 170.0 * (N - 0.6 * e_l + 0.7 * ez), ez), (focus - 170.0 * e_l + 20.0 * ez, ez))
    plotter = pv.Plotter(off_screen=True, shape=(1, 2), window_size=(1400, 700))
    for col, (eye, up) in enumerate(views):
        plotter.subplot(0, col)
        for name, mesh in meshes.items():
            plotter.add_mesh(mesh, color=COLOURS[name], show_edges=False, smooth_shading=False,
                             opacity=0.75 if name == "link1_1" else 1.0)
        plotter.add_axes()
        plotter.camera_position = [tuple(eye), tuple(focus), tuple(up)]
        plotter.camera.view_angle = 35.0
    plotter.add_text("carriage 1 (orange) with link1 (blue), home pose", font_size=10)
    plotter.screenshot(str(out))
    plotter.close()
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

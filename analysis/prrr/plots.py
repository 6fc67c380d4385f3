"""Pictures of the 3-PRRR's evaluator results (pyvista off screen for 3-D fields, matplotlib for
line drawings). Only ``--plots`` and the pipeline's report call these, through the registry;
evaluators never draw. Every axis and colour bar names its quantity and unit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hapticopt.analysis.prrr.structure import frame_model as fm
from hapticopt.analysis.prrr.geometry import workspace as W
from hapticopt.analysis.prrr.structure.stiffness import fea_element_stress
from hapticopt.design.atomic import atomic_path
from hapticopt.design.prrr.params import PrrrDesign


#: a vertical colour bar at the right edge, clear of the bounding-box axes (pyvista scalar_bar_args)
SCALAR_BAR = {"vertical": True, "position_x": 0.86, "position_y": 0.2, "width": 0.06, "height": 0.6,
              "title_font_size": 14, "label_font_size": 12, "n_labels": 5}


def mm_bounds(pl) -> None:
    """Bounding-box axes in whole millimetres, four labels each, on the outer edges (no overlap at a
    shared corner)."""
    pl.show_bounds(xtitle="x [mm]", ytitle="y [mm]", ztitle="z [mm]", n_xlabels=4, n_ylabels=4, n_zlabels=4,
                   fmt="%.0f", location="outer", font_size=10, bold=False)


def workspace_plots(design: PrrrDesign, result, out_dir: Path) -> list[Path]:
    """Off-screen pyvista picture of sampled workspace points and the inscribed cylinder."""
    import pyvista as pv

    pts = W.sample_points(W.workspace_params(design), n_phi=40, n_r=12, n_z=6)
    target = Path(out_dir) / f"{design.name}_workspace.png"
    pl = pv.Plotter(off_screen=True, window_size=(1000, 700))
    if len(pts):
        pl.add_points(pv.PolyData(pts * 1e3), scalars=pts[:, 2] * 1e3, point_size=5, opacity=0.5,
                      render_points_as_spheres=True,
                      scalar_bar_args={"title": "height z [mm]", "fmt": "%.0f", **SCALAR_BAR})
    if result.cylinder_diameter > 0:
        z0, z1 = W.cylinder_z_range(design, result)
        cyl = pv.Cylinder(center=(0.0, 0.0, (z0 + z1) * 500.0), direction=(0.0, 0.0, 1.0),
                          radius=result.cylinder_diameter * 500.0, height=(z1 - z0) * 1e3, resolution=96)
        pl.add_mesh(cyl, color="orange", opacity=0.55, label="inscribed cylinder")
    pl.add_axes()
    mm_bounds(pl)
    pl.add_text(f"{design.name}: workspace points (colour: height z), V = {result.volume * 1e9:.4g} mm³;\n"
                f"inscribed cylinder (orange) {result.cylinder_diameter * 1e3:.1f} mm diameter × "
                f"{result.cylinder_height * 1e3:.1f} mm", font_size=10)
    pl.camera.zoom(0.85)
    with atomic_path(target) as tmp:
        pl.screenshot(str(tmp))
    pl.close()
    return [target]


# ----------------------------------------------------------------------------- plots
def structure_plots(design: PrrrDesign, result, out_dir: Path) -> list[Path]:
    """PNG of the deformed frame under a lateral load; at fine fidelity also the FEA field."""
    import pyvista as pv

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    opts = result.options
    full = fm.solve_frame(fm.frame_params_of(design), p=result.pose, load_height=result.load_height, options=opts)
    h = result.load_height
    H = np.concatenate([np.eye(3), -np.array([[0, -h, 0], [h, 0, 0], [0, 0, 0]])], axis=1)
    wrench = H.T @ np.array([1.0, 0.0, 0.0])  # 1 N along x at the load point
    uP = full["compliance_ee"] @ wrench
    nodes, maps, rec = full["nodes"], full["node_maps"], full["recovery"]
    span = float(np.ptp(nodes.reshape(-1, 3), axis=0).max())
    scale = 0.1 * span / max(float(np.abs(uP[:3]).max()), 1e-30)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, side) = plt.subplots(1, 2, figsize=(10.5, 5.0), constrained_layout=True)
    for i in range(3):
        x_leg = np.concatenate([uP, -rec[i] @ uP])
        u_nodes = np.einsum("kij,j->ki", maps[i], x_leg)[:, :3]
        pts = np.vstack([nodes[i], result.pose[None]]) * 1e3
        upts = np.vstack([u_nodes, uP[None, :3]]) * 1e3
        for ax, (a, b) in ((top, (0, 1)), (side, (0, 2))):
            ax.plot(pts[:, a], pts[:, b], color="0.6", lw=2.5, label="undeformed" if i == 0 else None)
            d = pts + scale * upts
            ax.plot(d[:, a], d[:, b], color="crimson", lw=1.8,
                    label=f"deformed, displacement × {scale:.3g}" if i == 0 else None)
    p_mm = result.pose * 1e3
    for ax, (a, b), title in ((top, (0, 1), "top view (x–y)"), (side, (0, 2), "side view (x–z)")):
        ax.plot(p_mm[a], p_mm[b], "k^", ms=7, label="load point (1 N along x)")
        ax.annotate("", xy=(p_mm[a] + 0.08 * span * 1e3, p_mm[b]), xytext=(p_mm[a], p_mm[b]),
                    arrowprops={"arrowstyle": "->", "color": "k"})
        ax.set_xlabel(f"{'xyz'[a]} [mm]")
        ax.set_ylabel(f"{'xyz'[b]} [mm]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, alpha=0.3)
        ax.set_title(title, fontsize=10)
    top.legend(loc="best", fontsize=8)
    fig.suptitle(f"{design.name}: frame under 1 N along x at Δz = {h * 1e3:g} mm; load-point displacement "
                 f"{np.linalg.norm(uP[:3]) * 1e6:.3g} µm/N (drawn × {scale:.3g})", fontsize=10)
    target = out_dir / "structure_frame.png"
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    written.append(target)

    def save(plotter, name):
        target = out_dir / name
        with atomic_path(target) as tmp:
            plotter.screenshot(str(tmp))
        plotter.close()
        written.append(target)

    fea_res = getattr(result, "fea", None)
    if fea_res is not None and fea_res.mesh is not None and fea_res.displacement is not None:
        mesh = fea_res.mesh
        cells = np.hstack([np.full((mesh.tets.shape[1], 1), 4), mesh.tets.T]).ravel()
        grid = pv.UnstructuredGrid(cells, np.full(mesh.tets.shape[1], pv.CellType.TETRA), mesh.points.T * 1e3)  # [mm]
        grid.point_data["|u| per N [um/N]"] = np.linalg.norm(fea_res.displacement, axis=0) * 1e6
        grid.point_data["u"] = fea_res.displacement.T
        sc = 0.1 * span / max(float(np.abs(fea_res.displacement).max()), 1e-30)
        warped = grid.warp_by_vector("u", factor=sc * 1e3)  # u [m] on points in mm
        pl = pv.Plotter(off_screen=True, window_size=(900, 700))
        pl.add_mesh(warped, scalars="|u| per N [um/N]", show_edges=False,
                    scalar_bar_args={"title": "|u| per N [um/N]", "fmt": "%.3g", **SCALAR_BAR})
        mm_bounds(pl)
        pl.add_text(f"CAD FEA (bonded pins), 1 N along x at Δz = {h * 1e3:g} mm (×{sc:.3g})", font_size=10)
        save(pl, "structure_fea.png")
        st = getattr(result, "fea_stress", None)  # computed by the evaluator at fine fidelity
        if st is None:
            st = fea_element_stress(design, fea_res)
        if st is not None:  # von Mises from the P2 field (hapticopt.analysis.fem.stress), per element
            grid.cell_data["von_mises_MPa_per_N"] = st.von_mises * 1e-6
            warped = grid.warp_by_vector("u", factor=sc * 1e3)
            pl = pv.Plotter(off_screen=True, window_size=(900, 700))
            # the peak sits in a few pin elements: colours up to the 99th percentile, above in magenta
            top = float(np.percentile(st.von_mises, 99.0)) * 1e-6
            pl.add_mesh(warped, scalars="von_mises_MPa_per_N", preference="cell", show_edges=False,
                        clim=(0.0, top), above_color="magenta",
                        scalar_bar_args={"title": "von Mises per N [MPa/N]", "above_label": "> 99 %",
                                         "fmt": "%.3g", **SCALAR_BAR})
            mm_bounds(pl)
            pl.add_point_labels(warped.cell_centers().points[st.max_element][None], ["max"], point_size=12,
                                point_color="black", render_points_as_spheres=True, always_visible=True)
            xm = st.max_location * 1e3
            pl.add_text(f"CAD FEA von Mises stress, 1 N along x at Δz = {h * 1e3:g} mm (×{sc:.3g})\n"
                        f"max {st.max_von_mises * 1e-6:.3g} MPa/N (element centroid) at "
                        f"({xm[0]:.1f}, {xm[1]:.1f}, {xm[2]:.1f}) mm", font_size=10)
            save(pl, "structure_fea_stress.png")
    return written


def design_map_plots(dmap, out_dir: Path) -> list[Path]:
    """The firmware design map (:class:`hapticopt.analysis.prrr.loop.design_map.DesignMap`): three panels over
    (T, K_p) — the free-space residual, the K limit on the scene's axis and the force-loop bandwidth —
    with the simulated unstable points crossed out and the paper's K_p = 45 marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    T_ms = np.asarray(dmap.periods) * 1e3
    kp = np.asarray(dmap.force_gains, dtype=float)
    ax_name = "xyz"[dmap.axis]
    panels = (
        (dmap.residual, f"free-space residual ({dmap.scene}) [N]", True),
        (np.where(np.isfinite(dmap.stiffness_limit) & (dmap.stiffness_limit > 0), dmap.stiffness_limit * 1e-3, np.nan),
         f"K_{ax_name} limit, exact sampled analysis [N/mm] (blank: force loop lost)", False),
        (dmap.bandwidth, "force-loop bandwidth (locked, sampled) [Hz]", True),
    )
    fig, axes = plt.subplots(1, 3, figsize=(16, 5), constrained_layout=True)
    kp_plot = np.where(kp > 0, kp, np.nan)
    positive = kp > 0
    for ax, (data, title, log) in zip(axes, panels):
        Z = np.asarray(data, dtype=float)[:, positive]
        finite = Z[np.isfinite(Z) & (Z > 0)]
        norm = LogNorm(finite.min(), finite.max()) if log and finite.size and finite.min() < finite.max() else None
        mesh = ax.pcolormesh(kp_plot[positive], T_ms, np.ma.masked_invalid(Z), shading="nearest", norm=norm,
                             cmap="viridis")
        fig.colorbar(mesh, ax=ax, label=title.split(" (blank")[0])
        bad = ~np.asarray(dmap.stable)[:, positive]
        KK, TT = np.meshgrid(kp_plot[positive], T_ms)
        ax.scatter(KK[bad], TT[bad], marker="x", color="red", s=30, label="simulated unstable")
        ax.axvline(45.0, color="white", ls="--", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("force-loop gain K_p [-]")
        ax.set_ylabel("controller period T [ms]")
        ax.set_title(title, fontsize=10)
    axes[0].legend(loc="lower left", fontsize=8)
    fig.suptitle(f"design map of the firmware: {dmap.scene} (dashed: K_p = 45 of seed 002's identification)")
    target = Path(out_dir) / f"design-map-{dmap.scene}.png"
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
    return [target]

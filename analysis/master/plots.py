"""Pictures of the master's workspace (pyvista off screen, 3-D), balance, transparency and
counterweight trade-off (matplotlib: labelled axes with units, log frequency axes in Hz, twin axes
where units differ; matplotlib comes with pyvista). Only ``--plots`` and the pipeline's report
call these, through the registry; evaluators never draw.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hapticopt.analysis.master import balance as mb
from hapticopt.analysis.master import transparency as mt
from hapticopt.analysis.master import workspace as mw
from hapticopt.design.atomic import atomic_path
from hapticopt.design.master import kinematics as mk
from hapticopt.design.units import GRAVITY


def _save(plotter, target: Path) -> Path:
    with atomic_path(target) as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()
    return target


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save_fig(fig, target: Path) -> Path:
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    _pyplot().close(fig)
    return target


def balance_plots(design, result, out_dir: Path) -> list[Path]:
    """Unbalance-force map over the workspace (x–z plane) and the admissible CoM region."""
    plt = _pyplot()
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    # --- force map: the design's own CoM offset, or the worst direction on the circle if balanced
    P = np.asarray(result.com_offset)
    label = "design CoM offset"
    if np.hypot(*P) < 1e-9 and result.radius > 0:
        P = result.radius * np.asarray(result.worst_direction)
        label = "CoM on the unbalance circle, worst direction"
    ws = mb.workspace_of(design)
    n = 60
    T3, PH = np.meshgrid(np.linspace(*ws.theta3, n), np.linspace(*ws.phi, n), indexing="ij")
    A = mb.unbalance_maps(design.geometry.upper_arm, design.geometry.forearm,
                          max(result.moving_mass, 0.0) * GRAVITY, T3, PH)
    F = np.linalg.norm(A @ P, axis=-1)
    t2 = 0.5 * np.pi + T3 - PH
    g = design.geometry
    x = g.upper_arm * np.cos(t2) + g.forearm * np.sin(T3)
    z = g.shoulder_height + g.upper_arm * np.sin(t2) - g.forearm * np.cos(T3)
    fig, ax = plt.subplots(figsize=(8.0, 5.5), constrained_layout=True)
    mesh = ax.pcolormesh(x * 1e3, z * 1e3, F, shading="gouraud", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label="unbalance force |F| [N]", shrink=0.8)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    ax.set_aspect("equal", adjustable="box")
    ax.set_title(f"{design.name}: unbalance force |F| = |J⁻ᵀG| over the workspace at θ1 = 0\n"
                 f"({label}); max {F.max():.3g} N", fontsize=9)
    written.append(_save_fig(fig, out_dir / f"{design.name}_unbalance_force_map.png"))
    # --- admissible CoM region with the unbalance circle and the paper-style ellipse
    psi = np.append(result.region_angles, result.region_angles[0])
    rr = np.append(result.region_radii, result.region_radii[0]) * 1e3
    fig, ax = plt.subplots(figsize=(6.5, 6.0), constrained_layout=True)
    ax.plot(rr * np.cos(psi), rr * np.sin(psi), color="b", lw=2.0, label="exact region (|F| ≤ 0.1 N)")
    c = np.linspace(0, 2 * np.pi, 200)
    r = result.radius * 1e3
    ax.plot(r * np.cos(c), r * np.sin(c), color="r", lw=2.0, label=f"unbalance circle, r = {r:.3g} mm")
    a, b = (v * 1e3 for v in result.ellipse_axes)
    if a > 0 and b > 0:
        ex = a * np.cos(c) / np.sqrt(2) + b * np.sin(c) / np.sqrt(2)
        ey = a * np.cos(c) / np.sqrt(2) - b * np.sin(c) / np.sqrt(2)
        ax.plot(ex, ey, color="orange", ls="--", label=f"45° ellipse fit ({100 * result.ellipse_overlap:.0f} % IoU)")
    ax.plot([result.com_offset[0] * 1e3], [result.com_offset[1] * 1e3], "ko", ms=6, label="design CoM offset")
    ax.set_xlabel("CoM offset P_x [mm]")
    ax.set_ylabel("CoM offset P_z [mm]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"{design.name}: admissible centre-of-mass offsets", fontsize=10)
    written.append(_save_fig(fig, out_dir / f"{design.name}_unbalance_region.png"))
    return written


def transparency_plots(design, result, out_dir: Path) -> list[Path]:
    """|G_T(f)| along x and z at the evaluated pose, with the ±3 dB band (log frequency axis in Hz)."""
    plt = _pyplot()
    out_dir.mkdir(parents=True, exist_ok=True)
    f = np.geomspace(0.05, 50.0, 300)
    G = np.abs(mt.transfer(result.coefficients, f, result.setup))[0]  # (2 axes, f)
    fig, ax = plt.subplots(figsize=(7.5, 4.5), constrained_layout=True)
    for k, (name, col) in enumerate((("x", "b"), ("z", "r"))):
        ax.semilogx(f, 20 * np.log10(G[k]), color=col, lw=2.0, label=f"{name}: bandwidth {result.bandwidth[k]:.3g} Hz")
        if np.isfinite(result.bandwidth[k]):
            ax.axvline(result.bandwidth[k], color=col, ls=":", lw=1.0)
    ax.axhspan(-3.0, 3.0, color="0.85", zorder=0, label="±3 dB band")
    ax.set_xlabel("frequency f [Hz]")
    ax.set_ylabel("transparency |G_T| [dB]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"{design.name}: transparency transfer function", fontsize=10)
    return [_save_fig(fig, out_dir / f"{design.name}_transparency.png")]


def sweep_plot(rows: list[dict], out: Path, *, boundary_mass: float | None = None) -> Path:
    """Seed 003's trade-off: bandwidth (x, z; left axis, Hz) and maximum unbalance force (right
    axis, N) against the total counterweight mass, the 0.1 N unbalance boundary marked (vertical
    line at ``boundary_mass`` [kg]) and the first sample whose CoM offset reaches the unbalance
    radius (dotted)."""
    plt = _pyplot()
    m = np.array([r["counterweight_mass_kg"] for r in rows]) * 1e3
    bx = np.array([r["transparency_bandwidth_x_Hz"] for r in rows])
    bz = np.array([r["transparency_bandwidth_z_Hz"] for r in rows])
    f = np.array([r["max_unbalance_force_N"] for r in rows])
    fig, ax = plt.subplots(figsize=(8.0, 5.0), constrained_layout=True)
    right = ax.twinx()
    lines = ax.plot(m, bx, color="b", lw=2.0, label="bandwidth x [Hz] (left)")
    lines += ax.plot(m, bz, color="r", lw=2.0, label="bandwidth z [Hz] (left)")
    lines += right.plot(m, f, color="k", lw=2.0, label="max unbalance force [N] (right)")
    lines.append(right.axhline(0.1, color="gray", ls="--", label="0.1 N (10 % JND) (right)"))
    if boundary_mass is not None:
        b = boundary_mass * 1e3
        lines.append(ax.axvline(b, color="orange", ls="--", label=f"unbalance boundary {b:.1f} g"))
    on = [r["counterweight_mass_kg"] * 1e3 for r in rows if r["com_offset_mm"] >= r["unbalance_radius_mm"]]
    if on:
        lines.append(ax.axvline(on[0], color="m", ls=":", label="CoM beyond the unbalance radius (to the left)"))
    ax.set_xlabel("total counterweight mass [g]")
    ax.set_ylabel("transparency bandwidth [Hz]")
    right.set_ylabel("max unbalance force [N]")
    right.set_ylim(bottom=0.0)
    ax.grid(True, alpha=0.3)
    ax.legend(handles=lines, loc="best", fontsize=8)
    ax.set_title("counterweight trade-off (seed 003)", fontsize=10)
    return _save_fig(fig, out)


def workspace_plots(design, result, out_dir: Path) -> list[Path]:
    """Off-screen pyvista picture: workspace points coloured by 1/κ₂, and the required box."""
    import pyvista as pv

    prm = mk.params_of(design)
    n = 14
    t1 = np.linspace(float(prm.theta1_min), float(prm.theta1_max), n)
    t3 = np.linspace(float(prm.theta3_min), float(prm.theta3_max), n)
    ph = np.linspace(float(prm.parallelogram_min), float(prm.parallelogram_max), n)
    T1, T3, PH = np.meshgrid(t1, t3, ph, indexing="ij")
    q = np.asarray(mk.q_from_theta3_phi(T1, T3, PH)).reshape(-1, 3)
    p = np.asarray(mk.forward_kinematics(prm, q)) * 1e3
    inv_kappa = 1.0 / mw.condition_field(design, q)
    target = Path(out_dir) / f"{design.name}_workspace.png"
    pl = pv.Plotter(off_screen=True, window_size=(1000, 700))
    # VTK's fonts have no Greek subscripts: the colour-bar title is plain ASCII
    pl.add_points(pv.PolyData(p), scalars=inv_kappa, point_size=5, render_points_as_spheres=True,
                  scalar_bar_args={"title": "1/cond(J) [-]", "fmt": "%.2f", "vertical": True, "position_x": 0.86,
                                   "position_y": 0.2, "width": 0.06, "height": 0.6, "title_font_size": 14,
                                   "label_font_size": 12, "n_labels": 5})
    if result.volume > 0:
        c = np.asarray(result.box_centre) * 1e3
        b = np.asarray(result.box) * 1e3
        bounds = [c[0] - b[0] / 2, c[0] + b[0] / 2, c[1] - b[1] / 2, c[1] + b[1] / 2, c[2] - b[2] / 2, c[2] + b[2] / 2]
        pl.add_mesh(pv.Box(bounds=bounds), style="wireframe", color="red", line_width=2)
    pl.add_axes()
    pl.show_bounds(xtitle="x [mm]", ytitle="y [mm]", ztitle="z [mm]", n_xlabels=4, n_ylabels=4, n_zlabels=4,
                   fmt="%.0f", location="outer", font_size=10, bold=False)
    pl.add_text(f"{design.name}: workspace points (colour: inverse condition number), required box (red);\n"
                f"coverage {result.coverage:.3f}, GCI {result.global_conditioning_index:.3f}", font_size=10)
    pl.camera.zoom(0.85)
    with atomic_path(target) as tmp:
        pl.screenshot(str(tmp))
    pl.close()
    return [target]

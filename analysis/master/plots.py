"""Pictures of the master's balance and transparency results (pyvista off-screen; no matplotlib,
which is not a dependency: pyvista's 2-D charts cover line plots and it is already installed).
Only ``--plots`` and the pipeline's report call these, through the registry; evaluators never draw.
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


def _chart_plotter(chart):
    import pyvista as pv

    pl = pv.Plotter(off_screen=True, window_size=(900, 700))
    pl.add_chart(chart)
    return pl


def balance_plots(design, result, out_dir: Path) -> list[Path]:
    """Unbalance-force map over the workspace (x–z plane) and the admissible CoM region."""
    import pyvista as pv

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
    grid = pv.StructuredGrid(x * 1e3, np.zeros_like(x), z * 1e3)
    grid["unbalance force [N]"] = F.ravel(order="F")
    pl = pv.Plotter(off_screen=True, window_size=(900, 700))
    pl.add_mesh(grid, scalars="unbalance force [N]", cmap="viridis")
    pl.view_xz()
    pl.show_bounds(xtitle="x [mm]", ztitle="z [mm]")
    pl.add_text(f"{design.name}: |F| = |J⁻ᵀG| at θ1 = 0 ({label}); max {F.max():.3g} N", font_size=10)
    written.append(_save(pl, out_dir / f"{design.name}_unbalance_force_map.png"))
    # --- admissible CoM region with the unbalance circle and the paper-style ellipse
    psi = np.append(result.region_angles, result.region_angles[0])
    rr = np.append(result.region_radii, result.region_radii[0]) * 1e3
    chart = pv.Chart2D(x_label="P_x [mm]", y_label="P_z [mm]")
    chart.line(rr * np.cos(psi), rr * np.sin(psi), color="b", width=2.0, label="exact region (|F| ≤ 0.1 N)")
    c = np.linspace(0, 2 * np.pi, 200)
    r = result.radius * 1e3
    chart.line(r * np.cos(c), r * np.sin(c), color="r", width=2.0, label=f"unbalance circle r = {r:.3g} mm")
    a, b = (x * 1e3 for x in result.ellipse_axes)
    if a > 0 and b > 0:
        ex = a * np.cos(c) / np.sqrt(2) + b * np.sin(c) / np.sqrt(2)
        ey = a * np.cos(c) / np.sqrt(2) - b * np.sin(c) / np.sqrt(2)
        chart.line(ex, ey, color="orange", style="--", label=f"45° ellipse fit ({100 * result.ellipse_overlap:.0f} % IoU)")
    chart.scatter([result.com_offset[0] * 1e3], [result.com_offset[1] * 1e3], color="k", size=10, label="design")
    written.append(_save(_chart_plotter(chart), out_dir / f"{design.name}_unbalance_region.png"))
    return written


def transparency_plots(design, result, out_dir: Path) -> list[Path]:
    """|G_T(f)| along x and z at the evaluated pose, with the ±3 dB band."""
    import pyvista as pv

    out_dir.mkdir(parents=True, exist_ok=True)
    f = np.geomspace(0.05, 50.0, 300)
    G = np.abs(mt.transfer(result.coefficients, f, result.setup))[0]  # (2 axes, f)
    chart = pv.Chart2D(x_label="f [Hz] (log10)", y_label="|G_T| [dB]")
    lf = np.log10(f)
    for k, (name, col) in enumerate((("x", "b"), ("z", "r"))):
        chart.line(lf, 20 * np.log10(G[k]), color=col, width=2.0,
                   label=f"{name}: bandwidth {result.bandwidth[k]:.3g} Hz")
    for level in (3.0, -3.0):
        chart.line(lf[[0, -1]], [level, level], color="gray", style="--")
    return [_save(_chart_plotter(chart), out_dir / f"{design.name}_transparency.png")]


def sweep_plot(rows: list[dict], out: Path, *, boundary_mass: float | None = None) -> Path:
    """Seed 003's trade-off: bandwidth (x, z) and maximum unbalance force against the total
    counterweight mass, the 0.1 N unbalance boundary marked (vertical line at ``boundary_mass`` [kg])
    and the first sample whose CoM offset reaches the unbalance radius (dotted)."""
    import pyvista as pv

    m = np.array([r["counterweight_mass_kg"] for r in rows]) * 1e3
    bx = np.array([r["transparency_bandwidth_x_Hz"] for r in rows])
    bz = np.array([r["transparency_bandwidth_z_Hz"] for r in rows])
    f = np.array([r["max_unbalance_force_N"] for r in rows])
    top = pv.Chart2D(x_label="total counterweight mass [g]", y_label="transparency bandwidth [Hz]")
    top.line(m, bx, color="b", width=2.0, label="bandwidth x")
    top.line(m, bz, color="r", width=2.0, label="bandwidth z")
    bot = pv.Chart2D(x_label="total counterweight mass [g]", y_label="max unbalance force [N]")
    bot.line(m, f, color="k", width=2.0, label="max unbalance force")
    bot.line([m.min(), m.max()], [0.1, 0.1], color="gray", style="--", label="0.1 N (10 % JND)")
    if boundary_mass is not None:
        b = boundary_mass * 1e3
        lo_b = min(bx.min(), bz.min())
        top.line([b, b], [0.95 * lo_b, 1.05 * max(bx.max(), bz.max())], color="orange", style="--",
                 label=f"unbalance boundary {b:.1f} g")
        bot.line([b, b], [0.0, f.max()], color="orange", style="--", label=f"unbalance boundary {b:.1f} g")
    on = [r["counterweight_mass_kg"] * 1e3 for r in rows if r["com_offset_mm"] >= r["unbalance_radius_mm"]]
    if on:
        top.line([on[0], on[0]], [0.95 * min(bx.min(), bz.min()), 1.05 * max(bx.max(), bz.max())], color="m",
                 style=":", label="CoM beyond the unbalance radius (to the left)")
    pl = pv.Plotter(off_screen=True, window_size=(900, 1000), shape=(2, 1))
    pl.subplot(0, 0)
    pl.add_chart(top)
    pl.subplot(1, 0)
    pl.add_chart(bot)
    return _save(pl, out)


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
    pl = pv.Plotter(off_screen=True, window_size=(900, 700))
    pl.add_points(pv.PolyData(p), scalars=inv_kappa, point_size=5, render_points_as_spheres=True,
                  scalar_bar_args={"title": "1/κ₂"})
    if result.volume > 0:
        c = np.asarray(result.box_centre) * 1e3
        b = np.asarray(result.box) * 1e3
        bounds = [c[0] - b[0] / 2, c[0] + b[0] / 2, c[1] - b[1] / 2, c[1] + b[1] / 2, c[2] - b[2] / 2, c[2] + b[2] / 2]
        pl.add_mesh(pv.Box(bounds=bounds), style="wireframe", color="red", line_width=2)
    pl.add_axes()
    pl.show_bounds(xtitle="x [mm]", ytitle="y [mm]", ztitle="z [mm]")
    pl.add_text(f"{design.name}: coverage {result.coverage:.3f}, GCI {result.global_conditioning_index:.3f}",
                font_size=10)
    with atomic_path(target) as tmp:
        pl.screenshot(str(tmp))
    pl.close()
    return [target]

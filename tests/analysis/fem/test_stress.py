"""Von Mises stress from the P2 field (hapticopt.analysis.fem.stress) and its picture in ``--plots``.

Reference: Euler–Bernoulli bending stress σ_xx = −M y / I, M = P (L − x), of the clamped
200 × 20 × 10 mm aluminium cantilever of tests/analysis/fem/test_solid.py under a unit tip shear
along y (bending about z: I = t b³ / 12, outer fibre c = b / 2).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hapticopt.analysis.prrr import plots as prrr_plots
from hapticopt.analysis.fem import solid as fea, stress as fea_stress

L, B, T, E, NU = 0.2, 0.02, 0.01, 68.9e9, 0.33  # as tests/analysis/fem/test_solid.py
I_Z, C = T * B**3 / 12.0, B / 2.0
SIZE = T / fea.REFINEMENT_RATIO  # 7.1 mm: ~900 tetrahedra, 6·10³ DOFs, ~2 s


@pytest.fixture(scope="module")
def cantilever():
    mesh = fea.cantilever_mesh(length=L, width=B, thickness=T, size=SIZE)

    loads = fea.tip_shear_loads(mesh, B * T)  # unit total force along +y

    sol = fea.solve_elasticity(mesh, youngs_modulus=E, poisson_ratio=NU, fixed="clamp", loads=loads)
    uv, ue = fea_stress.p2_nodal_values(sol.basis, sol.displacements[:, 0])
    st = fea_stress.element_stress(mesh.points, mesh.tets, uv, ue, youngs_modulus=E, poisson_ratio=NU)
    return mesh, sol, uv, ue, st


def test_bending_stress_at_mid_span_matches_beam_theory(cantilever):
    # centroid σ_xx of every element in 0.3 L < x < 0.7 L against −P (L − x) y / I, relative to the
    # outer-fibre value P (L − x) c / I. Tolerance 2 %: P2 stress is linear per element, the beam
    # stress bilinear (x·y), so the centroid value is exact only to O(h²) (measured 0.3 % at this
    # mesh, 0.8 % at 10 mm); the window keeps 3 widths from the clamp and the load (Saint-Venant).
    mesh, _, _, _, st = cantilever
    x, y = st.centroids[0], st.centroids[1]
    sel = (x > 0.3 * L) & (x < 0.7 * L)
    assert sel.sum() > 100
    beam = -(L - x) * y / I_Z
    err = (st.stress[:, 0, 0] - beam) / ((L - x) * C / I_Z)
    assert np.abs(err[sel]).max() < 0.02


def test_top_fibre_von_mises_at_mid_span_is_mc_over_i(cantilever):
    # at the outer fibres y = ±c the shear stress vanishes (free surface), so σ_vM = |σ_xx| = M c / I;
    # each element's vertex value there within 3 % (measured ≤ 1.1 %), their mean within 0.5 %
    mesh, _, _, _, st = cantilever
    vx, vy = mesh.points[0][mesh.tets], mesh.points[1][mesh.tets]  # (4, n_tets) at the vertices
    fibre = (np.abs(np.abs(vy) - C) < 1e-9) & (np.abs(vx - 0.5 * L) < 0.1 * L)
    assert fibre.sum() > 50
    ratio = st.von_mises_vertices[fibre] / ((L - vx[fibre]) * C / I_Z)
    assert np.abs(ratio - 1.0).max() < 0.03
    assert ratio.mean() == pytest.approx(1.0, abs=0.005)


def test_max_is_at_the_clamp_outer_fibre(cantilever):
    # M is largest at the clamp: the most stressed element touches it, at an outer fibre; its
    # centroid value is below the beam value at the clamp (centroid inside the element) and the
    # vertex peak above it (the clamp's corner singularity)
    _, _, _, _, st = cantilever
    assert st.max_von_mises == st.von_mises.max() == st.von_mises[st.max_element]
    np.testing.assert_array_equal(st.max_location, st.centroids[:, st.max_element])
    assert st.max_location[0] < SIZE
    assert abs(st.max_location[1]) > 0.5 * C
    assert 0.7 * L * C / I_Z < st.max_von_mises < L * C / I_Z < st.peak_von_mises
    assert st.order == 2


def test_matches_skfem_interpolation(cantilever):
    # the numpy shape-function gradients against scikit-fem's own P2 interpolation, for a random
    # (seeded) P2 field, at the centroid and at the four vertices of every element
    from skfem import Basis, ElementTetP2, ElementVector

    mesh, sol, _, _, st0 = cantilever
    rng = np.random.default_rng(7)
    u = rng.normal(size=sol.basis.N) * 1e-6
    uv, ue = fea_stress.p2_nodal_values(sol.basis, u)
    st = fea_stress.element_stress(mesh.points, mesh.tets, uv, ue, youngs_modulus=E, poisson_ratio=NU)
    pts = np.column_stack([np.full(3, 0.25), np.zeros(3), np.eye(3)])  # reference centroid, vertices 0..3
    qb = Basis(sol.basis.mesh, ElementVector(ElementTetP2()), quadrature=(pts, np.ones(5)))
    grad = np.transpose(qb.interpolate(u).grad, (2, 3, 0, 1))  # (n_tets, 5, 3, 3)
    lam, mu = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))
    eps = 0.5 * (grad + np.swapaxes(grad, -1, -2))
    sigma = lam * np.trace(eps, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) + 2 * mu * eps
    scale = np.abs(sigma).max()
    np.testing.assert_allclose(st.stress, sigma[:, 0], rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(st.von_mises_vertices, fea_stress.von_mises(sigma[:, 1:]).T, rtol=0,
                               atol=1e-10 * scale)
    assert st0.wall_s > 0


@pytest.mark.parametrize("with_edges", [True, False])
def test_homogeneous_strain_is_exact(cantilever, with_edges):
    # patch test: a linear field u = ε·x is represented exactly by P1 and P2 alike. Uniaxial
    # stress σ_xx = s (u_x = s x / E, u_y,z = −ν s y,z / E) plus simple shear τ_xy = τ (u_x = τ y / G):
    # σ_vM = √(s² + 3τ²) everywhere (closed form)
    mesh, sol, _, _, _ = cantilever
    s, tau, G = 2.0e6, 0.5e6, E / (2 * (1 + NU))
    eps = np.array([[s / E, tau / G, 0.0], [0.0, -NU * s / E, 0.0], [0.0, 0.0, -NU * s / E]])
    uv = eps @ mesh.points
    ue = eps @ sol.basis.mesh.p[:, sol.basis.mesh.edges].mean(axis=1) if with_edges else None
    st = fea_stress.element_stress(mesh.points, mesh.tets, uv, ue, youngs_modulus=E, poisson_ratio=NU)
    expect = np.sqrt(s**2 + 3 * tau**2)
    np.testing.assert_allclose(st.von_mises, expect, rtol=1e-9)
    np.testing.assert_allclose(st.von_mises_vertices, expect, rtol=1e-9)
    assert st.order == (2 if with_edges else 1)


def test_wrong_edge_field_shape_is_rejected(cantilever):
    mesh, _, uv, ue, _ = cantilever
    with pytest.raises(ValueError, match="u_edges has shape"):
        fea_stress.element_stress(mesh.points, mesh.tets, uv, ue[:, :-1], youngs_modulus=E, poisson_ratio=NU)


def _offscreen_rendering() -> bool:
    try:
        import pyvista as pv

        pl = pv.Plotter(off_screen=True, window_size=(64, 64))
        pl.add_mesh(pv.Sphere())
        pl.screenshot(return_img=True)
        pl.close()
        return True
    except Exception:  # no OSMesa/EGL/X: nothing to render with
        return False


def test_plot_structure_writes_the_stress_picture(cantilever, tmp_path):
    # structure_plots on a frame result carrying an FEA field (the cantilever's real P2 solution in
    # the place of the CAD solid's, which takes minutes to mesh and solve on 2 cores)
    if not _offscreen_rendering():
        pytest.skip("pyvista off-screen rendering unavailable")
    from hapticopt.analysis.prrr.structure import fea_cad
    from hapticopt.analysis.prrr.structure import frame_model as fm
    from hapticopt.analysis.prrr.structure import stiffness as ss
    from hapticopt.design.io import load_preset

    mesh, _, uv, ue, st = cantilever
    design = load_preset("prrr-paper")
    design = replace(design, structure=replace(design.structure, youngs_modulus=E, poisson_ratio=NU))
    frame = ss.structural_stiffness(design, options=fm.FrameOptions(joints=fm.Joints.RELEASED, pins=False))
    nan33 = np.full((3, 3), np.nan)
    field = fea_cad.CadFeaResult(compliance_load=nan33, stiffness_load=np.full(3, np.nan), load_height=0.058,
                                 size=SIZE, n_dofs=0, iterations=(), wall_s=0.0, timings_s={}, branch=0,
                                 mesh=mesh, displacement=uv, displacement_edges=ue)
    files = prrr_plots.structure_plots(design, replace(frame, fea=field), tmp_path)
    assert [f.name for f in files] == ["structure_frame.png", "structure_fea.png", "structure_fea_stress.png"]
    assert all(f.stat().st_size > 10_000 for f in files)
    assert files[2].read_bytes() != files[1].read_bytes()  # cell stress, not the displacement picture again
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f.name for f in files)  # no temp files left
    # without the edge-midpoint values (a P1 field: stress one order less accurate) no stress picture
    files = prrr_plots.structure_plots(design, replace(frame, fea=replace(field, displacement_edges=None)), tmp_path / "p1")
    assert [f.name for f in files] == ["structure_frame.png", "structure_fea.png"]
    assert st.order == 2

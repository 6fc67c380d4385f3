"""Solid FEA (gmsh + scikit-fem P2 + pyamg CG) against Timoshenko's cantilever closed form.

Small meshes only; the finer levels and the 3-PRRR solid are in scripts/accuracy/accuracy_structure.py.
"""

import math
import os
import signal

import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis.fem import solid as fea
from hapticopt.analysis.prrr.structure import frame_beam
from hapticopt.analysis.prrr.structure import frame_model as fm
L, B, T, E, NU = 0.2, 0.02, 0.01, 68.9e9, 0.33  # aluminium bar, L/b = 10


@pytest.fixture(scope="module")
def closed_form():
    # Timoshenko: δ/P = L³/(3EI) + L/(κGA), κ = Cowper's rectangle value
    pr = fm.section_properties(fm.Section(jnp.asarray(B), jnp.asarray(T), jnp.asarray(E), jnp.asarray(NU)))
    return frame_beam.closed_form_tip_deflection(1.0, L, E, float(pr.i_z), float(pr.shear_coefficient),
                                         float(pr.shear_modulus), B * T)


@pytest.fixture(scope="module")
def levels():
    sizes = [T * fea.REFINEMENT_RATIO ** (1 - k) for k in range(3)]  # 14.1, 10, 7.1 mm
    return [fea.cantilever_fea(length=L, width=B, thickness=T, youngs_modulus=E, poisson_ratio=NU, size=s)
            for s in sizes]


def test_cantilever_fea_within_1_percent_of_timoshenko(levels, closed_form):
    finest = levels[-1]
    assert finest.compliance == pytest.approx(closed_form, rel=0.01)


def test_cantilever_fea_converges_with_observed_rate(levels, closed_form):
    c = [r.compliance for r in levels]
    # compliance is an energy: the FE solution is stiffer and converges monotonically from below
    assert c[0] < c[1] < c[2] < closed_form * 1.01
    rich = fea.richardson(*c)
    # observed order on unstructured meshes: > 1 (theory for P2 energy: up to 4; clamp corners lower it)
    assert rich.order > 1.0 and math.isfinite(rich.order)
    assert rich.extrapolated == pytest.approx(closed_form, rel=0.01)
    assert levels[-1].n_dofs > levels[0].n_dofs


def test_rigid_body_modes_span_the_kernel():
    mesh = fea.cantilever_mesh(length=0.05, width=B, thickness=T, size=0.02)
    from skfem import Basis, ElementTetP2, ElementVector, MeshTet, asm
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    basis = Basis(MeshTet(mesh.points, mesh.tets), ElementVector(ElementTetP2()))
    K = asm(linear_elasticity(*lame_parameters(E, NU)), basis)
    Bm = fea.rigid_body_modes(basis, centre=(0.01, 0.0, 0.0))
    assert np.abs(K @ Bm).max() < 1e-6 * abs(K).max() * np.abs(Bm).max()


def test_richardson_recovers_a_known_limit():
    # f(h) = 1 + h² sampled at h, h/r, h/r²: order 2, limit 1 (exact for this model)
    r = fea.REFINEMENT_RATIO
    f = [1 + (0.1 / r**k) ** 2 for k in range(3)]
    rich = fea.richardson(*f)
    assert rich.order == pytest.approx(2.0, rel=1e-9)
    assert rich.extrapolated == pytest.approx(1.0, rel=1e-12)


@pytest.mark.hardcase
@pytest.mark.parametrize("noise", [1e-15, 1e-14])
def test_richardson_on_rounding_level_differences_has_no_order(noise):
    """Issue 14: the order came from ``d1 == 0.0``: differences of 1e-15..1e-14 relative (rounding of a
    converged value; two to three decades below RICHARDSON_FLOOR = 1e-12) give sign and ratio noise.
    Now: converged, order NaN, the fine value kept — whichever sign the noise has."""
    for signs in ((1, -1), (1, 1), (-1, 1)):
        f = [1.0, 1.0 + signs[0] * noise, 1.0 + signs[0] * noise + signs[1] * 0.5 * noise]
        rich = fea.richardson(*f)
        assert math.isnan(rich.order) and rich.extrapolated == f[2]
    # differences 1e-10 relative (two decades above the floor) are discretisation error: order 2 again
    r = fea.REFINEMENT_RATIO
    f = [1 + 1e-5 * (0.1 / r**k) ** 2 for k in range(3)]
    assert fea.richardson(*f).order == pytest.approx(2.0, rel=1e-4)


def test_rigid_region_constraint_is_exact_and_matches_timoshenko(closed_form):
    # a rigid tip slab (x ≥ L − 2 mm) loaded by a unit force along y at its centre: the constrained
    # DOFs move exactly rigidly, and the tip compliance is the closed form's for the slab-free
    # length L − 2 mm plus the slab rotation lever (Timoshenko, within 1.5 % at this coarse mesh)
    mesh = fea.cantilever_mesh(length=L, width=B, thickness=T, size=0.01)
    slab = 0.002
    centre = np.array([L - slab / 2, 0.0, 0.0])

    def region(basis):
        return basis.doflocs[0] >= L - slab - 1e-9

    sol = fea.solve_with_rigid_region(mesh, youngs_modulus=E, poisson_ratio=NU, fixed=["clamp"], region=region,
                                      centre=centre, wrenches=np.array([[0.0], [1.0], [0.0], [0.0], [0.0], [0.0]]))
    u = sol.displacements[:, 0]
    Rm = fea.rigid_body_modes(sol.basis, centre=centre)
    in_region = region(sol.basis)
    np.testing.assert_allclose(u[in_region], Rm[in_region] @ sol.master[:, 0], rtol=0, atol=1e-12 * np.abs(u).max())
    pr = fm.section_properties(fm.Section(*(np.asarray(x) for x in (B, T, E, NU))), np)
    Lf = L - slab
    expect = frame_beam.closed_form_tip_deflection(1.0, Lf, E, float(pr.i_z), float(pr.shear_coefficient),
                                           float(pr.shear_modulus), B * T) + Lf**2 / (2 * E * float(pr.i_z)) * slab / 2
    assert sol.master[1, 0] == pytest.approx(expect, rel=0.015)
    assert sol.master[1, 0] < expect * 1.001  # the FE solution is stiffer than the limit


@pytest.mark.parametrize("intorder", [2, 4])
def test_elasticity_stiffness_is_skfems_assembly(intorder):
    """The vectorised P2 assembly against skfem's own ``asm(linear_elasticity)`` (the reference it
    replaces), on a curved-box mesh with skewed tetrahedra: equal to rounding, the same sparsity."""
    from skfem import Basis, ElementTetP2, ElementVector, MeshTet, asm
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    m = MeshTet.init_tensor(*(np.linspace(0.0, 1.0, 4),) * 3)
    m = MeshTet(m.p * np.array([[0.2], [0.03], [0.05]]) + 0.004 * np.sin(7.0 * m.p[[1, 2, 0]]), m.t)
    basis = Basis(m, ElementVector(ElementTetP2()), intorder=intorder)
    lam, mu = lame_parameters(E, NU)
    reference = asm(linear_elasticity(lam, mu), basis).tocsr()
    K = fea.elasticity_stiffness(basis, lam, mu)
    assert K.shape == reference.shape and K.nnz == reference.nnz
    assert abs(K - reference).max() <= 1e-13 * abs(reference).max()
    assert abs(K - K.T).max() <= 1e-13 * abs(reference).max()


def test_elasticity_stiffness_needs_a_vector_p2_basis():
    from skfem import Basis, ElementTetP2, MeshTet

    with pytest.raises(TypeError, match="ElementVector"):
        fea.elasticity_stiffness(Basis(MeshTet(), ElementTetP2()), 1.0, 1.0)


def _sigpipe_ignored_by_the_kernel() -> bool:
    """Bit 13 (SIGPIPE) of ``SigIgn`` in /proc/self/status: what the kernel does, not only Python's record."""
    with open("/proc/self/status") as fh:
        mask = next(int(line.split()[1], 16) for line in fh if line.startswith("SigIgn:"))
    return bool(mask >> (signal.SIGPIPE - 1) & 1)


@pytest.mark.skipif(not hasattr(signal, "SIGPIPE") or not os.path.exists("/proc/self/status"), reason="Linux only")
def test_meshing_leaves_sigpipe_ignored():
    """Issue 37: gmsh.initialize() reset SIGPIPE to its default; a later write to a broken pipe (a killed pool
    worker) ended the process with exit 141. The mesher restores the handler the process had."""
    before = signal.signal(signal.SIGPIPE, signal.SIG_IGN)
    try:
        fea.cantilever_mesh(length=0.05, width=B, thickness=T, size=0.02)  # gmsh_start + the meshing call
        assert signal.getsignal(signal.SIGPIPE) == signal.SIG_IGN and _sigpipe_ignored_by_the_kernel()
    finally:
        signal.signal(signal.SIGPIPE, before)

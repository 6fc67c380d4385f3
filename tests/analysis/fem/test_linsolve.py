"""Linear solves of the solid FEA (hapticopt.analysis.fem.linsolve): direct vs AMG-CG, verdicts.

Closed forms: a chain of n unit springs clamped at one end and pulled by a unit force at the
other stretches by n (series springs); the inverse of its stiffness has entries min(i, j).
"""

import math

import numpy as np
import pytest
import scipy.sparse as sp
from hapticopt.analysis.fem import linsolve
from hapticopt.analysis.fem import solid as fea
from hapticopt.analysis.fem.linsolve import Method
from hapticopt.analysis.status import Status

L, B, T, E, NU = 0.2, 0.02, 0.01, 68.9e9, 0.33  # aluminium bar (test_solid.py)


def chain(n: int, *, clamped: bool = True) -> sp.csr_matrix:
    """Stiffness of n unit springs in series [N/m]; node 0 tied to ground by the first spring when clamped."""
    main = np.full(n, 2.0)
    main[-1] = 1.0
    if not clamped:
        main[0] = 1.0
    off = -np.ones(n - 1)
    return sp.diags([off, main, off], [-1, 0, 1], format="csr")


@pytest.fixture(params=["cholmod", "superlu"])
def backend(request, monkeypatch):
    if request.param == "cholmod":
        if not linsolve.cholmod_available():
            pytest.skip("scikit-sparse (CHOLMOD) not installed: the SuperLU case covers the direct path")
    else:
        monkeypatch.setattr(linsolve, "cholmod_available", lambda: False)
    return request.param


def test_choose_by_size():
    n = linsolve.DIRECT_MAX_UNKNOWNS
    assert linsolve.choose(n) is Method.DIRECT
    assert linsolve.choose(n + 1) is Method.AMG_CG
    assert linsolve.choose(10, Method.AMG_CG) is Method.AMG_CG
    assert linsolve.choose(10**9, Method.DIRECT) is Method.DIRECT


def test_hager_estimate_bounds_the_inverse_norm():
    # clamped chain of 50 springs: (K⁻¹)_ij = min(i, j) + 1 (0-based), so ‖K⁻¹‖₁ = the last column's sum
    # Σ_{i<n} (i + 1) = n(n + 1)/2 (closed form); Hager's estimate is a lower bound, here exact
    n = 50
    K = chain(n)
    exact = n * (n + 1) / 2
    assert np.abs(np.linalg.inv(K.toarray())).sum(axis=0).max() == pytest.approx(exact, rel=1e-12)
    est = linsolve.hager_inverse_norm(lambda b: np.linalg.solve(K.toarray(), b), n)
    assert exact / 3 <= est <= exact * (1 + 1e-12)


def test_direct_solves_a_hard_but_well_posed_chain(backend):
    # 50 000 springs: rcond₁ of the Jacobi-scaled matrix ≈ 1 / (2 · n²) = 2e-10, 2.3 decades above the
    # singular band (1e-12); the tip stretches by n (closed form) to rounding
    n = 50_000
    f = np.zeros(n)
    f[-1] = 1.0
    lin = linsolve.solve_spd(chain(n), f, near_nullspace=np.ones((n, 1)), method=Method.DIRECT)
    assert lin.status is Status.OK and lin.backend == backend
    assert lin.x[-1, 0] == pytest.approx(n, rel=1e-6)
    assert 1e-11 < lin.rcond < 1e-9


@pytest.mark.hardcase
@pytest.mark.parametrize("method", [Method.DIRECT, Method.AMG_CG])
def test_unclamped_chain_is_singular_not_a_number(method, backend):
    # free–free chain: a rigid translation costs no energy (Rayleigh quotient 0 on the near-nullspace)
    n = 2_000
    f = np.zeros(n)
    f[-1] = 1.0
    lin = linsolve.solve_spd(chain(n, clamped=False), f, near_nullspace=np.ones((n, 1)), method=method)
    assert lin.status is Status.SINGULAR and "rigid-body motion" in lin.message
    assert np.all(np.isnan(lin.x))
    assert lin.rigid_rayleigh < 1e-14  # rounding of an exact zero, two decades below the band


@pytest.mark.hardcase
def test_floating_part_is_singular_by_the_condition_estimate(backend):
    # a clamped chain beside a free one, the near-nullspace only on the clamped part: the Rayleigh
    # check passes, the free chain's rigid translation makes the matrix singular (rcond estimate)
    n = 500
    A = sp.block_diag([chain(n), chain(n, clamped=False)], format="csr")
    Bm = np.concatenate([np.ones(n), np.zeros(n)])[:, None]
    f = np.zeros(2 * n)
    f[n - 1] = 1.0
    lin = linsolve.solve_spd(A, f, near_nullspace=Bm, method=Method.DIRECT)
    assert lin.rigid_rayleigh > 1e-8
    assert lin.status is Status.SINGULAR and lin.rcond < linsolve.RCOND_SINGULAR
    assert np.all(np.isnan(lin.x))


@pytest.mark.hardcase
def test_zero_stiffness_dof_is_singular():
    A = chain(10).tolil()
    A[4, :] = 0.0
    A[:, 4] = 0.0
    lin = linsolve.solve_spd(A.tocsr(), np.ones(10), near_nullspace=np.ones((10, 1)))
    assert lin.status is Status.SINGULAR and "unknown 4" in lin.message and np.all(np.isnan(lin.x))


@pytest.fixture(scope="module")
def bar_mesh():
    return fea.cantilever_mesh(length=L, width=B, thickness=T, size=0.01)


def _tip_slab(mesh, **kw):
    slab = 0.002
    centre = np.array([L - slab / 2, 0.0, 0.0])
    return fea.solve_with_rigid_region(mesh, youngs_modulus=E, poisson_ratio=NU, fixed=["clamp"],
                                       region=lambda basis: basis.doflocs[0] >= L - slab - 1e-9, centre=centre,
                                       wrenches=np.eye(6)[:, :3], **kw)


def test_direct_and_amg_cg_agree_to_1e_6(bar_mesh, backend):
    """Acceptance (issue 22): the same stiffness from both solvers to 1e-6 relative (CG at 1e-10:
    the compliance error is ~tol², far below)."""
    direct = _tip_slab(bar_mesh, method=Method.DIRECT)
    amg = _tip_slab(bar_mesh, method=Method.AMG_CG, tol=1e-10)
    assert direct.status is Status.OK and amg.status is Status.OK
    assert direct.solver == backend and amg.solver == "pyamg-sa-cg"
    assert direct.iterations == (0, 0, 0) and all(0 < i < 200 for i in amg.iterations)
    Cd, Ca = direct.master[:3], amg.master[:3]  # (3, 3) translations per unit force
    np.testing.assert_allclose(Ca, Cd, rtol=0, atol=1e-6 * np.abs(np.diagonal(Cd)).max())
    np.testing.assert_allclose(np.diagonal(Ca), np.diagonal(Cd), rtol=1e-6)
    assert max(direct.residuals) < 1e-9
    assert 1e-10 < direct.rcond < 1e-3  # an FE stiffness: far above the singular band, below the 1e-6 one


@pytest.mark.hardcase
@pytest.mark.parametrize("method", [Method.DIRECT, Method.AMG_CG])
def test_missing_clamp_gives_singular_status_with_either_solver(bar_mesh, method):
    # the clamp node set emptied: nothing holds the bar
    loose = fea.TetMesh(points=bar_mesh.points, tets=bar_mesh.tets,
                        node_sets={**bar_mesh.node_sets, "clamp": np.zeros(0, dtype=np.int64)})
    sol = _tip_slab(loose, method=method)
    assert sol.status is Status.SINGULAR and "supports" in sol.message
    assert np.all(np.isnan(sol.master)) and np.all(np.isnan(sol.displacements))
    k = 1.0 / np.diagonal(sol.master[:3])
    assert not np.any(np.isfinite(k))  # the caller's stiffness is NaN: its status cannot be ok


def test_elasticity_solution_reports_its_solver(bar_mesh):
    sol = fea.solve_elasticity(bar_mesh, youngs_modulus=E, poisson_ratio=NU, fixed="clamp",
                               loads=fea.tip_shear_loads(bar_mesh, B * T))
    assert sol.status is Status.OK and sol.solver in ("cholmod", "superlu")
    assert set(sol.timings_s) == {"assemble", "setup", "solve"} and math.isfinite(sol.rcond)


def test_cg_that_does_not_converge_is_failed_not_a_number(monkeypatch):
    # one CG iteration allowed on a 2 000-spring chain (condition ~1e6): far from the 1e-7 residual
    monkeypatch.setattr(linsolve, "CG_MAXITER", 1)
    n = 2_000
    f = np.zeros(n)
    f[-1] = 1.0
    lin = linsolve.solve_spd(chain(n), f, near_nullspace=np.ones((n, 1)), method=Method.AMG_CG)
    assert lin.status is Status.FAILED and "did not converge" in lin.message and np.all(np.isnan(lin.x))
    # the FEA's entry point raises it (the evaluators make it a `failed` status with this message)
    with pytest.raises(RuntimeError, match="CG did not converge on load case 0"):
        fea.solve_system(chain(n), np.ones((n, 1)), f[:, None], blocked=False, tol=1e-7, method=Method.AMG_CG)

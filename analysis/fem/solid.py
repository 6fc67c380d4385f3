"""Solid FEA: gmsh tetrahedra, scikit-fem quadratic elasticity, sparse direct or AMG-CG solve.

Pipeline (pitfalls: named physical groups, quadratic tetrahedra, measure direct vs AMG):

1. gmsh (OpenCASCADE kernel, geometry in mm) builds and meshes the solid; supports are named
   physical surfaces ("clamp", "tip", "support_leg<i>"), the body the physical volume "solid".
2. scikit-fem assembles linear elasticity with ``ElementVector(ElementTetP2())`` (10-node
   tetrahedra; linear ones lock in bending).
3. Dirichlet DOFs are condensed out; the system is solved by :mod:`hapticopt.analysis.fem.linsolve`:
   a sparse Cholesky/LU factorisation up to its size limit (one factor for all load cases),
   conjugate gradients preconditioned with pyamg smoothed aggregation (near-nullspace B: the
   six rigid-body modes) above it; an unsupported solid gets a singular status, not a number.

The generic pieces live here: meshing helpers, P2 assembly with clamped surfaces, rigid-body
modes, the linear solve, a rigid load region, the cantilever check (:func:`cantilever_fea`, compared with
Timoshenko's closed form) and Richardson extrapolation. Device solids build on them:
:mod:`hapticopt.analysis.prrr.structure.fea_cad` (the CAD solid with pins and hinges).
"""

from __future__ import annotations

import math
import signal
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from hapticopt.analysis.fem import linsolve
from hapticopt.analysis.fem.linsolve import Method
from hapticopt.analysis.status import Status


#: ratio of successive mesh sizes in the refinement studies
REFINEMENT_RATIO = math.sqrt(2.0)


@dataclass(frozen=True, kw_only=True)
class TetMesh:
    """A linear tetrahedral mesh [m] with named node sets (gmsh physical groups)."""

    points: np.ndarray  # (3, n_nodes) [m]
    tets: np.ndarray  # (4, n_tets) node indices
    node_sets: dict[str, np.ndarray] = field(default_factory=dict)  # physical group name -> node indices


# ----------------------------------------------------------------------------- gmsh
def gmsh_start(name: str):
    """A fresh gmsh model ``name``. ``gmsh.initialize()`` resets SIGPIPE to its default action (Python
    ignores it: a write to a broken pipe then raises instead of ending the process with exit 141 and no
    message, docs pitfalls): the handler is restored at once."""
    import gmsh

    if gmsh.isInitialized():
        gmsh.finalize()
    previous = signal.getsignal(signal.SIGPIPE) if hasattr(signal, "SIGPIPE") else None
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    if previous is not None and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGPIPE, previous)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add(name)
    return gmsh


def gmsh_mesh(gmsh, size_mm: float, groups_2d: dict[str, list[int]], volumes: list[int],
               groups_3d: dict[str, list[int]] | None = None) -> TetMesh:
    """Mesh the synchronised model (mm) and return it in metres with the named node sets
    (surface groups ``groups_2d`` and volume groups ``groups_3d``, besides the volume "solid")."""
    for name, tags in groups_2d.items():
        gmsh.model.addPhysicalGroup(2, tags, name=name)
    gmsh.model.addPhysicalGroup(3, volumes, name="solid")
    for name, tags in (groups_3d or {}).items():
        gmsh.model.addPhysicalGroup(3, tags, name=name)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size_mm)
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.3 * size_mm)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.model.mesh.generate(3)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(tags.size)
    points = coords.reshape(-1, 3).T * 1e-3
    etypes, _, enodes = gmsh.model.mesh.getElements(3)
    tets = [index[np.asarray(n, dtype=np.int64)].reshape(-1, 4).T for t, n in zip(etypes, enodes) if t == 4]
    if not tets:
        raise RuntimeError("gmsh produced no tetrahedra")
    node_sets = {}
    for dim, ptag in gmsh.model.getPhysicalGroups(2) + [g for g in gmsh.model.getPhysicalGroups(3)
                                                        if groups_3d and gmsh.model.getPhysicalName(*g) in groups_3d]:
        name = gmsh.model.getPhysicalName(dim, ptag)
        ntags, _ = gmsh.model.mesh.getNodesForPhysicalGroup(dim, ptag)
        node_sets[name] = index[ntags.astype(np.int64)]
    gmsh.finalize()
    return TetMesh(points=points, tets=np.concatenate(tets, axis=1), node_sets=node_sets)


def surfaces_at(gmsh, point_mm: np.ndarray, tol_mm: float) -> list[int]:
    """Surface tags whose centre of mass lies within ``tol_mm`` of ``point_mm``."""
    out = []
    for _, tag in gmsh.model.getEntities(2):
        com = np.asarray(gmsh.model.occ.getCenterOfMass(2, tag))
        if np.linalg.norm(com - point_mm) < tol_mm:
            out.append(tag)
    return out


def cantilever_mesh(*, length: float, width: float, thickness: float, size: float) -> TetMesh:
    """Box [0, L] × [−b/2, b/2] × [−t/2, t/2] [m]; groups "clamp" (x = 0) and "tip" (x = L)."""
    gmsh = gmsh_start("cantilever")
    L, b, t = length * 1e3, width * 1e3, thickness * 1e3
    vol = gmsh.model.occ.addBox(0.0, -b / 2, -t / 2, L, b, t)
    gmsh.model.occ.synchronize()
    tol = 1e-6 * L
    groups = {"clamp": surfaces_at(gmsh, np.array([0.0, 0.0, 0.0]), tol),
              "tip": surfaces_at(gmsh, np.array([L, 0.0, 0.0]), tol)}
    return gmsh_mesh(gmsh, size * 1e3, groups, [vol])


# ----------------------------------------------------------------------------- elasticity
@dataclass(frozen=True, kw_only=True)
class ElasticSolution:
    """Displacements of several load cases on one mesh, with solver diagnostics."""

    basis: Any  # skfem Basis (ElementVector(ElementTetP2))
    displacements: np.ndarray  # (n_dofs, n_cases) [m]
    loads: np.ndarray  # (n_dofs, n_cases) [N]
    n_dofs: int
    iterations: tuple[int, ...]
    residuals: tuple[float, ...]
    timings_s: dict[str, float]
    solver: str = ""  # linear-solver backend (hapticopt.analysis.fem.linsolve)
    status: Status = Status.OK  # singular: no equilibrium (displacements NaN)
    rcond: float = float("nan")  # 1-norm reciprocal condition estimate of the scaled system (direct solves)
    message: str = ""


def component_dofs(basis) -> list[np.ndarray]:
    """DOF indices of the x, y, z displacement components (vertex then edge DOFs)."""
    return [np.concatenate([basis.nodal_dofs[c], basis.edge_dofs[c]]) for c in range(3)]


def rigid_body_modes(basis, centre=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(n_dofs, 6): three translations and three rotations about ``centre`` [m] (unit rotation)."""
    x = basis.doflocs - np.asarray(centre, dtype=float)[:, None]
    B = np.zeros((basis.N, 6))
    comps = component_dofs(basis)
    for c in range(3):
        B[comps[c], c] = 1.0
    # rotation about axis a: u = e_a × x
    for a in range(3):
        rot = np.cross(np.eye(3)[a], x.T).T  # (3, n_dofs) at every DOF location
        for c in range(3):
            B[comps[c], 3 + a] = rot[c, comps[c]]
    return B


def elasticity_stiffness(basis, lam: float, mu: float) -> sp.csr_matrix:
    """Isotropic linear-elasticity stiffness (Lamé ``lam``, ``mu`` [Pa]) on a vector P2 tetrahedral
    ``basis`` (``ElementVector(ElementTetP2())``, any quadrature order), as csr.

    The same matrix as skfem's ``asm(linear_elasticity(lam, mu), basis)`` (equal to rounding: the sums
    run in another order; tests/analysis/fem/test_solid.py) at about a sixth of its time: skfem calls the
    form once per pair of the 30 local basis functions (900 Python-level kernels); here every element's
    30 × 30 matrix comes from one contraction of the ten scalar P2 gradients. For u = φ_r e_d, v = φ_p e_c,
    σ(u):ε(v) = μ δ_cd ∇φ_p·∇φ_r + μ ∂_c φ_r ∂_d φ_p + λ ∂_c φ_p ∂_d φ_r, integrated with the basis's
    quadrature (``basis.dx``: weights × |det J|). Local DOF 3p + c is scalar function p, component c
    (skfem's ``ElementVector`` order).
    """
    from skfem import ElementTetP2, ElementVector

    if not (isinstance(basis.elem, ElementVector) and isinstance(basis.elem.elem, ElementTetP2)):
        raise TypeError(f"elasticity_stiffness needs an ElementVector(ElementTetP2()) basis, not {basis.elem}")
    g = np.stack([basis.basis[3 * p][0].grad[0] for p in range(10)], axis=1)  # (3 derivatives, 10, nel, nqp)
    M = np.einsum("cpeq,dreq,eq->ecdpr", g, g, basis.dx, optimize=True)  # ∫ ∂_c φ_p ∂_d φ_r, (nel, 3, 3, 10, 10)
    local = lam * M + mu * M.transpose(0, 2, 1, 3, 4)  # [e, c, d, p, r]
    local[:, [0, 1, 2], [0, 1, 2]] += mu * (M[:, 0, 0] + M[:, 1, 1] + M[:, 2, 2])[:, None]
    local = local.transpose(0, 3, 1, 4, 2).reshape(-1, 30, 30)  # [e, 3p + c, 3r + d]
    dofs = basis.element_dofs.T  # (nel, 30)
    rows = np.repeat(dofs, 30, axis=1).ravel()
    cols = np.tile(dofs, (1, 30)).ravel()
    return sp.coo_matrix((local.ravel(), (rows, cols)), shape=(basis.N, basis.N)).tocsr()


def assemble_clamped(mesh: TetMesh, *, youngs_modulus: float, poisson_ratio: float, fixed: str | list[str]):
    """P2 linear-elasticity stiffness of ``mesh`` and the DOFs of its clamped faces.

    Returns (skfem MeshTet, vector P2 basis, K (csr), clamped DOFs D): the faces whose nodes all lie
    in the ``fixed`` node sets. Quadrature of order 2, exact for straight-sided P2 tetrahedra.
    """
    from skfem import Basis, ElementTetP2, ElementVector, MeshTet
    from skfem.models.elasticity import lame_parameters

    m = MeshTet(np.ascontiguousarray(mesh.points), np.ascontiguousarray(mesh.tets))
    basis = Basis(m, ElementVector(ElementTetP2()), intorder=2)
    K = elasticity_stiffness(basis, *lame_parameters(youngs_modulus, poisson_ratio))
    names = [fixed] if isinstance(fixed, str) else list(fixed)
    fixed_nodes = np.unique(np.concatenate([mesh.node_sets[n] for n in names]))
    is_fixed = np.zeros(m.nvertices, dtype=bool)
    is_fixed[fixed_nodes] = True
    D = basis.get_dofs(np.nonzero(np.all(is_fixed[m.facets], axis=0))[0]).all()
    return m, basis, K, D


def tip_shear_loads(mesh: TetMesh, area: float):
    """``loads(basis)`` of a unit total force along y, a uniform traction on the ``tip`` node set's faces."""

    def loads(basis):
        from skfem import FacetBasis, LinearForm, asm

        m = basis.mesh
        is_tip = np.zeros(m.nvertices, dtype=bool)
        is_tip[mesh.node_sets["tip"]] = True
        fb = FacetBasis(m, basis.elem, facets=np.nonzero(np.all(is_tip[m.facets], axis=0))[0])

        @LinearForm
        def traction(v, w):
            return v[1] / area

        return asm(traction, fb)

    return loads


def solve_elasticity(mesh: TetMesh, *, youngs_modulus: float, poisson_ratio: float, fixed: str | list[str],
                     loads, tol: float = 1e-7, method: Method = Method.AUTO) -> ElasticSolution:
    """Linear elasticity with P2 tetrahedra; ``fixed`` named node sets clamped.

    ``loads(basis) -> (n_dofs, n_cases)`` builds the load vectors on the quadratic basis.
    Quadrature of order 2 (exact for the stiffness of straight-sided P2 tetrahedra: ∇u·∇v is
    quadratic; skfem's default order 4 only adds quadrature points). The condensed system is solved
    by :func:`hapticopt.analysis.fem.linsolve.solve_spd` (one factorisation, or one AMG hierarchy,
    for every load case; ``method`` AUTO chooses by size); ``tol`` is CG's relative residual
    when AMG-CG runs (the compliance error is ~tol², negligible). A singular system (missing
    clamp) gives NaN displacements and ``status`` singular.
    """
    from skfem import condense

    t0 = time.perf_counter()
    _, basis, K, D = assemble_clamped(mesh, youngs_modulus=youngs_modulus, poisson_ratio=poisson_ratio, fixed=fixed)
    t1 = time.perf_counter()
    F = np.atleast_2d(np.asarray(loads(basis)).T).T
    A, _, _, I = condense(K, F[:, 0], D=D)
    B = rigid_body_modes(basis, centre=mesh.points.mean(axis=1))[I]
    # skfem numbers the components of a DOF location consecutively; clamping removes whole
    # locations, so the free DOFs stay in node blocks of 3: aggregate nodes, not scalars
    blocked = I.size % 3 == 0 and np.all(I[0::3] % 3 == 0) and np.all(np.diff(I.reshape(-1, 3), axis=1) == 1)
    lin = solve_system(A, B, F[I], blocked=bool(blocked), tol=tol, method=method)
    U = np.zeros_like(F) if lin.status is Status.OK else np.full_like(F, np.nan)
    U[I] = lin.x
    return ElasticSolution(basis=basis, displacements=U, loads=F, n_dofs=int(basis.N), iterations=lin.iterations,
                           residuals=lin.residuals, timings_s={"assemble": t1 - t0, **solver_timings(lin)},
                           solver=lin.backend, status=lin.status, rcond=lin.rcond, message=lin.message)


def solver_timings(lin: linsolve.LinearSolution) -> dict[str, float]:
    """"setup" (checks + factorisation and condition estimate, or the AMG hierarchy) and "solve"."""
    t = lin.timings_s
    return {"setup": t.get("check", 0.0) + t.get("factor", 0.0) + t.get("condition", 0.0) + t.get("amg_setup", 0.0),
            "solve": t.get("solve", 0.0)}


def solve_system(A, B: np.ndarray, rhs: np.ndarray, *, blocked: bool, tol: float,
                 method: Method = Method.AUTO) -> linsolve.LinearSolution:
    """A reduced stiffness system with near-nullspace ``B`` (the rigid-body modes in its unknowns),
    every column of ``rhs``: :func:`hapticopt.analysis.fem.linsolve.solve_spd`.

    A singular system comes back as a value (status singular, NaN solutions: the stiffness the
    callers compute from it is NaN, their status not ok). A solve that failed to converge or to
    reach its residual raises ``RuntimeError`` with the solver's message: the evaluators turn it into
    a ``failed`` status with that message.
    """
    lin = linsolve.solve_spd(A, rhs, near_nullspace=B, blocked=blocked, tol=tol, method=method)
    if lin.status is Status.FAILED:
        raise RuntimeError(lin.message)
    return lin


@dataclass(frozen=True, kw_only=True)
class RigidRegionSolution:
    """Elasticity with a rigid region tied exactly to six master DOFs (rigid-body MPC)."""

    basis: Any
    displacements: np.ndarray  # (n_dofs, n_cases) [m], full field
    master: np.ndarray  # (6, n_cases): [u; θ] of the rigid region about ``centre``
    n_dofs: int  # unknowns of the reduced system
    iterations: tuple[int, ...]
    residuals: tuple[float, ...]
    timings_s: dict[str, float]
    solver: str = ""
    status: Status = Status.OK
    rcond: float = float("nan")
    message: str = ""


def solve_with_rigid_region(mesh: TetMesh, *, youngs_modulus: float, poisson_ratio: float, fixed: list[str],
                            region, centre, wrenches: np.ndarray, tol: float = 1e-7,
                            method: Method = Method.AUTO) -> RigidRegionSolution:
    """Linear elasticity (P2) where the DOFs selected by ``region(basis) -> bool (n_dofs,)`` move
    as one rigid body: u = u_c + θ × (x − centre) (an exact multi-point constraint, u = T q; the
    reduced stiffness is Tᵀ K T). ``wrenches`` (6, n_cases) [N; N·m] about ``centre`` load the
    six master DOFs. The compliance is then a true energy quantity (no nodal point loads), so it
    converges monotonically under refinement, unlike a least-squares fit of a loaded node set.
    Solved by :func:`hapticopt.analysis.fem.linsolve.solve_spd` (``method``; NaN fields and
    ``status`` singular for an unsupported solid).
    """

    t0 = time.perf_counter()
    _, basis, K, D = assemble_clamped(mesh, youngs_modulus=youngs_modulus, poisson_ratio=poisson_ratio, fixed=fixed)
    t1 = time.perf_counter()
    in_region = np.asarray(region(basis), dtype=bool)
    in_region[D] = False
    free = np.ones(basis.N, dtype=bool)
    free[D] = False
    free[in_region] = False
    I = np.nonzero(free)[0]
    Rg = np.nonzero(in_region)[0]
    modes = rigid_body_modes(basis, centre=centre)
    n = I.size
    T = sp.hstack([sp.csr_matrix((np.ones(n), (I, np.arange(n))), shape=(basis.N, n)),
                   sp.csr_matrix((modes[Rg].ravel(), (np.repeat(Rg, 6), np.tile(np.arange(6), Rg.size))),
                                 shape=(basis.N, 6))]).tocsr()
    A = (T.T @ K @ T).tocsr()
    A = 0.5 * (A + A.T)
    B = np.vstack([modes[I], np.eye(6)])
    rhs = np.vstack([np.zeros((n, wrenches.shape[1])), np.asarray(wrenches, dtype=float)])
    blocked = n % 3 == 0 and np.all(I[0::3] % 3 == 0) and np.all(np.diff(I.reshape(-1, 3), axis=1) == 1)
    t2 = time.perf_counter()
    lin = solve_system(A, B, rhs, blocked=bool(blocked), tol=tol, method=method)
    return RigidRegionSolution(basis=basis, displacements=np.asarray(T @ lin.x), master=lin.x[n:],
                               n_dofs=int(A.shape[0]), iterations=lin.iterations, residuals=lin.residuals,
                               timings_s={"assemble": t1 - t0, "reduce": t2 - t1, **solver_timings(lin)},
                               solver=lin.backend, status=lin.status, rcond=lin.rcond, message=lin.message)


# ----------------------------------------------------------------------------- cantilever
@dataclass(frozen=True, kw_only=True)
class CantileverResult:
    compliance: float  # work-conjugate tip deflection per unit tip force [m/N]
    size: float  # mesh size [m]
    n_dofs: int
    iterations: int
    wall_s: float


def cantilever_fea(*, length: float, width: float, thickness: float, youngs_modulus: float,
                   poisson_ratio: float, size: float) -> CantileverResult:
    """Tip compliance [m/N] of a clamped box under a uniform shear traction along y on its tip face.

    The deflection is the traction-weighted mean u_y of the tip face (fᵀu / P²), the quantity
    Timoshenko's PL³/3EI + PL/κGA describes.
    """
    t0 = time.perf_counter()
    mesh = cantilever_mesh(length=length, width=width, thickness=thickness, size=size)
    sol = solve_elasticity(mesh, youngs_modulus=youngs_modulus, poisson_ratio=poisson_ratio, fixed="clamp",
                           loads=tip_shear_loads(mesh, width * thickness))
    compliance = float(sol.loads[:, 0] @ sol.displacements[:, 0])
    return CantileverResult(compliance=compliance, size=size, n_dofs=sol.n_dofs, iterations=sol.iterations[0],
                            wall_s=time.perf_counter() - t0)


@dataclass(frozen=True, kw_only=True)
class Richardson:
    """Richardson extrapolation of three levels with a constant refinement ratio."""

    extrapolated: float
    order: float  # observed convergence order p
    ratio: float


#: relative size below which a difference of two levels is rounding, not discretisation error
#: (four decades above float64 ε)
RICHARDSON_FLOOR = 1e-12


def richardson(coarse: float, medium: float, fine: float, *, ratio: float = REFINEMENT_RATIO) -> Richardson:
    """Observed order p = ln((f1−f2)/(f2−f3))/ln r and f∞ = f3 + (f3−f2)/(r^p − 1)."""
    d1, d2 = coarse - medium, medium - fine
    # differences at the rounding level of the values carry no order (their sign and ratio are
    # noise): below RICHARDSON_FLOOR of the values' size the sequence has converged, order NaN
    floor = RICHARDSON_FLOOR * max(abs(coarse), abs(medium), abs(fine))
    if not (abs(d1) > floor and abs(d2) > floor) or d1 / d2 <= 0.0:
        return Richardson(extrapolated=fine, order=float("nan"), ratio=ratio)
    p = math.log(d1 / d2) / math.log(ratio)
    return Richardson(extrapolated=fine + (fine - medium) / (ratio**p - 1.0), order=p, ratio=ratio)

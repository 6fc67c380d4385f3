"""Solid FEA: gmsh tetrahedra, scikit-fem quadratic elasticity, pyamg-preconditioned CG.

Pipeline (pitfalls: named physical groups, quadratic tetrahedra, AMG with rigid-body modes):

1. gmsh (OpenCASCADE kernel, geometry in mm) builds and meshes the solid; supports are named
   physical surfaces ("clamp", "tip", "support_leg<i>"), the body the physical volume "solid".
2. scikit-fem assembles linear elasticity with ``ElementVector(ElementTetP2())`` (10-node
   tetrahedra; linear ones lock in bending).
3. Dirichlet DOFs are condensed out; the system is solved by conjugate gradients preconditioned
   with pyamg smoothed aggregation whose near-nullspace B holds the six rigid-body modes.

Two models:

* :func:`cantilever_fea` — a prismatic cantilever (clamped face, uniform shear traction on the
  tip face); its work-conjugate tip deflection is compared with Timoshenko's closed form.
* :func:`prrr_fea` — the **frame-equivalent solid** of the 3-PRRR at the home pose: every frame
  segment of :mod:`analysis.frame_model` (carriage arm, d3, d4, r4 offset, platform arm) as a
  rectangular bar of the link section along the frame's centre line, extended by the boss radius
  past each joint node (the overlap that the frame's rigid joint zones stand for) except at the
  rail, fused into one
  body. Joints are **bonded** (the fused overlap is the pin); compare with
  ``FrameOptions(joints=Joints.BONDED)``. Supports: the carriage-arm end faces at the rails
  are clamped (sliders locked). Load: a rigid "hub" — every node within ``0.75·link_width``
  of the end-effector point P — receives the least-squares-consistent nodal forces of a
  unit wrench, and its rigid motion is fitted by least squares, giving the 6×6 compliance at
  P; the handle to the load point Δz above P is rigid, exactly as in the frame model.

  The CAD of ``design/cad_prrr.py`` is not meshed here: its parts are separate solids with
  axial clearance gaps at the joints (no shared volume), so a bonded-pin model needs pin solids
  and contact/tie definitions that this module does not provide.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticopt.analysis.status import Status

#: default mesh level of the PRRR solid for ``--fidelity fine`` (see docs/structure.md)
DEFAULT_PRRR_LEVEL = 1
#: ratio of successive mesh sizes in the refinement studies
REFINEMENT_RATIO = math.sqrt(2.0)


@dataclass(frozen=True, kw_only=True)
class TetMesh:
    """A linear tetrahedral mesh [m] with named node sets (gmsh physical groups)."""

    points: np.ndarray  # (3, n_nodes) [m]
    tets: np.ndarray  # (4, n_tets) node indices
    node_sets: dict[str, np.ndarray] = field(default_factory=dict)  # physical group name -> node indices


# ----------------------------------------------------------------------------- gmsh
def _gmsh_start(name: str):
    import gmsh

    if gmsh.isInitialized():
        gmsh.finalize()
    gmsh.initialize(["-noenv"], readConfigFiles=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.model.add(name)
    return gmsh


def _gmsh_mesh(gmsh, size_mm: float, groups_2d: dict[str, list[int]], volumes: list[int],
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


def _surfaces_at(gmsh, point_mm: np.ndarray, tol_mm: float) -> list[int]:
    """Surface tags whose centre of mass lies within ``tol_mm`` of ``point_mm``."""
    out = []
    for _, tag in gmsh.model.getEntities(2):
        com = np.asarray(gmsh.model.occ.getCenterOfMass(2, tag))
        if np.linalg.norm(com - point_mm) < tol_mm:
            out.append(tag)
    return out


def cantilever_mesh(*, length: float, width: float, thickness: float, size: float) -> TetMesh:
    """Box [0, L] × [−b/2, b/2] × [−t/2, t/2] [m]; groups "clamp" (x = 0) and "tip" (x = L)."""
    gmsh = _gmsh_start("cantilever")
    L, b, t = length * 1e3, width * 1e3, thickness * 1e3
    vol = gmsh.model.occ.addBox(0.0, -b / 2, -t / 2, L, b, t)
    gmsh.model.occ.synchronize()
    tol = 1e-6 * L
    groups = {"clamp": _surfaces_at(gmsh, np.array([0.0, 0.0, 0.0]), tol),
              "tip": _surfaces_at(gmsh, np.array([L, 0.0, 0.0]), tol)}
    return _gmsh_mesh(gmsh, size * 1e3, groups, [vol])


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


def _component_dofs(basis) -> list[np.ndarray]:
    """DOF indices of the x, y, z displacement components (vertex then edge DOFs)."""
    return [np.concatenate([basis.nodal_dofs[c], basis.edge_dofs[c]]) for c in range(3)]


def rigid_body_modes(basis, centre=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(n_dofs, 6): three translations and three rotations about ``centre`` [m] (unit rotation)."""
    x = basis.doflocs - np.asarray(centre, dtype=float)[:, None]
    B = np.zeros((basis.N, 6))
    comps = _component_dofs(basis)
    for c in range(3):
        B[comps[c], c] = 1.0
    # rotation about axis a: u = e_a × x
    for a in range(3):
        rot = np.cross(np.eye(3)[a], x.T).T  # (3, n_dofs) at every DOF location
        for c in range(3):
            B[comps[c], 3 + a] = rot[c, comps[c]]
    return B


def assemble_clamped(mesh: TetMesh, *, youngs_modulus: float, poisson_ratio: float, fixed: str | list[str]):
    """P2 linear-elasticity stiffness of ``mesh`` and the DOFs of its clamped faces.

    Returns (skfem MeshTet, vector P2 basis, K (csr), clamped DOFs D): the faces whose nodes all lie
    in the ``fixed`` node sets. Quadrature of order 2, exact for straight-sided P2 tetrahedra.
    """
    from skfem import Basis, ElementTetP2, ElementVector, MeshTet, asm
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    m = MeshTet(np.ascontiguousarray(mesh.points), np.ascontiguousarray(mesh.tets))
    basis = Basis(m, ElementVector(ElementTetP2()), intorder=2)
    K = asm(linear_elasticity(*lame_parameters(youngs_modulus, poisson_ratio)), basis).tocsr()
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
                     loads, tol: float = 1e-7) -> ElasticSolution:
    """Linear elasticity with P2 tetrahedra; ``fixed`` named node sets clamped.

    ``loads(basis) -> (n_dofs, n_cases)`` builds the load vectors on the quadratic basis.
    Quadrature of order 2 (exact for the stiffness of straight-sided P2 tetrahedra: ∇u·∇v is
    quadratic; ~3× faster assembly than skfem's default order 4). One smoothed-aggregation
    hierarchy (rigid-body modes as B, energy-minimising prolongation smoothing, strength
    threshold 0.02 (P2 stencils otherwise give ~65-node aggregates), one forward Gauss–Seidel
    sweep before and one backward after (a symmetric V-cycle at half the default cost); together
    −45 % CG time on the CAD solid, docs/structure.md) serves every load case;
    CG stops at relative residual ``tol`` (the compliance error is ~tol², negligible).
    """
    import pyamg
    from scipy.sparse.linalg import cg
    from skfem import condense

    t0 = time.perf_counter()
    _, basis, K, D = assemble_clamped(mesh, youngs_modulus=youngs_modulus, poisson_ratio=poisson_ratio, fixed=fixed)
    t1 = time.perf_counter()
    F = np.atleast_2d(np.asarray(loads(basis)).T).T
    A, _, _, I = condense(K, F[:, 0], D=D)
    A = A.tocsr()
    B = rigid_body_modes(basis, centre=mesh.points.mean(axis=1))[I]
    # skfem numbers the components of a DOF location consecutively; clamping removes whole
    # locations, so the free DOFs stay in node blocks of 3: aggregate nodes, not scalars
    blocked = I.size % 3 == 0 and np.all(I[0::3] % 3 == 0) and np.all(np.diff(I.reshape(-1, 3), axis=1) == 1)
    A_amg = A.tobsr(blocksize=(3, 3)) if blocked else A
    ml = pyamg.smoothed_aggregation_solver(A_amg, B=B, symmetry="hermitian", max_coarse=300,
                                           strength=("symmetric", {"theta": 0.02}),
                                           smooth=("energy", {"krylov": "cg", "maxiter": 2, "degree": 1,
                                                              "weighting": "local"}),
                                           presmoother=("block_gauss_seidel", {"sweep": "forward"}),
                                           postsmoother=("block_gauss_seidel", {"sweep": "backward"}))
    M = ml.aspreconditioner(cycle="V")
    t2 = time.perf_counter()
    U = np.zeros_like(F)
    its, res = [], []
    for k in range(F.shape[1]):
        b = F[I, k]
        count = [0]

        def cb(_xk):
            count[0] += 1

        x, info = cg(A, b, rtol=tol, atol=0.0, M=M, maxiter=2000, callback=cb)
        if info != 0:
            raise RuntimeError(f"CG did not converge (info={info}) on load case {k}")
        U[I, k] = x
        its.append(count[0])
        res.append(float(np.linalg.norm(A @ x - b) / max(np.linalg.norm(b), 1e-300)))
    t3 = time.perf_counter()
    return ElasticSolution(basis=basis, displacements=U, loads=F, n_dofs=int(basis.N), iterations=tuple(its),
                           residuals=tuple(res),
                           timings_s={"assemble": t1 - t0, "amg_setup": t2 - t1, "solve": t3 - t2})


def _amg_cg(A, B, rhs: np.ndarray, *, blocked: bool, tol: float) -> tuple[np.ndarray, list[int], list[float], float]:
    """SA-AMG (settings as in :func:`solve_elasticity`) + CG for every column of ``rhs``."""
    import pyamg
    from scipy.sparse.linalg import cg

    t0 = time.perf_counter()
    A = A.tocsr()
    ml = pyamg.smoothed_aggregation_solver(A.tobsr(blocksize=(3, 3)) if blocked else A, B=B, symmetry="hermitian",
                                           max_coarse=300, strength=("symmetric", {"theta": 0.02}),
                                           smooth=("energy", {"krylov": "cg", "maxiter": 2, "degree": 1,
                                                              "weighting": "local"}),
                                           presmoother=("block_gauss_seidel", {"sweep": "forward"}),
                                           postsmoother=("block_gauss_seidel", {"sweep": "backward"}))
    M = ml.aspreconditioner(cycle="V")
    t_setup = time.perf_counter() - t0
    X = np.zeros_like(rhs)
    its, res = [], []
    for k in range(rhs.shape[1]):
        count = [0]

        def cb(_xk):
            count[0] += 1

        x, info = cg(A, rhs[:, k], rtol=tol, atol=0.0, M=M, maxiter=3000, callback=cb)
        if info != 0:
            raise RuntimeError(f"CG did not converge (info={info}) on load case {k}")
        X[:, k] = x
        its.append(count[0])
        res.append(float(np.linalg.norm(A @ x - rhs[:, k]) / max(np.linalg.norm(rhs[:, k]), 1e-300)))
    return X, its, res, t_setup


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


def solve_with_rigid_region(mesh: TetMesh, *, youngs_modulus: float, poisson_ratio: float, fixed: list[str],
                            region, centre, wrenches: np.ndarray, tol: float = 1e-7) -> RigidRegionSolution:
    """Linear elasticity (P2) where the DOFs selected by ``region(basis) -> bool (n_dofs,)`` move
    as one rigid body: u = u_c + θ × (x − centre) (an exact multi-point constraint, u = T q; the
    reduced stiffness is Tᵀ K T). ``wrenches`` (6, n_cases) [N; N·m] about ``centre`` load the
    six master DOFs. The compliance is then a true energy quantity (no nodal point loads), so it
    converges monotonically under refinement, unlike a least-squares fit of a loaded node set.
    """
    import scipy.sparse as sp

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
    X, its, res, t_setup = _amg_cg(A, B, rhs, blocked=bool(blocked), tol=tol)
    t3 = time.perf_counter()
    return RigidRegionSolution(basis=basis, displacements=np.asarray(T @ X), master=X[n:], n_dofs=int(A.shape[0]),
                               iterations=tuple(its), residuals=tuple(res),
                               timings_s={"assemble": t1 - t0, "reduce": t2 - t1, "amg_setup": t_setup,
                                          "solve": t3 - t2 - t_setup})


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


def richardson(coarse: float, medium: float, fine: float, *, ratio: float = REFINEMENT_RATIO) -> Richardson:
    """Observed order p = ln((f1−f2)/(f2−f3))/ln r and f∞ = f3 + (f3−f2)/(r^p − 1)."""
    d1, d2 = coarse - medium, medium - fine
    if d1 == 0.0 or d2 == 0.0 or d1 / d2 <= 0.0:
        return Richardson(extrapolated=fine, order=float("nan"), ratio=ratio)
    p = math.log(d1 / d2) / math.log(ratio)
    return Richardson(extrapolated=fine + (fine - medium) / (ratio**p - 1.0), order=p, ratio=ratio)


# ----------------------------------------------------------------------------- 3-PRRR solid
def frame_segments(design, *, p=(0.0, 0.0, 0.0), branch: int = 0) -> list[dict[str, Any]]:
    """Centre-line segments [m] of the frame model (bonded offsets as beams), per leg.

    Each entry: x1, x2, zref (thickness direction), leg, name, clamp (x1 is the rail point).
    """
    from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
    import jax.numpy as jnp

    from hapticopt.analysis.prrr import frame_model as fm
    from hapticopt.design.prrr.kinematics import inverse_kinematics, leg_chain, leg_frames

    fp = fm.frame_params_of(design)
    kin = fp.kin
    p = np.asarray(p, dtype=float)
    ik = inverse_kinematics(kin, jnp.asarray(p))
    pts = leg_chain(kin, ik.sliders, ik.theta[branch])
    f = leg_frames(kin.beta)
    out = []
    r4, d4, r_p = float(kin.r4), float(kin.d4), float(fp.r_p)
    for i in range(3):
        w, u = np.asarray(f.w[i]), np.asarray(f.u[i])
        S = float(ik.sliders[i]) * np.array([0.0, 0.0, 1.0]) + r_p * u
        A, B, Q = (np.asarray(x[i]) for x in (pts.a, pts.b, pts.q))
        Bp = Q - r4 * w
        e4 = (Bp - B) / d4
        out += [
            dict(x1=S, x2=A, zref=w, leg=i, name="carriage_arm", clamp=True),
            dict(x1=A, x2=B, zref=w, leg=i, name="link_d3", clamp=False),
            dict(x1=B, x2=Bp, zref=w, leg=i, name="link_d4", clamp=False),
            dict(x1=Bp, x2=Q, zref=np.cross(w, e4), leg=i, name="offset_r4", clamp=False),
            dict(x1=Q, x2=p, zref=w, leg=i, name="platform_arm", clamp=False),
        ]
    return out


def prrr_mesh(design, *, size: float, p=(0.0, 0.0, 0.0), branch: int = 0) -> tuple[TetMesh, list[dict[str, Any]]]:
    """Mesh of the frame-equivalent solid (see module docstring); size [m]."""
    s = design.structure
    b, t = s.link_width * 1e3, s.link_thickness * 1e3
    ext = 0.5 * s.boss_diameter * 1e3  # the boss radius: same rigid zone as the frame model
    segs = frame_segments(design, p=p, branch=branch)
    gmsh = _gmsh_start("prrr")
    vols = []
    for seg in segs:
        x1, x2 = seg["x1"] * 1e3, seg["x2"] * 1e3
        d = x2 - x1
        L = float(np.linalg.norm(d))
        ex = d / L
        z = seg["zref"] - np.dot(seg["zref"], ex) * ex
        ez = z / np.linalg.norm(z)
        ey = np.cross(ez, ex)
        lo = 0.0 if seg["clamp"] else -ext
        tag = gmsh.model.occ.addBox(lo, -b / 2, -t / 2, L + ext - lo, b, t)
        R = np.stack([ex, ey, ez], axis=1)  # local -> global
        gmsh.model.occ.affineTransform([(3, tag)], list(np.concatenate([R, x1[:, None]], axis=1).ravel()))
        vols.append(tag)
    fused, _ = gmsh.model.occ.fuse([(3, vols[0])], [(3, v) for v in vols[1:]])
    gmsh.model.occ.removeAllDuplicates()
    gmsh.model.occ.synchronize()
    volumes = [tag for dim, tag in gmsh.model.getEntities(3)]
    groups = {}
    for seg in segs:
        if seg["clamp"]:
            tags = _surfaces_at(gmsh, seg["x1"] * 1e3, 1e-3 * b)
            if not tags:
                gmsh.finalize()
                raise RuntimeError(f"no support face found at the rail of leg {seg['leg'] + 1}")
            groups[f"support_leg{seg['leg'] + 1}"] = tags
    mesh = _gmsh_mesh(gmsh, size * 1e3, groups, volumes)
    del fused
    return mesh, segs


@dataclass(frozen=True, kw_only=True)
class PrrrFeaResult:
    """Solid-FEA stiffness of the frame-equivalent 3-PRRR solid (bonded joints) [SI]."""

    compliance_ee: np.ndarray  # (6, 6) at P
    stiffness_load: np.ndarray  # (3,) [N/m] at P + Δz e_z
    load_height: float
    size: float  # mesh size [m]
    n_dofs: int
    iterations: tuple[int, ...]
    wall_s: float
    timings_s: dict[str, float]
    status: Status = Status.OK
    message: str = ""
    mesh: TetMesh | None = None
    displacement: np.ndarray | None = None  # (3, n_nodes) [m] under a unit lateral force at the load point


def prrr_level_size(design, level: int) -> float:
    """Mesh size [m] of refinement ``level``: link thickness / √2^level."""
    return float(design.structure.link_thickness) / REFINEMENT_RATIO**level


def prrr_fea(design, *, level: int = DEFAULT_PRRR_LEVEL, size: float | None = None, p=(0.0, 0.0, 0.0),
             load_height: float | None = None, keep_fields: bool = True, branch: int = 0) -> PrrrFeaResult:
    """Stiffness of the frame-equivalent solid at the load point (6 load cases, one AMG hierarchy)."""
    from hapticopt.analysis.prrr import frame_model as fm

    t0 = time.perf_counter()
    h = fm.LOAD_HEIGHT if load_height is None else float(load_height)
    size = prrr_level_size(design, level) if size is None else size
    s = design.structure
    p = np.asarray(p, dtype=float)
    try:
        mesh, _ = prrr_mesh(design, size=size, p=p, branch=branch)
    except Exception as exc:  # gmsh/OCC failures become a status
        return PrrrFeaResult(compliance_ee=np.full((6, 6), np.nan), stiffness_load=np.full(3, np.nan),
                             load_height=h, size=size, n_dofs=0, iterations=(), wall_s=time.perf_counter() - t0,
                             timings_s={}, status=Status.FAILED, message=f"meshing failed: {exc}")
    t_mesh = time.perf_counter() - t0
    hub_r = 0.75 * s.link_width
    hub_nodes = np.nonzero(np.linalg.norm(mesh.points - p[:, None], axis=0) < hub_r)[0]
    state = {}

    def loads(basis):
        # hub DOFs: every DOF located within hub_r of P (vertex and edge DOFs)
        x = basis.doflocs
        in_hub = np.linalg.norm(x - p[:, None], axis=0) < hub_r
        R = rigid_body_modes(basis, centre=p)[in_hub]  # (n_hub, 6)
        G = np.linalg.inv(R.T @ R)
        F = np.zeros((basis.N, 6))
        F[in_hub] = R @ G  # min-norm nodal forces with resultant wrench = unit vector
        state.update(in_hub=in_hub, fit=G @ R.T)
        return F

    names = [n for n in mesh.node_sets if n.startswith("support")]
    sol = solve_elasticity(mesh, youngs_modulus=s.youngs_modulus, poisson_ratio=s.poisson_ratio, fixed=names,
                           loads=loads)
    C = state["fit"] @ sol.displacements[state["in_hub"]]  # (6, 6): rigid hub motion per unit wrench
    C = 0.5 * (C + C.T)
    H = np.concatenate([np.eye(3), -np.array([[0, -h, 0], [h, 0, 0], [0, 0, 0]])], axis=1)
    C_load = H @ C @ H.T
    stiffness = 1.0 / np.diagonal(C_load)
    disp = None
    if keep_fields:
        # displacement at the mesh vertices for a unit x force at the load point
        wrench = H.T @ np.array([1.0, 0.0, 0.0])
        u = sol.displacements @ wrench
        comps = _component_dofs(sol.basis)
        disp = np.stack([u[comps[c][: mesh.points.shape[1]]] for c in range(3)])
    status, message = Status.OK, ""
    if not np.all(np.isfinite(stiffness)) or np.any(stiffness <= 0):
        status, message = Status.SINGULAR, "FEA stiffness not positive (insufficient supports?)"
    del hub_nodes
    return PrrrFeaResult(compliance_ee=C, stiffness_load=stiffness, load_height=h, size=size, n_dofs=sol.n_dofs,
                         iterations=sol.iterations, wall_s=time.perf_counter() - t0,
                         timings_s={"mesh": t_mesh, **sol.timings_s}, status=status, message=message,
                         mesh=mesh if keep_fields else None, displacement=disp)


# ----------------------------------------------------------------------------- plots
def plot_structure(design, result, out_dir: Path) -> list[Path]:
    """PNG of the deformed frame under a lateral load; at fine fidelity also the FEA field."""
    import pyvista as pv

    from hapticopt.analysis.prrr import frame_model as fm
    from hapticopt.design.atomic import atomic_path

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
    pl = pv.Plotter(off_screen=True, window_size=(900, 700))
    for i in range(3):
        x_leg = np.concatenate([uP, -rec[i] @ uP])
        u_nodes = np.einsum("kij,j->ki", maps[i], x_leg)[:, :3]
        pts = np.vstack([nodes[i], result.pose[None]])
        upts = np.vstack([u_nodes, uP[None, :3]])
        for def_scale, color in ((0.0, "lightgray"), (scale, "crimson")):
            line = pv.lines_from_points(pts + def_scale * upts)
            pl.add_mesh(line, color=color, line_width=4)
    pl.add_text(f"frame, 1 N along x at Δz = {h * 1e3:g} mm (×{scale:.3g})", font_size=10)

    def save(plotter, name):
        target = out_dir / name
        with atomic_path(target) as tmp:
            plotter.screenshot(str(tmp))
        plotter.close()
        written.append(target)

    save(pl, "structure_frame.png")
    fea_res = getattr(result, "fea", None)
    if fea_res is not None and fea_res.mesh is not None and fea_res.displacement is not None:
        mesh = fea_res.mesh
        cells = np.hstack([np.full((mesh.tets.shape[1], 1), 4), mesh.tets.T]).ravel()
        grid = pv.UnstructuredGrid(cells, np.full(mesh.tets.shape[1], pv.CellType.TETRA), mesh.points.T.copy())
        grid.point_data["displacement_um_per_N"] = np.linalg.norm(fea_res.displacement, axis=0) * 1e6
        grid.point_data["u"] = fea_res.displacement.T
        sc = 0.1 * span / max(float(np.abs(fea_res.displacement).max()), 1e-30)
        warped = grid.warp_by_vector("u", factor=sc)
        pl = pv.Plotter(off_screen=True, window_size=(900, 700))
        pl.add_mesh(warped, scalars="displacement_um_per_N", show_edges=False)
        pl.add_text(f"CAD FEA (bonded pins), 1 N along x at Δz = {h * 1e3:g} mm (×{sc:.3g})", font_size=10)
        save(pl, "structure_fea.png")
        st = getattr(result, "fea_stress", None)  # computed by the evaluator at fine fidelity
        if st is None:
            from hapticopt.analysis.prrr.structure import fea_element_stress

            st = fea_element_stress(design, fea_res)
        if st is not None:  # von Mises from the P2 field (analysis.fea_stress), per element
            grid.cell_data["von_mises_MPa_per_N"] = st.von_mises * 1e-6
            warped = grid.warp_by_vector("u", factor=sc)
            pl = pv.Plotter(off_screen=True, window_size=(900, 700))
            # the peak sits in a few pin elements: colours up to the 99th percentile, above in magenta
            top = float(np.percentile(st.von_mises, 99.0)) * 1e-6
            pl.add_mesh(warped, scalars="von_mises_MPa_per_N", preference="cell", show_edges=False,
                        clim=(0.0, top), above_color="magenta",
                        scalar_bar_args={"title": "von Mises [MPa per N]", "above_label": "> 99 %"})
            pl.add_point_labels(warped.cell_centers().points[st.max_element][None], ["max"], point_size=12,
                                point_color="black", render_points_as_spheres=True, always_visible=True)
            xm = st.max_location * 1e3
            pl.add_text(f"CAD FEA von Mises stress, 1 N along x at Δz = {h * 1e3:g} mm (×{sc:.3g})\n"
                        f"max {st.max_von_mises * 1e-6:.3g} MPa/N (element centroid) at "
                        f"({xm[0]:.1f}, {xm[1]:.1f}, {xm[2]:.1f}) mm", font_size=10)
            save(pl, "structure_fea_stress.png")
    return written

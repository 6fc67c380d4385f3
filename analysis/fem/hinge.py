"""Hinge release in the solid FEA: frictionless bilateral cylindrical interfaces at the pins.

The bonded CAD FEA (:mod:`hapticopt.analysis.prrr.structure.fea_cad`) fuses every pin into both parts of its joint (gmsh
``fragment`` makes the bore surfaces conformal). Here the revolute joints are **released**, the
solid counterpart of ``FrameOptions(joints=Joints.RELEASED)``:

* each pin stays bonded to one of its two parts; on the bore surface of the other part (the
  "released" part) the mesh is split: the interface nodes are duplicated, the released part's
  tetrahedra get the copies (:func:`split_hinges`);
* every coincident DOF pair (P2: vertex and edge-midpoint DOFs; p on the pin side, q on the
  part side) is tied in the radial direction n (from the pin axis through the DOF location) and
  along the axis w, and free in the tangential direction t = w × n: u_q = u_p + s t with one new
  scalar unknown s per pair (:func:`hinge_ties`). A rigid rotation of the part about the pin axis
  (u = ω w × (x − a) = ω |x − a|⊥ t at every DOF location) satisfies the ties exactly, so the
  joint turns freely, while radial and axial force and the tilting moments pass by bearing.

The ties are imposed by elimination (u = T q, K_red = Tᵀ K T, as the rigid region of
:func:`hapticopt.analysis.fem.solid.solve_with_rigid_region`), never by penalties; q = [free node DOFs (node
blocks of 3, the part-side copies of tied DOF locations removed) | s (padded to blocks of 3) |
six rigid-region master DOFs]. The AMG near-nullspace is the six rigid-body modes expressed in q:
a rigid motion needs s = 0 (pin and part move together), and the masters carry identity rows.

Which side is released (``side``): "frame" (default) as the frame model's pin option, the hinge at
the pin's link-side end: R1's pin bonded to the carriage clevis and released in link1, R2's bonded
to link1 and released in link2, R3's bonded to the platform lug and released in link2's R3 boss;
"swapped" releases the other bore of every joint (carriage, link1, platform).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from hapticopt.analysis.fem import solid as fea
from hapticopt.analysis.fem.linsolve import Method
from hapticopt.analysis.status import Status
import scipy.sparse as sp



@dataclass(frozen=True, kw_only=True)
class Hinge:
    """One released joint [m]: the pin's and the released part's volume names, the pin axis."""

    name: str
    pin: str  # node set of the pin volume
    part: str  # node set of the part released from the pin (its bore is the interface)
    point: np.ndarray  # (3,) a point on the axis [m]
    axis: np.ndarray  # (3,) unit direction of the axis
    radius: float  # bore radius [m]


@dataclass(frozen=True, kw_only=True)
class SplitMesh:
    """The mesh with every hinge interface split, and the duplicated vertex pairs per hinge."""

    mesh: fea.TetMesh
    pairs: tuple[np.ndarray, ...]  # per hinge (2, n): [pin-side vertex; part-side copy]
    hinges: tuple[Hinge, ...]


def _tets_of(tets: np.ndarray, nodes: np.ndarray, n_nodes: int) -> np.ndarray:
    """Tetrahedra whose four nodes are all in ``nodes``."""
    inside = np.zeros(n_nodes, dtype=bool)
    inside[nodes] = True
    return np.all(inside[tets], axis=0)


def split_hinges(mesh: fea.TetMesh, hinges: list[Hinge] | tuple[Hinge, ...], *, tol: float = 1e-7) -> SplitMesh:
    """Duplicate the nodes of every pin/bore interface; the released part's tets take the copies.

    A tetrahedron belongs to the pin when its four nodes are pin nodes (a part tetrahedron cannot
    have all four nodes on the shared bore surface: their convex hull lies inside the pin), to
    the released part when its four nodes are part nodes and it is not a pin tetrahedron. The
    shared nodes must lie on the bore cylinder (``tol`` [m]); otherwise the joint is not a clean
    pin-in-bore interface and a ``RuntimeError`` names it.
    """
    points = mesh.points
    tets = mesh.tets.copy()
    node_sets = {k: v.copy() for k, v in mesh.node_sets.items()}
    new_points = [points]
    all_pairs = []
    for h in hinges:
        allp = np.concatenate(new_points, axis=1)
        pin_t = _tets_of(tets, node_sets[h.pin], allp.shape[1])
        part_t = _tets_of(tets, node_sets[h.part], allp.shape[1]) & ~pin_t
        shared = np.intersect1d(np.unique(tets[:, pin_t]), np.unique(tets[:, part_t]))
        if shared.size == 0:
            raise RuntimeError(f"hinge {h.name}: the pin {h.pin} shares no nodes with {h.part}")
        d = allp[:, shared] - h.point[:, None]
        radial = np.linalg.norm(d - np.outer(h.axis, h.axis @ d), axis=0)
        if np.max(np.abs(radial - h.radius)) > tol:
            raise RuntimeError(f"hinge {h.name}: {h.pin}/{h.part} interface node off the bore cylinder by "
                               f"{np.max(np.abs(radial - h.radius)):.3g} m (allowed {tol:g} m)")
        copy = np.full(allp.shape[1], -1, dtype=np.int64)
        start = copy.size
        copy[shared] = start + np.arange(shared.size)
        sub = tets[:, part_t]
        is_shared = copy[sub] >= 0
        sub[is_shared] = copy[sub[is_shared]]
        tets[:, part_t] = sub
        new_points.append(allp[:, shared])
        # node sets: the released part's set takes the copies, the pin's keeps the originals (a shared
        # node was in both); other sets (supports) keep the originals — reduction() refuses a tie on them
        pset = node_sets[h.part]
        keep = copy[pset] < 0 if pset.size else np.zeros(0, dtype=bool)
        node_sets[h.part] = np.concatenate([pset[keep], copy[pset[~keep]]])
        all_pairs.append(np.stack([shared, copy[shared]]))
    return SplitMesh(mesh=fea.TetMesh(points=np.concatenate(new_points, axis=1), tets=tets, node_sets=node_sets),
                     pairs=tuple(all_pairs), hinges=tuple(hinges))


@dataclass(frozen=True, kw_only=True)
class Ties:
    """Tied DOF locations: u_q = u_p + s t (radial and axial tied, tangential free)."""

    pin_dofs: np.ndarray  # (m, 3) global DOF indices (x, y, z) of the pin-side location p
    part_dofs: np.ndarray  # (m, 3) of the part-side copy q (eliminated)
    tangent: np.ndarray  # (m, 3) unit tangent t = w × n at the location
    hinge: np.ndarray  # (m,) index of the hinge


def hinge_ties(basis, split: SplitMesh) -> Ties:
    """Coincident P2 DOF locations of every split interface: vertex pairs and the midpoints of
    interface edges (a pin-side edge (a, b) whose copy (a', b') is a part-side edge)."""
    m = basis.mesh
    edges = m.edges  # (2, n_edges), sorted per column
    nv = m.nvertices
    keys = edges[0].astype(np.int64) * nv + edges[1]
    order = np.argsort(keys)
    skeys = keys[order]

    def edge_index(a, b):
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        k = lo.astype(np.int64) * nv + hi
        pos = np.clip(np.searchsorted(skeys, k), 0, skeys.size - 1)
        found = skeys[pos] == k
        return np.where(found, order[pos], -1)

    pin_dofs, part_dofs, tangent, which = [], [], [], []
    for j, (h, pr) in enumerate(zip(split.hinges, split.pairs)):
        copy = np.full(nv, -1, dtype=np.int64)
        copy[pr[0]] = pr[1]
        # vertex DOFs
        p_loc = [basis.nodal_dofs[:, pr[0]].T]
        q_loc = [basis.nodal_dofs[:, pr[1]].T]
        # edge DOFs: pin-side edges with both ends on the interface whose copy exists
        both = (copy[edges[0]] >= 0) & (copy[edges[1]] >= 0)
        e_pin = np.nonzero(both)[0]
        e_part = edge_index(copy[edges[0, e_pin]], copy[edges[1, e_pin]])
        ok = e_part >= 0
        p_loc.append(basis.edge_dofs[:, e_pin[ok]].T)
        q_loc.append(basis.edge_dofs[:, e_part[ok]].T)
        P, Q = np.concatenate(p_loc), np.concatenate(q_loc)
        x = basis.doflocs[:, P[:, 0]]
        if not np.allclose(x, basis.doflocs[:, Q[:, 0]], rtol=0.0, atol=1e-12):
            raise RuntimeError(f"hinge {h.name}: tied DOF locations do not coincide")
        d = x - h.point[:, None]
        nrm = d - np.outer(h.axis, h.axis @ d)
        nrm /= np.linalg.norm(nrm, axis=0)
        t = np.cross(h.axis, nrm.T)
        pin_dofs.append(P)
        part_dofs.append(Q)
        tangent.append(t)
        which.append(np.full(P.shape[0], j))
    return Ties(pin_dofs=np.concatenate(pin_dofs), part_dofs=np.concatenate(part_dofs),
                tangent=np.concatenate(tangent), hinge=np.concatenate(which))


@dataclass(frozen=True, kw_only=True)
class Reduction:
    """u = T q for the reduced unknowns q = [free node DOFs | s (padded) | 6 masters]."""

    T: object  # scipy.sparse (n_full, n_red)
    free: np.ndarray  # full DOF indices of the free node DOFs (node blocks of 3)
    n_ties: int  # number of s unknowns (before padding)
    n_pad: int
    n_master: int
    #: (n_red, 6 or 7) AMG near-nullspace in q: the six rigid-body modes (s = 0, masters: identity
    #: rows) and, with ties, the hinge mode (s = 1, all else 0: locally a relative rotation of the
    #: part about the pin; without it the interface aggregates cannot represent the hinge and CG
    #: needs ~40 % more iterations, docs/structure_hinge.md)
    B: np.ndarray


def reduction(basis, *, fixed: np.ndarray, ties: Ties | None, region: np.ndarray | None = None,
              centre=(0.0, 0.0, 0.0)) -> Reduction:
    """The elimination map of supports (``fixed`` DOFs, u = 0), hinge ties and an optional rigid
    ``region`` (bool per DOF, moving rigidly with six master DOFs about ``centre``)."""

    N = basis.N
    modes = fea.rigid_body_modes(basis, centre=centre)
    fixed_mask = np.zeros(N, dtype=bool)
    fixed_mask[fixed] = True
    in_region = np.zeros(N, dtype=bool) if region is None else np.asarray(region, dtype=bool).copy()
    in_region[fixed_mask] = False
    m = 0 if ties is None else ties.pin_dofs.shape[0]
    if m:
        bad = fixed_mask[ties.part_dofs] | in_region[ties.part_dofs] | fixed_mask[ties.pin_dofs] | in_region[ties.pin_dofs]
        if np.any(bad):
            raise RuntimeError("a hinge interface touches a support or the rigid region")
    free = ~fixed_mask & ~in_region
    if m:
        free[ties.part_dofs.ravel()] = False
    I = np.nonzero(free)[0]
    n = I.size
    pad = (-m) % 3
    n_master = 6 if in_region.any() else 0
    n_red = n + m + pad + n_master
    rows = [I]
    cols = [np.arange(n)]
    vals = [np.ones(n)]
    if m:
        # u_q = u_p + s t: the pin-side column of each component (only where p is free), and s
        P, Q, t = ties.pin_dofs, ties.part_dofs, ties.tangent
        col_of = np.full(N, -1, dtype=np.int64)
        col_of[I] = np.arange(n)
        rows += [Q.ravel(), Q.ravel()]
        cols += [col_of[P.ravel()], np.repeat(n + np.arange(m), 3)]
        vals += [np.ones(3 * m), t.ravel()]
        if np.any(col_of[P.ravel()] < 0):
            raise RuntimeError("a pin-side DOF of a hinge tie is not free")
    if n_master:
        Rg = np.nonzero(in_region)[0]
        rows.append(np.repeat(Rg, 6))
        cols.append(n + m + pad + np.tile(np.arange(6), Rg.size))
        vals.append(modes[Rg].ravel())
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, n_red))
    B = np.zeros((n_red, 7 if m else 6))
    B[:n, :6] = modes[I]
    if n_master:
        B[n + m + pad:, :6] = np.eye(6)
    if m:  # the hinge mode: a relative rotation about the pin axis is s = |x − a|⊥ ω (bore radius ≈ 1)
        B[n:n + m, 6] = 1.0
    return Reduction(T=T, free=I, n_ties=m, n_pad=pad, n_master=n_master, B=B)


def reduced_matrix(K, red: Reduction):
    """K_red = Tᵀ K T (symmetrised); padding unknowns get a unit diagonal scaled like K."""

    A = (red.T.T @ K @ red.T).tocsr()
    A = 0.5 * (A + A.T)
    if red.n_pad:
        n = red.free.size + red.n_ties
        d = np.zeros(A.shape[0])
        d[n:n + red.n_pad] = float(np.mean(K.diagonal()))
        A = (A + sp.diags(d)).tocsr()
    return A


@dataclass(frozen=True, kw_only=True)
class ReleasedSolution:
    basis: object
    displacements: np.ndarray  # (n_full, n_cases) [m]
    master: np.ndarray  # (6, n_cases)
    n_dofs: int
    n_ties: int
    iterations: tuple[int, ...]
    residuals: tuple[float, ...]
    timings_s: dict[str, float]
    solver: str = ""  # linear-solver backend (hapticopt.analysis.fem.linsolve)
    status: Status = Status.OK  # singular: no equilibrium (fields NaN)
    rcond: float = float("nan")
    message: str = ""


def solve_released(split: SplitMesh, *, youngs_modulus: float, poisson_ratio: float, fixed: list[str], region,
                   centre, wrenches: np.ndarray, tol: float = 1e-7, amg_blocks: bool = False,
                   method: Method = Method.AUTO) -> ReleasedSolution:
    """:func:`hapticopt.analysis.fem.solid.solve_with_rigid_region` with the hinge ties of ``split`` eliminated too.

    ``amg_blocks`` (AMG-CG only): aggregate 3×3 blocks (the s unknowns padded into triples) instead
    of scalar DOFs; scalar aggregation needed fewer CG iterations here (docs/structure_hinge.md).
    """
    t0 = time.perf_counter()
    _, basis, K, D = fea.assemble_clamped(split.mesh, youngs_modulus=youngs_modulus, poisson_ratio=poisson_ratio,
                                          fixed=fixed)
    t1 = time.perf_counter()
    ties = hinge_ties(basis, split)
    red = reduction(basis, fixed=D, ties=ties, region=region(basis), centre=centre)
    A = reduced_matrix(K, red)
    n_head = red.free.size + red.n_ties + red.n_pad
    rhs = np.vstack([np.zeros((n_head, wrenches.shape[1])), np.asarray(wrenches, dtype=float)])
    I = red.free
    blocked = I.size % 3 == 0 and np.all(I[0::3] % 3 == 0) and np.all(np.diff(I.reshape(-1, 3), axis=1) == 1)
    t2 = time.perf_counter()
    lin = fea.solve_system(A, red.B, rhs, blocked=bool(blocked) and amg_blocks, tol=tol, method=method)
    return ReleasedSolution(basis=basis, displacements=np.asarray(red.T @ lin.x), master=lin.x[n_head:],
                            n_dofs=int(A.shape[0]), n_ties=red.n_ties, iterations=lin.iterations,
                            residuals=lin.residuals,
                            timings_s={"assemble": t1 - t0, "reduce": t2 - t1, **fea.solver_timings(lin)},
                            solver=lin.backend, status=lin.status, rcond=lin.rcond, message=lin.message)

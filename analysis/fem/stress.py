"""Von Mises stress per element from a quadratic-tetrahedron (P2) displacement field.

Linear elasticity, small strain: ε = ½(∇u + ∇uᵀ), σ = λ tr(ε) I + 2μ ε, and
σ_vM = √(3/2 s:s) with s the deviator of σ. The displacement gradient of the 10-node
tetrahedron is evaluated from its shape functions in barycentric coordinates λ:

    ∇u = Σ_vertices u_i (4λ_i − 1) ∇λ_i + Σ_edges(a,b) u_ab · 4(λ_a ∇λ_b + λ_b ∇λ_a)

(u_ab the value at the edge midpoint, the P2 Lagrange DOF of skfem's ``ElementTetP2``), so the
strain and stress are **linear inside each element**: the value at the centroid is the element
mean, and the element's extreme von Mises value lies at one of its vertices (σ_vM is convex in
σ). Both are returned. Given only vertex displacements (a P1 field) the stress is the constant
one of the linear interpolant — one order less accurate; the result says which it used.

Units: SI in, SI out; for a displacement field per newton of load the stress is in Pa per N.
The gradient code is plain numpy (memory ∝ number of elements, no quadrature tables); it is
tested against scikit-fem's own interpolation in tests/analysis/fem/test_stress.py.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

#: vertex pairs of the six edges of a tetrahedron in skfem's local order (RefTet.edges), the
#: order of ElementTetP2's edge DOFs and of ``MeshTet.t2e``
TET_EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))


@dataclass(frozen=True, kw_only=True)
class ElementStress:
    """Stress of every tetrahedron for one load case [Pa] (Pa per N for a unit-load field)."""

    centroids: np.ndarray  # (3, n_tets) [m]
    stress: np.ndarray  # (n_tets, 3, 3) [Pa] Cauchy stress at the centroid (the element mean)
    von_mises: np.ndarray  # (n_tets,) [Pa] at the centroid
    von_mises_vertices: np.ndarray  # (4, n_tets) [Pa] at the element's vertices (P2: its extremes)
    max_von_mises: float  # [Pa] largest centroid value
    max_location: np.ndarray  # (3,) [m] centroid of that element
    max_element: int
    peak_von_mises: float  # [Pa] largest vertex value (mesh-dependent at re-entrant corners)
    peak_location: np.ndarray  # (3,) [m]
    order: int  # 2: P2 field (vertices + edge midpoints); 1: vertex values only
    wall_s: float


def p2_nodal_values(basis, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split a skfem ``ElementVector(ElementTetP2())`` DOF vector (n_dofs,) into vertex values
    (3, n_vertices) and edge-midpoint values (3, n_edges) [same unit], edges in
    ``basis.mesh.edges`` order."""
    dofs = np.asarray(dofs)
    vert = np.stack([dofs[basis.nodal_dofs[c]] for c in range(3)])
    edge = np.stack([dofs[basis.edge_dofs[c]] for c in range(3)])
    return vert, edge


def von_mises(stress: np.ndarray) -> np.ndarray:
    """σ_vM [Pa] of stress tensors (..., 3, 3)."""
    s = stress - np.trace(stress, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) / 3.0
    return np.sqrt(1.5 * np.einsum("...ij,...ij->...", s, s))


def _stress_from_gradient(grad: np.ndarray, lam: float, mu: float) -> np.ndarray:
    eps = 0.5 * (grad + np.swapaxes(grad, -1, -2))
    return lam * np.trace(eps, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) + 2.0 * mu * eps


def element_stress(points: np.ndarray, tets: np.ndarray, u_vertices: np.ndarray, u_edges: np.ndarray | None = None,
                   *, youngs_modulus: float, poisson_ratio: float) -> ElementStress:
    """Stress per tetrahedron of the displacement field ``u`` on the mesh (``points`` (3, n) [m],
    ``tets`` (4, n_tets)).

    ``u_vertices`` (3, n_vertices) [m]; ``u_edges`` (3, n_edges) [m] the edge-midpoint values of
    a P2 field with edges numbered as ``skfem.MeshTet(points, tets).edges`` (what
    :func:`p2_nodal_values` returns for the basis the field was solved on), or None for the
    vertex (P1) field only. ``youngs_modulus`` [Pa], ``poisson_ratio`` [-].
    """
    t0 = time.perf_counter()
    points = np.asarray(points, dtype=float)
    u_vertices = np.asarray(u_vertices, dtype=float)
    if u_edges is not None:
        from skfem import MeshTet

        m = MeshTet(np.ascontiguousarray(points), np.ascontiguousarray(tets))
        t, t2e = m.t, m.t2e  # same element order; vertex order as the basis saw it
        u_edges = np.asarray(u_edges, dtype=float)
        if u_edges.shape != (3, m.edges.shape[1]):
            raise ValueError(f"u_edges has shape {u_edges.shape}: expected (3, {m.edges.shape[1]}) (edges of the mesh)")
    else:
        t = np.asarray(tets)
    X = points[:, t]  # (3, 4, n)
    J = np.transpose(X[:, 1:, :] - X[:, :1, :], (2, 0, 1))  # (n, 3, 3): columns x_j − x_0
    G = np.linalg.inv(J)  # rows j: ∇λ_{j+1}
    dlam = np.concatenate([-G.sum(axis=1, keepdims=True), G], axis=1)  # (n, 4, 3): ∇λ_i
    uv = np.transpose(u_vertices[:, t], (2, 1, 0))  # (n, 4, 3): u at local vertex i, component c

    def gradient(bary: np.ndarray) -> np.ndarray:
        """∇u (n, 3 comp, 3 dir) at barycentric point ``bary`` (4,)."""
        if u_edges is None:
            return np.einsum("nic,nid->ncd", uv, dlam)
        g = np.einsum("nic,nid,i->ncd", uv, dlam, 4.0 * bary - 1.0)
        for k, (a, b) in enumerate(TET_EDGES):
            ue = u_edges[:, t2e[k]].T  # (n, 3)
            w = 4.0 * (bary[a] * dlam[:, b] + bary[b] * dlam[:, a])  # (n, 3)
            g += ue[:, :, None] * w[:, None, :]
        return g

    E, nu = float(youngs_modulus), float(poisson_ratio)
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    sigma_c = _stress_from_gradient(gradient(np.full(4, 0.25)), lam, mu)
    vm_c = von_mises(sigma_c)
    vm_v = np.stack([von_mises(_stress_from_gradient(gradient(np.eye(4)[i]), lam, mu)) for i in range(4)])
    centroids = X.mean(axis=1)
    k = int(np.argmax(vm_c))
    iv, kv = np.unravel_index(int(np.argmax(vm_v)), vm_v.shape)
    return ElementStress(centroids=centroids, stress=sigma_c, von_mises=vm_c, von_mises_vertices=vm_v,
                         max_von_mises=float(vm_c[k]), max_location=centroids[:, k].copy(), max_element=k,
                         peak_von_mises=float(vm_v[iv, kv]), peak_location=X[:, iv, kv].copy(),
                         order=1 if u_edges is None else 2, wall_s=time.perf_counter() - t0)

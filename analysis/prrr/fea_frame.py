"""The 3-PRRR's frame-equivalent solid: the frame model's centre lines meshed as one bonded body.

Every frame segment of :mod:`hapticopt.analysis.prrr.frame_model` (carriage arm, d3, d4, r4
offset, platform arm) becomes a rectangular bar of the link section along the frame's centre
line, extended by the boss radius past each joint node (the overlap that the frame's rigid joint
zones stand for) except at the rail, fused into one body. Joints are **bonded** (the fused
overlap is the pin); compare with ``FrameOptions(joints=Joints.BONDED)``. Supports: the
carriage-arm end faces at the rails are clamped (sliders locked). Load: a rigid "hub" — every
node within ``0.75·link_width`` of the end-effector point P — receives the least-squares-
consistent nodal forces of a unit wrench, and its rigid motion is fitted by least squares,
giving the 6×6 compliance at P; the handle to the load point Δz above P is rigid, exactly as in
the frame model. The solver is the generic one of :mod:`hapticopt.analysis.fem.solid`; the CAD
solid (pins, gaps, hinges) is :mod:`hapticopt.analysis.prrr.fea_cad`.
"""

from __future__ import annotations

import math

import time
from dataclasses import dataclass
from typing import Any

import jax.numpy as jnp
import numpy as np

from hapticopt.analysis.fem.solid import (
    REFINEMENT_RATIO,
    TetMesh,
    component_dofs,
    gmsh_mesh,
    gmsh_start,
    rigid_body_modes,
    solve_elasticity,
    surfaces_at,
)
from hapticopt.analysis.prrr import frame_model as fm
from hapticopt.analysis.status import Status
from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.design.prrr.kinematics import inverse_kinematics, leg_chain, leg_frames

#: default mesh level of the PRRR solid for ``--fidelity fine`` (see docs/structure.md)
DEFAULT_PRRR_LEVEL = 1


def frame_segments(design, *, p=(0.0, 0.0, 0.0), branch: int = 0) -> list[dict[str, Any]]:
    """Centre-line segments [m] of the frame model (bonded offsets as beams), per leg.

    Each entry: x1, x2, zref (thickness direction), leg, name, clamp (x1 is the rail point).
    """
    fp = fm.frame_params_of(design)
    kin = fp.kin
    p = np.asarray(p, dtype=float)
    ik = inverse_kinematics(kin, jnp.asarray(p))
    pts = leg_chain(kin, ik.sliders, ik.theta[branch])
    f = leg_frames(kin.beta)
    out = []
    r4, d4, r_p = float(kin.r4), float(kin.d4), float(fp.r_p)
    for i in range(3):
        w, u, t = np.asarray(f.w[i]), np.asarray(f.u[i]), np.asarray(f.t[i])
        th = float(fp.theta_1p)
        S = float(ik.sliders[i]) * np.array([0.0, 0.0, 1.0]) + r_p * (math.cos(th) * u + math.sin(th) * t)
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
    gmsh = gmsh_start("prrr")
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
            tags = surfaces_at(gmsh, seg["x1"] * 1e3, 1e-3 * b)
            if not tags:
                gmsh.finalize()
                raise RuntimeError(f"no support face found at the rail of leg {seg['leg'] + 1}")
            groups[f"support_leg{seg['leg'] + 1}"] = tags
    mesh = gmsh_mesh(gmsh, size * 1e3, groups, volumes)
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
        comps = component_dofs(sol.basis)
        disp = np.stack([u[comps[c][: mesh.points.shape[1]]] for c in range(3)])
    status, message = Status.OK, ""
    if not np.all(np.isfinite(stiffness)) or np.any(stiffness <= 0):
        status, message = Status.SINGULAR, "FEA stiffness not positive (insufficient supports?)"
    del hub_nodes
    return PrrrFeaResult(compliance_ee=C, stiffness_load=stiffness, load_height=h, size=size, n_dofs=sol.n_dofs,
                         iterations=sol.iterations, wall_s=time.perf_counter() - t0,
                         timings_s={"mesh": t_mesh, **sol.timings_s}, status=status, message=message,
                         mesh=mesh if keep_fields else None, displacement=disp)

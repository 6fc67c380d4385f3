"""NumPy fast path of the master's kinematics and dynamics (no jit, no tracing).

The reference implementation is jax (:mod:`hapticopt.design.master.kinematics`,
:mod:`hapticopt.analysis.master.dynamics`); a short CLI call cannot afford its compile time, so the
evaluators use this mirror. Derivatives are taken by the complex step
(f(q + ih·e_k).imag / h, exact to rounding), so the same general body-sum formulas hold:
M = Σ m J_vᵀJ_v + J_ωᵀ R I Rᵀ J_ω + rotor inertia, G = ∂V/∂q. The tests check this module
against the jax reference to ~1e-12.

Shapes: q (n, 3) [rad]; model arrays as in :class:`hapticopt.analysis.master.dynamics.MassModel`.
"""

from __future__ import annotations

import numpy as np

_H = 1e-30  # complex-step size


def frames(kin, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origins (n, 6, 3) and rotations (n, 6, 3, 3) of the six link frames (order of
    :class:`hapticopt.design.master.kinematics.LinkFrames`). Works for real or complex q."""
    q = np.asarray(q)
    t1, t2, t3 = q[:, 0], q[:, 1], q[:, 2]
    c1, s1 = np.cos(t1), np.sin(t1)
    zero, one = np.zeros_like(c1), np.ones_like(c1)
    e_rho = np.stack([c1, s1, zero], -1)
    e_z = np.stack([zero, zero, one], -1)
    axis = np.stack([s1, -c1, zero], -1)
    u = np.cos(t2)[:, None] * e_rho + np.sin(t2)[:, None] * e_z
    f = np.sin(t3)[:, None] * e_rho - np.cos(t3)[:, None] * e_z
    L5, L4, d, h = (float(kin.upper_arm), float(kin.forearm), float(kin.driver_link), float(kin.shoulder_height))
    shoulder = h * e_z
    elbow = shoulder + L5 * u
    o = np.stack([0 * e_z, shoulder, shoulder, shoulder - d * f, elbow, elbow + L4 * f], 1)

    def rot(x):  # columns x, a, x × a with a = (s1, −c1, 0)
        cross = np.stack([x[:, 2] * c1, x[:, 2] * s1, -x[:, 0] * c1 - x[:, 1] * s1], -1)
        return np.stack([x, axis, cross], -1)

    R = np.stack([np.stack([e_rho, -axis, e_z], -1), rot(u), rot(-f), rot(u), rot(f), rot(f)], 1)
    return o, R


def body_poses(model, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World CoM (n, nb, 3) and rotation (n, nb, 3, 3) of every body."""
    o, R = frames(model.kin, q)
    sel = np.asarray(model.frame)
    ob = np.einsum("bf,nfi->nbi", sel, o)
    Rb = np.einsum("bf,nfij->nbij", sel, R)
    return ob + np.einsum("nbij,bj->nbi", Rb, np.asarray(model.com)), Rb


def _derivatives(model, q: np.ndarray):
    """Body CoMs, rotations and their derivatives by the complex step: dc (n, nb, 3, k), dR (n, nb, 3, 3, k)."""
    q = np.asarray(q, dtype=float)
    c, R = body_poses(model, q)
    dc, dR = [], []
    for k in range(3):
        qc = q.astype(complex)
        qc[:, k] += 1j * _H
        ck, Rk = body_poses(model, qc)
        dc.append(ck.imag / _H)
        dR.append(Rk.imag / _H)
    return c, R, np.stack(dc, -1), np.stack(dR, -1)


def mass_matrix(model, q: np.ndarray) -> np.ndarray:
    """M(q) (n, 3, 3) [kg·m²] including the rotor inertia."""
    return body_mass_matrices(model, q).sum(axis=1) + np.diag(np.asarray(model.rotor_inertia))


def body_mass_matrices(model, q: np.ndarray) -> np.ndarray:
    """Each body's contribution m J_vᵀJ_v + J_ωᵀ R I Rᵀ J_ω to M(q): (n, nb, 3, 3) [kg·m²] (no rotor inertia).

    Sums over subsets give the mass matrix of part of the arm (e.g. the links without the
    counterweights, the model of a compensating controller) from one set of derivatives.
    """
    _, R, Jv, dR = _derivatives(model, q)
    W = np.einsum("nbikm,nbjk->nbijm", dR, R)
    Jw = np.stack([W[:, :, 2, 1], W[:, :, 0, 2], W[:, :, 1, 0]], 2)  # (n, nb, 3, m)
    Iw = np.einsum("nbij,bjk,nblk->nbil", R, np.asarray(model.inertia), R)
    m = np.asarray(model.mass)
    return np.einsum("b,nbik,nbil->nbkl", m, Jv, Jv) + np.einsum("nbik,nbij,nbjl->nbkl", Jw, Iw, Jw)


def gravity_torque(model, q: np.ndarray) -> np.ndarray:
    """G(q) = ∂V/∂q (n, 3) [N·m], V = g Σ m z."""
    q = np.asarray(q, dtype=float)
    out = []
    g, m = float(model.gravity), np.asarray(model.mass)
    for k in range(3):
        qc = q.astype(complex)
        qc[:, k] += 1j * _H
        c, _ = body_poses(model, qc)
        out.append(g * np.einsum("b,nb->n", m, c[..., 2].imag) / _H)
    return np.stack(out, -1)


def jacobian(kin, q: np.ndarray) -> np.ndarray:
    """Analytic handle Jacobian (n, 3, 3), as :func:`hapticopt.design.master.kinematics.jacobian`."""
    q = np.asarray(q)
    t1, t2, t3 = q[:, 0], q[:, 1], q[:, 2]
    c1, s1, c2, s2, c3, s3 = np.cos(t1), np.sin(t1), np.cos(t2), np.sin(t2), np.cos(t3), np.sin(t3)
    L5, L4 = float(kin.upper_arm), float(kin.forearm)
    rho = L5 * c2 + L4 * s3
    zero = np.zeros_like(rho)
    return np.stack([np.stack([-rho * s1, rho * c1, zero], -1),
                     np.stack([-L5 * s2 * c1, -L5 * s2 * s1, L5 * c2], -1),
                     np.stack([L4 * c3 * c1, L4 * c3 * s1, L4 * s3], -1)], -1)


def moving_mass(model) -> float:
    """Total mass of the bodies moving with θ2/θ3 (not on the turret frame) [kg]."""
    return float(np.sum(np.asarray(model.mass) * (1.0 - np.asarray(model.frame)[:, 0])))

"""The exact discrete-time boundary of a sampled virtual wall: the 1-DOF reference the 3-PRRR's sampled
loop (``hapticopt.analysis.prrr.loop.stability``, ``zwidth``) is checked against.

Mass m with physical damping b, zero-order hold at T, virtual spring K and damper B on a (filtered)
backward-difference velocity; the roots of the closed loop's characteristic polynomial (eigenvalues of
its transition matrix) leave the unit circle at the boundary (Colgate & Schenkel).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from hapticopt.analysis.prrr.loop.stability import _bisect_boundary


def sampled_wall_matrix(*, mass: float, damping: float, stiffness: float, virtual_damping: float, T: float,
                        alpha: float = 0.0) -> np.ndarray:
    """Transition matrix of the sampled wall, state [x, ẋ, x_prev, v_prev].

    Plant m ẍ + b ẋ = u, exact zero-order hold at T; u_k = −K x_k − B v_k with
    v_k = α v_{k−1} + (1 − α)(x_k − x_{k−1})/T (α = 0: Colgate's backward difference).
    """
    Ac = np.array([[0.0, 1.0], [0.0, -damping / mass]])
    aug = np.zeros((3, 3))
    aug[:2, :2] = Ac
    aug[1, 2] = 1.0 / mass
    E = scipy.linalg.expm(aug * T)
    Ad, Bd = E[:2, :2], E[:2, 2]
    # v_k and u_k as rows over [x, ẋ, x_prev, v_prev]
    v_row = np.array([(1 - alpha) / T, 0.0, -(1 - alpha) / T, alpha])
    u_row = -stiffness * np.array([1.0, 0.0, 0.0, 0.0]) - virtual_damping * v_row
    Phi = np.zeros((4, 4))
    Phi[:2, :2] = Ad
    Phi[:2] += np.outer(Bd, u_row)
    Phi[2, 0] = 1.0
    Phi[3] = v_row
    return Phi


def sampled_wall_poles(**kw) -> np.ndarray:
    """Closed-loop poles in z (roots of the characteristic polynomial det(zI − Φ))."""
    return np.roots(np.poly(sampled_wall_matrix(**kw)))


def sampled_wall_boundary(*, mass: float, damping: float, virtual_damping: float, T: float, alpha: float = 0.0,
                          rtol: float = 1e-10) -> float:
    """Largest stable K of the sampled wall [N/m] (spectral radius < 1), by bisection."""

    def stable(K: float) -> bool:
        Phi = sampled_wall_matrix(mass=mass, damping=damping, stiffness=K, virtual_damping=virtual_damping,
                                  T=T, alpha=alpha)
        return float(np.max(np.abs(np.linalg.eigvals(Phi)))) < 1.0

    hi = max(2.0 * damping / T, 1.0)
    if not stable(1e-12 * hi):
        return 0.0
    return _bisect_boundary(stable, 0.0, hi, rtol=rtol)

"""Analytic stability references the closed-loop simulation is checked against.

* SEA force loop with the output locked, seed 002 eq (8):
  f/f_r = η k K_p / (M_m s² + ξ s + k(1 + ηK_p)); bandwidth = −3 dB below the DC gain
  (38.5 Hz at K_p = 45 with Table 4): the evaluator's closed form (the positive root of a quadratic
  in ω², :func:`force_loop_bandwidth_closed_form`, arrays of designs at once) checked against a root
  search (:func:`force_loop_bandwidth`).
* End-effector stiffness limits, eq (14)–(15): diag(k_x, k_y, k_z) = J⁻ᵀ(kI)J⁻¹.
* Eigenvalues of the linearised continuous closed loop (two-mass SEA plant of eq 6 + P(I) force
  loop + virtual spring/damper). Because the rows of J are orthogonal, J Jᵀ is diagonal and
  the loop decouples per Cartesian axis; Routh–Hurwitz of the per-axis quartic
  mM s⁴ + ξM s³ + (cM + mk) s² + ξk s + ηK_p k K with c = k(1 + ηK_p) (zero virtual damping)
  gives the closed form K < k_a (1 + 1/(ηK_p)) → k_a as K_p → ∞ (k_a = k/2, k/2, 3k at β = π/3:
  Fig 13a / eq 15 of seed 002). Both the eigenvalue bisection and the closed form are here.
"""

from __future__ import annotations

from collections.abc import Callable

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from hapticopt.analysis.prrr.geometry import assembly

from hapticopt.analysis.prrr.structure import statics as prrr_statics
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.prrr.kinematics import jacobian
from hapticopt.analysis import conditioning
from hapticopt.analysis.status import Status
from hapticopt.design.prrr.params import PrrrDesign


# --------------------------------------------------------------------------------- SEA force loop
def force_loop_tf(design: PrrrDesign, kp: float) -> tuple[np.ndarray, np.ndarray]:
    """(numerator, denominator) polynomial coefficients in s of eq (8), highest power first."""
    a = design.actuator
    num = np.array([a.efficiency * a.spring * kp])
    den = np.array([a.motor_mass, a.viscous, a.spring * (1.0 + a.efficiency * kp)])
    return num, den


def force_loop_bandwidth(design: PrrrDesign, kp: float) -> float:
    """−3 dB bandwidth of eq (8) relative to its DC gain [Hz]."""
    from scipy.optimize import brentq  # lazy: a heavy import (tests/test_layers.py LAZY)
    num, den = force_loop_tf(design, kp)
    mag = lambda w: abs(np.polyval(num, 1j * w) / np.polyval(den, 1j * w))  # noqa: E731
    target = mag(0.0) / math.sqrt(2.0)
    hi = 1.0
    while mag(hi) > target:
        hi *= 2.0
    return brentq(lambda w: mag(w) - target, 0.0, hi, xtol=1e-12) / (2.0 * math.pi)


def force_loop_bandwidth_closed_form(efficiency, spring, motor_mass, viscous, kp: float):
    """−3 dB bandwidth of eq (8) relative to its DC gain [Hz], in closed form: with
    c = k(1 + ηK_p), |H(jω)|² = |H(0)|²/2 is (c − M_m ω²)² + ξ²ω² = 2c², a quadratic in x = ω²,
    M_m² x² + b x − c² = 0 with b = ξ² − 2cM_m, whose one positive root is taken in the form
    without cancellation (−b + √(b² + 4M_m²c²))/(2M_m²) for b ≤ 0, 2c²/(b + √(…)) for b > 0.
    Scalars or numpy arrays (broadcast: every design of a batch at once, element for element the
    same operations, so the same bits as one design at a time). Agrees with the root search of
    :func:`force_loop_bandwidth` (the reference) to rounding (tests/analysis/prrr/loop/test_stability.py)."""
    c = spring * (1.0 + efficiency * kp)
    b = viscous * viscous - 2.0 * c * motor_mass
    s = np.sqrt(b * b + 4.0 * (motor_mass * c) ** 2)
    x = np.where(b <= 0.0, (s - b) / (2.0 * motor_mass * motor_mass), 2.0 * c * c / np.where(b > 0.0, b + s, 1.0))
    return np.sqrt(x) / (2.0 * math.pi)


# ------------------------------------------------------------------------------ stiffness limits
def stiffness_limits(design: PrrrDesign) -> np.ndarray:
    """k_x, k_y, k_z of eq (14) [N/m]: diagonal of J⁻ᵀ (k I) J⁻¹ (from the statics evaluator)."""
    return prrr_statics.evaluate(design).stiffness_limit.copy()


def stiffness_limit_closed_form(design: PrrrDesign, kp: float, axis: int, *, limits: np.ndarray | None = None) -> float:
    """Continuous-time K limit with zero virtual damping: k_a (1 + 1/(η K_p)) [N/m] (Routh–Hurwitz);
    ``limits``: :func:`stiffness_limits` of ``design`` when the caller has them."""
    limits = stiffness_limits(design) if limits is None else limits
    return float(limits[axis] * (1.0 + 1.0 / (design.actuator.efficiency * kp)))


def continuous_closed_loop(design: PrrrDesign, *, stiffness: np.ndarray, damping: np.ndarray, kp: float,
                           ki: float = 0.0) -> np.ndarray:
    """State matrix of the linearised continuous closed loop (FULL plant, no operator).

    States [D, D_e, Ḋ, Ḋ_e] (+ the force-loop integrals when ``ki`` > 0); control
    F = K_p(f_r − k x) + K_i ∫(f_r − k x), f_r = Jᵀ(−K_v p − B_v ṗ), p = J D_e, exact velocity.
    """
    a = design.actuator
    J = jacobian(design.geometry.beta, xp=np)
    k, Mm, xi, eta, M = a.spring, a.motor_mass, a.viscous, a.efficiency, design.end_effector.mass
    Kv, Bv = np.diag(stiffness), np.diag(damping)
    I, Z = np.eye(3), np.zeros((3, 3))
    # f_r − k x as a linear function of [D, D_e, Ḋ, Ḋ_e]
    err = np.hstack([-k * I, k * I - J.T @ Kv @ J, Z, -J.T @ Bv @ J])
    Minv_out = np.linalg.inv(M * J.T @ J)
    n = 12 + (3 if ki > 0 else 0)
    A = np.zeros((n, n))
    A[0:6, 6:12] = np.eye(6)
    # motor: M_m D̈ = η F − ξ Ḋ − k (D − D_e)
    A[6:9, :12] = (eta * kp * err + np.hstack([-k * I, k * I, -xi * I, Z])) / Mm
    # output: M_e D̈_e = k (D − D_e)
    A[9:12, 0:3] = Minv_out @ (k * I)
    A[9:12, 3:6] = -Minv_out @ (k * I)
    if ki > 0:
        A[6:9, 12:15] = eta * I / Mm
        A[12:15, :12] = ki * err
    return A


def max_real_flexible_eigenvalue(A: np.ndarray) -> float:
    """Largest Re λ of ``A`` once its rigid-body modes are set aside [1/s].

    The free axes keep rigid-body modes at λ = 0, which round-off moves to ±1e-16·max|λ| with a
    kernel-dependent sign. Their number is explicit: the singular values of ``A`` below
    ``RCOND_SINGULAR``·σ_max (:mod:`hapticopt.analysis.conditioning`); that many eigenvalues of
    smallest modulus are dropped, and stability is decided on the others (no tolerance on Re λ).
    """
    sv = np.linalg.svd(A, compute_uv=False)
    n_rigid = int(np.sum(sv < conditioning.RCOND_SINGULAR * sv[0]))
    lam = np.linalg.eigvals(A)
    flexible = lam[np.argsort(np.abs(lam))][n_rigid:]
    return float(np.max(flexible.real)) if flexible.size else -math.inf


def _bisect_boundary(stable: Callable[[float], bool], lo: float, hi: float, *, rtol: float,
                     cap: float = math.inf) -> float:
    """The boundary of ``stable`` above ``lo`` (stable): ``hi`` doubled until unstable (inf beyond
    ``cap``), then bisected to ``rtol`` relative."""
    while stable(hi):
        lo, hi = hi, 2.0 * hi
        if hi > cap:
            return math.inf
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return 0.5 * (lo + hi)


def continuous_stiffness_limit(design: PrrrDesign, *, kp: float, axis: int, damping: float = 0.0,
                               rtol: float = 1e-9) -> float:
    """Largest stable K_v on ``axis`` by bisection on the eigenvalues of :func:`continuous_closed_loop` [N/m]."""

    def stable(K: float) -> bool:
        Kv, Bv = np.zeros(3), np.zeros(3)
        Kv[axis], Bv[axis] = K, damping
        return max_real_flexible_eigenvalue(continuous_closed_loop(design, stiffness=Kv, damping=Bv, kp=kp)) < 0.0

    return _bisect_boundary(stable, 0.0, float(stiffness_limits(design)[axis]), rtol=rtol, cap=1e15)


# ------------------------------------------------------------------------------------- evaluator
@dataclass(frozen=True, kw_only=True)
class StabilityResult:
    force_gain: float
    force_loop_bandwidth: float  # [Hz]
    stiffness_limits: np.ndarray  # (3,) [N/m], eq 14
    continuous_limits: np.ndarray  # (3,) [N/m] at the force gain, zero virtual damping
    status: Status = Status.OK
    message: str = ""

    def metrics(self) -> dict[str, object]:
        """Engineering-unit metrics; NaN unless the status is ok."""
        if self.status is not Status.OK:
            nan = float("nan")
            return {"force_loop_bandwidth_Hz": nan, "closed_loop_stiffness_limit_N_per_mm": [nan] * 3}
        return {
            "force_loop_bandwidth_Hz": float(self.force_loop_bandwidth),
            "closed_loop_stiffness_limit_N_per_mm": [float(x) * 1e-3 for x in self.continuous_limits],
        }


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD, kp: float = 45.0,
             limits: np.ndarray | None = None, shared: Any = None) -> StabilityResult:
    """Force-loop bandwidth and closed-loop stiffness limits of ``design`` at K_p (seed 002's 45).

    Status ``not-assemblable`` (metrics NaN) when the chain does not close
    (:func:`hapticopt.analysis.prrr.geometry.assembly.closure`): the decoupled per-axis loop assumes it.
    ``limits``: :func:`stiffness_limits` of ``design`` when the caller has them; computed once here
    otherwise (from the registry call's shared statics where ``shared``, its
    :class:`hapticopt.analysis.prrr.shared.DesignSteps`, is given). The bandwidth is
    :func:`force_loop_bandwidth_closed_form`.
    """
    del fidelity  # closed forms
    if limits is None and shared is not None:
        limits = shared.statics(design).stiffness_limit.copy()  # stiffness_limits' value
    limits = stiffness_limits(design) if limits is None else np.array(limits, dtype=float)
    return evaluate_many([design], kp=kp, limits=limits[None])[0]


def evaluate_many(designs: list[PrrrDesign], *, kp: float = 45.0, limits: np.ndarray) -> list[StabilityResult]:
    """:func:`evaluate` of many designs with their :func:`stiffness_limits` as the rows of
    ``limits`` (n, 3) [N/m] (the batched draft evaluator's statics rows): the bandwidths and the
    closed-loop limits of every design in one numpy pass, the same operations element for element as
    one design at a time (so the same bits; :func:`evaluate` is this with one design)."""
    a = [d.actuator for d in designs]
    eff = np.array([x.efficiency for x in a], dtype=float)
    bw = force_loop_bandwidth_closed_form(eff, np.array([x.spring for x in a], dtype=float),
                                          np.array([x.motor_mass for x in a], dtype=float),
                                          np.array([x.viscous for x in a], dtype=float), kp)
    limits = np.array(limits, dtype=float).reshape(len(designs), 3)
    cont = limits * (1.0 + 1.0 / (eff * kp))[:, None]  # stiffness_limit_closed_form of each axis
    out = []
    for i, design in enumerate(designs):
        blocked = assembly.closure(design)
        out.append(StabilityResult(force_gain=kp, force_loop_bandwidth=float(bw[i]), stiffness_limits=limits[i],
                                   continuous_limits=cont[i], status=Status.NOT_ASSEMBLABLE if blocked else Status.OK,
                                   message=blocked))
    return out


# ------------------------------------------------------------- exact sampled (discrete) analysis
def axis_scale(design: PrrrDesign, axis: int) -> float:
    """λ_a = ‖row a of J‖: the rows of J are orthogonal, so J = Λ R (R orthogonal) and ζ = R D
    decouples the whole loop per Cartesian axis, with p_a = λ_a ζ_a (λ_x² = 2 at β = π/3: k_x = k/λ²)."""
    J = np.asarray(jacobian(design.geometry.beta, xp=np))
    return float(np.linalg.norm(J[axis]))


def velocity_alpha(T: float, cutoff: float) -> float:
    """Pole of the firmware's first-order velocity filter at period T [s], cut-off [Hz] (0: none)."""
    return math.exp(-2.0 * math.pi * cutoff * T) if cutoff > 0 else 0.0


def _axis_plant(design: PrrrDesign, lam: float, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH (Ad (4, 4), Bd (4,)) of the two-mass SEA plant along one decoupled axis."""
    a = design.actuator
    k, Mm, xi, eta = a.spring, a.motor_mass, a.viscous, a.efficiency
    Mo = design.end_effector.mass * lam**2
    Ac = np.array([
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
        [-k / Mm, k / Mm, -xi / Mm, 0.0],
        [k / Mo, -k / Mo, 0.0, 0.0],
    ])
    aug = np.zeros((5, 5))
    aug[:4, :4], aug[2, 4] = Ac, eta / Mm
    E = scipy.linalg.expm(aug * T)
    return E[:4, :4], E[:4, 4]


def _axis_closed(design: PrrrDesign, lam: float, Ad: np.ndarray, Bd: np.ndarray, *, T: float, kp: float,
                 stiffness: float, damping: float, alpha: float) -> np.ndarray:
    p_row = np.array([0.0, lam, 0.0, 0.0, 0.0, 0.0])
    v_row = (1.0 - alpha) / T * (p_row - np.eye(6)[4]) + alpha * np.eye(6)[5]
    F_row = -stiffness * p_row - damping * v_row
    u_row = kp * (lam * F_row - design.actuator.spring * np.array([1.0, -1.0, 0.0, 0.0, 0.0, 0.0]))
    Phi = np.zeros((6, 6))
    Phi[:4, :4] = Ad
    Phi[:4] += np.outer(Bd, u_row)
    Phi[4] = p_row
    Phi[5] = v_row
    return Phi


def spectral_radius(Phi: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(Phi))))


def sampled_stiffness_limit(design: PrrrDesign, *, axis: int, T: float, kp: float, damping: float = 0.0,
                            alpha: float = 0.0, rtol: float = 1e-6) -> float:
    """Largest stable virtual K on ``axis`` of the sampled loop [N/m] (bisection on the spectral radius).

    0 when the loop is unstable for every K > 0 (the sampled force loop itself has lost
    stability); ``math.inf`` beyond 10¹² N/m.
    """

    lam = axis_scale(design, axis)
    Ad, Bd = _axis_plant(design, lam, T)

    def stable(K: float) -> bool:
        return spectral_radius(_axis_closed(design, lam, Ad, Bd, T=T, kp=kp, stiffness=K, damping=damping,
                                            alpha=alpha)) < 1.0

    lo = 1e-6 * float(stiffness_limits(design)[axis])
    if not stable(lo):
        return 0.0
    return _bisect_boundary(stable, lo, float(stiffness_limits(design)[axis]), rtol=rtol, cap=1e12)


def sampled_force_loop(design: PrrrDesign, *, T: float, kp: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Φ, Γ, C) of the sampled force loop of one leg with the output locked (eq 8 with a ZOH):
    x = [D, Ḋ], x⁺ = Φx + Γ f_r, f = C x; u_k = K_p(f_r − k D_k) held over T."""
    a = design.actuator
    Ac = np.array([[0.0, 1.0], [-a.spring / a.motor_mass, -a.viscous / a.motor_mass]])
    aug = np.zeros((3, 3))
    aug[:2, :2] = Ac
    aug[1, 2] = a.efficiency / a.motor_mass
    E = scipy.linalg.expm(aug * T)
    Ad, Bd = E[:2, :2], E[:2, 2]
    C = np.array([a.spring, 0.0])
    return Ad - kp * np.outer(Bd, C), kp * Bd, C


def sampled_force_loop_bandwidth(design: PrrrDesign, *, T: float, kp: float) -> tuple[bool, float]:
    """(stable, −3 dB bandwidth [Hz] below the DC gain) of the sampled force loop; the bandwidth is
    NaN when the loop is unstable, and the Nyquist frequency 1/(2T) when the gain never drops 3 dB
    below it."""
    from scipy.optimize import brentq  # lazy: a heavy import (tests/test_layers.py LAZY)
    Phi, Gam, C = sampled_force_loop(design, T=T, kp=kp)
    if spectral_radius(Phi) >= 1.0:
        return False, math.nan
    def mag(w):
        z = np.exp(1j * np.atleast_1d(w) * T)
        # (zI − Φ)⁻¹ Γ for a 2×2 Φ in closed form, vectorised over frequencies
        a, b, c, d = Phi[0, 0], Phi[0, 1], Phi[1, 0], Phi[1, 1]
        det = (z - a) * (z - d) - b * c
        x0 = ((z - d) * Gam[0] + b * Gam[1]) / det
        x1 = (c * Gam[0] + (z - a) * Gam[1]) / det
        out = np.abs(C[0] * x0 + C[1] * x1)
        return out if np.ndim(w) else float(out[0])

    target = mag(0.0) / math.sqrt(2.0)
    nyq = math.pi / T
    grid = np.geomspace(1e-3 * nyq, nyq, 400)
    below = np.nonzero(mag(grid) < target)[0]
    if below.size == 0:
        return True, nyq / (2.0 * math.pi)
    i = int(below[0])
    lo = grid[i - 1] if i > 0 else 0.0
    return True, brentq(lambda w: mag(w) - target, lo, grid[i], xtol=1e-12) / (2.0 * math.pi)

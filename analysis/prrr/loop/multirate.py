"""Exact discrete analysis of the 3-PRRR's sampled loop, single- and multi-rate (seed 000 upsampling).

The lumped plant (``lumped_plant.build_model``, two-mass SEA per leg, eq 6–7) in closed loop with the
firmware's linear law (``firmware.step``: p = J D_e, low-passed backward-difference velocity,
virtual spring-damper F = −K p − B v, f_r = Jᵀ F, SEA force loop u = K_p(f_r − k x̂), optionally
the hand of seed 000 eq 1 with its reference at rest) and the seed 000 upsampler on u (AR
prediction of u and the eq 23 spline of ``interpolation_variant``, L = l2/l1 samples per period;
L = 1 is the plain hold whatever the variant, as in the firmware):

    s_i = [z(iT), p_{i−1}, v_{i−1}, u_{i−1}, u_{i−2}],    s_{i+1} = 𝓛 s_i

with z the plant state and the plant stepped L times by its exact zero-order hold at T/L (the same
construction as ``analysis.control.upsampling.lifted_matrix``, here with the 3-PRRR's own state).
Effects that make the loop nonlinear (Coulomb friction, saturation, quantisation) or add offsets
(gravity) are left out: this is the linear loop whose spectral radius decides small-signal stability.

Because the rows of J are orthogonal the loop decouples per Cartesian axis; :func:`axis_eigenvalues`
rotates the leg-space groups by U = S⁻¹J (S = diag|J_row|) and keeps the chosen axis' block, after
checking that the coupling to the other axes is at rounding level (the free axes carry rigid-body
modes at z = 1 that would otherwise mask the verdict).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from hapticopt.analysis.control.upsampling import Variant, spline_weights
from hapticopt.analysis.loop.operator import Operator
from hapticopt.analysis.loop.scene import (ControllerSettings, Effect, EnvKind, Environment, Scene,
                                           resolve)
from hapticopt.analysis.prrr.loop.lumped_plant import PlantMode, build_model, discretise
from hapticopt.design.prrr.kinematics import jacobian
from hapticopt.design.prrr.params import PrrrDesign

#: effects of the linear loop analysed here
LINEAR_EFFECTS = frozenset({Effect.SEA_COMPLIANCE, Effect.MOTOR_DYNAMICS, Effect.VISCOUS_FRICTION, Effect.SAMPLING})
#: |coupling| / |block| above this means the axis does not decouple (a J whose rows are not orthogonal)
COUPLING_BAND = 1e-9
#: ρ within this of 1 is marginal (same band as ``analysis.control.upsampling.LIFTED_RHO_BAND``)
RHO_BAND = 1e-9


@dataclass(frozen=True, kw_only=True)
class LoopSettings:
    """The firmware's linear settings [SI]."""

    period_s: float = 1e-3
    force_gain: float = 45.0  #: K_p
    velocity_filter_Hz: float = 100.0  #: 0 = plain backward difference
    damping_N_s_per_m: float = 0.0  #: B_v on the analysed axis
    upsampling: int = 1  #: L
    variant: Variant = Variant.NONE
    ar: tuple[float, ...] = (2.0, -1.0)
    operator: Operator | None = None  #: seed 000's hand (reference at rest), or none


def linear_scene(settings: LoopSettings, *, axis: int = 0, stiffness_N_per_m: float = 0.0) -> Scene:
    """The scene whose resolved effects and controller are exactly the linear loop analysed here
    (the simulation cross-check runs it through ``closed_loop``)."""
    K = [0.0, 0.0, 0.0]
    B = [0.0, 0.0, 0.0]
    K[axis], B[axis] = stiffness_N_per_m, settings.damping_N_s_per_m
    fx = set(LINEAR_EFFECTS) | ({Effect.OPERATOR} if settings.operator is not None else set())
    off = [0.0, 0.0, 0.0]
    off[axis] = 1e-3
    return Scene(name="multirate", duration=1.0,
                 controller=ControllerSettings(period=settings.period_s, force_gain=settings.force_gain,
                                               velocity_filter=settings.velocity_filter_Hz,
                                               interpolation=settings.upsampling, ar_coefficients=settings.ar,
                                               interpolation_variant=settings.variant),
                 environment=Environment(kind=EnvKind.SPRING, stiffness=tuple(K), damping=tuple(B)),
                 operator=settings.operator if settings.operator is not None else Operator(),
                 initial_offset=tuple(off), effects=frozenset(fx))


def lifted_matrix(design: PrrrDesign, settings: LoopSettings, stiffness_N_per_m: float, *, axis: int = 0,
                  _plant=None) -> np.ndarray:
    """𝓛 over one controller period (module docstring); the virtual spring K_v [N/m] and damper
    ``settings.damping_N_s_per_m`` act along Cartesian ``axis``."""
    sc = linear_scene(settings)
    model = build_model(design, sc, resolve(sc)) if _plant is None else _plant[0]
    if model.mode is not PlantMode.FULL:
        raise ValueError(f"plant mode = {model.mode.value!r}: the multirate analysis needs the full SEA plant")
    T, L = settings.period_s, settings.upsampling
    keep = np.ones(model.n, dtype=bool)  # the hand's reference oscillator is at rest: drop it
    if model.ref_pos is not None:
        keep[model.ref_pos] = keep[model.ref_vel] = False
    n = int(keep.sum())
    d = discretise(model, T / L) if _plant is None else _plant[1]
    Ad, Bd = d.Ad[np.ix_(keep, keep)], d.Bud[keep]
    J = model.J
    a = np.asarray(settings.ar, dtype=float)
    alpha = math.exp(-2.0 * math.pi * settings.velocity_filter_Hz * T) if settings.velocity_filter_Hz > 0 else 0.0
    dim = n + 12
    iz, ipp, iv, iu1, iu2 = slice(0, n), slice(n, n + 3), slice(n + 3, n + 6), slice(n + 6, n + 9), slice(n + 9, n + 12)
    idx = np.flatnonzero(keep)
    pos_out = [int(np.flatnonzero(idx == j)[0]) for j in range(model.out_pos.start, model.out_pos.stop)]
    pos_mot = [int(np.flatnonzero(idx == j)[0]) for j in range(model.motor_pos.start, model.motor_pos.stop)]
    De = np.zeros((3, dim))
    De[:, pos_out] = np.eye(3)
    Dm = np.zeros((3, dim))
    Dm[:, pos_mot] = np.eye(3)
    p = J @ De  # (3, dim)
    Pp = np.zeros((3, dim))
    Pp[:, ipp] = np.eye(3)
    Vp = np.zeros((3, dim))
    Vp[:, iv] = np.eye(3)
    v = alpha * Vp + (1.0 - alpha) * (p - Pp) / T
    Kv, Bv = np.zeros((3, 3)), np.zeros((3, 3))
    Kv[axis, axis], Bv[axis, axis] = stiffness_N_per_m, settings.damping_N_s_per_m
    F = -Kv @ p - Bv @ v
    u = settings.force_gain * (J.T @ F - model.spring * (Dm - De))  # (3, dim)
    U1 = np.zeros((3, dim))
    U1[:, iu1] = np.eye(3)
    U2 = np.zeros((3, dim))
    U2[:, iu2] = np.eye(3)
    hist = [u, U1, U2]  # newest first
    p1 = sum(a[j] * hist[j] for j in range(a.size))
    newest = [p1, u, U1]
    p2 = sum(a[j] * newest[j] for j in range(a.size))
    ctrl = [U2, U1, u, p1, p2]
    # the 3-PRRR firmware interpolates only for L > 1 (``controller.interpolation = 1`` is off): L = 1 is the hold
    W = spline_weights(L, settings.variant if L > 1 else Variant.NONE)
    M = np.zeros((dim, dim))
    acc = np.eye(n)
    for j in range(L - 1, -1, -1):
        Cj = sum(W[j, k] * ctrl[k] for k in range(5))  # (3, dim)
        M[iz] += acc @ Bd @ Cj
        acc = acc @ Ad
    M[iz, iz] += acc  # Ad^L
    M[ipp] = p
    M[iv] = v
    M[iu1] = u
    M[iu2] = U1
    return M


def axis_block(design: PrrrDesign, M: np.ndarray, axis: int) -> np.ndarray:
    """The rows/columns of ``M`` (state layout of :func:`lifted_matrix`) that belong to Cartesian ``axis``."""
    J = np.asarray(jacobian(design.geometry.beta, xp=np))
    S = np.linalg.norm(J, axis=1)
    U = J / S[:, None]  # orthonormal rows
    groups = M.shape[0] // 3
    n_leg = groups - 4  # plant groups (D, D_e, Ḋ, Ḋ_e), then p, v (Cartesian), u, u (leg)
    R = np.zeros_like(M)
    for g in range(groups):
        cart = g in (n_leg, n_leg + 1)
        R[3 * g:3 * g + 3, 3 * g:3 * g + 3] = np.eye(3) if cart else U
    Mr = R @ M @ R.T
    sel = np.arange(axis, M.shape[0], 3)
    rest = np.setdiff1d(np.arange(M.shape[0]), sel)
    scale = np.abs(Mr[np.ix_(sel, sel)]).max()
    coupling = max(np.abs(Mr[np.ix_(sel, rest)]).max(), np.abs(Mr[np.ix_(rest, sel)]).max())
    if coupling > COUPLING_BAND * scale:
        raise ValueError(f"axis {axis} does not decouple: coupling {coupling:.3g} vs block {scale:.3g} "
                         f"(allowed ≤ {COUPLING_BAND:g} relative; rows of J not orthogonal)")
    return Mr[np.ix_(sel, sel)]


def axis_margin(design: PrrrDesign, settings: LoopSettings, stiffness_N_per_m: float, *, axis: int = 0,
                _plant=None) -> float:
    """−ln ρ / T of the axis block [1/s]; > 0 stable."""
    Mb = axis_block(design, lifted_matrix(design, settings, stiffness_N_per_m, axis=axis, _plant=_plant), axis)
    with np.errstate(divide="ignore"):
        return -float(np.log(np.max(np.abs(np.linalg.eigvals(Mb))))) / settings.period_s


@dataclass(frozen=True)
class AxisLimit:
    value_N_per_m: float  #: NaN unless status == "ok"
    status: str  #: "ok" | "unstable_without_wall" | "not_found"
    stable_below_N_per_m: float
    unstable_at_N_per_m: float


def stiffness_limit(design: PrrrDesign, settings: LoopSettings, *, axis: int = 0, rtol: float = 1e-9) -> AxisLimit:
    """First K_v (scan ×1.25 from 10 N/m) where the axis' spectral radius reaches 1 [N/m]."""
    from scipy.optimize import brentq  # lazy: a heavy import (tests/test_layers.py LAZY)
    sc = linear_scene(settings)
    model = build_model(design, sc, resolve(sc))
    plant = (model, discretise(model, settings.period_s / settings.upsampling))
    g = lambda K: axis_margin(design, settings, K, axis=axis, _plant=plant)  # noqa: E731
    band = RHO_BAND / settings.period_s
    lo = 10.0
    if not g(lo) > band:
        return AxisLimit(math.nan, "unstable_without_wall", math.nan, lo)
    while True:
        hi = 1.25 * lo
        if hi > 1e9:
            return AxisLimit(math.nan, "not_found", lo, math.nan)
        if g(hi) < 0.0:
            break
        lo = hi
    return AxisLimit(brentq(g, lo, hi, rtol=rtol), "ok", lo, hi)


def with_(settings: LoopSettings, **changes) -> LoopSettings:
    return replace(settings, **changes)


# ------------------------------------------------------------------ the operator effect, continuous time
@dataclass(frozen=True)
class HandLimit:
    """Continuous-time (T → 0) wall limit of one axis with a hand, and where its poles cross."""

    stiffness_N_per_m: float  #: K_v at the crossing
    crossing_rad_s: float  #: ω of the pole pair on the imaginary axis
    force_loop_rad_s: float  #: ω_f = √((1 + ηK_p) k / M_m), where the hand damper stops helping


def hand_limit_closed_form(design: PrrrDesign, *, force_gain: float, operator: Operator, axis: int = 0) -> HandLimit:
    """Where the critical pole pair crosses the imaginary axis, per axis in leg coordinates.

    Per axis (rows of J orthogonal; s_a = |J_a|, output mass M_o = (M + m_h) s_a², hand k_h s_a², b_h s_a²,
    wall K s_a²), with the spring force f = k(y_m − y) and a = 1 + ηK_p:

        [(M_m/k) s² + (ξ/k) s + a] [M_o s² + b s + k_h] + ηK_p K + M_m s² + ξ s = 0.

    At s = jω the imaginary part gives ω² = (k + k_h + k a b/ξ)/(M_o + M_m b/ξ) and the real part

        ηK_p K = a k + b [(ξ/k) ω² + (k/ξ)(a − M_m ω²/k)²].

    With b = 0 the limit is k_a(1 + 1/(ηK_p)) whatever k_h and m_h (seed 002 eq 15): the hand's spring
    only moves the crossing frequency. The hand's damper adds b·[…] ≥ 0, whose second term vanishes where
    ω reaches the force loop's own frequency ω_f = √(a k/M_m): a stiffer hand helps while it moves ω away
    from ω_f and hurts while it moves ω towards it.
    """
    a_ = design.actuator
    J = np.asarray(jacobian(design.geometry.beta, xp=np))
    s2 = float(np.sum(J[axis] ** 2))
    k, Mm, xi, eta = a_.spring, a_.motor_mass, a_.viscous, a_.efficiency
    a = 1.0 + eta * force_gain
    Mo = (design.end_effector.mass + operator.mass) * s2
    kh, b = operator.stiffness * s2, operator.damping * s2
    w2 = (k + kh + k * a * b / xi) / (Mo + Mm * b / xi)
    c = a * k + b * ((xi / k) * w2 + (k / xi) * (a - Mm * w2 / k) ** 2)
    return HandLimit(stiffness_N_per_m=c / (eta * force_gain) / s2, crossing_rad_s=math.sqrt(w2),
                     force_loop_rad_s=math.sqrt(a * k / Mm))

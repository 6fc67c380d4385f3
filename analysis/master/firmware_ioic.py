"""IOIC firmware mode of the surgical master: seed 001's learned impedance (outer loop) over its
nonsingular terminal sliding-mode tracking control (inner loop, joint space).

Per period (1 kHz, torques held) from the three joint encoder counts and the handle force
sensor F_h [N] (the force of the operator on the handle; the eq-2 operator pushes −f along the
learning axis, so f = −F_h·e_axis):

1. **Outer loop** (:class:`hapticopt.analysis.control.ioic_online.OnlineIoic`, seed 001 eq 5–10):
   the impedance reference x_r, ẋ_r, ẍ_r along the learning axis from f and the task's desired
   position x_d(t) (the scene's motion, which the eq-2 operator also follows); the other two
   axes hold the start position.
2. **Reference in joint space**: q_r by Newton's method on the closed-form forward kinematics
   (:func:`hapticopt.analysis.master.firmware.forward`, warm-started at the last q_r, to 1e-12 m),
   q̇_r = J(q_r)⁻¹ṗ_r, q̈_r = J(q_r)⁻¹(p̈_r − J̇q̇_r) (J̇q̇_r by a central difference along q̇_r).
3. **Inner loop**: NTSMTC (seed 001 eq 13–17, 26; :mod:`hapticopt.analysis.control.sliding_mode`)
   with e = q − q_r, ė from a filtered backward difference of the encoder angles, the firmware's
   rigid-body model M(q), C(q, q̇)q̇, G(q) of the design
   (:mod:`hapticopt.analysis.master.dynamics`, rotor inertia included) and τ_ext = Jᵀ F_h measured:
   τ = M(q̈_r − λ1ė − λ2φ'(e)ė − η sat(s/θ) − βs) + Cq̇ + G − τ_ext, clipped to the torque limit
   when saturation is on.

Cost: the model terms M(q), ∂M/∂q (for Cq̇ by Christoffel symbols) and G(q) come from one jitted
function of the mass model, re-evaluated only when q has moved more than ``model_refresh`` [rad]
from where they were last evaluated (1 mrad by default, ≈ 6 encoder counts; see the test for how much M changes over it;
0 = every tick, tested to agree); the control law runs in numpy (tested against the jax reference).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any

import numpy as np

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.control import ioic_online
from hapticopt.analysis.control.sliding_mode import NTSMTCParams
from hapticopt.analysis.loop.scene import Motion
from hapticopt.analysis.master.firmware import forward

_TWO_PI = 2.0 * math.pi


@dataclasses.dataclass(frozen=True, kw_only=True)
class MasterIoicConfig:
    """Everything the master's IOIC firmware knows [SI]."""

    period: float  # T [s]
    counts_per_rev: float
    q0: tuple[float, float, float]  # calibration pose [rad]
    upper_arm: float  # L5 [m]
    forearm: float  # L4 [m]
    shoulder_height: float  # h [m]
    axis: int  # learning axis (0 = x)
    x_start: tuple[float, float, float]  # handle position at the calibration pose [m]
    motion: Motion  # the task: x_d(t) = x_start + offset ± amplitude along the axis
    outer: ioic_online.OnlineIoicConfig
    ntsmtc: NTSMTCParams
    velocity_alpha: float  # joint-velocity filter pole e^{−2π f_c T}; 0 = plain difference
    torque_limit: float  # [N·m]
    saturation: bool
    gravity: bool  # G(q) in the model (the gravity effect is on)
    model_refresh: float = 1e-3  # re-evaluate M, ∂M/∂q, G when |q − q_model|∞ exceeds this [rad]

    def desired(self, t: float) -> float:
        """x_d(t) [m] along the learning axis."""
        m, a = self.motion, self.axis
        return self.x_start[a] + m.offset[a] + m.amplitude[a] * m.square(t)


@functools.lru_cache(maxsize=8)
def _model_terms(model_key: Any, gravity: bool):
    """Jitted q → (M (3, 3) [kg·m²], ∂M/∂q (3, 3, 3), G (3,) [N·m]) of the firmware's mass model."""
    import jax
    import jax.numpy as jnp

    from hapticopt.analysis.master import dynamics as md

    model = model_key.model

    def terms(q):
        m = md.mass_matrix(model, q)
        dm = jax.jacfwd(lambda qq: md.mass_matrix(model, qq))(q)
        g = md.gravity_torque(model, q) if gravity else jnp.zeros(3)
        return m, dm, g

    return jax.jit(terms)


def coriolis_from_dm(dm: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """C(q, q̇)q̇ [N·m] from ∂M_ij/∂q_k (3, 3, 3): c_i = Σ_jk (∂_k M_ij − ½ ∂_i M_jk) q̇_j q̇_k
    (Christoffel symbols of the first kind)."""
    return np.einsum("ijk,j,k->i", dm, qd, qd) - 0.5 * np.einsum("jki,j,k->i", dm, qd, qd)


def phi_np(p: NTSMTCParams, e: np.ndarray) -> np.ndarray:
    """:func:`hapticopt.analysis.control.sliding_mode.phi` in numpy (eq 14)."""
    ae = np.abs(e)
    return np.where(ae >= p.mu, np.sign(e) * np.maximum(ae, p.mu) ** p.ratio, p.sigma1 * e + p.sigma2 * e * ae)


def phi_prime_np(p: NTSMTCParams, e: np.ndarray) -> np.ndarray:
    """:func:`hapticopt.analysis.control.sliding_mode.phi_prime` in numpy."""
    ae = np.abs(e)
    return np.where(ae >= p.mu, p.ratio * np.maximum(ae, p.mu) ** (p.ratio - 1.0), p.sigma1 + 2.0 * p.sigma2 * ae)


def control_torque_np(p: NTSMTCParams, *, m, c_qd, g, tau_ext, e, de, qdd_r) -> np.ndarray:
    """:func:`hapticopt.analysis.control.sliding_mode.control_torque` (eq 17 with sat, eq 26) in
    numpy, the same operations in the same order (tested against it)."""
    l1, l2, beta = np.asarray(p.lambda1), np.asarray(p.lambda2), np.asarray(p.beta)
    s = de + l1 * e + l2 * phi_np(p, e)
    acc = qdd_r - l1 * de - l2 * phi_prime_np(p, e) * de - p.eta * np.clip(s / p.theta, -1.0, 1.0) - beta * s
    return m @ acc + c_qd + g - tau_ext


@dataclasses.dataclass(frozen=True)
class ModelKey:
    """Hashable wrapper (by design) of the firmware's mass model for the compile cache."""

    design: Any
    model: Any = dataclasses.field(compare=False, hash=False)


class MasterIoicController:
    """``step(counts (3,), hand_force (3,)) -> torques (1, 3)`` [N·m]; records its reference."""

    def __init__(self, cfg: MasterIoicConfig, model_key: ModelKey) -> None:
        self.cfg = cfg
        self.period = cfg.period
        self._scale = _TWO_PI / cfg.counts_per_rev
        self._q0 = np.asarray(cfg.q0, dtype=float)
        self._terms = _model_terms(model_key, cfg.gravity)
        self._q_model: np.ndarray | None = None
        self.outer = ioic_online.OnlineIoic(cfg.outer)
        self._ready = False

    def joint_angles(self, counts: np.ndarray) -> np.ndarray:
        return self._q0 + np.asarray(counts, dtype=float) * self._scale

    def reset(self, counts: np.ndarray) -> None:
        q = self.joint_angles(counts)
        p, _ = forward(self.cfg, q)
        self.outer.reset(float(p[self.cfg.axis]))
        self._q_prev, self._qd = q, np.zeros(3)
        self.q_r = q.copy()
        self._tick = 0
        self._ready = True

    def inverse(self, p: np.ndarray, guess: np.ndarray) -> np.ndarray:
        """q with forward(q) = p [m] by Newton's method from ``guess`` (≤ 20 steps, 1e-12 m)."""
        q = np.array(guess, dtype=float)
        for _ in range(20):
            pq, J = forward(self.cfg, q)
            r = p - pq
            if float(np.max(np.abs(r))) <= 1e-12:
                break
            q = q + np.linalg.solve(J, r)
        return q

    def jdot_qd(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """J̇q̇ [m/s²] by a central difference of J along q̇ (step 1e-5 rad: error ≈ 1e-10 relative)."""
        n = float(np.max(np.abs(qd)))
        if n == 0.0:
            return np.zeros(3)
        h = 1e-5 / n
        _, jp = forward(self.cfg, q + h * qd)
        _, jm = forward(self.cfg, q - h * qd)
        return (jp - jm) @ qd / (2.0 * h)

    def step(self, counts: np.ndarray, hand_force: np.ndarray) -> np.ndarray:
        cfg = self.cfg
        if not self._ready:
            self.reset(counts)
        T, ax = cfg.period, cfg.axis
        t = self._tick * T
        q = self.joint_angles(counts)
        diff = (q - self._q_prev) / T
        a = cfg.velocity_alpha
        qd = a * self._qd + (1.0 - a) * diff if a > 0.0 else diff
        f = -float(hand_force[ax])
        x_d = cfg.desired(t)
        x_r, v_r, u, _ = self.outer.step(x_d, f)
        p_r = np.array(cfg.x_start, dtype=float)
        p_r[ax] = x_r
        e_ax = np.eye(3)[ax]
        self.q_r = self.inverse(p_r, self.q_r)
        _, jr = forward(cfg, self.q_r)
        qd_r = np.linalg.solve(jr, v_r * e_ax)
        qdd_r = np.linalg.solve(jr, u * e_ax - self.jdot_qd(self.q_r, qd_r))
        if self._q_model is None or float(np.max(np.abs(q - self._q_model))) > cfg.model_refresh:
            self._m, self._dm, self._g = (np.asarray(v) for v in self._terms(q))
            self._q_model = q
        _, jq = forward(cfg, q)
        tau = control_torque_np(cfg.ntsmtc, m=self._m, c_qd=coriolis_from_dm(self._dm, qd), g=self._g,
                                tau_ext=jq.T @ np.asarray(hand_force, dtype=float), e=q - self.q_r, de=qd - qd_r,
                                qdd_r=qdd_r)
        if cfg.saturation:
            tau = np.clip(tau, -cfg.torque_limit, cfg.torque_limit)
        self._q_prev, self._qd = q, qd
        self._tick += 1
        self.x_r, self.x_d, self.f = x_r, x_d, f
        self.joint_error = q - self.q_r
        return tau[None, :]

"""Firmware of the surgical master (seed 003): joint-torque impedance control τ = Jᵀ F at 1 kHz.

The counterpart of :mod:`hapticopt.analysis.prrr.loop.firmware` / :mod:`hapticopt.analysis.prrr.loop.firmware_law` for device B, with
the same ``reset(counts)`` / ``step(counts) -> commands`` idea. It sees only the three joint
encoder counts (θ1, θ2, θ3, counted from the calibration pose ``q0`` it was homed at, at
``encoder_counts_per_rev``); from them it computes the handle position p(q) and the Jacobian
(the master's closed-form forward kinematics, :mod:`hapticopt.design.master.kinematics` conventions), the
velocity by a filtered backward difference, the virtual environment's force F (a spring
F = −K(p − p_r) − B ṗ, or walls of a box around p_r: −K_b·depth − B_b ṗ on every axis beyond its
wall) and the joint torques τ = Jᵀ F (+ the model's gravity torque G(q) when gravity
compensation is on), clipped to the motor torque limit when saturation is on. The plant holds τ
for the period (zero-order hold).

Transparency mode (seed 003's controller, ``compensation_model`` set): model-based feedback
compensation of the dynamics *without gravity*, τ += M̂(q) q̂̈ + Ĉ(q, q̂̇) q̂̇, with M̂ the mass matrix of
the compensation model's bodies (``compensation_weights`` selects them: the links without the
counterweights in seed 003's reading, docs/master.md) and q̂̇, q̂̈ two cascaded filtered backward
differences of the joint angles (the velocity filter's pole; no filter = plain differences; each
filter starts at its first input), applied from the third step on (q̂̈ needs three samples). Ĉ q̂̇ =
Ṁ q̂̇ − ½ ∂(q̂̇ᵀ M̂ q̂̇)/∂q by central differences of M̂ (h = 1e-6 rad). The frequency-domain model of this
loop is :func:`hapticopt.analysis.master.transparency.transfer`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticopt.analysis.master import dynamics_numpy as mn

from hapticopt.analysis.loop.scene import EnvKind

_TWO_PI = 2.0 * math.pi


@dataclass(frozen=True, kw_only=True)
class MasterFirmwareConfig:
    """Everything the master firmware knows [SI]."""

    period: float  # T [s]
    counts_per_rev: float
    q0: tuple[float, float, float]  # calibration pose (θ1, θ2, θ3) [rad]
    upper_arm: float  # L5 [m]
    forearm: float  # L4 [m]
    shoulder_height: float  # h [m]
    env: EnvKind
    anchor: tuple[float, float, float]  # p_r [m] (world)
    stiffness: tuple[float, float, float]  # K [N/m]
    damping: tuple[float, float, float]  # B [N·s/m]
    half_size: tuple[float, float, float]  # box half-sizes [m]
    wall_stiffness: float  # K_b [N/m]
    wall_damping: float  # B_b [N·s/m]
    velocity_alpha: float  # first-order filter pole e^{−2π f_c T}; 0 = plain difference
    torque_limit: float  # [N·m]
    saturation: bool
    quantized: bool  # counts are integers (informational; the plant rounds)
    gravity_compensation: bool
    gravity_g1: float = 0.0  # G(q) = (0, G1 cos θ2, G2 sin θ3) [N·m] (hapticopt.analysis.master.dynamics.gravity_parameters)
    gravity_g2: float = 0.0
    compensation_model: Any = None  # hapticopt.analysis.master.dynamics.MassModel; None = no dynamics compensation
    compensation_weights: tuple[float, ...] = ()  # per body of the model: 1 compensated, 0 not


_H_COMP = 1e-6  # [rad] central-difference step of ∂M̂/∂q


def compensation_torque(model: Any, weights: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """M̂(q) q̈ + Ĉ(q, q̇) q̇ (3,) [N·m] of the bodies selected by ``weights`` (rotor inertia included)."""
    Q = np.repeat(np.asarray(q, dtype=float)[None], 7, axis=0)
    for k in range(3):
        Q[1 + 2 * k, k] += _H_COMP
        Q[2 + 2 * k, k] -= _H_COMP
    M = np.einsum("b,nbij->nij", weights, mn.body_mass_matrices(model, Q)) + np.diag(np.asarray(model.rotor_inertia))
    dM = (M[1::2] - M[2::2]) / (2 * _H_COMP)  # (k, i, j) = ∂M_ij/∂q_k
    c = np.einsum("kij,j,k->i", dM, qd, qd) - 0.5 * np.einsum("ijk,j,k->i", dM, qd, qd)
    return M[0] @ qdd + c


def forward(cfg: MasterFirmwareConfig, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Handle position p(q) [m] and Jacobian ∂p/∂q (3×3) of the master (reduced joints θ1, θ2, θ3)."""
    t1, t2, t3 = (float(x) for x in q)
    L5, L4 = cfg.upper_arm, cfg.forearm
    c1, s1, c2, s2, c3, s3 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2), math.cos(t3), math.sin(t3)
    rho = L5 * c2 + L4 * s3
    p = np.array([rho * c1, rho * s1, cfg.shoulder_height + L5 * s2 - L4 * c3])
    J = np.array([[-rho * s1, -L5 * s2 * c1, L4 * c3 * c1],
                  [rho * c1, -L5 * s2 * s1, L4 * c3 * s1],
                  [0.0, L5 * c2, L4 * s3]])
    return p, J


class MasterController:
    """The master's firmware: ``step(encoder_counts (3,)) -> torques (1, 3)`` [N·m]."""

    def __init__(self, cfg: MasterFirmwareConfig) -> None:
        self.cfg = cfg
        self.period = cfg.period
        self._scale = _TWO_PI / cfg.counts_per_rev
        self._q0 = np.asarray(cfg.q0, dtype=float)
        self._K, self._B = np.asarray(cfg.stiffness), np.asarray(cfg.damping)
        self._anchor, self._half = np.asarray(cfg.anchor), np.asarray(cfg.half_size)
        self.last_force = np.zeros(3)
        self._weights = np.asarray(cfg.compensation_weights, dtype=float)
        self._ready = False

    def joint_angles(self, counts: np.ndarray) -> np.ndarray:
        return self._q0 + np.asarray(counts, dtype=float) * self._scale

    def reset(self, counts: np.ndarray) -> None:
        q = self.joint_angles(counts)
        self._p_prev, _ = forward(self.cfg, q)
        self._v = np.zeros(3)
        self._q_prev, self._qd, self._qdd = q, np.zeros(3), np.zeros(3)
        self._samples = 0  # joint-angle samples seen by step(): q̂̇ needs 2, q̂̈ 3 (no compensation before)
        self._ready = True

    def _compensation(self, q: np.ndarray) -> np.ndarray:
        """M̂ q̂̈ + Ĉ q̂̇ from filtered differences of the step samples (zero until q̂̈ is defined)."""
        cfg, a = self.cfg, self.cfg.velocity_alpha
        n = self._samples
        self._samples = n + 1
        if n == 0:  # the first sample: nothing to difference
            self._q_prev = q
            return np.zeros(3)
        diff = (q - self._q_prev) / cfg.period
        qd = diff if n == 1 else a * self._qd + (1.0 - a) * diff  # the filter starts at its first input
        if n == 1:
            self._q_prev, self._qd = q, qd
            return np.zeros(3)
        d2 = (qd - self._qd) / cfg.period
        qdd = d2 if n == 2 else a * self._qdd + (1.0 - a) * d2
        self._q_prev, self._qd, self._qdd = q, qd, qdd
        return compensation_torque(cfg.compensation_model, self._weights, q, qd, qdd)

    def step(self, counts: np.ndarray) -> np.ndarray:
        cfg = self.cfg
        if not self._ready:
            self.reset(counts)
        q = self.joint_angles(counts)
        p, J = forward(cfg, q)
        diff = (p - self._p_prev) / cfg.period
        a = cfg.velocity_alpha
        v = a * self._v + (1.0 - a) * diff if a > 0.0 else diff
        delta = p - self._anchor
        if cfg.env == EnvKind.SPRING:
            F = -self._K * delta - self._B * v
        elif cfg.env == EnvKind.BOX:
            depth = np.abs(delta) - self._half
            F = np.where(depth > 0.0, -cfg.wall_stiffness * np.sign(delta) * depth - cfg.wall_damping * v, 0.0)
        else:
            F = np.zeros(3)
        # Jᵀ F summed in a fixed order (a BLAS product's order / FMA is the library's; the compiled loop of
        # hapticopt.analysis.loop.mujoco_compiled reproduces this bit for bit)
        tau = np.array([F[0] * J[0, j] + F[1] * J[1, j] + F[2] * J[2, j] for j in range(3)])
        if cfg.compensation_model is not None:
            tau = tau + self._compensation(q)
        if cfg.gravity_compensation:
            tau = tau + np.array([0.0, cfg.gravity_g1 * math.cos(q[1]), cfg.gravity_g2 * math.sin(q[2])])
        if cfg.saturation:
            tau = np.clip(tau, -cfg.torque_limit, cfg.torque_limit)
        self._p_prev, self._v = p, v
        self.last_force = F
        return tau[None, :]

"""IOIC firmware mode of the 3-PRRR: seed 001's learned impedance as the outer loop of the
impedance controller, the SEA force loops staying the inner loop.

Per period from the slider and spring-deflection counts and the handle force sensor F_h [N]
(the eq-2 operator pushes −f along the learning axis, f = −F_h·e_axis):

1. **Outer loop** (:class:`hapticopt.analysis.control.ioic_online.OnlineIoic`, seed 001 eq 5–10):
   the impedance reference x_r, ẋ_r, ẍ_r along the learning axis; the other axes hold the start.
2. **Impedance controller** (Cartesian, the 3-PRRR firmware's position and velocity estimates):
   F = M ẍ_r e_axis + K_t (p_r − p) + B_t (ṗ_r − ṗ) − F_h (+ the weight M g e_z with gravity
   compensation), with M the end-effector mass and K_t, B_t the scene's ``ioic.tracking_*`` — the
   counterpart of NTSMTC's feed-forward and τ_ext cancellation (seed 001 eq 17) for a
   force-controlled device.
3. **Inner loop**: the slider forces f_ref = Jᵀ F rendered by the SEA force loops of
   :mod:`hapticopt.analysis.prrr.loop.firmware` (K_p (f_ref − k x) + integral), or directly without
   series springs, clipped to the motor limit — the same law as
   the law of :mod:`hapticopt.analysis.prrr.loop.firmware_law` (tested equal with the reference held still).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hapticopt.analysis.control import ioic_online
from hapticopt.analysis.loop.scene import Motion
from hapticopt.analysis.prrr.loop.firmware import FirmwareConfig, ForceLoop, Gains


@dataclasses.dataclass(frozen=True, kw_only=True)
class PrrrIoicConfig:
    """The 3-PRRR's IOIC firmware [SI]: base firmware structure and gains, the outer loop, the task."""

    base: FirmwareConfig
    gains: Gains
    outer: ioic_online.OnlineIoicConfig
    axis: int
    x_start: tuple[float, float, float]  # end-effector start [m]
    motion: Motion
    mass: float  # end-effector mass M [kg] (feed-forward of ẍ_r)
    tracking_stiffness: float  # K_t [N/m]
    tracking_damping: float  # B_t [N·s/m]

    def desired(self, t: float) -> float:
        m, a = self.motion, self.axis
        return self.x_start[a] + m.offset[a] + m.amplitude[a] * m.square(t)


class PrrrIoicController:
    """``step(slider_counts, deflection_counts, hand_force) -> commands (1, 3)`` [N]."""

    def __init__(self, cfg: PrrrIoicConfig) -> None:
        self.cfg = cfg
        self.period = cfg.base.period
        g = {k: np.asarray(v, dtype=np.float64) for k, v in cfg.gains._asdict().items()}
        self._J = g["J"]
        self._res, self._spring, self._eta = float(g["resolution"]), float(g["spring"]), float(g["efficiency"])
        self._kp, self._ki, self._limit = float(g["kp"]), float(g["ki"]), float(g["motor_limit"])
        self._weight = float(g["weight"])
        self.outer = ioic_online.OnlineIoic(cfg.outer)
        self.last_force = np.zeros(3)
        self._ready = False

    def reset(self, slider_counts: np.ndarray) -> None:
        p = (np.asarray(slider_counts, dtype=np.float64) * self._res) @ self._J.T
        self._p_prev, self._v = p, np.zeros(3)
        self._integral = np.zeros(3)
        self.outer.reset(float(p[self.cfg.axis]))
        self._tick = 0
        self._ready = True

    def render(self, p_r: np.ndarray, v_r: np.ndarray, a_r: np.ndarray, slider_counts: np.ndarray,
               deflection_counts: np.ndarray, hand_force: np.ndarray) -> np.ndarray:
        """One period of the impedance controller + SEA loops tracking (p_r, ṗ_r, p̈_r) [m, m/s, m/s²]."""
        cfg, base = self.cfg, self.cfg.base
        T = base.period
        p = (np.asarray(slider_counts, dtype=np.float64) * self._res) @ self._J.T
        diff = (p - self._p_prev) / T
        a = base.velocity_alpha
        v = a * self._v + (1.0 - a) * diff if a > 0.0 else diff
        F = cfg.mass * a_r + cfg.tracking_stiffness * (p_r - p) + cfg.tracking_damping * (v_r - v) - hand_force
        if base.gravity_compensation:
            F = F + np.array([0.0, 0.0, self._weight])
        f_ref = F @ self._J
        integral = self._integral
        if base.force_loop == ForceLoop.SEA:
            err = f_ref - self._spring * (np.asarray(deflection_counts, dtype=np.float64) * self._res)
            out = self._kp * err
            if base.integral:
                integral = integral + self._ki * T * err
                if base.saturation:
                    integral = np.clip(integral, -self._limit, self._limit)
                out = out + integral
        elif base.force_loop == ForceLoop.RIGID:
            out = f_ref / self._eta
        else:
            out = f_ref
        if base.saturation:
            out = np.clip(out, -self._limit, self._limit)
        self._p_prev, self._v, self._integral = p, v, integral
        self.last_force = F
        return out[None, :]

    def step(self, slider_counts: np.ndarray, deflection_counts: np.ndarray, hand_force: np.ndarray) -> np.ndarray:
        cfg = self.cfg
        if not self._ready:
            self.reset(slider_counts)
        t = self._tick * cfg.base.period
        hand_force = np.asarray(hand_force, dtype=float)
        x_d = cfg.desired(t)
        x_r, v_r, u, _ = self.outer.step(x_d, -float(hand_force[cfg.axis]))
        e = np.eye(3)[cfg.axis]
        p_r = np.array(cfg.x_start, dtype=float)
        p_r[cfg.axis] = x_r
        self._tick += 1
        self.x_r, self.x_d, self.f = x_r, x_d, -float(hand_force[cfg.axis])
        return self.render(p_r, v_r * e, u * e, slider_counts, deflection_counts, hand_force)

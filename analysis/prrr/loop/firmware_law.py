"""The 3-PRRR firmware law for one controller, one tick, on scalars: the MuJoCo loops' single definition.

:func:`tick` is plain Python arithmetic on flat sequences (Python lists or 1-D numpy arrays), written so
that numba compiles it unchanged: the Python MuJoCo loop calls it as is (through :class:`ScalarController`),
the compiled MuJoCo loop (:mod:`hapticopt.analysis.prrr.loop._mujoco_kernel`) compiles and inlines it. It is the
law of :func:`hapticopt.analysis.prrr.loop.firmware.step` (jax, batched over controllers and fused with the
lumped plant's compiled loop) for one controller without interpolation, term by term and in the same
order; ``tests/analysis/prrr/loop/test_firmware_law.py`` holds the two equal on every bundled scene's
structure and the optional terms. Interpolation (L > 1, the seed 000 spline and predictor) is the jax
law's alone: :func:`controller` gives :class:`hapticopt.analysis.prrr.loop.firmware.FirmwareController` there.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hapticopt.analysis.loop.scene import BoxMode, EnvKind
from hapticopt.analysis.prrr.loop import firmware
from hapticopt.analysis.prrr.loop.firmware import FirmwareConfig, ForceLoop, Gains

#: environment codes of :func:`tick` (``flg[0]``)
ENV_FREE, ENV_SPRING, ENV_BOX_INSIDE, ENV_BOX_OUTSIDE, ENV_FORCE = 0, 1, 2, 3, 4
#: force-loop codes of :func:`tick` (``flg[3]``)
LOOP_SEA, LOOP_RIGID, LOOP_IDEAL = 0, 1, 2
#: the numbers of ``par``, in order
PAR = ("resolution", "period", "velocity_alpha", "wall_stiffness", "wall_damping", "force_omega", "friction_comp",
       "friction_comp_velocity", "weight", "spring", "kp", "ki_period", "motor_limit", "efficiency")


def tick(par, flg, J, K, B, anchor, half, famp, fphase, st, k, slider_counts, deflection_counts, out):
    """One control period of the law (steps 1–5 and 7 of :mod:`hapticopt.analysis.prrr.loop.firmware`).

    par: the numbers named by :data:`PAR` [SI]; flg: env code, friction compensation, gravity compensation,
    force-loop code, integral, saturation; J: the Jacobian (3, 3) row-major, flat (9); K, B, anchor, half,
    famp, fphase: the scene's 3-vectors [SI]; st (12): p_prev, velocity, integral, F_r — updated in place;
    k: the tick (force reference phase); the counts (3 each); out (3): the motor-force commands [N].
    """
    r, T, a = par[0], par[1], par[2]
    env, friction, gravity, loop, integral, saturation = flg[0], flg[1], flg[2], flg[3], flg[4], flg[5]
    s0, s1, s2 = slider_counts[0] * r, slider_counts[1] * r, slider_counts[2] * r
    p0 = s0 * J[0] + s1 * J[1] + s2 * J[2]  # (counts · res) @ Jᵀ
    p1 = s0 * J[3] + s1 * J[4] + s2 * J[5]
    p2 = s0 * J[6] + s1 * J[7] + s2 * J[8]
    for i, p in ((0, p0), (1, p1), (2, p2)):  # st[3 + i] ← ṗ̂, st[i] ← p
        if a > 0.0:
            st[3 + i] = a * st[3 + i] + (1.0 - a) * ((p - st[i]) / T)
        else:
            st[3 + i] = (p - st[i]) / T
        st[i] = p
    # F_r into st[9:12]
    if env == ENV_FREE:
        for i in range(3):
            st[9 + i] = 0.0
    elif env == ENV_SPRING:
        for i in range(3):
            st[9 + i] = -K[i] * (st[i] - anchor[i]) - B[i] * st[3 + i]
    elif env == ENV_BOX_INSIDE:  # eq 13, inside: every axis beyond its wall pushes back
        for i in range(3):
            st[9 + i] = 0.0
            dl = st[i] - anchor[i]
            depth = abs(dl) - half[i]
            if depth > 0.0:
                sgn = 1.0 if dl > 0.0 else (-1.0 if dl < 0.0 else 0.0)
                st[9 + i] = -par[3] * sgn * depth - par[4] * st[3 + i]
    elif env == ENV_BOX_OUTSIDE:  # outside: all axes within → push out along the shallowest axis
        d0, d1, d2 = abs(st[0] - anchor[0]) - half[0], abs(st[1] - anchor[1]) - half[1], abs(st[2] - anchor[2]) - half[2]
        deepest = 0 if (d0 >= d1 and d0 >= d2) else (1 if d1 >= d2 else 2)  # np.argmax: the first maximum
        inside = d0 < 0.0 and d1 < 0.0 and d2 < 0.0
        for i, depth in ((0, d0), (1, d1), (2, d2)):
            st[9 + i] = 0.0
            if inside and i == deepest:
                dl = st[i] - anchor[i]
                sgn = 1.0 if dl > 0.0 else (-1.0 if dl < 0.0 else 0.0)
                st[9 + i] = par[3] * sgn * (-depth) - par[4] * st[3 + i]
    else:  # ENV_FORCE: a prescribed force per axis
        ph = par[5] * (k * T)
        for i in range(3):
            st[9 + i] = famp[i] * math.sin(ph + fphase[i])
    if friction:
        st[9] = st[9] + par[6] * math.tanh(st[3] / par[7])
        st[10] = st[10] + par[6] * math.tanh(st[4] / par[7])
        st[11] = st[11] + 0.0
    if gravity:
        st[11] = st[11] + par[8]
    lim = par[12]
    for j in range(3):
        f = st[9] * J[j] + st[10] * J[3 + j] + st[11] * J[6 + j]  # (F_r @ J)_j: the leg's spring-force reference
        if loop == LOOP_SEA:
            err = f - par[9] * (deflection_counts[j] * r)
            o = par[10] * err
            if integral:
                ig = st[6 + j] + par[11] * err
                if saturation:  # min(max(x, −lim), lim) as Python evaluates it (NaN stays NaN)
                    ig = -lim if -lim > ig else ig
                    ig = lim if lim < ig else ig
                o = o + ig
                st[6 + j] = ig
        elif loop == LOOP_RIGID:
            o = f / par[13]
        else:
            o = f
        if saturation:
            o = -lim if -lim > o else o
            o = lim if lim < o else o
        out[j] = o


def arguments(cfg: FirmwareConfig, gains: Gains) -> tuple[list, ...]:
    """(par, flg, J, K, B, anchor, half, famp, fphase) of :func:`tick` for ``cfg`` and ``gains`` (Python lists)."""
    if cfg.interpolation > 1:
        raise ValueError("the scalar firmware law runs interpolation 1; L > 1 is the jax law's "
                         "(hapticopt.analysis.prrr.loop.firmware.FirmwareController)")
    g = {k: np.asarray(v, dtype=np.float64) for k, v in gains._asdict().items() if v is not None}
    f = lambda name: float(g[name])  # noqa: E731
    v3 = lambda name: np.broadcast_to(g[name], (3,)).tolist()  # noqa: E731
    par = [f("resolution"), cfg.period, cfg.velocity_alpha, f("wall_stiffness"), f("wall_damping"), f("force_omega"),
           f("friction_comp"), f("friction_comp_velocity"), f("weight"), f("spring"), f("kp"), f("ki") * cfg.period,
           f("motor_limit"), f("efficiency")]
    if cfg.env == EnvKind.BOX:
        env = ENV_BOX_INSIDE if cfg.box_mode == BoxMode.INSIDE else ENV_BOX_OUTSIDE
    else:
        env = {EnvKind.FREE: ENV_FREE, EnvKind.SPRING: ENV_SPRING, EnvKind.FORCE: ENV_FORCE}[cfg.env]
    loop = {ForceLoop.SEA: LOOP_SEA, ForceLoop.RIGID: LOOP_RIGID, ForceLoop.IDEAL: LOOP_IDEAL}[cfg.force_loop]
    flg = [env, int(cfg.friction_compensation), int(cfg.gravity_compensation), loop, int(cfg.integral),
           int(cfg.saturation)]
    return (par, flg, g["J"].ravel().tolist(), v3("stiffness"), v3("damping"), v3("anchor"), v3("half_size"),
            v3("force_amplitude"), v3("force_phase"))


class ScalarController:
    """:func:`tick` as a controller object (``reset``, ``step``, ``last_force``: the interface of
    :class:`hapticopt.analysis.prrr.loop.firmware.FirmwareController`); interpolation 1 only."""

    def __init__(self, cfg: FirmwareConfig, gains: Gains) -> None:
        self.cfg, self.gains, self.period = cfg, gains, cfg.period
        self.args = arguments(cfg, gains)
        self._JT = np.asarray(gains.J, dtype=np.float64).T.copy()
        self.state = [0.0] * 12  # p_prev, velocity, integral, F_r
        self.tick = 0
        self._ready = False

    @property
    def last_force(self) -> np.ndarray:
        """F_r of the last tick (3,) [N]."""
        return np.array(self.state[9:12])

    def reset(self, slider_counts: np.ndarray) -> None:
        """Power-up: the first reading is the previous position; nothing integrated."""
        p = (np.asarray(slider_counts, dtype=np.float64) * self.args[0][0]) @ self._JT
        self.state = p.tolist() + [0.0] * 9
        self.tick = 0
        self._ready = True

    def step(self, slider_counts: Any, deflection_counts: Any) -> np.ndarray:
        """Commands (1, 3) [N] for this period from the counts read at its start (lists or arrays)."""
        if not self._ready:
            self.reset(slider_counts)
        out = [0.0, 0.0, 0.0]
        tick(*self.args, self.state, self.tick, slider_counts, deflection_counts, out)
        self.tick += 1
        return np.array([out])


def controller(cfg: FirmwareConfig, gains: Gains) -> Any:
    """The law for a Python loop: :class:`ScalarController` at interpolation 1, else the jax law's object."""
    return ScalarController(cfg, gains) if cfg.interpolation == 1 else firmware.FirmwareController(cfg, gains)

"""Plain-numpy fast path of the firmware control law, for plants stepped from Python.

:func:`hapticopt.analysis.prrr.firmware.step` is the reference (jax, batched, compiled); called once per tick
from a Python loop its dispatch costs ≈ 0.1–1 ms, several times a MuJoCo controller period of
physics. This is the same law, term by term and in the same order, for one controller with
numpy scalars/3-vectors (≈ 20–40 µs per tick); ``tests/analysis/prrr/test_firmware_numpy.py`` checks it
against the reference on every bundled scene's structure and on the optional terms (integral,
interpolation, box outside, force reference). It implements the
:class:`hapticopt.analysis.prrr.firmware.FirmwareController` interface (``reset``, ``step``, ``last_force``).

Without interpolation and outside-box walls (every bundled scene) ``step`` runs a scalar path
on Python floats (≈ 8 µs per tick instead of ≈ 35 µs for 3-vector numpy operations), the same
operations in the same order; the generic numpy path stays as ``step_generic`` (both tested).
"""

from __future__ import annotations

import math

import numpy as np

from hapticopt.analysis.control import upsampling as up
from hapticopt.analysis.prrr import firmware
from hapticopt.analysis.prrr.firmware import FirmwareConfig, ForceLoop, Gains
from hapticopt.analysis.loop.scene import BoxMode, EnvKind

_XY = np.array([1.0, 1.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])


class NumpyController:
    """One firmware controller in numpy (no batch axes)."""

    def __init__(self, cfg: FirmwareConfig, gains: Gains) -> None:
        self.cfg = cfg
        self.gains = gains
        self.period = cfg.period
        g = {k: np.asarray(v, dtype=np.float64) for k, v in gains._asdict().items()}
        self._J, self._JT = g["J"], g["J"].T.copy()
        self._res = float(g["resolution"])
        self._spring, self._eta = float(g["spring"]), float(g["efficiency"])
        self._K, self._B, self._anchor = g["stiffness"], g["damping"], g["anchor"]
        self._half, self._Kb, self._Bb = g["half_size"], float(g["wall_stiffness"]), float(g["wall_damping"])
        self._famp, self._fomega = g["force_amplitude"], float(g["force_omega"])
        self._fphase = [float(x) for x in np.broadcast_to(g["force_phase"], (3,))]
        self._kp, self._ki, self._limit = float(g["kp"]), float(g["ki"]), float(g["motor_limit"])
        self._fc, self._fcv, self._weight = float(g["friction_comp"]), float(g["friction_comp_velocity"]), float(g["weight"])
        self._W = firmware.interpolation_weights(cfg) if cfg.interpolation > 1 else None
        self.last_force = np.zeros(3)
        self._ready = False
        self.scalar = cfg.interpolation == 1 and not (cfg.env == EnvKind.BOX and cfg.box_mode == BoxMode.OUTSIDE)
        self._Jl = self._J.tolist()
        self._Kl, self._Bl, self._anchorl = self._K.tolist(), self._B.tolist(), self._anchor.tolist()
        self._halfl, self._famp_l = self._half.tolist(), self._famp.tolist()

    def reset(self, slider_counts: np.ndarray) -> None:
        p = (np.asarray(slider_counts, dtype=np.float64) * self._res) @ self._JT
        self._tick = 0
        self._p_prev = p
        self._v = np.zeros(3)
        self._integral = np.zeros(3)
        self._history = np.zeros((3, 3))
        self._positions = np.tile(p, (self.cfg.ar_window, 1)) if self.cfg.online else None
        self.fit_counts: dict[up.ARStatus, int] = {}  # per axis and tick (online predictor)
        self._ready = True
        self._sp = p.tolist()
        self._sv = [0.0, 0.0, 0.0]
        self._si = [0.0, 0.0, 0.0]

    def step(self, slider_counts: np.ndarray, deflection_counts: np.ndarray) -> np.ndarray:
        """Commands (L, 3) [N] for this period from the counts read at its start."""
        if self.scalar:
            return self._step_scalar(slider_counts, deflection_counts)
        return self.step_generic(slider_counts, deflection_counts)

    def _step_scalar(self, slider_counts: np.ndarray | list[float], deflection_counts: np.ndarray | list[float]
                     ) -> np.ndarray:
        """:meth:`step_generic` on Python floats (interpolation 1, no outside-box walls); the counts may come
        as Python lists (the MuJoCo loop passes them so, saving two conversions per tick)."""
        cfg = self.cfg
        if not self._ready:
            self.reset(slider_counts)
        T, r, J = cfg.period, self._res, self._Jl
        sl = slider_counts if type(slider_counts) is list else np.asarray(slider_counts, dtype=np.float64).tolist()
        sc = [c * r for c in sl]
        p = [sc[0] * J[i][0] + sc[1] * J[i][1] + sc[2] * J[i][2] for i in range(3)]  # (s·res) @ Jᵀ
        pp, vo = self._sp, self._sv
        a = cfg.velocity_alpha
        if a > 0.0:
            v = [a * vo[i] + (1.0 - a) * ((p[i] - pp[i]) / T) for i in range(3)]
        else:
            v = [(p[i] - pp[i]) / T for i in range(3)]
        env = cfg.env
        if env == EnvKind.FREE:
            F = [0.0, 0.0, 0.0]
        elif env == EnvKind.SPRING:
            K, B, an = self._Kl, self._Bl, self._anchorl
            F = [-K[i] * (p[i] - an[i]) - B[i] * v[i] for i in range(3)]
        elif env == EnvKind.BOX:  # inside
            an, half, Kb, Bb = self._anchorl, self._halfl, self._Kb, self._Bb
            F = [0.0, 0.0, 0.0]
            for i in range(3):
                dl = p[i] - an[i]
                depth = abs(dl) - half[i]
                if depth > 0.0:
                    sgn = 1.0 if dl > 0.0 else (-1.0 if dl < 0.0 else 0.0)
                    F[i] = -Kb * sgn * depth - Bb * v[i]
        else:
            ph = self._fomega * (self._tick * T)
            F = [fa * math.sin(ph + phi) for fa, phi in zip(self._famp_l, self._fphase)]
        if cfg.friction_compensation:
            fc, fcv = self._fc, self._fcv
            F = [F[0] + fc * math.tanh(v[0] / fcv), F[1] + fc * math.tanh(v[1] / fcv), F[2] + 0.0]
        if cfg.gravity_compensation:
            F[2] = F[2] + self._weight
        f_ref = [F[0] * J[0][j] + F[1] * J[1][j] + F[2] * J[2][j] for j in range(3)]  # F @ J
        lim = self._limit
        if cfg.force_loop == ForceLoop.SEA:
            ks, kp = self._spring, self._kp
            dc = (deflection_counts if type(deflection_counts) is list
                  else np.asarray(deflection_counts, dtype=np.float64).tolist())
            err = [f_ref[j] - ks * (dc[j] * r) for j in range(3)]
            out = [kp * e for e in err]
            if cfg.integral:
                kiT = self._ki * T
                integ = [self._si[j] + kiT * err[j] for j in range(3)]
                if cfg.saturation:
                    integ = [min(max(x, -lim), lim) for x in integ]
                out = [out[j] + integ[j] for j in range(3)]
                self._si = integ
        elif cfg.force_loop == ForceLoop.RIGID:
            eta = self._eta
            out = [f / eta for f in f_ref]
        else:
            out = f_ref
        if cfg.saturation:
            out = [min(max(x, -lim), lim) for x in out]
        self._tick += 1
        self._sp, self._sv = p, v
        self.last_force = np.array(F)
        return np.array([out])

    def _render(self, p: np.ndarray, v: np.ndarray, tick: int) -> np.ndarray:
        """F_r at position p, velocity v, tick (:func:`hapticopt.analysis.prrr.firmware._render`)."""
        cfg, T = self.cfg, self.cfg.period
        delta = p - self._anchor
        if cfg.env == EnvKind.FREE:
            F = np.zeros(3)
        elif cfg.env == EnvKind.SPRING:
            F = -self._K * delta - self._B * v
        elif cfg.env == EnvKind.BOX:
            depth = np.abs(delta) - self._half
            sgn = np.sign(delta)
            if cfg.box_mode == BoxMode.INSIDE:
                F = np.where(depth > 0.0, -self._Kb * sgn * depth - self._Bb * v, 0.0)
            else:
                inside = bool(np.all(depth < 0.0))
                pick = np.arange(3) == int(np.argmax(depth))
                F = np.where(inside & pick, self._Kb * sgn * (-depth) - self._Bb * v, 0.0)
        else:
            F = self._famp * np.sin(self._fomega * (tick * T) + np.asarray(self._fphase))
        if cfg.friction_compensation:
            F = F + self._fc * np.tanh(v / self._fcv) * _XY
        if cfg.gravity_compensation:
            F = F + self._weight * _Z
        return F

    def _force_loop(self, f_ref: np.ndarray, deflection_counts, integral: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.cfg
        if cfg.force_loop == ForceLoop.SEA:
            err = f_ref - self._spring * (np.asarray(deflection_counts, dtype=np.float64) * self._res)
            out = self._kp * err
            if cfg.integral:
                integral = integral + self._ki * cfg.period * err
                if cfg.saturation:
                    integral = np.clip(integral, -self._limit, self._limit)
                out = out + integral
        elif cfg.force_loop == ForceLoop.RIGID:
            out = f_ref / self._eta
        else:
            out = f_ref
        return out, integral

    def _online_predictions(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p̂_{i+1}, p̂_{i+2}) per axis by ``upsampling.fit_ar`` over the last ar_window positions."""
        cfg = self.cfg
        coef = np.empty((3, cfg.ar_order))
        for k in range(3):
            fit = up.fit_ar(positions[:, k], order=cfg.ar_order, window=cfg.ar_window)
            coef[k] = fit.coefficients
            self.fit_counts[fit.status] = self.fit_counts.get(fit.status, 0) + 1
        newest = positions[::-1][: cfg.ar_order]  # (p, 3): p_i, p_{i−1}, …
        p1 = np.sum(coef.T * newest, axis=0)
        newest2 = np.concatenate([p1[None], newest[:-1]], axis=0)
        p2 = np.sum(coef.T * newest2, axis=0)
        return p1, p2

    def step_generic(self, slider_counts: np.ndarray, deflection_counts: np.ndarray) -> np.ndarray:
        """Commands (L, 3) [N] for this period from the counts read at its start (numpy 3-vectors)."""
        cfg = self.cfg
        if not self._ready:
            self.reset(slider_counts)
        T = cfg.period
        p = (np.asarray(slider_counts, dtype=np.float64) * self._res) @ self._JT
        diff = (p - self._p_prev) / T
        a = cfg.velocity_alpha
        v = a * self._v + (1.0 - a) * diff if a > 0.0 else diff
        F = self._render(p, v, self._tick)
        f_ref = F @ self._J
        out, integral = self._force_loop(f_ref, deflection_counts, self._integral)
        history = self._history
        if self._W is not None:
            history = np.concatenate([history[1:], out[None]], axis=0)
            if cfg.online:
                self._positions = np.concatenate([self._positions[1:], p[None]], axis=0)
                p1, p2 = self._online_predictions(self._positions)

                def vel(v_prev: np.ndarray, new: np.ndarray, old: np.ndarray) -> np.ndarray:
                    d = (new - old) / T
                    return a * v_prev + (1.0 - a) * d if a > 0.0 else d

                v1 = vel(v, p1, p)
                v2 = vel(v1, p2, p1)
                pred, ik = self._force_loop(self._render(p1, v1, self._tick + 1) @ self._J, deflection_counts, integral)
                pred2, _ = self._force_loop(self._render(p2, v2, self._tick + 2) @ self._J, deflection_counts, ik)
            else:
                pred, pred2 = firmware.predictions(cfg.ar, history)
            ctrl = np.concatenate([history, pred[None], pred2[None]], axis=0)
            cmd = self._W @ ctrl
        else:
            cmd = out[None, :]
        if cfg.saturation:
            cmd = np.clip(cmd, -self._limit, self._limit)
        self._tick += 1
        self._p_prev, self._v, self._integral, self._history = p, v, integral, history
        self.last_force = F
        return cmd

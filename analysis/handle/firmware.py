"""The handle's firmware in a scene: the wall of eq (8) at the update rate, prediction + eq (23) upsampling.

Per update i (period T), from the measured tip position x_i:

1. velocity by backward difference v_i = (x_i − x_{i−1})/T (seed 000 section 1);
2. predicted positions x̂_{i+1}, x̂_{i+2} by the AR recursion (``analysis.control.upsampling.predict``)
   with the scene's fixed coefficients (default (2, −1));
3. the wall's shaft force at the measured and predicted positions, f = law(x, v) (:class:`WallLaw`);
4. L = l2/l1 output samples from the eq (23) spline of the scene's variant
   (``analysis.control.upsampling.spline_weights``; ``none`` holds f_i).

For a bilateral wall this is term by term the law of ``analysis.control.upsampling.simulate`` and
of the lifted analysis (tested). The one-sided wall (the elastic ball of the paper's experiment)
computes its clipped force at each predicted position, so the spline never pulls on a position
that is predicted to be outside the wall.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from hapticopt.analysis.control import upsampling as up


class WallKind(enum.Enum):
    BILATERAL = "bilateral"  #: spring-damper f = K (x − a) + B v (the paper's virtual wall, eq 8)
    ONE_SIDED = "one_sided"  #: contact beyond a ± d only, pushing out, never pulling (elastic ball)


@dataclass(frozen=True, kw_only=True)
class WallLaw:
    """Shaft force f_m [N] of the virtual environment at a tip position x [m], velocity v [m/s]."""

    kind: WallKind
    stiffness_N_per_m: float  #: K_e (shaft force per tip displacement)
    damping_N_s_per_m: float  #: B_e
    anchor_m: float = 0.0  #: a
    half_width_m: float = 0.0  #: d: the one-sided walls are at a ± d

    def force(self, x: float, v: float) -> float:
        K, B = self.stiffness_N_per_m, self.damping_N_s_per_m
        d = x - self.anchor_m
        if self.kind is WallKind.BILATERAL:
            return K * d + B * v
        depth = abs(d) - self.half_width_m
        if depth <= 0.0:
            return 0.0
        sgn = 1.0 if d > 0.0 else -1.0
        return sgn * max(0.0, K * depth + sgn * B * v)


@dataclass(frozen=True, kw_only=True)
class HandleFirmwareConfig:
    period_s: float
    upsampling: int
    variant: up.Variant
    ar_coefficients: tuple[float, ...]
    wall: WallLaw

    def __post_init__(self) -> None:
        up.spline_weights(self.upsampling, self.variant)  # validates L
        if not (math.isfinite(self.period_s) and self.period_s > 0.0):
            raise ValueError(f"period_s = {self.period_s!r}: allowed finite values > 0 [s]")


class HandleFirmware:
    """One controller: ``step(x_i) -> (L,) shaft forces`` [N], held T/L each."""

    def __init__(self, cfg: HandleFirmwareConfig) -> None:
        self.cfg = cfg
        self._W = up.spline_weights(cfg.upsampling, cfg.variant)
        self._a = np.asarray(cfg.ar_coefficients, dtype=float)
        self._hist: list[float] | None = None
        self._f = (0.0, 0.0)  # f_{i−2}, f_{i−1}

    def reset(self, x0: float) -> None:
        """At power-up the history is the first reading (at rest)."""
        n = max(self._a.size, 2)
        self._hist = [float(x0)] * n
        f0 = self.cfg.wall.force(float(x0), 0.0)
        self._f = (f0, f0)

    def step(self, x: float) -> np.ndarray:
        if self._hist is None:
            self.reset(x)
        T, law = self.cfg.period_s, self.cfg.wall
        h = self._hist[1:] + [float(x)]
        self._hist = h
        fi = law.force(h[-1], (h[-1] - h[-2]) / T)
        if self.cfg.variant is up.Variant.NONE:
            P = np.array([self._f[0], self._f[1], fi, 0.0, 0.0])
        else:
            x1, x2 = up.predict(self._a, h, steps=2)
            P = np.array([self._f[0], self._f[1], fi, law.force(x1, (x1 - h[-1]) / T), law.force(x2, (x2 - x1) / T)])
        self._f = (self._f[1], fi)
        return self._W @ P

"""The handle's firmware in a scene: the wall of eq (8) at the update rate, prediction + eq (23) upsampling.

Per update i (period T), from the measured tip position x_i:

1. velocity by backward difference v_i = (x_i − x_{i−1})/T (seed 000 section 1);
2. predicted positions x̂_{i+1}, x̂_{i+2} by the AR recursion (``analysis.control.upsampling.predict``)
   with the scene's fixed coefficients (default (2, −1)) or, with ``predictor = online`` (seed 000's
   method), coefficients fitted by least squares to the last ``ar_window`` positions at this update
   (``analysis.control.upsampling.fit_ar``; a short or unexciting history falls back to (2, −1), and
   every update's fit status is counted — :meth:`HandleFirmware.predictor_report`);
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
    predictor: up.Predictor = up.Predictor.FIXED
    ar_order: int = 2  #: p, online predictor only [samples]
    ar_window: int = 16  #: regression window, online predictor only [samples]

    def __post_init__(self) -> None:
        up.spline_weights(self.upsampling, self.variant)  # validates L
        if self.predictor is up.Predictor.ONLINE:
            up.fit_ar(np.zeros(1), order=self.ar_order, window=self.ar_window)  # validates p and the window
        if not (math.isfinite(self.period_s) and self.period_s > 0.0):
            raise ValueError(f"period_s = {self.period_s!r}: allowed finite values > 0 [s]")


class HandleFirmware:
    """One controller: ``step(x_i) -> (L,) shaft forces`` [N], held T/L each."""

    def __init__(self, cfg: HandleFirmwareConfig) -> None:
        self.cfg = cfg
        self._W = up.spline_weights(cfg.upsampling, cfg.variant)
        self._a = np.asarray(cfg.ar_coefficients, dtype=float)
        self._online = cfg.predictor is up.Predictor.ONLINE
        self._hist: list[float] | None = None
        self._f = (0.0, 0.0)  # f_{i−2}, f_{i−1}
        self._counts = {s: 0 for s in up.ARStatus}
        self._coef_sum = np.zeros(cfg.ar_order if self._online else self._a.size)
        self._residuals: list[float] = []
        self._last = up.ARFit(self._a.copy(), up.ARStatus.FIXED, math.nan, math.nan)

    def reset(self, x0: float) -> None:
        """At power-up the history is the first reading (at rest)."""
        n = max(self._a.size, 2)
        if self._online:
            n = max(self.cfg.ar_window, self.cfg.ar_order + 1, 2)
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
            a = self._a
            if self._online:
                fit = up.fit_ar(h, order=self.cfg.ar_order, window=self.cfg.ar_window)
                self._counts[fit.status] += 1
                self._last = fit
                a = fit.coefficients
                if fit.status is up.ARStatus.FITTED:
                    self._coef_sum += a
                    self._residuals.append(fit.residual_rms_m)
            x1, x2 = up.predict(a, h, steps=2)
            P = np.array([self._f[0], self._f[1], fi, law.force(x1, (x1 - h[-1]) / T), law.force(x2, (x2 - x1) / T)])
        self._f = (self._f[1], fi)
        return self._W @ P

    def predictor_report(self) -> dict[str, object]:
        """How the predictor ran: the source of its coefficients, for an online fit the share of
        updates that fitted (others fell back to (2, −1)), the mean fitted coefficients and the
        median rms one-step residual [m], and the last update's coefficients and status."""
        if not self._online:
            return {"predictor": "fixed", "ar_coefficients": tuple(float(v) for v in self._a)}
        n = sum(self._counts.values())
        fitted = self._counts[up.ARStatus.FITTED]
        return {
            "predictor": "online",
            "ar_order": self.cfg.ar_order,
            "ar_window": self.cfg.ar_window,
            "ar_updates": n,
            "ar_fitted_fraction": fitted / n if n else math.nan,
            "ar_fallbacks": {s.value: c for s, c in self._counts.items() if c and s is not up.ARStatus.FITTED},
            "ar_mean_coefficients": tuple(float(v) for v in self._coef_sum / fitted) if fitted else (),
            "ar_median_residual_rms_m": float(np.median(self._residuals)) if self._residuals else math.nan,
            "ar_last_coefficients": tuple(float(v) for v in self._last.coefficients),
            "ar_last_status": self._last.status.value,
        }

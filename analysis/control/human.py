"""Human operator model of seed 001 eq 2: K_r ḟ + K_f f = K_c e_p.

The gains describe the operator's skill; the impedance learner never reads them (it only sees
the measured e_p, ė_p, f). They enter the simulator through the state-space form of eq 4.

Units: e_p [m], f [N], K_r [s], K_f [-], K_c [N/m].
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


@dataclasses.dataclass(frozen=True, kw_only=True)
class HumanModel:
    """Gains of eq 2. Defaults: seed 001 section 4.1 (K_r = 0.5, K_f = 5, K_c (printed K_e) = 20)."""

    k_r: float = 0.5  # [s]
    k_f: float = 5.0  # [-]
    k_c: float = 20.0  # [N/m]

    def __post_init__(self) -> None:
        for name in ("k_r", "k_f", "k_c"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"HumanModel.{name} = {v!r}: must be finite and > 0 (unit: "
                                 f"{ {'k_r': 's', 'k_f': '-', 'k_c': 'N/m'}[name] })")


def force_rate(model: HumanModel, e_p: float, f: float) -> float:
    """ḟ [N/s] from eq 2 for tracking error e_p [m] and force f [N]."""
    return (model.k_c * e_p - model.k_f * f) / model.k_r


def state_space(model: HumanModel) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of eq 4 for one Cartesian axis, state X = [e_p, ė_p, f], input u = ë_p.

    A = [[0, 1, 0], [0, 0, 0], [K_c/K_r, 0, −K_f/K_r]], B = [0, 1, 0]ᵀ (eq 4; eq 29 for the
    section 4.1 gains).
    """
    a = np.array([[0.0, 1.0, 0.0],
                  [0.0, 0.0, 0.0],
                  [model.k_c / model.k_r, 0.0, -model.k_f / model.k_r]])
    b = np.array([[0.0], [1.0], [0.0]])
    return a, b

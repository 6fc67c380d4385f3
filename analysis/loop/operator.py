"""The operator's hand as the scenes and the stability analyses model it.

:class:`Operator` is seed 000's hand impedance Z_h = m_h s + b_h + k_h/s (eq 1): a mass on a
spring and a damper to the reference motion, tied to the handle. The lumped plant, the MuJoCo
plants, the scenes and the seed-000 handle's stability analysis (``analysis/handle``) all take
this one type. Its defaults are the scenes' firm grip; :data:`NO_HAND` is the hand absent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields


@dataclass(frozen=True, kw_only=True)
class Operator:
    """Hand impedance Z_h = m_h s + b_h + k_h/s (seed 000 eq 1), SI."""

    mass: float = 0.3  # m_h [kg]
    damping: float = 50.0  # b_h [N·s/m]
    stiffness: float = 20e3  # k_h [N/m]

    def __post_init__(self) -> None:
        units = {"mass": "kg", "damping": "N·s/m", "stiffness": "N/m"}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"Operator.{f.name} = {v!r}: allowed finite values ≥ 0 [{units[f.name]}]")


#: no hand on the device (m_h = b_h = k_h = 0)
NO_HAND = Operator(mass=0.0, damping=0.0, stiffness=0.0)


def hand(*, mass: float = 0.0, damping: float = 0.0, stiffness: float = 0.0) -> Operator:
    """An :class:`Operator` whose unnamed terms are absent (zero) instead of the scenes' defaults."""
    return Operator(mass=mass, damping=damping, stiffness=stiffness)

"""The operator's hand as the scenes model it.

:class:`Operator` is seed 000's hand impedance Z_h = m_h s + b_h + k_h/s (eq 1): a mass on a
spring and a damper to the reference motion, tied to the handle. The lumped plant, the MuJoCo
plants and the stability analyses all take this one type.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, kw_only=True)
class Operator:
    """Hand impedance Z_h = m_h s + b_h + k_h/s (seed 000 eq 1)."""

    mass: float = 0.3  # [kg]
    damping: float = 50.0  # [N·s/m]
    stiffness: float = 20e3  # [N/m]

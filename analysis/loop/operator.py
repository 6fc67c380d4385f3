"""The operator as the scenes model it: one type, two kinds.

:class:`Operator` is the project's one operator type. Its ``kind`` picks the model:

* ``mass_spring_damper`` — seed 000's hand impedance Z_h = m_h s + b_h + k_h/s (eq 1): a mass on
  a spring and a damper to the reference motion, tied to the handle. The lumped plant, the
  MuJoCo plants and the stability analyses take this kind.
* ``force_eq2`` — seed 001's operator of eq 2, K_r ḟ + K_f f = K_c e_p: a force source whose
  force f [N] follows the error e_p = x − x_d [m] between the device's position and the
  operator's desired position x_d (the scene's motion). The gains describe the operator's skill
  and are unknown to the impedance learner (it only sees the measured e_p, ė_p, f). With eq 1
  of seed 001 the device yields to −f, so the force on the device is −f along the learning axis.
  The IOIC firmware mode (scenes with ``controller.mode = "ioic"``) and the seed-001 outer-loop
  simulator (:mod:`hapticopt.analysis.control.impedance_learning`) take this kind.

The seed-000 handle's stability analysis (``analysis/handle``) takes the first kind too. The
defaults are the scenes' firm grip; :data:`NO_HAND` is the hand absent, :func:`hand` a hand whose
unnamed terms are zero.

Units: m_h [kg], b_h [N·s/m], k_h [N/m]; K_r [s], K_f [-], K_c [N/m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from hapticopt.design.errors import InvalidInput


class OperatorKind(StrEnum):
    MASS_SPRING_DAMPER = "mass_spring_damper"  # seed 000 eq 1
    FORCE_EQ2 = "force_eq2"  # seed 001 eq 2


_EQ2_UNITS = {"force_time_constant": "s", "force_decay": "-", "force_gain": "N/m"}


def _finite_number(v: object) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)


@dataclass(frozen=True, kw_only=True)
class Operator:
    """The operator. ``mass``/``damping``/``stiffness``: seed 000 eq 1 (kind ``mass_spring_damper``);
    ``force_time_constant`` K_r, ``force_decay`` K_f, ``force_gain`` K_c: seed 001 eq 2 (kind
    ``force_eq2``; defaults: seed 001 §4.1, K_r = 0.5 s, K_f = 5, K_c (printed K_e) = 20 N/m).
    The fields of the other kind are not used by any plant."""

    kind: OperatorKind = OperatorKind.MASS_SPRING_DAMPER
    mass: float = 0.3  # m_h [kg]
    damping: float = 50.0  # b_h [N·s/m]
    stiffness: float = 20e3  # k_h [N/m]
    force_time_constant: float = 0.5  # K_r [s]
    force_decay: float = 5.0  # K_f [-]
    force_gain: float = 20.0  # K_c [N/m]

    def __post_init__(self) -> None:
        if not isinstance(self.kind, OperatorKind):
            raise InvalidInput(f"Operator.kind = {self.kind!r} is not known: allowed "
                               + ", ".join(k.value for k in OperatorKind))
        for name, unit in (("mass", "kg"), ("damping", "N·s/m"), ("stiffness", "N/m")):
            v = getattr(self, name)
            if not _finite_number(v) or v < 0.0:
                raise InvalidInput(f"Operator.{name} = {v!r}: allowed finite values ≥ 0 [{unit}]")
        for name, unit in _EQ2_UNITS.items():
            v = getattr(self, name)
            if not _finite_number(v) or v <= 0.0:
                raise InvalidInput(f"Operator.{name} = {v!r}: allowed finite values > 0 [{unit}]")

    @classmethod
    def eq2(cls, *, k_r: float = 0.5, k_f: float = 5.0, k_c: float = 20.0) -> Operator:
        """Seed 001's operator of eq 2 with K_r [s], K_f [-], K_c [N/m] (defaults §4.1)."""
        return cls(kind=OperatorKind.FORCE_EQ2, mass=0.0, damping=0.0, stiffness=0.0,
                   force_time_constant=k_r, force_decay=k_f, force_gain=k_c)


#: no hand on the device (m_h = b_h = k_h = 0)
NO_HAND = Operator(mass=0.0, damping=0.0, stiffness=0.0)


def hand(*, mass: float = 0.0, damping: float = 0.0, stiffness: float = 0.0) -> Operator:
    """A seed-000 hand whose unnamed terms are absent (zero) instead of the scenes' defaults."""
    return Operator(mass=mass, damping=damping, stiffness=stiffness)


def _require_eq2(op: Operator) -> None:
    if op.kind != OperatorKind.FORCE_EQ2:
        raise InvalidInput(f"operator.kind = {op.kind.value!r}: seed 001 eq 2 needs kind = \"force_eq2\"")


def force_step(op: Operator, f: float, e_p: float, h: float) -> float:
    """f after h [s] of eq 2 with e_p [m] held: the exact first-order step
    f(h) = f e^{−h K_f/K_r} + (K_c/K_f) e_p (1 − e^{−h K_f/K_r})."""
    _require_eq2(op)
    a = math.exp(-h * op.force_decay / op.force_time_constant)
    return f * a + op.force_gain / op.force_decay * e_p * (1.0 - a)


def state_space(op: Operator) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of seed 001 eq 4 for one Cartesian axis, X = [e_p, ė_p, f], u = ë_p:
    A = [[0, 1, 0], [0, 0, 0], [K_c/K_r, 0, −K_f/K_r]], B = [0, 1, 0]ᵀ (eq 29 for §4.1's gains)."""
    _require_eq2(op)
    a = np.array([[0.0, 1.0, 0.0],
                  [0.0, 0.0, 0.0],
                  [op.force_gain / op.force_time_constant, 0.0, -op.force_decay / op.force_time_constant]])
    b = np.array([[0.0], [1.0], [0.0]])
    return a, b

"""The plant interface the closed-loop runner talks to (lumped today, multibody in issue 8).

A plant is a stateful object advanced one controller period at a time. It exposes exactly
what the firmware's sensors measure (true, unquantised values; the runner quantises) and the
observables the metrics need; the controller never sees anything else.

Conventions: slider positions D_e are measured from the home pose (p = 0) [m]; spring
deflections x = D − D_e [m]; end-effector quantities are Cartesian [m, m/s, N]. Commands are
the motor forces F per leg [N] (or, without motor dynamics, the spring forces), shape
``(L, 3)``: L samples spread evenly over the period (L = 1: zero-order hold).
"""

from __future__ import annotations

from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np


class Sensors(NamedTuple):
    """What the firmware reads each tick."""

    slider: np.ndarray  # (3,) output-slider positions from home [m] (encoders)
    deflection: np.ndarray  # (3,) spring deflections D − D_e [m] (deflection encoders)


class Observation(NamedTuple):
    """Simulator-side observables for the metrics (never shown to the firmware)."""

    position: np.ndarray  # (3,) end-effector p [m]
    velocity: np.ndarray  # (3,) ṗ [m/s]
    hand_force: np.ndarray  # (3,) force of the hand on the device [N] (zero without an operator)
    actuator_force: np.ndarray  # (3,) Cartesian force the actuators apply to the output, J⁻ᵀ f [N]
    energy: float  # mechanical energy of the device (kinetic + spring) [J]


@runtime_checkable
class Plant(Protocol):
    """Minimal plant interface. ``backend`` names it in every result ("lumped", "multibody")."""

    backend: str

    def reset(self) -> None:
        """Return to the scene's initial state."""

    def sensors(self) -> Sensors:
        """True sensor values now."""

    def advance(self, commands: np.ndarray) -> None:
        """Advance one controller period with ``commands`` (L, 3) [N] held piecewise constant."""

    def observe(self) -> Observation:
        """Observables at the end of the last period."""

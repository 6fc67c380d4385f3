"""MuJoCo settings shared by every multibody plant: solver settings per fidelity, and the
closed-chain health of a state (constraint residuals), reported by each plant's results.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.errors import InvalidInput


class Integrator(StrEnum):
    EULER = "Euler"
    IMPLICITFAST = "implicitfast"
    IMPLICIT = "implicit"
    RK4 = "RK4"


@dataclass(frozen=True, kw_only=True)
class SolverSettings:
    """MuJoCo solver settings: part of the fidelity level.

    ``solref`` = (time constant [s], damping ratio) of the equality constraints; MuJoCo clamps
    the time constant to ≥ 2·timestep. ``solimp`` = (d0, d_width, width [m], midpoint, power).
    """

    timestep: float = 1e-4
    integrator: Integrator = Integrator.RK4
    solref: tuple[float, float] = (2e-4, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.9999, 0.9999, 0.001, 0.5, 2.0)
    iterations: int = 50
    tolerance: float = 1e-12

    def __post_init__(self) -> None:
        if not (0.0 < self.timestep <= 0.01):
            raise InvalidInput(f"solver timestep = {self.timestep!r} s must be in (0, 0.01]")
        if not (0.0 < self.solimp[0] < 1.0 and 0.0 < self.solimp[1] < 1.0):
            raise InvalidInput(f"solver solimp = {self.solimp!r}: d0 and d_width must be in (0, 1)")


#: Solver settings per fidelity (chosen from the measured table in docs/multibody.md).
SOLVER_BY_FIDELITY: dict[Fidelity, SolverSettings] = {
    Fidelity.DRAFT: SolverSettings(timestep=2.5e-4, integrator=Integrator.EULER, solref=(5e-4, 1.0)),
    Fidelity.STANDARD: SolverSettings(timestep=1e-4, integrator=Integrator.EULER, solref=(2e-4, 1.0)),
    Fidelity.FINE: SolverSettings(timestep=2.5e-5, integrator=Integrator.RK4, solref=(5e-5, 1.0)),
}


# --------------------------------------------------------------------------- constraint health
@dataclass(frozen=True, kw_only=True)
class Health:
    """Closed-chain health of one state (or the worst over a run)."""

    violation: float  # largest equality-constraint residual [m]
    rotation: float  # end-effector rotation angle [rad]
    closure: float  # |p_ee − J(D_e − c_e)|: end-effector vs forward kinematics of the sliders [m]

    def worst(self, other: "Health") -> "Health":
        return Health(violation=max(self.violation, other.violation),
                      rotation=max(self.rotation, other.rotation),
                      closure=max(self.closure, other.closure))

    def metrics(self) -> dict[str, float]:
        return {"constraint_violation_mm": self.violation * 1e3,
                "ee_rotation_mrad": self.rotation * 1e3,
                "closure_error_mm": self.closure * 1e3}


ZERO_HEALTH = Health(violation=0.0, rotation=0.0, closure=0.0)

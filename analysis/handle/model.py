"""Per-axis model of seed 000's haptic handle in SI, with the operator (eq 1) and a virtual wall.

Dynamics (eq 3–4 of the paper, x = Rθ the tip displacement):

    (I/R² + m_h) ẍ + (B_m/R² + b_h) ẋ + k_h x = −(r/R) f_m + f_ext,    I = I_m + I_l

with f_m = K_e x + B_e ẋ the virtual wall's force (eq 8) at the motor shaft of radius r, applied
after a zero-order hold of period T (eq 9). The operator of eq (1), Z_h = m_h s + b_h + k_h/s, acts
at the tip against a fixed motion command (x_e = 0); it is the project's one hand type,
:class:`hapticopt.analysis.loop.operator.Operator` (fields ``mass`` [kg], ``damping`` [N·s/m], ``stiffness`` [N/m]).

Paper values and their conversion to SI (section 2.2):

================  =========================  =========================================
paper             SI                         how
================  =========================  =========================================
r = 6 mm          6e-3 m                     mm → m
R = 15 cm         0.15 m                     cm → m
I_m = 34.7 g·cm²  3.47e-6 kg·m²              1 g·cm² = 1e-3 kg · 1e-4 m² = 1e-7 kg·m²
I_l = 4593.75     4.59375e-4 kg·m²           same; = 245 g · (15 cm)² / 12 (rod, 70 cm³ × 3.5 g/cm³)
B_m = 11.72       1.172e-3 N·m·s/rad         g·cm²/ms = 1e-7 kg·m² / 1e-3 s = 1e-4 kg·m²/s;
  g·cm²/ms                                   B_m = I_m/τ_mech = 34.7 g·cm² / 2.96 ms
B_e = 30          0.030 N·s/m                eq (19) substitutes it as 9·B_e with rR = 9 cm², so
  "g·cm²/s"                                  rR·B_e is in g·cm²/s and B_e carries g/s:
                                             30 g/s = 0.030 kg/s. Read literally (30 g·cm²/s
                                             divided by rR) it would be 3.3e-3 N·s/m and eq (19)
                                             would give 2.614 N/mm instead of the paper's 2.67.
K_e in eq (19)    N/m                        eq (19) is in g/s²; 1 g/s² = 1e-3 N/m = 1e-6 N/mm
================  =========================  =========================================
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from hapticopt.analysis.control.upsampling import Plant
from hapticopt.analysis.loop.operator import NO_HAND, Operator, hand  # noqa: F401  (re-exported)
from hapticopt.design.handle.params import HandleDesign

G_CM2 = 1e-7  #: 1 g·cm² in kg·m²
MS = 1e-3  #: 1 ms in s
N_PER_MM = 1e3  #: 1 N/mm in N/m


class Hold(enum.Enum):
    """How the zero-order hold of eq (9) is modelled."""

    EXACT = "exact"  #: sampled loop, exact ZOH discretisation (matrix exponential)
    PADE = "pade"  #: the paper's continuous approximation 2/(2 + sT)


#: no operator: the handle alone (the one hand type, ``analysis.loop.operator.Operator``)
NO_OPERATOR = NO_HAND


@dataclass(frozen=True, kw_only=True)
class Handle:
    """One axis of seed 000's handle with its virtual wall and sampling period (SI throughout)."""

    motor_radius_m: float = 6e-3  # r = 6 mm
    lever_m: float = 0.15  # R = 15 cm
    motor_inertia_kg_m2: float = 34.7 * G_CM2  # I_m = 34.7 g·cm²
    link_inertia_kg_m2: float = 4593.75 * G_CM2  # I_l = 4593.75 g·cm²
    motor_damping_N_m_s: float = 11.72 * G_CM2 / MS  # B_m = 11.72 g·cm²/ms
    wall_stiffness_N_per_m: float = 0.0  # K_e
    wall_damping_N_s_per_m: float = 0.0  # B_e
    period_s: float = 1e-3  # T
    operator: Operator = NO_OPERATOR

    def __post_init__(self) -> None:
        positive = ("motor_radius_m", "lever_m", "motor_inertia_kg_m2", "link_inertia_kg_m2",
                    "motor_damping_N_m_s", "period_s")
        for name in positive:
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0.0):
                raise ValueError(f"Handle.{name} = {v!r}: must be finite and > 0 [unit in the name]")
        for name in ("wall_stiffness_N_per_m", "wall_damping_N_s_per_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0.0):
                raise ValueError(f"Handle.{name} = {v!r}: must be finite and ≥ 0 [unit in the name]")

    # ------------------------------------------------------------------ derived quantities (SI)
    @property
    def inertia_kg_m2(self) -> float:
        """I = I_m + I_l [kg·m²]."""
        return self.motor_inertia_kg_m2 + self.link_inertia_kg_m2

    @property
    def rR_m2(self) -> float:
        """r·R [m²] (9 cm² for the paper's handle)."""
        return self.motor_radius_m * self.lever_m

    @property
    def transmission(self) -> float:
        """r/R [-]: tip force per wall force f_m."""
        return self.motor_radius_m / self.lever_m

    @property
    def mass_kg(self) -> float:
        """Equivalent tip mass I/R² + m_h [kg]."""
        return self.inertia_kg_m2 / self.lever_m**2 + self.operator.mass

    @property
    def damping_N_s_per_m(self) -> float:
        """Equivalent tip damping B_m/R² + b_h [N·s/m]."""
        return self.motor_damping_N_m_s / self.lever_m**2 + self.operator.damping

    def with_(self, **changes) -> Handle:
        """``dataclasses.replace`` shorthand."""
        return dataclasses.replace(self, **changes)


#: the paper's handle (section 2.2), no wall, T = 1 ms
HANDLE_PAPER = Handle()


def from_design(design: HandleDesign) -> Handle:
    """The analysis model of a handle description (``design/handle/params.py``), SI throughout."""
    g, d, w, o = design.geometry, design.drive, design.wall, design.operator
    return Handle(motor_radius_m=g.motor_radius, lever_m=g.lever, motor_inertia_kg_m2=d.motor_inertia,
                  link_inertia_kg_m2=d.link_inertia, motor_damping_N_m_s=d.motor_damping,
                  wall_stiffness_N_per_m=w.stiffness, wall_damping_N_s_per_m=w.damping,
                  period_s=design.firmware.period,
                  operator=Operator(mass=o.mass, damping=o.damping, stiffness=o.stiffness))
#: the paper's virtual damping B_e = 30 "g·cm²/s" of eq (19), i.e. 30 g/s (module docstring)
PAPER_WALL_DAMPING_N_S_PER_M = 30e-3


@dataclass(frozen=True)
class StateSpace:
    """ẋ = A x + B u, y = C x; u = [f_m, f_ext] (or the held force's input for the Padé loop)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray


def plant(handle: Handle, *, with_operator: bool = True) -> StateSpace:
    """Open-loop plant, state [x, ẋ] [m, m/s], inputs [f_m, f_ext] [N], output x [m]."""
    op = handle.operator if with_operator else NO_OPERATOR
    h = dataclasses.replace(handle, operator=op)
    m, b, k = h.mass_kg, h.damping_N_s_per_m, op.stiffness
    A = np.array([[0.0, 1.0], [-k / m, -b / m]])
    B = np.array([[0.0, 0.0], [-h.transmission / m, 1.0 / m]])
    C = np.array([[1.0, 0.0]])
    return StateSpace(A, B, C)


def pade_closed_loop(handle: Handle, *, with_operator: bool = True) -> StateSpace:
    """The paper's continuous loop: the wall force K_e x + B_e ẋ through 2/(2 + sT) (eq 9–10).

    State [x, ẋ, f_m]; input f_ext; output x. Its characteristic polynomial is eq (15)
    (without the operator) or eq (20) with R² k_h (with; see ``stability``), divided by T·I.
    """
    p = plant(handle, with_operator=with_operator)
    T = handle.period_s
    A = np.zeros((3, 3))
    A[:2, :2] = p.A
    A[:2, 2] = p.B[:, 0]
    A[2, :] = [2.0 / T * handle.wall_stiffness_N_per_m, 2.0 / T * handle.wall_damping_N_s_per_m, -2.0 / T]
    B = np.array([[0.0], [p.B[1, 1]], [0.0]])
    C = np.array([[1.0, 0.0, 0.0]])
    return StateSpace(A, B, C)


def discrete_plant(handle: Handle, *, period_s: float | None = None, with_operator: bool = True
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH plant over ``period_s`` (default T): Φ − I (2×2), Γ (2×2) for inputs [f_m, f_ext].

    Φ − I is returned instead of Φ so that the loop can be analysed in delta form without the
    cancellation 1 − ρ suffers as T → 0: with Ψ = ∫₀ʰ e^{Aτ} dτ (one expm of [[A, I], [0, 0]]h),
    Φ − I = AΨ and Γ = ΨB exactly.
    """
    p = plant(handle, with_operator=with_operator)
    h = handle.period_s if period_s is None else period_s
    n = p.A.shape[0]
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = p.A * h
    M[:n, n:] = np.eye(n) * h
    Psi = scipy.linalg.expm(M)[:n, n:]
    return p.A @ Psi, Psi @ p.B


def wall_plant(handle: Handle, *, with_operator: bool = True):
    """The plant as seen by the shared firmware (``analysis.control.upsampling.Plant``): input the
    wall force f_m [N], output the tip position x [m]."""
    p = plant(handle, with_operator=with_operator)
    return Plant(p.A, p.B[:, 0].copy(), p.C[0].copy())

"""Seed 000's force-feedback handle, per axis (section 2.2 of the paper).

One axis of the 3-DOF parallel handle: a motor of shaft radius r drives a link of length R
(tip displacement x = Rθ); the motor and link inertias I_m, I_l and the motor damping B_m act
at the shaft. The firmware renders a virtual wall f_m = K_e x + B_e ẋ at the shaft (eq 8),
held by a zero-order hold of period T (eq 9), optionally upsampled by prediction + B-spline
(section 4, eq 23). The operator of eq (1) holds the tip.

Units at the edge are the paper's: inertias in g·cm², B_m in g·cm²/ms. The paper's virtual
damping "B_e = 30 g·cm²/s" is a linear damping of 30 g/s = 0.030 N·s/m (eq 19 substitutes it as
9·B_e with rR = 9 cm²; docs/seed000.md), so ``wall.damping_Ns_per_m`` is in N·s/m. K_e is the
paper's wall stiffness: shaft force per tip displacement (the tip feels (r/R)·K_e).

The wall and the operator are part of the description because the stability evaluators judge
this wall with this hand (eq 18–22); ``hapticopt verify`` scenes bring their own.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hapticopt.design.errors import InvalidDesign
from hapticopt.design.schema import param, validate_section

DEVICE = "handle"

_LEN = dict(lo=0.0, hi=2000.0, lo_open=True)
_INERTIA = dict(lo=0.0, hi=1e9, lo_open=True)


@dataclass(frozen=True, kw_only=True)
class HandleGeometry:
    """Transmission (seed 000 section 2.2)."""

    motor_radius: float = param("motor_radius_mm", "mm", default=6.0, **_LEN, doc="motor shaft radius r")
    lever: float = param("lever_mm", "mm", default=150.0, **_LEN, doc="link length R (tip x = Rθ)")


@dataclass(frozen=True, kw_only=True)
class HandleDrive:
    """Inertias and damping at the motor shaft (seed 000 section 2.2)."""

    motor_inertia: float = param("motor_inertia_g_cm2", "g_cm2", default=34.7, **_INERTIA, doc="I_m")
    link_inertia: float = param("link_inertia_g_cm2", "g_cm2", default=4593.75, **_INERTIA,
                                doc="I_l = 245 g · (15 cm)² / 12 (70 cm³ rod of 3.5 g/cm³)")
    motor_damping: float = param("motor_damping_g_cm2_per_ms", "g_cm2_per_ms", default=11.72, lo=0.0, hi=1e9,
                                 lo_open=True, doc="B_m = I_m / 2.96 ms")


@dataclass(frozen=True, kw_only=True)
class HandleFirmware:
    """Update period and the prediction + upsampling of section 4."""

    period: float = param("period_ms", "ms", default=1.0, lo=0.0, hi=100.0, lo_open=True,
                          doc="T, the virtual environment's update period (zero-order hold)")
    upsampling: int = param("upsampling", "", default=1, lo=1, hi=64, integer=True,
                            doc="l2/l1 output samples per update (1 = plain hold)")
    ar_order: int = param("ar_order", "", default=2, lo=1, hi=16, integer=True, doc="AR predictor order p")
    ar_window: int = param("ar_window", "", default=16, lo=2, hi=4096, integer=True,
                           doc="positions in the AR least-squares window (≥ 2p)")


@dataclass(frozen=True, kw_only=True)
class HandleWall:
    """The virtual wall of eq (8) the stability evaluators judge."""

    stiffness: float = param("stiffness_N_per_mm", "N_per_mm", default=2.0, lo=0.0, hi=1e6,
                             doc="K_e: shaft force per tip displacement")
    damping: float = param("damping_Ns_per_m", "Ns_per_m", default=0.030, lo=0.0, hi=1e6,
                           doc="B_e on the backward-difference velocity (paper: 30 g/s)")


@dataclass(frozen=True, kw_only=True)
class HandleOperator:
    """The operator of eq (1) at the tip, Z_h = m_h s + b_h + k_h/s (0 = no hand)."""

    mass: float = param("mass_kg", "kg", default=0.0, lo=0.0, hi=100.0, doc="m_h")
    damping: float = param("damping_Ns_per_m", "Ns_per_m", default=0.0, lo=0.0, hi=1e7, doc="b_h")
    stiffness: float = param("stiffness_N_per_mm", "N_per_mm", default=0.0, lo=0.0, hi=1e7, doc="k_h")


@dataclass(frozen=True, kw_only=True)
class HandleDesign:
    """A complete handle description. Frozen; change with :func:`dataclasses.replace`."""

    name: str = "handle"
    description: str = ""
    geometry: HandleGeometry = field(default_factory=HandleGeometry)
    drive: HandleDrive = field(default_factory=HandleDrive)
    firmware: HandleFirmware = field(default_factory=HandleFirmware)
    wall: HandleWall = field(default_factory=HandleWall)
    operator: HandleOperator = field(default_factory=HandleOperator)

    device = DEVICE

    SECTIONS = ("geometry", "drive", "firmware", "wall", "operator")

    def __post_init__(self) -> None:
        validate(self)


def validate(design: HandleDesign) -> None:
    """Check every field's range and the cross-field rules; raise :class:`InvalidDesign`."""
    for section in HandleDesign.SECTIONS:
        validate_section(getattr(design, section), section)
    fw = design.firmware
    if fw.ar_window < 2 * fw.ar_order:
        raise InvalidDesign(f"firmware.ar_window = {fw.ar_window:g} is out of range: allowed ≥ 2·firmware.ar_order = "
                            f"{2 * fw.ar_order:g} (samples; at least as many regression equations as coefficients)")

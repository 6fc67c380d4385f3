"""Units: SI inside, engineering units with the unit in the key at the edges.

A TOML key carries its unit as a suffix (``d3_mm``, ``beta_deg``, ``spring_N_per_mm``).
This module is the one place where those suffixes are turned into SI factors.
"""

from __future__ import annotations

import math

#: standard acceleration of gravity [m/s²]; the one value every evaluator, plant and MJCF uses
GRAVITY = 9.81

#: unit label -> factor that converts a value in that unit to SI.
TO_SI: dict[str, float] = {
    "": 1.0,
    "mm": 1e-3,
    "m": 1.0,
    "deg": math.pi / 180.0,
    "rad": 1.0,
    "kg": 1.0,
    "g": 1e-3,
    "N": 1.0,
    "Nm": 1.0,
    "N_per_mm": 1e3,
    "N_per_m": 1.0,
    "Ns_per_m": 1.0,
    "Ns_per_mm": 1e3,
    "Nms_per_rad": 1.0,
    "kg_per_m3": 1.0,
    "kg_mm2": 1e-6,
    "g_cm2": 1e-7,
    "g_cm2_per_ms": 1e-4,  # 1 g·cm²/ms = 1e-7 kg·m² / 1e-3 s (seed 000's B_m) [N·m·s/rad]
    "GPa": 1e9,
    "MPa": 1e6,
    "Hz": 1.0,
    "s": 1.0,
    "ms": 1e-3,
    "um": 1e-6,
    "mm3": 1e-9,
}


def to_si(value: float, unit: str) -> float:
    """Convert ``value`` given in ``unit`` to SI."""
    return value * TO_SI[unit]


def from_si(value: float, unit: str) -> float:
    """Convert an SI ``value`` to ``unit``."""
    return value / TO_SI[unit]


def pretty(unit: str) -> str:
    """Human-readable unit label for messages and tables (``N_per_mm`` -> ``N/mm``)."""
    if unit == "":
        return "-"
    return (
        unit.replace("_per_", "/")
        .replace("kg_mm2", "kg·mm²")
        .replace("g_cm2", "g·cm²")
        .replace("mm3", "mm³")
        .replace("m3", "m³")
        .replace("um", "µm")
    )

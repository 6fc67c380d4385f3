"""The one place where SI lengths meet build123d's millimetres.

build123d (and our manifold3d meshes) work in mm; hapticopt works in SI. Every conversion of
a length, area, volume or inertia between the two goes through this module.
"""

from __future__ import annotations

import numpy as np

#: millimetres per metre
MM_PER_M = 1000.0


def to_mm(x_m):
    """Length(s) [m] -> [mm] (scalar or array)."""
    return np.asarray(x_m, dtype=float) * MM_PER_M if not np.isscalar(x_m) else float(x_m) * MM_PER_M


def from_mm(x_mm):
    """Length(s) [mm] -> [m]."""
    return np.asarray(x_mm, dtype=float) / MM_PER_M if not np.isscalar(x_mm) else float(x_mm) / MM_PER_M


def volume_from_mm3(v_mm3: float) -> float:
    """Volume [mm³] -> [m³]."""
    return float(v_mm3) * 1e-9


def inertia_from_mm5(i_mm5):
    """Volume-weighted second moments [mm⁵] -> [m⁵] (multiply by density for kg·m²)."""
    return np.asarray(i_mm5, dtype=float) * 1e-15


def transform_to_mm(T_m: np.ndarray) -> np.ndarray:
    """4×4 homogeneous transform with its translation in m -> translation in mm."""
    T = np.array(T_m, dtype=float, copy=True)
    T[:3, 3] *= MM_PER_M
    return T

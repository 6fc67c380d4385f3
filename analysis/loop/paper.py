"""A seed experiment's reported quantity, computed the way the paper computes it.

Seed 002 reports each experiment as one number; the definitions (from its text, §3.4, §4.3–4.4):

* **Fig 14** (zero impedance): an external linear motor moves the end-effector sinusoidally along
  *one* axis and a force sensor between motor and end-effector measures the force; the number
  is the RMS of that force *along the driven axis* (F_x or F_y), not of the 3-D force.
  → :func:`axis_rms` of the hand force.
* **Fig 8** (force tracking, leg 1, 100 N at 3 Hz): the RMS of the tracking error of F_z (and of
  F_y, whose reference is zero), e(t) = F_d(t) − F(t) at one instant. → :func:`axis_error_rms` of
  (F − F_r) on one axis, the two taken at the same instant
  (:func:`hapticopt.analysis.loop.traces.tracking_pair`).
* **Fig 9 / 10** (force circle, 80 N at 1 Hz, x and y waves 90° apart): "the RMS of the error
  curve", the error being the difference between the reference and the actual end-effector force
  (Fig 10 plots its x and y components). We read it as the RMS of the error vector's magnitude in
  the plane, √(mean(e_x² + e_y²)), at one instant as for Fig 8. → :func:`plane_error_rms`.
* **Fig 15** (rendered stiffness): |K_rendered − K| / K in % (the fit is
  :func:`hapticopt.analysis.prrr.loop.closed_loop.metrics_from_traces`').

Every function is pure numpy on traces of shape (N, 3) over the settled window.
"""

from __future__ import annotations

import numpy as np


def axis_rms(force: np.ndarray, axis: int) -> float:
    """RMS of ``force[:, axis]`` [N] (Fig 14: the force along the driven axis)."""
    f = np.asarray(force, dtype=float)[:, axis]
    return float(np.sqrt(np.mean(f**2)))


def axis_error_rms(actual: np.ndarray, reference: np.ndarray, axis: int) -> float:
    """RMS of (actual − reference) along ``axis`` [N] (Fig 8)."""
    e = np.asarray(actual, dtype=float)[:, axis] - np.asarray(reference, dtype=float)[:, axis]
    return float(np.sqrt(np.mean(e**2)))


def plane_error_rms(actual: np.ndarray, reference: np.ndarray, axes: tuple[int, int]) -> float:
    """RMS of the magnitude of (actual − reference) in the plane of ``axes`` [N] (Fig 9)."""
    idx = list(axes)
    e = np.asarray(actual, dtype=float)[:, idx] - np.asarray(reference, dtype=float)[:, idx]
    return float(np.sqrt(np.mean(np.sum(e**2, axis=-1))))


def max_force_deviation_pct(force: np.ndarray, position: np.ndarray, stiffness: float, axis: int) -> float:
    """max |F_a − K p_a| / max |K p_a| × 100 [%]: a second reading of Fig 15's "maximum stiffness
    error" (the largest departure of the measured force–displacement curve from the commanded line,
    relative to the line's peak force) — friction hysteresis shows here, not in a least-squares slope."""
    f = np.asarray(force, dtype=float)[:, axis]
    line = stiffness * np.asarray(position, dtype=float)[:, axis]
    return float(np.max(np.abs(f - line)) / np.max(np.abs(line)) * 100.0)

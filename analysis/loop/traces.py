"""Closed-loop time histories and the run constants every plant shares.

Every closed loop (the 3-PRRR's fused lumped loop, its MuJoCo plant, the master's MuJoCo plant)
records :class:`Traces` per controller tick; the instability rules read them.

Time base of a record k (one convention for every plant): the plant's quantities (position, velocity,
hand and actuator force, energy) are those at the **end** of tick k, t = (k + 1)·T; the force reference
F_r is the one the firmware computed **in** tick k from the sensors it read at the tick's start, t = k·T.
A tracking error at one instant, seed 002's e(t) = F_d(t) − F(t), therefore pairs reference k with the
actuator force of record k − 1 (:func:`tracking_pair`); pairing record k with itself compares the force
one tick late (|1 − z·H(z)| instead of |1 − H(z)| for a loop F = H(z) F_d).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticopt.analysis.fidelity import Fidelity

#: controller ticks per nominal period with sampling off (continuous-time limit)
OVERSAMPLE = {Fidelity.DRAFT: 10, Fidelity.STANDARD: 20, Fidelity.FINE: 50}
#: sustained saturation (an instability): the motor force saturated for more than this fraction of
#: a window of this length [s]
SATURATION_WINDOW_S = 0.1
SATURATION_FRACTION = 0.5


@dataclass(frozen=True, kw_only=True)
class Traces:
    """Per-tick records, leading axes (ticks, batch)."""

    period: float
    energy: np.ndarray  # (N, B) [J]
    saturated: np.ndarray  # (N, B) bool
    stop_tick: np.ndarray  # (B,) int, −1 = ran to the end
    position: np.ndarray | None = None  # (N, B, 3) [m]
    hand_force: np.ndarray | None = None  # (N, B, 3) [N]
    actuator_force: np.ndarray | None = None  # (N, B, 3) [N]
    force_reference: np.ndarray | None = None  # (N, B, 3) [N]
    velocity: np.ndarray | None = None  # (N, B, 3) [m/s]


def tracking_pair(tr: Traces, sl: slice, b: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(F(kT), F_d(kT)) over the ticks k of ``sl`` for batch element ``b``, each (n, 3) [N]: the actuator force
    and its reference at the same instant (module docstring). F(0) is not recorded, so a window that starts at
    tick 0 starts at tick 1."""
    start = max(1, sl.start or 0)
    stop = tr.force_reference.shape[0] if sl.stop is None else sl.stop
    return tr.actuator_force[start - 1:stop - 1, b], tr.force_reference[start:stop, b]

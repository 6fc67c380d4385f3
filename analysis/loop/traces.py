"""Closed-loop time histories and the run constants every plant shares.

Every closed loop (the 3-PRRR's fused lumped loop, its MuJoCo plant, the master's MuJoCo plant)
records :class:`Traces` per controller tick; the instability rules read them.
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

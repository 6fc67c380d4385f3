"""Link interference of the 3-PRRR over its workspace, fast enough for the optimiser.

A separate evaluator (not a part of ``workspace``) so that it runs only where it is asked for: a
problem that constrains ``interference_overlap_fraction`` (or the removed fraction) pulls it in, a plain draft workspace
evaluation does not pay for it (issue 4's ≤ 20 ms draft budget).

Metric ``interference_removed_fraction``: the share of the sampled workspace volume whose poses
make two parts collide, from :mod:`hapticopt.analysis.prrr.interference_fast` (convex primitives of the CAD part
tables, separating axes; ~30 ms for the 216 poses of
:data:`hapticopt.analysis.prrr.workspace.INTERFERENCE_SAMPLING`). The same model at every fidelity: it never
misses a collision the manifold3d reference (:mod:`analysis.interference`) finds, so a bound on it
is conservative (docs/workspace_interference.md). At fine fidelity the ``workspace`` evaluator
also reports the manifold3d value, ``workspace_interference_removed_fraction``.

Metric ``interference_overlap_fraction``: its continuous companion from the same pass, each pose
weighted by clip(d / 1 mm, 0, 1), d its deepest part-pair overlap
(:data:`hapticopt.analysis.prrr.interference_fast.OVERLAP_SCALE`). The removed fraction is a sum of pose weights
that switch on and off, piecewise constant in the design, which stalls COBYLA; the companion moves
continuously with the overlap depths (docs/workspace_interference.md).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.errors import HapticoptError
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.analysis.prrr import interference_fast
from hapticopt.analysis.prrr.workspace import INTERFERENCE_SAMPLING


@dataclass(frozen=True, kw_only=True)
class PrrrInterference:
    """Share of the sampled workspace volume lost to link interference (fast model)."""

    removed_fraction: float  # [-] 0 … 1 (NaN when the check could not run)
    overlap_fraction: float  # [-] 0 … 1, continuous companion (NaN when the check could not run)
    wall_s: float
    status: Status = Status.OK
    message: str = ""

    def metrics(self) -> dict[str, float]:
        return {"interference_removed_fraction": self.removed_fraction,
                "interference_overlap_fraction": self.overlap_fraction}


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD) -> PrrrInterference:
    """Fast interference over the workspace samples (same model and samples at every fidelity)."""

    Fidelity(fidelity)
    t0 = time.perf_counter()
    try:
        removed, overlap = interference_fast.interference_fractions(design, **INTERFERENCE_SAMPLING)
    except HapticoptError as exc:  # the CAD cannot lay this design's parts out
        return failed(exc, t0)
    return PrrrInterference(removed_fraction=removed, overlap_fraction=overlap, wall_s=time.perf_counter() - t0)


def failed(exc: Exception, t0: float) -> PrrrInterference:
    """The result where the CAD cannot lay the parts out (status failed, NaN metrics)."""
    return PrrrInterference(removed_fraction=float("nan"), overlap_fraction=float("nan"), wall_s=time.perf_counter() - t0,
                            status=Status.FAILED, message=f"interference not checked: {exc}")

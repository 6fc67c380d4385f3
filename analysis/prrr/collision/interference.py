"""Link interference of the 3-PRRR over its workspace, fast enough for the optimiser.

A separate evaluator (not a part of ``workspace``) so that it runs only where it is asked for: a
problem that constrains ``interference_overlap_fraction`` (or the removed fraction) pulls it in, a plain draft workspace
evaluation does not pay for it (issue 4's ≤ 20 ms draft budget).

Metric ``interference_removed_fraction``: the share of the sampled workspace volume whose poses
make two parts collide, from :mod:`hapticopt.analysis.prrr.collision.interference_fast` (convex primitives of the CAD part
tables, separating axes) over the poses of
:data:`hapticopt.analysis.prrr.geometry.workspace.INTERFERENCE_SAMPLING`). The same model at every fidelity: it never
misses a collision the manifold3d reference (:mod:`analysis.interference`) finds, so a bound on it
is conservative (docs/workspace_interference.md). At fine fidelity the ``workspace`` evaluator
also reports the manifold3d value, ``workspace_interference_removed_fraction``.

Metric ``interference_overlap_fraction``: its continuous companion from the same pass, each pose
weighted by clip(d / 1 mm, 0, 1), d its deepest part-pair overlap
(:data:`hapticopt.analysis.prrr.collision.interference_fast.OVERLAP_SCALE`). The removed fraction is a sum of pose weights
that switch on and off, piecewise constant in the design, which stalls COBYLA; the companion moves
continuously with the overlap depths (docs/workspace_interference.md).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.errors import HapticoptError
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.prrr.collision import interference_fast
from hapticopt.analysis.prrr.geometry.workspace import INTERFERENCE_SAMPLING, workspace_params

#: most poses of the check: 3 thirds · n_phi · n_r · n_z (fewer where the workspace is thinner)
INTERFERENCE_POSES = 3 * INTERFERENCE_SAMPLING["n_phi"] * INTERFERENCE_SAMPLING["n_r"] * INTERFERENCE_SAMPLING["n_z"]


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


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD, shared: Any = None,
             compute: Compute = DEFAULT) -> PrrrInterference:  # one route for one design (the registry passes it to every entry alike)
    """Fast interference over the workspace samples (same model and samples at every fidelity).

    Status ``ok`` when no sampled pose makes two parts collide; ``collides`` (numbers kept: the
    optimiser constrains them) when some do; ``not-assemblable`` (NaN) when the chain does not
    close or the CAD cannot lay the parts out (:mod:`hapticopt.analysis.prrr.geometry.assembly`). ``shared``:
    the registry call's :class:`hapticopt.analysis.prrr.shared.DesignSteps` of ``design`` (the
    envelope and the primitive tables).
    """

    Fidelity(fidelity)
    t0 = time.perf_counter()
    nan = float("nan")
    blocked = assembly.check(design, with_parts=True)
    if blocked:
        return PrrrInterference(removed_fraction=nan, overlap_fraction=nan, wall_s=time.perf_counter() - t0,
                                status=Status.NOT_ASSEMBLABLE, message=blocked)
    try:
        if shared is None:
            removed, overlap = interference_fast.interference_fractions(design, **INTERFERENCE_SAMPLING)
        else:
            removed, overlap = interference_fast.interference_fractions(
                design, **INTERFERENCE_SAMPLING, wp=workspace_params(design, envelope=shared.envelope(design)),
                check=shared.point_checker(design))
    except HapticoptError as exc:  # the parts are laid out but a pose's parts cannot be placed
        return failed(exc, t0)
    return from_fractions(removed, overlap, t0)


def from_fractions(removed: float, overlap: float, t0: float) -> PrrrInterference:
    """The verdict on the sampled fractions (single and batched paths): ``collides`` when any sampled
    pose collides (a count of colliding poses, no rounding-level threshold), else ``ok``."""
    status, message = Status.OK, ""
    if removed > 0.0:
        status = Status.COLLIDES
        message = (f"parts collide over {100.0 * removed:.3g} % of the sampled workspace volume "
                   f"(fast model, up to {INTERFERENCE_POSES} sampled poses)")
    return PrrrInterference(removed_fraction=removed, overlap_fraction=overlap, wall_s=time.perf_counter() - t0,
                            status=status, message=message)


def failed(exc: Exception, t0: float) -> PrrrInterference:
    """The result where a pose's parts cannot be placed (status failed, NaN metrics)."""
    return PrrrInterference(removed_fraction=float("nan"), overlap_fraction=float("nan"), wall_s=time.perf_counter() - t0,
                            status=Status.FAILED, message=f"interference not checked: {exc}")

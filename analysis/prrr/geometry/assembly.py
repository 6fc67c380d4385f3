"""Whether a 3-PRRR design can be assembled: the precondition of every 3-PRRR status.

Two ways a described 3-PRRR cannot be put together:

* **The chain does not close** (every evaluator checks this, :func:`closure`): no end-effector
  position puts every leg within its reach annulus |d3 − d4| ≤ |ρ| ≤ d3 + d4 with its slider
  within the stroke. The legs then cannot all be pinned to one platform, in any pose: the
  statics, stiffness and stability numbers of such a design describe nothing that can be built
  (e.g. prrr-paper with d2 = 300 mm: |ρ| ≥ 300 mm > d3 + d4 = 171 mm everywhere). The test is
  the workspace's own closed forms (:func:`hapticopt.analysis.prrr.geometry.workspace.closure`)
  with the pure kinematic annulus (no fold margin: a design that closes only near its folded
  elbow is assemblable, its workspace is ``empty``) on :data:`CLOSURE_RAYS` rays per third of the
  circle (3-fold symmetry); a reachable region thinner than the ray spacing (2.5°) can be missed.
* **The parts cannot be laid out** (:func:`parts`): :func:`hapticopt.design.prrr.cad.layout`
  refuses the design (a wall thinner than the CAD's minimum feature, no face of the carriage block
  can carry the R1 clevis, …).

Either way the device does not exist, and no number describes it: the registry's one rule
(:data:`hapticopt.analysis.registry.ASSEMBLY` → :func:`check_built`) reports every evaluator of such
a design ``not-assemblable`` with every metric NaN — the kinematic ones (statics, stiffness,
workspace, stability) too, whose model could be evaluated but describes nothing that can be built.
An evaluator called directly keeps its own early check (:func:`closure`, or :func:`check` with the parts).

Each returns ``''`` when assemblable, else the message of the ``not-assemblable`` status.
"""

from __future__ import annotations

import functools

from hapticopt.analysis.prrr.geometry.workspace import CLOSURE_RAYS, closure, closure_many  # noqa: F401  (re-exported)
from hapticopt.design.errors import HapticoptError
from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.prrr import layout as prrr_layout
from hapticopt.design.prrr.params import PrrrDesign

#: cached: one evaluation asks it for each design several times (the registry, statics, stability,
#: structure and the part evaluators), over a chunk of up to 1024 designs in the batched draft evaluator
@functools.lru_cache(maxsize=4096)
def parts(design: PrrrDesign) -> str:
    """'' when the CAD lays the design's parts out, else why not (its one-line reason)."""
    try:
        cad_prrr.layout(design)
    except HapticoptError as exc:
        return f"the parts cannot be laid out: {exc}"
    return ""


def check(design: PrrrDesign, *, with_parts: bool = False) -> str:
    """'' when ``design`` can be assembled (the chain closes; and, with ``with_parts``, the CAD lays
    its parts out), else the message of the ``not-assemblable`` status."""
    return closure(design) or (parts(design) if with_parts else "")


def check_built(design: PrrrDesign) -> str:
    """'' when ``design`` can be built (its chain closes and the CAD lays its parts out), else why not:
    the registry's rule for the 3-PRRR (:data:`hapticopt.analysis.registry.ASSEMBLY`)."""
    return check(design, with_parts=True)


def check_built_many(designs: list[PrrrDesign], *, compute: Compute = DEFAULT) -> list[str]:
    """:func:`check_built` of many designs: the chain closure of the batch (:func:`closure_many`) and the
    layout's rules in one array pass (:func:`hapticopt.design.prrr.layout.layouts`); the message of a
    refused layout is :func:`parts`'s (the same rule, the first one failed)."""
    if not designs:
        return []
    closes = closure_many(designs, compute=compute)
    refused = prrr_layout.layouts(designs).failed >= 0
    return [why or (parts(d) if refused[k] else "") for k, (d, why) in enumerate(zip(designs, closes))]

"""``analysis/prrr/collision/interference.py``: the fast interference evaluator's status."""

from __future__ import annotations

import math

from hapticopt.analysis.prrr.collision import interference as I
from hapticopt.analysis.status import Status
from hapticopt.design import io


def test_collisions_over_part_of_the_workspace_are_collides():
    # issue 21: "interference: ok" for a design that loses most of its workspace. d2 = 40 mm pulls
    # the R1 joints towards the axis: about half the sampled volume collides (fast model)
    paper = io.load_preset("prrr-paper")
    assert I.evaluate(paper).status is Status.OK and I.evaluate(paper).removed_fraction == 0.0
    r = I.evaluate(io.apply_overrides(paper, ["geometry.d2_mm=40"]))
    assert r.status is Status.COLLIDES and 0.3 < r.removed_fraction < 1.0
    assert f"{100 * r.removed_fraction:.3g} % of the sampled workspace volume" in r.message
    assert math.isfinite(r.metrics()["interference_overlap_fraction"])  # numbers kept: problems constrain them

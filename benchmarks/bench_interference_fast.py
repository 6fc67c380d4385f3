"""Fast interference benchmark (docs/workspace_interference.md), 2-core CPU.

Target: the fine-fidelity workspace poses of prrr-paper (``workspace.INTERFERENCE_SAMPLING``: 216 poses when
this benchmark was written, 207 with today's reach-and-stroke sample) checked in ≤ 50 ms, part tables and
sampling included (manifold3d reference: ~4.8 s). prrr-paper is free of link interference over that sample
since the R1 bracket's root was let into the block (its report: ``interference_removed_fraction`` 0).
"""

from __future__ import annotations

from hapticopt.analysis.prrr import interference_fast as F
from hapticopt.analysis.prrr import workspace as W
from hapticopt.design import io

PRRR = io.load_preset("prrr-paper")


def test_removed_fraction_fine_sample(benchmark):
    removed, _ = benchmark(F.interference_fractions, PRRR, **W.INTERFERENCE_SAMPLING)
    assert removed == 0.0
    assert benchmark.stats.stats.median <= 0.050


def test_check_points_fine_sample(benchmark):
    pts, _ = W.workspace_sample_weights(PRRR, **W.INTERFERENCE_SAMPLING)
    model = F.prepare(PRRR)
    res = benchmark(F.check_points, model, pts, branch=W.ELBOW_BRANCH)
    assert len(pts) > 150 and len(res.collides) == len(pts)
    assert not res.collides.any()

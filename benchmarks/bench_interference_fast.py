"""Fast interference benchmark (docs/workspace_interference.md), 2-core CPU.

Target: the 216 fine-fidelity workspace poses of prrr-paper (prrr_workspace.INTERFERENCE_SAMPLING)
checked in ≤ 50 ms, part tables and sampling included (manifold3d reference: ~4.8 s).
"""

from __future__ import annotations

from hapticopt.analysis.prrr import interference_fast as F
from hapticopt.analysis.prrr import workspace as W
from hapticopt.design import io

PRRR = io.load_preset("prrr-paper")


def test_removed_fraction_216_poses(benchmark):
    frac = benchmark(F.removed_fraction, PRRR, **W.INTERFERENCE_SAMPLING)
    assert 0.0 < frac < 1.0
    assert benchmark.stats.stats.median <= 0.050


def test_check_points_216_poses(benchmark):
    pts, _ = W.workspace_sample_weights(PRRR, **W.INTERFERENCE_SAMPLING)
    model = F.prepare(PRRR)
    res = benchmark(F.check_points, model, pts, branch=W.ELBOW_BRANCH)
    assert len(res.collides) == 216

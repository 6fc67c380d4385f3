"""Collision-free workspace benchmarks (issue 15), 2-core CPU.

Target: the collision-free metrics at draft ≤ 20 ms per design, single (warm). The batched
target of ≤ 2 ms per design is measured by ``bench_batched_draft.py`` and
``ratio_interference_kernel.py`` (met with the compiled check: docs/workspace_interference.md).
"""

from __future__ import annotations

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import free_workspace
from hapticopt.design import io

PRRR = io.load_preset("prrr-paper")


def test_prrr_free_workspace_draft(benchmark):
    free_workspace.evaluate(PRRR, fidelity=Fidelity.DRAFT)  # warm-up (imports, first numpy calls)
    r = benchmark(free_workspace.evaluate, PRRR, fidelity=Fidelity.DRAFT)
    assert r.free_radius > 0


def test_prrr_free_workspace_standard(benchmark):
    r = benchmark(free_workspace.evaluate, PRRR, fidelity=Fidelity.STANDARD)
    assert r.free_radius > 0

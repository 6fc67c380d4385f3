"""Workspace benchmarks, 2-core CPU.

Targets: draft workspace + conditioning of one design ≤ 20 ms (3-PRRR and master, warm);
1000 designs batched ≤ 2 s (3-PRRR draft, after the one-off jit compile, which is reported
separately by ``test_prrr_batch_compile``); the fast interference check of the 216 workspace samples
(the ``interference`` evaluator) ≤ 50 ms.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from hapticopt.analysis.master import workspace as master_workspace
from hapticopt.analysis.prrr.geometry import workspace as prrr_workspace
from hapticopt.analysis.prrr.structure import statics as prrr_statics
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.registry import evaluate_all
from hapticopt.design import io

PRRR = io.load_preset("prrr-paper")
MASTER = io.load_preset("master-paper")


def _designs(n: int) -> list:
    rng = np.random.default_rng(0)
    g = PRRR.geometry
    return [dataclasses.replace(PRRR, geometry=dataclasses.replace(
        g, beta=math.radians(rng.uniform(20, 75)), d2=rng.uniform(0.06, 0.11), d3=rng.uniform(0.06, 0.10),
        d4=rng.uniform(0.06, 0.10), stroke=rng.uniform(0.1, 0.25))) for _ in range(n)]


def test_prrr_draft_workspace_and_conditioning(benchmark):
    prrr_statics.evaluate(PRRR)  # jit warm-up of the statics (conditioning) evaluator

    def run():
        return prrr_workspace.evaluate(PRRR, fidelity=Fidelity.DRAFT), prrr_statics.evaluate(PRRR)

    ws, st = benchmark(run)
    assert ws.cylinder_diameter > 0 and st.condition > 1


def test_master_draft_workspace_and_conditioning(benchmark):
    master_workspace.evaluate(MASTER, fidelity=Fidelity.DRAFT)  # jit warm-up
    r = benchmark(master_workspace.evaluate, MASTER, fidelity=Fidelity.DRAFT)
    assert 0 < r.global_conditioning_index <= 1


def test_prrr_batch_1000(benchmark):
    designs = _designs(1000)
    prrr_workspace.evaluate_batch(designs, fidelity=Fidelity.DRAFT)  # compile once
    out = benchmark.pedantic(prrr_workspace.evaluate_batch, args=(designs,), kwargs={"fidelity": Fidelity.DRAFT},
                             rounds=5, iterations=1)
    assert len(out) == 1000


def test_prrr_batch_arrays_1000(benchmark):
    """The optimiser's path: stacked parameters in, per-design arrays out (no Result objects)."""
    wp = prrr_workspace.stack([prrr_workspace.workspace_params(d) for d in _designs(1000)])
    prrr_workspace.batch_arrays(wp, fidelity=Fidelity.DRAFT)
    out = benchmark.pedantic(prrr_workspace.batch_arrays, args=(wp,), kwargs={"fidelity": Fidelity.DRAFT},
                             rounds=5, iterations=1)
    assert len(out) == 1000


def test_prrr_batch_compile(benchmark):
    """One-off jit compile + first call of a 1000-design draft batch (new batch shape)."""
    designs = _designs(999)

    def first():
        prrr_workspace._batched.cache_clear()
        t = time.perf_counter()
        prrr_workspace.evaluate_batch(designs, fidelity=Fidelity.DRAFT)
        return time.perf_counter() - t

    benchmark.pedantic(first, rounds=1, iterations=1)


def test_prrr_interference_samples(benchmark):
    evaluate_all(PRRR, fidelity=Fidelity.STANDARD, only=("interference",))
    ev = benchmark(evaluate_all, PRRR, fidelity=Fidelity.STANDARD, only=("interference",))
    assert ev.metrics()["interference_removed_fraction"] == 0.0

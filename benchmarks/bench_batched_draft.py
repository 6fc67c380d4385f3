"""Batched draft evaluation of the 3-PRRR: designs/s at batch 1, 64 and 1024 against the single
path (``registry.evaluate_all`` per design), side by side in one run.

Targets (the project's speed issue): ≥ 2,000 designs/s at batch 1024 (≥ 40× the single path's
51/s), one design ≤ 8 ms, no recompile for a new batch size (``analysis.prrr.draft_batch.TRACES``);
the collision-free workspace metrics ≤ 20 ms per design single, ≤ 2 ms per design batched.
Run with ``pytest benchmarks/bench_batched_draft.py --benchmark-enable``; against another revision
(interleaved fresh processes, medians): ``benchmarks/ab.py REV draft-batch --n 1024`` and ``… draft-one``.

The designs are seeded, ±10 % around prrr-paper (about a third of them cannot have their parts laid
out: ``not-assemblable`` for the part evaluators, which the batch still runs the kinematic ones for).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import draft_batch
from hapticopt.analysis.prrr.collision import free_workspace as FW
from hapticopt.analysis.registry import evaluate_all, evaluate_batch
from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign

BASE = io.load_preset("prrr-paper")


def designs(n: int, seed: int = 0) -> list:
    """``n`` valid designs around the preset (seeded)."""
    rng = np.random.default_rng(seed)
    g = BASE.geometry
    out = []
    while len(out) < n:
        kw = dict(beta=g.beta * rng.uniform(0.9, 1.1), r_p=g.r_p * rng.uniform(0.9, 1.1),
                  d3=g.d3 * rng.uniform(0.9, 1.1), d4=g.d4 * rng.uniform(0.9, 1.1),
                  stroke=g.stroke * rng.uniform(0.9, 1.1))
        try:
            out.append(dataclasses.replace(BASE, geometry=dataclasses.replace(g, **kw)))
        except InvalidDesign:
            continue
    return out


@pytest.mark.parametrize("n", [1, 64])
def test_batched_draft(benchmark, n):
    ds = designs(n)
    evaluate_batch(ds, fidelity=Fidelity.DRAFT)  # compile (or load from the persistent cache)
    traces = draft_batch.TRACES["core"]
    benchmark(evaluate_batch, ds, fidelity=Fidelity.DRAFT)
    assert draft_batch.TRACES["core"] == traces  # no recompile


def test_single_draft(benchmark):
    d = designs(1)[0]
    evaluate_all(d, fidelity=Fidelity.DRAFT)
    benchmark(evaluate_all, d, fidelity=Fidelity.DRAFT)



def test_free_workspace_draft(benchmark):
    """The collision-free workspace evaluator alone on one design, warm (target ≤ 20 ms)."""
    FW.evaluate(BASE, fidelity=Fidelity.DRAFT)
    assert benchmark(FW.evaluate, BASE, fidelity=Fidelity.DRAFT).free_radius > 0


def test_free_workspace_batched(benchmark):
    """The same in a batch of 64 (target ≤ 2 ms per design)."""
    ds = designs(64)
    evaluate_batch(ds, fidelity=Fidelity.DRAFT, only=("free_workspace",))
    benchmark(evaluate_batch, ds, fidelity=Fidelity.DRAFT, only=("free_workspace",))

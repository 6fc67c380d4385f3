"""Batched draft evaluation of the 3-PRRR (issue 22, item 3): designs/s at batch 1, 64 and 1024
against the single path (``registry.evaluate_all`` per design), side by side in one run.

Targets (issue 22): ≥ 2,000 designs/s at batch 1024 (≥ 40× the single path), one design ≤ 8 ms,
no recompile for a new batch size (``analysis.prrr.draft_batch.TRACES``). Run with
``pytest benchmarks/bench_batched_draft.py --benchmark-enable``; ``python
benchmarks/bench_batched_draft.py [sizes…]`` prints the ratios (medians of 5).
"""

from __future__ import annotations

import dataclasses
import statistics
import sys
import time

import numpy as np
import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import draft_batch
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


def _median(fn, reps: int = 5) -> float:
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main(sizes: list[int]) -> None:
    single = designs(8, seed=1)
    evaluate_all(single[0], fidelity=Fidelity.DRAFT)
    for n in sizes:
        ds = designs(n)
        evaluate_batch(ds, fidelity=Fidelity.DRAFT)  # compile once per bucket
        t_batch = _median(lambda: evaluate_batch(ds, fidelity=Fidelity.DRAFT))
        t_single = _median(lambda: [evaluate_all(d, fidelity=Fidelity.DRAFT) for d in single]) / len(single)
        print(f"batch {n:5d}: {n / t_batch:8.1f} designs/s batched, {1 / t_single:6.1f} designs/s single, "
              f"ratio {t_single * n / t_batch:5.2f}")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [1, 64])

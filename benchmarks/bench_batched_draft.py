"""Batched draft evaluation of the 3-PRRR: designs/s at batch 1, 64 and 1024 against the single
path (``registry.evaluate_all`` per design), side by side in one run.

Targets (the project's speed issue): ≥ 2,000 designs/s at batch 1024 (≥ 40× the single path's
51/s), one design ≤ 8 ms, no recompile for a new batch size (``analysis.prrr.draft_batch.TRACES``);
the collision-free workspace metrics ≤ 20 ms per design single, ≤ 2 ms per design batched.
Run with ``pytest benchmarks/bench_batched_draft.py --benchmark-enable``; ``python
benchmarks/bench_batched_draft.py [sizes…]`` prints, per batch size, in interleaved rounds (medians):

* the batch's designs/s (``registry.evaluate_batch``, every draft evaluator);
* the single path's designs/s on the first :data:`N_SINGLE` designs of the same batch;
* a floor measured in the same rounds: ``numpy.linalg.cond`` of each design's Jacobian in a
  Python loop (the cost of touching each design once; it scales the machine's load out of the
  ratios);
* ``free_workspace`` alone: ms per design single and batched.

The designs are seeded, ±10 % around prrr-paper (about a third of them cannot have their parts laid
out: ``not-assemblable`` for the part evaluators, which the batch still runs the kinematic ones for).
"""

from __future__ import annotations

import dataclasses
import os
import statistics
import sys
import time

import numpy as np
import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import draft_batch
from hapticopt.analysis.prrr import free_workspace as FW
from hapticopt.analysis.registry import evaluate_all, evaluate_batch
from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.prrr.kinematics import jacobian

BASE = io.load_preset("prrr-paper")
#: designs of each batch also timed one by one (the single path is ~20 ms a design)
N_SINGLE = 16


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


def _cond_floor(ds: list) -> None:
    for d in ds:
        np.linalg.cond(np.asarray(jacobian(d.geometry.beta, xp=np)))


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def measure(n: int, rounds: int = 3) -> dict[str, float]:
    """Medians over interleaved rounds: seconds per design of the batch, the single path, the cond
    floor, and free_workspace alone (single and batched), at batch size ``n``."""
    ds = designs(n)
    few = ds[:N_SINGLE]
    fw_only = ("free_workspace",)
    evaluate_batch(ds, fidelity=Fidelity.DRAFT)  # compile once per bucket (or load it)
    evaluate_batch(ds, fidelity=Fidelity.DRAFT, only=fw_only)
    traces = sum(draft_batch.TRACES.values())
    t: dict[str, list[float]] = {k: [] for k in ("batch", "single", "floor", "fw_batch", "fw_single")}
    for _ in range(rounds):
        t["batch"].append(_timed(lambda: evaluate_batch(ds, fidelity=Fidelity.DRAFT)) / n)
        t["single"].append(_timed(lambda: [evaluate_all(d, fidelity=Fidelity.DRAFT) for d in few]) / len(few))
        t["floor"].append(_timed(lambda: _cond_floor(ds)) / n)
        t["fw_batch"].append(_timed(lambda: evaluate_batch(ds, fidelity=Fidelity.DRAFT, only=fw_only)) / n)
        t["fw_single"].append(_timed(lambda: [FW.evaluate(d, fidelity=Fidelity.DRAFT) for d in few]) / len(few))
    out = {k: statistics.median(v) for k, v in t.items()}
    out["retraced"] = sum(draft_batch.TRACES.values()) - traces
    return out


def main(sizes: list[int]) -> None:
    print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    evaluate_all(BASE, fidelity=Fidelity.DRAFT)
    for n in sizes:
        m = measure(n)
        print(f"batch {n:5d}: {1 / m['batch']:8.1f} designs/s batched, {1 / m['single']:6.1f} single "
              f"(ratio {m['single'] / m['batch']:5.2f}), cond floor {1 / m['floor']:8.0f}/s "
              f"(batch/floor {m['batch'] / m['floor']:6.0f}); free_workspace {1e3 * m['fw_batch']:6.2f} ms/design "
              f"batched, {1e3 * m['fw_single']:6.2f} single; retraced {m['retraced']}", flush=True)
    print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [1, 64, 1024])

"""Structural stiffness speed: the evaluator on one design (target ≤ 5 ms) and in a batch of 256 through the
registry's batched draft path (target ≤ 1 ms per design).

Run with ``make bench``. FEA timings come from scripts/accuracy/accuracy_structure.py (minutes).
"""

import dataclasses

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.structure import stiffness as structure
from hapticopt.analysis.registry import evaluate_batch
from hapticopt.design import io

PAPER = io.load_preset("prrr-paper")
N_BATCH = 256


def test_structural_evaluate(benchmark):
    out = benchmark(lambda: structure.evaluate(PAPER, fidelity=Fidelity.DRAFT).metrics())
    assert len(out["structural_stiffness_N_per_mm"]) == 3


def test_structural_batched(benchmark):
    betas = np.deg2rad(np.random.default_rng(0).uniform(45.0, 70.0, N_BATCH))
    ds = [dataclasses.replace(PAPER, geometry=dataclasses.replace(PAPER.geometry, beta=b)) for b in betas]
    evaluate_batch(ds, fidelity=Fidelity.DRAFT, only=("structural_stiffness",))
    benchmark(evaluate_batch, ds, fidelity=Fidelity.DRAFT, only=("structural_stiffness",))
    benchmark.extra_info["designs_per_call"] = N_BATCH

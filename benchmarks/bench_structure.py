"""Frame-model speed (targets: ≤ 5 ms per design single, ≤ 1 ms per design batched).

Run with ``make bench``. FEA timings come from benchmarks/accuracy_structure.py (minutes).
"""

import dataclasses

import jax
import numpy as np
import pytest

from hapticopt.analysis.prrr import frame_params
from hapticopt.analysis.prrr import frame_model as fm
from hapticopt.design import io

N_BATCH = 256


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def test_frame_single(benchmark, paper):
    # numpy path (what `hapticopt evaluate` uses): no compilation
    fp = fm.frame_params_of(paper, xp=np)
    out = benchmark(fm.solve_frame, fp)
    assert np.all(np.isfinite(out["stiffness_load"]))


def test_frame_single_jax(benchmark, paper):
    fp = fm.frame_params_of(paper)
    fm.solve_frame_jax(fp)  # compile outside the timing
    out = benchmark(fm.solve_frame_jax, fp)
    assert np.all(np.isfinite(out["stiffness_load"]))


def test_structural_evaluate_cold_numpy(benchmark, paper):
    # the evaluator end to end on the numpy path (design -> metrics), as the CLI calls it
    from hapticopt.analysis.prrr import structure as ss

    out = benchmark(lambda: ss.evaluate(paper).metrics())
    assert len(out["structural_stiffness_N_per_mm"]) == 3


def test_frame_batched_per_design(benchmark, paper):
    rng = np.random.default_rng(0)
    betas = np.deg2rad(rng.uniform(45.0, 70.0, N_BATCH))
    designs = [dataclasses.replace(paper, geometry=dataclasses.replace(paper.geometry, beta=b)) for b in betas]
    fp = frame_params.stack_frame_params(designs)
    fm.solve_frame_batch(fp)
    out = benchmark(lambda: jax.block_until_ready(fm.solve_frame_batch(fp)))
    benchmark.extra_info["designs_per_call"] = N_BATCH
    assert out["stiffness_load"].shape == (N_BATCH, 3)

"""Benchmarks of the surgical-master evaluators (issue 5). Run with ``make bench``.

Targets: unbalance radius at standard fidelity ≤ 50 ms; transparency bandwidth at a pose ≤ 5 ms.
"""

from __future__ import annotations

import analysis  # noqa: F401
import pytest

from analysis import master_balance as mb
from analysis import master_dynamics as md
from analysis import master_transparency as mt
from analysis.fidelity import Fidelity
from design.io import load_preset


@pytest.fixture(scope="module")
def design():
    return load_preset("master-paper")


def test_bench_unbalance_radius_standard(benchmark, design):
    result = benchmark(lambda: mb.evaluate(design, fidelity=Fidelity.STANDARD))
    assert result.radius > 0


def test_bench_unbalance_radius_from_gravity_parameters(benchmark, design):
    gp = md.gravity_parameters(md.model_of(design))
    result = benchmark(lambda: mb.evaluate_parameters(design, gp))
    assert result.radius > 0


def test_bench_transparency_bandwidth_at_pose(benchmark, design):
    model = md.model_of(design)
    result = benchmark(lambda: mt.evaluate(design, model=model))
    assert min(result.bandwidth) > 0


def test_bench_transparency_evaluate_with_model_build(benchmark, design):
    result = benchmark(lambda: mt.evaluate(design))
    assert min(result.bandwidth) > 0

"""Benchmarks of the surgical-master evaluators (issue 5). Run with ``make bench``.

Targets: unbalance radius at standard fidelity ≤ 50 ms; transparency bandwidth at a pose ≤ 5 ms;
worst case over the workspace at standard fidelity ≤ 200 ms (issue 16).
"""

from __future__ import annotations

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import pytest

from hapticopt.analysis.master import balance as mb
from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master import transparency as mt
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.io import load_preset


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
    result = benchmark(lambda: mt.evaluate(design, model=model, fidelity=Fidelity.DRAFT))  # the pose only
    assert min(result.bandwidth) > 0


def test_bench_transparency_evaluate_with_model_build(benchmark, design):
    result = benchmark(lambda: mt.evaluate(design, fidelity=Fidelity.DRAFT))
    assert min(result.bandwidth) > 0


def test_bench_transparency_worst_case_standard(benchmark, design):
    """Issue 16: worst case over the workspace at standard fidelity ≤ 200 ms."""
    model = md.model_of(design)
    result = benchmark(lambda: mt.evaluate(design, model=model, fidelity=Fidelity.STANDARD))
    assert result.worst_bandwidth is not None and min(result.worst_bandwidth) > 0

"""CAD performance targets (issue 3): full export of prrr-paper ≤ 15 s, interference at one
pose ≤ 50 ms, analytic mass properties ≤ 1 ms per design. Run with `make bench`."""

from hapticopt.design import export as design_export
from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np
import pytest

from hapticopt.analysis import interference as itf
from hapticopt.design import io, mass_properties as mp
from hapticopt.design.export import export


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def test_export_prrr_paper(benchmark, paper, tmp_path):
    export(paper, tmp_path / "warm")  # imports (build123d, jax) are not part of the target
    benchmark.pedantic(export, args=(paper, tmp_path / "out"), rounds=3, iterations=1)


def test_interference_one_pose(benchmark, paper):
    model = itf.prepare(paper)
    p = np.array([0.01, -0.02, 0.015])
    itf.check_pose(model, p)
    res = benchmark(itf.check_pose, model, p)
    assert res.ok


def test_interference_prepare(benchmark, paper):
    benchmark(itf.prepare, paper)


def test_analytic_mass_properties(benchmark, paper):
    # a different design every call (β sweep), as inside an optimiser: nothing can be cached
    designs = [io.apply_overrides(paper, [f"geometry.beta_deg={b:.3f}"]) for b in np.linspace(30, 60, 64)]
    state = {"k": 0}

    def one():
        state["k"] = (state["k"] + 1) % len(designs)
        return design_export.mass_properties(designs[state["k"]])

    one()
    res = benchmark(one)
    assert res.total_mass > 0


def test_cad_mass_properties(benchmark, paper):
    design_export.mass_properties(paper, method=mp.Method.CAD)
    benchmark.pedantic(design_export.mass_properties, args=(paper,), kwargs={"method": mp.Method.CAD}, rounds=3, iterations=1)

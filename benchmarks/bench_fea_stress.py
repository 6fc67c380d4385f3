"""Stress step of the solid FEA (hapticopt.analysis.fem.stress): von Mises per element from a P2 field.

Mesh: the 200 × 20 × 10 mm cantilever at 2.5 mm (1.3·10⁴ tetrahedra, about the size of the CAD
solid at level 2: 1.4·10⁴). The cost does not depend on the field's values, so a seeded random
P2 field stands in for a solve. Run with `make bench`; figures in docs/structure_stress.md.
"""

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np
import pytest

from hapticopt.analysis.fem import solid as fea, stress as fea_stress


@pytest.fixture(scope="module")
def field():
    from skfem import MeshTet

    mesh = fea.cantilever_mesh(length=0.2, width=0.02, thickness=0.01, size=0.0025)
    n_edges = MeshTet(mesh.points, mesh.tets).edges.shape[1]
    rng = np.random.default_rng(3)
    return mesh, rng.normal(size=mesh.points.shape) * 1e-6, rng.normal(size=(3, n_edges)) * 1e-6


def test_element_stress_p2(benchmark, field):
    mesh, uv, ue = field
    st = benchmark(fea_stress.element_stress, mesh.points, mesh.tets, uv, ue, youngs_modulus=68.9e9,
                   poisson_ratio=0.33)
    assert st.von_mises.shape == (mesh.tets.shape[1],)

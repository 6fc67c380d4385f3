"""Device size and mass of the 3-PRRR: the array form (many designs of one part layout at once)
equals the per-design path.

Reference: :func:`hapticopt.analysis.prrr.geometry.device_size.from_specs` on
:func:`hapticopt.design.prrr.cad.part_specs`, design by design (its mass model is tested against
OpenCASCADE's integrals in tests/design/test_mass_properties.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hapticopt.analysis.prrr.geometry import device_size as DS
from hapticopt.design import io
from hapticopt.design.prrr import cad, layout

#: agreement of the array form: the same closed forms, summed in another order (a few ulp)
REL = 1e-12


def test_from_tables_equals_from_specs(problem_sample):
    designs = problem_sample(40, seed=32) + [io.load_preset("prrr-paper")]
    designs.append(dataclasses.replace(designs[-1], geometry=dataclasses.replace(designs[-1].geometry, r4=0.030)))
    groups, _ = layout.part_tables_many(designs)
    assert len(groups) == 2  # with and without the riser of link2
    checked = 0
    for t in groups:
        for i, got in zip(t.index, DS.from_tables(t, 0.0)):
            want = DS.from_specs(designs[i], cad.part_specs(designs[i]), 0.0)
            assert got.status is want.status and got.message == want.message
            np.testing.assert_allclose(list(got.metrics().values()), list(want.metrics().values()), rtol=REL, atol=0)
            assert list(got.metrics()) == list(want.metrics())
            checked += 1
    assert checked >= 10

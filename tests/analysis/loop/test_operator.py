"""analysis/loop/operator.py: the one hand type (seed 000 eq 1), its validation and the absent hand."""

from __future__ import annotations

import math

import pytest

from hapticopt.analysis.loop.operator import NO_HAND, Operator, hand


def test_defaults_and_absent_terms():
    assert Operator() == Operator(mass=0.3, damping=50.0, stiffness=20e3)  # the scenes' firm grip
    assert NO_HAND == Operator(mass=0.0, damping=0.0, stiffness=0.0)
    assert hand(stiffness=5.0) == Operator(mass=0.0, damping=0.0, stiffness=5.0)


@pytest.mark.parametrize("field, value, unit", [("mass", -1.0, "kg"), ("damping", math.nan, "N·s/m"),
                                                ("stiffness", math.inf, "N/m"), ("stiffness", True, "N/m")])
def test_invalid_terms_are_one_line(field, value, unit):
    with pytest.raises(ValueError, match=rf"^Operator\.{field} = {value!r}: allowed finite values ≥ 0 \[{unit}\]$"):
        hand(**{field: value})

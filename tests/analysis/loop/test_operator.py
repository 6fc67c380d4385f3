"""hapticopt.analysis.loop.operator: the one operator type — seed 000's hand (eq 1), its absent
hand, and seed 001's eq-2 force operator — with its validation paths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticopt.analysis.loop.operator import NO_HAND, Operator, OperatorKind, force_step, hand, state_space
from hapticopt.design.errors import InvalidInput

# seed 001 eq 29: A, B of eq 4 for the §4.1 gains K_r = 0.5 s, K_f = 5, K_c = 20 N/m
A29 = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 0.0], [40.0, 0.0, -10.0]])
B29 = np.array([[0.0], [1.0], [0.0]])


def force_rate(op: Operator, e_p: float, f: float) -> float:
    """ḟ [N/s] of seed 001 eq 2, K_r ḟ = K_c e_p − K_f f: the ODE :func:`force_step` solves exactly."""
    return (op.force_gain * e_p - op.force_decay * f) / op.force_time_constant


def test_eq2_state_space_is_eq29():
    """Seed 001 eq 4 with the §4.1 gains gives eq 29's A, B; ḟ of eq 2 is A's last row."""
    op = Operator.eq2()
    assert op.kind == OperatorKind.FORCE_EQ2
    a, b = state_space(op)
    np.testing.assert_array_equal(a, A29)
    np.testing.assert_array_equal(b, B29)
    assert force_rate(op, 0.1, 0.3) == pytest.approx(a[2] @ [0.1, 0.0, 0.3])


def test_force_step_is_the_exact_solution_of_eq2():
    """K_r ḟ + K_f f = K_c e_p with e_p held: f(0) = f0, f(∞) = K_c e_p / K_f, and the step
    satisfies the ODE (central difference in h against ḟ of eq 2)."""
    op = Operator.eq2(k_r=0.3, k_f=2.0, k_c=50.0)
    f0, e = 0.7, -0.02
    assert force_step(op, f0, e, 0.0) == f0
    assert force_step(op, f0, e, 100.0) == pytest.approx(op.force_gain * e / op.force_decay, rel=1e-12)
    h, d = 0.05, 1e-6
    slope = (force_step(op, f0, e, h + d) - force_step(op, f0, e, h - d)) / (2 * d)
    assert slope == pytest.approx(force_rate(op, e, force_step(op, f0, e, h)), rel=1e-7)
    # two half steps = one step (a semigroup: the step is exact, not an integrator)
    assert force_step(op, force_step(op, f0, e, h / 2), e, h / 2) == pytest.approx(force_step(op, f0, e, h), rel=1e-14)


def test_default_is_the_seed000_hand():
    op = Operator()
    assert op.kind == OperatorKind.MASS_SPRING_DAMPER and (op.mass, op.damping, op.stiffness) == (0.3, 50.0, 20e3)
    with pytest.raises(InvalidInput, match='needs kind = "force_eq2"'):
        state_space(op)
    with pytest.raises(InvalidInput, match='needs kind = "force_eq2"'):
        force_step(op, 0.0, 0.0, 1e-3)


@pytest.mark.parametrize("kwargs,match", [
    ({"k_r": -1.0}, r"force_time_constant = -1.0: allowed finite values > 0 \[s\]"),
    ({"k_f": 0.0}, r"force_decay = 0.0: allowed finite values > 0 \[-\]"),
    ({"k_c": math.inf}, r"force_gain = inf: allowed finite values > 0 \[N/m\]"),
])
def test_eq2_validation(kwargs, match):
    with pytest.raises(InvalidInput, match=match):
        Operator.eq2(**kwargs)


def test_hand_validation():
    with pytest.raises(InvalidInput, match=r"Operator.mass = -0.1: allowed finite values ≥ 0 \[kg\]"):
        Operator(mass=-0.1)
    with pytest.raises(InvalidInput, match="Operator.kind = 'hand' is not known: allowed mass_spring_damper, force_eq2"):
        Operator(kind="hand")


def test_defaults_and_absent_terms():
    assert Operator() == Operator(mass=0.3, damping=50.0, stiffness=20e3)  # the scenes' firm grip
    assert NO_HAND == Operator(mass=0.0, damping=0.0, stiffness=0.0)
    assert hand(stiffness=5.0) == Operator(mass=0.0, damping=0.0, stiffness=5.0)


@pytest.mark.parametrize("field, value, unit", [("mass", -1.0, "kg"), ("damping", math.nan, "N·s/m"),
                                                ("stiffness", math.inf, "N/m"), ("stiffness", True, "N/m")])
def test_invalid_terms_are_one_line(field, value, unit):
    with pytest.raises(ValueError, match=rf"^Operator\.{field} = {value!r}: allowed finite values ≥ 0 \[{unit}\]$"):
        hand(**{field: value})

"""Local sensitivities (optim/sensitivity.py): jax against central differences on the statics closed
forms, a closed-form derivative of seed 002's force limit, the step plateau, the key and metric lists."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design import io
from hapticopt.design.errors import InvalidInput
from hapticopt.optim import sensitivity as sens

#: the statics evaluator only, at standard fidelity (one design at a time, numpy: no jit compile)
FAST = dict(fidelity=Fidelity.STANDARD, only=("statics",))
KEYS = ["geometry.beta_deg", "actuator.spring_N_per_mm", "actuator.force_limit_N", "end_effector.mass_kg",
        "geometry.d3_mm"]


@pytest.fixture(scope="module")
def design():
    return io.load_preset("prrr-paper")


@pytest.fixture(scope="module")
def jax_rows(design):
    return sens.sensitivities(design, keys=KEYS, **FAST)


@pytest.fixture(scope="module")
def fd_rows(design):
    return sens.sensitivities(design, keys=KEYS, use_jax=False, **FAST)


def test_continuous_keys_come_from_the_parameter_metadata(design):
    keys = {k.key: k for k in sens.continuous_keys(design)}
    assert keys["geometry.beta_deg"].value == 60.0 and keys["geometry.beta_deg"].unit == "deg"
    assert keys["actuator.spring_N_per_mm"].value == pytest.approx(56.27)
    assert len(keys) == sum(len(sens.specs(type(getattr(design, s)))) for s in design.SECTIONS)


def test_scalar_metrics_flatten_lists_and_skip_the_rest():
    out = sens.scalar_metrics({"a_N": [1.0, 2.0], "m_kg": [[1.0, 2.0], [3.0, 4.0]], "ok": True, "s": "x", "v": 3})
    assert out == {"a_N[0]": 1.0, "a_N[1]": 2.0, "m_kg[0][0]": 1.0, "m_kg[0][1]": 2.0, "m_kg[1][0]": 3.0,
                   "m_kg[1][1]": 4.0, "v": 3.0}


def test_jax_and_finite_differences_agree_on_the_statics(jax_rows, fd_rows):
    """Every statics scalar × every key: |jax − FD| ≤ 1e-5 relative (zeros: both exactly 0)."""
    fd = {(r.metric, r.key): r for r in fd_rows}
    checked = 0
    for r in jax_rows:
        assert r.method == "jax"
        other = fd[(r.metric, r.key)]
        assert other.method == "fd"
        if r.status == "zero":
            assert other.derivative == 0.0 or abs(other.derivative) <= 1e-9 * max(1.0, abs(r.value))
            continue
        assert other.status == "ok", other
        assert other.derivative == pytest.approx(r.derivative, rel=1e-5)
        checked += 1
    assert checked >= 25  # β, k, F_max and M move every statics metric they enter


def test_max_force_derivative_against_seed_002_closed_form(jax_rows, design):
    """Seed 002 (digest, Table 5 formulas): F_x max = 2 F_max / tan β, F_y max = √3 F_max / tan β, so
    ∂F_x/∂β = −2 F_max / sin²β and ∂F_y/∂β = −√3 F_max / sin²β [N/rad], × π/180 per degree;
    ∂F_x/∂F_max = 2 / tan β. At β = 60°, F_max = 3581/3 N: −55.556 N/deg."""
    beta, fmax = design.geometry.beta, design.actuator.force_limit
    row = {(r.metric, r.key): r.derivative for r in jax_rows}
    dx = -2.0 * fmax / math.sin(beta) ** 2 * math.pi / 180.0
    dy = -math.sqrt(3.0) * fmax / math.sin(beta) ** 2 * math.pi / 180.0
    assert row[("max_force_N[0]", "geometry.beta_deg")] == pytest.approx(dx, rel=1e-8)
    assert row[("max_force_N[1]", "geometry.beta_deg")] == pytest.approx(dy, rel=1e-8)
    assert row[("max_force_N[0]", "actuator.force_limit_N")] == pytest.approx(2.0 / math.tan(beta), rel=1e-8)
    assert row[("max_force_N[2]", "geometry.beta_deg")] == 0.0  # F_z max = 3 F_max


def test_elasticity_and_ranking(jax_rows):
    """Elasticity of k_x = 3k/(2 tan²β) to k is exactly 1 (seed 002 eq 15); rows sorted by |elasticity|."""
    row = next(r for r in jax_rows if r.metric == "stiffness_limit_N_per_mm[0]" and r.key == "actuator.spring_N_per_mm")
    assert row.elasticity == pytest.approx(1.0, rel=1e-12)
    el = [abs(r.elasticity) for r in jax_rows if r.elasticity is not None]
    assert el == sorted(el, reverse=True)


def test_plateau_picks_the_steps_that_agree():
    """Estimates over decreasing steps: biased (large h), plateau, noisy (small h)."""
    k, unc = sens.plateau(np.array([1.1, 1.0001, 1.0, 0.7]))
    assert k == 2 and unc == pytest.approx(1e-4 / 1.1)
    assert sens.plateau(np.array([0.0, 0.0]))[1] != sens.plateau(np.array([0.0, 0.0]))[1]  # nan: no scale


def test_unknown_names_are_one_line_errors(design):
    with pytest.raises(InvalidInput, match="not a continuous key"):
        sens.sensitivities(design, keys=["geometry.nope_mm"], **FAST)
    with pytest.raises(InvalidInput, match="no numeric metric"):
        sens.sensitivities(design, metrics=["nope_N"], keys=KEYS[:1], **FAST)

"""hapticopt.analysis.prrr.loop.ioic: the 3-PRRR with seed 001's IOIC as the outer loop of its impedance
controller (SEA force loops inside) on the lumped plant with the eq-2 operator (scene prrr-ioic)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hapticopt.analysis import verify
from hapticopt.analysis.control import impedance_learning as il
from hapticopt.analysis.loop.scene import Effect, IoicStrategy, load_scene
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidInput
from hapticopt.design.io import load_preset

DESIGN = load_preset("prrr-paper")
SCENE = load_scene("prrr-ioic")
SHORT = dataclasses.replace(SCENE, duration=4.0)
K30 = np.array([38.2969, 13.2889, 0.7335])  # seed 001 eq 30


@pytest.fixture(scope="module")
def runs():
    return {s: verify.simulate(DESIGN, dataclasses.replace(SHORT, ioic=dataclasses.replace(SHORT.ioic, strategy=s)))
            for s in IoicStrategy}


def test_learned_impedance_is_not_met_with_the_three_errors(runs):
    """The optimum of eq 6 is eq 30's K*. On the 3-PRRR the learned impedance is 27 % light, 21 % less
    damped and 24 % softer than M*, B*, K* (regression values, scripts/accuracy/accuracy_seed001_devices.py;
    docs/seed001.md: the sliders' 3 N Coulomb friction against the operator's ≈ 0.05 N and the SEA loop's
    0.5 mm tracking error against the exploration's 15 µm), although the gain norm is only 5.8 % off:
    the status is not-met (tolerance 10 % on each of M, B, K) and the message names the three errors;
    the numbers are kept (not-met holds its metrics)."""
    r = runs[IoicStrategy.IOIC]
    m = r.metrics()
    np.testing.assert_allclose(m["optimal_gain_SI"], K30, atol=5e-5)
    assert m["learning_status"] == "ok" and m["learning_iterations"] <= 10
    assert m["impedance_tolerance"] == 0.10
    errs = [m[f"impedance_{k}_rel_error"] for k in ("mass", "damping", "stiffness")]
    np.testing.assert_allclose(errs, [-0.2744, -0.2092, -0.2364], atol=5e-3)
    assert r.status == Status.NOT_MET
    assert "M -27.4 %" in r.message and "B -20.9 %" in r.message and "K -23.6 %" in r.message, r.message
    assert m["impedance_mass_kg"] == pytest.approx(m["optimal_impedance_mass_kg"] * (1 + errs[0]), rel=1e-12)


def test_ioic_within_5_percent_of_oic_and_fic_worse(runs):
    """Seed 001 Figs 4–6 on the 3-PRRR: after learning IOIC's RMS impedance error and force are within
    5 % of OIC's; FIC's are ≥ 10 % larger."""
    m = {s: r.metrics() for s, r in runs.items()}
    for key in ("impedance_error_rms_after_learning_mm", "interaction_force_rms_after_learning_N"):
        oic = m[IoicStrategy.OIC][key]
        assert abs(m[IoicStrategy.IOIC][key] - oic) <= 0.05 * oic
        assert m[IoicStrategy.FIC][key] >= 1.10 * oic


def test_inner_loop_metrics(runs):
    m = runs[IoicStrategy.IOIC].metrics()
    assert m["backend"] == "lumped" and m["firmware_mode"] == "ioic"
    assert m["tracking_error_rms_mm"] <= 1.0 and m["off_axis_drift_peak_mm"] <= 1.0
    assert m["motor_command_peak_N"] < DESIGN.actuator.force_limit / DESIGN.actuator.efficiency


def test_no_exploration_is_a_status_not_a_number():
    sc = dataclasses.replace(SCENE, duration=1.2, ioic=dataclasses.replace(SCENE.ioic, exploration=False))
    r = verify.simulate(DESIGN, sc)
    m = r.metrics()
    assert r.status == Status.SINGULAR and "not_exciting" in r.message
    assert m["data_matrix_rcond"] < il.RCOND_MIN * 0.1
    assert m["gain_SI"] is None and m["interaction_force_rms_N"] is None and m["tracking_error_rms_mm"] is None


def test_refusals():
    with pytest.raises(InvalidInput, match=r"the 3-PRRR's IOIC mode runs on the lumped plant"):
        verify.simulate(DESIGN, SCENE, backend=verify.Backend.MULTIBODY)
    with pytest.raises(InvalidInput, match=r"controller.interpolation = 2"):
        verify.simulate(DESIGN, dataclasses.replace(SCENE, controller=dataclasses.replace(SCENE.controller,
                                                                                         interpolation=2)))
    assert Effect.COULOMB_FRICTION in SCENE.effects

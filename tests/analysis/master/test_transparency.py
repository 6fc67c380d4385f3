"""Tests of hapticopt.analysis.master.transparency (seed 003 eq 13–15) and the MuJoCo sweep of hapticopt.analysis.master.sweep."""

from __future__ import annotations

import dataclasses

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np
import pytest

from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master import transparency as mt
from hapticopt.analysis.master import tradeoff as master_tradeoff
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.io import load_preset


@pytest.fixture(scope="module")
def design():
    return load_preset("master-paper")


def _point_mass(design, m):
    links = dataclasses.replace(design.links, upper_arm_mass=0, forearm_mass=0, driver_link_mass=0, coupler_mass=0,
                                handle_mass=m, turret_inertia=0)
    d = dataclasses.replace(design, links=links,
                            counterweights=dataclasses.replace(design.counterweights, upper_mass=0, forearm_mass=0),
                            actuators=dataclasses.replace(design.actuators, rotor_inertia=0, viscous=0, coulomb=0))
    bodies = tuple(dataclasses.replace(b, inertia=((0, 0, 0), (0, 0, 0), (0, 0, 0)))
                   for b in md.analytic_mass_properties(d))
    return d, md.model_of(d, bodies, gravity=0.0)


@pytest.mark.parametrize("m, K", [(0.5, 50.0), (0.1, 200.0)])
def test_point_mass_closed_form_bandwidth(design, m, K):
    """A point mass m held by the hand along x(t) = X sin ωt while the device renders F_D = −K x
    with no compensation: the device pushes on the hand with F_H = F_D − m ẍ = −K x + m ω² x, so
    G_T = F_H/F_D = 1 − m ω²/K (real; 1 at DC). |G_T| first leaves 0 ± 3 dB at its −3 dB crossing,
    1 − m ω²/K = 1/√2, i.e. ω = √((1 − 1/√2) K/m) and f_bw = √((1 − 1/√2)·K/m)/(2π)
    (the +3 dB crossing, mω²/K = 1 + √2, comes later). Continuous rendering (hold period 0)."""
    d, model = _point_mass(design, m)
    setup = mt.RenderingSetup(spring=K, hold_period=0.0, compensation=mt.OPEN_LOOP)
    r = mt.evaluate(d, setup=setup, model=model)
    expected = np.sqrt((1 - 1 / np.sqrt(2)) * K / m) / (2 * np.pi)
    np.testing.assert_allclose(r.apparent_mass, (m, m), rtol=1e-10)
    np.testing.assert_allclose(r.bandwidth, (expected, expected), rtol=0.01)
    np.testing.assert_allclose(r.bandwidth, (expected, expected), rtol=1e-6)  # the solver is in fact exact


def test_zero_order_hold_barely_changes_the_bandwidth_at_1kHz(design):
    d, model = _point_mass(design, 0.5)
    cont = mt.evaluate(d, setup=mt.RenderingSetup(hold_period=0.0, compensation=mt.OPEN_LOOP), model=model).bandwidth
    held = mt.evaluate(d, setup=mt.RenderingSetup(hold_period=mt.HOLD_PERIOD_S, compensation=mt.OPEN_LOOP),
                       model=model).bandwidth
    np.testing.assert_allclose(held, cont, rtol=1e-3)
    assert not np.allclose(held, cont, rtol=1e-12)


def test_inertia_compensation_raises_bandwidth(design):
    base = mt.evaluate(design, setup=mt.RenderingSetup(compensation=mt.OPEN_LOOP, hold_period=mt.HOLD_PERIOD_S))
    comp = mt.evaluate(design, setup=mt.RenderingSetup(compensation=mt.Compensation(inertia=mt.DynamicsCompensation.FULL, friction=True), hold_period=mt.HOLD_PERIOD_S))
    # the compensation goes through the same 1 kHz hold, so a residual λ(1 − H) ≈ λ·jωT/2 remains
    assert comp.bandwidth[0] > 5 * base.bandwidth[0] and comp.bandwidth[1] > 5 * base.bandwidth[1]


def test_gravity_compensation_removes_gravity_stiffness(design):
    d = dataclasses.replace(design, counterweights=dataclasses.replace(design.counterweights, upper_mass=0.1))
    r = mt.evaluate(d)
    assert abs(r.gravity_stiffness[0]) + abs(r.gravity_stiffness[1]) > 0.1
    G = mt.transfer(r.coefficients, np.array([1e-3]), mt.RenderingSetup(hold_period=0.0,
                    compensation=mt.Compensation(gravity=True)))
    np.testing.assert_allclose(np.abs(G), 1.0, atol=1e-6)


def test_seed003_trend_lighter_counterweight(design):
    # seed 003: lighter counterweights → more unbalance force and a higher transparency bandwidth
    rows = master_tradeoff.counterweight_sweep(design, (1.0, 0.9, 0.6, 0.3, 0.0), fidelity=Fidelity.DRAFT)
    force = [r["max_unbalance_force_N"] for r in rows]
    bx = [r["transparency_bandwidth_x_Hz"] for r in rows]
    bz = [r["transparency_bandwidth_z_Hz"] for r in rows]
    assert force[0] < 1e-9
    assert np.all(np.diff(force) > 0) and np.all(np.diff(bx) > 0) and np.all(np.diff(bz) > 0)


@pytest.mark.hardcase
@pytest.mark.parametrize("offset, status", [(0.0, Status.SINGULAR), (1e-8, Status.ILL_CONDITIONED)])
def test_singular_pose_reports_a_status_and_nan(design, offset, status):
    """θ2 − θ3 = 90° (cos = 6e-17 in float, rcond 3e-17: issue 14 saw a LinAlgError) and 1e-8 rad off
    it (rcond 5e-9: 2.3 decades below RCOND_ILL, 3.7 above RCOND_SINGULAR): a named status, NaN
    metrics, no exception (house style 9)."""
    pose = np.array([0.0, 0.5 * np.pi + offset, 0.0])
    r = mt.evaluate(design, pose=pose)
    assert r.status is status and "reciprocal condition number" in r.message
    assert all(np.isnan(np.asarray(v)).all() for v in r.metrics().values())


def test_worst_case_over_workspace_is_at_most_the_pose_value(design):
    r = mt.evaluate(design, fidelity=Fidelity.FINE)
    assert r.worst_bandwidth is not None
    assert r.worst_bandwidth[0] <= r.bandwidth[0] and r.worst_bandwidth[1] <= r.bandwidth[1]
    assert min(r.worst_bandwidth) > 0


@pytest.mark.slow
def test_mujoco_sine_sweep_agrees_with_frequency_domain(design):
    # acceptance: time domain (MuJoCo, 1 kHz hold) within 5 % of the frequency-domain bandwidth
    from hapticopt.analysis.master import sweep as master_sweep

    r = master_sweep.sweep(design, "z", factors=(0.9, 1.1))
    assert r.relative_error < 0.05
    assert r.closure_error < 1e-4


def test_full_compensation_of_exact_state_is_perfectly_transparent(design):
    """Closed form: with every body compensated from the exact state (T = 0, no filter) and no gravity
    stiffness or friction, G_T = [K − ω²(λ − λ̂)]/K = 1 at every frequency."""
    d, model = _point_mass(design, 0.5)
    r = mt.evaluate(d, model=model, setup=mt.RenderingSetup(compensation=mt.Compensation(
        inertia=mt.DynamicsCompensation.FULL)))
    G = mt.transfer(r.coefficients, np.array([0.1, 1.0, 10.0, 100.0]), r.setup)
    np.testing.assert_allclose(G, 1.0, atol=1e-12)


def test_estimator_is_one_at_low_frequency_and_lags_by_about_a_period():
    """Two plain backward differences D = (1 − z⁻¹)/T: D²/(jω)² = e^{−jωT}·sinc²(ωT/2), i.e. a delay of
    one period T and unit gain at low frequency (closed form)."""
    T, w = 1e-3, np.array([1.0, 10.0, 100.0])
    E = mt.estimator(w, T, 0.0)
    np.testing.assert_allclose(E, np.exp(-1j * w * T) * np.sinc(w * T / 2 / np.pi) ** 2, rtol=1e-12)
    np.testing.assert_allclose(mt.estimator(w, 0.0, 0.0), 1.0)

"""Tests of hapticopt.analysis.master.balance (seed 003 unbalance force and unbalance radius)."""

from __future__ import annotations

import dataclasses

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np
import pytest

from hapticopt.analysis.master import balance as mb
from hapticopt.analysis.master import dynamics as md
from hapticopt.design.master import kinematics as mk
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.io import load_preset


@pytest.fixture(scope="module")
def design():
    return load_preset("master-paper")


def _with_com(design, P):
    mu, mf = md.counterweights_for_com_offset(design, tuple(P))
    cw = dataclasses.replace(design.counterweights, upper_mass=mu, forearm_mass=mf)
    return dataclasses.replace(design, counterweights=cw)


def test_sup_K1_is_sqrt3_over_the_paper_workspace(design):
    # seed 003 eq 5–6: with G2 = 0 the radial unbalance force is F_ρ = −(G1/L5)·K1,
    # K1 = sin θ3 cos θ2 / cos(θ2 − θ3); over −90° < θ3 < 40°, 35° < 90° − θ2 + θ3 < 150°
    # the paper (and the seed digest) give sup|K1| = √3.
    L5, L4 = design.geometry.upper_arm, design.geometry.forearm
    Mg = 1.0
    P = np.array([L5, 0.0])  # G1 = Mg·P_x = L5 → G1/L5 = 1

    def frho(T, Ph):
        return np.abs((mb.unbalance_maps(L5, L4, Mg, T, Ph) @ P)[..., 0])

    ws = mb.workspace_of(design)
    value, t3, ph = mb._maximise(frho, ws, 41, 6)
    np.testing.assert_allclose(value, np.sqrt(3.0), rtol=1e-9)
    t2 = 0.5 * np.pi + t3 - ph
    np.testing.assert_allclose(value, abs(np.sin(t3) * np.cos(t2) / np.cos(t2 - t3)), rtol=1e-12)


def test_closed_form_map_matches_general_J_inv_T_G():
    # the fast linear map A(q)·P equals J⁻ᵀG from the general dynamics at random poses
    d = _with_com(load_preset("master-paper"), (0.003, -0.002))
    gp = md.gravity_parameters(md.model_of(d))
    rng = np.random.default_rng(5)
    t3, ph = rng.uniform(-1.5, 0.6, 8), rng.uniform(0.7, 2.5, 8)
    q = np.asarray(mk.q_from_theta3_phi(np.zeros(8), t3, ph))
    F = mb.force_field(d, q)
    A = mb.unbalance_maps(d.geometry.upper_arm, d.geometry.forearm, gp.moving_mass * md.GRAVITY, t3, ph)
    Fa = A @ np.asarray(gp.com_offset)
    np.testing.assert_allclose(F[:, [0, 2]], Fa, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(F[:, 1], 0.0, atol=1e-14)


def test_perfect_balance_has_no_unbalance_force(design):
    # acceptance: perfect-balance counterweights → unbalance ≤ 1e-9 N everywhere
    r = mb.evaluate(design, fidelity=Fidelity.FINE)
    assert r.max_force <= 1e-9
    assert r.inside and r.status is Status.OK


def test_com_on_the_circle_in_the_worst_direction_gives_the_threshold(design):
    # acceptance: CoM on the unbalance circle (worst direction) → max force = threshold ± 1 %; inside → below
    r0 = mb.evaluate(design)
    d = np.asarray(r0.worst_direction)
    on = _with_com(design, r0.radius * d)
    r_on = mb.evaluate(on)
    # the counterweights change M, so the circle is recomputed for the moved design
    assert abs(r_on.radius - r0.radius) / r0.radius < 0.05
    on2 = _with_com(design, r_on.radius * np.asarray(r_on.worst_direction))
    r_on2 = mb.evaluate(on2)
    np.testing.assert_allclose(r_on2.max_force, mb.FORCE_JND_N, rtol=0.01)
    inside = _with_com(design, 0.9 * r_on.radius * np.asarray(r_on.worst_direction))
    assert mb.evaluate(inside).max_force < mb.FORCE_JND_N


def test_circle_is_inside_the_region_in_every_direction(design):
    # any CoM on the circle stays at or below the threshold (radius = min over directions)
    r = mb.evaluate(design, fidelity=Fidelity.FINE)
    assert np.all(r.region_radii >= r.radius * (1 - 1e-9))
    Mg = r.moving_mass * md.GRAVITY
    ws = mb.workspace_of(design)
    for ang in np.linspace(0, np.pi, 7):
        P = r.radius * np.array([np.cos(ang), np.sin(ang)])
        fmax, _, _ = mb._maximise(lambda T, Ph: np.linalg.norm(  # noqa: B023
            mb.unbalance_maps(design.geometry.upper_arm, design.geometry.forearm, Mg, T, Ph) @ P, axis=-1), ws, 81, 4)
        assert fmax <= mb.FORCE_JND_N * (1 + 1e-6)


def test_standard_fidelity_agrees_with_fine(design):
    d = _with_com(design, (0.004, 0.001))
    s, f = mb.evaluate(d), mb.evaluate(d, fidelity=Fidelity.FINE)
    np.testing.assert_allclose(s.radius, f.radius, rtol=1e-6)
    np.testing.assert_allclose(s.max_force, f.max_force, rtol=1e-6)
    dr = mb.evaluate(d, fidelity=Fidelity.DRAFT)
    np.testing.assert_allclose(dr.radius, f.radius, rtol=0.05)


def test_ellipse_fit_is_comparable_to_the_paper(design):
    # seed 003 eq 7/12: a 45° ellipse with axis ratio a/b = 66.7/10.3 ≈ 6.5 and 87 % overlap;
    # our link data differ, so only the shape class is checked: elongated along (1, 1), large overlap
    r = mb.evaluate(design)
    a, b = r.ellipse_axes
    assert a > 2 * b > 0
    assert 0.6 < r.ellipse_overlap <= 1.0


def test_singular_joint_range_is_excluded_with_a_status(design):
    j = dataclasses.replace(design.joints, parallelogram_min=0.0, parallelogram_max=np.pi)
    d = _with_com(dataclasses.replace(design, joints=j), (0.002, 0.0))
    r = mb.evaluate(d)
    assert r.status is Status.SINGULAR and "singular" in r.message
    assert all(np.isfinite(v).all() for v in map(np.asarray, [x for x in r.metrics().values() if not isinstance(x, bool)]))


@pytest.mark.parametrize("case", ["zero_counterweight", "massless_links", "no_mass"])
def test_hard_cases_have_finite_metrics(design, case):
    if case == "zero_counterweight":
        d = dataclasses.replace(design, counterweights=dataclasses.replace(design.counterweights, upper_mass=0.0,
                                                                            forearm_mass=0.0))
    else:
        links = dataclasses.replace(design.links, upper_arm_mass=0.0, forearm_mass=0.0, driver_link_mass=0.0,
                                    coupler_mass=0.0, handle_mass=0.0 if case == "no_mass" else 0.03)
        cw = design.counterweights if case == "massless_links" else dataclasses.replace(
            design.counterweights, upper_mass=0.0, forearm_mass=0.0)
        d = dataclasses.replace(design, links=links, counterweights=cw)
    r = mb.evaluate(d)
    for v in r.metrics().values():
        assert np.all(np.isfinite(np.asarray(v, dtype=float)))
    if case == "no_mass":
        assert r.status is Status.FAILED
    else:
        assert r.status is Status.NOT_MET and r.max_force > mb.FORCE_JND_N  # above the JND: the requirement misses


def test_unbalance_above_the_jnd_is_not_met(master_paper):
    # seed 003: the unbalance force must stay ≤ 0.1 N (10 % JND of 1 N); without the upper counterweight
    # the paper's balance is lost (its balance point P = 0 needs both, design/master/params)
    from hapticopt.design import io

    r = mb.evaluate(io.apply_overrides(master_paper, ["counterweights.upper_mass_kg=0"]))
    assert r.max_force > mb.FORCE_JND_N and r.status is Status.NOT_MET
    assert "allowed ≤ 0.1 N" in r.message and r.metrics()["max_unbalance_force_N"] == r.max_force  # numbers kept
    assert mb.evaluate(master_paper).status is Status.OK  # balanced: max force ~1e-16 N

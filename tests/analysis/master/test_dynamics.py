"""Tests of hapticopt.analysis.master.dynamics (jax reference) and hapticopt.analysis.master.dynamics_numpy (NumPy fast path)."""

from __future__ import annotations

import dataclasses

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis.master import dynamics as md
from hapticopt.design.master import kinematics as mk
from hapticopt.analysis.master import dynamics_numpy as mn
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.io import load_preset


@pytest.fixture(scope="module")
def design():
    # an unbalanced variant so that G ≠ 0 (preset counterweights halved)
    d = load_preset("master-paper")
    cw = dataclasses.replace(d.counterweights, upper_mass=0.2, forearm_mass=0.05)
    return dataclasses.replace(d, counterweights=cw)


@pytest.fixture(scope="module")
def q():
    rng = np.random.default_rng(7)
    return np.asarray(mk.q_from_theta3_phi(rng.uniform(-1, 1, 6), rng.uniform(-1.5, 0.6, 6), rng.uniform(0.7, 2.5, 6)))


def test_mass_matrix_is_symmetric_positive_definite(design, q):
    M = np.asarray(md.mass_matrix(md.model_of(design), jnp.asarray(q)))
    np.testing.assert_allclose(M, np.swapaxes(M, -1, -2), atol=1e-15)
    assert np.all(np.linalg.eigvalsh(M) > 0)


def test_numpy_fast_path_matches_jax_reference(design, q):
    model = md.model_of(design)
    np.testing.assert_allclose(mn.mass_matrix(model, q), np.asarray(md.mass_matrix(model, jnp.asarray(q))),
                               rtol=1e-12, atol=1e-16)
    np.testing.assert_allclose(mn.gravity_torque(model, q), np.asarray(md.gravity_torque(model, jnp.asarray(q))),
                               rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(mn.jacobian(model.kin, q), np.asarray(mk.jacobian(model.kin, jnp.asarray(q))), atol=1e-15)


def test_gravity_has_the_seed003_eq4_form(design, q):
    # seed 003 eq 4: G = [0, G1 cos θ2, G2 sin θ3] — from the general ∂V/∂q, not typed in
    G = np.asarray(md.gravity_torque(md.model_of(design), jnp.asarray(q)))
    np.testing.assert_allclose(G[:, 0], 0.0, atol=1e-15)
    g1 = G[:, 1] / np.cos(q[:, 1])
    g2 = G[:, 2] / np.sin(q[:, 2])
    np.testing.assert_allclose(g1, g1[0], rtol=1e-12)
    np.testing.assert_allclose(g2, g2[0], rtol=1e-12)
    gp = md.gravity_parameters(md.model_of(design))
    np.testing.assert_allclose([gp.G1, gp.G2], [g1[0], g2[0]], rtol=1e-12)


def test_gravity_parameters_match_seed003_eq4_by_hand(design):
    # eq 4 with this mechanism's bodies: G1 = g(m_u c_u + m_c c_c + (m_f + m_h) L5 − m2 r2x),
    # G2 = g(m_f c_f + m_h L4 − m_d c_d − m_c d − m4 r4z); eq 10–11: P = (G1, G2)/(M g)
    g, ln, cw = design.geometry, design.links, design.counterweights
    G1 = md.GRAVITY * (ln.upper_arm_mass * ln.upper_arm_com + ln.coupler_mass * ln.coupler_com
                       + (ln.forearm_mass + ln.handle_mass) * g.upper_arm - cw.upper_mass * cw.upper_distance)
    G2 = md.GRAVITY * (ln.forearm_mass * ln.forearm_com + ln.handle_mass * g.forearm
                       - ln.driver_link_mass * ln.driver_link_com - ln.coupler_mass * g.driver_link
                       - cw.forearm_mass * cw.forearm_distance)
    gp = md.gravity_parameters(md.model_of(design))
    np.testing.assert_allclose([gp.G1, gp.G2], [G1, G2], rtol=1e-12)
    M = (ln.upper_arm_mass + ln.forearm_mass + ln.driver_link_mass + ln.coupler_mass + ln.handle_mass
         + cw.upper_mass + cw.forearm_mass)
    np.testing.assert_allclose(gp.moving_mass, M, rtol=1e-14)
    np.testing.assert_allclose(gp.com_offset, (G1 / (M * md.GRAVITY), G2 / (M * md.GRAVITY)), rtol=1e-12)


def test_gravity_is_gradient_of_potential_by_finite_differences(design, q):
    model = md.model_of(design)
    h = 1e-6
    G = np.asarray(md.gravity_torque(model, jnp.asarray(q[0])))
    fd = [(float(md.potential_energy(model, jnp.asarray(q[0] + h * e)))
           - float(md.potential_energy(model, jnp.asarray(q[0] - h * e)))) / (2 * h) for e in np.eye(3)]
    np.testing.assert_allclose(G, fd, atol=1e-8)


def test_coriolis_passivity(design, q):
    # property: q̇ᵀ(Ṁ − 2C)q̇ = 0, i.e. q̇ᵀṀq̇ = 2 q̇ᵀ c(q, q̇)
    model = md.model_of(design)
    rng = np.random.default_rng(3)
    qd = rng.normal(size=q.shape)
    c = np.asarray(md.coriolis(model, jnp.asarray(q), jnp.asarray(qd)))
    h = 1e-6
    Mdot = (mn.mass_matrix(model, q + h * qd) - mn.mass_matrix(model, q - h * qd)) / (2 * h)
    lhs = np.einsum("ni,nij,nj->n", qd, Mdot, qd)
    np.testing.assert_allclose(lhs, 2 * np.einsum("ni,ni->n", qd, c), atol=1e-8)


def test_point_mass_at_the_handle_gives_m_JtJ():
    # closed form: a lone point mass m at the handle has M(q) = m JᵀJ
    d = load_preset("master-paper")
    zero_links = dataclasses.replace(d.links, upper_arm_mass=0, forearm_mass=0, driver_link_mass=0, coupler_mass=0,
                                     handle_mass=0.5, turret_inertia=0)
    d = dataclasses.replace(d, links=zero_links,
                            counterweights=dataclasses.replace(d.counterweights, upper_mass=0, forearm_mass=0),
                            actuators=dataclasses.replace(d.actuators, rotor_inertia=0))
    bodies = tuple(dataclasses.replace(b, inertia=((0, 0, 0), (0, 0, 0), (0, 0, 0)))
                   for b in md.analytic_mass_properties(d))
    model = md.model_of(d, bodies)
    q = np.array([[0.2, 0.3, -0.4]])
    J = mn.jacobian(model.kin, q)[0]
    np.testing.assert_allclose(mn.mass_matrix(model, q)[0], 0.5 * J.T @ J, atol=1e-14)


def test_balancing_counterweights_zero_the_com_offset(design):
    mu, mf = md.balancing_counterweights(design)
    cw = dataclasses.replace(design.counterweights, upper_mass=mu, forearm_mass=mf)
    gp = md.gravity_parameters(md.model_of(dataclasses.replace(design, counterweights=cw)))
    assert abs(gp.G1) < 1e-12 and abs(gp.G2) < 1e-12
    # the bundled preset is the perfectly balanced design
    np.testing.assert_allclose(md.balancing_counterweights(load_preset("master-paper")),
                               (load_preset("master-paper").counterweights.upper_mass,
                                load_preset("master-paper").counterweights.forearm_mass), rtol=1e-9)


def test_counterweights_for_com_offset(design):
    target = (0.002, -0.001)
    mu, mf = md.counterweights_for_com_offset(design, target)
    cw = dataclasses.replace(design.counterweights, upper_mass=mu, forearm_mass=mf)
    gp = md.gravity_parameters(md.model_of(dataclasses.replace(design, counterweights=cw)))
    np.testing.assert_allclose(gp.com_offset, target, atol=1e-12)


def test_balancing_needs_a_lever_arm(design):
    cw = dataclasses.replace(design.counterweights, upper_distance=0.0)
    with pytest.raises(InvalidDesign, match="upper_distance_mm"):
        md.balancing_counterweights(dataclasses.replace(design, counterweights=cw))


def test_unknown_body_frame_is_rejected(design):
    bad = (md.BodyMass(name="x", frame="elbow", mass=1.0, com=(0, 0, 0), inertia=((1, 0, 0), (0, 1, 0), (0, 0, 1))),)
    with pytest.raises(ValueError, match="frame 'elbow'"):
        md.model_of(design, bad)

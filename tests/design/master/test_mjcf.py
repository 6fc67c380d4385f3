"""Tests of hapticopt.design.master.mjcf: the MuJoCo model agrees with hapticopt.analysis.master.dynamics."""

from __future__ import annotations

import dataclasses

from hapticopt.design import export as design_export
from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import mujoco
import numpy as np
import pytest

from hapticopt.analysis.master import dynamics as md
from hapticopt.design.master import kinematics as mk
from hapticopt.analysis.master import dynamics_numpy as mn
from hapticopt.design.io import load_preset
from hapticopt.design.master.mjcf import REDUCTION, full_qpos, master_mjcf


@pytest.fixture(scope="module")
def design():
    d = load_preset("master-paper")  # unbalanced variant: G ≠ 0
    return dataclasses.replace(d, counterweights=dataclasses.replace(d.counterweights, upper_mass=0.25,
                                                                      forearm_mass=0.05))


def _reduced(m, data, q):
    data.qpos[:] = full_qpos(q)
    data.qvel[:] = 0.0
    mujoco.mj_forward(m, data)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, data, M)
    return REDUCTION.T @ M @ REDUCTION, REDUCTION.T @ data.qfrc_bias


def test_mass_matrix_and_gravity_match_mujoco(design):
    # acceptance: M(q), G(q) from the dynamics vs MuJoCo (mj_fullM / qfrc_bias) ≤ 1 % at random poses
    m = mujoco.MjModel.from_xml_string(master_mjcf(design))
    data = mujoco.MjData(m)
    model = md.model_of(design)
    rng = np.random.default_rng(11)
    for _ in range(5):
        q = np.asarray(mk.q_from_theta3_phi(rng.uniform(-1, 1), rng.uniform(-1.5, 0.6), rng.uniform(0.7, 2.5)))
        M_mj, G_mj = _reduced(m, data, q)
        M = mn.mass_matrix(model, q[None])[0]
        G = mn.gravity_torque(model, q[None])[0]
        assert np.abs(M_mj - M).max() <= 0.01 * np.abs(M).max()
        assert np.abs(G_mj - G).max() <= 0.01 * np.abs(G).max()
        # in fact they agree to the 1e-9 kg mass floor of the joint bodies
        np.testing.assert_allclose(M_mj, M, atol=1e-8)
        np.testing.assert_allclose(G_mj, G, atol=1e-7)
        np.testing.assert_allclose(data.site_xpos[m.site("handle").id], mk.forward_kinematics(model.kin, q), atol=1e-12)


def test_parallelogram_closes_at_every_pose(design):
    m = mujoco.MjModel.from_xml_string(master_mjcf(design))
    data = mujoco.MjData(m)
    data.qpos[:] = full_qpos([0.4, 0.7, -0.9])
    mujoco.mj_forward(m, data)
    c = m.body("coupler").id
    end = data.xpos[c] + data.xmat[c].reshape(3, 3) @ np.array([design.geometry.upper_arm, 0, 0])
    np.testing.assert_allclose(end, data.site_xpos[m.site("forearm_rear").id], atol=1e-12)


def test_gravity_switch_and_actuators(design):
    m = mujoco.MjModel.from_xml_string(master_mjcf(design, gravity=False))
    data = mujoco.MjData(m)
    _, G = _reduced(m, data, np.array([0.1, 0.2, -0.3]))
    np.testing.assert_allclose(G, 0.0, atol=1e-15)
    assert [m.actuator(i).name for i in range(m.nu)] == ["theta1", "theta2", "theta3"]
    np.testing.assert_allclose(m.actuator_ctrlrange[0], [-design.actuators.torque_limit, design.actuators.torque_limit])


def test_massless_links_still_compile(design):
    links = dataclasses.replace(design.links, upper_arm_mass=0.0, forearm_mass=0.0, driver_link_mass=0.0,
                                coupler_mass=0.0, handle_mass=0.0, turret_inertia=0.0)
    d = dataclasses.replace(design, links=links)
    m = mujoco.MjModel.from_xml_string(master_mjcf(d))
    assert m.nq == 5


def test_custom_mass_properties_are_used(design):
    bodies = md.analytic_mass_properties(design)
    heavier = tuple(dataclasses.replace(b, mass=2 * b.mass) if b.name == "handle" else b for b in bodies)
    m = mujoco.MjModel.from_xml_string(master_mjcf(design, heavier))
    np.testing.assert_allclose(m.body_mass[m.body("handle_mass").id], 2 * design.links.handle_mass)


def test_cad_mass_model_matches_mujoco_too():
    # the CAD engineer's geometric mass model (design.mass_properties.analytic) through the same path

    d = load_preset("master-paper")
    bodies = md.bodies_from_mass_properties(design_export.mass_properties(d))
    m = mujoco.MjModel.from_xml_string(master_mjcf(d, bodies))
    data = mujoco.MjData(m)
    model = md.model_of(d, bodies)
    q = np.array([0.3, 0.4, -0.6])
    M_mj, G_mj = _reduced(m, data, q)
    np.testing.assert_allclose(M_mj, mn.mass_matrix(model, q[None])[0], atol=1e-8)
    np.testing.assert_allclose(G_mj, mn.gravity_torque(model, q[None])[0], atol=1e-7)

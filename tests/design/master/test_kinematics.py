"""Tests of hapticopt.design.master.kinematics (PHANToM-type master of seed 003)."""

from __future__ import annotations

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hapticopt.design.master import kinematics as mk
from hapticopt.design.io import load_preset


def planar_jacobian(params, q: jax.Array) -> jax.Array:
    """In-plane Jacobian ∂(ρ, z)/∂(θ2, θ3) (…, 2, 2) [m/rad]; det = −L4·L5·cos(θ2 − θ3)."""
    q = jnp.asarray(q)
    t2, t3 = q[..., 1], q[..., 2]
    L5, L4 = params.upper_arm, params.forearm
    row_rho = jnp.stack([-L5 * jnp.sin(t2), L4 * jnp.cos(t3)], axis=-1)
    row_z = jnp.stack([L5 * jnp.cos(t2), L4 * jnp.sin(t3)], axis=-1)
    return jnp.stack([row_rho, row_z], axis=-2)


@pytest.fixture(scope="module")
def params():
    return mk.params_of(load_preset("master-paper"))


def _random_q(params, n, seed=0):
    rng = np.random.default_rng(seed)
    t1 = rng.uniform(float(params.theta1_min), float(params.theta1_max), n)
    t3 = rng.uniform(float(params.theta3_min), float(params.theta3_max), n)
    ph = rng.uniform(float(params.parallelogram_min), float(params.parallelogram_max), n)
    return np.asarray(mk.q_from_theta3_phi(t1, t3, ph))


def test_analytic_jacobian_matches_autodiff(params):
    q = jnp.asarray(_random_q(params, 20))
    J = mk.jacobian(params, q)
    J_ad = jax.vmap(jax.jacfwd(lambda qq: mk.forward_kinematics(params, qq)))(q)
    np.testing.assert_allclose(J, J_ad, atol=1e-14)


def test_jacobian_determinant_is_proportional_to_cos_theta2_minus_theta3(params):
    # seed 003 eq 2 / 5: the denominator of every unbalance factor is cos(θ2 − θ3)
    q = jnp.asarray(_random_q(params, 20, seed=1))
    det = np.linalg.det(np.asarray(mk.jacobian(params, q)))
    rho = np.asarray(mk.reach(params, q))
    expected = rho * float(params.upper_arm * params.forearm) * np.cos(q[:, 1] - q[:, 2])
    np.testing.assert_allclose(det, expected, rtol=1e-12, atol=1e-16)
    pdet = np.linalg.det(np.asarray(planar_jacobian(params, q)))
    np.testing.assert_allclose(pdet, -float(params.upper_arm * params.forearm) * np.cos(q[:, 1] - q[:, 2]), rtol=1e-12)


def test_planar_jacobian_is_the_theta2_theta3_block(params):
    # at θ1 = 0 the radial direction is x: rows (x, z), columns (θ2, θ3) of the full Jacobian
    q = jnp.asarray(_random_q(params, 5, seed=2)).at[:, 0].set(0.0)
    J = np.asarray(mk.jacobian(params, q))
    np.testing.assert_allclose(np.asarray(planar_jacobian(params, q)), J[:, [0, 2]][:, :, [1, 2]], atol=1e-15)


@settings(max_examples=40, deadline=None)
@given(t1=st.floats(-1.0, 1.0), t3=st.floats(-1.5, 0.69), phi=st.floats(0.62, 2.6))
def test_ik_inverts_fk(t1, t3, phi):
    # property: IK∘FK = id on the working elbow branch (0 < φ < 180°) with the handle in front (ρ > 0)
    prm = mk.params_of(load_preset("master-paper"))
    q = mk.q_from_theta3_phi(t1, t3, phi)
    if float(mk.reach(prm, q)) < 1e-3:
        return
    sol = mk.inverse_kinematics(prm, mk.forward_kinematics(prm, q))
    assert bool(sol.reachable)
    np.testing.assert_allclose(np.asarray(sol.q), np.asarray(q), atol=1e-9)


def test_ik_behind_the_axis_uses_rho_sign(params):
    q = mk.q_from_theta3_phi(0.3, -1.4, 2.6)  # θ2 = −140°, θ3 = −80°: ρ = L5 c2 + L4 s3 < 0
    assert float(mk.reach(params, q)) < 0
    p = mk.forward_kinematics(params, q)
    back = mk.inverse_kinematics(params, p, rho_sign=-1.0)
    np.testing.assert_allclose(np.asarray(back.q), np.asarray(q), atol=1e-9)


def test_ik_out_of_reach_is_flagged_not_nan(params):
    far = jnp.asarray([[2.0, 0.0, 0.4], [0.0, 0.0, float(params.shoulder_height)]])
    sol = mk.inverse_kinematics(params, far)
    assert not bool(sol.reachable[0])
    assert np.all(np.isfinite(np.asarray(sol.q)))


def test_joint_range_uses_paper_variables(params):
    # seed 003: −90° < θ3 < 40°, 35° < 90° − θ2 + θ3 < 150°
    d = np.deg2rad
    inside = mk.q_from_theta3_phi(0.0, d(-30.0), d(90.0))
    assert bool(mk.in_joint_range(params, inside))
    assert not bool(mk.in_joint_range(params, mk.q_from_theta3_phi(0.0, d(45.0), d(90.0))))
    assert not bool(mk.in_joint_range(params, mk.q_from_theta3_phi(0.0, d(0.0), d(30.0))))
    assert not bool(mk.in_joint_range(params, mk.q_from_theta3_phi(0.0, d(0.0), d(151.0))))
    assert not bool(mk.in_joint_range(params, mk.q_from_theta3_phi(d(70.0), d(0.0), d(90.0))))
    np.testing.assert_allclose(float(mk.parallelogram_angle(inside)), d(90.0))
    # the design itself is accepted too
    assert bool(mk.in_joint_range(load_preset("master-paper"), inside))


def test_link_frames_chain_consistency(params):
    q = jnp.asarray(_random_q(params, 7, seed=3))
    fr = mk.link_frames(params, q)
    np.testing.assert_allclose(fr.handle.origin, mk.forward_kinematics(params, q), atol=1e-15)
    L5, d = float(params.upper_arm), float(params.driver_link)
    ex = lambda f: np.asarray(f.rotation[..., :, 0])  # noqa: E731
    np.testing.assert_allclose(fr.forearm.origin, fr.upper_arm.origin + L5 * ex(fr.upper_arm), atol=1e-15)
    # parallelogram closes: coupler end = forearm rear extension end
    coupler_end = fr.coupler.origin + L5 * ex(fr.coupler)
    np.testing.assert_allclose(coupler_end, fr.forearm.origin - d * ex(fr.forearm), atol=1e-15)
    np.testing.assert_allclose(fr.driver_link.origin + d * ex(fr.driver_link), fr.coupler.origin, atol=1e-15)
    for f in fr:
        R = np.asarray(f.rotation)
        np.testing.assert_allclose(np.einsum("...ji,...jk->...ik", R, R), np.broadcast_to(np.eye(3), R.shape), atol=1e-14)
        np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)
    # θ2/θ3 rotate about the links' local y axis: the upper arm frame's y is the turret's −y
    np.testing.assert_allclose(fr.upper_arm.rotation[..., :, 1], -fr.turret.rotation[..., :, 1], atol=1e-15)


def test_paper_workspace_holds_a_200mm_cube(params):
    # design/presets/master-paper.toml chooses L4 = L5 so that a ~200 mm cube fits in the paper's joint
    # ranges; the cube placement is the one found by scripts in docs/master.md (corner at
    # x = 0.29·L, z = h − 1.44·L, y centred).
    L = float(params.upper_arm)
    side = 0.199
    u = np.linspace(0.0, 1.0, 9)
    g = np.stack(np.meshgrid(u, u, u, indexing="ij"), -1).reshape(-1, 3)
    p = np.stack([0.29 * L + g[:, 0] * side, (g[:, 1] - 0.5) * side,
                  float(params.shoulder_height) - 1.44 * L + g[:, 2] * side], -1)
    assert bool(np.all(mk.inverse_kinematics(params, jnp.asarray(p)).in_range))

"""Tests of analysis/control/two_link.py (seed 001 §4.2: Table 1, eq 11, 34, Figs 9–11)."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis.control import impedance_learning as il
from hapticopt.analysis.control import two_link as tl

ARM = tl.ArmParams()  # Table 1


@pytest.fixture(scope="module")
def run_1ms():
    return tl.simulate(tl.TwoLinkConfig())


@pytest.fixture(scope="module")
def run_paper_step():
    return tl.simulate(tl.TwoLinkConfig(outer=il.OuterLoopConfig(step=0.01)))


def test_table1_parameters():
    """Seed 001 Table 1: l = 1 m, m = 1.5 kg, I = 5 kg·m², g = 9.81 m/s²."""
    assert (ARM.l1, ARM.l2, ARM.m1, ARM.m2, ARM.i1, ARM.i2, ARM.g) == (1, 1, 1.5, 1.5, 5, 5, 9.81)


def test_dynamics_structure():
    """Eq 11 properties: M(q) symmetric positive definite; Ṁ − 2C skew-symmetric (passivity);
    G = ∂V/∂q for the potential V of the two links (centre of mass at mid-link)."""
    rng = np.random.default_rng(0)

    def potential(q):
        y1 = ARM.lc1 * jnp.sin(q[0])
        y2 = ARM.l1 * jnp.sin(q[0]) + ARM.lc2 * jnp.sin(q[0] + q[1])
        return ARM.g * (ARM.m1 * y1 + ARM.m2 * y2)

    for _ in range(5):
        q = jnp.asarray(rng.uniform(-np.pi, np.pi, 2))
        qd = jnp.asarray(rng.normal(size=2))
        m = np.asarray(tl.mass_matrix(ARM, q))
        np.testing.assert_allclose(m, m.T)
        assert np.linalg.eigvalsh(m).min() > 0
        m_dot = np.asarray(jnp.einsum("ijk,k->ij", jax.jacfwd(lambda qq: tl.mass_matrix(ARM, qq))(q),
                                      qd))
        n = m_dot - 2 * np.asarray(tl.coriolis_matrix(ARM, q, qd))
        np.testing.assert_allclose(n, -n.T, atol=1e-12)
        np.testing.assert_allclose(np.asarray(tl.gravity(ARM, q)),
                                   np.asarray(jax.grad(potential)(q)), atol=1e-12)


def test_kinematics():
    """FK∘IK = id on the task; J = ∂FK/∂q; J̇q̇ = d/dt(J) q̇ (autodiff)."""
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = jnp.asarray([1.0 + rng.uniform(-0.6, 0.6), rng.uniform(0.5, 1.0)])
        q = tl.inverse(ARM, x)
        np.testing.assert_allclose(np.asarray(tl.forward(ARM, q)), np.asarray(x), atol=1e-12)
        np.testing.assert_allclose(np.asarray(tl.jacobian(ARM, q)),
                                   np.asarray(jax.jacfwd(lambda qq: tl.forward(ARM, qq))(q)),
                                   atol=1e-12)
        qd = jnp.asarray(rng.normal(size=2))
        jd = jnp.einsum("ijk,k->ij", jax.jacfwd(lambda qq: tl.jacobian(ARM, qq))(q), qd)
        np.testing.assert_allclose(np.asarray(tl.jacobian_dot_qd(ARM, q, qd)),
                                   np.asarray(jd @ qd), atol=1e-12)


def test_tracking_errors_fig10(run_1ms):
    """Seed 001 Fig 10: joint errors reach 3e-3 rad (joint 1) and 6e-3 rad (joint 2) after the
    initial transient (here from t = 0.5 s, the end of the data phase; the run starts on the
    reference so there is no larger transient), under the eq 34 disturbance; no NaN. θ (not printed)
    = 1 rad/s is chosen to reproduce these magnitudes (docs/seed001.md's sweep: 2.99e-3 / 5.17e-3 rad;
    θ = 0.05 gave 16× less, θ = 2 exceeds both): each within 20 % of the figure's value."""
    r = run_1ms
    assert r.learning.status is il.LearningStatus.OK
    assert np.all(np.isfinite(r.e)) and np.all(np.isfinite(r.tau))
    err = r.max_abs_error(0.5)
    np.testing.assert_allclose(err, [3e-3, 6e-3], rtol=0.2)
    # the end effector follows the impedance trajectory x_r (Fig 9)
    assert np.abs(r.x - r.x_r).max() < 1e-2


@pytest.mark.xfail(strict=True, reason=(
    "Seed 001 Fig 11 reports |τ1| ≤ 25 N·m and |τ2| ≤ 42 N·m; with Table 1 and the square-wave "
    "x_d of §4.1, ẍ_r jumps by K1·0.8 m ≈ 30.6 m/s² at 5 s and 10 s, which needs ≈ 230 / 185 "
    "N·m (measured; see test_torque_peak_is_the_reference_acceleration_step). Between the edges "
    "the torques are ≈ 20–30 N·m. docs/seed001.md"))
def test_torque_bounds_fig11(run_1ms):
    """Seed 001 Fig 11: |τ1| ≤ 25 N·m and |τ2| ≤ 42 N·m over the 15 s run."""
    tmax = run_1ms.max_abs_torque()
    assert tmax[0] <= 25.0 and tmax[1] <= 42.0


def test_torque_peak_is_the_reference_acceleration_step(run_1ms):
    """Why Fig 11 is not reproduced: at t = 10 s the step of x_d by +0.8 m changes e_p by −0.8 m
    and u = ẍ_r by −K1·(−0.8); the torque step must be M(q) J⁻¹ [Δẍ_r, 0] (eq 17: only q̈_r
    jumps), within 2 % (the disturbance and state change over one 1 ms step)."""
    r = run_1ms
    h = r.t[1]
    i = int(round(10.0 / h))
    d_tau = r.tau[i] - r.tau[i - 1]
    k1 = r.learning.k[0, 0]
    q = jnp.asarray(r.q[i])
    predicted = np.asarray(tl.mass_matrix(ARM, q)) @ np.linalg.solve(
        np.asarray(tl.jacobian(ARM, tl.inverse(ARM, jnp.asarray(r.x_r[i])))),
        np.array([k1 * 0.8, 0.0]))
    np.testing.assert_allclose(d_tau, predicted, rtol=0.02)
    assert np.abs(r.tau[i]).max() > 100.0


def test_paper_step_also_tracks(run_paper_step, run_1ms):
    """Seed 001 §4 setting (RK4, 0.01 s): finite, errors of Fig 10's magnitude (within 20 %); the 200π rad/s
    terms of eq 34 alias (sin(200πt) = 0 at every sample), so the 0.01 s run differs from the
    1 ms run by less than half Fig 10's joint-1 bound."""
    r = run_paper_step
    assert np.all(np.isfinite(r.e))
    np.testing.assert_allclose(r.max_abs_error(0.5), [3e-3, 6e-3], rtol=0.2)
    t_s = np.arange(0.0, 15.0, 0.01)
    np.testing.assert_allclose(np.asarray(jax.vmap(tl.disturbance)(jnp.asarray(t_s)))[:, 0],
                               np.sin(t_s), atol=1e-9)
    stride = 10
    np.testing.assert_allclose(r.e, run_1ms.e[::stride], atol=1.5e-3)  # half Fig 10's joint-1 bound (7.1e-4)


@pytest.mark.parametrize("step", [1e-7, 0.5])
def test_step_out_of_range_raises(step):
    with pytest.raises(ValueError, match=r"step = .* s is outside the allowed range .* s"):
        tl.TwoLinkConfig(outer=il.OuterLoopConfig(step=step))


def test_base_outside_workspace_raises():
    with pytest.raises(ValueError, match=r"TwoLinkConfig.base = \(1.8, 0.5\) m"):
        tl.TwoLinkConfig(base=(1.8, 0.5))


def test_config_is_value():
    """Frozen configuration: changed by dataclasses.replace only."""
    cfg = tl.TwoLinkConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.base = (0.0, 0.0)  # type: ignore[misc]

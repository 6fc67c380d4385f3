"""hapticopt.analysis.master.firmware_ioic: the numpy fast paths against their jax references, the
joint-space reference (inverse kinematics, J̇q̇) and the model-refresh tolerance."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis.control import sliding_mode as sm
from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master import firmware_ioic as fi
from hapticopt.analysis.master.firmware import forward
from hapticopt.analysis.master.transparency import default_pose
from hapticopt.design.io import load_preset

DESIGN = load_preset("master-paper")
P3 = sm.NTSMTCParams(lambda1=(3.0,) * 3, lambda2=(3.0,) * 3, beta=(0.5, 1.0, 1.0))


@dataclasses.dataclass(frozen=True)
class Kin:
    upper_arm: float = DESIGN.geometry.upper_arm
    forearm: float = DESIGN.geometry.forearm
    shoulder_height: float = DESIGN.geometry.shoulder_height


def test_numpy_ntsmtc_law_equals_the_jax_reference():
    """Eq 17 with sat (eq 26), both branches of φ (|e| < μ and ≥ μ, eq 14), e → 0 included."""
    rng = np.random.default_rng(3)
    for scale in (1e-9, 1e-3, 0.1):
        kw = dict(m=np.diag([0.01, 0.02, 0.005]) + 1e-3, c_qd=rng.normal(size=3) * 1e-3, g=rng.normal(size=3) * 1e-2,
                  tau_ext=rng.normal(size=3) * 1e-2, e=rng.normal(size=3) * scale, de=rng.normal(size=3) * 0.1,
                  qdd_r=rng.normal(size=3))
        ref = np.asarray(sm.control_torque(P3, **kw))
        np.testing.assert_allclose(fi.control_torque_np(P3, **kw), ref, rtol=1e-13, atol=1e-16)
        assert np.all(np.isfinite(fi.control_torque_np(P3, **kw)))


def test_coriolis_from_christoffel_equals_the_dynamics_module():
    model = md.model_of(DESIGN)
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = np.asarray(default_pose(DESIGN)) + rng.normal(size=3) * 0.2
        qd = rng.normal(size=3)
        dm = np.asarray(jax.jacfwd(lambda qq: md.mass_matrix(model, qq))(jnp.asarray(q)))
        np.testing.assert_allclose(fi.coriolis_from_dm(dm, qd), np.asarray(md.coriolis(model, q, qd)),
                                   rtol=1e-10, atol=1e-15)


def _controller():
    from hapticopt.analysis.loop.scene import load_scene
    from hapticopt.analysis.control import ioic_online

    sc = load_scene("master-ioic")
    q0 = np.asarray(default_pose(DESIGN))
    x0, _ = forward(Kin(), q0)
    cfg = fi.MasterIoicConfig(period=1e-3, counts_per_rev=40000.0, q0=tuple(q0), upper_arm=Kin.upper_arm,
                              forearm=Kin.forearm, shoulder_height=Kin.shoulder_height, axis=0, x_start=tuple(x0),
                              motion=sc.motion, outer=ioic_online.outer_config(sc, 1e-3), ntsmtc=P3,
                              velocity_alpha=0.0, torque_limit=0.5, saturation=True, gravity=True)
    return fi.MasterIoicController(cfg, fi.ModelKey(design=DESIGN, model=md.model_of(DESIGN))), q0, x0


def test_inverse_kinematics_and_jdot_qd():
    ctl, q0, x0 = _controller()
    target = x0 + np.array([0.03, -0.01, 0.02])
    q = ctl.inverse(target, q0)
    np.testing.assert_allclose(forward(Kin(), q)[0], target, atol=1e-12)
    qd = np.array([0.3, -0.2, 0.5])

    def jac(qq):
        L5, L4 = Kin.upper_arm, Kin.forearm
        rho = L5 * jnp.cos(qq[1]) + L4 * jnp.sin(qq[2])
        return jax.jacfwd(lambda x: jnp.array([
            (L5 * jnp.cos(x[1]) + L4 * jnp.sin(x[2])) * jnp.cos(x[0]), (L5 * jnp.cos(x[1]) + L4 * jnp.sin(x[2])) * jnp.sin(x[0]),
            L5 * jnp.sin(x[1]) - L4 * jnp.cos(x[2])]))(qq) + 0 * rho

    ref = np.asarray(jax.jvp(lambda qq: jac(qq) @ qd, (jnp.asarray(q),), (jnp.asarray(qd),))[1])
    np.testing.assert_allclose(ctl.jdot_qd(q, qd), ref, rtol=1e-8, atol=1e-12)


def test_model_refresh_tolerance_is_small_against_the_mass_matrix():
    """Over the 1 mrad refresh step M(q) changes by less than 0.1 % (the firmware's model error)."""
    model = md.model_of(DESIGN)
    q = np.asarray(default_pose(DESIGN))
    m0 = np.asarray(md.mass_matrix(model, q))
    worst = max(np.linalg.norm(np.asarray(md.mass_matrix(model, q + 1e-3 * e)) - m0) / np.linalg.norm(m0)
                for e in np.eye(3))
    assert worst < 1e-3


def test_step_holds_still_without_force_and_motion():
    """At rest on the reference, with no operator force and x_d at the start (amplitude 0), FIC
    gives zero torque apart from gravity compensation G(q) (≈ 0: the preset is balanced)."""
    ctl, q0, x0 = _controller()
    cfg = dataclasses.replace(ctl.cfg, motion=dataclasses.replace(ctl.cfg.motion, amplitude=(0.0, 0.0, 0.0)),
                              outer=dataclasses.replace(ctl.cfg.outer, strategy=ctl.cfg.outer.strategy.FIC))
    ctl = fi.MasterIoicController(cfg, fi.ModelKey(design=DESIGN, model=md.model_of(DESIGN)))
    ctl.reset(np.zeros(3))
    for _ in range(5):
        tau = ctl.step(np.zeros(3), np.zeros(3))
    assert np.max(np.abs(tau)) < 1e-12
    with pytest.raises(AssertionError):
        np.testing.assert_array_equal(ctl.step(np.zeros(3), np.array([0.5, 0.0, 0.0])), tau)

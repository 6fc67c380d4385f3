"""The surgical master in closed loop (analysis/master/mujoco_plant.py, analysis/master/firmware.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hapticopt.analysis import verify
from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.master.firmware import MasterController, MasterFirmwareConfig, forward
from hapticopt.analysis.master.mujoco_plant import simulate, start_pose
from hapticopt.analysis.prrr.loop.mujoco_model import Integrator, SolverSettings
from hapticopt.analysis.loop.scene import Backend, EnvKind, load_scene
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidInput
from hapticopt.design.io import load_preset

MASTER = load_preset("master-paper")


def _cfg(**kw):
    g = MASTER.geometry
    base = dict(period=1e-3, counts_per_rev=40000.0, q0=tuple(start_pose(MASTER)), upper_arm=g.upper_arm,
                forearm=g.forearm, shoulder_height=g.shoulder_height, env=EnvKind.SPRING, anchor=(0.0, 0.0, 0.0),
                stiffness=(50.0, 50.0, 50.0), damping=(0.0, 0.0, 0.0), half_size=(0.005, 0.1, 0.1),
                wall_stiffness=1e3, wall_damping=0.0, velocity_alpha=0.0, torque_limit=0.5, saturation=True,
                quantized=True, gravity_compensation=False)
    base.update(kw)
    return MasterFirmwareConfig(**base)


def test_firmware_kinematics_match_mujoco_and_numeric_jacobian():
    """The firmware's closed-form p(q), J(q) equal the MJCF handle site (hapticopt.design.master.mjcf) and
    hapticopt.analysis.master.dynamics_numpy.jacobian at poses across the workspace."""
    import mujoco

    from hapticopt.analysis.master import dynamics as md
    from hapticopt.analysis.master import dynamics_numpy as mn
    from hapticopt.design.master.mjcf import full_qpos, master_mjcf

    model = mujoco.MjModel.from_xml_string(master_mjcf(MASTER))
    data = mujoco.MjData(model)
    kin = md.model_of(MASTER).kin
    for q in (start_pose(MASTER), np.array([0.3, 0.8, -0.2]), np.array([-0.4, 0.2, -1.0])):
        p, J = forward(_cfg(), q)
        data.qpos[:] = full_qpos(q)
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(p, data.site_xpos[model.site("handle").id], atol=1e-12)
        np.testing.assert_allclose(J, mn.jacobian(kin, q[None])[0], atol=1e-12)


def test_firmware_sees_counts_and_renders_jt_f_with_saturation():
    """τ = Jᵀ F of the spring at the pose the counts say (counts → q = q0 + 2π c / N); clipped at the limit."""
    q0 = start_pose(MASTER)
    p0, _ = forward(_cfg(), q0)
    ctl = MasterController(_cfg(anchor=tuple(p0)))
    ctl.reset(np.zeros(3))
    counts = np.array([100.0, -250.0, 40.0])
    q = q0 + counts * 2 * math.pi / 40000.0
    p, J = forward(_cfg(), q)
    tau = ctl.step(counts)
    np.testing.assert_allclose(tau[0], J.T @ (-50.0 * (p - p0)), rtol=1e-12)
    stiff = MasterController(_cfg(anchor=tuple(p0), stiffness=(1e6, 1e6, 1e6)))
    stiff.reset(np.zeros(3))
    assert np.max(np.abs(stiff.step(counts))) == pytest.approx(0.5)  # torque_limit_Nm of master-paper
    wall = MasterController(_cfg(anchor=tuple(p0), env=EnvKind.BOX))
    wall.reset(np.zeros(3))
    inside = wall.step(np.zeros(3))
    assert np.all(inside == 0.0)  # inside the walls nothing is rendered


def test_master_transparency_sweep_agrees_with_frequency_domain():
    """Issue 8 acceptance: the time-domain bandwidth of the master-transparency sweep (firmware in the
    loop, quantised encoders, 1 kHz ZOH, MuJoCo master) within 5 % of hapticopt.analysis.master.transparency."""
    r = simulate(MASTER, load_scene("master-transparency"), fidelity=Fidelity.DRAFT)
    m = r.metrics()
    assert r.status == Status.OK, r.message
    assert m["bandwidth_error_pct"] <= 5.0
    assert m["backend"] == "multibody" and "master" in m["backend_reason"]
    g = np.asarray(m["transparency_gain"])
    assert np.all(np.diff(g) < 0)  # inertia: the felt force falls with frequency around the bandwidth
    assert m["constraint_health_ok"]


def test_master_wall_renders_the_wall():
    """master-wall: hand spring k_h = 1 N/mm pulled 8 mm against a 1 N/mm wall at 5 mm: quasi-static
    penetration k_h(8 − 5)/(k_h + K_b) = 1.5 mm (springs in series); rendered wall stiffness ≈ K_b."""
    r = simulate(MASTER, load_scene("master-wall"), fidelity=Fidelity.DRAFT)
    m = r.metrics()
    assert r.status == Status.OK and m["stable"], r.message
    assert m["wall_penetration_mm"] == pytest.approx(1.5, rel=0.1)
    assert m["rendered_wall_stiffness_N_per_mm"] == pytest.approx(1.0, rel=0.05)
    assert m["torque_saturated_fraction"] == 0.0 and m["constraint_health_ok"]


def test_master_soft_solver_is_flagged():
    """MuJoCo's default soft equality settings leave the parallelogram open beyond 0.01 mm: flagged."""
    scene = dataclasses.replace(load_scene("master-wall"), duration=0.3)
    soft = SolverSettings(timestep=2.5e-4, integrator=Integrator.EULER, solref=(0.02, 1.0),
                          solimp=(0.9, 0.95, 0.001, 0.5, 2.0))
    r = simulate(MASTER, scene, solver=soft)
    assert r.status == Status.FAILED and not r.health_ok and "parallelogram" in r.message


def test_master_stiff_wall_and_spring_are_unstable_not_nan():
    """Hard cases: a 1000 N/mm wall at 1 kHz chatters on the torque limit (saturated limit cycle);
    a 1000 N/mm spring without saturation diverges. Both end with a status, no NaN in the metrics."""
    from hapticopt.analysis.loop.scene import Effect

    sc = load_scene("master-wall")
    env = dataclasses.replace(sc.environment, wall_stiffness=1e6)
    r = simulate(MASTER, dataclasses.replace(sc, environment=env, duration=0.5), fidelity=Fidelity.DRAFT)
    assert r.status == Status.UNSTABLE and not r.stable and r.unstable_at is not None
    tr = dataclasses.replace(load_scene("master-transparency"), sweep_factors=(), duration=0.5)
    env = dataclasses.replace(tr.environment, stiffness=(1e6, 1e6, 1e6))
    r2 = simulate(MASTER, dataclasses.replace(tr, environment=env, effects=tr.effects - {Effect.SATURATION}),
                  fidelity=Fidelity.DRAFT)
    assert r2.status in (Status.UNSTABLE, Status.FAILED) and not r2.stable
    for res in (r, r2):
        assert all(v is None or np.isfinite(v) for v in res.metrics().values() if isinstance(v, float))


def test_master_dispatch_and_refusals():
    wall = dataclasses.replace(load_scene("master-wall"), duration=0.1)
    r = verify.simulate(MASTER, wall, fidelity=Fidelity.DRAFT)
    assert r.metrics()["device"] == "master" and r.metrics()["backend"] == "multibody"
    with pytest.raises(InvalidInput, match="backend = lumped cannot simulate the master"):
        verify.simulate(MASTER, wall, backend=Backend.LUMPED)
    with pytest.raises(InvalidInput, match="is a prrr"):
        simulate(load_preset("prrr-paper"), wall)


@pytest.mark.parametrize("duration_s", [0.005, 0.05])
def test_a_master_run_shorter_than_the_detector_window_is_inconclusive_not_ok(duration_s):
    """Issue 37: 5–50 ms against a 1e9 N/mm wall were called ok; the same wall is unstable at 0.2 s. A run
    shorter than SATURATION_WINDOW_S (0.1 s, the 3-PRRR's rule) has no verdict."""
    sc = load_scene("master-wall")
    env = dataclasses.replace(sc.environment, wall_stiffness=1e12)  # 1e9 N/mm
    r = simulate(MASTER, dataclasses.replace(sc, environment=env, duration=duration_s), fidelity=Fidelity.DRAFT)
    assert r.status == Status.INCONCLUSIVE and not r.stable, (r.status, r.message)
    assert "shorter than the 0.1 s the instability detector needs" in r.message

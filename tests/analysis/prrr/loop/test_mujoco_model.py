"""Tests of the MuJoCo 3-PRRR model (analysis/prrr/loop/mujoco_model.py)."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest

from hapticopt.design import export as design_export
from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.loop.mujoco_model import (
    LUMPED_LINK_MASS,
    SOLVER_BY_FIDELITY,
    Integrator,
    LinkMasses,
    ModelOptions,
    Platform,
    SolverSettings,
    build,
    health,
    set_pose,
    stress_probe,
)
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design.io import load_preset

DESIGN = load_preset("prrr-paper")
STANDARD = SOLVER_BY_FIDELITY[Fidelity.STANDARD]


@pytest.mark.parametrize("platform", list(Platform))
def test_posed_model_closes_exactly(platform):
    """At any reachable pose the IK-placed model satisfies every closure (residual ~ round-off)
    and the end-effector sits at p and on J(D − c_e) (seed 002 eq 1)."""
    mj = build(DESIGN, ModelOptions(platform=platform))
    data = mujoco.MjData(mj.model)
    rng = np.random.default_rng(8)
    for p in rng.uniform(-0.03, 0.03, size=(5, 3)):
        set_pose(mj, data, p)
        h = health(mj, data)
        assert h.violation < 1e-12 and h.rotation == 0.0 and h.closure < 1e-12
        np.testing.assert_allclose(data.xpos[mj.ee_body], p, atol=1e-12)


def test_mass_split():
    """Total moving mass of the output side equals M (seed 002 Table 4) in both modes; the real
    links carry a substantial share (aluminium bars + bosses from the design's structure)."""
    for lm in LinkMasses:
        mj = build(DESIGN, ModelOptions(link_masses=lm))
        assert mj.ee_mass + mj.link_mass == pytest.approx(DESIGN.end_effector.mass, rel=1e-9)
    lumped = build(DESIGN, ModelOptions(link_masses=LinkMasses.LUMPED))
    assert lumped.link_mass == pytest.approx(6 * LUMPED_LINK_MASS)
    real = build(DESIGN, ModelOptions(link_masses=LinkMasses.REAL))
    assert 0.1 < real.link_mass < DESIGN.end_effector.mass


def test_effects_switch_the_model():
    """Gravity and contacts are off by flag unless asked; no spring joint without SEA compliance;
    the motor mass is present only with motor dynamics."""
    off = build(DESIGN, ModelOptions()).model
    assert off.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY
    assert off.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    on = build(DESIGN, ModelOptions(gravity=True)).model
    assert not on.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY
    rigid = build(DESIGN, ModelOptions(sea_compliance=False))
    assert rigid.motor_qpos is None and rigid.model.ntendon == 0 and off.ntendon == 3
    assert rigid.model.nq == off.nq - 3
    ideal = build(DESIGN, ModelOptions(motor_dynamics=False))
    assert ideal.motor_qpos is None
    assert ideal.model.body_subtreemass[0] < off.body_subtreemass[0] - 3 * DESIGN.actuator.motor_mass + 1e-6


def test_real_link_mass_exceeding_m_is_refused():
    light = dataclasses.replace(DESIGN, end_effector=dataclasses.replace(DESIGN.end_effector, mass=0.2))
    with pytest.raises(InvalidDesign, match="end_effector.mass_kg"):
        build(light, ModelOptions(link_masses=LinkMasses.REAL))


def test_solver_settings_validation():
    with pytest.raises(InvalidInput, match="timestep"):
        SolverSettings(timestep=0.0)
    with pytest.raises(InvalidInput, match="solimp"):
        SolverSettings(solimp=(1.0, 0.9, 0.001, 0.5, 2.0))


@pytest.mark.parametrize("link_masses", list(LinkMasses))
def test_standard_fidelity_meets_closure_tolerance_under_stress(link_masses):
    """Hand dragging the platform at ≈ 0.5 m/s with ±100 N on the sliders: violation ≤ 0.01 mm,
    rotation ≤ 0.1 mrad, end-effector within 0.01 mm of J(D − c_e) (issue 8 tolerances)."""
    r = stress_probe(DESIGN, ModelOptions(platform=Platform.FREE, link_masses=link_masses,
                                          motor_dynamics=False, solver=STANDARD), duration=0.2)
    assert r.finite and not r.warnings
    assert r.health.violation <= 1e-5
    assert r.health.rotation <= 1e-4
    assert r.health.closure <= 1e-5


def test_soft_default_constraints_do_drift():
    """MuJoCo's default solref/solimp on this mechanism drift by far more than the tolerance
    (pitfalls.md: millimetres): the tuned settings are what make the closure hold."""
    soft = SolverSettings(timestep=STANDARD.timestep, integrator=STANDARD.integrator, solref=(0.02, 1.0),
                          solimp=(0.9, 0.95, 0.001, 0.5, 2.0))
    r = stress_probe(DESIGN, ModelOptions(platform=Platform.FREE, link_masses=LinkMasses.REAL,
                                          motor_dynamics=False, solver=soft), duration=0.2)
    assert r.health.violation > 1e-4  # > 0.1 mm


def oscillator_energy(link_masses: LinkMasses, solver: SolverSettings, periods: float = 10.0):
    """Undamped oscillator: the end-effector on the three SEA springs against the free motor
    masses, released 2 mm off; returns (energy trace, samples per period)."""
    mj = build(DESIGN, ModelOptions(link_masses=link_masses, platform=Platform.FREE, solver=solver))
    m = mj.model
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(m)
    p0 = np.array([0.002, 0.001, 0.001])
    set_pose(mj, data, p0)
    data.qpos[mj.motor_qpos] = 0.0  # motors stay home: the springs are stretched
    assert np.allclose(data.qpos[mj.slider_qpos], np.linalg.solve(mj.jacobian, p0))
    mujoco.mj_forward(m, data)
    # output-side mode: k against the slider-space mass M JᵀJ (eq 7); slowest eigen-frequency
    Me = DESIGN.end_effector.mass * mj.jacobian.T @ mj.jacobian
    w = np.sqrt(np.linalg.eigvalsh(np.linalg.solve(Me, DESIGN.actuator.spring * np.eye(3)))).min()
    per = int(round(2 * np.pi / w / m.opt.timestep))
    e = np.empty(int(periods * per))
    for k in range(len(e)):
        mujoco.mj_step(m, data)
        e[k] = data.energy.sum()
    return e, per


@pytest.mark.parametrize("link_masses", list(LinkMasses))
def test_undamped_oscillator_conserves_energy(link_masses):
    """Energy drift ≤ 1 % over 10 periods at standard fidelity (issue 8): period-averaged energy
    of the last period vs the first (the symplectic Euler step oscillates within a period)."""
    e, per = oscillator_energy(link_masses, STANDARD)
    first, last = e[:per].mean(), e[-per:].mean()
    assert abs(last - first) / first <= 0.01


def test_explicit_integrators_diverge_where_dt_is_too_long():
    """Joint stiffness is explicit in MuJoCo (pitfalls.md): a stiff SEA at a long step blows up
    and MuJoCo flags it with a warning rather than NaN; the standard step stays stable."""
    stiff = dataclasses.replace(DESIGN, actuator=dataclasses.replace(DESIGN.actuator, spring=5e7))
    long = SolverSettings(timestep=2e-3, integrator=Integrator.EULER, solref=(4e-3, 1.0))
    r = stress_probe(stiff, ModelOptions(solver=long), duration=0.05)
    assert r.warnings or not r.finite or r.health.violation > 1e-3
    ok = stress_probe(stiff, ModelOptions(solver=STANDARD), duration=0.05)
    assert ok.finite and not ok.warnings


def test_real_links_carry_the_cad_mass_model():
    """REAL link masses, CoMs and inertias are issue 3's analytic mass model (tested against the
    CAD there), placed at the CAD's home pose: compare in world coordinates."""
    from hapticopt.design.prrr import cad as cad_prrr

    mj = build(DESIGN, ModelOptions(link_masses=LinkMasses.REAL))
    data = mujoco.MjData(mj.model)
    set_pose(mj, data, np.zeros(3))
    bodies = design_export.mass_properties(DESIGN).bodies()
    frames = cad_prrr.part_frames(DESIGN, cad_prrr.solve_pose(DESIGN, (0.0, 0.0, 0.0), branch=cad_prrr.DEFAULT_BRANCH))
    for leg in cad_prrr.LEGS:
        for j in (1, 2):
            name = f"link{j}_{leg}"
            bid = mujoco.mj_name2id(mj.model, mujoco.mjtObj.mjOBJ_BODY, f"link{j}_{leg}")
            pm, T = bodies[name], frames[name]
            assert mj.model.body_mass[bid] == pytest.approx(pm.mass, rel=1e-9)
            np.testing.assert_allclose(data.xipos[bid], T[:3, :3] @ pm.com + T[:3, 3], atol=1e-9)
            R = data.ximat[bid].reshape(3, 3)
            world = R @ np.diag(mj.model.body_inertia[bid]) @ R.T
            np.testing.assert_allclose(world, T[:3, :3] @ pm.inertia @ T[:3, :3].T, atol=1e-12, rtol=1e-6)


def test_r_joint_friction_in_the_multibody_model():
    """Issue 19: τ_c as frictionloss on R1 and R2 of every leg and on a fixed tendon θ1 + θ2 (= −θ3,
    R3's relative rotation on a translating platform); none on the sliders unless asked for."""
    mj = build(DESIGN, ModelOptions(r_joint_friction=True)).model
    tau = DESIGN.structure.joint_friction
    for i in (1, 2, 3):  # leg names are 1-based (the CAD's part names)
        for j in ("r1", "r2"):
            assert mj.dof_frictionloss[mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, f"{j}_{i}")]] == tau
        t = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_TENDON, f"r3_{i}")
        assert t >= 0 and mj.tendon_frictionloss[t] == tau
        s = mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, f"slider_{i}")]
        assert mj.dof_frictionloss[s] == 0.0
    plain = build(DESIGN, ModelOptions()).model
    assert plain.dof_frictionloss.max() == 0.0 and mujoco.mj_name2id(plain, mujoco.mjtObj.mjOBJ_TENDON, "r3_1") < 0


def test_export_joint_limits_are_the_joint_limit_evaluators_about_home():
    """Issue 30: the exported MJCF's R-joint ranges are the joint-limits evaluator's, about the home pose.
    Standard fidelity: the folded-elbow limit |θ2| ≤ θ2_max only (the parts' stops are fine-only), so R2 spans
    [−θ2_max − θ2_home, θ2_max − θ2_home] and R1, R3 are free; they land in the model as hinge / tendon ranges."""
    import math

    from hapticopt.analysis.prrr.geometry import joint_limits
    from hapticopt.design.prrr import mjcf
    from hapticopt.design.prrr.kinematics import inverse_kinematics, params_of
    from hapticopt.analysis.prrr.loop.mujoco_model import export_joint_limits

    lim = export_joint_limits(DESIGN, fidelity=Fidelity.STANDARD)
    e = joint_limits.elbow_limit(DESIGN)
    th2 = float(np.asarray(inverse_kinematics(params_of(DESIGN), np.zeros(3), xp=np).theta)[mjcf.BRANCH, 0, 1])
    assert lim.r1 is None and lim.r3 is None
    assert lim.r2 == pytest.approx((-e - th2, e - th2), rel=1e-12)
    assert lim.r2[0] < 0.0 < lim.r2[1]  # home lies inside
    stops = mjcf.RJointLimits(r1=(-1.0, 0.5), r2=lim.r2, r3=(-0.25, math.pi / 2))
    model = mujoco.MjModel.from_xml_string(mjcf.prrr_mjcf(DESIGN, mjcf.export_options(stops)))
    for n in (1, 2, 3):
        assert model.joint(f"r1_{n}").range == pytest.approx([-1.0, 0.5])
        assert model.joint(f"r2_{n}").range == pytest.approx(list(lim.r2))
        t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, f"r3_{n}")
        assert model.tendon_limited[t] and model.tendon_range[t] == pytest.approx([-0.25, math.pi / 2])

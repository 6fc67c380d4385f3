"""3-PRRR MJCF (design/prrr/mjcf.py, the one generator): the exported model is drivable, its
masses are the CAD's, its geoms collide where parts meet; the plant's options map onto it."""

import json

import mujoco
import numpy as np
import pytest

from hapticopt.design import export as design_export
from hapticopt.design import io
from hapticopt.design.prrr import mjcf
from hapticopt.design.prrr.kinematics import inverse_kinematics, params_of


def closure_errors(model, data) -> dict[str, float]:
    """Distance [m] between the two sides of every connect constraint (anchors recomputed from
    body poses)."""
    out = {}
    for k in range(model.neq):
        if model.eq_type[k] != mujoco.mjtEq.mjEQ_CONNECT:
            continue
        b1, b2 = model.eq_obj1id[k], model.eq_obj2id[k]
        a1 = model.eq_data[k, 0:3]
        a2 = model.eq_data[k, 3:6]
        p1 = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ a1
        p2 = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ a2
        out[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_EQUALITY, k)] = float(np.linalg.norm(p1 - p2))
    return out


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


@pytest.fixture(scope="module")
def exported(paper):
    masses = design_export.mass_properties(paper)
    return masses, mujoco.MjModel.from_xml_string(mjcf.prrr_mjcf(paper, mjcf.export_options(), mass_properties=masses))


def _full_inertia(model, b):
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, model.body_iquat[b])
    R = R.reshape(3, 3)
    return R @ np.diag(model.body_inertia[b]) @ R.T


def test_exported_masses_are_the_mass_properties_json(paper, exported):
    masses, model = exported
    data = json.loads(masses.to_json())["bodies"]
    names = {"platform": "ee"}  # the MJCF's platform body carries the handle site
    for body, rec in data.items():
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, names.get(body, body))
        assert b >= 0, body
        assert model.body_mass[b] == pytest.approx(rec["mass_kg"], rel=1e-9), body
    # every CAD kilogram is in the model; the rest is the three motor sides' equivalent mass M_m
    # (seed 002 Table 4: reflected rotor and screw inertia, gravity-compensated, not a part)
    assert model.body_mass.sum() == pytest.approx(masses.total_mass + 3 * paper.actuator.motor_mass, rel=1e-9)
    # inertia about the CoM, world axes at home: the link frame's tensor rotated (parallel axes)
    frames = mjcf.cad_prrr.part_frames(paper, mjcf.cad_prrr.solve_pose(paper, (0.0, 0.0, 0.0)))
    pm = masses.bodies()["link1_1"]
    R = frames["link1_1"][:3, :3]
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "link1_1")
    assert _full_inertia(model, b) == pytest.approx(R @ pm.inertia @ R.T, rel=1e-6, abs=1e-12)


def test_exported_model_has_actuators_limits_and_contacts(paper, exported):
    _, model = exported
    assert model.nu == 3 and np.all(model.actuator_ctrllimited)
    np.testing.assert_allclose(model.actuator_ctrlrange[:, 1], paper.actuator.force_limit / paper.actuator.efficiency)
    for n in (1, 2, 3):
        j = model.joint(f"slider_{n}")
        assert j.limited[0] and j.range == pytest.approx([-paper.geometry.stroke / 2, paper.geometry.stroke / 2])
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY
    assert model.nexclude > 0
    assert np.any(model.geom_contype == 1)


def test_a_position_loop_drives_the_exported_model(paper, exported):
    # issue 15: drive the exported file with a position loop and check it tracks. Motor-side PD
    # (15 Hz, critically damped on M_m) with velocity feed-forward and the screw's viscous friction ξV fed
    # forward, divided by the gear η (the exported dynamics, issue 30), references from the IK of a
    # 60 mm circle in x-y with a 20 mm z swing, gravity on, contacts on, R-joint friction on.
    _, model = exported
    data = mujoco.MjData(model)
    prm = params_of(paper)
    home = np.asarray(inverse_kinematics(prm, np.zeros(3), xp=np).sliders)
    mq = [model.jnt_qposadr[model.joint(f"motor_{n}").id] for n in (1, 2, 3)]
    md = [model.jnt_dofadr[model.joint(f"motor_{n}").id] for n in (1, 2, 3)]
    Mm = paper.actuator.motor_mass
    wn = 2 * np.pi * 15
    kp, kd = Mm * wn**2, 2 * Mm * wn
    dt, T = 1e-3, 2.0
    t = np.arange(int(T / dt) + 1) * dt
    ref = np.stack([0.03 * np.sin(np.pi * t), 0.03 * (1 - np.cos(np.pi * t)), 0.02 * np.sin(0.5 * np.pi * t)], axis=1)
    D = np.asarray(inverse_kinematics(prm, ref, xp=np).sliders) - home
    V = np.gradient(D, dt, axis=0)
    sub = int(round(dt / model.opt.timestep))
    err = []
    for k in range(len(t) - 1):
        data.ctrl[:] = (kp * (D[k] - data.qpos[mq]) + kd * (V[k] - data.qvel[md])
                        + paper.actuator.viscous * V[k]) / paper.actuator.efficiency
        mujoco.mj_step(model, data, nstep=sub)
        err.append(np.linalg.norm(data.body("ee").xpos - ref[k + 1]))
    err = np.asarray(err)
    assert np.all(np.isfinite(err))
    assert err[200:].max() < 1e-3  # measured 0.34 mm worst (accelerating start), 0.16 mm at the end
    assert np.sqrt(np.mean(err[200:] ** 2)) < 0.5e-3
    assert max(closure_errors(model, data).values()) < 1e-4


def test_contacts_where_parts_meet(paper):
    # rails on u_i (θ_1p = 0): at this pose link 2 of leg 1 meets its carriage 1.1 mm deep
    # (analysis.prrr.interference_fast on the same part tables)
    d = io.apply_overrides(paper, ["geometry.theta_1p_deg=0"])
    from hapticopt.analysis.prrr.collision import interference_fast as F
    p = np.array([0.069, 0.0, -0.044])
    assert F.check_points(F.prepare(d), p[None], branch=mjcf.BRANCH).collides[0]
    model = mujoco.MjModel.from_xml_string(mjcf.prrr_mjcf(d, mjcf.export_options(), pose=p))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    assert data.ncon > 0
    assert data.body("ee").xpos == pytest.approx(p, abs=1e-9)  # the keyframe is the pose


def test_plant_options_give_the_plant_model(paper):
    # the multibody plant's XML is this generator's (analysis/prrr/mujoco_model.build_xml)
    from hapticopt.analysis.prrr.loop import mujoco_model as mm
    opts = mm.ModelOptions(link_masses=mm.LinkMasses.REAL, gravity=True)
    assert mm.build_xml(paper, opts) == mjcf.prrr_mjcf(paper, mm.mjcf_options(opts))
    model = mujoco.MjModel.from_xml_string(mm.build_xml(paper, mm.ModelOptions()))
    assert model.ngeom == 0 and model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT


# ------------------------------------------------------- the exported model's dynamics as modelled (issue 30)
def _lumped_z(design, moving_mass: float, command: float, times) -> np.ndarray:
    """End-effector z [m] of the lumped SEA plant (seed 002 eq 6–7, analysis/prrr/loop/lumped_plant.py) with
    every moving kilogram of the exported model on its output (a pure z motion turns no R joint, so every
    moving body translates with ż), gravity on it (the motor sides gravity-compensated, as exported), ξ on
    the motor sides and the same motor-force command on every leg: the exact (matrix-exponential) solution."""
    import dataclasses

    from hapticopt.analysis.loop.scene import Effect, load_scene, resolve
    from hapticopt.analysis.prrr.loop import lumped_plant as lp

    d = io.apply_overrides(design, [f"end_effector.mass_kg={moving_mass!r}"])
    sc = dataclasses.replace(load_scene("free-space"), initial_offset=(0.0, 0.0, 0.0), effects=frozenset(
        {Effect.SEA_COMPLIANCE, Effect.MOTOR_DYNAMICS, Effect.VISCOUS_FRICTION, Effect.GRAVITY}))
    m = lp.build_model(d, sc, resolve(sc))
    u = np.full(3, command)
    out = []
    for t in times:
        disc = lp.discretise(m, t)
        x = disc.Ad @ m.x0 + disc.Bud @ u + disc.cd
        out.append((m.J @ x[m.out_pos])[2])
    return np.asarray(out)


def _mjcf_z(model, command: float, times) -> np.ndarray:
    data = mujoco.MjData(model)
    data.ctrl[:] = command
    out, done = [], 0
    for t in times:
        n = int(round(t / model.opt.timestep)) - done
        mujoco.mj_step(model, data, nstep=n)
        done += n
        out.append(data.body("ee").xpos[2])
    return np.asarray(out)


def _moving_mass(model) -> float:
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(model.nbody)]
    return float(sum(model.body_mass[b] for b, n in enumerate(names) if n not in ("world", "base")
                     and not n.startswith("motor_")))


def test_exported_model_carries_xi_eta_and_r_joint_friction(paper, exported):
    """ξ (damping) on the motor joints, η as the motor actuators' gear (the command is the motor force F,
    ηF drives the screw; its range F_max/η), τ_c on R1, R2 and the R3 tendon."""
    _, model = exported
    a = paper.actuator
    for n in (1, 2, 3):
        assert model.dof_damping[model.joint(f"motor_{n}").dofadr[0]] == pytest.approx(a.viscous)
        for j in ("r1", "r2"):
            assert model.dof_frictionloss[model.joint(f"{j}_{n}").dofadr[0]] == pytest.approx(
                paper.structure.joint_friction)
        t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, f"r3_{n}")
        assert model.tendon_frictionloss[t] == pytest.approx(paper.structure.joint_friction)
    np.testing.assert_allclose(model.actuator_gear[:, 0], a.efficiency)
    np.testing.assert_allclose(model.actuator_ctrlrange[:, 1] * a.efficiency, a.force_limit)


def test_exported_unpowered_sag_and_driven_step_match_the_lumped_plant(paper, exported):
    """Issue 30: unpowered, the exported platform sank 24.6 mm in 1 s (no ξ: the motor sides fell
    freely). With ξ on the motor joints the weight W of the moving parts creeps them down at W/(3ξ) per leg;
    the lumped plant with the same moving mass gives the sag in closed form: within 5 % after 1 s. A driven
    step (the same motor-force command on every leg, through the gear η) likewise, at 0.2, 0.5 and 1 s."""
    _, model = exported
    M = _moving_mass(model)
    times = [0.2, 0.5, 1.0]
    sag = _mjcf_z(model, 0.0, times)
    ref = _lumped_z(paper, M, 0.0, times)
    assert ref[-1] < -0.2e-3  # it does sag (W/(3ξ) ≈ 0.3 mm/s for the CAD's moving mass)
    assert sag[-1] == pytest.approx(ref[-1], rel=0.05)
    # a step of 40 N of motor force per leg lifts the platform against its weight
    F = 40.0
    up = _mjcf_z(model, F, times)
    ref_up = _lumped_z(paper, M, F, times)
    assert ref_up[-1] > 1e-3
    np.testing.assert_allclose(up, ref_up, rtol=0.05)

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
    np.testing.assert_allclose(model.actuator_ctrlrange[:, 1], paper.actuator.force_limit)
    for n in (1, 2, 3):
        j = model.joint(f"slider_{n}")
        assert j.limited[0] and j.range == pytest.approx([-paper.geometry.stroke / 2, paper.geometry.stroke / 2])
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY
    assert model.nexclude > 0
    assert np.any(model.geom_contype == 1)


def test_a_position_loop_drives_the_exported_model(paper, exported):
    # issue 15: drive the exported file with a position loop and check it tracks. Motor-side PD
    # (15 Hz, critically damped on M_m) with velocity feed-forward, references from the IK of a
    # 60 mm circle in x-y with a 20 mm z swing, gravity on, contacts on.
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
        data.ctrl[:] = kp * (D[k] - data.qpos[mq]) + kd * (V[k] - data.qvel[md])
        mujoco.mj_step(model, data, nstep=sub)
        err.append(np.linalg.norm(data.body("ee").xpos - ref[k + 1]))
    err = np.asarray(err)
    assert np.all(np.isfinite(err))
    assert err[200:].max() < 1e-3  # measured 0.7 mm worst (accelerating start), 0.1 mm at the end
    assert np.sqrt(np.mean(err[200:] ** 2)) < 0.5e-3
    assert max(closure_errors(model, data).values()) < 1e-4


def test_without_control_the_platform_sags_under_gravity(paper, exported):
    # the tracking above is not trivial: with zero forces the parts fall onto the SEA springs
    # and the limits; the motor sides are held (gravity-compensated equivalent masses)
    _, model = exported
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, nstep=5000)  # 0.5 s: the weight (≈ 12 N) drags the free motor sides
    assert data.body("ee").xpos[2] < -3e-3


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

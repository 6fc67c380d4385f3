"""3-PRRR MJCF: compiles, masses/inertias from the mass properties, closed chains stay closed."""

import mujoco
import numpy as np
import pytest

from hapticopt.design import export as design_export
from hapticopt.design import io
from hapticopt.design.prrr.mjcf import MjcfOptions, closure_errors, prrr_mjcf


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def _full_inertia(model, b):
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, model.body_iquat[b])
    R = R.reshape(3, 3)
    return R @ np.diag(model.body_inertia[b]) @ R.T


def test_masses_and_inertias_match_the_mass_properties(paper):
    masses = design_export.mass_properties(paper)
    model = mujoco.MjModel.from_xml_string(prrr_mjcf(paper, mass_properties=masses))
    assert model.body_mass.sum() == pytest.approx(masses.total_mass, rel=1e-9)
    for name, pm in masses.bodies().items():
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        assert model.body_mass[b] == pytest.approx(pm.mass, rel=1e-9)
        assert model.body_ipos[b] == pytest.approx(pm.com, abs=1e-9)
        assert _full_inertia(model, b) == pytest.approx(pm.inertia, rel=1e-6, abs=1e-12)


@pytest.mark.parametrize("point", [(0.0, 0.0, 0.0), (0.02, -0.03, 0.03)])
def test_held_sliders_keep_the_chains_closed_and_the_platform_still(paper, point):
    # acceptance (issue 3): 1 s passive simulation, closure ≤ 0.01 mm, end-effector rotation ≤ 0.1 mrad
    model = mujoco.MjModel.from_xml_string(prrr_mjcf(paper, p=point, options=MjcfOptions(hold_sliders=True)))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "platform")
    R0 = data.xmat[pid].reshape(3, 3).copy()
    worst_gap = worst_rot = 0.0
    for k in range(int(round(1.0 / model.opt.timestep))):
        mujoco.mj_step(model, data)
        if k % 25 == 0:
            worst_gap = max(worst_gap, max(closure_errors(model, data).values()))
            Rr = R0.T @ data.xmat[pid].reshape(3, 3)
            worst_rot = max(worst_rot, np.linalg.norm([Rr[2, 1] - Rr[1, 2], Rr[0, 2] - Rr[2, 0], Rr[1, 0] - Rr[0, 1]]) / 2)
    assert worst_gap <= 1e-5
    assert worst_rot <= 1e-4
    assert data.site("ee").xpos == pytest.approx(point, abs=1e-5)


def test_free_sliders_fall_under_gravity(paper):
    # the held case above is not trivially still: without the holds the mechanism moves
    model = mujoco.MjModel.from_xml_string(prrr_mjcf(paper))
    data = mujoco.MjData(model)
    for _ in range(500):
        mujoco.mj_step(model, data)
    assert data.site("ee").xpos[2] < -1e-4


def test_switches(paper):
    model = mujoco.MjModel.from_xml_string(prrr_mjcf(paper, options=MjcfOptions(gravity=False, contacts=False)))
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    model = mujoco.MjModel.from_xml_string(prrr_mjcf(paper, options=MjcfOptions(contacts=True)))
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert model.nexclude > 0

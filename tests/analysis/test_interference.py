"""Interference (manifold3d) at poses, over poses, and joint limits from geometry."""

import math

import numpy as np
import pytest

from hapticopt.analysis import interference as itf
from hapticopt.analysis.status import Status
from hapticopt.design import io


@pytest.fixture(scope="module")
def paper_model():
    return itf.prepare(io.load_preset("prrr-paper"))


def test_paper_design_at_home_has_no_interference(paper_model):
    res = itf.check_pose(paper_model, (0.0, 0.0, 0.0))
    assert res.status == Status.OK and res.collisions == () and res.overlap_mm3 == 0.0


def test_a_colliding_design_names_the_parts():
    # rails on u_i (θ_1p = 0, the layout before issue 15), three times as wide, cross the links at home
    d = io.apply_overrides(io.load_preset("prrr-paper"), ["geometry.theta_1p_deg=0", "structure.rail_width_mm=60"])
    res = itf.check_pose(d, (0.0, 0.0, 0.0))
    assert res.status == Status.COLLIDES
    assert res.pairs
    a, b = res.pairs[0]
    assert f"{a} × {b}" in res.message
    assert all(c.overlap_mm3 > itf.NOISE_MM3 for c in res.collisions)


def test_inward_elbow_branch_collides_under_the_platform(paper_model):
    res = itf.check_pose(paper_model, (0.0, 0.0, 0.0), branch=0)
    assert {("link2_1", "link2_2"), ("link2_1", "link2_3"), ("link2_2", "link2_3")} <= set(res.pairs)


def test_many_poses_and_unreachable(paper_model):
    pts = np.array([[0.0, 0.0, -0.03], [0.0, 0.0, 0.03], [0.5, 0.0, 0.0]])
    res = itf.check_poses(paper_model, pts)
    assert [r.status for r in res] == [Status.OK, Status.OK, Status.EMPTY]
    assert "not reachable" in res[2].message


def test_overlap_volume_is_exact_for_boxes():
    # two unit boxes overlapping by half: 0.5 m³ = 5e8 mm³ (closed form)
    from hapticopt.design import parts

    class Model:
        pass

    spec = parts.PartSpec(name="b", body="b", density=1.0,
                          primitives=(parts.box((0, 0, 0), np.eye(3), 1.0, 1.0, 1.0),))
    mesh = parts.manifold_of(spec)
    m = itf.InterferenceModel(design=None, meshes={"a": mesh, "b": mesh}, skip=frozenset(),
                              bodies={"a": "a", "b": "b"})
    T = np.eye(4)
    T[0, 3] = 0.5
    (c,) = itf.check_frames(m, {"a": np.eye(4), "b": T})
    assert c.overlap_mm3 == pytest.approx(0.5e9, rel=1e-9)


def test_joint_limits_contain_the_home_angles(paper_model):
    limits = {lim.joint: lim for lim in itf.joint_limits(paper_model, step_deg=5.0)}
    assert set(limits) == {"r1_1", "r2_1", "r3_1"}
    for lim in limits.values():
        assert lim.lo <= lim.reference <= lim.hi
        assert lim.hi - lim.lo <= 2 * math.pi
    # link1 and link2 sit in different layers: R2 turns freely; R1 meets the carriage
    assert limits["r2_1"].free
    assert not limits["r1_1"].free

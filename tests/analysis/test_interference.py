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


def _pair_loop(model, frames):
    """The plain reference of :func:`itf.check_frames`: every pair in turn, box test, then the boolean."""
    names = [n for n in model.meshes if n in frames]
    moved = {n: itf._moved(model.meshes[n], frames[n]) for n in names}
    out = []
    for i, a in enumerate(names):
        lo_a, hi_a = itf._aabb(moved[a])
        for b in names[i + 1:]:
            if frozenset((a, b)) in model.skip:
                continue
            lo_b, hi_b = itf._aabb(moved[b])
            if np.any(lo_a > hi_b) or np.any(lo_b > hi_a):
                continue
            vol = (moved[a] ^ moved[b]).volume()
            if vol > itf.NOISE_MM3:
                out.append(itf.Collision(a=a, b=b, overlap_mm3=float(vol)))
    return tuple(out)


def test_check_frames_equals_the_pair_loop():
    # colliding layout (rails on u_i, three times as wide) on both elbow branches: many pairs meet
    d = io.apply_overrides(io.load_preset("prrr-paper"), ["geometry.theta_1p_deg=0", "structure.rail_width_mm=60"])
    model = itf.prepare(d)
    from hapticopt.design.prrr import cad as cad_prrr
    n = 0
    for branch in (0, 1):
        for p in ([0.0, 0.0, 0.0], [0.02, -0.01, -0.03], [-0.03, 0.02, 0.02]):
            frames = cad_prrr.part_frames(d, cad_prrr.solve_pose(d, p, branch=branch))
            fast = itf.check_frames(model, frames)
            assert fast == _pair_loop(model, frames)  # bit for bit: the same booleans in the same order
            n += len(fast)
    assert n > 6  # the comparison covered colliding pairs


@pytest.mark.parametrize("overrides", [(), ("geometry.theta_1p_deg=0", "structure.rail_width_mm=60")])
def test_check_poses_agrees_with_check_pose(overrides):
    # the batched numpy IK against the one-point jax path: same statuses and pairs, overlaps to rounding
    d = io.apply_overrides(io.load_preset("prrr-paper"), list(overrides))
    model = itf.prepare(d)
    rng = np.random.default_rng(7)
    pts = np.concatenate([rng.uniform(-0.08, 0.08, (40, 3)), [[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]]])
    statuses = set()
    for branch in (0, 1):
        many = itf.check_poses(model, pts, branch=branch)
        for p, got in zip(pts, many):
            ref = itf.check_pose(model, p, branch=branch)
            assert got.status == ref.status and got.pairs == ref.pairs and got.pose_mm == ref.pose_mm
            for c, r in zip(got.collisions, ref.collisions):
                assert c.overlap_mm3 == pytest.approx(r.overlap_mm3, rel=1e-9)
            statuses.add(got.status)
    assert {Status.OK, Status.COLLIDES, Status.EMPTY} <= statuses  # every kind of verdict was compared

"""Collision-free workspace (analysis/prrr/collision/free_workspace.py), issue 15 acceptance."""

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from hapticopt.analysis import interference as itf
from hapticopt.analysis.prrr.collision import free_workspace as FW
from hapticopt.analysis.prrr.structure import statics
from hapticopt.analysis.prrr.geometry import workspace as W
from hapticopt.analysis.status import Status
from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def test_paper_cylinder_is_collision_free_by_manifold3d(paper):
    # seed 002 Table 1 and its design goal: a φ140 × 89 mm workspace without link interference.
    # ≥ 216 poses covering the cylinder (12 angles × 6 radii × 3 heights + the axis column), manifold3d
    g = paper.geometry
    h = g.stroke - 0.140 / math.tan(g.beta)
    assert h >= 0.089  # 89.17 mm (seed digest: H = L − 2R cot β)
    phi = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    r = np.linspace(0.0, 0.070, 7)[1:]
    z = np.array([-h / 2, 0.0, h / 2])
    P, R, Z = np.meshgrid(phi, r, z, indexing="ij")
    pts = np.stack([R * np.cos(P), R * np.sin(P), Z], axis=-1).reshape(-1, 3)
    pts = np.concatenate([pts, [[0, 0, -h / 2], [0, 0, 0], [0, 0, h / 2]]])
    assert len(pts) >= 216
    res = itf.check_poses(paper, pts, branch=W.ELBOW_BRANCH)
    assert all(x.status == Status.OK for x in res), [x.message for x in res if not x.ok][:3]


@pytest.mark.parametrize("fidelity", ["draft", "standard", "fine"])
def test_paper_meets_the_required_cylinder_at_every_fidelity(paper, fidelity):
    r = FW.evaluate(paper, fidelity=fidelity)
    assert r.status == Status.OK, r.message
    m = r.metrics()
    # the free radius cannot exceed the reach radius d3 + d4 − d2 = 71.25 mm (seed digest)
    assert 70.0 <= m["workspace_free_radius_mm"] <= 71.25 + 1e-9
    assert m["workspace_free_height_at_diameter_mm"] == pytest.approx(170 - 140 / math.sqrt(3))
    assert m["workspace_free_footprint_ratio"] == pytest.approx(r.cylinder_diameter / r.footprint_diameter)


def test_rails_on_u_i_lose_the_workspace_and_say_so(paper):
    # θ_1p = 0 (the layout before issue 15): the rails stand in other legs' sweep. An interference
    # result with a status, not a crash; the issue measured φ62 mm collision-free on main
    d = io.apply_overrides(paper, ["geometry.theta_1p_deg=0"])
    r = FW.evaluate(d, fidelity="draft")
    assert r.status == Status.COLLIDES and "misses the required" in r.message and "collide" in r.message
    assert r.free_radius < 0.070 and r.colliding > 0  # 66.8 mm with the preset's parts
    assert np.isfinite(list(r.metrics().values())).all()


def test_rail_too_close_names_r_p_and_theta_1p(paper):
    d = io.apply_overrides(paper, ["geometry.theta_1p_deg=70"])  # clevis inside the carriage block
    with pytest.raises(InvalidDesign, match=r"r_p_mm = 117.*theta_1p_deg = 70"):
        from hapticopt.design.prrr import cad
        cad.layout(d)
    r = FW.evaluate(d, fidelity="draft")
    assert r.status == Status.NOT_ASSEMBLABLE and "theta_1p_deg" in r.message and math.isnan(r.free_radius)


@settings(max_examples=15, deadline=None)
@given(theta=st.floats(-180, 180), r_p=st.floats(60, 200))
def test_rail_placement_changes_no_kinematic_or_static_metric(paper, theta, r_p):
    d = io.apply_overrides(paper, [f"geometry.theta_1p_deg={theta!r}", f"geometry.r_p_mm={r_p!r}"])
    a, b = W.evaluate(paper, fidelity="draft"), W.evaluate(d, fidelity="draft")
    # equal to rounding (the override round trip through TOML degrees costs a few ulps)
    for k in ("volume", "reach_radius", "cylinder_diameter", "cylinder_height", "height_at_required"):
        assert getattr(b, k) == pytest.approx(getattr(a, k), rel=1e-12, abs=1e-15)
    sa, sb = statics.evaluate(paper).metrics(), statics.evaluate(d).metrics()
    assert set(sa) == set(sb)
    for k in sa:
        np.testing.assert_allclose(np.asarray(sb[k], dtype=float), np.asarray(sa[k], dtype=float), rtol=1e-12)


def test_reach_only_results_unchanged(paper):
    # seed digest: φ142.5 reach disc, 89.17 mm at φ140 for L = 170 mm
    r = W.evaluate(paper, fidelity="standard")
    assert r.cylinder_diameter == pytest.approx(0.1425, abs=1e-9) or r.reach_radius == pytest.approx(0.07125)
    assert r.height_at_required == pytest.approx(0.170 - 0.140 / math.sqrt(3))


def test_joint_limits_from_the_hardware(paper):
    from hapticopt.analysis.prrr.geometry import joint_limits as J
    r = J.evaluate(paper, fidelity="draft")
    assert r.status == Status.OK
    # folded-elbow margin: |ρ| ≥ boss radius 12 mm, d3 = d4 = 80 mm:
    # |θ2| ≤ acos((12² − 2·80²)/(2·80²)) = 171.40° (closed form)
    assert r.metrics()["joint_elbow_limit_deg"] == pytest.approx(math.degrees(math.acos((144 - 12800) / 12800)))
    lo, hi = r.used["r2"]
    assert max(abs(lo), abs(hi)) <= r.elbow_limit and r.margin > 0
    # the workspace honours it: the reach hole is |ρ| < 12 mm, the φ142.5 disc is untouched
    # (its edge is 88.75 − 12 = 76.75 mm from the axis along t, beyond 71.25 mm)
    assert W.workspace_params(paper).rho_min == pytest.approx(0.012)
    # a fold margin that cuts the φ140 cylinder is reported, not hidden
    fat = io.apply_overrides(paper, ["structure.boss_diameter_mm=60", "structure.bore_diameter_mm=8"])
    assert J.evaluate(fat, fidelity="draft").status == Status.NOT_MET


def test_r1_bracket_does_not_stop_r1_inside_the_cylinder(paper):
    # the R1 bracket stays in the clevis layer (docs/cad.md "R1 bracket"): link1 turns past it. Fine
    # fidelity adds the parts' stops (interference.joint_limits, manifold3d, 2° steps, leg 1). The
    # φ140 mm cylinder needs R1 over −92.2…+37.2° (the evaluator's own IK grid); R1's stop, now from the
    # carriage block, is +66.3° (measured; the bounding-box root stopped it at +14.3°: not-met by 22.9°),
    # so we ask for 20° of margin on both sides
    from hapticopt.analysis.prrr.geometry import joint_limits as J
    r = J.evaluate(paper, fidelity="fine")
    assert r.status == Status.OK, r.message
    (used_lo, used_hi), (stop_lo, stop_hi) = r.used["r1"], r.stops["r1"]
    assert stop_hi - used_hi >= math.radians(20.0) and used_lo - stop_lo >= math.radians(20.0)
    assert r.margin > 0.0


def test_paper_is_the_size_seed_002_built(paper):
    # seed 002 Table 1: φ260 × 231 mm, 4.4 kg; issue 15 acceptance: footprint ≤ 270 mm,
    # height ≤ 240 mm, mass within ± 15 %, split stated
    from hapticopt.analysis.prrr.geometry import device_size
    s = device_size.evaluate(paper)
    assert s.status == Status.OK
    assert s.height <= 0.240
    assert s.mass == pytest.approx(4.4, rel=0.15)
    assert s.sea_mass + s.link_mass + s.frame_mass == pytest.approx(s.mass, rel=1e-12)
    # SEA modules: 3 × (motor 0.40 + screw 0.12 + housing 0.20 kg), the preset's sea_module values
    assert s.sea_mass == pytest.approx(3 * (0.40 + 0.12 + 0.20), rel=1e-9)
    assert W.evaluate(paper, fidelity="draft").footprint_diameter <= 0.270


def test_finish_takes_the_callers_assembly_verdict(paper):
    """``blocked`` given (the batch's, for designs whose part tables it built) gives the result
    ``assembly.check`` would: '' the same result as asking it, a message the not-assemblable one."""
    core = W.workspace_core(W.workspace_params(paper), n_phi=48, n_r=2)
    found = (0.08, 100, 0)
    asked = FW.finish(paper, core, found, fidelity="draft", t0=0.0)
    given_ok = FW.finish(paper, core, found, fidelity="draft", t0=0.0, blocked="")
    assert asked.status is given_ok.status is Status.OK
    assert {**asked.__dict__, "wall_s": 0.0} == {**given_ok.__dict__, "wall_s": 0.0}
    out = FW.finish(paper, core, found, fidelity="draft", t0=0.0, blocked="the parts cannot be laid out: test")
    assert out.status is Status.NOT_ASSEMBLABLE and out.message == "the parts cannot be laid out: test"
    assert math.isnan(out.free_radius)

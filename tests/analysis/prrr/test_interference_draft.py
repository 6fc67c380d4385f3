"""Draft interference model (capsules and vertical prisms in jax) against closed forms, the fast
separating-axis model and the manifold3d reference."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis import interference as itf
from hapticopt.analysis.prrr import interference_draft as D
from hapticopt.analysis.prrr import interference_fast as F
from hapticopt.analysis.prrr import workspace as W
from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.prrr import cad

LEGACY = ["geometry.theta_1p_deg=0", "geometry.r_p_mm=100", "structure.rail_width_mm=20",
          "structure.carriage_wall_mm=8", "structure.carriage_height_mm=50", "structure.sea_envelope_mm=25",
          "structure.base_radius_mm=140", "structure.base_clearance_mm=5"]
OLD_OPTIMUM = LEGACY + ["geometry.beta_deg=59.0563", "geometry.d2_mm=75.8151", "geometry.d3_mm=75.8225",
                        "geometry.d4_mm=75.8223", "geometry.stroke_mm=184.838", "geometry.r_p_mm=99.5627"]


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def _check(design, pts):
    return D.check(D.stack([D.geometry_of(design)]), np.asarray(pts, dtype=float)[None])


def test_segment_distance_closed_forms():
    """Skew lines (distance = offset along the common normal), parallel overlapping segments,
    end-to-end, a degenerate segment (a point) against a segment."""
    p1, q1 = jnp.array([[-1.0, 0, 0], [0, 0, 0], [0, 0, 0], [0.3, 2.0, 0]]), jnp.array([[1.0, 0, 0], [1, 0, 0], [1, 0, 0], [0.3, 2.0, 0]])
    p2, q2 = jnp.array([[0.0, -1, 0.7], [0.5, 0.2, 0], [2.5, 0, 0], [0, 0, 0]]), jnp.array([[0.0, 1, 0.7], [3, 0.2, 0], [4, 0, 0], [1, 0, 0]])
    np.testing.assert_allclose(D._seg_seg(p1, q1, p2, q2), [0.7, 0.2, 1.5, 2.0], rtol=0, atol=1e-15)


def test_segment_prism_distance_is_a_tight_lower_bound():
    """A horizontal segment passing 3 above a unit-square prism's top (z ∈ [0, 1]) and one beside a
    circle prism of radius 1: distances 3 and 2 (closed form); the golden-section bound is below
    them by at most the bracket's Lipschitz term (segment length × 0.618^GOLDEN / 2)."""
    a = jnp.array([[-5.0, 0.2, 4.0], [-5.0, 3.0, 0.5]])
    b = jnp.array([[5.0, 0.2, 4.0], [5.0, 3.0, 0.5]])
    d = D._seg_prism(a, b, jnp.zeros(2), jnp.zeros((2, 2)), jnp.array([[0.5, 0.5], [1.0, 1.0]]),
                     jnp.array([D._RECT, D._CIRC]), jnp.array([[0.0, 1.0], [0.0, 1.0]]))
    slack = 10.0 * 0.618034 ** D.GOLDEN / 2
    assert np.all(np.asarray(d) <= [3.0, 2.0]) and np.all(np.asarray(d) >= np.array([3.0, 2.0]) - slack)


def test_pairs_follow_the_references_rule():
    """Every tested pair joins parts on different bodies that no joint joins; a link is tested
    against the other legs' links, and never against its own carriage (R1) or link (R2)."""
    tab = D.pair_tables()
    names = {c[0]: c for c in D._CAPS}
    pairs = {(D._CAPS[i][0], D._CAPS[j][0]) for i, j in tab["cc"]}
    assert ("link1_1", "link2_2") in pairs and ("link2_1", "link2_2") in pairs
    assert ("bracket_1", "link1_1") not in pairs and ("link1_1", "link2_1") not in pairs
    assert ("link2_1", "arm_1") not in pairs and ("bracket_1", "link2_1") in pairs
    for i, j in tab["cc"]:
        assert names[D._CAPS[i][0]][2] != names[D._CAPS[j][0]][2]
    cp = {(D._CAPS[i][0], D._PRISMS[j][0]) for i, j in tab["cp"]}
    assert ("bracket_1", "rail_1") not in cp and ("link1_1", "rail_1") in cp and ("bracket_1", "block_1") not in cp


def test_home_is_free_and_inward_elbows_collide(paper):
    """The reference's home verdicts (tests/analysis/test_interference.py): home free; rails three
    times as wide on u_i cross the links at home."""
    c, r, _ = _check(paper, np.zeros((1, 3)))
    assert r[0, 0] and not c[0, 0]
    wide = io.apply_overrides(paper, ["geometry.theta_1p_deg=0", "structure.rail_width_mm=60"])
    assert _check(wide, np.zeros((1, 3)))[0][0, 0]


@pytest.mark.parametrize("overrides", [[], LEGACY, OLD_OPTIMUM], ids=["paper", "legacy-paper", "old-optimum"])
def test_conservative_against_the_fast_model_and_manifold3d(paper, overrides):
    """The draft shapes enclose the CAD parts: every pose the fast model (or manifold3d, on a
    subset) calls colliding is colliding here, and reachability is the same IK."""
    d = io.apply_overrides(paper, overrides)
    pts, _ = W.workspace_sample_weights(d, **W.INTERFERENCE_SAMPLING)
    fast = F.check_points(F.prepare(d), pts, branch=W.ELBOW_BRANCH)
    c, r, _ = _check(d, pts)
    assert np.array_equal(r[0], fast.reachable)
    assert not np.any(fast.collides & ~c[0])
    sub = pts[:: max(1, len(pts) // 12)]
    ref = ~np.array([x.ok for x in itf.check_poses(d, sub, branch=W.ELBOW_BRANCH)])
    assert not np.any(ref & ~_check(d, sub)[0][0])


def test_new_batch_size_in_a_bucket_does_not_retrace(paper):
    g = D.stack([D.geometry_of(paper)] * 3)
    pts = np.zeros((3, 5, 3))
    D.check(g, pts)
    n = D.TRACES["check"]
    D.check(D.stack([D.geometry_of(paper)] * 4), np.zeros((4, 7, 3)))
    assert D.TRACES["check"] == n


def test_an_unbuildable_design_raises_the_cads_error(paper):
    bad = io.apply_overrides(paper, ["structure.link_thickness_mm=0.2"])
    with pytest.raises(InvalidDesign, match="link_thickness_mm"):
        D.geometry_of(bad)


def test_link_capsule_radius_encloses_the_bar_and_bosses(paper):
    """r = √(max(W/2, R)² + (T/2)²): the farthest point of the bar's cross-section from its axis."""
    L = cad.layout(paper)
    g = D.geometry_of(paper)
    assert float(g.r_link) == pytest.approx(math.hypot(max(L.W / 2, L.R_boss), L.T / 2), rel=1e-15)

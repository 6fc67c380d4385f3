"""Fast interference (convex primitives, separating axes) against the manifold3d reference."""

import dataclasses
import math

import numpy as np
import pytest

from hapticopt.analysis import interference as itf
from hapticopt.analysis.prrr.collision import interference_fast as F
from hapticopt.analysis.prrr.geometry import workspace as W
from hapticopt.analysis.status import Status
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.prrr.kinematics import PrrrParams, inverse_kinematics


def pairs_at(res, k: int) -> list[tuple[str, str]]:
    """Colliding part pairs of a check's result at pose ``k``."""
    return [res.part_pairs[j] for j in np.flatnonzero(res.depth[k] > F.DEPTH_TOL)]


# the optimum of prrr-workspace before the interference constraint (cad_out/prrr-workspace/
# optimum.toml of that run, docs/workspace_interference.md): it collides more than the paper
#: the layout before issue 15 (rails on u_i, the old part sizes); the SEA motor, screw and housing
#: parts exist since issue 15, so the fractions measured on that layout are not reproduced exactly
LEGACY = ["geometry.theta_1p_deg=0", "geometry.r_p_mm=100", "structure.rail_width_mm=20",
          "structure.carriage_wall_mm=8", "structure.carriage_height_mm=50", "structure.sea_envelope_mm=25",
          "structure.base_radius_mm=140", "structure.base_clearance_mm=5"]

OLD_OPTIMUM = LEGACY + ["geometry.beta_deg=59.0563", "geometry.d2_mm=75.8151", "geometry.d3_mm=75.8225",
               "geometry.d4_mm=75.8223", "geometry.stroke_mm=184.838", "geometry.r_p_mm=99.5627"]


@pytest.fixture(scope="module")
def paper():
    return io.load_preset("prrr-paper")


def _points(design, **sampling):
    pts, _ = W.workspace_sample_weights(design, **sampling)
    return pts


def test_pairs_are_the_references(paper):
    """Same part pairs as hapticopt.analysis.interference: different bodies, not joined."""
    fast = F.prepare(paper)
    ref = itf.prepare(paper)
    names = list(ref.meshes)
    expected = {frozenset((a, b)) for i, a in enumerate(names) for b in names[i + 1:]
                if frozenset((a, b)) not in ref.skip}
    assert {frozenset(p) for p in fast.part_pairs} == expected


def test_frames_are_the_cads(paper, collision_reference):
    pts = _points(paper, n_phi=2, n_r=2, n_z=2)
    frames, reach = collision_reference.part_frames_batch(paper, pts)
    assert reach.all()
    for k, p in enumerate(pts):
        ref = cad_prrr.part_frames(paper, cad_prrr.solve_pose(paper, p))
        for name, T in ref.items():
            R, o = frames[name]
            np.testing.assert_allclose(R[k], T[:3, :3], atol=1e-12)
            np.testing.assert_allclose(o[k], T[:3, 3], atol=1e-12)


@pytest.mark.parametrize("overrides", [LEGACY, OLD_OPTIMUM], ids=["legacy-paper", "old-optimum"])
def test_agrees_with_manifold3d_on_a_pose_set(paper, overrides):
    """Verdicts on 24 workspace poses. Bound: the measured agreement on the 216 fine poses,
    1.000 (prrr-paper) and 0.917 (old optimum), scripts/accuracy/accuracy_interference_fast.py; every
    disagreement is a fast-only collision (conservative), so no reference collision is missed."""
    d = io.apply_overrides(paper, overrides)
    pts = _points(d, n_phi=2, n_r=2, n_z=2)
    fast = F.check_points(F.prepare(d), pts, branch=W.ELBOW_BRANCH)
    ref = ~np.array([r.ok for r in itf.check_poses(d, pts, branch=W.ELBOW_BRANCH)])
    assert not np.any(ref & ~fast.collides)  # conservative: every reference collision is found
    assert (fast.collides == ref).mean() >= (1.0 if overrides == LEGACY else 0.9)
    assert ref.any() and (~ref).any()  # the set has both verdicts


def test_known_colliding_and_free_poses(paper):
    m = F.prepare(paper)
    # home pose: interference-free (tests/analysis/test_interference.py, manifold3d)
    res = F.check_points(m, np.zeros((1, 3)))
    assert not res.collides[0] and pairs_at(res, 0) == []
    # inward elbows (branch 0) collide under the platform: link2 × link2 (same reference test)
    res = F.check_points(m, np.zeros((1, 3)), branch=0)
    assert {("link2_1", "link2_2"), ("link2_1", "link2_3"), ("link2_2", "link2_3")} <= set(pairs_at(res, 0))
    # rails on u_i three times as wide cross the links at home (reference test names the same pairs)
    wide = io.apply_overrides(paper, ["geometry.theta_1p_deg=0", "structure.rail_width_mm=60"])
    res = F.check_points(F.prepare(wide), np.zeros((1, 3)))
    ref = itf.check_pose(wide, (0.0, 0.0, 0.0))
    assert res.collides[0] and set(ref.pairs) <= set(pairs_at(res, 0)) and ref.pairs


def test_box_box_depth_is_exact(collision_reference):
    """Two unit-free boxes overlapping by 2 mm along x (closed form: depth = 2 mm), and rotated
    45° about z so that the corner enters by 1 mm (closed form: a√2/2 + b/2 − gap)."""
    eye = np.eye(3)[None]
    half = np.array([[0.01, 0.01, 0.01]])
    k = np.array([0])
    dep = collision_reference._depth(k, eye, half, np.zeros((1, 3)), k, eye, half, np.array([[0.018, 0.0, 0.0]]))
    assert dep[0] == pytest.approx(0.002, abs=1e-12)
    c, s = math.cos(math.pi / 4), math.sin(math.pi / 4)
    Rz = np.array([[[c, -s, 0], [s, c, 0], [0, 0, 1]]])
    gap = 0.01 * math.sqrt(2) + 0.01 - 0.001
    dep = collision_reference._depth(k, Rz, half, np.zeros((1, 3)), k, eye, half, np.array([[gap, 0.0, 0.0]]))
    assert dep[0] == pytest.approx(0.001, abs=1e-12)


def test_cylinder_rim_near_box_corner_is_separated(collision_reference):
    """A disc (r 12 mm, 10 mm thick) beside a box corner, 1 mm apart along the diagonal: the
    frame axes alone do not separate them, the sampled closest-point axes do."""
    half_box = np.array([[0.01, 0.01, 0.005]])
    half_cyl = np.array([[0.012, 0.012, 0.005]])
    corner = np.array([0.01, 0.01, 0.0])
    centre = corner + (0.012 + 0.001) * np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    eye = np.eye(3)[None]
    dep = collision_reference._depth(np.array([0]), eye, half_box, np.zeros((1, 3)), np.array([1]), eye, half_cyl, centre[None])
    assert dep[0] < 0.0
    dep = collision_reference._depth(np.array([0]), eye, half_box, np.zeros((1, 3)), np.array([1]), eye, half_cyl,
                   (corner + 0.011 * np.array([1.0, 1.0, 0.0]) / math.sqrt(2))[None])
    assert dep[0] > 0.0  # 1 mm inside


def test_degenerate_designs_stay_finite(paper):
    # (almost) zero stroke, 1 nm (0 is outside the design's range): a workspace of ~1e-27 m³
    flat = dataclasses.replace(paper, geometry=dataclasses.replace(paper.geometry, stroke=1e-9))
    frac = F.interference_fractions(flat, n_phi=2, n_r=2, n_z=2)[0]
    assert math.isfinite(frac) and 0.0 <= frac <= 1.0
    # links just long enough for their bosses (the CAD's lower bound): finite verdicts
    short = io.apply_overrides(paper, ["geometry.d3_mm=25", "geometry.d4_mm=25", "geometry.d2_mm=45"])
    # R1 moves with d2: put the rail where the carriage carries it (design.prrr.cad.carried_theta_1p)
    th = math.degrees(cad_prrr.carried_theta_1p(short)) + 0.1
    short = io.apply_overrides(short, [f"geometry.theta_1p_deg={th!r}"])
    frac = F.interference_fractions(short, n_phi=2, n_r=2, n_z=2)[0]
    assert math.isfinite(frac) and 0.0 <= frac <= 1.0
    # unreachable points are never reported as colliding
    res = F.check_points(F.prepare(paper), np.array([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    assert not res.reachable[0] and not res.collides[0] and np.isfinite(res.depth).all()
    # tiny links: the CAD refuses them with a one-line message, and the evaluator says so
    tiny = io.apply_overrides(paper, ["geometry.d3_mm=5", "geometry.d4_mm=5"])
    with pytest.raises(InvalidDesign, match="d3_mm"):
        F.prepare(tiny)


def test_interference_evaluator_reports_the_fast_fraction_and_workspace_stays_cheap(paper):
    # the optimiser's metric comes from its own evaluator (hapticopt.analysis.prrr.collision.interference), so a plain
    # draft workspace evaluation neither runs nor reports it (issue 4's 20 ms draft budget)
    from hapticopt.analysis.prrr.collision import interference as prrr_interference
    from hapticopt.analysis.registry import evaluate_all

    r = prrr_interference.evaluate(paper, fidelity="draft")
    assert r.status == Status.OK
    assert r.metrics()["interference_removed_fraction"] == pytest.approx(
        F.interference_fractions(paper, **W.INTERFERENCE_SAMPLING)[0], rel=1e-12)
    # prrr-paper (issue 15 layout): none of the 216 reach-and-stroke samples collides (regression
    # snapshot of this evaluator; before issue 15: 0.46848); the layout before loses a share
    assert r.removed_fraction == 0.0
    assert prrr_interference.evaluate(io.apply_overrides(paper, LEGACY)).removed_fraction > 0.1
    assert r.metrics()["interference_overlap_fraction"] == pytest.approx(
        F.interference_fractions(paper, **W.INTERFERENCE_SAMPLING)[1], rel=1e-12)
    assert "workspace_interference_removed_fraction" not in W.evaluate(paper, fidelity="draft").metrics()
    assert evaluate_all(paper, fidelity="draft", only=("interference",)).statuses["interference"] == Status.OK
    # links too short to reach: the chain cannot close (|ρ| ≥ d1-offset > d3 + d4 = 10 mm everywhere), so the
    # design cannot be assembled — said by its status with NaN fractions, not an error and not a fake 0
    tiny = io.apply_overrides(paper, ["geometry.d3_mm=5", "geometry.d4_mm=5"])
    empty = prrr_interference.evaluate(tiny)
    assert empty.status == Status.NOT_ASSEMBLABLE and "does not close" in empty.message
    assert np.isnan(empty.removed_fraction) and np.isnan(empty.overlap_fraction)


def test_overlap_share_is_the_clipped_depth_ramp():
    """Closed form: clip(d / OVERLAP_SCALE, 0, 1) of the deepest pair at each pose."""
    depth = np.array([[0.0, 0.0], [0.002, 0.0003], [0.0, 0.0005], [0.0001, 0.00005]])
    res = F.FastResult(points=np.zeros((4, 3)), reachable=np.ones(4, bool), collides=depth.max(1) > F.DEPTH_TOL,
                       depth=depth, part_pairs=(("a", "b"), ("c", "d")))
    np.testing.assert_allclose(F.overlap_share(res, scale=0.001), [0.0, 1.0, 0.5, 0.1], rtol=1e-12)


def test_overlap_fraction_equals_removed_fraction_when_depths_are_saturated(paper):
    """The layout before issue 15 (prrr-paper then lost 0.46848): every colliding pose is deeper
    than OVERLAP_SCALE and the others are 0, so both fractions are the same sum of weights. The
    precondition is checked here, not assumed. (prrr-paper now loses nothing: both are 0.)"""
    paper = io.apply_overrides(paper, LEGACY)
    pts, w = W.workspace_sample_weights(paper, **W.INTERFERENCE_SAMPLING)
    dmax = F.check_points(F.prepare(paper), pts, branch=W.ELBOW_BRANCH).depth.max(axis=1)
    assert np.all((dmax == 0.0) | (dmax >= F.OVERLAP_SCALE)) and (dmax > 0).any() and (dmax == 0).any()
    removed, overlap = F.interference_fractions(paper, **W.INTERFERENCE_SAMPLING)
    assert overlap == pytest.approx(removed, rel=1e-12)
    assert removed > 0.0 and (removed, overlap) == F.interference_fractions(paper, **W.INTERFERENCE_SAMPLING)


# the prrr-workspace optimum of the step-constrained run (commit 12e33d8, docs/optimisation.md)
STEP_OPTIMUM = LEGACY + ["geometry.beta_deg=57.035581000819", "geometry.d2_mm=77.9848002283854",
                "geometry.d3_mm=73.9316796078444", "geometry.d4_mm=79.3338793692093",
                "geometry.stroke_mm=180.260544633171", "geometry.r_p_mm=101.546119285948"]


def test_overlap_fraction_is_continuous_across_a_jump_of_the_removed_fraction(paper):
    """β between 56.175° and 56.195° (at that optimum) crosses a jump of the removed fraction
    (scripts/accuracy/accuracy_interference_overlap.py: 0.0191 at β ≈ 56.1847°). Bisected to ~1e-8°,
    the step still jumps by ≥ 0.01 while the companion changes by < 1e-7 (measured 2e-9)."""
    base = io.apply_overrides(paper, STEP_OPTIMUM)

    def fr(beta):
        return F.interference_fractions(io.apply_overrides(base, [f"geometry.beta_deg={beta!r}"]),
                                        **W.INTERFERENCE_SAMPLING)

    a, b = 56.175, 56.195
    fa, fb = fr(a), fr(b)
    assert abs(fb[0] - fa[0]) > 0.01  # the bracket holds a jump
    for _ in range(21):
        m = 0.5 * (a + b)
        fm = fr(m)
        if abs(fm[0] - fa[0]) >= abs(fb[0] - fm[0]):
            b, fb = m, fm
        else:
            a, fa = m, fm
    assert b - a < 1e-7
    assert abs(fb[0] - fa[0]) >= 0.01
    # continuous: it moves by about its slope × Δβ (measured 2.0e-9 over Δβ < 1e-7° on the legacy layout
    # with the issue-15 SEA parts; 4e-16 before them), against the step's ≥ 0.01
    assert abs(fb[1] - fa[1]) < 1e-7


# --- the numba kernel against its numpy reference (tests/analysis/prrr/interference_reference.py) -------


def _bits(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=np.float64).view(np.int64)


def _largest_layout_group(models) -> list[int]:
    """Indices of the models of the most common part layout (at least two: one call stacks them)."""
    groups: dict = {}
    for i, m in enumerate(models):
        groups.setdefault(F.layout_key(m), []).append(i)
    members = max(groups.values(), key=len)
    assert len(members) >= 2
    return members


def test_check_points_equals_the_numpy_reference_bitwise(problem_sample, collision_reference):
    """check_points (the one IK, then the kernel) and the numpy reference on the CAD's part frames of the
    same IK (``interference_reference.part_frames_batch`` + ``check_posed``): depths bit for bit (signed
    zeros included), on the workspace samples of 16 seeded designs within the problem bounds, one design at
    a time; the sample holds colliding poses, shallow (0 < depth ≤ DEPTH_TOL) overlaps, box–cylinder pairs'
    sampled axes and an unreachable point per design."""
    R = collision_reference
    assert F.availability() is None  # numba is a dependency
    designs = problem_sample(16, seed=4242, accept=F.prepare)  # the CAD lays them out
    n_colliding = n_shallow = n_free = 0
    for d in designs:
        m = F.prepare(d)
        pts, _ = W.workspace_sample_weights(d, **W.INTERFERENCE_SAMPLING)
        pts = np.concatenate([pts, [[0.5, 0.0, 0.0]]])  # and one unreachable point
        frames, ok = R.part_frames_batch(d, pts, branch=W.ELBOW_BRANCH)
        ref = R.check_posed(F.stack_models([m]), np.zeros(len(pts), dtype=int), pts, frames, ok)
        fast = F.check_points(m, pts, branch=W.ELBOW_BRANCH)
        assert np.array_equal(_bits(fast.depth), _bits(ref.depth)), d.geometry
        assert np.array_equal(fast.collides, ref.collides) and np.array_equal(fast.reachable, ok)
        n_colliding += int(ref.collides.sum())
        n_shallow += int(np.count_nonzero((ref.depth > 0) & (ref.depth <= F.DEPTH_TOL)))
        n_free += int(not ref.collides.any())
    assert n_colliding > 100 and n_shallow > 0 and n_free > 0  # depths of all kinds, not only zeros


def test_the_check_says_why_when_the_kernel_cannot_load(monkeypatch):
    """Without the kernel (numba missing, no writable cache folder) the check raises with the reason."""
    d = io.apply_overrides(io.load_preset("prrr-paper"), LEGACY)
    monkeypatch.setattr(F, "availability", lambda: "numba not importable (test)")
    with pytest.raises(RuntimeError, match="numba not importable"):
        F.check_points(F.prepare(d), _points(d, n_phi=2, n_r=2, n_z=2))


def test_models_from_tables_equal_prepare(problem_sample):
    """The primitive tables of a part layout's designs built at once (``models_from_tables`` on
    ``layout.part_tables_many``) equal :func:`prepare` design by design: part names, pairs and
    primitive kinds exactly, axes, centres and half sizes to 1e-12 relative (the array part tables'
    agreement with ``cad.part_specs``, tests/design/prrr/test_layout.py)."""
    from hapticopt.design.prrr import layout as cad_layout

    designs = problem_sample(40, seed=31) + [io.load_preset("prrr-paper")]
    designs.append(dataclasses.replace(designs[-1], geometry=dataclasses.replace(designs[-1].geometry, r4=0.030)))
    groups, _ = cad_layout.part_tables_many(designs)
    assert len(groups) == 2 and sum(len(t.index) for t in groups) >= 10  # both layouts (r4 = 30 mm: the riser)
    for t in groups:
        for i, fast in zip(t.index, F.models_from_tables([designs[i] for i in t.index], t)):
            ref = F.prepare(designs[i])
            assert fast.design is designs[i]
            assert F.layout_key(fast) == F.layout_key(ref)
            assert fast.part_pairs == ref.part_pairs
            for name in ("pair_a", "pair_b", "pair_part"):
                np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name))
            for name in ("R", "o", "half"):
                got, want = getattr(fast, name), getattr(ref, name)
                assert got.shape == want.shape
                assert np.all(np.abs(got - want) <= 1e-12 * np.maximum(np.abs(want), 0.1)), name


def _joint_poses(design, pts):
    """Sliders, elbow-branch joint angles and reachability of ``pts`` by the numpy IK (the branch and
    IK of the reference's ``part_frames_batch``)."""
    from hapticopt.design.prrr.kinematics import inverse_kinematics

    ik = inverse_kinematics(cad_prrr.params_of(design), pts, xp=np)
    return np.asarray(ik.sliders), np.asarray(ik.theta)[:, W.ELBOW_BRANCH], np.asarray(ik.reachable)


def _geometry(designs):
    return F.LegGeometry(*(np.array([float(getattr(d.geometry, f)) for d in designs]) for f in F.LegGeometry._fields))


def _joint_problem(problem_sample) -> tuple:
    """The largest layout group of 16 seeded designs within the problem bounds and their interference
    poses (one unreachable point each; the last two designs' poses shuffled together, so a design's
    fixed parts are set up again and again): batch, owner, pts, sliders, theta, ok, geometry."""
    designs = problem_sample(16, seed=4242, accept=F.prepare)
    models = [F.prepare(d) for d in designs]
    members = _largest_layout_group(models)
    batch = F.stack_models([models[i] for i in members])
    owner, pts, sliders, theta, ok = [], [], [], [], []
    for k, i in enumerate(members):
        p, _ = W.workspace_sample_weights(designs[i], **W.INTERFERENCE_SAMPLING)
        p = np.concatenate([p, [[0.5, 0.0, 0.0]]])  # and one unreachable point
        s, t, r = _joint_poses(designs[i], p)
        owner.append(np.full(len(p), k))
        pts.append(p), sliders.append(s), theta.append(t), ok.append(r)
    owner, pts, sliders, theta, ok = (np.concatenate(x) for x in (owner, pts, sliders, theta, ok))
    order = np.arange(len(owner))
    order[-300:] = order[-300:][np.random.default_rng(7).permutation(300)]  # the last two designs' poses mixed
    owner, pts, sliders, theta, ok = (x[order] for x in (owner, pts, sliders, theta, ok))
    assert len(np.unique(owner[-300:])) >= 2 and np.count_nonzero(np.diff(owner[-300:])) > 50
    return batch, owner, pts, sliders, theta, ok, _geometry([designs[i] for i in members])


def test_joint_kernel_equals_the_numpy_reference_on_the_cads_frames_bitwise(problem_sample, collision_reference):
    """check_joints' kernel builds the part frames itself from the joint values: its depths equal, bit for
    bit, the numpy reference's on cad.part_frames_arrays' frames of the same joint values, for every
    design of the largest layout group of 16 seeded designs within the problem bounds in one call
    (the last two designs' poses shuffled together, so a design's fixed parts are set up again and again), with colliding, shallow
    and free poses and an unreachable point."""
    batch, owner, pts, sliders, theta, ok, geo = _joint_problem(problem_sample)
    frames = cad_prrr.part_frames_arrays(geo.beta[owner], geo.d1[owner], geo.d2[owner], geo.d3[owner],
                                         geo.theta_1p[owner], sliders, theta, pts)
    ref = collision_reference.check_posed(batch, owner, pts, frames, ok)
    fast = F.check_joints(batch, owner, pts, sliders, theta, ok, geo)
    assert np.array_equal(_bits(fast.depth), _bits(ref.depth))
    assert np.array_equal(fast.collides, ref.collides) and np.array_equal(fast.reachable, ok)
    assert ref.collides.sum() > 100 and np.any((ref.depth > 0) & (ref.depth <= F.DEPTH_TOL))
    assert not ref.collides.all() and not ok.all()


def test_frame_rules_cover_the_cads_parts_and_nothing_else(paper):
    """Every part of cad.part_frames_arrays has a frame rule (its frame is built in the kernel); a part
    it does not know has none, and joint_tables refuses it."""
    specs = cad_prrr.part_specs(paper)
    rule, leg = F._frame_rules(tuple(specs))
    frames = cad_prrr.part_frames_arrays(paper.geometry.beta, 0.0, 0.0, 0.0, 0.0, np.zeros((1, 3)),
                                         np.zeros((1, 3, 3)), np.zeros((1, 3)))
    assert set(frames) == set(specs)
    assert [int(r) for r in rule[[list(specs).index(n) for n in ("base", "rail_2", "housing_3", "link1_1", "link2_2", "platform")]]] == [0, 0, 1, 2, 3, 4]
    assert int(leg[list(specs).index("carriage_3")]) == 2
    assert F._frame_rules(("base", "gizmo_1")) is None and F._frame_rules(("rail_4",)) is None
    assert F._frame_rules(("rail",)) is None and F._frame_rules(("platform_1",)) is None
    batch = F.stack_models([F.prepare(paper)])
    with pytest.raises(ValueError, match="no frame rule"):
        F.joint_tables(batch._replace(part_names=("gizmo_1",) + batch.part_names[1:]), _geometry([paper]))


def test_part_boxes_are_each_parts_primitive_extents_bitwise(problem_sample):
    """``_part_boxes`` (one ``ufunc.reduceat`` over the primitives grouped by part) equals the reference
    it replaced, a loop over the parts taking the min and max of each part's primitives' extents (min and
    max are exact, so the two agree bit for bit), on one design and on a stack of a layout's designs,
    with the primitives in part order and shuffled; a part without SOLID primitives gets the zero box."""

    def reference(batch):
        m, P = len(batch.R), len(batch.kind)
        ext = F._world_extent(np.tile(batch.kind, m), batch.R.reshape(-1, 3, 3),
                              batch.half.reshape(-1, 3)).reshape(m, P, 3)
        lo = np.full((m, len(batch.part_names), 3), np.inf)
        hi = np.full((m, len(batch.part_names), 3), -np.inf)
        for j in range(len(batch.part_names)):
            sel = batch.prim_part == j
            if sel.any():
                lo[:, j] = np.min(batch.o[:, sel] - ext[:, sel], axis=1)
                hi[:, j] = np.max(batch.o[:, sel] + ext[:, sel], axis=1)
        empty = ~np.isfinite(lo)
        lo[empty], hi[empty] = 0.0, 0.0
        return 0.5 * (lo + hi), 0.5 * (hi - lo)

    models = []
    for d in problem_sample(60, seed=47):
        try:
            models.append(F.prepare(d))
        except InvalidDesign:
            continue
    groups: dict = {}
    for m in models:
        groups.setdefault(F.layout_key(m), []).append(m)
    batches = [F.stack_models(g) for g in groups.values()] + [F.stack_models([m]) for m in models[:3]]
    # a part with no SOLID primitive: the last part's primitives moved to the one before it
    m0 = models[0]
    last = len(m0.part_names) - 1
    moved = F.stack_models([dataclasses.replace(m0, prim_part=np.where(m0.prim_part == last, last - 1,
                                                                         m0.prim_part))])
    # the primitives out of part order (the reduceat then runs on them sorted by part)
    perm = np.random.default_rng(5).permutation(len(m0.kind))
    shuffled = F.stack_models([dataclasses.replace(m0, prim_part=m0.prim_part[perm], kind=m0.kind[perm], R=m0.R[perm],
                                                   o=m0.o[perm], half=m0.half[perm])])
    assert len(models) >= 5
    for batch in batches + [moved, shuffled]:
        got, want = F._part_boxes(batch)[:2], reference(batch)
        for g, w in zip(got, want):
            assert g.shape == w.shape and np.array_equal(_bits(g), _bits(w))
    assert np.all(F._part_boxes(moved)[1][:, last] == 0.0)


def test_deepest_joints_are_check_joints_deepest_bitwise(problem_sample):
    """deepest_joints (the kernel keeping each pose's deepest overlap only) gives check_joints' collides and
    depth.max(axis=1) bit for bit."""
    batch, owner, pts, sliders, theta, ok, geo = _joint_problem(problem_sample)
    tables = F.joint_tables(batch, geo)
    ref = F.check_joints(batch, owner, pts, sliders, theta, ok, geo, tables=tables)
    hit, deepest = F.deepest_joints(owner, pts, sliders, theta, ok, tables)
    assert np.array_equal(hit, ref.collides)
    assert np.array_equal(_bits(deepest), _bits(ref.depth.max(axis=1)))
    assert ref.collides.any() and not ref.collides.all()


def test_joint_kernels_release_the_gil_and_run_in_two_threads_bitwise(problem_sample):
    """The kernel is compiled nogil and allocates its scratch itself: two threads checking the two
    halves of the poses at once (the split inside a design's run of poses) give bit for bit one call's
    results."""
    from concurrent.futures import ThreadPoolExecutor

    from hapticopt.analysis.prrr.collision import _interference_kernels as K
    assert F.availability() is None
    assert K.check_joint_poses.targetoptions.get("nogil") is True
    batch, owner, pts, sliders, theta, ok, geo = _joint_problem(problem_sample)
    tables = F.joint_tables(batch, geo)
    one = F.deepest_joints(owner, pts, sliders, theta, ok, tables)
    h = len(owner) // 2 + 7
    assert owner[h - 1] == owner[h]  # the split falls inside a run
    halves = [slice(0, h), slice(h, None)]
    with ThreadPoolExecutor(2) as pool:
        for _ in range(3):
            parts = list(pool.map(lambda s: F.deepest_joints(owner[s], pts[s], sliders[s], theta[s], ok[s], tables),
                                  halves))
            assert np.array_equal(np.concatenate([p[0] for p in parts]), one[0])
            assert np.array_equal(_bits(np.concatenate([p[1] for p in parts])), _bits(one[1]))


def test_pose_joints_are_the_array_iks_bitwise(problem_sample):
    """The compiled per-pose joint values (``pose_joints``: ``kinematics.make_ik`` over numba primitives) equal
    the numpy ``inverse_kinematics`` batch-first and ``joint_trig`` of its angles bit for bit, both elbow
    branches, on 6,000 seeded poses of 9 designs (owners in runs and interleaved; a subset of rows written)."""
    designs = problem_sample(9, seed=29)
    geo = {f: np.array([float(getattr(d.geometry, f)) for d in designs]) for f in F.IK_FIELDS}
    rng = np.random.default_rng(29)
    n = 6000
    owner = np.concatenate([np.sort(rng.integers(0, len(designs), n // 2)), rng.integers(0, len(designs), n // 2)])
    pts = rng.uniform(-0.06, 0.06, (n, 3))
    ik = inverse_kinematics(PrrrParams(*(geo[f][owner] for f in F.IK_FIELDS)), pts, xp=np)
    assert 0.2 < ik.reachable.mean() < 1.0  # both verdicts occur
    rows = np.flatnonzero(rng.random(n) < 0.7)
    for branch in (0, 1):
        out = (np.full((n, 3), np.nan),) + tuple(np.full((n, 3), np.nan) for _ in range(4)) + (np.zeros(n, bool),)
        F.pose_joints(rows, owner, pts, geo, branch, out)
        want = (ik.sliders,) + F.joint_trig(ik.theta[:, branch]) + (ik.reachable,)
        for got, ref in zip(out, want, strict=True):
            assert np.array_equal(_bits(got[rows]), _bits(ref[rows]))
        assert np.isnan(np.delete(out[0], rows, axis=0)).all()  # rows not asked for are not written

"""Tests of hapticopt.analysis.prrr.geometry.workspace (3-PRRR reach ∩ stroke workspace)."""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np
import pytest

from hapticopt.analysis.compute import Compute
from hapticopt.analysis.prrr import plots as prrr_plots
from hapticopt.analysis.prrr.geometry import workspace as W
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.prrr.kinematics import inverse_kinematics, leg_chain, params_of
from hapticopt.analysis.status import Status
from hapticopt.design import io
from hapticopt.design.prrr.params import PrrrDesign


@pytest.fixture(scope="module")
def paper() -> PrrrDesign:
    return io.load_preset("prrr-paper")


def with_geometry(design: PrrrDesign, **changes: float) -> PrrrDesign:
    return dataclasses.replace(design, geometry=dataclasses.replace(design.geometry, **changes))


def test_paper_inscribed_cylinder_matches_closed_form(paper: PrrrDesign) -> None:
    g = paper.geometry
    r = W.evaluate(paper, fidelity=Fidelity.DRAFT)
    m = r.metrics()
    assert r.status == Status.OK
    # seed digest (seed 002): the largest disc every leg reaches has radius d3 + d4 − d2 = 71.25 mm
    assert m["workspace_cylinder_diameter_mm"] == pytest.approx(142.5, abs=0.5)
    assert r.cylinder_diameter == pytest.approx(2.0 * (g.d3 + g.d4 - g.d2), rel=1e-12)
    # H = L − 2R cot β at R = 70 mm, L = 170 mm (seed digest; paper Table 1: φ140 × 89 mm)
    assert m["workspace_height_at_diameter_mm"] == pytest.approx(89.0, abs=0.5)
    assert r.height_at_required == pytest.approx(g.stroke - 0.140 / math.tan(g.beta), rel=1e-12)
    # max-volume cylinder: R* = min(R_reach, L tan β / 3); here R_reach = 71.25 mm < 98.1 mm
    assert r.cylinder_height == pytest.approx(g.stroke - 2.0 * 0.07125 / math.tan(g.beta), rel=1e-12)


def test_required_diameter_that_does_not_fit_gives_zero_height(paper: PrrrDesign) -> None:
    r = W.evaluate(paper, fidelity=Fidelity.DRAFT, required_diameter=0.150)  # > φ142.5 reach disc
    assert r.height_at_required == 0.0
    assert "does not fit" in r.message
    assert r.metrics()["workspace_required_diameter_mm"] == pytest.approx(150.0)


def test_cylinder_is_volume_optimal_when_stroke_binds(paper: PrrrDesign) -> None:
    # short stroke: L tan β / 3 < R_reach, so R* = L tan β / 3 (d/dR of R²(L − 2R cot β) = 0)
    d = with_geometry(paper, stroke=0.060)
    r = W.evaluate(d, fidelity=Fidelity.DRAFT)
    assert r.cylinder_diameter / 2.0 == pytest.approx(0.060 * math.tan(d.geometry.beta) / 3.0, rel=1e-12)
    assert r.cylinder_height == pytest.approx(0.060 / 3.0, rel=1e-12)


def _grid_volume(design: PrrrDesign, n: int) -> float:
    """Independent volume: midpoint xy grid, reach from the geometric IK (z-independent) and the
    z interval from its slider positions (slope 1 in z, eq 1)."""
    g = design.geometry
    P = params_of(design)
    ext = 0.2
    xs = (np.arange(n) + 0.5) / n * 2 * ext - ext
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=-1)
    ik = inverse_kinematics(P, jnp.asarray(pts))
    reach = np.asarray(ik.reach_ok).all(axis=-1)
    dev = np.asarray(ik.sliders) - g.c_e  # slider deviation at z = 0
    height = np.clip((g.stroke / 2 - dev).min(axis=-1) - (-g.stroke / 2 - dev).max(axis=-1), 0.0, None)
    return float(np.sum(np.where(reach, height, 0.0)) * (2 * ext / n) ** 2)


def test_volume_agrees_with_independent_ik_grid(paper: PrrrDesign) -> None:
    # the IK grid knows no joint limits: compare with the closed form without the fold margin
    wp = W.workspace_params(paper, rho_min=abs(paper.geometry.d3 - paper.geometry.d4))
    v = float(W.workspace_core(wp, n_phi=W.SAMPLING[Fidelity.FINE].n_phi, n_r=2)["volume"])
    v_grid = _grid_volume(paper, 500)
    assert v_grid == pytest.approx(v, rel=3e-3)  # grid: O(h) boundary error, h = 0.8 mm


def test_volume_converges_at_second_order(paper: PrrrDesign) -> None:
    # without the fold margin (the measurement of docs/workspace.md); its reach hole adds kinks
    # where the rays graze the hole (measured rate 1.41 with it)
    wp = W.workspace_params(paper, rho_min=abs(paper.geometry.d3 - paper.geometry.d4))
    ref = float(W.workspace_core(wp, n_phi=16384, n_r=2)["volume"])
    ns = np.array([24, 48, 96, 192])
    err = np.array([abs(float(W.workspace_core(wp, n_phi=int(n), n_r=2)["volume"]) - ref) for n in ns])
    rate = -np.polyfit(np.log(ns), np.log(err), 1)[0]
    # midpoint rule on a periodic integrand with kinks: O(n⁻²) (observed ≈ 2, docs/workspace.md)
    assert rate > 1.8
    assert err[-1] / ref < 1e-4


def test_sampled_points_are_reachable_by_ik(paper: PrrrDesign) -> None:
    pts = W.sample_points(W.workspace_params(paper), n_phi=16, n_r=8, n_z=4)
    assert len(pts) > 1000
    ik = inverse_kinematics(params_of(paper), jnp.asarray(pts))
    assert bool(np.all(np.asarray(ik.reachable)))


def test_outside_points_are_unreachable_by_ik(paper: PrrrDesign) -> None:
    """Points just beyond the cylinder's top/bottom and beyond the reach disc are not reachable."""
    g = paper.geometry
    r = W.evaluate(paper, fidelity=Fidelity.DRAFT)
    z0, z1 = W.cylinder_z_range(paper, r)
    R = r.cylinder_diameter / 2
    ang = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    ring = np.stack([R * np.cos(ang), R * np.sin(ang), np.zeros_like(ang)], axis=-1)
    P = params_of(paper)
    inside = inverse_kinematics(P, jnp.asarray(ring * (1 - 1e-9) + [0, 0, z1 * (1 - 1e-9)])).reachable
    assert bool(np.all(np.asarray(inside)))
    # the cylinder touches the stroke limit somewhere on its top rim and the reach edge somewhere on its side
    above = np.asarray(inverse_kinematics(P, jnp.asarray(ring + [0, 0, z1 + 1e-4])).reachable)
    outside = np.asarray(inverse_kinematics(P, jnp.asarray(ring * (1 + 1e-3))).reachable)
    assert not above.all() and not outside.all()
    assert g.stroke > 0


def test_jacobian_constancy_checked_at_fine(paper: PrrrDesign) -> None:
    r = W.evaluate(paper, fidelity=Fidelity.FINE, interference=False)
    assert r.condition_points > 500
    # the slider map is affine in p (eq 1), so central differences are exact up to rounding
    assert 0.0 <= r.metrics()["jacobian_condition_deviation"] < 1e-9
    assert "jacobian_condition_deviation" not in W.evaluate(paper, fidelity=Fidelity.DRAFT).metrics()


def test_footprint_covers_rails_and_links(paper: PrrrDesign) -> None:
    g, s = paper.geometry, paper.structure
    r = W.evaluate(paper, fidelity=Fidelity.STANDARD)
    # the device body: base plate, and the rail's outer face (closed form, a lower bound of the
    # part-table envelope); seed 002 Table 1: φ260, issue 15 acceptance ≤ 270 mm
    assert r.footprint_diameter >= 2 * max(s.base_radius, g.r_p + s.rail_width / 2)
    assert r.footprint_diameter <= 0.270
    # links' swept extent from the kinematics module's serial chain at sampled workspace points
    pts = W.sample_points(W.workspace_params(paper), n_phi=32, n_r=12, n_z=1)
    P = params_of(paper)
    ik = inverse_kinematics(P, jnp.asarray(pts))
    chain = leg_chain(P, ik.sliders, ik.theta[:, W.ELBOW_BRANCH])
    extent = max(np.linalg.norm(np.asarray(getattr(chain, k))[..., :2], axis=-1).max() for k in ("a", "b", "q"))
    fine = W.evaluate(paper, fidelity=Fidelity.FINE, interference=False).link_sweep_diameter
    assert fine >= 2 * (extent + s.boss_diameter / 2) - 1e-9 or fine == pytest.approx(
        2 * (extent + s.boss_diameter / 2), rel=2e-3)
    # sampling under-estimates a maximum: cheaper levels are within 2 % of fine and (up to the
    # samples' placement around the fold-margin hole, measured 0.004 %) below it
    assert r.link_sweep_diameter <= fine * (1 + 1e-4)
    assert r.link_sweep_diameter == pytest.approx(fine, rel=2e-2)
    assert r.footprint_ratio == pytest.approx(r.cylinder_diameter / r.footprint_diameter)


def _hard_cases(paper: PrrrDesign) -> dict[str, PrrrDesign]:
    g = paper.geometry
    # the z axis reaches the R1→R3 distance ρ0 = sqrt((c_u/sin β)² + d2²) = d2 when c_u = 0
    return {
        "beta_1deg": with_geometry(paper, beta=math.radians(1.0)),
        "beta_89deg": with_geometry(paper, beta=math.radians(89.0)),
        "barely_reaching": with_geometry(paper, d3=g.d2 / 2 + 0.0002, d4=g.d2 / 2 + 0.0002),
        "empty": with_geometry(paper, d3=g.d2 / 2 - 0.001, d4=g.d2 / 2 - 0.001),
        "unequal_links": with_geometry(paper, d3=0.100, d4=0.040),
    }


@pytest.mark.parametrize("fidelity", list(Fidelity))
def test_hard_cases_give_finite_metrics(paper: PrrrDesign, fidelity: Fidelity) -> None:
    for name, design in _hard_cases(paper).items():
        r = W.evaluate(design, fidelity=fidelity, interference=False)  # interference: see below
        for key, value in r.metrics().items():
            assert math.isfinite(value), (name, key)
            assert value >= 0.0, (name, key)
        if r.status in (Status.EMPTY, Status.NOT_ASSEMBLABLE):
            assert r.volume == 0.0 and r.cylinder_diameter == 0.0 and r.cylinder_height == 0.0


def test_hard_case_statuses(paper: PrrrDesign) -> None:
    cases = {k: W.evaluate(d, fidelity=Fidelity.STANDARD) for k, d in _hard_cases(paper).items()}
    assert cases["empty"].status == Status.NOT_ASSEMBLABLE  # d3 + d4 < d2 with c_u = 0: the chain cannot close
    assert cases["beta_1deg"].status == Status.NOT_ASSEMBLABLE  # ellipse semi-axis (d3+d4) sin 1° ≈ 2.8 mm
    tiny = cases["barely_reaching"]
    assert tiny.status == Status.NOT_MET  # computed (numbers below), but φ140 × 89 mm cannot fit in it
    # reach radius = d3 + d4 − d2 = 0.4 mm (seed digest closed form, c_u = 0)
    assert tiny.cylinder_diameter == pytest.approx(0.0008, rel=1e-9)
    # tiny: the region lies within ~1 mm of the axis, so V < L·(π·1 mm²) ≈ 5.3e-7 m³ (paper: 2.2e-3 m³)
    assert 0.0 < tiny.volume < paper.geometry.stroke * math.pi * 1e-6
    # workspaces that exist but whose reach radius (66.6 mm, 28.8 mm: the messages) is below the
    # required 70 mm: computed, the requirement not met (issue 21: no longer "ok")
    assert cases["beta_89deg"].status == Status.NOT_MET and cases["beta_89deg"].volume > 0
    assert cases["unequal_links"].status == Status.NOT_MET and cases["unequal_links"].volume > 0


def test_batch_equals_single(paper: PrrrDesign) -> None:
    rng = np.random.default_rng(4)
    designs = list(_hard_cases(paper).values()) + [paper]
    for _ in range(6):
        designs.append(with_geometry(paper, beta=math.radians(rng.uniform(20, 75)),
                                     d2=rng.uniform(0.05, 0.12), d3=rng.uniform(0.05, 0.12),
                                     d4=rng.uniform(0.05, 0.12), stroke=rng.uniform(0.05, 0.3)))
    for fidelity in (Fidelity.DRAFT, Fidelity.STANDARD):
        batch = W.evaluate_batch(designs, fidelity=fidelity)
        for d, b in zip(designs, batch):
            s = W.evaluate(d, fidelity=fidelity)
            assert b.status == s.status
            for f in ("volume", "reach_radius", "cylinder_diameter", "cylinder_height", "height_at_required",
                      "footprint_diameter"):
                x, y = getattr(s, f), getattr(b, f)
                assert abs(x - y) <= 1e-12 * max(abs(x), 1e-3), (d.geometry, f, x, y)


def test_plot_writes_png(paper: PrrrDesign, tmp_path) -> None:
    r = W.evaluate(paper, fidelity=Fidelity.DRAFT)
    files = prrr_plots.workspace_plots(paper, r, tmp_path)
    assert [f.name for f in files] == ["prrr-paper_workspace.png"]
    assert files[0].stat().st_size > 10_000


def test_elbow_branch_is_the_cads() -> None:
    from hapticopt.design.prrr import cad as cad_prrr

    assert W.ELBOW_BRANCH == cad_prrr.DEFAULT_BRANCH


def test_interference_aware_workspace_is_a_subset(paper: PrrrDesign, monkeypatch) -> None:
    small = dict(n_phi=2, n_r=2, n_z=2)  # 24 poses (the fine level uses 216)
    pts, w, free = W.interference_samples(paper, **small)
    assert len(pts) == 24 and np.all(w > 0)
    # the volume weights are a quadrature of the same workspace (coarse: within 15 %)
    reach_only = W.evaluate(paper, fidelity=Fidelity.STANDARD)
    assert w.sum() == pytest.approx(reach_only.volume, rel=0.15)
    monkeypatch.setattr(W, "INTERFERENCE_SAMPLING", small)
    r = W.evaluate(paper, fidelity=Fidelity.STANDARD, interference=True)
    removed = float(w[~free].sum() / w.sum())
    assert r.interference_removed == pytest.approx(removed, rel=1e-12)
    assert 0.0 <= r.volume <= reach_only.volume
    assert r.volume == pytest.approx(reach_only.volume * (1 - removed), rel=1e-12)
    assert r.metrics()["workspace_interference_removed_fraction"] == pytest.approx(removed)
    # every interference-free pose is reachable (subset of the reach-only workspace)
    ik = inverse_kinematics(params_of(paper), jnp.asarray(pts[free]))
    assert bool(np.all(np.asarray(ik.reachable)))


def test_required_cylinder_that_does_not_fit_is_not_met(paper: PrrrDesign) -> None:
    # issue 21: "workspace: ok — a cylinder of diameter 140 mm does not fit". d3 = d4 = 60 mm: the
    # reach radius (31.25 mm, the message) is below 70 mm, so H(φ140) = 0 < 89 mm (seed 002 Table 1)
    r = W.evaluate(io.apply_overrides(paper, ["geometry.d3_mm=60", "geometry.d4_mm=60"]))
    assert r.status == Status.NOT_MET and r.height_at_required == 0.0
    assert "φ140 × 89 mm cylinder does not fit" in r.message
    assert r.metrics()["workspace_volume_mm3"] > 0  # numbers kept: the optimiser steers on them
    # the height requirement alone: prrr-paper's H(φ140) = L − 140 mm·cot β = 89.17 mm (closed form) holds
    # 89 mm and misses 90 mm
    ok = W.evaluate(paper)
    assert ok.height_at_required == pytest.approx(0.170 - 0.140 / math.tan(math.radians(60)), rel=1e-12)
    assert ok.status == Status.OK
    assert W.evaluate(paper, required_height=0.090).status == Status.NOT_MET


def test_workspace_params_many_equal_workspace_params_bitwise(problem_sample):
    """One table for many designs (the batched draft evaluator's) gives each design's
    :func:`workspace_params` bit for bit (same operations per value; the envelope given)."""
    designs = problem_sample(12, seed=33)
    env = np.linspace(0.12, 0.2, len(designs))
    rows = W.workspace_params_many(designs, env)
    for d, e, row in zip(designs, env, rows, strict=True):
        want = W.workspace_params(d, envelope=float(e))
        assert type(row) is W.WorkspaceParams
        for a, b in zip(row, want, strict=True):
            assert np.float64(a).tobytes() == np.float64(b).tobytes()


def test_workspace_sample_weights_many_equal_the_per_design_function_bitwise(problem_sample):
    """The interference samples of many designs in one pass (the batched draft evaluator's) equal
    :func:`workspace_sample_weights` design by design bit for bit, points and weights, on a seeded
    sample within the bundled problem's bounds and hard cases (no workspace; β near 0 and 90 deg;
    a short stroke that leaves few columns)."""
    base = io.load_preset("prrr-paper")

    def geo(**kw):
        return dataclasses.replace(base, geometry=dataclasses.replace(base.geometry, **kw))

    designs = problem_sample(40, seed=34) + [base, geo(stroke=1e-4), geo(beta=math.radians(89.999999)),
                                             geo(beta=math.radians(1e-6)), geo(stroke=0.02)]
    wps = [W.workspace_params(d) for d in designs]
    many = W.workspace_sample_weights_many(designs, wps, **W.INTERFERENCE_SAMPLING)
    sizes = []
    for d, wp, (pts, w) in zip(designs, wps, many, strict=True):
        p0, w0 = W.workspace_sample_weights(d, **W.INTERFERENCE_SAMPLING, wp=wp)
        assert pts.shape == p0.shape and pts.tobytes() == p0.tobytes()
        assert w.shape == w0.shape and w.tobytes() == w0.tobytes()
        sizes.append(len(pts))
    assert 0 in sizes and max(sizes) == 3 * 6 * 4 * 3  # an empty sample and a full one are covered
    assert W.workspace_sample_weights_many([], [], **W.INTERFERENCE_SAMPLING) == []


def test_result_rows_give_the_results_of_each_row():
    # reference: _result on each design's own numpy workspace_core (the single path's conversion);
    # rows: the preset (ok), a stroke too short (not-met), d2 = 300 mm (empty), seeded layouts
    base = io.load_preset("prrr-paper")
    g = base.geometry
    rng = np.random.default_rng(4)
    designs = [base, dataclasses.replace(base, geometry=dataclasses.replace(g, stroke=0.05)),
               dataclasses.replace(base, geometry=dataclasses.replace(g, d2=0.300))]
    designs += [dataclasses.replace(base, geometry=dataclasses.replace(g, d3=g.d3 * rng.uniform(0.8, 1.2)))
                for _ in range(4)]
    cores = [W.workspace_core(W.workspace_params(d), n_phi=48, n_r=8, xp=np) for d in designs]
    stacked = {k: np.stack([np.asarray(c[k]) for c in cores]) for k in cores[0]}
    statuses = set()
    for core, vals in zip(cores, W.result_rows(stacked)):
        ref = W._result(core, 0.07, Fidelity.DRAFT)
        assert W._result_of(vals, 0.07, Fidelity.DRAFT) == ref
        statuses.add(ref.status)
    assert statuses == {Status.OK, Status.NOT_MET, Status.EMPTY}


def _link_extent_by_angles(wp: W.WorkspaceParams, n_phi: int, n_r: int) -> float:
    # reference: the links' swept extent with the joint angles themselves (two-link IK:
    # θ2 = ±arccos c2, θ1 = atan2(ρt, ρv) − atan2(d4 sin θ2, d3 + d4 cos θ2)) over workspace_core's own
    # samples (its ray intervals and radii); workspace_core takes θ1's and θ1 + θ2's cosines and sines
    # through the angle-difference formulas instead
    phi = (np.arange(n_phi) + 0.5) * (W._THIRD / n_phi)
    _, _, _, lo, hi, holes = W._ray_intervals(wp, phi, np)
    r = lo[:, None] + np.linspace(0.0, 1.0, n_r)[None, :] * (hi - lo)[:, None]
    mask = (hi > lo)[:, None] & ~W._in_hole(r, holes, np)
    s, cu = np.sin(wp.beta), W._c_u(wp, np)
    ang = phi[:, None, None] - W._GAMMA
    rv, rt = (r[..., None] * np.cos(ang) - cu) / s, r[..., None] * np.sin(ang) - wp.d2
    c2 = (rv**2 + rt**2 - wp.d3**2 - wp.d4**2) / (2.0 * wp.d3 * wp.d4)
    th2 = (1.0 - 2.0 * W.ELBOW_BRANCH) * np.arccos(np.clip(c2, -1.0, 1.0))
    th1 = np.arctan2(rt, rv) - np.arctan2(wp.d4 * np.sin(th2), wp.d3 + wp.d4 * np.cos(th2))
    bu, bt = wp.d1 + wp.d3 * np.cos(th1) * s, wp.d2 + wp.d3 * np.sin(th1)
    qu = bu + wp.d4 * np.cos(th1 + th2) * s - wp.r4 * np.cos(wp.beta)
    qt = bt + wp.d4 * np.sin(th1 + th2)
    radius = np.maximum(np.hypot(bu, bt), np.hypot(qu, qt))
    extent = max(np.max(np.where(mask[..., None], radius, 0.0)), math.hypot(wp.d1, wp.d2))
    return float(extent + wp.boss_radius)


@pytest.mark.parametrize("fidelity", [Fidelity.DRAFT, Fidelity.STANDARD])
def test_link_extent_equals_the_joint_angle_route(paper: PrrrDesign, fidelity: Fidelity) -> None:
    # the preset and the hard cases (β near 0 and 90°, barely reaching, empty, unequal links);
    # rounding-level agreement (measured ≤ 3.3e-16 relative on 1024 designs around the preset)
    smp = W.SAMPLING[fidelity]
    for design in [paper, *_hard_cases(paper).values()]:
        wp = W.workspace_params(design)
        got = float(W.workspace_core(wp, n_phi=smp.n_phi, n_r=smp.n_r, xp=np)["link_extent"])
        assert got == pytest.approx(_link_extent_by_angles(wp, smp.n_phi, smp.n_r), rel=1e-13, abs=0)


def _closure_sample(problem_sample) -> list:
    """Designs that close (the preset, most of the problem's sample), that do not (d2 = 300 mm: |ρ| ≥
    300 mm > d3 + d4 everywhere; β = 1e-12 deg) and that have almost no workspace (stroke 0.1 mm)."""
    base = io.load_preset("prrr-paper")
    g = base.geometry
    odd = [dataclasses.replace(base, geometry=dataclasses.replace(g, **kw))
           for kw in ({"d2": 0.300}, {"stroke": 1e-4}, {"beta": math.radians(1e-12)}, {"beta": math.radians(89.999999)})]
    return [base, *odd, *problem_sample(40, seed=2203)]


def _numpy_closure(design) -> str:
    """The reference: the numpy workspace core of one design, uncached (``closure``'s own rule)."""
    return W._closure_message(design) if W._closure_empty(design) else ""


def test_closure_batch_equals_the_numpy_closure(problem_sample):
    designs = _closure_sample(problem_sample)
    ref = [_numpy_closure(d) for d in designs]
    assert W.closure_batch(designs) == ref
    assert "" in ref and any(ref)  # designs that close and designs that do not


def test_closure_many_remembers_the_batch_for_closure(problem_sample, monkeypatch):
    designs = _closure_sample(problem_sample)
    ref = [_numpy_closure(d) for d in designs]
    monkeypatch.setattr(W, "_closures", {})
    assert W.closure_many(designs + designs[:3]) == ref + ref[:3]  # a design twice: once in the pass

    def numpy_again(design):
        raise AssertionError("closure recomputed a design closure_many passed")

    monkeypatch.setattr(W, "_closure_empty", numpy_again)
    assert [W.closure(d) for d in designs] == ref


def test_closure_many_of_a_few_designs_takes_the_numpy_path(monkeypatch):
    base = io.load_preset("prrr-paper")
    few = [dataclasses.replace(base, geometry=dataclasses.replace(base.geometry, d3=base.geometry.d3 * f))
           for f in (0.9, 1.0, 1.1)]
    monkeypatch.setattr(W, "_closures", {})
    monkeypatch.setattr(W, "closure_batch", lambda designs: pytest.fail("a jitted pass for fewer than "
                                                                         "CLOSURE_BATCH_AFTER designs"))
    assert W.closure_many(few) == [_numpy_closure(d) for d in few] == ["", "", ""]


def test_closure_many_route_follows_the_call_not_the_memo(problem_sample, monkeypatch):
    """A call of many designs takes the jitted pass even when the memo holds some of them (the route is
    the call's, not the process's), and takes numpy one by one when its Compute says numpy."""
    designs = _closure_sample(problem_sample)
    ref = [_numpy_closure(d) for d in designs]
    monkeypatch.setattr(W, "_closures", {})
    W.closure_many(designs[:3])  # remembered: the memo now holds three of them
    passed = []
    real = W.closure_batch
    monkeypatch.setattr(W, "closure_batch", lambda ds: passed.extend(ds) or real(ds))
    assert W.closure_many(designs) == ref and passed == list(dict.fromkeys(designs))
    monkeypatch.setattr(W, "_closures", {})
    monkeypatch.setattr(W, "closure_batch", lambda ds: pytest.fail("a jitted pass with Compute numpy"))
    assert W.closure_many(designs, compute=Compute(backend="numpy")) == ref


def test_closure_cache_drops_the_oldest_design(monkeypatch):
    base = io.load_preset("prrr-paper")
    designs = [dataclasses.replace(base, geometry=dataclasses.replace(base.geometry, stroke=0.1 + 1e-3 * k))
               for k in range(3)]
    monkeypatch.setattr(W, "_closures", {})
    monkeypatch.setattr(W, "CLOSURE_CACHE", 2)
    for d in designs:
        W.closure(d)
    assert list(W._closures) == designs[1:]


def test_scalar_newton_steps_equal_the_array_form_bitwise(problem_sample):
    """One design's reach radius with numpy scalars (``_newton_scalar``: Python conditionals for
    ``where``/``clip``/``abs``) equals the array form of ``_edge_distance`` (the same parameters as
    one-element arrays, which take numpy's ``where`` and ``clip``) bit for bit, at the outer and inner
    reach radii of draws within the problem's bounds, the preset and its closure parameters."""
    designs = problem_sample(40, seed=35) + [io.load_preset("prrr-paper")]
    n = 0
    for d in designs:
        for wp in (W.workspace_params(d, envelope=0.1), W._closure_params(d)):
            one = W.WorkspaceParams(*(np.array([float(v)]) for v in wp))
            for rho, rho1 in ((wp.rho_max, one.rho_max), (wp.rho_min, one.rho_min)):
                got = W._edge_distance(wp, rho, np)
                want = W._edge_distance(one, rho1, np)
                assert np.ndim(got) == 0 and want.shape == (1,)
                assert np.float64(got).tobytes() == want[0].tobytes()
                n += 1
    assert n == 4 * len(designs)


def test_device_diameter_is_the_body_or_the_link_sweep():
    """Issue 30 item 3: the device's diameter counts what the links sweep. prrr-paper's links sweep beyond its
    body (the issue measured 367.2 mm against a 267 mm footprint at standard fidelity), so the device diameter
    is the sweep; the collision-free ratio over it is the free cylinder over that diameter."""
    from hapticopt.analysis.registry import evaluate_all

    m = evaluate_all(io.load_preset("prrr-paper"), fidelity="standard", only=("workspace", "free_workspace")).metrics()
    assert m["device_diameter_mm"] == max(m["footprint_diameter_mm"], m["link_sweep_diameter_mm"])
    assert m["link_sweep_diameter_mm"] > m["footprint_diameter_mm"] + 90.0
    assert m["workspace_free_device_ratio"] == pytest.approx(
        m["workspace_free_cylinder_diameter_mm"] / m["device_diameter_mm"], rel=1e-12)
    assert m["workspace_free_device_ratio"] < m["workspace_free_footprint_ratio"]

"""Seed 003 as the paper describes it (issue 16): master-paper's mass data against eq 7/12, the
counterweight lesson under the paper's controller, the time-domain protocol against the
frequency-domain evaluator, the exported MJCF's gravity torques, and the hard cases."""

from __future__ import annotations

import dataclasses

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np
import pytest
from scipy.optimize import brentq

from hapticopt.analysis.master import balance as mb
from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master import transparency as mt
from hapticopt.analysis.status import Status
from hapticopt.design.io import load_preset
from hapticopt.design.units import GRAVITY

# seed 003 eq 7/12: a = 66.7, b = 10.3 (N·mm, G space); semi-axes in CoM space 5.24 and 0.81 mm
PAPER_A_NMM, PAPER_B_NMM = 66.7, 10.3
PAPER_LONG_MM, PAPER_SHORT_MM = 5.24, 0.81


@pytest.fixture(scope="module")
def design():
    return load_preset("master-paper")


@pytest.fixture(scope="module")
def balance(design):
    return mb.evaluate(design)


def test_moving_mass_is_the_papers(balance):
    # M = a / (g · 5.24 mm) (eq 7 and eq 12 describe the same ellipse in G and in CoM space)
    M = PAPER_A_NMM * 1e-3 / (GRAVITY * PAPER_LONG_MM * 1e-3)
    assert balance.moving_mass == pytest.approx(M, rel=0.01)
    assert PAPER_B_NMM * 1e-3 / (GRAVITY * M) * 1e3 == pytest.approx(PAPER_SHORT_MM, rel=0.01)  # the paper is consistent


def test_unbalance_ellipse_short_axis_and_tilt(balance):
    # short semi-axis 0.81 mm ± 10 % (eq 12); the exact unbalance radius is that short semi-axis (L4 = L5)
    assert balance.ellipse_axes[1] * 1e3 == pytest.approx(PAPER_SHORT_MM, rel=0.10)
    assert balance.radius * 1e3 == pytest.approx(PAPER_SHORT_MM, rel=0.10)
    # tilt 45° ± 5° (the paper: "40°–45°", fitted at 45°): the free-tilt moment ellipse of the exact region
    assert np.rad2deg(balance.fit_tilt) == pytest.approx(45.0, abs=5.0)
    assert balance.status is Status.OK


def test_papers_long_axis_is_not_reachable_by_the_exact_region(design):
    """The exact region's aspect (long/short extent along the diagonals) depends on L4/L5 only; over
    L4/L5 ∈ [0.4, 2.5] it stays below 3.7, so the paper's 5.24/0.81 = 6.47 (from its approximate eq 6)
    cannot be met together with 0.81 mm: documented in docs/master.md, not forced."""
    ws = mb.workspace_of(design)
    T, P = np.meshgrid(np.linspace(*ws.theta3, 121), np.linspace(*ws.phi, 121), indexing="ij")
    d1, d2 = np.array([1.0, 1.0]) / np.sqrt(2), np.array([1.0, -1.0]) / np.sqrt(2)
    ratios = []
    for L4 in np.linspace(0.4, 2.5, 15):
        A = mb.unbalance_maps(1.0, L4, 1.0, T.ravel(), P.ravel())
        e1 = 1 / np.max(np.linalg.norm(A @ d1, axis=-1))
        e2 = 1 / np.max(np.linalg.norm(A @ d2, axis=-1))
        ratios.append(max(e1, e2) / min(e1, e2))
    assert max(ratios) < 3.7 < PAPER_LONG_MM / PAPER_SHORT_MM


def _on_radius(design, balance):
    """master-paper with both counterweights scaled by one factor s < 1 so that |P| = unbalance radius."""
    cw = design.counterweights

    def with_scale(s):
        return dataclasses.replace(design, counterweights=dataclasses.replace(
            cw, upper_mass=s * cw.upper_mass, forearm_mass=s * cw.forearm_mass))

    def offset(s):
        return np.hypot(*md.gravity_parameters(md.model_of(with_scale(s))).com_offset)

    s = brentq(lambda s: offset(s) - balance.radius, 0.0, 1.0, xtol=1e-12)
    return with_scale(s), s


def test_lighter_counterweights_raise_bandwidth_on_both_axes(design, balance):
    """Seed 003's lesson under its controller (links compensated, no gravity compensation): the CoM on
    the unbalance radius by lighter counterweights raises the bandwidth on both axes by ≥ +4.5 %
    (half the paper's +9.3 %); the unbalance force stays at the 0.1 N threshold."""
    light, s = _on_radius(design, balance)
    assert s < 1.0
    b0 = np.array(mt.evaluate(design).bandwidth)
    b1 = np.array(mt.evaluate(light).bandwidth)
    assert np.all(b1 / b0 >= 1.045), (b0, b1)
    b = mb.evaluate(light)
    assert np.hypot(*b.com_offset) == pytest.approx(balance.radius, rel=1e-9) and b.max_force <= 0.1 + 1e-12
    # open-loop rendering: the same counterweights change the bandwidth by < 1 % (why the reading matters)
    ol = mt.RenderingSetup(compensation=mt.OPEN_LOOP)
    o0, o1 = np.array(mt.evaluate(design, setup=ol).bandwidth), np.array(mt.evaluate(light, setup=ol).bandwidth)
    assert np.all(np.abs(o1 / o0 - 1) < 0.01)


@pytest.mark.parametrize("scene_name", ["master-protocol-x", "master-protocol-z"])
def test_time_domain_protocol_matches_frequency_domain(design, scene_name):
    """Seed 003's protocol (7.5 sin(2πt) mm, 3 s, 0.05 N/mm) in MuJoCo with the firmware's compensation
    mode: |G_T| at 1 Hz within 5 % of the frequency-domain evaluator's."""
    from hapticopt.analysis.loop.scene import load_scene
    from hapticopt.analysis.master.mujoco_plant import simulate

    r = simulate(design, load_scene(scene_name))
    assert r.status is Status.OK, r.message
    assert r.measures["transparency_gain_error_pct"] <= 5.0


def test_exported_mjcf_holds_the_dynamics_gravity_torque(design):
    """Joint torques that hold random poses in the MJCF (Sᵀ qfrc_bias) equal G(q) of the dynamics to
    1e-9 N·m; for the balanced master-paper they are ≤ 1e-9 N·m. Joint ranges and motors are present."""
    import mujoco

    from hapticopt.design.master.mjcf import REDUCTION, full_qpos, master_mjcf
    from hapticopt.analysis.master import dynamics_numpy as mn

    rng = np.random.default_rng(16)
    j = design.joints
    t3 = rng.uniform(j.theta3_min, j.theta3_max, 8)
    ph = rng.uniform(j.parallelogram_min, j.parallelogram_max, 8)
    Q = np.stack([rng.uniform(j.theta1_min, j.theta1_max, 8), 0.5 * np.pi + t3 - ph, t3], -1)
    unbalanced = dataclasses.replace(design, counterweights=dataclasses.replace(design.counterweights, upper_mass=0.02))
    for d in (design, unbalanced):
        m = mujoco.MjModel.from_xml_string(master_mjcf(d))
        data = mujoco.MjData(m)
        G_ref = mn.gravity_torque(md.model_of(d), Q)
        for q, g in zip(Q, G_ref):
            data.qpos[:] = full_qpos(q)
            data.qvel[:] = 0.0
            mujoco.mj_forward(m, data)
            G = REDUCTION.T @ data.qfrc_bias
            np.testing.assert_allclose(G, g, atol=1e-9, rtol=0)
            if d is design:
                assert np.max(np.abs(G)) <= 1e-9
    m = mujoco.MjModel.from_xml_string(master_mjcf(design))
    assert m.nu == 3 and all(m.jnt_limited[m.joint(n).id] for n in ("theta1", "theta3", "forearm_rel"))
    np.testing.assert_allclose(m.jnt_range[m.joint("theta3").id], (j.theta3_min, j.theta3_max))
    total = sum(b.mass for b in md.analytic_mass_properties(design))
    assert float(np.sum(m.body_mass)) == pytest.approx(total, abs=1e-9)


# ------------------------------------------------------------------------------------------ hard cases
def test_zero_counterweight_mass_and_distance_give_finite_metrics(design):
    for cw in (dataclasses.replace(design.counterweights, upper_mass=0.0, forearm_mass=0.0),
               dataclasses.replace(design.counterweights, upper_distance=0.0, forearm_distance=0.0)):
        d = dataclasses.replace(design, counterweights=cw)
        b, t = mb.evaluate(d), mt.evaluate(d)
        assert np.all(np.isfinite(list(b.metrics()["unbalance_ellipse_fit_mm"]) + [b.max_force, b.radius]))
        assert np.all(np.isfinite(t.bandwidth)) and t.status is Status.OK
        assert b.max_force > 0.1 and not b.inside  # unbalanced: the status of the constraint is the number


def test_com_exactly_on_the_boundary(design, balance):
    # P = r·(worst direction): the force reaches the threshold exactly (r = T / max σ_max(A))
    P = balance.radius * np.asarray(balance.worst_direction)
    mu, mf = md.counterweights_for_com_offset(design, tuple(P))
    d = dataclasses.replace(design, counterweights=dataclasses.replace(design.counterweights, upper_mass=mu,
                                                                          forearm_mass=mf))
    b = mb.evaluate(d)
    assert b.max_force == pytest.approx(0.1, rel=2e-3) and np.isfinite(b.radius)  # r moves with M (r ∝ 1/M)
    assert np.hypot(*b.com_offset) == pytest.approx(b.radius, rel=2e-3)  # r moves with M
    t = mt.evaluate(d)
    assert t.status is Status.OK and np.all(np.isfinite(t.bandwidth))


@pytest.mark.parametrize("eps", [1e-3, 1e-7, 0.0])
def test_pose_at_the_parallelogram_singularity_gives_a_clear_status(design, eps):
    # cos(θ2 − θ3) → 0: θ2 = θ3 + 90° − eps
    q = np.array([0.0, np.deg2rad(-20.0) + 0.5 * np.pi - eps, np.deg2rad(-20.0)])
    r = mt.evaluate(design, pose=q)
    if r.status is Status.OK:
        assert np.all(np.isfinite(r.bandwidth))
    else:  # a named status, never a number presented as valid (issue 14: metrics NaN when not ok)
        assert r.status in (Status.SINGULAR, Status.ILL_CONDITIONED) and "condition" in r.message
        assert np.all(np.isnan(r.bandwidth))


# ------------------------------------------------------------------------------------- the optimiser
def _snapshot():
    import json
    from pathlib import Path

    return json.loads((Path(__file__).parents[2] / "snapshots" / "master_transparency_optimum.json").read_text())


def _optimum(design):
    c = _snapshot()["counterweights"]
    cw = dataclasses.replace(design.counterweights, upper_mass=c["upper_mass_kg"],
                             upper_distance=c["upper_distance_mm"] * 1e-3, forearm_mass=c["forearm_mass_kg"],
                             forearm_distance=c["forearm_distance_mm"] * 1e-3)
    return dataclasses.replace(design, counterweights=cw)


def test_problem_optimises_counterweight_masses_and_positions_and_verifies_in_two_scenes():
    from hapticopt.optim.problem import load_problem

    p = load_problem("master-transparency")
    keys = {v.key for v in p.variables}
    assert keys == {"counterweights.upper_mass_kg", "counterweights.upper_distance_mm",
                    "counterweights.forearm_mass_kg", "counterweights.forearm_distance_mm"}
    assert p.objective.metric.text == "transparency_bandwidth_min_Hz"
    assert {c.metric.text for c in p.constraints} == {"max_unbalance_force_N", "workspace_coverage"}
    assert set(p.scenes) == {"master-transparency", "master-wall"}


def test_optimum_is_lighter_than_balance_faster_on_both_axes_and_inside_the_constraint(design):
    """The recorded optimum (labelled snapshot, scripts/master_transparency_optimum.py from the bundled
    command): counterweights lighter than balance at their own distances, both bandwidths ≥ master-paper's
    (balanced), the recorded objective and unbalance reproduced by the evaluators to 1e-9, the unbalance
    ≤ 0.1 N. The constraint is not active (0.0839 N, 16 % inside): the ISRES points near the 0.1 N
    boundary are sparse and the COBYLA polish converges to an infeasible point (0.134 N), so the best
    feasible point is ISRES's (docs/master.md)."""
    snap = _snapshot()
    opt = _optimum(design)
    mu, mf = md.balancing_counterweights(opt)
    assert opt.counterweights.upper_mass < mu and opt.counterweights.forearm_mass < mf
    b = mb.evaluate(opt)
    assert b.max_force == pytest.approx(snap["max_unbalance_force_N"], rel=1e-9)
    assert b.max_force <= 0.1
    bw = np.array(mt.evaluate(opt).bandwidth)
    assert min(bw) == pytest.approx(snap["objective_Hz"], rel=1e-9)
    assert np.all(bw >= np.array(mt.evaluate(design).bandwidth))


def test_bundled_command_reproduces_its_recorded_run_at_a_reduced_budget():
    """Issue 31: the bundled problem, seeded (GN_ISRES seed 1), run at 20 evaluations asks exactly the
    first 14 search points of the recorded full run (20 × GLOBAL_SHARE 0.7) and gets the same values
    (1e-9): the optimum in the snapshot and docs/master.md is what the command yields. No wall-clock
    limit can cut it short (max_time_s is a day; the evaluation budget ends the run)."""
    from hapticopt.optim import driver
    from hapticopt.optim.problem import load_problem

    snap = _snapshot()
    p = load_problem("master-transparency")
    assert p.optimiser.max_time_s >= 86400
    res = driver.run(p.with_optimiser(max_evals=20), only=("workspace", "balance", "transparency"))
    search = [r for r in res.history if r.stage == "search"]
    assert len(search) == len(snap["search_prefix"]) == 14
    for rec, (x, vals) in zip(search, snap["search_prefix"]):
        np.testing.assert_allclose(rec.x, x, rtol=1e-12)
        np.testing.assert_allclose([rec.objective, rec.metrics["max_unbalance_force_N"],
                                    rec.metrics["workspace_coverage"]], vals, rtol=1e-9)


def test_optimum_passes_its_verification_scenes(design):
    from hapticopt.analysis.loop.scene import load_scene
    from hapticopt.analysis.master.mujoco_plant import simulate

    opt = _optimum(design)
    for name in ("master-transparency", "master-wall"):
        r = simulate(opt, load_scene(name))
        assert r.status is Status.OK, (name, r.message)
        if name == "master-transparency":  # time-domain sweep vs the frequency-domain evaluator
            assert r.measures["bandwidth_error_pct"] <= 5.0

"""Tests of analysis/control/impedance_learning.py (seed 001 section 2 and §4.1)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hapticopt.analysis.loop import operator as op_mod
from hapticopt.analysis.control import impedance_learning as il

# Seed 001 eq 27, 29: the section 4.1 problem.
A29 = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 0.0], [40.0, 0.0, -10.0]])
B29 = np.array([[0.0], [1.0], [0.0]])
Q27 = np.eye(3)
R27 = np.array([[0.01]])
K0_31 = np.array([[10.0, 4.0, 0.2]])  # eq 31
X0 = np.array([-0.4, 0.0, 0.0])  # x_r(0) = 0, x_d = +0.4 m (square wave, §4.1)


def _learn(noise, *, n_intervals=50, substeps=10, a=A29, b=B29, **kw):
    data = il.collect_data(a, b, K0_31, noise, X0, duration=0.5, n_intervals=n_intervals,
                           substeps=substeps)
    return data, il.policy_iteration(data, K0_31, Q27, R27, **kw)


@pytest.fixture(scope="module")
def outer():
    return il.simulate_outer_loop(il.OuterLoopConfig())


def test_riccati_optimum_eq30_and_impedance_eq33():
    """Seed 001 eq 30: P* and K* to 4 decimals; eq 33: M*, B*, K* (the paper derives eq 33 from
    K_7 of eq 32, which differs from K* in the 5th digit, hence rel 1e-4)."""
    opt = il.riccati_optimum(A29, B29, Q27, R27)
    p30 = np.array([[4.7958, 0.3830, 0.1708], [0.3830, 0.1329, 0.0073], [0.1708, 0.0073, 0.0497]])
    k30 = np.array([[38.2969, 13.2889, 0.7335]])
    np.testing.assert_allclose(opt.p, p30, rtol=0, atol=0.5e-4)
    np.testing.assert_allclose(opt.k, k30, rtol=0, atol=0.5e-4)
    # the Riccati residual itself (closed form check, not a paper number)
    res = A29.T @ opt.p + opt.p @ A29 - opt.p @ B29 @ np.linalg.solve(R27, B29.T) @ opt.p + Q27
    assert np.abs(res).max() < 1e-10
    np.testing.assert_allclose([opt.mass, opt.damping, opt.stiffness],
                               [1.3632, 18.1150, 52.2048], rtol=1e-4)


def test_exploration_noise_eq28_as_printed():
    """Seed 001 eq 28 as printed: Σ_j (0.05/j) sin(100 t) = 0.05·H_10·sin(100 t)."""
    t = np.linspace(0.0, 0.5, 101)
    h10 = sum(1.0 / j for j in range(1, 11))
    np.testing.assert_allclose(il.ExplorationNoise.printed()(t), 0.05 * h10 * np.sin(100 * t),
                               atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_policy_iteration_reaches_riccati_optimum(seed):
    """Seed 001 eq 9 / Fig 8 / eq 32: from K_0 = [10, 4, 0.2] (eq 31), 0.5 s of data on 50
    intervals of a seeded random multi-sine, ‖K − K*‖/‖K*‖ ≤ 1e-4 within 10 iterations (paper: 7
    iterations, K_7 of eq 32)."""
    _, res = _learn(il.ExplorationNoise.multisine(seed))
    k_star = il.riccati_optimum(A29, B29, Q27, R27).k
    assert res.status is il.LearningStatus.OK, res.message
    assert res.iterations <= 10
    assert res.rank == 9
    assert np.linalg.norm(res.k - k_star) / np.linalg.norm(k_star) <= 1e-4
    np.testing.assert_allclose(res.p, il.riccati_optimum(A29, B29, Q27, R27).p, rtol=1e-4)


def test_multisine_is_varied_and_seeded():
    """The seeded multi-sine: eq 28's amplitudes 0.05/j, ten distinct frequencies inside the band
    (not eq 28's single 100 rad/s), phases in [0, 2π); the same seed gives the same signal, another
    seed another one; a band with low ≥ high is refused."""
    a, b = il.ExplorationNoise.multisine(3), il.ExplorationNoise.multisine(4)
    assert a == il.ExplorationNoise.multisine(3) and a != b
    np.testing.assert_allclose(a.amplitudes, [0.05 / j for j in range(1, 11)])
    lo, hi = il.MULTISINE_BAND
    assert len(set(a.frequencies)) == 10 and all(lo <= w <= hi for w in a.frequencies)
    assert all(0 <= p < 2 * np.pi for p in a.phases)
    t = np.linspace(0.0, 0.5, 1001)
    assert not np.allclose(a(t), b(t), atol=1e-3)
    with pytest.raises(ValueError, match="band"):
        il.ExplorationNoise.multisine(0, band=(100.0, 10.0))


def test_printed_noise_matches_paper_k7():
    """Seed 001 eq 32: K_7 = [38.2966, 13.2889, 0.7336] with the printed noise of eq 28."""
    _, res = _learn(il.ExplorationNoise.printed())
    assert res.status is il.LearningStatus.OK
    np.testing.assert_allclose(res.k, [[38.2966, 13.2889, 0.7336]], rtol=1e-4)
    # iterate history starts at K_0 and the P_k sequence converges (Fig 8)
    np.testing.assert_array_equal(res.k_history[0], K0_31)
    dp = np.linalg.norm(np.diff(res.p_history, axis=0), axis=(1, 2))
    assert dp[-1] < dp[0] * 1e-6


def test_learner_recovers_another_operator():
    """Recovery: data from an operator with K_r = 1, K_f = 2, K_c = 10 (eq 2) — never shown to
    the learner — give that operator's Riccati optimum (eq 6)."""
    a, b = op_mod.state_space(op_mod.Operator.eq2(k_r=1.0, k_f=2.0, k_c=10.0))
    _, res = _learn(il.ExplorationNoise.multisine(7), a=a, b=b)
    k_star = il.riccati_optimum(a, b, Q27, R27).k
    assert res.status is il.LearningStatus.OK
    assert np.linalg.norm(res.k - k_star) / np.linalg.norm(k_star) <= 1e-4


def test_no_exploration_is_not_exciting():
    """Seed 001 eq 8 / rank condition under eq 8: without v_n, u = −K_0 X makes ∫X⊗u a linear
    combination of ∫X⊗X, so [I_xx, I_xu] has rank 6 < 9; the status says so and the gains are
    NaN. The exciting case sits ≥ 2 decades above the rcond band (pitfalls: verdict bands)."""
    _, res = _learn(il.ExplorationNoise.zero())
    assert res.status is il.LearningStatus.NOT_EXCITING
    assert res.rank == 6
    assert res.rcond < il.RCOND_MIN * 1e-2
    assert np.isnan(res.k).all() and np.isnan(res.p).all()
    assert "rank 6 of 9" in res.message
    _, ok = _learn(il.ExplorationNoise.printed())
    assert ok.rcond > il.RCOND_MIN * 1e2


def test_too_few_intervals_is_refused():
    """Jiang & Jiang 2012 (eq 9 needs ≥ n(n+1)/2 + mn = 9 rows): 5 intervals → refused."""
    data, res = _learn(il.ExplorationNoise.printed(), n_intervals=5, substeps=100)
    assert data.ixx.shape[0] == 5
    assert res.status is il.LearningStatus.NOT_EXCITING
    assert res.n_rows == 5 and res.n_unknowns == 9
    assert "too few rows" in res.message
    assert np.isnan(res.k).all()


def test_iteration_cap_reports_not_converged():
    """Eq 9 stopping rule ‖P_k − P_k−1‖ ≤ ε not met within the cap → not_converged, NaN K."""
    _, res = _learn(il.ExplorationNoise.printed(), max_iterations=2)
    assert res.status is il.LearningStatus.NOT_CONVERGED
    assert res.iterations == 2
    assert np.isnan(res.k).all()


def test_soft_switch_eq10_endpoints_and_monotone():
    """Seed 001 eq 10 / Fig 2: K' = K_0 at the start, K_1 after T_s, monotone in between."""
    k1 = np.array([[38.0, 13.0, 0.7]])
    t = np.linspace(0.0, 2.0, 401)
    kk = il.soft_switch(t, K0_31, k1, t_start=0.5, t_switch=0.5)
    np.testing.assert_allclose(kk[t <= 0.5], np.broadcast_to(K0_31, kk[t <= 0.5].shape))
    np.testing.assert_allclose(kk[t >= 1.0], np.broadcast_to(k1, kk[t >= 1.0].shape), atol=1e-14)
    assert np.all(np.diff(kk[:, 0, 0]) >= 0) and np.all(np.diff(kk[:, 0, 2]) >= 0)
    with pytest.raises(ValueError, match="t_switch = 0.0 s"):
        il.soft_switch(t, K0_31, k1, t_start=0.5, t_switch=0.0)


def test_soft_switch_removes_step_in_control():
    """Seed 001 Fig 7: without the soft function u = ë_p jumps at 0.5 s; with it the peak change
    per sample after the data phase is smaller (measured on the same 1 ms grid)."""
    cfg = il.OuterLoopConfig(duration=2.0)
    soft = il.simulate_outer_loop(cfg).ioic
    hard = il.simulate_outer_loop(dataclasses.replace(cfg, soft=False)).ioic

    def peak_change(tr):
        sel = tr.t[1:] >= cfg.t_learn - 1e-12  # changes from the last data sample on
        return np.abs(np.diff(tr.u))[sel].max()

    assert peak_change(soft) < 0.2 * peak_change(hard)
    # the unswitched jump is (K − K_0)·X(0.5) (plus the noise switching off)
    i = int(round(cfg.t_learn / cfg.step))
    jump = hard.u[i] - hard.u[i - 1]
    k_learned = hard.k[i]
    predicted = -(k_learned - K0_31[0]) @ hard.x[i] - cfg.noise(hard.t[i - 1])
    assert jump == pytest.approx(predicted, rel=0.05)


def test_fic_oic_ioic_rms(outer):
    """Seed 001 Figs 4–6: IOIC's tracking error and force RMS within 5 % of OIC after the
    learning phase (t ≥ t_learn + T_s) and on the 5–15 s segments the paper compares; FIC is
    worse than OIC on both (Fig 5–6: overshoot and oscillation)."""
    assert outer.status is il.LearningStatus.OK
    for t0 in (1.0, 5.0):
        e_o, f_o = outer.oic.rms(t0, 15.0)
        e_i, f_i = outer.ioic.rms(t0, 15.0)
        e_f, f_f = outer.fic.rms(t0, 15.0)
        assert abs(e_i - e_o) <= 0.05 * e_o and abs(f_i - f_o) <= 0.05 * f_o
        assert e_f > 1.1 * e_o and f_f > 1.1 * f_o


def test_rms_fields_are_the_trace_rms(outer):
    """The result's RMS table (Figs 5–6) is the traces' RMS over [0, 15] and [1, 15] s."""
    assert outer.rms_full[il.Strategy.OIC] == outer.oic.rms(0.0, 15.0)
    assert outer.rms_after_learning[il.Strategy.IOIC] == outer.ioic.rms(1.0, 15.0)


def test_unexciting_run_keeps_initial_impedance():
    """Eq 8 without v_n: IOIC refuses to learn (NaN gains, status not_exciting) and keeps K_0,
    so its trace equals FIC's."""
    res = il.simulate_outer_loop(il.OuterLoopConfig(noise=il.ExplorationNoise.zero(),
                                                    duration=2.0))
    assert res.status is il.LearningStatus.NOT_EXCITING
    assert np.isnan(res.learning.k).all()
    np.testing.assert_array_equal(res.ioic.k, res.fic.k)
    np.testing.assert_allclose(res.ioic.x, res.fic.x, atol=1e-12)


def test_ioic_data_phase_is_the_same_trajectory(outer):
    """The simulator's IOIC run over [0, 0.5] s reproduces the data phase (eq 8) it learnt from."""
    i = int(round(0.5 / outer.ioic.t[1]))
    np.testing.assert_allclose(outer.ioic.x[i], outer.data.x[-1], atol=1e-12)


@pytest.mark.parametrize("step", [1e-7, 1.0, float("nan")])
def test_step_out_of_range_raises(step):
    """Integrator step validation: the error names the parameter, value, range and unit."""
    with pytest.raises(ValueError, match=r"OuterLoopConfig\.step = .* s is outside the allowed "
                                         r"range \[1e-05, 0\.02\] s"):
        il.OuterLoopConfig(step=step)


def test_step_must_divide_sampling_interval():
    with pytest.raises(ValueError, match="must divide the sampling interval"):
        il.OuterLoopConfig(step=3e-3)


def test_paper_step_learns():
    """Seed 001 §4 uses a 0.01 s step: one RK4 step per sampling interval still learns K*
    within 1e-4 (eq 30)."""
    _, res = _learn(il.ExplorationNoise.printed(), substeps=1)
    k_star = il.riccati_optimum(A29, B29, Q27, R27).k
    assert res.status is il.LearningStatus.OK
    assert np.all(np.isfinite(res.k))
    assert np.linalg.norm(res.k - k_star) / np.linalg.norm(k_star) <= 1e-4


def test_learned_gain_converges_at_rk4_rate():
    """The data integrals of eq 7 are extra RK4 states, so the learned K converges to the
    Riccati K* (eq 30) at 4th order in the step: 10, 5, 2.5 ms steps (0.5 s, 50 intervals)."""
    k_star = il.riccati_optimum(A29, B29, Q27, R27).k
    errs = []
    for sub in (1, 2, 4):
        _, res = _learn(il.ExplorationNoise.printed(), substeps=sub)
        errs.append(np.linalg.norm(res.k - k_star))
    slope = np.polyfit(np.log([10.0, 5.0, 2.5]), np.log(errs), 1)[0]
    assert 3.5 < slope < 4.5

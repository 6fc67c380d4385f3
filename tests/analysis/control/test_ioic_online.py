"""hapticopt.analysis.control.ioic_online: seed 001's outer loop stepped as firmware, on an exact
eq-4 plant (the impedance reference is rendered perfectly, the operator is eq 2)."""

from __future__ import annotations

import numpy as np
import pytest

from hapticopt.analysis.control import impedance_learning as il
from hapticopt.analysis.control import ioic_online as io
from hapticopt.analysis.loop.operator import Operator, force_step, state_space
from hapticopt.analysis.status import Status

OP = Operator.eq2()  # §4.1
Q27, R27 = (1.0, 1.0, 1.0), 0.01
K0_31 = (10.0, 4.0, 0.2)


def k_star(op=OP):
    a, b = state_space(op)
    return il.riccati_optimum(a, b, np.diag(Q27), np.array([[R27]])).k[0]


def run(period, *, strategy=il.Strategy.IOIC, noise=il.ExplorationNoise.printed(), seconds=1.2, op=OP,
        x_d=0.4):
    """The firmware against eq 4 exactly: x_r as the firmware integrates it, f of eq 2 on the
    error x_r − x_d, advanced in 20 exact sub-steps per period (e_p is quadratic in t)."""
    cfg = io.OnlineIoicConfig(period=period, strategy=strategy, k0=K0_31, k_star=tuple(k_star(op)), q=Q27, r=R27,
                              learn_time=0.5, intervals=50, switch_time=0.5, noise=noise)
    c = io.OnlineIoic(cfg)
    c.reset(0.0)
    f = 0.0
    gains = []
    for _ in range(int(round(seconds / period))):
        xr, vr, u, _ = c.step(x_d, f)
        gains.append(c.last_gain)
        h = period / 20
        for j in range(20):
            tm = (j + 0.5) * h
            f = force_step(op, f, xr + vr * tm + 0.5 * u * tm * tm - x_d, h)
    return c, np.array(gains)


def rel(k, ref):
    return float(np.linalg.norm(k - ref) / np.linalg.norm(ref))


def test_online_learning_reaches_the_riccati_optimum():
    """Seed 001 eq 9 from tick samples at 1 kHz: 7 iterations (as Fig 8) and within 1e-6 of K*
    (eq 30); the trapezoid rule of the data is 2nd order: the error falls ≈ 4× per halving of T."""
    errs = {}
    for T in (2e-3, 1e-3, 5e-4):
        c, _ = run(T)
        assert c.learning.status is il.LearningStatus.OK and c.learning.iterations <= 10
        errs[T] = rel(c.learning.k[0], k_star())
    assert errs[1e-3] <= 1e-6
    slope = np.polyfit(np.log(list(errs)), np.log(list(errs.values())), 1)[0]
    assert 1.7 <= slope <= 2.3, errs


def test_online_learning_five_noise_seeds_and_another_operator():
    """Five seeded random multi-sines (ten frequencies in the band, random phases), and an operator never shown to the learner (K_r = 1 s,
    K_f = 2, K_c = 10 N/m): ‖K − K*‖/‖K*‖ ≤ 1e-4 within 10 iterations (issue 18's bound)."""
    for seed in range(5):
        c, _ = run(1e-3, noise=il.ExplorationNoise.multisine(seed))
        assert c.learning.status is il.LearningStatus.OK and c.learning.iterations <= 10
        assert rel(c.learning.k[0], k_star()) <= 1e-4
    other = Operator.eq2(k_r=1.0, k_f=2.0, k_c=10.0)
    c, _ = run(1e-3, op=other)
    assert rel(c.learning.k[0], k_star(other)) <= 1e-4


def test_no_exploration_is_refused_and_keeps_k0():
    """Without v_n the data matrix has rank 6 of 9 (rank condition under eq 8): status
    not_exciting, NaN gain, and the firmware keeps K_0 (the soft switch goes nowhere)."""
    c, gains = run(1e-3, noise=il.ExplorationNoise.zero())
    L = c.learning
    assert L.status is il.LearningStatus.NOT_EXCITING and L.rank == 6 and L.n_unknowns == 9
    assert L.rcond < il.RCOND_MIN * 1e-4 and np.all(np.isnan(L.k))
    np.testing.assert_array_equal(gains, np.broadcast_to(K0_31, gains.shape))


def test_fic_oic_gains_and_soft_switch_midpoint():
    """FIC keeps K_0 (eq 31), OIC uses K*; IOIC's gain at t_learn + T_s/2 is the midpoint of eq 10."""
    _, g_fic = run(1e-3, strategy=il.Strategy.FIC, seconds=0.2)
    np.testing.assert_array_equal(g_fic[-1], K0_31)
    _, g_oic = run(1e-3, strategy=il.Strategy.OIC, seconds=0.2)
    np.testing.assert_allclose(g_oic[0], k_star(), rtol=0, atol=0)
    c, g = run(1e-3, seconds=1.2)
    k1 = c.learning.k[0]
    np.testing.assert_allclose(g[750], (np.asarray(K0_31) + k1) / 2, rtol=1e-12)  # t = 0.75 s
    np.testing.assert_allclose(g[-1], k1, rtol=1e-12)
    np.testing.assert_array_equal(g[499], K0_31)


def test_trapezoid_data_are_exact_for_linear_samples():
    """For X linear in t and u held per tick: ∫u Xᵀ by the trapezoid is exact, and ∫X Xᵀ (quadratic)
    carries the trapezoid's closed-form error Σ T³/12 · d²(XXᵀ)/dt² = 10 T³/6 · c1c1ᵀ over 10 ticks."""
    T, m = 1e-3, 10
    t = T * np.arange(101)
    x = np.stack([1 + 2 * t, -t, 3 * t], axis=1)
    u = np.sin(t[:-1])[:, None]
    d = io.data_from_samples(x, u, T, m)
    lo, hi = t[10], t[20]  # interval 1
    c0, c1 = np.array([1.0, 0.0, 0.0]), np.array([2.0, -1.0, 3.0])
    exact = (np.outer(c0, c0) * (hi - lo) + (np.outer(c0, c1) + np.outer(c1, c0)) * (hi**2 - lo**2) / 2
             + np.outer(c1, c1) * (hi**3 - lo**3) / 3)
    np.testing.assert_allclose(d.ixx[1], exact + 10 * T**3 / 6 * np.outer(c1, c1), rtol=1e-10, atol=1e-18)
    ux = sum(u[k, 0] * (x[k] + x[k + 1]) * T / 2 for k in range(10, 20))
    np.testing.assert_allclose(d.iux[1, 0], ux, rtol=1e-12)
    assert d.x.shape == (11, 3) and d.ixx.shape == (10, 3, 3)


def test_config_validation():
    with pytest.raises(ValueError, match=r"learn_time/intervals = 0.0005 s must be a whole number ≥ 1 of periods"):
        io.OnlineIoicConfig(period=1e-3, strategy=il.Strategy.IOIC, k0=K0_31, k_star=K0_31, q=Q27, r=R27,
                            learn_time=0.5, intervals=1000, switch_time=0.5, noise=il.ExplorationNoise.zero())


def _measures(k_used, strategy=il.Strategy.IOIC, tol=io.IMPEDANCE_TOLERANCE):
    a, b = state_space(OP)
    opt = il.riccati_optimum(a, b, np.diag(Q27), np.array([[R27]]))
    t = np.arange(10) * 1e-3
    rec = io.OuterRecord(t=t, x=np.zeros(10), x_r=np.zeros(10), x_d=np.zeros(10), f=np.zeros(10),
                         gain=np.tile(k_used, (10, 1)))
    L = il.LearningResult(status=il.LearningStatus.OK, k=np.atleast_2d(k_used), p=np.eye(3), iterations=7,
                          rank=9, rcond=1e-3, n_rows=50, n_unknowns=9, k_history=np.zeros((1, 1, 3)),
                          p_history=np.zeros((1, 3, 3)), message="")
    m = io.outer_metrics(rec, strategy=strategy, learning=L, optimum=opt, after=0.0, tolerance=tol)
    return m, L


def test_status_judges_each_of_m_b_k_not_the_gain_norm():
    """IOIC is ok only when each of M, B, K (eq 33: 1/K3, K2/K3, K1/K3) is within the tolerance of the
    Riccati optimum. K* with K3 scaled by 1/0.73 (the prrr-ioic case of issue 31: gain norm 5.8 % off,
    M 27 % light) is not-met although ‖K − K*‖/‖K*‖ = 0.27·0.7335/40.6 ≈ 0.7 %: the message names the
    three errors (M −27 %, B −27 %, K −27 %); a 5 % change of K3 is ok (each error 1/1.05 − 1 = −4.8 %)."""
    ks = k_star()
    bad = ks * np.array([1.0, 1.0, 1 / 0.73])
    m, L = _measures(bad)
    assert m["gain_rel_error_to_optimum"] < 0.01
    for key in ("mass", "damping", "stiffness"):
        assert m[f"impedance_{key}_rel_error"] == pytest.approx(-0.27, rel=1e-9)
    status, msg = io.run_status(stable=True, unstable_at=None, strategy=il.Strategy.IOIC, learning=L, problems=[],
                                measures=m)
    assert status == Status.NOT_MET
    assert "M -27.0 %" in msg and "B -27.0 %" in msg and "K -27.0 %" in msg and "±10 %" in msg
    clean = io.clean_metrics(m, status=status)
    assert clean["impedance_mass_kg"] == m["impedance_mass_kg"]  # not-met keeps its numbers
    good, L = _measures(ks * np.array([1.0, 1.0, 1.05]))
    assert good["impedance_mass_rel_error"] == pytest.approx(1 / 1.05 - 1, rel=1e-9)
    assert io.run_status(stable=True, unstable_at=None, strategy=il.Strategy.IOIC, learning=L, problems=[],
                         measures=good)[0] == Status.OK
    # only K (K1 alone 15 % up): M, B exact, K +15 % → not-met, and a 20 % tolerance accepts it
    one, L = _measures(ks * np.array([1.15, 1.0, 1.0]))
    status, msg = io.run_status(stable=True, unstable_at=None, strategy=il.Strategy.IOIC, learning=L, problems=[],
                                measures=one)
    assert status == Status.NOT_MET and "M +0.0 %" in msg and "K +15.0 %" in msg
    loose, L = _measures(ks * np.array([1.15, 1.0, 1.0]), tol=0.2)
    assert io.run_status(stable=True, unstable_at=None, strategy=il.Strategy.IOIC, learning=L, problems=[],
                         measures=loose)[0] == Status.OK
    # FIC renders K_0 (M = 5 kg, 267 % off) by choice: not judged
    fic, _ = _measures(np.asarray(K0_31), strategy=il.Strategy.FIC)
    assert io.run_status(stable=True, unstable_at=None, strategy=il.Strategy.FIC, learning=None, problems=[],
                         measures=fic)[0] == Status.OK

"""hapticopt.analysis.prrr.loop.stability: analytic references, and the simulation checked against them (issue 6 acceptance)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hapticopt.analysis.prrr.loop import stability as sb
from hapticopt.analysis.loop.scene import Effect, load_scene
from hapticopt.analysis.prrr.loop.zwidth import StabilityProbe


# seed 000's cubic (eq 15, 17–19) and Colgate's passivity condition: closed forms only these tests use
def hurwitz_cubic(a3: float, a2: float, a1: float, a0: float) -> bool:
    """Routh–Hurwitz for a3 s³ + a2 s² + a1 s + a0 (seed 000 eq 17): all a > 0 and a2 a1 > a3 a0."""
    return a3 > 0 and a2 > 0 and a1 > 0 and a0 > 0 and a2 * a1 > a3 * a0


def seed000_cubic(*, inertia: float, damping: float, ratio: float, T: float, stiffness: float,
                  virtual_damping: float = 0.0, hand_stiffness: float = 0.0, R: float = 1.0) -> tuple[float, ...]:
    """Coefficients of seed 000 eq (15) (operator term eq 20–22 when ``hand_stiffness`` > 0).

    T I s³ + (2I + T B_m) s² + (2(B_m + rR B_e) + R k_h T) s + 2 rR K_e + 2R k_h, with
    I = I_m + I_l, ``ratio`` = rR.
    """
    I, Bm = inertia, damping
    return (T * I, 2 * I + T * Bm, 2 * (Bm + ratio * virtual_damping) + R * hand_stiffness * T,
            2 * ratio * stiffness + 2 * R * hand_stiffness)


def seed000_stiffness_limit(*, inertia: float, damping: float, ratio: float, T: float,
                            virtual_damping: float = 0.0) -> float:
    """Eq (18)–(19): K_e < (2I + T B_m)(B_m + rR B_e) / (rR T I)."""
    I, Bm = inertia, damping
    return (2 * I + T * Bm) * (Bm + ratio * virtual_damping) / (ratio * T * I)


def colgate_passive(*, damping: float, stiffness: float, virtual_damping: float, T: float) -> bool:
    """Colgate & Schenkel's passivity condition b > KT/2 + |B|."""
    return damping > stiffness * T / 2.0 + abs(virtual_damping)


def test_force_loop_bandwidth_eq8(prrr_paper):
    # seed digest: eq (8) with Table 4 at K_p = 45 gives 38.5 Hz (DC gain 0.976)
    assert sb.force_loop_bandwidth(prrr_paper, 45.0) == pytest.approx(38.5, abs=0.05)
    num, den = sb.force_loop_tf(prrr_paper, 45.0)
    assert num[0] / den[-1] == pytest.approx(0.976, abs=5e-4)


def test_stiffness_limits_eq14(prrr_paper):
    # seed digest table: k_x = k_y = k/2 = 28.14, k_z = 3k = 168.8 N/mm at β = π/3
    assert sb.stiffness_limits(prrr_paper) * 1e-3 == pytest.approx([28.135, 28.135, 168.81], rel=1e-4)


@pytest.mark.parametrize("kp", [2.0, 45.0, 1e4])
@pytest.mark.parametrize("axis", [0, 2])
def test_eigenvalue_limit_matches_routh_hurwitz(prrr_paper, kp, axis):
    # closed form K < k_a(1 + 1/(ηK_p)) from Routh–Hurwitz of the per-axis quartic (module docstring)
    assert sb.continuous_stiffness_limit(prrr_paper, kp=kp, axis=axis) == pytest.approx(
        sb.stiffness_limit_closed_form(prrr_paper, kp, axis), rel=1e-4)  # bisection on Re λ of the flexible modes (rigid modes counted by SVD)


def test_limit_tends_to_eq15(prrr_paper):
    k = prrr_paper.actuator.spring
    big = [sb.stiffness_limit_closed_form(prrr_paper, 1e6, a) for a in range(3)]
    assert big == pytest.approx([k / 2, k / 2, 3 * k], rel=1e-5)  # seed 002 eq 15, Fig 13a


def test_seed000_eq19():
    # seed 000 parameters (digest): r = 6 mm, R = 150 mm, I_m = 34.7 g·cm², I_l = 4593.75 g·cm²,
    # B_m = 11.72 g·cm²/ms; eq 19 gives K_e < 2.61 N/mm at T = 1 ms, B_e = 0 (2.67 at B_e = 30 g·cm²/s)
    I = (34.7 + 4593.75) * 1e-7
    Bm = 11.72 * 1e-7 / 1e-3
    r, R = 6e-3, 150e-3
    lim = seed000_stiffness_limit(inertia=I, damping=Bm, ratio=r * R, T=1e-3)
    assert lim * 1e-3 == pytest.approx(2.61, abs=0.01)  # [N/mm]
    with_be = seed000_stiffness_limit(inertia=I, damping=Bm, ratio=r * R, T=1e-3, virtual_damping=30e-7 / (r * R))
    assert with_be > lim  # the critical stiffness rises with virtual damping (seed 000 conclusion)
    cubic = seed000_cubic(inertia=I, damping=Bm, ratio=r * R, T=1e-3, stiffness=0.99 * lim)
    assert hurwitz_cubic(*cubic)
    assert not hurwitz_cubic(*seed000_cubic(inertia=I, damping=Bm, ratio=r * R, T=1e-3, stiffness=1.01 * lim))


def test_sampled_wall_boundary_is_unit_circle_crossing(sampled_wall):
    m, b, T = 1.0, 2.0, 1e-3
    K = sampled_wall.sampled_wall_boundary(mass=m, damping=b, virtual_damping=0.0, T=T)
    assert K == pytest.approx(2 * b / T, rel=0.01)  # Colgate: b > KT/2 nearly tight for light damping
    r = lambda k: np.max(np.abs(sampled_wall.sampled_wall_poles(mass=m, damping=b, stiffness=k,  # noqa: E731
                                                      virtual_damping=0.0, T=T)))
    assert r(0.999 * K) < 1.0 < r(1.001 * K)


# ------------------------------------------------------------------ simulation vs analysis
def _one_dof(prrr_paper):
    """The 3-PRRR with a rigid transmission is a sampled mass per axis: m = M + M_m/2, b = ξ/2 in x."""
    d = dataclasses.replace(prrr_paper, actuator=dataclasses.replace(prrr_paper.actuator, viscous=400.0))
    base = load_scene("z-width")
    sc = dataclasses.replace(base, duration=2.0,
                             effects=base.effects - {Effect.SEA_COMPLIANCE, Effect.QUANTIZATION, Effect.SATURATION})
    m = d.end_effector.mass + d.actuator.motor_mass / 2.0  # J Jᵀ = diag(2, 2, 1/3) at π/3
    b = d.actuator.viscous / 2.0
    return d, sc, m, b


@pytest.mark.parametrize("B", [0.0, 60.0])
def test_one_dof_sampled_boundary_within_2pct(prrr_paper, B, sampled_wall):
    d, sc, m, b = _one_dof(prrr_paper)
    K_exact = sampled_wall.sampled_wall_boundary(mass=m, damping=b, virtual_damping=B, T=1e-3)
    probe = StabilityProbe(d, sc)
    Ks = K_exact * np.linspace(0.9, 1.1, 21)  # 1 % grid
    ok = probe(Ks, np.full(len(Ks), B))
    first_unstable = Ks[np.argmin(ok)]
    assert ok[0] and not ok[-1]
    assert ok[: np.argmin(ok)].all()  # one boundary
    assert abs(first_unstable / K_exact - 1) <= 0.02


def test_colgate_passive_points_are_stable(prrr_paper):
    d, sc, m, b = _one_dof(prrr_paper)
    rng = np.random.default_rng(6)
    Ks = rng.uniform(1e3, 2 * b / 1e-3, 400)
    Bs = rng.uniform(-b, b, 400)
    keep = np.array([colgate_passive(damping=b, stiffness=k, virtual_damping=v, T=1e-3) for k, v in zip(Ks, Bs)])
    Ks, Bs = Ks[keep][:60], Bs[keep][:60]
    assert len(Ks) == 60
    assert StabilityProbe(d, sc)(Ks, Bs).all()


@pytest.mark.parametrize("axis", [0, 2])
def test_continuous_limit_sweep_within_2pct(prrr_paper, axis):
    """Sampling off, zero virtual damping: simulated K limit vs eigenvalues over a K_p sweep."""
    base = load_scene("z-width")
    sc = dataclasses.replace(base, duration=1.0, initial_offset=tuple(1e-3 * (i == axis) for i in range(3)),
                             effects=base.effects - {Effect.SAMPLING, Effect.QUANTIZATION, Effect.SATURATION})
    for kp in (5.0, 45.0, 500.0):
        K_eig = sb.continuous_stiffness_limit(prrr_paper, kp=kp, axis=axis)
        ok = StabilityProbe(prrr_paper, sc, axis=axis, kp=kp)(K_eig * np.array([0.98, 1.02]), np.zeros(2))
        assert ok[0] and not ok[1], kp
    assert K_eig == pytest.approx(sb.stiffness_limits(prrr_paper)[axis], rel=0.01)  # → k/2, 3k at large K_p


def test_evaluator_metrics(prrr_paper):
    m = sb.evaluate(prrr_paper).metrics()
    assert m["force_loop_bandwidth_Hz"] == pytest.approx(38.5, abs=0.05)  # eq 8, Table 4
    # k_a (1 + 1/(ηK_p)) at K_p = 45: 28.14·1.0242 N/mm (eq 14 and the Routh–Hurwitz closed form)
    assert m["closed_loop_stiffness_limit_N_per_mm"][0] == pytest.approx(28.135 * (1 + 1 / (0.9173 * 45)), rel=1e-4)


# --------------------------------------------------------------- exact sampled analysis (issue 19)
@pytest.mark.parametrize("kp", [2.0, 45.0, 500.0])
def test_sampled_limit_tends_to_the_continuous_closed_form(prrr_paper, kp):
    """T → 0: the sampled K limit → k_a(1 + 1/(ηK_p)) (Routh–Hurwitz closed form), within 0.1 % at
    10 µs on x and at 1 µs on z (z's loop is faster: 3k on M/3)."""
    K = sb.sampled_stiffness_limit(prrr_paper, axis=0, T=1e-5, kp=kp, rtol=1e-7)
    assert K == pytest.approx(sb.stiffness_limit_closed_form(prrr_paper, kp, 0), rel=1e-3)
    Kz = sb.sampled_stiffness_limit(prrr_paper, axis=2, T=1e-6, kp=kp, rtol=1e-7)
    assert Kz == pytest.approx(sb.stiffness_limit_closed_form(prrr_paper, kp, 2), rel=1e-3)


def test_sampled_force_loop_tends_to_eq8_and_loses_stability(prrr_paper):
    """Bandwidth → eq (8)'s 38.52 Hz at K_p = 45 as T → 0; the DC gain of the sampled loop is eq 8's
    ηkK_p/(k(1 + ηK_p)) exactly (ZOH keeps DC); at T = 1 ms, K_p = 500 the sampled loop is unstable."""
    ok, bw = sb.sampled_force_loop_bandwidth(prrr_paper, T=1e-5, kp=45.0)
    assert ok and bw == pytest.approx(sb.force_loop_bandwidth(prrr_paper, 45.0), rel=2e-3)
    Phi, Gam, C = sb.sampled_force_loop(prrr_paper, T=1e-3, kp=45.0)
    dc = C @ np.linalg.solve(np.eye(2) - Phi, Gam)
    a = prrr_paper.actuator
    assert dc == pytest.approx(a.efficiency * 45.0 / (1 + a.efficiency * 45.0), rel=1e-10)
    assert sb.sampled_force_loop_bandwidth(prrr_paper, T=1e-3, kp=500.0) [0] is False
    assert sb.sampled_stiffness_limit(prrr_paper, axis=0, T=1e-3, kp=500.0) == 0.0


def test_sampled_axis_matrix_decouples_like_eq14(prrr_paper):
    """λ_a² k_x = k: the per-axis scale of the decoupled loop reproduces eq (14) (k/2, k/2, 3k at π/3)."""
    k = prrr_paper.actuator.spring
    lims = sb.stiffness_limits(prrr_paper)
    for axis in range(3):
        assert k / sb.axis_scale(prrr_paper, axis) ** 2 == pytest.approx(lims[axis], rel=1e-12)


@pytest.mark.hardcase
@pytest.mark.parametrize("factor, stable", [(0.01, True), (0.5, True), (2.0, False), (1000.0, False)])
def test_stability_verdict_sets_rigid_modes_aside_explicitly(prrr_paper, factor, stable):
    """Issue 14: the verdict was max Re λ < 1e-9·max|λ| with the free axes' rigid modes at round-off.
    Now the rigid modes are counted by SVD and dropped; at 0.01–0.5× and 2–1000× the closed-form
    limit (Routh–Hurwitz, k_a(1 + 1/(η K_p))) the flexible modes' Re λ is ≥ 1e-3·max|λ| away from 0."""
    kp = 45.0
    K = np.zeros(3)
    K[0] = factor * sb.stiffness_limit_closed_form(prrr_paper, kp, 0)
    A = sb.continuous_closed_loop(prrr_paper, stiffness=K, damping=np.zeros(3), kp=kp)
    re = sb.max_real_flexible_eigenvalue(A)
    assert (re < 0.0) == stable
    assert abs(re) > 1e-3 * np.max(np.abs(np.linalg.eigvals(A)))


def _actuator_sample(prrr_paper, n: int = 200):
    """Seeded actuators spanning decades around the preset (spring, motor mass, friction, η, K_p)."""
    rng = np.random.default_rng(8)
    a = prrr_paper.actuator
    for _ in range(n):
        yield dataclasses.replace(a, spring=a.spring * 10 ** rng.uniform(-2, 2),
                                  motor_mass=a.motor_mass * 10 ** rng.uniform(-3, 2),
                                  viscous=a.viscous * 10 ** rng.uniform(-3, 3),
                                  efficiency=rng.uniform(0.05, 1.0)), 10 ** rng.uniform(-1, 4)


def test_bandwidth_closed_form_equals_the_root_search(prrr_paper):
    # reference: force_loop_bandwidth's brentq root of |H(jω)| = |H(0)|/√2, within its own tolerance
    # on ω (xtol = 1e-12 rad/s, rtol = 4ε): both quadratic branches (b ≤ 0 and b > 0) occur in the sample
    branches = set()
    for a, kp in _actuator_sample(prrr_paper):
        d = dataclasses.replace(prrr_paper, actuator=a)
        w_ref = 2 * np.pi * sb.force_loop_bandwidth(d, kp)
        w = 2 * np.pi * float(sb.force_loop_bandwidth_closed_form(a.efficiency, a.spring, a.motor_mass, a.viscous, kp))
        assert abs(w - w_ref) <= 2e-12 + 1e-14 * w_ref
        c = a.spring * (1 + a.efficiency * kp)
        branches.add(a.viscous**2 - 2 * c * a.motor_mass > 0)
    assert branches == {False, True}


def test_evaluate_many_equals_evaluate_bitwise(prrr_paper):
    # the batched draft evaluator's array form against one design at a time: the same bits
    designs = [dataclasses.replace(prrr_paper, actuator=a) for a, _ in _actuator_sample(prrr_paper, 40)]
    limits = np.array([sb.stiffness_limits(d) for d in designs])
    many = sb.evaluate_many(designs, limits=limits)
    for d, r in zip(designs, many):
        one = sb.evaluate(d)
        assert r.force_loop_bandwidth == one.force_loop_bandwidth
        assert np.array_equal(r.continuous_limits, one.continuous_limits)
        assert np.array_equal(r.stiffness_limits, one.stiffness_limits)
        assert (r.status, r.message) == (one.status, one.message)
        assert r.continuous_limits == pytest.approx(
            [sb.stiffness_limit_closed_form(d, 45.0, ax) for ax in range(3)], rel=0, abs=0)

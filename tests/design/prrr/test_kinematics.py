"""3-PRRR kinematics: geometric IK vs the analytic Jacobian (seed 002 eq 1–2), FK∘IK, leg chains."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hapticopt.design.prrr import kinematics as kin
from hapticopt.design.prrr.params import PrrrDesign, PrrrGeometry

MM = 1e-3


def random_design(rng: np.random.Generator) -> PrrrDesign:
    return PrrrDesign(geometry=PrrrGeometry(
        beta=math.radians(rng.uniform(10.0, 80.0)),
        d1=rng.uniform(5, 60) * MM, d2=rng.uniform(20, 120) * MM,
        d3=rng.uniform(40, 150) * MM, d4=rng.uniform(40, 150) * MM,
        r4=rng.uniform(5, 40) * MM, b5=rng.uniform(10, 60) * MM,
        stroke=rng.uniform(50, 300) * MM,
    ))


IK = jax.jit(kin.inverse_kinematics)


def reachable_points(params: kin.PrrrParams, rng: np.random.Generator, n: int) -> np.ndarray:
    """Up to n reachable points: xy by rejection, z uniform inside the stroke-feasible interval."""
    reach = float(params.d3 + params.d4)
    xy = rng.uniform(-reach, reach, size=(4000, 2))
    f = kin.leg_frames(params.beta)
    s = (xy @ np.asarray(f.u)[:, :2].T) / math.tan(float(params.beta))  # slider shift needed per leg
    half = float(params.stroke) / 2
    lo, hi = s.max(axis=1) - half, s.min(axis=1) + half
    keep = lo < hi
    z = lo[keep] + rng.uniform(0, 1, size=keep.sum()) * (hi[keep] - lo[keep])
    pts = np.column_stack([xy[keep], z])
    pts = np.resize(pts, (4000, 3)) if len(pts) else np.zeros((4000, 3))  # static shape: one jit trace
    ok = np.asarray(IK(params, jnp.asarray(pts)).reachable)
    found = pts[ok][:n]
    return np.resize(found, (n, 3)) if len(found) else found  # repeat to a static length




def central_difference_jacobian(params: kin.PrrrParams, p: np.ndarray, h: float = 1e-5) -> np.ndarray:
    """∂D/∂p (n, 3 sliders, 3 coords) of the geometric IK by central differences."""
    cols = []
    for axis in range(3):
        dp = np.zeros(3)
        dp[axis] = h
        hi = np.asarray(IK(params, jnp.asarray(p + dp)).sliders)
        lo = np.asarray(IK(params, jnp.asarray(p - dp)).sliders)
        cols.append((hi - lo) / (2 * h))
    return np.stack(cols, axis=-1)


def test_analytic_jacobian_is_inverse_of_eq1_rows(prrr_paper):
    P = kin.params_of(prrr_paper)
    np.testing.assert_allclose(kin.jacobian(P.beta) @ kin.jacobian_inverse(P.beta), np.eye(3), atol=1e-14)


def test_jacobian_at_pi_over_3_is_eq2(prrr_paper):
    # seed 002 eq 2 with T = tan(π/3) = √3
    T = math.sqrt(3.0)
    expected = np.array([[-2 * T, T, T], [0, -math.sqrt(3) * T, math.sqrt(3) * T], [1, 1, 1]]) / 3
    np.testing.assert_allclose(kin.jacobian(kin.params_of(prrr_paper).beta), expected, atol=1e-15)


def test_home_slider_position_is_c_e(prrr_paper):
    # seed digest: c_e = −17.32 mm for Table 2 (eq 1), the slider position at p = 0
    P = kin.params_of(prrr_paper)
    sol = kin.inverse_kinematics(P, jnp.zeros(3))
    np.testing.assert_allclose(sol.sliders, -17.3205e-3, atol=1e-7)
    assert float(kin.slider_offset(P)) == pytest.approx(prrr_paper.geometry.c_e, rel=1e-15)


def test_fd_jacobian_of_geometric_ik_equals_analytic_j_on_1000_points():
    """≥ 1000 random reachable points of random valid designs; relative error ≤ 1e-8."""
    rng = np.random.default_rng(2026)
    count = 0
    while count < 1000:
        params = kin.params_of(random_design(rng))
        p = reachable_points(params, rng, 100)
        if len(p) == 0:
            continue
        fd = central_difference_jacobian(params, p)  # ∂D/∂p = J⁻¹
        J = np.asarray(kin.jacobian(params.beta))
        for Jinv_fd in fd:
            err = np.linalg.norm(np.linalg.inv(Jinv_fd) - J) / np.linalg.norm(J)
            assert err <= 1e-8
        count += len(np.unique(p, axis=0))  # distinct points only
    assert count >= 1000


def test_fk_of_ik_and_leg_chains_reproduce_p_on_random_designs():
    rng = np.random.default_rng(7)
    checked = 0
    while checked < 1000:
        params = kin.params_of(random_design(rng))
        p = reachable_points(params, rng, 100)
        if len(p) == 0:
            continue
        checked += len(np.unique(p, axis=0))
        sol = IK(params, jnp.asarray(p))
        # FK(IK(p)) = p within 1e-9 mm
        np.testing.assert_allclose(kin.forward_kinematics(params, sol.sliders), p, rtol=0, atol=1e-12)
        for branch in range(2):
            legs = kin.leg_chain(params, sol.sliders, sol.theta[:, branch])
            np.testing.assert_allclose(legs.p, np.broadcast_to(p[:, None, :], legs.p.shape), rtol=0, atol=1e-12)
            th = np.asarray(sol.theta[:, branch])
            np.testing.assert_allclose(th[..., 2], -(th[..., 0] + th[..., 1]), atol=1e-14)
        assert np.all(np.asarray(sol.theta[:, 0, :, 1]) >= 0) and np.all(np.asarray(sol.theta[:, 1, :, 1]) <= 0)


@given(
    beta_deg=st.floats(5.0, 85.0),
    x=st.floats(-0.06, 0.06), y=st.floats(-0.06, 0.06), z=st.floats(-0.04, 0.04),
)
def test_property_ik_closes_every_leg(prrr_paper, beta_deg, x, y, z):
    """Property: every leg's joint axes are geometrically consistent — link lengths hold, R axes ∥ w."""
    design = PrrrDesign(geometry=PrrrGeometry(beta=math.radians(beta_deg), stroke=1.0))
    params = kin.params_of(design)
    p = jnp.array([x, y, z])
    sol = kin.inverse_kinematics(params, p)
    if not bool(sol.reachable):
        return
    legs = kin.leg_chain(params, sol.sliders, sol.theta[0])
    f = kin.leg_frames(params.beta)
    ab = np.linalg.norm(np.asarray(legs.b - legs.a), axis=-1)
    np.testing.assert_allclose(ab, float(params.d3), rtol=1e-12)
    bq = np.asarray(legs.q - legs.b) - float(params.r4) * np.asarray(f.w)
    np.testing.assert_allclose(np.linalg.norm(bq, axis=-1), float(params.d4), rtol=1e-12)
    np.testing.assert_allclose(np.sum(bq * np.asarray(f.w), axis=-1), 0.0, atol=1e-15)
    np.testing.assert_allclose(legs.p, np.broadcast_to(np.asarray(p), (3, 3)), atol=1e-12)


def test_unreachable_points_are_flagged_and_finite(prrr_paper):
    params = kin.params_of(prrr_paper)
    far = jnp.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.5], [0.0, 0.0, 0.0]])
    sol = kin.inverse_kinematics(params, far)
    assert list(np.asarray(sol.reachable)) == [False, False, True]
    assert not bool(sol.reach_ok[0].all()) and not bool(sol.stroke_ok[1].all())
    for arr in sol:
        assert np.all(np.isfinite(np.asarray(arr, dtype=float)))
    assert float(sol.reach_margin[0]) < 0 < float(sol.reach_margin[2])


def test_home_reach_margin_is_closed_form(prrr_paper):
    # at p = 0 the in-plane R1→R3 distance is d2, so the margin to full extension is d3 + d4 − d2 = 71.25 mm
    sol = kin.inverse_kinematics(kin.params_of(prrr_paper), jnp.zeros(3))
    np.testing.assert_allclose(sol.rho, 0.08875, atol=1e-15)
    assert float(sol.reach_margin) == pytest.approx(0.07125, abs=1e-15)


def test_vmap_over_designs_equals_one_at_a_time():
    rng = np.random.default_rng(3)
    designs = [random_design(rng) for _ in range(5)]
    p = jnp.asarray(rng.uniform(-0.03, 0.03, size=(7, 3)))
    batched = jax.vmap(lambda prm: kin.inverse_kinematics(prm, p).sliders)(kin.stack_params(designs))
    for i, d in enumerate(designs):
        np.testing.assert_array_equal(batched[i], kin.inverse_kinematics(kin.params_of(d), p).sliders)


def test_float64_is_on():
    assert kin.inverse_kinematics(kin.params_of(PrrrDesign()), jnp.zeros(3)).sliders.dtype == jnp.float64


def test_numpy_leg_frames_reuse_read_only_constants_equal_to_fresh_ones():
    """The numpy path's u, t, e_z (made once) equal a fresh :func:`_in_plane` bit for bit and cannot be
    written; the leg frames built on them equal the jax path's to rounding."""
    from hapticopt.design.prrr import kinematics as K

    for got, fresh in zip(K._IN_PLANE_NP, K._in_plane(np)):
        assert got.tobytes() == np.ascontiguousarray(fresh).tobytes() and not got.flags.writeable
    for beta in (0.5, 1.1336):
        for a, b in zip(K.leg_frames(beta, xp=np), K.leg_frames(beta)):
            np.testing.assert_allclose(a, np.asarray(b), rtol=0, atol=1e-15)


def test_numpy_ik_angles_are_the_branch_formulas_in_place():
    """The numpy IK writes each branch's (θ1, θ2, θ3 = −(θ1 + θ2)) into one array: the two branches
    share the elbow magnitude with opposite signs, θ3 is exactly −(θ1 + θ2), and the angles equal the
    jax path's (a stack of the same formulas) to rounding, for a batch of points of shape (4, 5, 3)."""
    from hapticopt.design import io
    from hapticopt.design.prrr import kinematics as K

    d = io.load_preset("prrr-paper")
    pts = np.random.default_rng(2).uniform(-0.05, 0.05, (4, 5, 3))
    th = K.inverse_kinematics(K.params_np(d), pts, xp=np).theta
    assert th.shape == (4, 5, 2, 3, 3)
    assert np.array_equal(th[..., 0, :, 1], -th[..., 1, :, 1])
    assert np.array_equal(th[..., 2], -(th[..., 0] + th[..., 1]))
    np.testing.assert_allclose(th, np.asarray(K.inverse_kinematics(K.params_of(d), pts).theta), rtol=0, atol=1e-12)

"""Tests of analysis/control/sliding_mode.py (seed 001 eq 11–26)."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hapticopt.analysis.control import sliding_mode as sm

P = sm.NTSMTCParams()  # seed 001 §4.2 parameters


def test_paper_parameters():
    """Seed 001 §4.2: λ1 = λ2 = diag(3,3), a = 5, b = 3, μ = 0.005, β = diag(0.5,1), η = 1.5;
    σ1 = (2 − b/a) μ^(b/a−1), σ2 = (b/a − 1) μ^(b/a−2) (eq 14)."""
    assert (P.lambda1, P.lambda2, P.a, P.b, P.mu, P.beta, P.eta) == (
        (3.0, 3.0), (3.0, 3.0), 5, 3, 0.005, (0.5, 1.0), 1.5)
    assert P.sigma1 == pytest.approx(1.4 * 0.005 ** -0.4)
    assert P.sigma2 == pytest.approx(-0.4 * 0.005 ** -1.4)


def test_phi_is_c1_at_mu():
    """Eq 14: the quadratic branch meets e^(b/a) at |e| = μ with equal value and slope
    (closed form: φ(μ) = μ^r, φ'(μ) = r μ^(r−1))."""
    r = P.ratio
    for sgn in (1.0, -1.0):
        inside = sgn * P.mu * (1 - 1e-12)
        at = sgn * P.mu
        assert float(sm.phi(P, inside)) == pytest.approx(sgn * P.mu ** r, rel=1e-9)
        assert float(sm.phi(P, at)) == pytest.approx(sgn * P.mu ** r, rel=1e-12)
        assert float(sm.phi_prime(P, inside)) == pytest.approx(r * P.mu ** (r - 1), rel=1e-9)
        assert float(sm.phi_prime(P, at)) == pytest.approx(r * P.mu ** (r - 1), rel=1e-12)


def test_phi_prime_is_the_derivative():
    """φ' against jax autodiff of φ on both branches (finite where the pure power law is not)."""
    grad = jax.vmap(jax.grad(lambda e: sm.phi(P, e)))
    e = np.array([-0.3, -0.01, -0.004, -1e-4, 1e-4, 0.004, 0.01, 0.3])
    np.testing.assert_allclose(np.asarray(grad(e)), np.asarray(sm.phi_prime(P, e)), rtol=1e-12)


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=-2 * 0.005, max_value=2 * 0.005, allow_subnormal=True))
def test_no_singularity_near_zero(e):
    """Eq 14's purpose: φ, φ' finite and bounded by σ1 as e → 0 (the pure power law has
    φ' = r|e|^(r−1) → ∞); φ is odd."""
    f, fp = float(sm.phi(P, e)), float(sm.phi_prime(P, e))
    assert np.isfinite(f) and np.isfinite(fp)
    assert 0.0 < fp <= P.sigma1 * (1 + 1e-12)
    assert float(sm.phi(P, -e)) == -f
    s = np.asarray(sm.surface(P, np.array([e, -e]), np.array([0.0, 1e-9])))
    assert np.all(np.isfinite(s))


def test_sat_eq26():
    """Eq 26: sat(z) = 1 for z ≥ θ, z/θ inside, −1 for z ≤ −θ."""
    np.testing.assert_allclose(np.asarray(sm.sat(np.array([-1.0, -0.05, 0.01, 0.05, 2.0]), 0.05)),
                               [-1.0, -1.0, 0.2, 1.0, 1.0])


def test_control_law_gives_reaching_dynamics():
    """Eq 16–17 on the exact model (no τ_d): ṡ = −η sat(s/θ) − β s (eq 20 without τ_d). Checks the
    sign erratum (e = q − q_r) with a random SPD mass matrix and random states."""
    rng = np.random.default_rng(3)
    for _ in range(5):
        l = rng.normal(size=(2, 2))
        m = l @ l.T + 2 * np.eye(2)
        c_qd, g, tau_ext = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
        e, de, qdd_r = rng.normal(scale=0.01, size=2), rng.normal(size=2), rng.normal(size=2)
        tau = np.asarray(sm.control_torque(P, m=m, c_qd=c_qd, g=g, tau_ext=tau_ext, e=e, de=de,
                                           qdd_r=qdd_r))
        qdd = np.linalg.solve(m, tau - c_qd - g + tau_ext)  # eq 11 with τ_d = 0
        s = np.asarray(sm.surface(P, e, de))
        s_dot = (qdd - qdd_r) + np.array(P.lambda1) * de + np.array(P.lambda2) * np.asarray(
            sm.phi_prime(P, e)) * de
        np.testing.assert_allclose(s_dot, -P.eta * np.asarray(sm.sat(s, P.theta))
                                   - np.array(P.beta) * s, atol=1e-10)


def test_parameter_validation():
    with pytest.raises(ValueError, match=r"a = 4, b = 3: must be odd"):
        sm.NTSMTCParams(a=4)
    with pytest.raises(ValueError, match=r"theta = 0.0"):
        sm.NTSMTCParams(theta=0.0)

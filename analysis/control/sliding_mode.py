"""Nonsingular terminal sliding-mode trajectory tracking (NTSMTC) of seed 001, eq 11–26.

Joint space, n joints. Error e = q − q_r [rad] (see the erratum below), surface (eq 13)
    s = ė + λ1 e + λ2 φ(e),
with φ of eq 14 applied per joint, r = b/a (a, b odd, 1/2 < r < 1):
    φ(e) = sign(e)|e|^r                       |e| ≥ μ
    φ(e) = σ1 e + σ2 e² sign(e)               |e| < μ,
    σ1 = (2 − r) μ^(r−1), σ2 = (r − 1) μ^(r−2)
(φ and φ' are continuous at |e| = μ, and φ' = σ1 + 2σ2|e| stays finite as e → 0, which is the
point: dφ/dt = r|e|^(r−1) ė of the pure power law is singular at e = 0). The control (eq 17, with
sat of eq 26 in place of sign, remark 1):
    τ = M(q̈_r − λ1 ė − λ2 φ'(e) ė − η sat(s/θ) − β s) + C q̇ + G − τ_ext,
which gives ṡ = −η sat(s/θ) − β s + M⁻¹ τ_d on the exact model.

Errata applied:
* eq 12 defines e = q_r − q, but eq 17 with that sign makes ṡ = +2λ1ė + … (unstable); eq 17
  and eq 19–20 are consistent with e = q − q_r, which is used here.
* eq 17 prints C_0 q; the Coriolis term is C q̇ (eq 11).
* eq 14's first branch also applies when R_i = 0 for |e| < μ; R_i = 0 is a measure-zero set in
  floating point and taking the power law there would bring back the singular φ'. The
  quadratic branch is used whenever |e| < μ.
* θ (the boundary-layer width of eq 26) is not printed. θ = 1 rad/s is the value at which §4.2's
  two-link example reproduces the magnitude of Fig 10's joint errors (3e-3 / 6e-3 rad; the sweep
  in docs/seed001.md: the errors grow ∝ θ, from 3.8e-5 rad at θ = 0.01 to 7.3e-3 at θ = 5, while
  the torque's chattering falls).

Functions use jax.numpy so that the jitted simulator in :mod:`.two_link` calls them; they
accept numpy arrays as well.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)


@dataclasses.dataclass(frozen=True, kw_only=True)
class NTSMTCParams:
    """Seed 001 §4.2: λ1 = λ2 = diag(3, 3) [1/s], a = 5, b = 3, μ = 0.005 [rad],
    β = diag(0.5, 1) [1/s], η = 1.5 [rad/s²]; θ [rad/s] not printed: 1 rad/s reproduces Fig 10's error magnitude (docs/seed001.md)."""

    lambda1: tuple[float, ...] = (3.0, 3.0)
    lambda2: tuple[float, ...] = (3.0, 3.0)
    a: int = 5
    b: int = 3
    mu: float = 0.005
    beta: tuple[float, ...] = (0.5, 1.0)
    eta: float = 1.5
    theta: float = 1.0

    def __post_init__(self) -> None:
        if not (self.a % 2 == 1 and self.b % 2 == 1 and 0.5 < self.b / self.a < 1.0):
            raise ValueError(f"NTSMTCParams a = {self.a}, b = {self.b}: must be odd with "
                             "1/2 < b/a < 1 (eq 14)")
        for name in ("mu", "eta", "theta"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"NTSMTCParams.{name} = {v!r}: must be finite and > 0")

    @property
    def ratio(self) -> float:
        return self.b / self.a

    @property
    def sigma1(self) -> float:
        r = self.ratio
        return (2.0 - r) * self.mu ** (r - 1.0)

    @property
    def sigma2(self) -> float:
        r = self.ratio
        return (r - 1.0) * self.mu ** (r - 2.0)


def phi(p: NTSMTCParams, e):
    """φ(e) of eq 14 (per element) [rad^r]."""
    e = jnp.asarray(e)
    ae = jnp.abs(e)
    power = jnp.sign(e) * jnp.maximum(ae, p.mu) ** p.ratio
    quad = p.sigma1 * e + p.sigma2 * e * ae
    return jnp.where(ae >= p.mu, power, quad)


def phi_prime(p: NTSMTCParams, e):
    """dφ/de (per element); finite for all e (quadratic branch inside |e| < μ)."""
    e = jnp.asarray(e)
    ae = jnp.abs(e)
    power = p.ratio * jnp.maximum(ae, p.mu) ** (p.ratio - 1.0)
    quad = p.sigma1 + 2.0 * p.sigma2 * ae
    return jnp.where(ae >= p.mu, power, quad)


def sat(z, theta: float):
    """Eq 26: sat(z) = clip(z/θ, −1, 1)."""
    return jnp.clip(jnp.asarray(z) / theta, -1.0, 1.0)


def surface(p: NTSMTCParams, e, de):
    """s = ė + λ1 e + λ2 φ(e) (eq 13) [rad/s]."""
    return de + jnp.asarray(p.lambda1) * e + jnp.asarray(p.lambda2) * phi(p, e)


def control_torque(p: NTSMTCParams, *, m, c_qd, g, tau_ext, e, de, qdd_r):
    """Eq 17 with sat (eq 26): τ [N·m] for mass matrix m (n, n) [kg·m²], Coriolis torque
    c_qd = C(q, q̇) q̇ (n,), gravity g (n,), measured τ_ext (n,), e = q − q_r, ė, q̈_r."""
    s = surface(p, e, de)
    acc = (qdd_r - jnp.asarray(p.lambda1) * de - jnp.asarray(p.lambda2) * phi_prime(p, e) * de
           - p.eta * sat(s, p.theta) - jnp.asarray(p.beta) * s)
    return m @ acc + c_qd + g - tau_ext

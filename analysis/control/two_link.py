"""The two-link arm of seed 001 §4.2 (Table 1, eq 11, 34) under NTSMTC, tracking the IOIC
impedance trajectory of the outer loop.

Planar arm in a vertical plane (gravity along −y), revolute joints q = [q1, q2] [rad], links of
Table 1 (l = 1 m, m = 1.5 kg, I = 5 kg·m², g = 9.81 m/s²). The paper does not give the centre
of mass, so it is taken at mid-link (l_c = l/2) with I about the centre of mass:
    M11 = m1 lc1² + I1 + m2 (l1² + lc2² + 2 l1 lc2 cos q2) + I2
    M12 = m2 (lc2² + l1 lc2 cos q2) + I2,   M22 = m2 lc2² + I2
    C = h [[−q̇2, −(q̇1 + q̇2)], [q̇1, 0]],   h = m2 l1 lc2 sin q2
    G = [(m1 lc1 + m2 l1) g cos q1 + m2 lc2 g cos(q1 + q2), m2 lc2 g cos(q1 + q2)].

The end-effector reference is p_r(t) = p0 + [x_r(t), 0] with x_r = x_d + e_p from the outer loop
(the paper's base point is not given; p0 = (1.0, 1.0) m here), elbow q2 > 0. The outer-loop
state and the arm are integrated together by one fixed-step RK4 (jax.lax.scan, float64): the
operator force acts on the arm as F = [−f, 0] N (eq 1: the impedance yields to −f), τ_ext = JᵀF,
measured and cancelled by eq 17. The disturbance eq 34 is evaluated at the RK4 stage times:
with the paper's 0.01 s step, sin(200πt) = 0 at t_k and t_k + h/2, and cos(200πt) = ±1, so the
RK4 average of 0.2 cos(200πt) over a step is −0.2/3 (a constant bias), not 0.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import jax
import jax.numpy as jnp

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np  # noqa: E402

from . import impedance_learning as il  # noqa: E402
from . import sliding_mode as sm  # noqa: E402


@dataclasses.dataclass(frozen=True, kw_only=True)
class ArmParams:
    """Table 1. Lengths [m], masses [kg], inertias about the centre of mass [kg·m²], g [m/s²]."""

    l1: float = 1.0
    l2: float = 1.0
    m1: float = 1.5
    m2: float = 1.5
    i1: float = 5.0
    i2: float = 5.0
    g: float = 9.81

    @property
    def lc1(self) -> float:
        return self.l1 / 2

    @property
    def lc2(self) -> float:
        return self.l2 / 2


def mass_matrix(p: ArmParams, q):
    c2 = jnp.cos(q[1])
    m11 = p.m1 * p.lc1**2 + p.i1 + p.m2 * (p.l1**2 + p.lc2**2 + 2 * p.l1 * p.lc2 * c2) + p.i2
    m12 = p.m2 * (p.lc2**2 + p.l1 * p.lc2 * c2) + p.i2
    m22 = p.m2 * p.lc2**2 + p.i2
    return jnp.array([[m11, m12], [m12, m22]])


def coriolis_matrix(p: ArmParams, q, qd):
    h = p.m2 * p.l1 * p.lc2 * jnp.sin(q[1])
    return h * jnp.array([[-qd[1], -(qd[0] + qd[1])], [qd[0], 0.0]])


def gravity(p: ArmParams, q):
    c1 = jnp.cos(q[0])
    c12 = jnp.cos(q[0] + q[1])
    return jnp.array([(p.m1 * p.lc1 + p.m2 * p.l1) * p.g * c1 + p.m2 * p.lc2 * p.g * c12,
                      p.m2 * p.lc2 * p.g * c12])


def forward(p: ArmParams, q):
    """End-effector position [m]."""
    return jnp.array([p.l1 * jnp.cos(q[0]) + p.l2 * jnp.cos(q[0] + q[1]),
                      p.l1 * jnp.sin(q[0]) + p.l2 * jnp.sin(q[0] + q[1])])


def jacobian(p: ArmParams, q):
    s1, c1 = jnp.sin(q[0]), jnp.cos(q[0])
    s12, c12 = jnp.sin(q[0] + q[1]), jnp.cos(q[0] + q[1])
    return jnp.array([[-p.l1 * s1 - p.l2 * s12, -p.l2 * s12], [p.l1 * c1 + p.l2 * c12, p.l2 * c12]])


def jacobian_dot_qd(p: ArmParams, q, qd):
    """J̇ q̇ [m/s²]."""
    w12 = qd[0] + qd[1]
    return jnp.array([-p.l1 * jnp.cos(q[0]) * qd[0]**2 - p.l2 * jnp.cos(q[0] + q[1]) * w12**2,
                      -p.l1 * jnp.sin(q[0]) * qd[0]**2 - p.l2 * jnp.sin(q[0] + q[1]) * w12**2])


def solve2(m, v):
    """m⁻¹ v for a 2×2 m by Cramer's rule (LAPACK calls dominate a small scan step on CPU)."""
    det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    return jnp.array([m[1, 1] * v[0] - m[0, 1] * v[1], m[0, 0] * v[1] - m[1, 0] * v[0]]) / det


def inverse(p: ArmParams, x):
    """Elbow-up (q2 > 0) inverse kinematics of x [m] → q [rad]."""
    c2 = (x[0]**2 + x[1]**2 - p.l1**2 - p.l2**2) / (2 * p.l1 * p.l2)
    q2 = jnp.arccos(jnp.clip(c2, -1.0, 1.0))
    q1 = jnp.arctan2(x[1], x[0]) - jnp.arctan2(p.l2 * jnp.sin(q2), p.l1 + p.l2 * jnp.cos(q2))
    return jnp.array([q1, q2])


def disturbance(t, *, fast_amplitude: float = 0.2):
    """Eq 34: τ_d = [sin t + 0.2 sin 200πt, cos t + 0.2 cos 200πt] [N·m]."""
    w = 200.0 * jnp.pi
    return jnp.array([jnp.sin(t) + fast_amplitude * jnp.sin(w * t),
                      jnp.cos(t) + fast_amplitude * jnp.cos(w * t)])


@dataclasses.dataclass(frozen=True, kw_only=True)
class TwoLinkConfig:
    """outer: the section 4.1 outer loop (its step is the step of the whole run, [s]);
    base: p0 [m]; fast_disturbance: amplitude of the 200π rad/s terms of eq 34 [N·m]."""

    outer: il.OuterLoopConfig = il.OuterLoopConfig()
    arm: ArmParams = ArmParams()
    ctrl: sm.NTSMTCParams = sm.NTSMTCParams()
    base: tuple[float, float] = (1.0, 1.0)
    fast_disturbance: float = 0.2

    def __post_init__(self) -> None:
        dx = 1.5 * self.outer.amplitude
        reach = max(math.hypot(self.base[0] + s * dx, self.base[1]) for s in (-1.0, 1.0))
        if reach >= self.arm.l1 + self.arm.l2:
            raise ValueError(f"TwoLinkConfig.base = {self.base} m: the trajectory (±1.5·amplitude "
                             f"along x) would leave the workspace of radius "
                             f"{self.arm.l1 + self.arm.l2} m")


@dataclasses.dataclass(frozen=True, kw_only=True)
class TwoLinkResult:
    """Traces on the grid t (T,) [s]: q, q_r (T, 2) [rad], e = q − q_r [rad], tau (T, 2) [N·m],
    x_r, x (T, 2) [m] reference and actual end-effector; outer (T, 3) = [e_p, ė_p, f];
    learning: the IOIC outcome (the outer gain stays K_0 when it is not ok)."""

    t: np.ndarray
    q: np.ndarray
    q_r: np.ndarray
    e: np.ndarray
    tau: np.ndarray
    x_r: np.ndarray
    x: np.ndarray
    outer: np.ndarray
    learning: il.LearningResult

    def max_abs_error(self, t0: float) -> np.ndarray:
        """max |e_i| over t ≥ t0 [rad], per joint."""
        return np.max(np.abs(self.e[self.t >= t0]), axis=0)

    def max_abs_torque(self, t0: float = 0.0) -> np.ndarray:
        return np.max(np.abs(self.tau[self.t >= t0]), axis=0)


@functools.lru_cache(maxsize=16)
def _compiled(cfg: TwoLinkConfig):
    """The jitted run for one configuration (shapes and constants static)."""
    oc = cfg.outer
    a_np, b_np, _, _ = oc.matrices()
    a = jnp.asarray(a_np)
    bvec = jnp.asarray(b_np[:, 0])
    h = oc.step
    n_steps = int(round(oc.duration / h))
    arm, ctrl = cfg.arm, cfg.ctrl
    base = jnp.asarray(cfg.base)
    noise_a = jnp.asarray(oc.noise.amplitudes)
    noise_w = jnp.asarray(oc.noise.frequencies)
    noise_ph = jnp.asarray(oc.noise.phases)
    k0 = jnp.asarray(oc.k0)

    def xd(t):
        phase = jnp.mod(t + 1e-9 * h, oc.period)
        return jnp.where(phase < oc.period / 2, oc.amplitude, -oc.amplitude)

    def gain(t, mid, k1):
        tau = jnp.clip(t - oc.t_learn, 0.0, oc.t_switch)
        soft = (k1 + k0) / 2 - (k1 - k0) / 2 * jnp.cos(jnp.pi * tau / oc.t_switch)
        after = soft if oc.soft else k1
        return jnp.where(mid < oc.t_learn, k0, after)

    def noise(t):
        return jnp.sum(noise_a * jnp.sin(noise_w * t + noise_ph))

    def reference(t, xo, u):
        """q_r, q̇_r, q̈_r from x_r = x_d + e_p, ẋ_r = ė_p, ẍ_r = u."""
        pr = base + jnp.array([xd(t) + xo[0], 0.0])
        qr = inverse(arm, pr)
        jr = jacobian(arm, qr)
        qdr = solve2(jr, jnp.array([xo[1], 0.0]))
        qddr = solve2(jr, jnp.array([u, 0.0]) - jacobian_dot_qd(arm, qr, qdr))
        return qr, qdr, qddr

    def rhs(t, mid, z, k1):
        xo, q, qd = z[:3], z[3:5], z[5:7]
        learn = jnp.where(mid < oc.t_learn, 1.0, 0.0)
        u = -gain(t, mid, k1) @ xo + learn * noise(t)
        dxo = a @ xo + bvec * u
        qr, qdr, qddr = reference(t, xo, u)
        m = mass_matrix(arm, q)
        cqd = coriolis_matrix(arm, q, qd) @ qd
        g = gravity(arm, q)
        tau_ext = jacobian(arm, q).T @ jnp.array([-xo[2], 0.0])
        tau = sm.control_torque(ctrl, m=m, c_qd=cqd, g=g, tau_ext=tau_ext, e=q - qr,
                                de=qd - qdr, qdd_r=qddr)
        qdd = solve2(m, tau - cqd - g + tau_ext
                               + disturbance(t, fast_amplitude=cfg.fast_disturbance))
        return jnp.concatenate([dxo, qd, qdd]), tau, qr

    def step(z, i, k1):
        t = i * h
        mid = t + h / 2
        k_1, tau, qr = rhs(t, mid, z, k1)
        k_2 = rhs(mid, mid, z + h / 2 * k_1, k1)[0]
        k_3 = rhs(mid, mid, z + h / 2 * k_2, k1)[0]
        k_4 = rhs(t + h, mid, z + h * k_3, k1)[0]
        z_new = z + h / 6 * (k_1 + 2 * k_2 + 2 * k_3 + k_4)
        z_new = z_new.at[0].add(-(xd(t + h) - xd(t)))
        return z_new, (z, tau, qr)

    @jax.jit
    def run(z0, k1):
        z_end, (zs, taus, qrs) = jax.lax.scan(lambda z, i: step(z, i, k1), z0,
                                              jnp.arange(n_steps))
        # final grid point: record its state, torque and reference
        mid = n_steps * h + h / 2
        _, tau_end, qr_end = rhs(n_steps * h, mid, z_end, k1)
        return (jnp.concatenate([zs, z_end[None]]), jnp.concatenate([taus, tau_end[None]]),
                jnp.concatenate([qrs, qr_end[None]]))

    return run


def simulate(cfg: TwoLinkConfig = TwoLinkConfig()) -> TwoLinkResult:
    """IOIC outer loop + NTSMTC inner loop on the two-link arm over cfg.outer.duration."""
    oc = cfg.outer
    a, b, q, r = oc.matrices()
    k0 = np.atleast_2d(np.asarray(oc.k0, dtype=float))
    x0 = np.array([-oc.desired(np.array(0.0)).item(), 0.0, 0.0])
    data = il.collect_data(a, b, k0, oc.noise, x0, duration=oc.t_learn,
                           n_intervals=oc.n_intervals, substeps=oc.substeps)
    learning = il.policy_iteration(data, k0, q, r, eps=oc.eps)
    k1 = learning.k if learning.status is il.LearningStatus.OK else k0
    q0 = np.asarray(inverse(cfg.arm, jnp.asarray(cfg.base) + jnp.array([0.0, 0.0])))
    z0 = jnp.asarray(np.concatenate([x0, q0, np.zeros(2)]))
    zs, taus, qrs = _compiled(cfg)(z0, jnp.asarray(k1.reshape(-1)))
    zs, taus, qrs = np.asarray(zs), np.asarray(taus), np.asarray(qrs)
    t = oc.step * np.arange(zs.shape[0])
    xd = oc.desired(t)
    x_r = np.stack([cfg.base[0] + xd + zs[:, 0], np.full_like(t, cfg.base[1])], axis=1)
    x = np.asarray(jax.vmap(lambda qq: forward(cfg.arm, qq))(jnp.asarray(zs[:, 3:5])))
    return TwoLinkResult(t=t, q=zs[:, 3:5], q_r=qrs, e=zs[:, 3:5] - qrs, tau=taus, x_r=x_r, x=x,
                         outer=zs[:, :3], learning=learning)

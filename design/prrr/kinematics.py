"""3-PRRR kinematics: geometric inverse kinematics, forward kinematics, the constant Jacobian.

Vectorised with jax (float64). Leg geometry as in the seed digest (seed 002, eq 1–2):
per leg i, u = (cos γ, sin γ, 0), t = e_z × u, w = −cos β u + sin β e_z (R-axis direction),
v = sin β u + cos β e_z; R1 on A = D e_z + d1 u + d2 t; R2 on B = A + d3 e(θ1);
R3 on Q = B + d4 e(θ1+θ2) + r4 w, e(a) = cos a v + sin a t; end-effector
p = Q + b5 w − r5 e_z; θ3 = −(θ1 + θ2) (the platform only translates).

Shapes: a point ``p`` is ``(..., 3)`` [m]; slider positions ``D`` are ``(..., 3)`` [m], one per
leg; joint angles ``theta`` are ``(..., 3 legs, 3 joints)`` [rad].
"""

from __future__ import annotations

import functools
import math
from types import SimpleNamespace
from typing import Any, Callable, NamedTuple

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design.prrr.params import GAMMAS, PrrrDesign

_GAMMA = np.asarray(GAMMAS)
_EZ = np.array([0.0, 0.0, 1.0])


class PrrrParams(NamedTuple):
    """Kinematic parameters as a jax pytree [SI]; each entry a scalar or a batch ``(n,)``."""

    beta: jax.Array
    d1: jax.Array
    d2: jax.Array
    d3: jax.Array
    d4: jax.Array
    r4: jax.Array
    b5: jax.Array
    stroke: jax.Array


def params_of(design: PrrrDesign) -> PrrrParams:
    """Kinematic parameters of one design (jax scalars of :func:`params_np`)."""
    return PrrrParams(*(jnp.asarray(x) for x in params_np(design)))


def params_np(design: PrrrDesign) -> PrrrParams:
    """Kinematic parameters of one design as plain floats (for the numpy paths)."""
    g = design.geometry
    return PrrrParams(*(float(x) for x in (g.beta, g.d1, g.d2, g.d3, g.d4, g.r4, g.b5, g.stroke)))


def stack_params(designs: list[PrrrDesign]) -> PrrrParams:
    """Parameters of many designs stacked along a leading batch axis (for ``jax.vmap``)."""
    each = [params_of(d) for d in designs]
    return PrrrParams(*(jnp.stack(col) for col in zip(*each)))


class LegFrames(NamedTuple):
    """Per-leg unit vectors, each ``(3 legs, 3)``."""

    u: jax.Array
    t: jax.Array
    v: jax.Array
    w: jax.Array


def _in_plane(xp) -> tuple:
    """The legs' u and t (3 legs, 3) and e_z per leg, which do not depend on β."""
    c, s = xp.cos(_GAMMA), xp.sin(_GAMMA)
    zero = xp.zeros(3)
    return xp.stack([c, s, zero], axis=-1), xp.stack([-s, c, zero], axis=-1), xp.broadcast_to(_EZ, (3, 3))


#: :func:`_in_plane` with numpy, made once (read-only): the numpy path's leg frames reuse them (the same
#: numbers: the same operations on the same constants; a one-design IK spent ~20 % of its time making them)
_IN_PLANE_NP = tuple(np.array(x) for x in _in_plane(np))
for _x in _IN_PLANE_NP:
    _x.setflags(write=False)


def leg_frames(beta: jax.Array, xp=jnp) -> LegFrames:
    """Unit vectors of every leg for inclination ``beta`` [rad] (``xp``: array module)."""
    u, t, ez = _IN_PLANE_NP if xp is np else _in_plane(xp)
    w = -xp.cos(beta) * u + xp.sin(beta) * ez
    v = xp.sin(beta) * u + xp.cos(beta) * ez
    return LegFrames(u=u, t=t, v=v, w=w)


def r5_of(params: PrrrParams, xp=jnp) -> jax.Array:
    """r5 = b5·sin β [m] (seed 002 Table 2)."""
    return params.b5 * xp.sin(params.beta)


def slider_offset(params: PrrrParams, xp=jnp) -> jax.Array:
    """c_e of eq (1) [m]: −(b5 + r4)/sin β + r5 + d1·cot β; also the home-pose slider position."""
    b = params.beta
    return _ik_of(xp).offset(xp.sin(b), xp.tan(b), params.b5, params.r4, params.d1)


def jacobian_inverse(beta: jax.Array, xp=jnp) -> jax.Array:
    """J⁻¹ (3×3), rows [−cos γ_i / tan β, −sin γ_i / tan β, 1] (seed 002 eq 1).

    ``xp`` is the array module (``jax.numpy`` default, ``numpy`` for jit-free single calls).
    """
    T = xp.tan(beta)
    return xp.stack([-xp.cos(_GAMMA) / T, -xp.sin(_GAMMA) / T, xp.ones(3)], axis=-1)


def jacobian(beta: jax.Array, xp=jnp) -> jax.Array:
    """Analytic J (3×3), Ḋ ↦ ṗ: (1/3)[[−2T, T, T], [0, −√3T, √3T], [1, 1, 1]] (seed 002 eq 2)."""
    T = xp.tan(beta)
    r3 = xp.sqrt(3.0)
    one = xp.ones_like(T)
    return xp.stack([
        xp.stack([-2.0 * T, T, T]),
        xp.stack([0.0 * T, -r3 * T, r3 * T]),
        xp.stack([one, one, one]),
    ]) / 3.0


def condition_2norm(J: jax.Array, xp=jnp) -> jax.Array:
    """cond₂(J) = σ_max/σ_min. Has a kink where singular values coincide: no gradients through it."""
    s = xp.linalg.svd(J, compute_uv=False)
    return s[..., 0] / s[..., -1]


def condition_frobenius(J: jax.Array, xp=jnp) -> jax.Array:
    """Smooth condition number ‖J‖_F‖J⁻¹‖_F / 3 (= 1 exactly where cond₂ = 1); use for gradients."""
    Ji = xp.linalg.inv(J)
    return xp.sqrt(xp.sum(J**2, axis=(-2, -1)) * xp.sum(Ji**2, axis=(-2, -1))) / 3.0


class IkOps(NamedTuple):
    """The primitives :func:`make_ik` is written in besides + − × ÷, ``**2`` and ``abs`` (elementwise for
    arrays): ``arccos``, ``arctan2``, ``sqrt``, ``clip(x, lo, hi)``, ``mod(x, y)`` (the sign of y, as
    ``numpy.mod`` and Python's ``%``)."""

    arccos: Callable
    arctan2: Callable
    sqrt: Callable
    clip: Callable
    mod: Callable


def make_ik(ops: IkOps, wrap: Callable[[Callable], Any] = lambda f: f) -> SimpleNamespace:
    """The 3-PRRR inverse kinematics of one leg, written once over ``ops`` (each function passed through
    ``wrap``: ``njit(inline="always")`` for numba), as the firmware law is
    (:func:`hapticopt.analysis.prrr.loop.firmware_law.make_law`). Every argument is a scalar or an array
    (broadcasting) and nothing is written in place, so one text serves :func:`inverse_kinematics` (numpy or
    jax arrays, every leg at once) and the collision check's compiled per-pose loop (numba, scalars); the same
    operations in the same order give the same bits.

    Returns a namespace of ``leg`` (the slider and the planar two-link angles of one leg), ``joints`` (the
    joint angles of one elbow branch from them) and ``offset`` (c_e, the slider offset of eq 1)."""
    arccos, arctan2, sqrt, clip, mod = ops
    pi = math.pi

    @wrap
    def leg(px, py, pz, cb, sb, b5, d1, d2, d3, d4, r4, ux, uy, tx, ty):
        """One leg at end-effector point (px, py, pz) [m], cos β, sin β, the design's lengths [m] and the
        leg's in-plane axes u = (ux, uy, 0), t = (tx, ty, 0): (slider D [m], reach ok (|cos θ2| ≤ 1),
        in-plane R1→R3 distance ρ [m], elbow angle |θ2|, φ, ψ [rad]; θ1 = φ ∓ ψ for θ2 = ±elbow).

        The slider closes the leg along its joint axis w (the in-plane links have no w component):
        w·(Q − A) = r4 with w = −cos β u + sin β e_z, v = sin β u + cos β e_z, Q = p − b5 w + r5 e_z the R3
        axis point, A − D e_z = d1 u + d2 t the R1 offset; the angles from the planar two-link problem in
        the (v, t) plane (clipped outside the reach: nothing returns NaN)."""
        wx, wy = -cb * ux, -cb * uy
        relx = (px - b5 * wx) - (d1 * ux + d2 * tx)
        rely = (py - b5 * wy) - (d1 * uy + d2 * ty)
        relz = (pz - b5 * sb) + b5 * sb  # − b5 w_z + r5, r5 = b5 sin β
        slider = (((relx * wx + rely * wy) + relz * sb) - r4) / sb  # w·(Q − A) = r4; w·e_z = sin β
        relz = relz - slider
        rho_v = (relx * (sb * ux) + rely * (sb * uy)) + relz * cb
        rho_t = relx * tx + rely * ty
        rho2 = rho_v**2 + rho_t**2
        c2 = (rho2 - d3**2 - d4**2) / (2.0 * d3 * d4)
        reach_ok = abs(c2) <= 1.0 + 1e-12
        c2 = clip(c2, -1.0, 1.0)
        elbow = arccos(c2)
        s2 = sqrt(1.0 - c2**2)  # sin of the elbow angle, ≥ 0
        # the two branches share every transcendental: θ1 = φ ∓ ψ for θ2 = ±elbow
        return slider, reach_ok, sqrt(rho2), elbow, arctan2(rho_t, rho_v), arctan2(d4 * s2, d3 + d4 * c2)

    @wrap
    def joints(elbow, phi, psi, branch):
        """(θ1, θ2, θ3) [rad] of elbow ``branch`` (0: θ2 ≥ 0, 1: θ2 ≤ 0), θ1 wrapped to [−π, π),
        θ3 = −(θ1 + θ2) (the platform only translates)."""
        if branch == 0:
            th1, th2 = phi - psi, elbow
        else:
            th1, th2 = phi + psi, -elbow
        th1 = mod(th1 + pi, 2.0 * pi) - pi
        return th1, th2, -(th1 + th2)

    @wrap
    def offset(sb, tb, b5, r4, d1):
        """c_e of eq (1) [m] from sin β, tan β: −(b5 + r4)/sin β + r5 + d1·cot β."""
        return -(b5 + r4) / sb + b5 * sb + d1 / tb

    return SimpleNamespace(leg=leg, joints=joints, offset=offset)


#: the scalar primitives (``math``; also the functions numba compiles for the collision check's loop)
SCALAR_IK_OPS = dict(arccos=lambda x: math.acos(x), arctan2=lambda y, x: math.atan2(y, x),
                     sqrt=lambda x: math.sqrt(x), clip=lambda x, lo, hi: min(max(x, lo), hi),
                     mod=lambda x, y: x % y)


@functools.cache
def _ik_of(xp) -> SimpleNamespace:
    """:func:`make_ik` over the array module ``xp`` (numpy or jax.numpy)."""
    return make_ik(IkOps(arccos=xp.arccos, arctan2=xp.arctan2, sqrt=xp.sqrt, clip=xp.clip, mod=xp.mod))


class IkSolution(NamedTuple):
    """Inverse kinematics of points ``p`` (..., 3) for both elbow branches."""

    sliders: jax.Array  # (..., 3) slider positions D_i [m]
    theta: jax.Array  # (..., 2 branches, 3 legs, 3 joints) [rad]; branch 0: θ2 ≥ 0, branch 1: θ2 ≤ 0
    rho: jax.Array  # (..., 3) in-plane R1→R3 distance per leg [m]
    reach_ok: jax.Array  # (..., 3) bool: |d3 − d4| ≤ |ρ| ≤ d3 + d4
    stroke_ok: jax.Array  # (..., 3) bool: slider inside its stroke
    reachable: jax.Array  # (...,) bool: every leg reaches and every slider is in stroke
    reach_margin: jax.Array  # (...,) [m] smallest distance to a reach or stroke limit (< 0 outside)


def inverse_kinematics(params: PrrrParams, p: jax.Array, xp=jnp) -> IkSolution:
    """Geometric IK of end-effector positions ``p`` (..., 3) [m]: of one design (``params`` scalars) or
    batch-first, one design per point (each entry of ``params`` broadcasting with ``p``'s leading shape ``...``).

    :func:`make_ik`'s ``leg`` for the three legs at once (arrays (..., 3 legs)), both elbow branches.
    Points outside the reach get clipped angles and ``reachable = False``; nothing here returns NaN.
    ``xp``: array module (``numpy`` for jit-free single calls).
    """
    ik = _ik_of(xp)
    p = xp.asarray(p)
    params = PrrrParams(*(xp.asarray(x)[..., None] for x in params))  # (..., 1): against the legs axis
    u, t, _ = _IN_PLANE_NP if xp is np else _in_plane(xp)
    cb, sb = xp.cos(params.beta), xp.sin(params.beta)
    d3, d4 = params.d3, params.d4
    sliders, reach_ok, rho, elbow, phi, psi = ik.leg(p[..., 0, None], p[..., 1, None], p[..., 2, None], cb, sb,
                                                     params.b5, params.d1, params.d2, d3, d4, params.r4,
                                                     u[:, 0], u[:, 1], t[:, 0], t[:, 1])
    branches = (ik.joints(elbow, phi, psi, 0), ik.joints(elbow, phi, psi, 1))
    if xp is np:  # the same numbers written into one array (cheaper than numpy's stack)
        theta = np.empty(phi.shape[:-1] + (2, 3, 3))
        for k, joints in enumerate(branches):
            for j, angle in enumerate(joints):
                theta[..., k, :, j] = angle
    else:
        theta = xp.stack([xp.stack(joints, axis=-1) for joints in branches], axis=-3)
    c_e = ik.offset(sb, xp.tan(params.beta), params.b5, params.r4, params.d1)
    half = params.stroke / 2.0
    s_dev = sliders - c_e
    stroke_ok = xp.abs(s_dev) <= half * (1.0 + 1e-12)
    margin = xp.minimum(
        xp.minimum(rho - xp.abs(d3 - d4), d3 + d4 - rho),
        half - xp.abs(s_dev),
    )
    return IkSolution(
        sliders=sliders,
        theta=theta,
        rho=rho,
        reach_ok=reach_ok,
        stroke_ok=stroke_ok,
        reachable=xp.all(reach_ok & stroke_ok, axis=-1),
        reach_margin=xp.min(margin, axis=-1),
    )


def joint_rate_jacobian(params: PrrrParams, p: jax.Array, branch: int) -> jax.Array:
    """∂θ/∂p (3 legs, 3 joints, 3) [rad/m] at ``p`` (3,) on elbow ``branch``: the R-joint rates per
    end-effector velocity (θ3 = −(θ1 + θ2), so its row is minus the sum of the other two).

    The in-plane R1→R3 vector does not depend on z (seed digest), so the z column is zero: a pure
    z translation turns no R joint. Exact (forward-mode autodiff of :func:`inverse_kinematics`).
    """
    return jax.jacfwd(lambda q: inverse_kinematics(params, q).theta[branch])(jnp.asarray(p, dtype=jnp.float64))


def forward_kinematics(params: PrrrParams, sliders: jax.Array) -> jax.Array:
    """End-effector position [m] from slider positions ``D`` (..., 3): p = J(D − c_e·1) (eq 1)."""
    J = jacobian(params.beta)
    return (jnp.asarray(sliders) - slider_offset(params)[..., None]) @ J.T


class LegPoints(NamedTuple):
    """Joint-axis points of every leg along its serial chain, each (..., 3 legs, 3) [m]."""

    a: jax.Array  # on the R1 axis
    b: jax.Array  # on the R2 axis
    q: jax.Array  # on the R3 axis
    p: jax.Array  # end-effector centre reached by each leg


def leg_chain(params: PrrrParams, sliders: jax.Array, theta: jax.Array, xp=jnp) -> LegPoints:
    """Serial-chain forward kinematics of each leg from its slider and joint angles.

    ``sliders`` (..., 3), ``theta`` (..., 3 legs, 3 joints). Each leg's ``p`` must equal the
    end-effector position when the angles come from :func:`inverse_kinematics`.
    """
    f = leg_frames(params.beta, xp=xp)
    D = xp.asarray(sliders)[..., None]
    th1, th2 = theta[..., 0], theta[..., 1]

    def e(angle: jax.Array) -> jax.Array:
        return xp.cos(angle)[..., None] * f.v + xp.sin(angle)[..., None] * f.t

    a = D * _EZ + params.d1 * f.u + params.d2 * f.t
    b = a + params.d3 * e(th1)
    q = b + params.d4 * e(th1 + th2) + params.r4 * f.w
    # the platform frame is rotated by θ1+θ2+θ3 about w; with θ3 = −(θ1+θ2) it is the base frame
    rot = th1 + th2 + theta[..., 2]
    offset = params.b5 * f.w - r5_of(params, xp=xp) * xp.cos(rot)[..., None] * _EZ
    return LegPoints(a=a, b=b, q=q, p=q + offset)

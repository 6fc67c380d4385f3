"""The 3-PRRR firmware law, steps 1–5 and 7 of :mod:`hapticopt.analysis.prrr.loop.firmware`, written once.

:func:`make_law` builds the law from a few primitives (:class:`Ops`: select, sign, sin, tanh, clip, logical
and/not, a trace note) and a wrapper applied to each of its functions. Every vector is three separate
components (x, y, z) and nothing is written in place, so one text serves three callers:

* :data:`PYTHON` (``math`` and plain Python on floats): the Python MuJoCo loop's
  :class:`hapticopt.analysis.prrr.loop.firmware.ScalarController`;
* numba (``njit``-compiled primitives, each law function ``njit(inline="always")``): the compiled MuJoCo tick
  loop :mod:`hapticopt.analysis.prrr.loop._mujoco_kernel`;
* jax (``jnp`` primitives; each component an array carrying the batch axes):
  :func:`hapticopt.analysis.prrr.loop.firmware.step`, the lumped plant's batched compiled loop, which adds the
  seed 000 interpolation and prediction around it.

The structure flags ``flg`` (:data:`FLG`) are plain ints: in jax they are Python constants, so a term that is
off is not traced; in numba and Python they are read per tick. The numbers ``par`` (:data:`PAR`) are scalars
(or batched arrays in jax). ``J`` is the Jacobian row-major as nine components; ``K, B, anchor, half, famp,
fphase`` are the scene's 3-vectors as three components each [SI].
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any, Callable, NamedTuple

#: environment codes (``flg[FLG_ENV]``)
ENV_FREE, ENV_SPRING, ENV_BOX_INSIDE, ENV_BOX_OUTSIDE, ENV_FORCE = 0, 1, 2, 3, 4
#: force-loop codes (``flg[FLG_LOOP]``)
LOOP_SEA, LOOP_RIGID, LOOP_IDEAL = 0, 1, 2
#: the structure flags of ``flg``, in order
FLG = ("env", "friction", "gravity", "loop", "integral", "saturation", "filter")
FLG_ENV, FLG_FRICTION, FLG_GRAVITY, FLG_LOOP, FLG_INTEGRAL, FLG_SATURATION, FLG_FILTER = range(7)
#: the numbers of ``par``, in order (ki_period = K_i·T; velocity_alpha: the filter's pole, read when it exists)
PAR = ("resolution", "period", "velocity_alpha", "wall_stiffness", "wall_damping", "force_omega", "friction_comp",
       "friction_comp_velocity", "weight", "spring", "kp", "ki_period", "motor_limit", "efficiency")


class Ops(NamedTuple):
    """The primitives the law is written in (elementwise for arrays)."""

    where: Callable  # where(cond, a, b)
    sign: Callable
    sin: Callable
    tanh: Callable
    clip: Callable  # clip(x, lo, hi) = min(max(x, lo), hi), NaN stays NaN
    and_: Callable
    not_: Callable
    note: Callable  # note(name): called where an optional term is built (jax: trace counts; else nothing)


#: the primitives on Python floats (also the functions numba compiles for the kernel)
SCALAR_PRIMITIVES = dict(
    where=lambda c, a, b: a if c else b,
    sign=lambda x: 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0),
    sin=lambda x: math.sin(x),
    tanh=lambda x: math.tanh(x),
    clip=lambda x, lo, hi: hi if hi < (lo if lo > x else x) else (lo if lo > x else x),
    and_=lambda a, b: a and b,
    not_=lambda a: not a,
    note=lambda name: None,
)


def make_law(ops: Ops, wrap: Callable[[Callable], Any] = lambda f: f) -> SimpleNamespace:
    """The law's functions over ``ops`` (each passed through ``wrap``: ``njit(inline="always")`` for numba).

    Returns a namespace of ``position``, ``velocity``, ``render``, ``legs``, ``force_loop``, ``saturate``,
    ``command`` (steps 1–5) and ``tick`` (steps 1–5 and 7)."""
    where, sign, sin, tanh, clip, and_, not_, note = ops

    @wrap
    def position(r, J, sc):
        """Step 1: p = J (counts · resolution) [m] from the slider counts."""
        s0, s1, s2 = sc[0] * r, sc[1] * r, sc[2] * r
        return (s0 * J[0] + s1 * J[1] + s2 * J[2], s0 * J[3] + s1 * J[4] + s2 * J[5],
                s0 * J[6] + s1 * J[7] + s2 * J[8])

    @wrap
    def _velocity1(filt, a, T, p, q, v):
        d = (p - q) / T
        if filt:
            return a * v + (1.0 - a) * d
        return d

    @wrap
    def velocity(par, flg, p, p_prev, v_prev):
        """Step 2: ṗ̂ [m/s], the backward difference, low-passed with pole ``velocity_alpha`` when the filter exists."""
        filt, a, T = flg[FLG_FILTER], par[2], par[1]
        return (_velocity1(filt, a, T, p[0], p_prev[0], v_prev[0]), _velocity1(filt, a, T, p[1], p_prev[1], v_prev[1]),
                _velocity1(filt, a, T, p[2], p_prev[2], v_prev[2]))

    @wrap
    def _inside1(ws, wd, dl, h, v):
        depth = abs(dl) - h  # > 0: beyond the wall on that axis
        return where(depth > 0.0, -ws * sign(dl) * depth - wd * v, 0.0)

    @wrap
    def _outside1(ws, wd, dl, depth, v, push):
        return where(push, ws * sign(dl) * (-depth) - wd * v, 0.0)

    @wrap
    def render(par, flg, K, B, anchor, half, famp, fphase, p, v, k):
        """Step 3: F_r [N] at position p, velocity v and tick k, with friction and weight compensation."""
        env = flg[FLG_ENV]
        ws, wd = par[3], par[4]
        d0, d1, d2 = p[0] - anchor[0], p[1] - anchor[1], p[2] - anchor[2]
        if env == ENV_SPRING:
            note("spring")
            F0, F1, F2 = -K[0] * d0 - B[0] * v[0], -K[1] * d1 - B[1] * v[1], -K[2] * d2 - B[2] * v[2]
        elif env == ENV_BOX_INSIDE:  # eq 13, inside: every axis beyond its wall pushes back
            note("box")
            F0, F1, F2 = (_inside1(ws, wd, d0, half[0], v[0]), _inside1(ws, wd, d1, half[1], v[1]),
                          _inside1(ws, wd, d2, half[2], v[2]))
        elif env == ENV_BOX_OUTSIDE:  # outside: all axes within → push out along the shallowest axis
            note("box")
            e0, e1, e2 = abs(d0) - half[0], abs(d1) - half[1], abs(d2) - half[2]
            inside = and_(and_(e0 < 0.0, e1 < 0.0), e2 < 0.0)
            first = and_(e0 >= e1, e0 >= e2)  # the first maximum, as argmax
            second = and_(not_(first), e1 >= e2)
            third = and_(not_(first), not_(e1 >= e2))
            F0, F1, F2 = (_outside1(ws, wd, d0, e0, v[0], and_(inside, first)),
                          _outside1(ws, wd, d1, e1, v[1], and_(inside, second)),
                          _outside1(ws, wd, d2, e2, v[2], and_(inside, third)))
        elif env == ENV_FORCE:  # a prescribed force per axis, A sin(ωt + φ)
            note("force")
            ph = par[5] * (k * par[1])
            F0, F1, F2 = famp[0] * sin(ph + fphase[0]), famp[1] * sin(ph + fphase[1]), famp[2] * sin(ph + fphase[2])
        else:  # ENV_FREE
            F0, F1, F2 = 0.0, 0.0, 0.0
        if flg[FLG_FRICTION]:
            note("friction_compensation")
            F0 = F0 + par[6] * tanh(v[0] / par[7])
            F1 = F1 + par[6] * tanh(v[1] / par[7])
        if flg[FLG_GRAVITY]:
            note("gravity_compensation")
            F2 = F2 + par[8]
        return F0, F1, F2

    @wrap
    def legs(J, F):
        """Step 4: f_r = Jᵀ F_r, the spring-force reference per leg [N]."""
        return (F[0] * J[0] + F[1] * J[3] + F[2] * J[6], F[0] * J[1] + F[1] * J[4] + F[2] * J[7],
                F[0] * J[2] + F[1] * J[5] + F[2] * J[8])

    @wrap
    def _sea1(par, flg, f, dc, ig):
        err = f - par[9] * (dc * par[0])
        o = par[10] * err
        if flg[FLG_INTEGRAL]:
            ig = ig + par[11] * err
            if flg[FLG_SATURATION]:  # anti-windup: the integral is clamped to the motor limit too
                ig = clip(ig, -par[12], par[12])
            o = o + ig
        return o, ig

    @wrap
    def force_loop(par, flg, f, dc, integral):
        """Step 5: (commands, integral) [N] per leg from the references f and the spring-deflection counts dc:
        SEA K_p (f − k x̂) + K_i ∫(f − k x̂), rigid f/η, ideal f."""
        loop = flg[FLG_LOOP]
        if loop == LOOP_SEA:
            note("force_loop")
            if flg[FLG_INTEGRAL]:
                note("integral")
            o0, i0 = _sea1(par, flg, f[0], dc[0], integral[0])
            o1, i1 = _sea1(par, flg, f[1], dc[1], integral[1])
            o2, i2 = _sea1(par, flg, f[2], dc[2], integral[2])
            return (o0, o1, o2), (i0, i1, i2)
        if loop == LOOP_RIGID:
            return (f[0] / par[13], f[1] / par[13], f[2] / par[13]), integral
        return f, integral

    @wrap
    def saturate(par, flg, x):
        """Step 7: |x| ≤ the motor limit when saturation is on (x: one value or array)."""
        if flg[FLG_SATURATION]:
            note("saturation")
            return clip(x, -par[12], par[12])
        return x

    @wrap
    def command(par, flg, J, K, B, anchor, half, famp, fphase, p_prev, v_prev, integral, k, sc, dc):
        """Steps 1–5 for one tick k: (p, ṗ̂, integral, F_r, commands before saturation)."""
        p = position(par[0], J, sc)
        v = velocity(par, flg, p, p_prev, v_prev)
        F = render(par, flg, K, B, anchor, half, famp, fphase, p, v, k)
        out, integral = force_loop(par, flg, legs(J, F), dc, integral)
        return p, v, integral, F, out

    @wrap
    def tick(par, flg, J, K, B, anchor, half, famp, fphase, p_prev, v_prev, integral, k, sc, dc):
        """Steps 1–5 and 7 for one tick k: (p, ṗ̂, integral, F_r, motor-force commands) [SI]."""
        p, v, integral, F, out = command(par, flg, J, K, B, anchor, half, famp, fphase, p_prev, v_prev, integral,
                                         k, sc, dc)
        out = (saturate(par, flg, out[0]), saturate(par, flg, out[1]), saturate(par, flg, out[2]))
        return p, v, integral, F, out

    return SimpleNamespace(position=position, velocity=velocity, render=render, legs=legs, force_loop=force_loop,
                           saturate=saturate, command=command, tick=tick)


#: the law on Python floats
PYTHON = make_law(Ops(**SCALAR_PRIMITIVES))

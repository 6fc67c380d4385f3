"""numba kernels of :mod:`hapticopt.analysis.loop.mujoco_compiled` (imported only through it, after
``libmujoco`` is loaded for the linker): the native access to MuJoCo (``mj_step`` by name, mjData fields at
byte offsets), the firmware delay line, and the master's tick loop :func:`master_chunk` (the 3-PRRR's is
:mod:`hapticopt.analysis.prrr.loop._mujoco_kernel`). A kernel runs ticks [start, end) of one plant's loop and
mirrors the Python loop and controller it replaces operation by operation (same order, no fused
multiply-add: numba does not contract without ``fastmath``), so the records are bit-identical — except the
master's dynamics compensation (:func:`_compensation_basis`: the same torque in closed form, from M̂ in a trig basis
identified once per plant and model from the body-by-body form :func:`_compensation`, where the reference takes central
differences; the records agree within the reference's own rounding envelope)."""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

#: environment kinds of the compiled master firmware
ENV_FREE, ENV_SPRING, ENV_BOX = 0, 1, 2

# void mj_step(const mjModel* m, mjData* d): pointers passed as integers (same registers on x86-64 / arm64)
_mj_step = types.ExternalFunction("mj_step", types.void(types.intp, types.intp))


@intrinsic
def _f64(typingctx, addr, i):
    """double at byte address ``addr``, element ``i``."""
    sig = types.float64(types.intp, types.intp)

    def codegen(context, builder, signature, args):
        p = builder.inttoptr(args[0], ir.DoubleType().as_pointer())
        return builder.load(builder.gep(p, [args[1]]))

    return sig, codegen


@intrinsic
def _i32(typingctx, addr, i):
    """int at byte address ``addr``, element ``i`` (as intp)."""
    sig = types.intp(types.intp, types.intp)

    def codegen(context, builder, signature, args):
        p = builder.inttoptr(args[0], ir.IntType(32).as_pointer())
        return builder.sext(builder.load(builder.gep(p, [args[1]])), ir.IntType(64))

    return sig, codegen


@intrinsic
def _ptr(typingctx, addr):
    """pointer stored at byte address ``addr`` (as intp)."""
    sig = types.intp(types.intp)

    def codegen(context, builder, signature, args):
        p = builder.inttoptr(args[0], ir.IntType(64).as_pointer())
        return builder.load(p)

    return sig, codegen


@njit(cache=True, inline="always")
def _clip(x, lim):
    """``min(max(x, -lim), lim)`` as Python evaluates it (NaN stays NaN, as np.clip)."""
    lo = -lim
    y = lo if lo > x else x
    return lim if lim < y else y


@njit(cache=True, inline="always")
def _delayed(new, dbuf, ist, slot, D, cmd):
    """The firmware's delay line: ``cmd`` ← the command issued D ticks ago (zeros at start), ``new``
    pushed in its place (a FIFO of D commands; D = 0 passes ``new`` through). ``ist[slot]`` is the
    line's position."""
    if D > 0:
        pos = ist[slot]
        for j in range(3):
            cmd[j] = dbuf[pos, j]
            dbuf[pos, j] = new[j]
        ist[slot] = (pos + 1) % D
    else:
        for j in range(3):
            cmd[j] = new[j]



# --------------------------------------------------------------------------------------- master
@njit(cache=True)
def _frames(c1, s1, c2, s2, c3, s3, L5, L4, dl, hs, O, dO, R, dR):
    """The six link frames of ``dynamics_numpy.frames`` from the joint angles' cosines and sines, and their exact
    derivatives ∂/∂q_k (what the reference's complex step gives, to rounding): O (6, 3), dO (6, 3, k), R (6, 3, 3),
    dR (6, 3, 3, k). Entries that are structurally zero (turret origin, ∂/∂θ2 of f, …) are not written: the caller
    zeroes the arrays once (:func:`comp_scratch`)."""
    # e_rho = (c1, s1, 0), axis a = (s1, −c1, 0), u = c2 e_rho + s2 e_z, f = s3 e_rho − c3 e_z
    u0, u1, u2 = c2 * c1, c2 * s1, s2
    f0, f1, f2 = s3 * c1, s3 * s1, -c3
    O[1, 2] = hs
    O[2, 2] = hs
    O[3, 0], O[3, 1], O[3, 2] = -dl * f0, -dl * f1, hs - dl * f2
    O[4, 0], O[4, 1], O[4, 2] = L5 * u0, L5 * u1, hs + L5 * u2
    O[5, 0], O[5, 1], O[5, 2] = L5 * u0 + L4 * f0, L5 * u1 + L4 * f1, hs + L5 * u2 + L4 * f2
    # ∂u/∂q_k, ∂f/∂q_k (k = θ1, θ2, θ3)
    du = ((-c2 * s1, c2 * c1, 0.0), (-s2 * c1, -s2 * s1, c2), (0.0, 0.0, 0.0))
    df = ((-s3 * s1, s3 * c1, 0.0), (0.0, 0.0, 0.0), (c3 * c1, c3 * s1, s3))
    for k in range(3):
        for i in range(3):
            dO[3, i, k] = -dl * df[k][i]
            dO[4, i, k] = L5 * du[k][i]
            dO[5, i, k] = L5 * du[k][i] + L4 * df[k][i]
    # turret: columns e_rho, −a, e_z
    R[0, 0, 0], R[0, 1, 0] = c1, s1
    R[0, 0, 1], R[0, 1, 1] = -s1, c1
    R[0, 2, 2] = 1.0
    dR[0, 0, 0, 0], dR[0, 1, 0, 0] = -s1, c1
    dR[0, 0, 1, 0], dR[0, 1, 1, 0] = -c1, -s1
    # rot(x): columns x, a, x × a = (x2 c1, x2 s1, −x0 c1 − x1 s1); frames 1..5 take x = u, −f, u, f, f
    for fr in range(1, 6):
        sg = -1.0 if fr == 2 else 1.0
        if fr == 1 or fr == 3:
            x0, x1, x2 = u0, u1, u2
        else:
            x0, x1, x2 = sg * f0, sg * f1, sg * f2
        R[fr, 0, 0], R[fr, 1, 0], R[fr, 2, 0] = x0, x1, x2
        R[fr, 0, 1], R[fr, 1, 1] = s1, -c1
        R[fr, 0, 2], R[fr, 1, 2], R[fr, 2, 2] = x2 * c1, x2 * s1, -x0 * c1 - x1 * s1
        for k in range(3):
            if fr == 1 or fr == 3:
                d0, d1, d2 = du[k][0], du[k][1], du[k][2]
            else:
                d0, d1, d2 = sg * df[k][0], sg * df[k][1], sg * df[k][2]
            dc1, ds1 = (-s1, c1) if k == 0 else (0.0, 0.0)
            dR[fr, 0, 0, k], dR[fr, 1, 0, k], dR[fr, 2, 0, k] = d0, d1, d2
            dR[fr, 0, 1, k], dR[fr, 1, 1, k] = ds1, -dc1
            dR[fr, 0, 2, k] = d2 * c1 + x2 * dc1
            dR[fr, 1, 2, k] = d2 * s1 + x2 * ds1
            dR[fr, 2, 2, k] = -(d0 * c1 + x0 * dc1) - (d1 * s1 + x1 * ds1)


@njit(cache=True, inline="always")
def _jm(a, b):
    """Product of two second-order jets (value, D, D²) along one direction: (ab, Da b + a Db, D²a b + 2 Da Db + a D²b)."""
    return (a[0] * b[0], a[1] * b[0] + a[0] * b[1], a[2] * b[0] + 2.0 * a[1] * b[1] + a[0] * b[2])


@njit(cache=True)
def _frames_dd(c1, s1, c2, s2, c3, s3, v, L5, L4, dl, O2, R2):
    """Second derivatives along q̂̇ = v, D²(·) = Σ_jk ∂²(·)/∂q_j∂q_k v_j v_k, of the frames of :func:`_frames`:
    O2 (6, 3), R2 (6, 3, 3) (structural zeros not written, as there)."""
    C1 = (c1, -s1 * v[0], -c1 * (v[0] * v[0]))
    S1 = (s1, c1 * v[0], -s1 * (v[0] * v[0]))
    C2 = (c2, -s2 * v[1], -c2 * (v[1] * v[1]))
    S2 = (s2, c2 * v[1], -s2 * (v[1] * v[1]))
    C3 = (c3, -s3 * v[2], -c3 * (v[2] * v[2]))
    S3 = (s3, c3 * v[2], -s3 * (v[2] * v[2]))
    u0, u1, u2 = _jm(C2, C1), _jm(C2, S1), S2
    f0, f1, f2 = _jm(S3, C1), _jm(S3, S1), (-C3[0], -C3[1], -C3[2])
    O2[3, 0], O2[3, 1], O2[3, 2] = -dl * f0[2], -dl * f1[2], -dl * f2[2]
    O2[4, 0], O2[4, 1], O2[4, 2] = L5 * u0[2], L5 * u1[2], L5 * u2[2]
    O2[5, 0], O2[5, 1], O2[5, 2] = L5 * u0[2] + L4 * f0[2], L5 * u1[2] + L4 * f1[2], L5 * u2[2] + L4 * f2[2]
    R2[0, 0, 0], R2[0, 1, 0] = C1[2], S1[2]
    R2[0, 0, 1], R2[0, 1, 1] = -S1[2], C1[2]
    for fr in range(1, 6):
        if fr == 1 or fr == 3:
            x0, x1, x2 = u0, u1, u2
        elif fr == 2:
            x0, x1, x2 = (-f0[0], -f0[1], -f0[2]), (-f1[0], -f1[1], -f1[2]), (-f2[0], -f2[1], -f2[2])
        else:
            x0, x1, x2 = f0, f1, f2
        R2[fr, 0, 0], R2[fr, 1, 0], R2[fr, 2, 0] = x0[2], x1[2], x2[2]
        R2[fr, 0, 1], R2[fr, 1, 1] = S1[2], -C1[2]
        R2[fr, 0, 2], R2[fr, 1, 2] = _jm(x2, C1)[2], _jm(x2, S1)[2]
        R2[fr, 2, 2] = -_jm(x0, C1)[2] - _jm(x1, S1)[2]


@njit(cache=True)
def comp_scratch():
    """Scratch arrays of :func:`_compensation`, zeroed: O, ∂O, R, ∂R, D²O, D²R, J_v, J_ω."""
    return (np.zeros((6, 3)), np.zeros((6, 3, 3)), np.zeros((6, 3, 3)), np.zeros((6, 3, 3, 3)),
            np.zeros((6, 3)), np.zeros((6, 3, 3)), np.zeros((3, 3)), np.zeros((3, 3)))


@njit(cache=True)
def _compensation(c1, s1, c2, s2, c3, s3, qd, qdd, kin, bfr, bw, bm, bcom, bI, rotor, sc, out):
    """M̂(q) q̂̈ + Ĉ(q, q̂̇) q̂̇ into out (3,): the torque of ``firmware.compensation_torque`` in closed form, from the
    cosines and sines of q (the kinematics' own: no further trig call).

    The reference sums M̂ = Σ_b w_b (m J_vᵀJ_v + J_ωᵀ R I Rᵀ J_ω) + diag(rotor) (``dynamics_numpy.body_mass_matrices``)
    and takes Ĉ q̂̇ = Ṁ q̂̇ − ½ ∂(q̂̇ᵀ M̂ q̂̇)/∂q by central differences of M̂ (h = 1e-6 rad, 7 mass matrices). The same
    torque, as Lagrange's equations give it body by body (Newton–Euler projected on the joints):
    Σ_b w_b (J_vᵀ m (J_v q̂̈ + a_b) + J_ωᵀ (I (J_ω q̂̈ + α_b) + ω_b × I ω_b)) + rotor q̂̈, in body axes (J_ω = vee(Rᵀ ∂R/∂q),
    ω_b = J_ω q̂̇), with the velocity-product accelerations a_b = D²c_b and α_b = vee of the skew part of Rᵀ D²R (D²
    along q̂̇: :func:`_frames_dd`). The frames' derivatives are exact (the reference's complex step gives them to
    rounding); the difference to the reference is its central difference's truncation O(h²) and rounding (ε|M̂|/h):
    both below the reference's own sensitivity to its rounding (docs/performance.md §2).

    The loop does not call this per tick: it identifies M̂'s basis coefficients from it once per plant and model
    (:func:`mass_basis`) and evaluates :func:`_compensation_basis`, a few times cheaper than this body sum."""
    O, dO, R, dR, O2, R2, Jv, Jw = sc
    _frames(c1, s1, c2, s2, c3, s3, kin[0], kin[1], kin[2], kin[3], O, dO, R, dR)
    _frames_dd(c1, s1, c2, s2, c3, s3, qd, kin[0], kin[1], kin[2], O2, R2)
    t0 = t1 = t2 = 0.0
    for b in range(bfr.shape[0]):
        w = bw[b]
        if w == 0.0:
            continue
        f = bfr[b]
        cx, cy, cz = bcom[b, 0], bcom[b, 1], bcom[b, 2]
        for k in range(3):
            for i in range(3):  # J_v = ∂(o + R com)/∂q
                Jv[i, k] = dO[f, i, k] + (dR[f, i, 0, k] * cx + dR[f, i, 1, k] * cy + dR[f, i, 2, k] * cz)
            # body-axes angular velocity per unit q̇_k: vee(Rᵀ ∂R/∂q_k)
            Jw[0, k] = R[f, 0, 2] * dR[f, 0, 1, k] + R[f, 1, 2] * dR[f, 1, 1, k] + R[f, 2, 2] * dR[f, 2, 1, k]
            Jw[1, k] = R[f, 0, 0] * dR[f, 0, 2, k] + R[f, 1, 0] * dR[f, 1, 2, k] + R[f, 2, 0] * dR[f, 2, 2, k]
            Jw[2, k] = R[f, 0, 1] * dR[f, 0, 0, k] + R[f, 1, 1] * dR[f, 1, 0, k] + R[f, 2, 1] * dR[f, 2, 0, k]
        I = bI[b]
        wm = w * bm[b]
        # CoM acceleration Jv q̂̈ + a, a = D²O + D²R com (the velocity-product part)
        a0 = (Jv[0, 0] * qdd[0] + Jv[0, 1] * qdd[1] + Jv[0, 2] * qdd[2]) + (
            O2[f, 0] + (R2[f, 0, 0] * cx + R2[f, 0, 1] * cy + R2[f, 0, 2] * cz))
        a1 = (Jv[1, 0] * qdd[0] + Jv[1, 1] * qdd[1] + Jv[1, 2] * qdd[2]) + (
            O2[f, 1] + (R2[f, 1, 0] * cx + R2[f, 1, 1] * cy + R2[f, 1, 2] * cz))
        a2 = (Jv[2, 0] * qdd[0] + Jv[2, 1] * qdd[1] + Jv[2, 2] * qdd[2]) + (
            O2[f, 2] + (R2[f, 2, 0] * cx + R2[f, 2, 1] * cy + R2[f, 2, 2] * cz))
        # body-axes ω = J_ω q̂̇ and angular acceleration J_ω q̂̈ + α, α = vee(skew(Rᵀ D²R))
        w0 = Jw[0, 0] * qd[0] + Jw[0, 1] * qd[1] + Jw[0, 2] * qd[2]
        w1 = Jw[1, 0] * qd[0] + Jw[1, 1] * qd[1] + Jw[1, 2] * qd[2]
        w2 = Jw[2, 0] * qd[0] + Jw[2, 1] * qd[1] + Jw[2, 2] * qd[2]
        x21 = R[f, 0, 2] * R2[f, 0, 1] + R[f, 1, 2] * R2[f, 1, 1] + R[f, 2, 2] * R2[f, 2, 1]
        x12 = R[f, 0, 1] * R2[f, 0, 2] + R[f, 1, 1] * R2[f, 1, 2] + R[f, 2, 1] * R2[f, 2, 2]
        x02 = R[f, 0, 0] * R2[f, 0, 2] + R[f, 1, 0] * R2[f, 1, 2] + R[f, 2, 0] * R2[f, 2, 2]
        x20 = R[f, 0, 2] * R2[f, 0, 0] + R[f, 1, 2] * R2[f, 1, 0] + R[f, 2, 2] * R2[f, 2, 0]
        x10 = R[f, 0, 1] * R2[f, 0, 0] + R[f, 1, 1] * R2[f, 1, 0] + R[f, 2, 1] * R2[f, 2, 0]
        x01 = R[f, 0, 0] * R2[f, 0, 1] + R[f, 1, 0] * R2[f, 1, 1] + R[f, 2, 0] * R2[f, 2, 1]
        al0 = (Jw[0, 0] * qdd[0] + Jw[0, 1] * qdd[1] + Jw[0, 2] * qdd[2]) + 0.5 * (x21 - x12)
        al1 = (Jw[1, 0] * qdd[0] + Jw[1, 1] * qdd[1] + Jw[1, 2] * qdd[2]) + 0.5 * (x02 - x20)
        al2 = (Jw[2, 0] * qdd[0] + Jw[2, 1] * qdd[1] + Jw[2, 2] * qdd[2]) + 0.5 * (x10 - x01)
        Iw0 = I[0, 0] * w0 + I[0, 1] * w1 + I[0, 2] * w2
        Iw1 = I[1, 0] * w0 + I[1, 1] * w1 + I[1, 2] * w2
        Iw2 = I[2, 0] * w0 + I[2, 1] * w1 + I[2, 2] * w2
        h0 = I[0, 0] * al0 + I[0, 1] * al1 + I[0, 2] * al2 + (w1 * Iw2 - w2 * Iw1)
        h1 = I[1, 0] * al0 + I[1, 1] * al1 + I[1, 2] * al2 + (w2 * Iw0 - w0 * Iw2)
        h2 = I[2, 0] * al0 + I[2, 1] * al1 + I[2, 2] * al2 + (w0 * Iw1 - w1 * Iw0)
        # the body's wrench projected on the joints: J_vᵀ m acc + J_ωᵀ (I α + ω × I ω)
        t0 += wm * (Jv[0, 0] * a0 + Jv[1, 0] * a1 + Jv[2, 0] * a2) + w * (Jw[0, 0] * h0 + Jw[1, 0] * h1 + Jw[2, 0] * h2)
        t1 += wm * (Jv[0, 1] * a0 + Jv[1, 1] * a1 + Jv[2, 1] * a2) + w * (Jw[0, 1] * h0 + Jw[1, 1] * h1 + Jw[2, 1] * h2)
        t2 += wm * (Jv[0, 2] * a0 + Jv[1, 2] * a1 + Jv[2, 2] * a2) + w * (Jw[0, 2] * h0 + Jw[1, 2] * h1 + Jw[2, 2] * h2)
    out[0] = t0 + rotor[0] * qdd[0]
    out[1] = t1 + rotor[1] * qdd[1]
    out[2] = t2 + rotor[2] * qdd[2]


# M̂ in a trig basis: the loop's per-tick compensation. The arm turns rigidly about the vertical axis (M̂ does not depend
# on θ1), and every entry of M̂ is a polynomial of degree ≤ 2 in (cos θ2, sin θ2, cos θ3, sin θ3): a body on a link frame
# has its CoM and its body-axes angular velocity per unit q̇ linear in them (in turret axes; the frames turn by θ2 or θ3
# about the horizontal axis, their origins move along u(θ2), f(θ3)), and the kinetic energy is quadratic in those. So
# M̂(θ2, θ3) = Σ_k ψ_k(θ2, θ3) C_k exactly, over the 13 functions
#     ψ = (1, cos θ2, sin θ2, cos 2θ2, sin 2θ2, cos θ3, sin θ3, cos 2θ3, sin 2θ3,
#          cos θ2 cos θ3, cos θ2 sin θ3, sin θ2 cos θ3, sin θ2 sin θ3),
# with C_k symmetric 3×3 matrices fixed by the bodies (and the rotor inertia in C_0). Ĉ q̂̇ = Ṁ q̂̇ − ½ ∂(q̂̇ᵀ M̂ q̂̇)/∂q
# then needs only ∂ψ/∂θ2, ∂ψ/∂θ3 (closed form): about 250 multiply-adds a tick instead of the frames and their second
# derivatives body by body (:func:`_compensation`, from which :func:`mass_basis` identifies the C_k once per plant and model).
N_BASIS = 13
#: M̂'s six entries, the coefficient columns: (row, column) of M11, M12, M13, M22, M23, M33
_ENTRY_I = (0, 0, 0, 1, 1, 2)
_ENTRY_J = (0, 1, 2, 1, 2, 2)
#: identification grid points per angle: ψ's products hold harmonics ≤ 4 in each angle, so 8 points resolve them
_GRID = 8


@njit(cache=True, inline="always")
def _basis(c2, s2, c3, s3, bs):
    """ψ and its partial derivatives ∂ψ/∂θ2, ∂ψ/∂θ3 at (θ2, θ3) from their cosines and sines into bs (3, 13)."""
    C2, S2 = c2 * c2 - s2 * s2, 2.0 * (c2 * s2)
    C3, S3 = c3 * c3 - s3 * s3, 2.0 * (c3 * s3)
    cc, cs, sc_, ss = c2 * c3, c2 * s3, s2 * c3, s2 * s3
    bs[0, 0], bs[0, 1], bs[0, 2], bs[0, 3], bs[0, 4] = 1.0, c2, s2, C2, S2
    bs[0, 5], bs[0, 6], bs[0, 7], bs[0, 8] = c3, s3, C3, S3
    bs[0, 9], bs[0, 10], bs[0, 11], bs[0, 12] = cc, cs, sc_, ss
    bs[1, 0], bs[1, 1], bs[1, 2], bs[1, 3], bs[1, 4] = 0.0, -s2, c2, -2.0 * S2, 2.0 * C2
    bs[1, 5], bs[1, 6], bs[1, 7], bs[1, 8] = 0.0, 0.0, 0.0, 0.0
    bs[1, 9], bs[1, 10], bs[1, 11], bs[1, 12] = -sc_, -ss, cc, cs
    bs[2, 0], bs[2, 1], bs[2, 2], bs[2, 3], bs[2, 4] = 0.0, 0.0, 0.0, 0.0, 0.0
    bs[2, 5], bs[2, 6], bs[2, 7], bs[2, 8] = -s3, c3, -2.0 * S3, 2.0 * C3
    bs[2, 9], bs[2, 10], bs[2, 11], bs[2, 12] = -cs, cc, -ss, sc_


@njit(cache=True)
def _compensation_basis(c2, s2, c3, s3, qd, qdd, coef, bs, md, out):
    """M̂ q̂̈ + Ĉ q̂̇ into out (3,) from M̂'s basis coefficients coef (13, 6) (:func:`mass_basis`) at θ2, θ3 given by
    their cosines and sines (the kinematics' own). bs (3, 13), md (3, 6): scratch (allocated once per chunk).

    md rows: M̂, ∂M̂/∂θ2, ∂M̂/∂θ3 (six entries each); Ṁ = q̂̇2 ∂M̂/∂θ2 + q̂̇3 ∂M̂/∂θ3 (∂M̂/∂θ1 = 0) and
    ½ ∂(q̂̇ᵀ M̂ q̂̇)/∂q = ½ (0, q̂̇ᵀ ∂M̂/∂θ2 q̂̇, q̂̇ᵀ ∂M̂/∂θ3 q̂̇)."""
    _basis(c2, s2, c3, s3, bs)
    for r in range(3):  # md[r, e] = Σ_k bs[r, k] coef[k, e], summed in k order (the six entries side by side)
        for e in range(6):
            md[r, e] = 0.0
        for k in range(N_BASIS):
            b = bs[r, k]
            for e in range(6):
                md[r, e] += b * coef[k, e]
    t0 = t1 = t2 = 0.0
    g2 = g3 = 0.0
    v1, v2 = qd[1], qd[2]
    for e in range(6):
        i, j = _ENTRY_I[e], _ENTRY_J[e]
        m, d2, d3 = md[0, e], md[1, e], md[2, e]
        dm = v1 * d2 + v2 * d3  # Ṁ_ij
        a = m * qdd[j] + dm * qd[j]  # row i, column j of M̂ q̂̈ + Ṁ q̂̇
        w = qd[i] * qd[j]
        if i != j:
            b = m * qdd[i] + dm * qd[i]  # the symmetric entry (row j, column i)
            w = 2.0 * w
        else:
            b = 0.0
        g2 += d2 * w
        g3 += d3 * w
        if i == 0:
            t0 += a
        elif i == 1:
            t1 += a
        else:
            t2 += a
        if i != j:
            if j == 1:
                t1 += b
            else:
                t2 += b
    out[0] = t0
    out[1] = t1 - 0.5 * g2
    out[2] = t2 - 0.5 * g3


@njit(cache=True)
def _mass_matrix_bodies(q1, q2, q3, kin, bfr, bw, bm, bcom, bI, rotor, sc, M):
    """M̂(q) (3, 3) by :func:`_compensation` (q̂̇ = 0, q̂̈ the unit vectors: its columns) into M."""
    z = np.zeros(3)
    e = np.zeros(3)
    col = np.empty(3)
    c1, s1, c2, s2, c3, s3 = math.cos(q1), math.sin(q1), math.cos(q2), math.sin(q2), math.cos(q3), math.sin(q3)
    for j in range(3):
        e[:] = 0.0
        e[j] = 1.0
        _compensation(c1, s1, c2, s2, c3, s3, z, e, kin, bfr, bw, bm, bcom, bI, rotor, sc, col)
        for i in range(3):
            M[i, j] = col[i]


@njit(cache=True)
def mass_basis(kin, bfr, bw, bm, bcom, bI, rotor):
    """M̂'s coefficients (13, 6) in the basis ψ (see above), identified from the body-by-body M̂ (:func:`_compensation`)
    on a uniform _GRID × _GRID grid of (θ2, θ3) (θ1 = 0) by the discrete Fourier sums (exact for ψ's harmonics on
    this grid; fixed summation order, no BLAS: the coefficients do not depend on the BLAS kernel)."""
    sc = comp_scratch()
    coef = np.zeros((N_BASIS, 6))
    bs = np.empty((3, N_BASIS))
    M = np.empty((3, 3))
    n = _GRID
    for a in range(n):
        t2 = 2.0 * math.pi * a / n
        for b in range(n):
            t3 = 2.0 * math.pi * b / n
            _mass_matrix_bodies(0.0, t2, t3, kin, bfr, bw, bm, bcom, bI, rotor, sc, M)
            _basis(math.cos(t2), math.sin(t2), math.cos(t3), math.sin(t3), bs)
            for k in range(N_BASIS):
                for e in range(6):
                    coef[k, e] += bs[0, k] * M[_ENTRY_I[e], _ENTRY_J[e]]
    for k in range(N_BASIS):  # ⟨ψ_k, ψ_k⟩ on the grid: n² (constant), n²/2 (one harmonic), n²/4 (products)
        norm = 1.0 if k == 0 else (2.0 if k < 9 else 4.0)
        for e in range(6):
            coef[k, e] *= norm / (n * n)
    return coef


@njit(cache=True)
def mass_basis_residual(coef, kin, bfr, bw, bm, bcom, bI, rotor):
    """max |Σ ψ_k C_k − M̂| / max |M̂| over 16 poses off the identification grid (θ1 ≠ 0 included), M̂ body by body:
    rounding (≈ 1e-16) when M̂ is in the basis, O(1) when not."""
    sc = comp_scratch()
    bs = np.empty((3, N_BASIS))
    M = np.empty((3, 3))
    err = 0.0
    big = 0.0
    for p in range(16):
        t1, t2, t3 = 0.7 * p, 0.3 + 1.3 * p, -0.2 + 0.9 * p
        _mass_matrix_bodies(t1, t2, t3, kin, bfr, bw, bm, bcom, bI, rotor, sc, M)
        _basis(math.cos(t2), math.sin(t2), math.cos(t3), math.sin(t3), bs)
        for e in range(6):
            acc = 0.0
            for k in range(N_BASIS):
                acc += bs[0, k] * coef[k, e]
            ref = M[_ENTRY_I[e], _ENTRY_J[e]]
            err = max(err, abs(acc - ref), abs(M[_ENTRY_J[e], _ENTRY_I[e]] - ref))
            big = max(big, abs(ref))
    return err / big if big > 0.0 else (0.0 if err == 0.0 else np.inf)


@njit(cache=True)
def compensation(q, qd, qdd, coef):
    """:func:`_compensation_basis` (the loop's per-tick torque) with its own scratch (for tests: one call)."""
    out = np.empty(3)
    _compensation_basis(math.cos(q[1]), math.sin(q[1]), math.cos(q[2]), math.sin(q[2]), qd, qdd, coef,
                        np.empty((3, N_BASIS)), np.empty((3, 6)), out)
    return out


@njit(cache=True)
def master_chunk(m_addr, d_addr, off, start, end, nstep,
                 qpos, qvel, qacc, ctrl, qs, qfa, site_xpos, site,
                 qa, hq, hd, REF, DREF, par, flg, q0, K, B, anchor, half,
                 st, ist, dbuf,
                 P, TAU, FREF, EF, has_ef, clock, HQ, HV, HA, EQF, x0, chk_f, every, coef):
    """Ticks from ``start`` (a window boundary) of ``MasterPlant.run`` with ``MasterController.step`` (with or without
    dynamics compensation), window by window (``every`` ticks), until the end of the first window holding a possibly bad
    tick (returned: the plant checks that window exactly) or ``end`` (returns −1: no tick was). "Possibly bad":
    the plant's rule with margins (non-finite handle, further than RUNAWAY·(1 − 1e-12) from x0, MuJoCo's clock
    reset); chk_f: RUNAWAY, T. EF: the closure residual max_j |efc_pos[j]| over the n_closure rows (as numpy's
    ``np.abs(rows).max()``: exact, NaN when one is), where a tick has them (has_ef).

    par: count scale (counts per rad), angle scale (rad per count), T, alpha, L5, L4, h, Kb, Bb, lim, g1, g2;
    flg: quantize, env, gravity compensation, saturation, has_hand, n_closure, eq_hand, eq_type, delay, compensation;
    st: p_prev(3), v(3), F(3), q_prev(3), q̂̇(3), q̂̈(3); ist: delay position, compensation samples seen;
    coef: the compensation model's M̂ in the trig basis (:func:`mass_basis`; (13, 6)); off: mjData offsets (time, nefc,
    efc_pos, efc_force, efc_type, efc_id)."""
    cscale, ascale, T, a = par[0], par[1], par[2], par[3]
    L5, L4, hgt, Kb, Bb, lim, g1, g2 = par[4], par[5], par[6], par[7], par[8], par[9], par[10], par[11]
    quantize, env, gcomp, saturation, has_hand = flg[0], flg[1], flg[2], flg[3], flg[4]
    n, eq_hand, eq_type, D, comp = flg[5], flg[6], flg[7], flg[8], flg[9]
    off_time, off_nefc, off_pos, off_force, off_type, off_id = off[0], off[1], off[2], off[3], off[4], off[5]
    q = np.empty(3)
    p = np.empty(3)
    v = np.empty(3)
    F = np.empty(3)
    Jm = np.empty((3, 3))
    tau = np.empty(3)
    cmd = np.empty(3)
    rows = np.empty(3, dtype=np.intp)
    qdn = np.empty(3)
    qddn = np.empty(3)
    ctau = np.empty(3)
    bs = np.empty((3, N_BASIS))  # compensation scratch (once per chunk, not per tick)
    md = np.empty((3, 6))
    runaway, Tp = chk_f[0], chk_f[1]
    suspect = False
    for k in range(start, end):
        for i in range(3):  # encoder counts → joint angles (controller.joint_angles)
            c = (qpos[qa[i]] - q0[i]) * cscale
            if quantize:
                c = np.rint(c)
            q[i] = q0[i] + c * ascale
        t1, t2, t3 = q[0], q[1], q[2]
        c1, s1, c2, s2, c3, s3 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2), math.cos(t3), math.sin(t3)
        rho = L5 * c2 + L4 * s3
        p[0] = rho * c1
        p[1] = rho * s1
        p[2] = hgt + L5 * s2 - L4 * c3
        Jm[0, 0], Jm[0, 1], Jm[0, 2] = -rho * s1, -L5 * s2 * c1, L4 * c3 * c1
        Jm[1, 0], Jm[1, 1], Jm[1, 2] = rho * c1, -L5 * s2 * s1, L4 * c3 * s1
        Jm[2, 0], Jm[2, 1], Jm[2, 2] = 0.0, L5 * c2, L4 * s3
        for i in range(3):
            diff = (p[i] - st[i]) / T
            v[i] = a * st[3 + i] + (1.0 - a) * diff if a > 0.0 else diff
            delta = p[i] - anchor[i]
            if env == ENV_SPRING:
                F[i] = -K[i] * delta - B[i] * v[i]
            elif env == ENV_BOX:
                depth = abs(delta) - half[i]
                sgn = np.sign(delta)
                F[i] = -Kb * sgn * depth - Bb * v[i] if depth > 0.0 else 0.0
            else:
                F[i] = 0.0
        for j in range(3):  # Jᵀ F
            tau[j] = F[0] * Jm[0, j] + F[1] * Jm[1, j] + F[2] * Jm[2, j]
        if comp:  # MasterController._compensation: cascaded filtered differences, M̂ q̂̈ + Ĉ q̂̇ from the third sample
            ns = ist[1]
            ist[1] = ns + 1
            if ns == 0:
                for i in range(3):
                    st[9 + i] = q[i]
                    tau[i] = tau[i] + 0.0  # the reference adds zeros (−0.0 → 0.0)
            else:
                for i in range(3):
                    diff = (q[i] - st[9 + i]) / T
                    qdn[i] = diff if ns == 1 else a * st[12 + i] + (1.0 - a) * diff
                if ns >= 2:
                    for i in range(3):
                        d2 = (qdn[i] - st[12 + i]) / T
                        qddn[i] = d2 if ns == 2 else a * st[15 + i] + (1.0 - a) * d2
                        st[15 + i] = qddn[i]
                for i in range(3):
                    st[9 + i] = q[i]
                    st[12 + i] = qdn[i]
                if ns >= 2:
                    _compensation_basis(c2, s2, c3, s3, qdn, qddn, coef, bs, md, ctau)
                else:
                    ctau[:] = 0.0
                for j in range(3):
                    tau[j] = tau[j] + ctau[j]
        if gcomp:
            tau[0] = tau[0] + 0.0
            tau[1] = tau[1] + g1 * c2  # math.cos(q[1]), math.sin(q[2]): the kinematics' own values
            tau[2] = tau[2] + g2 * s3
        if saturation:
            for j in range(3):
                tau[j] = _clip(tau[j], lim)
        for i in range(3):
            st[i] = p[i]
            st[3 + i] = v[i]
            st[6 + i] = F[i]
        _delayed(tau, dbuf, ist, 0, D, cmd)
        for j in range(3):
            ctrl[j] = cmd[j]
        if has_hand:
            for j in range(3):
                qs[hq[j]] = REF[k, j]
                qfa[hd[j]] = DREF[k, j]
        for _ in range(nstep):
            _mj_step(m_addr, d_addr)
        for j in range(3):
            P[k, j] = site_xpos[site, j]
            TAU[k, j] = cmd[j]
            FREF[k, j] = F[j]
        nefc = _i32(d_addr + off_nefc, 0)
        if n > 0 and nefc >= n:
            ep = _ptr(d_addr + off_pos)
            mx = abs(_f64(ep, 0))
            for j in range(1, n):
                x = abs(_f64(ep, j))
                if x > mx or math.isnan(x):  # NaN wins (and stays: no comparison with it holds)
                    mx = x
            EF[k] = mx
            has_ef[k] = True
        clock[k] = _f64(d_addr + off_time, 0)
        if has_hand:
            for j in range(3):
                HQ[k, j] = qpos[hq[j]]
                HV[k, j] = qvel[hd[j]]
                HA[k, j] = qacc[hd[j]]
            # the hand connect's efc rows (equality rows lead efc, in equality order): its force on the hand
            et, ei = _ptr(d_addr + off_type), _ptr(d_addr + off_id)
            nr = 0
            for r_ in range(nefc):
                if _i32(et, r_) == eq_type and _i32(ei, r_) == eq_hand:
                    if nr < 3:
                        rows[nr] = r_
                    nr += 1
            if nr == 3:
                ef = _ptr(d_addr + off_force)
                for j in range(3):
                    EQF[k, j] = -_f64(ef, rows[j])
        for j in range(3):  # prefilter of the window check (conservative: see the docstring)
            if not (abs(P[k, j] - x0[j]) <= runaway * (1.0 - 1e-12)):  # also NaN / inf
                suspect = True
        if clock[k] < (k + 0.5) * Tp * (1.0 + 1e-9):
            suspect = True
        if suspect and ((k + 1) % every == 0 or k + 1 == end):
            return k + 1
    return -1


def warm() -> None:
    """Load (or compile) the master's kernels: zero ticks on dummy arrays (no MuJoCo call is made)."""
    f, i = np.zeros(16), np.zeros(16, dtype=np.int64)
    x = np.zeros(3, dtype=np.int64)
    a2 = np.zeros((1, 3))
    master_chunk(0, 0, i, 0, 0, 1, f, f, f, f, f, f, a2, 0, x, x, x, a2, a2, f, i, f, f, f, f, f,
                 f, i, a2, a2, a2, a2, f, np.zeros(1, dtype=np.bool_), f, a2, a2, a2, a2, f, f, 1,
                 np.zeros((N_BASIS, 6)))
    body = (f, x, f, f, np.zeros((1, 3)), np.zeros((1, 3, 3)), f)
    mass_basis_residual(mass_basis(*body), *body)

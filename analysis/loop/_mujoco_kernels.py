"""numba kernels of :mod:`hapticopt.analysis.loop.mujoco_compiled` (imported only through it, after
``libmujoco`` is loaded for the linker). Each kernel runs ticks [start, end) of one plant's loop and
mirrors the Python loop and controller it replaces operation by operation (same order, no fused
multiply-add: numba does not contract without ``fastmath``), so the records are bit-identical."""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

#: environment kinds of the compiled 3-PRRR / master firmwares
ENV_FREE, ENV_SPRING, ENV_BOX, ENV_FORCE = 0, 1, 2, 3
#: force loops of the compiled 3-PRRR firmware (hapticopt.analysis.prrr.firmware.ForceLoop)
LOOP_SEA, LOOP_RIGID, LOOP_IDEAL = 0, 1, 2

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


# --------------------------------------------------------------------------------------- 3-PRRR
@njit(cache=True)
def prrr_chunk(m_addr, d_addr, off, start, end, nstep,
               qpos, qvel, qacc, ctrl, energy, qs, qfa,
               sl_idx, mo_idx, spr_idx, hd_idx, REF, DREF,
               par, flg, J, K, B, anchor, half, famp, fphase,
               st, ist, dbuf,
               Qp, Qv, Qa, KE, clock, CMD, Fref, EF,
               ee_idx, mo_e, Kst, chk_f, chk_i):
    """Ticks from ``start`` (a window boundary) of ``MujocoPlant.run`` with ``NumpyController._step_scalar``
    (interpolation 1), window by window (``check_every`` ticks), until the end of the first window that holds a
    possibly bad tick (returned: the plant checks that window exactly) or ``end`` (returns −1: no tick was).

    "Possibly bad" is the plant's ``_window_bad`` rule with margins (MuJoCo's clock reset, a non-finite or
    |p| ≥ 1 m end-effector, the energy over ``explode`` less a margin of 1e-9 of its terms' sum), so a window it
    passes is clean however numpy rounds and sums the same quantities; chk_f: explode, spring, T; chk_i:
    check_every, whether the spring deflection (mo_e − slider) counts.

    par: inv_res, res, T, alpha, Kb, Bb, fomega, fc, fcv, weight, spring, kp, kiT, lim, eta, gain;
    flg: quantize, has_motor, env, friction, gravity, loop, integral, saturation, has_hand, n_eq, delay;
    st: p_prev(3), v(3), integral(3), F(3); ist: tick, delay position; dbuf: (delay, 3) commands.
    off: mjData offsets (time, nefc, efc_pos)."""
    inv_res, r, T, a = par[0], par[1], par[2], par[3]
    Kb, Bb, fomega, fc, fcv, weight = par[4], par[5], par[6], par[7], par[8], par[9]
    ks, kp, kiT, lim, eta, gain = par[10], par[11], par[12], par[13], par[14], par[15]
    quantize, has_motor, env, friction, gravity = flg[0], flg[1], flg[2], flg[3], flg[4]
    loop, integral, saturation, has_hand, n_eq, D = flg[5], flg[6], flg[7], flg[8], flg[9], flg[10]
    off_time, off_nefc, off_efc_pos = off[0], off[1], off[2]
    sc = np.empty(3)
    dc = np.empty(3)
    p = np.empty(3)
    v = np.empty(3)
    F = np.empty(3)
    fr = np.empty(3)
    out = np.empty(3)
    cmd = np.empty(3)
    explode, spring_e, Tp = chk_f[0], chk_f[1], chk_f[2]
    every, mo_chk = chk_i[0], chk_i[1]
    suspect = False
    for k in range(start, end):
        # encoders: slider counts and spring deflection counts (motor − slider), rounded when quantised
        for i in range(3):
            s = qpos[sl_idx[i]]
            y = s * inv_res
            dd = (qpos[mo_idx[i]] - s) * inv_res if has_motor else 0.0
            if quantize:
                y = np.rint(y)
                dd = np.rint(dd)
            sc[i] = y * r
            dc[i] = dd
        for i in range(3):  # (counts · res) @ Jᵀ
            p[i] = sc[0] * J[i, 0] + sc[1] * J[i, 1] + sc[2] * J[i, 2]
        for i in range(3):
            if a > 0.0:
                v[i] = a * st[3 + i] + (1.0 - a) * ((p[i] - st[i]) / T)
            else:
                v[i] = (p[i] - st[i]) / T
        if env == ENV_FREE:
            F[0] = 0.0
            F[1] = 0.0
            F[2] = 0.0
        elif env == ENV_SPRING:
            for i in range(3):
                F[i] = -K[i] * (p[i] - anchor[i]) - B[i] * v[i]
        elif env == ENV_BOX:  # inside
            for i in range(3):
                F[i] = 0.0
                dl = p[i] - anchor[i]
                depth = abs(dl) - half[i]
                if depth > 0.0:
                    sgn = 1.0 if dl > 0.0 else (-1.0 if dl < 0.0 else 0.0)
                    F[i] = -Kb * sgn * depth - Bb * v[i]
        else:  # ENV_FORCE
            ph = fomega * (ist[0] * T)
            for i in range(3):
                F[i] = famp[i] * math.sin(ph + fphase[i])
        if friction:
            F[0] = F[0] + fc * math.tanh(v[0] / fcv)
            F[1] = F[1] + fc * math.tanh(v[1] / fcv)
            F[2] = F[2] + 0.0
        if gravity:
            F[2] = F[2] + weight
        for j in range(3):  # F @ J
            fr[j] = F[0] * J[0, j] + F[1] * J[1, j] + F[2] * J[2, j]
        for j in range(3):
            if loop == LOOP_SEA:
                err = fr[j] - ks * (dc[j] * r)
                o = kp * err
                if integral:
                    ig = st[6 + j] + kiT * err
                    if saturation:
                        ig = _clip(ig, lim)
                    o = o + ig
                    st[6 + j] = ig
            elif loop == LOOP_RIGID:
                o = fr[j] / eta
            else:
                o = fr[j]
            if saturation:
                o = _clip(o, lim)
            out[j] = o
        ist[0] += 1
        for i in range(3):
            st[i] = p[i]
            st[3 + i] = v[i]
            st[9 + i] = F[i]
        # delay line (FIFO of D commands, zeros at start)
        if D > 0:
            pos = ist[1]
            for j in range(3):
                cmd[j] = dbuf[pos, j]
                dbuf[pos, j] = out[j]
            ist[1] = (pos + 1) % D
        else:
            for j in range(3):
                cmd[j] = out[j]
        for j in range(3):
            ctrl[j] = cmd[j] * gain
        if has_hand:
            for j in range(3):
                qs[spr_idx[j]] = REF[k, j]
                qfa[hd_idx[j]] = DREF[k, j]
        for _ in range(nstep):
            _mj_step(m_addr, d_addr)
        Qp[k, :] = qpos
        Qv[k, :] = qvel
        Qa[k, :] = qacc
        KE[k] = energy[1]
        clock[k] = _f64(d_addr + off_time, 0)
        for j in range(3):
            CMD[k, 0, j] = cmd[j]
            Fref[k, j] = F[j]
        if n_eq > 0 and _i32(d_addr + off_nefc, 0) >= n_eq:
            efc = _ptr(d_addr + off_efc_pos)
            for j in range(n_eq):
                EF[k, j] = _f64(efc, j)
        # prefilter of the window check (conservative: see the docstring)
        e = KE[k]
        scale = abs(e)
        for i in range(3):
            x = qpos[ee_idx[i]]
            if not (abs(x) < 1.0 - 1e-12):  # also NaN
                suspect = True
            t = 0.5 * (Kst[i] * (x * x))
            e += t
            scale += abs(t)
            if mo_chk:
                dfl = qpos[mo_e[i]] - qpos[sl_idx[i]]
                t = 0.5 * spring_e * (dfl * dfl)
                e += t
                scale += abs(t)
        if not (e < explode - 1e-9 * scale) or clock[k] < (k + 0.5) * Tp * (1.0 + 1e-9):
            suspect = True
        if suspect and ((k + 1) % every == 0 or k + 1 == end):
            return k + 1
    return -1


# --------------------------------------------------------------------------------------- master
@njit(cache=True)
def master_chunk(m_addr, d_addr, off, start, end, nstep,
                 qpos, qvel, qacc, ctrl, qs, qfa, site_xpos, site,
                 qa, hq, hd, REF, DREF, par, flg, q0, K, B, anchor, half,
                 st, ist, dbuf,
                 P, TAU, FREF, EFR, has_ef, clock, HQ, HV, HA, EQF, x0, chk_f, every):
    """Ticks from ``start`` (a window boundary) of ``MasterPlant.run`` with ``MasterController.step`` (no dynamics
    compensation), window by window (``every`` ticks), until the end of the first window holding a possibly bad
    tick (returned: the plant checks that window exactly) or ``end`` (returns −1: no tick was). "Possibly bad":
    the plant's rule with margins (non-finite handle, further than RUNAWAY·(1 − 1e-12) from x0, MuJoCo's clock
    reset); chk_f: RUNAWAY, T.

    par: count scale (counts per rad), angle scale (rad per count), T, alpha, L5, L4, h, Kb, Bb, lim, g1, g2;
    flg: quantize, env, gravity compensation, saturation, has_hand, n_closure, eq_hand, eq_type, delay;
    st: p_prev(3), v(3), F(3); ist: delay position; off: mjData offsets (time, nefc, efc_pos, efc_force,
    efc_type, efc_id)."""
    cscale, ascale, T, a = par[0], par[1], par[2], par[3]
    L5, L4, hgt, Kb, Bb, lim, g1, g2 = par[4], par[5], par[6], par[7], par[8], par[9], par[10], par[11]
    quantize, env, gcomp, saturation, has_hand = flg[0], flg[1], flg[2], flg[3], flg[4]
    n, eq_hand, eq_type, D = flg[5], flg[6], flg[7], flg[8]
    off_time, off_nefc, off_pos, off_force, off_type, off_id = off[0], off[1], off[2], off[3], off[4], off[5]
    q = np.empty(3)
    p = np.empty(3)
    v = np.empty(3)
    F = np.empty(3)
    Jm = np.empty((3, 3))
    tau = np.empty(3)
    cmd = np.empty(3)
    rows = np.empty(3, dtype=np.intp)
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
        if gcomp:
            tau[0] = tau[0] + 0.0
            tau[1] = tau[1] + g1 * math.cos(q[1])
            tau[2] = tau[2] + g2 * math.sin(q[2])
        if saturation:
            for j in range(3):
                tau[j] = _clip(tau[j], lim)
        for i in range(3):
            st[i] = p[i]
            st[3 + i] = v[i]
            st[6 + i] = F[i]
        if D > 0:
            pos = ist[0]
            for j in range(3):
                cmd[j] = dbuf[pos, j]
                dbuf[pos, j] = tau[j]
            ist[0] = (pos + 1) % D
        else:
            for j in range(3):
                cmd[j] = tau[j]
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
        if nefc >= n:
            ep = _ptr(d_addr + off_pos)
            for j in range(n):
                EFR[k, j] = _f64(ep, j)
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
    """Load (or compile) both kernels: zero ticks on dummy arrays (no MuJoCo call is made)."""
    f, i = np.zeros(16), np.zeros(16, dtype=np.int64)
    x = np.zeros(3, dtype=np.int64)
    a2, a3 = np.zeros((1, 3)), np.zeros((1, 1, 3))
    prrr_chunk(0, 0, x, 0, 0, 1, f, f, f, f, f, f, f, x, x, x, x, a2, a2, f, i, np.zeros((3, 3)), f, f, f, f, f, f,
               f, i, a2, a2, a2, a2, f, f, a3, a2, a2, x, x, f, f, i)
    master_chunk(0, 0, i, 0, 0, 1, f, f, f, f, f, f, a2, 0, x, x, x, a2, a2, f, i, f, f, f, f, f,
                 f, i, a2, a2, a2, a2, a2, np.zeros(1, dtype=np.bool_), f, a2, a2, a2, a2, f, f, 1)

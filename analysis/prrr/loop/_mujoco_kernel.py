"""The 3-PRRR's compiled MuJoCo tick loop (numba): encoder read, the firmware law, delay line, hand reference,
``mj_step`` and the per-tick records in one native loop (imported only through
:meth:`hapticopt.analysis.prrr.loop.mujoco_plant.MujocoPlant.run`, after :mod:`hapticopt.analysis.loop.mujoco_compiled`
has loaded ``libmujoco`` for the linker).

The law is :func:`hapticopt.analysis.prrr.loop.firmware_law.make_law` instantiated with numba-compiled scalar
primitives (the same Python functions the Python loop calls) and each of its functions ``njit(inline="always")``:
both loops run one definition and their records are bit-identical (tested). numba's on-disk cache keys a function
on its own bytecode and closure values, not on the functions it calls: :func:`prrr_chunk` is built in a closure
that holds the law module's source hash, so an edit of the law recompiles it instead of loading a stale kernel.
"""

from __future__ import annotations

import hashlib
import inspect

import numpy as np
from numba import njit

from hapticopt.analysis.loop._mujoco_kernels import _delayed, _f64, _i32, _mj_step, _ptr
from hapticopt.analysis.prrr.loop import firmware_law

_inline = njit(inline="always")
#: the law's tick, compiled (numba, inlined into the loop)
LAW = firmware_law.make_law(firmware_law.Ops(**{k: _inline(f) for k, f in firmware_law.SCALAR_PRIMITIVES.items()}),
                            _inline)
_law = LAW.tick


def _build(law_hash: str):
    @njit(cache=True)
    def prrr_chunk(m_addr, d_addr, off, start, end, nstep,
                   qpos, qvel, qacc, ctrl, energy, qs, qfa,
                   sl_idx, mo_idx, spr_idx, hd_idx, REF, DREF,
                   par, flg, J, K, B, anchor, half, famp, fphase,
                   lpar, lflg, st, ist, dbuf,
                   Qp, Qv, Qa, KE, clock, CMD, Fref, EF,
                   ee_idx, mo_e, Kst, chk_f, chk_i):
        """Ticks from ``start`` (a window boundary) of ``MujocoPlant.run``, window by window (``check_every``
        ticks), until the end of the first window that holds a possibly bad tick (returned: the plant checks that
        window exactly) or ``end`` (returns −1: no tick was).

        "Possibly bad" is the plant's ``_window_bad`` rule with margins (MuJoCo's clock reset, a non-finite or
        |p| ≥ 1 m end-effector, the energy over ``explode`` less a margin of 1e-9 of its terms' sum), so a window
        it passes is clean however numpy rounds and sums the same quantities; chk_f: explode, spring, T; chk_i:
        check_every, whether the spring deflection (mo_e − slider) counts.

        par … fphase: the law's arguments (:func:`hapticopt.analysis.prrr.loop.firmware.scalar_arguments`); st:
        p_prev, velocity, integral, F_r (12, updated); lpar: 1/res,
        the motor gain; lflg: quantize, has_motor, has_hand, n_eq, delay; ist: tick, delay position; dbuf:
        (delay, 3) commands; off: mjData offsets (time, nefc, efc_pos)."""
        _ = law_hash  # in the closure: numba's cache key (see the module docstring)
        inv_res, gain = lpar[0], lpar[1]
        quantize, has_motor, has_hand, n_eq, D = lflg[0], lflg[1], lflg[2], lflg[3], lflg[4]
        off_time, off_nefc, off_efc_pos = off[0], off[1], off[2]
        sc = np.empty(3)
        dc = np.empty(3)
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
                sc[i] = y
                dc[i] = dd
            p, v, ig, F, o = _law(par, flg, J, K, B, anchor, half, famp, fphase, (st[0], st[1], st[2]),
                                  (st[3], st[4], st[5]), (st[6], st[7], st[8]), ist[0], sc, dc)
            for j in range(3):
                st[j], st[3 + j], st[6 + j], st[9 + j], out[j] = p[j], v[j], ig[j], F[j], o[j]
            ist[0] += 1
            _delayed(out, dbuf, ist, 1, D, cmd)
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
                Fref[k, j] = st[9 + j]
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

    return prrr_chunk


prrr_chunk = _build(hashlib.sha256(inspect.getsource(firmware_law).encode()).hexdigest())


def warm() -> None:
    """Load (or compile) the kernel: zero ticks on dummy arrays (no MuJoCo call is made)."""
    f, i = np.zeros(16), np.zeros(16, dtype=np.int64)
    x = np.zeros(3, dtype=np.int64)
    a2, a3 = np.zeros((1, 3)), np.zeros((1, 1, 3))
    prrr_chunk(0, 0, x, 0, 0, 1, f, f, f, f, f, f, f, x, x, x, x, a2, a2, f, i, f, f, f, f, f, f, f,
               f, i, f, i, a2, a2, a2, a2, f, f, a3, a2, a2, x, x, f, f, i)

"""numba kernel of :func:`hapticopt.analysis.prrr.interference_fast.check_posed` (imported only through
:func:`hapticopt.analysis.prrr.interference_fast.availability`, so numba loads on first use).

One loop over the poses of a chunk and, per pose, over the tested part pairs and their primitive
pairs: the part boxes, the posed primitives (computed once per pose, only for primitives of part pairs
whose boxes meet), the primitives' world boxes, and the separating axes of
:func:`~hapticopt.analysis.prrr.interference_fast._depth`. Every quantity is the numpy reference's, term by
term and in its order (the reference's 3-vector products are fixed-order sums, ``_mm``; numba does not
contract to fused multiply-adds without ``fastmath``), so the depths are bitwise equal. The one
difference in the work done: the reference computes every axis of a pair and clips the smallest overlap
at 0; here a pair stops at the first axis whose overlap is ≤ 0 (its clipped depth is 0 either way).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_BOX, _CYL = 0, 1


@njit(cache=True, inline="always")
def _support(kind, R, h, n0, n1, n2):
    """Projection half-width of one primitive (rotation R (3, 3), half extents h (3,)) on axis n."""
    l0 = abs(n0 * R[0, 0] + n1 * R[1, 0] + n2 * R[2, 0])
    l1 = abs(n0 * R[0, 1] + n1 * R[1, 1] + n2 * R[2, 1])
    l2 = abs(n0 * R[0, 2] + n1 * R[1, 2] + n2 * R[2, 2])
    if kind == _BOX:
        return l0 * h[0] + l1 * h[1] + l2 * h[2]
    if kind == _CYL:
        s = 1.0 - l2 * l2
        return h[2] * l2 + h[0] * math.sqrt(s if s > 0.0 else 0.0)
    return h[0]


@njit(cache=True, inline="always")
def _overlap(ka, Ra, ha, kb, Rb, hb, d, n0, n1, n2):
    """Overlap of the two projections on axis n [m]; +inf for a zero (ignored) axis."""
    if not n0 * n0 + n1 * n1 + n2 * n2 > 0.25:
        return np.inf
    gap = abs(n0 * d[0] + n1 * d[1] + n2 * d[2])
    return _support(ka, Ra, ha, n0, n1, n2) + _support(kb, Rb, hb, n0, n1, n2) - gap


@njit(cache=True, inline="always")
def _unit_overlap(ka, Ra, ha, kb, Rb, hb, d, x0, x1, x2):
    """:func:`_overlap` on x / |x| (the reference's ``_unit``: a zero vector where |x| ≤ 1e-12)."""
    nrm = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    if nrm > 1e-12:
        return _overlap(ka, Ra, ha, kb, Rb, hb, d, x0 / nrm, x1 / nrm, x2 / nrm)
    return np.inf


@njit(cache=True)
def _samples(kind, R, h, c, sgn, rim, out):
    """Surface samples (S, 3) of one primitive (the reference's ``_surface_samples``)."""
    for s in range(sgn.shape[0]):
        if kind == _BOX:
            v0, v1, v2 = sgn[s, 0] * h[0], sgn[s, 1] * h[1], sgn[s, 2] * h[2]
        elif kind == _CYL:
            v0, v1, v2 = rim[s, 0] * h[0], rim[s, 1] * h[1], rim[s, 2] * h[2]
        else:
            out[s, 0], out[s, 1], out[s, 2] = c[0], c[1], c[2]
            continue
        for i in range(3):
            out[s, i] = c[i] + (v0 * R[i, 0] + v1 * R[i, 1] + v2 * R[i, 2])


@njit(cache=True, inline="always")
def _closest(kind, R, h, c, x0, x1, x2):
    """Closest point of one primitive to x (the reference's ``_closest``)."""
    y0, y1, y2 = x0 - c[0], x1 - c[1], x2 - c[2]
    l0 = y0 * R[0, 0] + y1 * R[1, 0] + y2 * R[2, 0]
    l1 = y0 * R[0, 1] + y1 * R[1, 1] + y2 * R[2, 1]
    l2 = y0 * R[0, 2] + y1 * R[1, 2] + y2 * R[2, 2]
    if kind == _BOX:
        n0 = min(max(l0, -h[0]), h[0])
        n1 = min(max(l1, -h[1]), h[1])
        n2 = min(max(l2, -h[2]), h[2])
    elif kind == _CYL:
        rad = math.sqrt(l0 * l0 + l1 * l1)
        scale = min(1.0, h[0] / (rad if rad > 0 else 1.0))
        n0, n1, n2 = l0 * scale, l1 * scale, min(max(l2, -h[2]), h[2])
    else:
        dist = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
        scale = min(1.0, h[0] / (dist if dist > 0 else 1.0))
        n0, n1, n2 = l0 * scale, l1 * scale, l2 * scale
    return (c[0] + (n0 * R[0, 0] + n1 * R[0, 1] + n2 * R[0, 2]),
            c[1] + (n0 * R[1, 0] + n1 * R[1, 1] + n2 * R[1, 2]),
            c[2] + (n0 * R[2, 0] + n1 * R[2, 1] + n2 * R[2, 2]))


@njit(cache=True)
def _depth(ka, Ra, ha, ca, kb, Rb, hb, cb, d, sgn, rim, sa, sb):
    """The reference's ``_depth`` of one primitive pair where it is > 0, else a value ≤ 0 (not
    necessarily the reference's: the axes stop at the first that separates)."""
    for k in range(3):
        d[k] = cb[k] - ca[k]
    best = np.inf
    # both frames' axes and the centre-to-centre direction (the reference's _separated, then _depth)
    for i in range(3):
        best = min(best, _overlap(ka, Ra, ha, kb, Rb, hb, d, Ra[0, i], Ra[1, i], Ra[2, i]))
        if best <= 0.0:
            return best
    for i in range(3):
        best = min(best, _overlap(ka, Ra, ha, kb, Rb, hb, d, Rb[0, i], Rb[1, i], Rb[2, i]))
        if best <= 0.0:
            return best
    best = min(best, _unit_overlap(ka, Ra, ha, kb, Rb, hb, d, d[0], d[1], d[2]))
    if best <= 0.0:
        return best
    # the 9 cross products of the frames' axes (np.cross's terms)
    for i in range(3):
        a0, a1, a2 = Ra[0, i], Ra[1, i], Ra[2, i]
        for j in range(3):
            b0, b1, b2 = Rb[0, j], Rb[1, j], Rb[2, j]
            best = min(best, _unit_overlap(ka, Ra, ha, kb, Rb, hb, d,
                                           a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))
            if best <= 0.0:
                return best
    if ka == _BOX and kb == _BOX:  # the 15 axes are complete
        return best
    # closest-point directions from each primitive's surface samples to the other
    _samples(ka, Ra, ha, ca, sgn, rim, sa)
    _samples(kb, Rb, hb, cb, sgn, rim, sb)
    for s in range(sa.shape[0]):
        q0, q1, q2 = _closest(kb, Rb, hb, cb, sa[s, 0], sa[s, 1], sa[s, 2])
        best = min(best, _unit_overlap(ka, Ra, ha, kb, Rb, hb, d, q0 - sa[s, 0], q1 - sa[s, 1], q2 - sa[s, 2]))
        if best <= 0.0:
            return best
    for s in range(sb.shape[0]):
        q0, q1, q2 = _closest(ka, Ra, ha, ca, sb[s, 0], sb[s, 1], sb[s, 2])
        best = min(best, _unit_overlap(ka, Ra, ha, kb, Rb, hb, d, sb[s, 0] - q0, sb[s, 1] - q1, sb[s, 2] - q2))
        if best <= 0.0:
            return best
    return best


@njit(cache=True)
def _pose_primitive(p, q, part, Rp, tp, Rprim, oprim, half, kind, Rw, cw, lo, hi):
    """World rotation, centre and world box of primitive p at pose q (the reference's
    ``_posed_primitives`` and world boxes)."""
    Rf = Rp[q, part]
    Rl = Rprim[p]
    ol = oprim[p]
    h = half[p]
    for i in range(3):
        for k in range(3):
            Rw[p, i, k] = Rf[i, 0] * Rl[0, k] + Rf[i, 1] * Rl[1, k] + Rf[i, 2] * Rl[2, k]
    for i in range(3):
        cw[p, i] = (Rf[i, 0] * ol[0] + Rf[i, 1] * ol[1] + Rf[i, 2] * ol[2]) + tp[q, part, i]
        a0, a1, a2 = abs(Rw[p, i, 0]), abs(Rw[p, i, 1]), abs(Rw[p, i, 2])
        if kind[p] == _BOX:
            e = a0 * h[0] + a1 * h[1] + a2 * h[2]
        elif kind[p] == _CYL:
            s = 1.0 - a2 * a2
            e = h[2] * a2 + h[0] * math.sqrt(s if s > 0.0 else 0.0)
        else:
            e = h[0]
        lo[p, i] = cw[p, i] - e
        hi[p, i] = cw[p, i] + e


@njit(cache=True)
def check_poses(Rp, tp, owner, reachable, pc_all, ph_all, pp_a, pp_b, start, count, pair_a, pair_b,
                prim_part, kind, Rprim_all, oprim_all, half_all, sgn, rim, depth):
    """Depths (c, part pairs) of the poses of one chunk, written into ``depth`` (zeros on entry).

    Rp (c, parts, 3, 3), tp (c, parts, 3): part frames; owner (c,) design of each pose; pc_all,
    ph_all (m, parts, 3): part boxes in the part frame; pp_a, pp_b, start, count: the part pairs'
    parts and primitive-pair blocks; pair_a, pair_b: primitive pairs; Rprim_all, oprim_all, half_all
    (m, P, ..): primitives; sgn, rim (S, 3): surface sample tables."""
    c, n_parts = Rp.shape[0], Rp.shape[1]
    P = kind.shape[0]
    wc = np.empty((n_parts, 3))
    wh = np.empty((n_parts, 3))
    stamp = np.full(P, -1, dtype=np.int64)
    Rw = np.empty((P, 3, 3))
    cw = np.empty((P, 3))
    lo = np.empty((P, 3))
    hi = np.empty((P, 3))
    d = np.empty(3)
    sa = np.empty((sgn.shape[0], 3))
    sb = np.empty((sgn.shape[0], 3))
    for q in range(c):
        if not reachable[q]:
            continue
        m = owner[q]
        pc, ph = pc_all[m], ph_all[m]
        for j in range(n_parts):
            R = Rp[q, j]
            for i in range(3):
                wc[j, i] = (R[i, 0] * pc[j, 0] + R[i, 1] * pc[j, 1] + R[i, 2] * pc[j, 2]) + tp[q, j, i]
                wh[j, i] = abs(R[i, 0]) * ph[j, 0] + abs(R[i, 1]) * ph[j, 1] + abs(R[i, 2]) * ph[j, 2]
        Rprim, oprim, half = Rprim_all[m], oprim_all[m], half_all[m]
        for jj in range(pp_a.shape[0]):
            a, b = pp_a[jj], pp_b[jj]
            near = True
            for i in range(3):
                if not abs(wc[a, i] - wc[b, i]) <= wh[a, i] + wh[b, i]:
                    near = False
                    break
            if not near:
                continue
            for k in range(start[jj], start[jj] + count[jj]):
                pa, pb = pair_a[k], pair_b[k]
                if stamp[pa] != q:
                    _pose_primitive(pa, q, prim_part[pa], Rp, tp, Rprim, oprim, half, kind, Rw, cw, lo, hi)
                    stamp[pa] = q
                if stamp[pb] != q:
                    _pose_primitive(pb, q, prim_part[pb], Rp, tp, Rprim, oprim, half, kind, Rw, cw, lo, hi)
                    stamp[pb] = q
                if not (lo[pa, 0] <= hi[pb, 0] and lo[pa, 1] <= hi[pb, 1] and lo[pa, 2] <= hi[pb, 2]
                        and lo[pb, 0] <= hi[pa, 0] and lo[pb, 1] <= hi[pa, 1] and lo[pb, 2] <= hi[pa, 2]):
                    continue
                dep = _depth(kind[pa], Rw[pa], half[pa], cw[pa], kind[pb], Rw[pb], half[pb], cw[pb],
                             d, sgn, rim, sa, sb)
                if dep > depth[q, jj]:
                    depth[q, jj] = dep

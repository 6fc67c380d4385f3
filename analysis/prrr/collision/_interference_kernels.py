"""numba kernel of :func:`hapticopt.analysis.prrr.collision.interference_fast.check_joints` (imported through
:func:`hapticopt.analysis.prrr.collision.interference_fast.availability`, so numba loads on first use).

:func:`check_joint_poses`: one loop over the poses of a call and, per pose, over the tested part pairs and
their primitive pairs. The part frames are built here from the joint values (the products of
``cad.part_frames_arrays``, term by term); work that does not change with the pose is done once per run of a
design's poses: the rotations, boxes and primitives of the parts whose rotation is the design's (base,
rails, screws, motors, carriages, housings, platform); the x and y tests of pairs of parts that only slide
along z, and their separating axes with no z component; the boxes of every part over a block of up to
:data:`RUN_BLOCK` poses, so that only pairs with a moving part whose block boxes meet are tested per pose.
Each pair's separating axes follow the numpy reference (``tests/analysis/prrr/interference_reference.py``)
term by term and in its order (fixed-order 3-vector sums; numba does not contract to fused multiply-adds
without ``fastmath``), so the depths are bitwise equal to it; a pair stops at the first axis whose overlap
is ≤ 0 (its clipped depth is 0 either way). Compiled ``nogil``, allocating its own scratch: calls on
disjoint outputs may run in parallel threads.

:func:`pose_joints`: the joint values the check reads (sliders, cos / sin of the joint angles, reachability) per
pose, from the one IK's text (:func:`hapticopt.design.prrr.kinematics.make_ik`) compiled over scalar primitives.
numba's on-disk cache keys a function on its own bytecode and closure values, not on the functions it calls, so
it is built in a closure holding the kinematics module's source hash: an edit of the IK recompiles it.
"""

from __future__ import annotations

import hashlib
import inspect
import math

import numpy as np
from numba import njit

from hapticopt.design.prrr import kinematics

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


@njit(cache=True, inline="always")
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
def _depth_call(ka, Ra, ha, ca, kb, Rb, hb, cb, d, sgn, rim, sa, sb):
    """:func:`_depth` as a call (where it runs rarely: one inlined copy, compiled once)."""
    return _depth(ka, Ra, ha, ca, kb, Rb, hb, cb, d, sgn, rim, sa, sb)


@njit(cache=True, inline="always")
def _boxes_meet(wc, wh, a, b):
    """Whether the world boxes (centres wc, half widths wh) of parts a and b overlap on every axis."""
    for i in range(3):
        if not abs(wc[a, i] - wc[b, i]) <= wh[a, i] + wh[b, i]:
            return False
    return True


@njit(cache=True, inline="always")
def _extent(k, Rw, h, i):
    """World half extent along axis i of a primitive of kind k (its world box: the support along that axis)."""
    a0, a1, a2 = abs(Rw[i, 0]), abs(Rw[i, 1]), abs(Rw[i, 2])
    if k == _BOX:
        return a0 * h[0] + a1 * h[1] + a2 * h[2]
    if k == _CYL:
        s = 1.0 - a2 * a2
        return h[2] * a2 + h[0] * math.sqrt(s if s > 0.0 else 0.0)
    return h[0]






# ---------------------------------------------------------------------------- poses from joint values
#: how each part's frame follows from the joint values (interference_fast._frame_rules; the rules of
#: hapticopt.design.prrr.cad.part_frames_arrays): fixed at the origin (base, rails, screws, motors),
#: sliding along z with its leg's slider (carriage, housing), the leg's first or second link, platform
_FIXED, _SLIDE, _LINK1, _LINK2, _PLATFORM = 0, 1, 2, 3, 4
#: margin [m] of the union of a part's boxes over a run of one design's poses: far above the rounding of
#: the boxes' bounds (~1e-16 m at these sizes), so a pair whose boxes meet at a pose (the exact test)
#: meets in the unions
RUN_MARGIN = 1e-9
#: reachable poses of one design whose frames and boxes :func:`check_joint_poses` keeps at a time (and
#: whose union of part boxes decides which pairs with a moving part are tested at them)
RUN_BLOCK = 32


@njit(cache=True, inline="always")
def _rotate_primitive(p, Rf, Rl, ol, h, k, Rw, ro, ext):
    """World rotation Rw[p], rotated centre ro[p] (add the part origin for the world centre) and world
    half extents ext[p] of primitive p in a part of rotation Rf (the reference's ``_posed_primitives`` products)."""
    for i in range(3):
        for kk in range(3):
            Rw[p, i, kk] = Rf[i, 0] * Rl[0, kk] + Rf[i, 1] * Rl[1, kk] + Rf[i, 2] * Rl[2, kk]
    for i in range(3):
        ro[p, i] = Rf[i, 0] * ol[0] + Rf[i, 1] * ol[1] + Rf[i, 2] * ol[2]
        ext[p, i] = _extent(k, Rw[p], h, i)


@njit(cache=True, inline="always")
def _pose_frames(q, m, u, rule, leg, D, c1, s1, c12, s12, pts, W, V, U, T, d1, d2, d3, pc_all, ph_all, Rpc, Rq, tq,
                 wc, wh, ulo, uhi, A, e1, e12):
    """At pose q of design m, into slot u of the block: the rotations Rq[u] of the links, the origins
    tq[u] of the moving parts (the sliding parts' and the platform's; the fixed parts' stay 0) and the
    world boxes (wc[u], wh[u]) of the parts that move (the links'; the centres of the sliding parts and
    the platform: their rotated centre Rpc plus the origin; the rest is the design's, set up before), and
    those boxes added to the block's union (ulo, uhi): :func:`hapticopt.design.prrr.cad.part_frames_arrays`'
    products, term by term (scalar indexing: no array views in this per-pose step)."""
    n_parts = rule.shape[0]
    # the legs' link frames (cad.part_frames_arrays: e1, e12, A = D ez + d1 u + d2 t, B = A + d3 e1)
    for k in range(3):
        Dk = D[q, k]
        for i in range(3):
            v, t = V[m, k, i], T[k, i]
            e1[k, i] = c1[q, k] * v + s1[q, k] * t
            e12[k, i] = c12[q, k] * v + s12[q, k] * t
            A[k, i] = (Dk * (1.0 if i == 2 else 0.0) + d1[m] * U[k, i]) + d2[m] * t
    for j in range(n_parts):
        r = rule[j]
        if r == _FIXED:
            continue
        k = leg[j]
        if r == _SLIDE or r == _PLATFORM:
            if r == _SLIDE:
                Dk = D[q, k]
                tq[u, j, 0], tq[u, j, 1], tq[u, j, 2] = Dk * 0.0, Dk * 0.0, Dk * 1.0
            else:
                tq[u, j, 0], tq[u, j, 1], tq[u, j, 2] = pts[q, 0], pts[q, 1], pts[q, 2]
            for i in range(3):
                wc[u, j, i] = Rpc[j, i] + tq[u, j, i]
        else:
            link1 = r == _LINK1
            for i in range(3):
                Rq[u, j, i, 0] = e1[k, i] if link1 else e12[k, i]
                Rq[u, j, i, 2] = W[m, k, i]
                tq[u, j, i] = A[k, i] if link1 else A[k, i] + d3[m] * e1[k, i]
            x0, x1, x2 = Rq[u, j, 0, 0], Rq[u, j, 1, 0], Rq[u, j, 2, 0]
            w0, w1, w2 = W[m, k, 0], W[m, k, 1], W[m, k, 2]
            Rq[u, j, 0, 1] = w1 * x2 - w2 * x1  # np.cross(w, x)'s terms
            Rq[u, j, 1, 1] = w2 * x0 - w0 * x2
            Rq[u, j, 2, 1] = w0 * x1 - w1 * x0
            # the link's world box (the reference's products in their order)
            for i in range(3):
                R0, R1, R2 = Rq[u, j, i, 0], Rq[u, j, i, 1], Rq[u, j, i, 2]
                wc[u, j, i] = (R0 * pc_all[m, j, 0] + R1 * pc_all[m, j, 1] + R2 * pc_all[m, j, 2]) + tq[u, j, i]
                wh[u, j, i] = abs(R0) * ph_all[m, j, 0] + abs(R1) * ph_all[m, j, 1] + abs(R2) * ph_all[m, j, 2]
        for i in range(3):
            ulo[j, i] = min(ulo[j, i], wc[u, j, i] - wh[u, j, i])
            uhi[j, i] = max(uhi[j, i], wc[u, j, i] + wh[u, j, i])


@njit(cache=True, inline="always")
def _fixed_part(rule, j):
    """Whether part j's rotation is constant over the poses of a design (fixed or sliding along z)."""
    return rule[j] <= _SLIDE


@njit(cache=True)
def _separated_across_z(ka, Ra, ha, kb, Rb, hb, d0, d1, d):
    """Whether one of :func:`_depth`'s axes with no z component (a frame axis or a cross product of
    frame axes whose z is exactly 0) has an overlap ≤ 0, for two primitives whose centres differ by
    (d0, d1, ·). On such an axis the overlap is :func:`_overlap`'s bit for bit whatever the z offset of
    the centres (its z term is ±0), so a pair of parts that only slide along z is then separated, depth
    ≤ 0, at every pose of the design. ``d`` (3,): scratch."""
    d[0], d[1], d[2] = d0, d1, 0.0
    for i in range(3):
        if Ra[2, i] == 0.0 and _overlap(ka, Ra, ha, kb, Rb, hb, d, Ra[0, i], Ra[1, i], 0.0) <= 0.0:
            return True
        if Rb[2, i] == 0.0 and _overlap(ka, Ra, ha, kb, Rb, hb, d, Rb[0, i], Rb[1, i], 0.0) <= 0.0:
            return True
    for i in range(3):
        a0, a1, a2 = Ra[0, i], Ra[1, i], Ra[2, i]
        for j in range(3):
            b0, b1, b2 = Rb[0, j], Rb[1, j], Rb[2, j]
            x2 = a0 * b1 - a1 * b0
            if x2 == 0.0 and _unit_overlap(ka, Ra, ha, kb, Rb, hb, d, a1 * b2 - a2 * b1, a2 * b0 - a0 * b2,
                                           x2) <= 0.0:
                return True
    return False


@njit(cache=True, inline="always")
def _rotate_only(p, Rf, Rl, h, k, Rw, ext):
    """World rotation Rw[p] and world half extents ext[p] of primitive p in a part of rotation Rf
    (:func:`_rotate_primitive` without the centre)."""
    for i in range(3):
        for kk in range(3):
            Rw[p, i, kk] = Rf[i, 0] * Rl[0, kk] + Rf[i, 1] * Rl[1, kk] + Rf[i, 2] * Rl[2, kk]
    for i in range(3):
        ext[p, i] = _extent(k, Rw[p], h, i)


@njit(cache=True, nogil=True)
def check_joint_poses(rule, leg, D, c1, s1, c12, s12, pts, owner, reachable, Rslide, W, V, U, T, d1, d2, d3,
                      pc_all, ph_all, pp_a, pp_b, start, count, pair_a, pair_b, prim_part, kind, Rprim_all,
                      oprim_all, half_all, sgn, rim, col, depth):
    """Depths of the poses of a call, the part frames built here from the joint values (the products of
    :func:`hapticopt.design.prrr.cad.part_frames_arrays`, term by term): the depth of part pair jj at
    pose q goes to ``depth[q, col[jj]]`` (the largest where pairs share a column, 0 where none meets:
    ``col = arange`` gives every pair's depth (the reference's bit for bit), ``col = zeros`` the deepest
    overlap of each pose in one column); ``depth`` zeros on entry.

    rule, leg (parts,): each part's frame rule (_FIXED … _PLATFORM) and leg index; per pose: D (n, 3)
    sliders [m], c1, s1, c12, s12 (n, 3) cos / sin of θ₁ and of θ₁ + θ₂ per leg, pts (n, 3) platform
    origin [m]; per design: Rslide (m, 3 legs, 3, 3) carriage rotation, W, V (m, 3 legs, 3) the legs'
    joint axis w and v, d1, d2, d3 (m,) [m]; U, T (3 legs, 3) the legs' u and t. The frames of the
    fixed and sliding parts (rotation constant per design) and their primitives' rotations, rotated
    centres and extents are computed once per run of poses of one design; per pose only the origin is
    added, as in the reference. The moving parts' frames and every part's box are computed once
    per pose, for a block of up to :data:`RUN_BLOCK` reachable poses of the run at a time (kept for the
    pair tests). Allocates all its scratch (no shared state: calls on disjoint outputs may run in
    parallel threads; it releases the GIL)."""
    n, n_parts = D.shape[0], rule.shape[0]
    P = kind.shape[0]
    B = RUN_BLOCK
    Rd = np.zeros((n_parts, 3, 3))  # the design's rotation of the parts whose rotation is constant
    whd = np.empty((n_parts, 3))  # … and their boxes' world half widths
    Rpc = np.empty((n_parts, 3))  # … and rotated box centres (add the origin)
    Rqb = np.zeros((B, n_parts, 3, 3))  # per pose of the block: link rotations,
    tqb = np.zeros((B, n_parts, 3))  # part origins (fixed parts' stay 0),
    wcb = np.empty((B, n_parts, 3))  # every part's world box
    whb = np.empty((B, n_parts, 3))
    blk = np.empty(B, dtype=np.int64)  # the block's poses
    stamp = np.full(P, -1, dtype=np.int64)  # pose whose full world pose (Rw, ext, lo, hi) primitive p holds
    cstamp = np.full(P, -1, dtype=np.int64)  # pose whose world centre cw primitive p holds
    Rw = np.empty((P, 3, 3))
    ro = np.empty((P, 3))
    ext = np.empty((P, 3))
    bw = np.empty((P, 3))  # half widths bounding a primitive's world box at any rotation (+ RUN_MARGIN)
    cw = np.empty((P, 3))
    lo = np.empty((P, 3))
    hi = np.empty((P, 3))
    fixed_prim = np.empty(P, dtype=np.bool_)  # primitive of a part whose rotation is the design's (not a link)
    for p in range(P):
        fixed_prim[p] = rule[prim_part[p]] != _LINK1 and rule[prim_part[p]] != _LINK2
    n_fixed = 0
    for jj in range(pp_a.shape[0]):
        n_fixed += _fixed_part(rule, pp_a[jj]) and _fixed_part(rule, pp_b[jj])
    fixed_pairs = np.empty(n_fixed, dtype=np.int64)
    moving_pairs = np.empty(pp_a.shape[0] - n_fixed, dtype=np.int64)
    nf = nm = 0
    for jj in range(pp_a.shape[0]):
        if _fixed_part(rule, pp_a[jj]) and _fixed_part(rule, pp_b[jj]):
            fixed_pairs[nf] = jj
            nf += 1
        else:
            moving_pairs[nm] = jj
            nm += 1
    live_moving = np.empty(moving_pairs.shape[0], dtype=np.int64)  # per block: the moving pairs that can meet
    # the distinct primitives of each side of each part pair (side 0: pair_a's, 1: pair_b's), in CSR form
    side_start = np.zeros(2 * pp_a.shape[0] + 1, dtype=np.int64)
    side_prim = np.empty(2 * pair_a.shape[0], dtype=np.int64)
    seen = np.full(P, -1, dtype=np.int64)
    n_side = 0
    for jj in range(pp_a.shape[0]):
        for side in range(2):
            for k in range(start[jj], start[jj] + count[jj]):
                pp = pair_a[k] if side == 0 else pair_b[k]
                if seen[pp] != 2 * jj + side:
                    seen[pp] = 2 * jj + side
                    side_prim[n_side] = pp
                    n_side += 1
            side_start[2 * jj + side + 1] = n_side
    passed = np.full(P, -1, dtype=np.int64)  # the (pose, part pair) tag at which primitive p passed
    tag = -1
    n_pass_a = 0
    ulo = np.empty((n_parts, 3))
    uhi = np.empty((n_parts, 3))
    live = np.zeros(pp_a.shape[0], dtype=np.bool_)  # per design: a fixed pair can meet at some z
    live_fixed = np.empty(n_fixed, dtype=np.int64)  # … the list of those
    pair_live = np.zeros(pair_a.shape[0], dtype=np.bool_)  # … and its primitive pair
    A = np.empty((3, 3))
    e1 = np.empty((3, 3))
    e12 = np.empty((3, 3))
    d = np.empty(3)
    sa = np.empty((sgn.shape[0], 3))
    sb = np.empty((sgn.shape[0], 3))
    q = 0
    while q < n:
        m = owner[q]
        e = q  # the run of design m's poses: q … e − 1
        while e < n and owner[e] == m:
            e += 1
        pc, ph = pc_all[m], ph_all[m]
        Rprim, oprim, half = Rprim_all[m], oprim_all[m], half_all[m]
        # the design's fixed and sliding parts' rotations, boxes and primitives
        for j in range(n_parts):
            if rule[j] == _FIXED or rule[j] == _PLATFORM:
                for i in range(3):
                    for kk in range(3):
                        Rd[j, i, kk] = 1.0 if i == kk else 0.0
            elif rule[j] == _SLIDE:
                Rd[j] = Rslide[m, leg[j]]
            else:
                continue
            for i in range(3):
                R = Rd[j]
                Rpc[j, i] = R[i, 0] * pc[j, 0] + R[i, 1] * pc[j, 1] + R[i, 2] * pc[j, 2]
                whd[j, i] = abs(R[i, 0]) * ph[j, 0] + abs(R[i, 1]) * ph[j, 1] + abs(R[i, 2]) * ph[j, 2]
            for u in range(B):  # the box half widths (and the fixed parts' centres) of every pose of the design
                for i in range(3):
                    whb[u, j, i] = whd[j, i]
                    if rule[j] == _FIXED:
                        wcb[u, j, i] = Rpc[j, i] + 0.0  # the origin's 0 added, as per pose before
        for p in range(P):
            if fixed_prim[p]:
                _rotate_primitive(p, Rd[prim_part[p]], Rprim[p], oprim[p], half[p], kind[p], Rw, ro, ext)
                for i in range(3):
                    bw[p, i] = ext[p, i] + RUN_MARGIN
            else:  # a link's: the box's half diagonal, the cylinder's (radius, half length), the sphere's radius
                h = half[p]
                if kind[p] == _BOX:
                    r = math.sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2])
                elif kind[p] == _CYL:
                    r = math.sqrt(h[0] * h[0] + h[2] * h[2])
                else:
                    r = h[0]
                for i in range(3):
                    bw[p, i] = r + RUN_MARGIN
        # pairs of fixed and sliding parts: their x and y are the design's (the origins' x, y are ±0), so
        # the x, y tests of their boxes and the axes with no z component are decided once per design
        n_live_fixed = 0
        for jj in fixed_pairs:
            a, b = pp_a[jj], pp_b[jj]
            live[jj] = (abs(Rpc[a, 0] - Rpc[b, 0]) <= whd[a, 0] + whd[b, 0]
                        and abs(Rpc[a, 1] - Rpc[b, 1]) <= whd[a, 1] + whd[b, 1])
            if not live[jj]:
                continue
            live[jj] = False
            for k in range(start[jj], start[jj] + count[jj]):
                pa, pb = pair_a[k], pair_b[k]
                pair_live[k] = ((ro[pa, 0] - ext[pa, 0]) <= (ro[pb, 0] + ext[pb, 0])
                                and (ro[pa, 1] - ext[pa, 1]) <= (ro[pb, 1] + ext[pb, 1])
                                and (ro[pb, 0] - ext[pb, 0]) <= (ro[pa, 0] + ext[pa, 0])
                                and (ro[pb, 1] - ext[pb, 1]) <= (ro[pa, 1] + ext[pa, 1])
                                and not _separated_across_z(kind[pa], Rw[pa], half[pa], kind[pb], Rw[pb], half[pb],
                                                            ro[pb, 0] - ro[pa, 0], ro[pb, 1] - ro[pa, 1], d))
                live[jj] = live[jj] or pair_live[k]
            if live[jj]:
                live_fixed[n_live_fixed] = jj
                n_live_fixed += 1
        r = q
        while r < e:
            # a block of up to B reachable poses of the run: their frames and boxes, and every part's box
            # over the block (a pair that meets at a pose has its boxes inside these)
            nb = 0
            while r < e and nb < B:
                if reachable[r]:
                    blk[nb] = r
                    nb += 1
                r += 1
            if nb == 0:
                break
            for j in range(n_parts):
                for i in range(3):
                    if rule[j] == _FIXED:  # the design's box
                        ulo[j, i], uhi[j, i] = wcb[0, j, i] - whb[0, j, i], wcb[0, j, i] + whb[0, j, i]
                    else:
                        ulo[j, i], uhi[j, i] = np.inf, -np.inf
            for t in range(nb):
                _pose_frames(blk[t], m, t, rule, leg, D, c1, s1, c12, s12, pts, W, V, U, T, d1, d2, d3, pc_all, ph_all,
                             Rpc, Rqb, tqb, wcb, whb, ulo, uhi, A, e1, e12)
            n_live = 0
            for jj in moving_pairs:
                a, b = pp_a[jj], pp_b[jj]
                if (ulo[a, 0] - RUN_MARGIN <= uhi[b, 0] + RUN_MARGIN and ulo[b, 0] - RUN_MARGIN <= uhi[a, 0] + RUN_MARGIN
                        and ulo[a, 1] - RUN_MARGIN <= uhi[b, 1] + RUN_MARGIN
                        and ulo[b, 1] - RUN_MARGIN <= uhi[a, 1] + RUN_MARGIN
                        and ulo[a, 2] - RUN_MARGIN <= uhi[b, 2] + RUN_MARGIN
                        and ulo[b, 2] - RUN_MARGIN <= uhi[a, 2] + RUN_MARGIN):
                    live_moving[n_live] = jj
                    n_live += 1
            for t in range(nb):
                qq = blk[t]
                Rq, tq, wc, wh = Rqb[t], tqb[t], wcb[t], whb[t]
                for u in range(n_live_fixed):  # x, y decided for the design above: z here
                    jj = live_fixed[u]
                    a, b = pp_a[jj], pp_b[jj]
                    if not abs(wc[a, 2] - wc[b, 2]) <= wh[a, 2] + wh[b, 2]:
                        continue
                    for k in range(start[jj], start[jj] + count[jj]):
                        if not pair_live[k]:
                            continue
                        pa, pb = pair_a[k], pair_b[k]
                        ja, jb = prim_part[pa], prim_part[pb]
                        ca2, cb2 = ro[pa, 2] + tq[ja, 2], ro[pb, 2] + tq[jb, 2]
                        if not (ca2 - ext[pa, 2] <= cb2 + ext[pb, 2] and cb2 - ext[pb, 2] <= ca2 + ext[pa, 2]):
                            continue
                        for pp in (pa, pb):
                            if stamp[pp] != qq:
                                stamp[pp] = cstamp[pp] = qq
                                for i in range(3):
                                    cw[pp, i] = ro[pp, i] + tq[prim_part[pp], i]
                                    lo[pp, i] = cw[pp, i] - ext[pp, i]
                                    hi[pp, i] = cw[pp, i] + ext[pp, i]
                        dep = _depth_call(kind[pa], Rw[pa], half[pa], cw[pa], kind[pb], Rw[pb], half[pb], cw[pb],
                                          d, sgn, rim, sa, sb)
                        if dep > depth[qq, col[jj]]:
                            depth[qq, col[jj]] = dep
                for u in range(n_live):
                    jj = live_moving[u]
                    a, b = pp_a[jj], pp_b[jj]
                    if not _boxes_meet(wc, wh, a, b):
                        continue
                    # each side's primitives: the world centre (a link primitive's: its rotated centre, 9
                    # products) and a test of the bounding widths against the other part's box; a primitive
                    # pair whose world boxes meet has both primitives pass (the part boxes hold their
                    # primitives' boxes, RUN_MARGIN in bw covering the rounding)
                    tag += 1
                    n_pass = 0
                    for side in range(2):
                        for idx in range(side_start[2 * jj + side], side_start[2 * jj + side + 1]):
                            pp = side_prim[idx]
                            other = b if prim_part[pp] == a else a
                            if cstamp[pp] != qq:
                                cstamp[pp] = qq
                                j = prim_part[pp]
                                if not fixed_prim[pp]:
                                    for i in range(3):
                                        ro[pp, i] = (Rq[j, i, 0] * oprim[pp, 0] + Rq[j, i, 1] * oprim[pp, 1]
                                                     + Rq[j, i, 2] * oprim[pp, 2])
                                for i in range(3):
                                    cw[pp, i] = ro[pp, i] + tq[j, i]
                            if (abs(cw[pp, 0] - wc[other, 0]) <= bw[pp, 0] + wh[other, 0]
                                    and abs(cw[pp, 1] - wc[other, 1]) <= bw[pp, 1] + wh[other, 1]
                                    and abs(cw[pp, 2] - wc[other, 2]) <= bw[pp, 2] + wh[other, 2]):
                                passed[pp] = tag
                                n_pass += 1
                        if n_pass == 0:
                            break
                        if side == 0:
                            n_pass_a = n_pass
                            n_pass = 0
                    if n_pass == 0 or n_pass_a == 0:
                        continue
                    for k in range(start[jj], start[jj] + count[jj]):
                        pa, pb = pair_a[k], pair_b[k]
                        if passed[pa] != tag or passed[pb] != tag:
                            continue
                        if not (abs(cw[pa, 0] - cw[pb, 0]) <= bw[pa, 0] + bw[pb, 0]
                                and abs(cw[pa, 1] - cw[pb, 1]) <= bw[pa, 1] + bw[pb, 1]
                                and abs(cw[pa, 2] - cw[pb, 2]) <= bw[pa, 2] + bw[pb, 2]):
                            continue
                        for pp in (pa, pb):
                            if stamp[pp] != qq:
                                stamp[pp] = qq
                                if not fixed_prim[pp]:
                                    _rotate_only(pp, Rq[prim_part[pp]], Rprim[pp], half[pp], kind[pp], Rw, ext)
                                for i in range(3):
                                    lo[pp, i] = cw[pp, i] - ext[pp, i]
                                    hi[pp, i] = cw[pp, i] + ext[pp, i]
                        if not (lo[pa, 0] <= hi[pb, 0] and lo[pa, 1] <= hi[pb, 1] and lo[pa, 2] <= hi[pb, 2]
                                and lo[pb, 0] <= hi[pa, 0] and lo[pb, 1] <= hi[pa, 1] and lo[pb, 2] <= hi[pa, 2]):
                            continue
                        dep = _depth(kind[pa], Rw[pa], half[pa], cw[pa], kind[pb], Rw[pb], half[pb], cw[pb],
                                     d, sgn, rim, sa, sb)
                        if dep > depth[qq, col[jj]]:
                            depth[qq, col[jj]] = dep
        q = e








_inline = njit(inline="always")
#: the one 3-PRRR IK (:func:`hapticopt.design.prrr.kinematics.make_ik`) over numba-compiled scalar primitives,
#: each of its functions inlined into :func:`pose_joints`
IK = kinematics.make_ik(kinematics.IkOps(**{k: _inline(f) for k, f in kinematics.SCALAR_IK_OPS.items()}), _inline)
_ik_leg, _ik_joints, _ik_offset = IK.leg, IK.joints, IK.offset


def _build_pose_joints(ik_hash: str):
    @njit(cache=True, nogil=True)
    def pose_joints(idx, owner, pts, beta, d1, d2, d3, d4, r4, b5, stroke, U, T, branch, D, c1, s1, c12, s12, ok):
        """The collision check's joint values at the poses ``idx`` (rows of ``pts`` (n, 3) [m]; design
        ``owner[q]``'s parameters, arrays per design [m, rad]): sliders ``D`` (n, 3) [m], the cos / sin of θ₁
        and of θ₁ + θ₂ of elbow ``branch`` (``c1, s1, c12, s12`` (n, 3 legs)) and reachability ``ok`` (n,),
        written at rows ``idx``; U, T (3 legs, 3) the legs' u and t. What
        ``kinematics.inverse_kinematics`` and ``interference_fast.joint_trig`` give (the same ``make_ik``
        text, the same operations and libm functions: the same bits, tested), per pose in registers, with no
        array of both branches. nogil: threads may fill disjoint rows at once."""
        _ = ik_hash  # in the closure: numba's cache key (see the module docstring)
        for j in range(idx.shape[0]):
            q = idx[j]
            m = owner[q]
            b = beta[m]
            cb, sb = math.cos(b), math.sin(b)
            c_e = _ik_offset(sb, math.tan(b), b5[m], r4[m], d1[m])
            half = stroke[m] / 2.0
            good = True
            for k in range(3):
                sl, reach, _rho, elbow, phi, psi = _ik_leg(pts[q, 0], pts[q, 1], pts[q, 2], cb, sb, b5[m], d1[m],
                                                           d2[m], d3[m], d4[m], r4[m], U[k, 0], U[k, 1], T[k, 0],
                                                           T[k, 1])
                th1, th2, _th3 = _ik_joints(elbow, phi, psi, branch)
                th12 = th1 + th2
                D[q, k] = sl
                c1[q, k], s1[q, k] = math.cos(th1), math.sin(th1)
                c12[q, k], s12[q, k] = math.cos(th12), math.sin(th12)
                good = good and reach and abs(sl - c_e) <= half * (1.0 + 1e-12)
            ok[q] = good

    return pose_joints


pose_joints = _build_pose_joints(hashlib.sha256(inspect.getsource(kinematics).encode()).hexdigest())

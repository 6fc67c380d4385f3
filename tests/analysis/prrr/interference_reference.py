"""The numpy reference of the fast collision check (:mod:`hapticopt.analysis.prrr.collision.interference_fast`):
the separating-axis test written as numpy passes over chunks of poses, from part frames given per pose.
It exists to prove the shipped numba kernel (:mod:`hapticopt.analysis.prrr.collision._interference_kernels`) right,
bit for bit (as MuJoCo keeps ``py_rollout`` in ``rollout_test.py``); the package does not run it.

Stages per chunk: world-axis-aligned boxes of every part over every tested part pair; the world rotation,
centre and exact world extents of every primitive at every pose; the primitive pairs of the surviving part
pairs tested on those extents; the seven cheapest separating axes (both frames, centre to centre), then
:func:`_depth`'s 16 cheap axes and its 40 sampled axes on curved pairs still overlapping. The 3-vector
products are fixed-order sums (:func:`_mm`), no BLAS, so the last bit does not depend on the BLAS build.
"""

from __future__ import annotations

import numpy as np

from hapticopt.analysis.prrr.collision.interference_fast import (DEPTH_TOL, FastResult, PrimitiveBatch, _BOX, _CYL,
                                                       _half_width, _part_boxes, _sample_tables, _world_extent)
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.prrr.kinematics import inverse_kinematics, params_np
from hapticopt.design.prrr.params import PrrrDesign


def part_frames_batch(design: PrrrDesign, points, *, branch: int = cad_prrr.DEFAULT_BRANCH
                      ) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], np.ndarray]:
    """World rotation (n, 3, 3) and origin (n, 3) [m] of every part at ``points`` (n, 3) [m]
    (:func:`hapticopt.design.prrr.cad.part_frames_batch` after the numpy IK), and whether each point is reachable."""

    p = np.atleast_2d(np.asarray(points, dtype=float))
    ik = inverse_kinematics(params_np(design), p, xp=np)
    theta = np.asarray(ik.theta)[:, branch]  # (n, 3 legs, 3)
    return cad_prrr.part_frames_batch(design, np.asarray(ik.sliders), theta, p), np.asarray(ik.reachable)


def _mm(a, b):
    """``a @ b`` for stacks of (.., I, 3) and (.., 3, K), summed in a fixed order, (a₀b₀ + a₁b₁) + a₂b₂,
    with no fused multiply-add: numpy's matmul goes to BLAS, whose kernels fuse and reorder, so its
    last bit depends on the BLAS build (and would differ from :mod:`._interference_kernels`'s)."""
    return (a[..., :, 0, None] * b[..., None, 0, :] + a[..., :, 1, None] * b[..., None, 1, :]
            + a[..., :, 2, None] * b[..., None, 2, :])


def _mv(R, v):
    """``R @ v`` for stacks of (.., 3, 3) and (.., 3), in :func:`_mm`'s order."""
    return R[..., 0] * v[..., 0, None] + R[..., 1] * v[..., 1, None] + R[..., 2] * v[..., 2, None]


def _dot(a, b):
    """Σ a_k b_k over the last axis (3), in :func:`_mm`'s order."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _support(kind, R, half, n):
    """Projection half-width of primitives on unit axes: R (m, 3, 3), half (m, 3), n (m, A, 3)."""
    return _half_width(kind, np.abs(_mm(n, R)), half)


def _unit(x):
    nrm = np.sqrt(_dot(x, x))[..., None]
    return np.where(nrm > 1e-12, x / np.where(nrm > 1e-12, nrm, 1.0), 0.0)


def _overlap(kind_a, Ra, ha, kind_b, Rb, hb, d, axes):
    """Smallest overlap [m] of the two projections over ``axes`` (m, A, 3) (zero axes ignored);
    ``d`` (m, 3) is the centre-to-centre vector."""
    valid = _dot(axes, axes) > 0.25
    gap = np.abs(_dot(axes, d[:, None]))
    overlap = _support(kind_a, Ra, ha, axes) + _support(kind_b, Rb, hb, axes) - gap
    return np.min(np.where(valid, overlap, np.inf), axis=1)


def _surface_samples(kind, R, half, c):
    """Points (m, S, 3) on the surface of each primitive where curved contacts happen: box
    corners and edge midpoints (20), cylinder rim points (2·_RIM_SAMPLES, padded by repetition),
    sphere centre (repeated)."""
    sgn, loc = _sample_tables()
    box = c[:, None] + _mm(sgn[None] * half[:, None], np.swapaxes(R, 1, 2))
    cyl = c[:, None] + _mm(loc[None] * half[:, None], np.swapaxes(R, 1, 2))
    k = kind[:, None, None]
    return np.where(k == _BOX, box, np.where(k == _CYL, cyl, c[:, None]))


def _closest(kind, R, half, c, x):
    """Closest point (m, S, 3) of each primitive to points ``x`` (m, S, 3) (x itself if inside)."""
    loc = _mm(x - c[:, None], R)  # local coordinates
    box = np.clip(loc, -half[:, None], half[:, None])
    rad = np.sqrt(loc[..., 0] * loc[..., 0] + loc[..., 1] * loc[..., 1])[..., None]
    scale = np.minimum(1.0, half[:, None, :1] / np.where(rad > 0, rad, 1.0))
    cyl = np.concatenate([loc[..., :2] * scale, np.clip(loc[..., 2:], -half[:, None, 2:], half[:, None, 2:])], axis=-1)
    dist = np.sqrt(_dot(loc, loc))[..., None]
    sph = loc * np.minimum(1.0, half[:, None, :1] / np.where(dist > 0, dist, 1.0))
    k = kind[:, None, None]
    near = np.where(k == _BOX, box, np.where(k == _CYL, cyl, sph))
    return c[:, None] + _mm(near, np.swapaxes(R, 1, 2))


#: a pair counts as separated by :func:`_separated` when an axis shows a gap wider than this [m]
#: (far above the rounding of the projections, ~1e-17 m, so _depth's own evaluation of that axis,
#: in another array layout, is negative too)
SEPARATION_MARGIN = 1e-12


def _separated(kind_a, Ra, ha, ca, kind_b, Rb, hb, cb):
    """Pairs (m,) that one of :func:`_depth`'s candidate axes separates by more than
    :data:`SEPARATION_MARGIN`: both frames' axes and the centre-to-centre direction (7 of its 16
    cheap axes). Their depth is then negative: a pre-filter that changes no clipped depth."""
    d = cb - ca
    axes = np.concatenate([np.swapaxes(Ra, 1, 2), np.swapaxes(Rb, 1, 2), _unit(d)[:, None]], axis=1)
    return _overlap(kind_a, Ra, ha, kind_b, Rb, hb, d, axes) < -SEPARATION_MARGIN


def _depth(kind_a, Ra, ha, ca, kind_b, Rb, hb, cb):
    """Smallest overlap [m] of the projections over the candidate axes (≤ 0: separated).

    Axes: both frames (6), their cross products (9), centre to centre (1), and the directions
    from surface samples of each primitive to their closest points on the other (2·20). The
    cheap axes go first; the sampled ones only for the pairs they leave overlapping."""
    m = len(ca)
    d = cb - ca
    RaT, RbT = np.swapaxes(Ra, 1, 2), np.swapaxes(Rb, 1, 2)
    cross = np.cross(RaT[:, :, None, :], RbT[:, None, :, :]).reshape(m, 9, 3)
    axes = np.concatenate([RaT, RbT, _unit(cross), _unit(d)[:, None]], axis=1)
    out = _overlap(kind_a, Ra, ha, kind_b, Rb, hb, d, axes)
    curved = (out > 0.0) & ((kind_a != _BOX) | (kind_b != _BOX))  # box–box: the 15 axes are complete
    if np.any(curved):
        i = np.flatnonzero(curved)
        sa = _surface_samples(kind_a[i], Ra[i], ha[i], ca[i])
        sb = _surface_samples(kind_b[i], Rb[i], hb[i], cb[i])
        extra = np.concatenate([_unit(_closest(kind_b[i], Rb[i], hb[i], cb[i], sa) - sa),
                                _unit(sb - _closest(kind_a[i], Ra[i], ha[i], ca[i], sb))], axis=1)
        out[i] = np.minimum(out[i], _overlap(kind_a[i], Ra[i], ha[i], kind_b[i], Rb[i], hb[i], d[i], extra))
    return out


#: poses per pass of :func:`check_posed` (bounds the per-(pose, primitive) world tables: ~4 MB
#: of rotations per 1,000 poses of a 51-primitive layout)
CHUNK_POSES = 4096


def check_posed(batch: PrimitiveBatch, owner: np.ndarray, points: np.ndarray,
                frames: dict[str, tuple[np.ndarray, np.ndarray]], reachable: np.ndarray) -> FastResult:
    """Interference at n posed configurations of the designs of ``batch``: pose k belongs to design
    ``owner[k]``, its parts at ``frames`` (name → world rotation (n, 3, 3), origin (n, 3) [m], as
    :func:`hapticopt.design.prrr.cad.part_frames_arrays`), ``reachable`` (n,) bool; numpy passes over
    chunks of :data:`CHUNK_POSES` poses (the module docstring's stages)."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    n = len(pts)
    owner = np.asarray(owner, dtype=int)
    reachable = np.asarray(reachable)
    depth = np.zeros((n, len(batch.part_pairs)))
    P = len(batch.kind)
    pc_all, ph_all, pp_a, pp_b, start, count = _part_boxes(batch)
    kind_all = np.tile(batch.kind, CHUNK_POSES)
    for s in range(0, n, CHUNK_POSES):
        e = min(n, s + CHUNK_POSES)
        _check_chunk(batch, owner[s:e], frames, s, e, reachable[s:e], depth[s:e], pc_all, ph_all,
                     pp_a, pp_b, start, count, kind_all[: (e - s) * P])
    return FastResult(points=pts, reachable=reachable, collides=np.any(depth > DEPTH_TOL, axis=1),
                      depth=depth, part_pairs=batch.part_pairs)


def _posed_primitives(batch, owner, Rp, hw, kind_flat) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World rotations (c·P, 3, 3), world extents (c·P, 3) and rotated centres (c, P, 3) (the part
    rotation times the primitive's centre in the part frame; add the part origin for the world
    centre) of every primitive at every pose of the chunk.

    A part whose rotation is the same at every pose of a design in the chunk (the base's parts, the
    carriages and housings, which only slide, and the platform, which only translates) has these
    computed at one pose per design and copied: the same products of the same numbers, so the same
    values as computing them at every pose."""
    c = len(owner)
    P = len(batch.kind)
    _, first, inv = np.unique(owner, return_index=True, return_inverse=True)
    rep = first[inv]  # each pose's design's first pose in the chunk
    fixed = np.all(Rp == Rp[rep], axis=(0, 2, 3))[batch.prim_part]  # (P,) rotation constant per design
    Rw = np.empty((c, P, 3, 3))
    ext = np.empty((c, P, 3))
    ro = np.empty((c, P, 3))
    hw3 = hw.reshape(c, P, 3)
    kind3 = kind_flat.reshape(c, P)
    for sel, rows in ((np.flatnonzero(~fixed), slice(None)), (np.flatnonzero(fixed), first)):
        if len(sel) == 0:
            continue
        r = np.arange(c)[rows][:, None]
        s = sel[None, :]
        Rf = Rp[r, batch.prim_part[s]]  # (poses or designs, |sel|, 3, 3), each operand gathered in one step
        R = _mm(Rf, batch.R[owner[r], s])
        o = _mv(Rf, batch.o[owner[r], s])
        x = _world_extent(kind3[r, s].ravel(), R.reshape(-1, 3, 3), hw3[r, s].reshape(-1, 3)).reshape(len(R), len(sel), 3)
        if isinstance(rows, slice):
            Rw[:, sel], ext[:, sel], ro[:, sel] = R, x, o
        else:
            Rw[:, sel], ext[:, sel], ro[:, sel] = R[inv], x[inv], o[inv]
    return Rw.reshape(c * P, 3, 3), ext.reshape(c * P, 3), ro


def _check_chunk(batch, owner, frames, s, e, reachable, depth, pc_all, ph_all, pp_a, pp_b, start, count,
                 kind_flat) -> None:
    """:func:`check_posed` on poses s:e (``depth`` is that chunk's view, updated in place)."""
    c = e - s
    P = len(batch.kind)
    Rp = np.stack([frames[name][0][s:e] for name in batch.part_names], axis=1)  # (c, parts, 3, 3)
    tp = np.stack([frames[name][1][s:e] for name in batch.part_names], axis=1)  # (c, parts, 3)
    pc, ph = pc_all[owner], ph_all[owner]
    # (parts, 3, poses) layout: the part-pair gathers below copy whole rows
    wc = np.ascontiguousarray((_mv(Rp, pc) + tp).transpose(1, 2, 0))
    wh = np.ascontiguousarray(_mv(np.abs(Rp), ph).transpose(1, 2, 0))
    part_near = np.all(np.abs(wc[pp_a] - wc[pp_b]) <= wh[pp_a] + wh[pp_b], axis=1)  # (part pairs, poses)
    part_near &= reachable[None, :]
    j, pose = np.nonzero(part_near)
    cnt = count[j]
    total = int(cnt.sum())
    if total == 0:
        return
    # every primitive pair of the surviving part pairs, in (pose, primitive pair) order
    pose = np.repeat(pose, cnt)
    k = np.repeat(start[j] - (np.cumsum(cnt) - cnt), cnt) + np.arange(total)
    # world rotation, centre and exact world extents of every primitive at every pose of the chunk
    hw = batch.half[owner].reshape(c * P, 3)
    Rw, ext, ro = _posed_primitives(batch, owner, Rp, hw, kind_flat)
    cw = (ro + tp[:, batch.prim_part]).reshape(c * P, 3)
    box = np.concatenate([cw - ext, cw + ext], axis=1)  # (c·P, 6): world box low corner, high corner
    ia = pose * P + batch.pair_a[k]
    ib = pose * P + batch.pair_b[k]
    ba, bb = box[ia], box[ib]
    near = np.all((ba[:, :3] <= bb[:, 3:]) & (bb[:, :3] <= ba[:, 3:]), axis=-1)
    if not near.any():
        return
    t = np.flatnonzero(near)
    ia, ib = ia[t], ib[t]
    # a pair separated on one of _depth's own axes has a depth ≤ 0 there, which adds nothing to
    # ``depth`` (its floor is 0): the seven cheapest axes first (~99 % of the pairs), _depth on the rest
    keep = ~_separated(kind_flat[ia], Rw[ia], hw[ia], cw[ia], kind_flat[ib], Rw[ib], hw[ib], cw[ib])
    if not keep.any():
        return
    t, ia, ib = t[keep], ia[keep], ib[keep]
    dep = _depth(kind_flat[ia], Rw[ia], hw[ia], cw[ia], kind_flat[ib], Rw[ib], hw[ib], cw[ib])
    np.maximum.at(depth, (pose[t], batch.pair_part[k[t]]), np.maximum(dep, 0.0))

"""Fast 3-PRRR link interference: convex primitives and separating axes, vectorised over poses.

The reference is :mod:`analysis.interference` (manifold3d meshes of the CAD parts, one exact
boolean per candidate pair, ~20 ms a pose). This module tests the same part pairs, built from
the same part tables (:func:`hapticopt.design.prrr.cad.part_specs`), without meshes:

* **Shapes.** Every SOLID primitive of a part table is used as it is — box, cylinder, sphere —
  in its own frame; a part is the union of its primitives. HOLEs (pin bores, the carriage's
  rail slot) are ignored, so parts are *filled*: material is only ever added (conservative).
  OVERLAP primitives are mass-model bookkeeping and are not material.
* **Pairs.** The reference's rule: every pair of parts on different rigid bodies that are not
  joined by a joint (:func:`hapticopt.design.prrr.cad.neighbours`).
* **Test.** Two convex primitives are disjoint iff some axis separates their projections
  (separating-axis theorem). The projection half-width of a primitive on a unit axis n is its
  support: box Σ_k |n·e_k| h_k; cylinder h|n·a| + r√(1 − (n·a)²); sphere r. Candidate axes per
  primitive pair: the 3 + 3 frame axes, their 9 cross products (the complete set for two boxes,
  so box–box is exact), the centre–centre direction, and for each cylinder the radial direction
  towards the other centre and its rim-point direction. Any separating axis proves
  separation, so a missing axis can only report a collision that is not there: the test is
  conservative for every shape, exact for box–box, exact for sphere–sphere.
* **Depth.** The smallest overlap over the candidate axes is an upper bound on the penetration
  depth [m] (exact for box–box). The reference ignores overlaps below
  :data:`analysis.interference.NOISE_MM3` (1 mm³); here a pair collides when that depth
  exceeds :data:`DEPTH_TOL` (0.1 mm). Shallow corner contacts (depth 0.1–0.8 mm, < 1 mm³) are
  therefore collisions here and noise there: the fast model is the stricter of the two.
* **Speed.** World-axis-aligned boxes of every part over every tested part pair first; the
  world-axis-aligned bounds of the primitives (exact support extents, computed once per pose and
  primitive) on the primitive pairs of the surviving part pairs; then the seven cheapest of the
  candidate axes (both frames, centre to centre), which separate ~99 % of what is left and change
  no result (a separated pair's depth is negative, the depth table's floor is 0); the 16 cheap
  axes on the rest, the 40 sampled axes only on curved pairs still overlapping; each stage one
  numpy pass over a chunk of poses. By default these stages run as one numba loop over poses and
  pairs (:mod:`._interference_kernels`, bitwise-equal depths; the numpy path is the reference and
  the fallback where :func:`availability` says why the kernel cannot run). :func:`check_joints` takes
  the poses as joint values and its kernel builds the part frames itself (no per-pose frame arrays),
  doing the work that does not change with the pose once per design (docs/workspace_interference.md);
  :func:`deepest_joints` is that kernel keeping only each pose's deepest overlap, from the joint
  angles' cos / sin (:func:`joint_cos_sin`), for the batched draft evaluator.
  Poses come from the numpy inverse kinematics (:func:`hapticopt.design.prrr.kinematics.inverse_kinematics`,
  ``xp=numpy``; the batched draft evaluator's jitted copy), in the CAD's elbow branch.

Usage::

    model = prepare(design)                        # once per design (part tables, ~ms)
    res = check_points(model, points)              # points (n, 3) [m]; res.collides (n,)
    frac = removed_fraction(design)                # share of the sampled workspace volume lost
    frac, soft = interference_fractions(design)    # … and its continuous companion (depth ramp)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from hapticopt.analysis import compute
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.parts import Kind, Role
from hapticopt.design.prrr.params import GAMMAS, PrrrDesign
from hapticopt.design.prrr.kinematics import inverse_kinematics, params_np
from hapticopt.analysis.prrr.workspace import ELBOW_BRANCH, workspace_sample_weights

#: a primitive pair collides when its smallest overlap over the candidate axes exceeds this [m]:
#: above the chord error of the reference's 32-segment circles at the 12 mm bosses,
#: 12·(1 − cos(π/32)) = 0.058 mm, so contacts the reference's meshes cannot resolve are not
#: reported; every deeper overlap is (docs/workspace_interference.md: the only disagreements
#: with the reference are real overlaps of 0.1–0.8 mm depth but < 1 mm³ volume, which the
#: reference discards as noise)
DEPTH_TOL = 1e-4

#: depth scale of the continuous companion of the removed fraction [m]: a pose counts
#: clip(d / OVERLAP_SCALE, 0, 1) of its weight, d its deepest pair overlap. 1 mm spans the band
#: where the fast model and the manifold3d reference disagree (fast-only collisions 0.17–0.81 mm
#: deep; the reference's shallowest accepted one 0.72 mm), and every colliding pose of prrr-paper (the layout
#: before issue 15) is deeper (≥ 1.06 mm), so there both fractions were 0.46848 (docs/workspace_interference.md)
OVERLAP_SCALE = 1e-3

_BOX, _CYL, _SPH = 0, 1, 2
_KIND = {Kind.BOX: _BOX, Kind.CYLINDER: _CYL, Kind.SPHERE: _SPH}


@dataclass(frozen=True, kw_only=True, eq=False)
class FastModel:
    """Per-design precomputation: the SOLID primitives of every part (part frame, SI), the
    primitive pairs to test (from the part pairs that can collide)."""

    design: PrrrDesign
    part_names: tuple[str, ...]
    part_pairs: tuple[tuple[str, str], ...]  # tested part pairs (as the reference)
    prim_part: np.ndarray  # (P,) index into part_names
    kind: np.ndarray  # (P,) 0 box, 1 cylinder, 2 sphere
    R: np.ndarray  # (P, 3, 3) primitive axes in the part frame (columns)
    o: np.ndarray  # (P, 3) primitive centre in the part frame [m]
    half: np.ndarray  # (P, 3) box: half extents; cylinder: (r, r, h/2); sphere: (r, r, r) [m]
    pair_a: np.ndarray  # (K,) primitive index
    pair_b: np.ndarray  # (K,) primitive index
    pair_part: np.ndarray  # (K,) index into part_pairs


@dataclass(frozen=True, kw_only=True)
class FastResult:
    """Interference at ``n`` poses: per pose whether any pair collides, and the per-part-pair
    upper bound on the penetration depth (0 where separated) [m]."""

    points: np.ndarray  # (n, 3) [m]
    reachable: np.ndarray  # (n,) bool
    collides: np.ndarray  # (n,) bool (False where unreachable)
    depth: np.ndarray  # (n, n_part_pairs) [m]
    part_pairs: tuple[tuple[str, str], ...]

    def pairs_at(self, k: int) -> list[tuple[str, str]]:
        """Colliding part pairs at pose ``k``."""
        return [self.part_pairs[j] for j in np.flatnonzero(self.depth[k] > DEPTH_TOL)]


def _skip_pairs(specs: dict[str, Any]) -> set[frozenset]:
    """The reference's skip rule (:func:`analysis.interference.prepare`): joined parts and
    parts of one rigid body."""
    return _skip_rule(tuple(specs), tuple(spec.body for spec in specs.values()))


def _skip_rule(names: tuple[str, ...], bodies: tuple[str, ...]) -> set[frozenset]:
    skip = set(cad_prrr.neighbours())
    for i, a in enumerate(names):
        for j in range(i + 1, len(names)):
            if bodies[i] == bodies[j]:
                skip.add(frozenset((a, names[j])))
    return skip


@functools.lru_cache(maxsize=32)
def _pair_tables(names: tuple[str, ...], bodies: tuple[str, ...], prim_part: tuple[int, ...]
                 ) -> tuple[tuple[tuple[str, str], ...], np.ndarray, np.ndarray, np.ndarray]:
    """Part pairs to test and their primitive pairs; depend only on the part names, bodies and
    the number of SOLID primitives of each part (cached: every design of one layout shares them)."""
    skip = _skip_rule(names, bodies)
    prim = np.asarray(prim_part)
    part_pairs, pa, pb, pp = [], [], [], []
    members = [np.flatnonzero(prim == j) for j in range(len(names))]
    for i, a in enumerate(names):
        ia = members[i]
        for j in range(i + 1, len(names)):
            b = names[j]
            ib = members[j]
            if frozenset((a, b)) in skip or len(ia) == 0 or len(ib) == 0:
                continue
            pa.append(np.repeat(ia, len(ib)))
            pb.append(np.tile(ib, len(ia)))
            pp.append(np.full(len(ia) * len(ib), len(part_pairs)))
            part_pairs.append((a, b))
    out = (np.concatenate(pa), np.concatenate(pb), np.concatenate(pp))
    for x in out:
        x.flags.writeable = False
    return (tuple(part_pairs), *out)


def prepare(design: PrrrDesign, *, specs: dict[str, Any] | None = None) -> FastModel:
    """Primitive tables of every part of ``design`` (raises :class:`InvalidDesign` where the CAD
    cannot lay the parts out; ``specs``: :func:`hapticopt.design.prrr.cad.part_specs` of ``design``,
    computed when omitted)."""
    specs = cad_prrr.part_specs(design) if specs is None else specs
    names = tuple(specs)
    prim_part, kind, R, o, half = [], [], [], [], []
    for j, name in enumerate(names):
        for p in specs[name].primitives:
            if p.role != Role.SOLID:
                continue
            a, b, c = p.dims
            k = _KIND[p.kind]
            h = {_BOX: (a / 2, b / 2, c / 2), _CYL: (a, a, b / 2), _SPH: (a, a, a)}[k]
            prim_part.append(j)
            kind.append(k)
            R.append(np.asarray(p.R, dtype=float))
            o.append(np.asarray(p.o, dtype=float))
            half.append(h)
    part_pairs, pa, pb, pp = _pair_tables(names, tuple(s.body for s in specs.values()), tuple(prim_part))
    return FastModel(design=design, part_names=names, part_pairs=part_pairs, prim_part=np.asarray(prim_part),
                     kind=np.asarray(kind), R=np.asarray(R), o=np.asarray(o), half=np.asarray(half, dtype=float),
                     pair_a=pa, pair_b=pb, pair_part=pp)


def models_from_tables(designs: list[PrrrDesign], tables: Any) -> list[FastModel]:
    """:func:`prepare` of every design of one part layout at once, from the stacked part tables
    ``tables`` (:class:`hapticopt.design.prrr.cad_arrays.PartTables`; ``designs``: its rows' designs,
    in order): the SOLID primitives' axes, centres and half sizes as array slices of one stacked
    table (tested equal to :func:`prepare` of :func:`hapticopt.design.prrr.cad.part_specs`)."""
    solid = np.array([role == Role.SOLID for role in tables.role], dtype=bool)
    prim_part = np.asarray(tables.prim_part)[solid]
    kind = np.array([_KIND[Kind(k)] for k in np.asarray(tables.kind)[solid]], dtype=int)
    dims = tables.dims[:, solid]
    a, b, c = dims[..., 0], dims[..., 1], dims[..., 2]
    kb, kc = (kind == _BOX)[None], (kind == _CYL)[None]
    # box: a/2, b/2, c/2; cylinder: a, a, b/2; sphere: a, a, a (as prepare)
    half = np.stack([np.where(kb, a / 2, a), np.where(kb, b / 2, a),
                     np.where(kb, c / 2, np.where(kc, b / 2, a))], axis=-1)
    R, o = tables.R[:, solid], tables.o[:, solid]
    for x in (R, o, half, prim_part, kind):
        x.flags.writeable = False  # every model's rows are views of these (shared, as the pair tables)
    part_pairs, pa, pb, pp = _pair_tables(tables.part_names, tables.bodies, tuple(prim_part.tolist()))
    return [FastModel(design=d, part_names=tables.part_names, part_pairs=part_pairs, prim_part=prim_part,
                      kind=kind, R=R[k], o=o[k], half=half[k], pair_a=pa, pair_b=pb, pair_part=pp)
            for k, d in enumerate(designs)]


class PrimitiveBatch(NamedTuple):
    """The primitive tables of many designs of one layout (same parts, same primitive kinds), stacked:
    ``R`` (m, P, 3, 3), ``o`` (m, P, 3), ``half`` (m, P, 3); the rest shared (see :class:`FastModel`)."""

    part_names: tuple[str, ...]
    part_pairs: tuple[tuple[str, str], ...]
    prim_part: np.ndarray
    kind: np.ndarray
    R: np.ndarray
    o: np.ndarray
    half: np.ndarray
    pair_a: np.ndarray
    pair_b: np.ndarray
    pair_part: np.ndarray


def layout_key(model: FastModel) -> tuple:
    """Designs with equal keys share the part pairs and primitive kinds (one :class:`PrimitiveBatch`)."""
    return model.part_names, tuple(model.prim_part.tolist()), tuple(model.kind.tolist())


def stack_models(models: list[FastModel]) -> PrimitiveBatch:
    """Stack the primitive tables of models with one :func:`layout_key` (ValueError otherwise)."""
    m0 = models[0]
    key = layout_key(m0)
    if any(layout_key(m) != key for m in models[1:]):
        raise ValueError("stack_models: the models have different part layouts (group them by layout_key)")
    return PrimitiveBatch(part_names=m0.part_names, part_pairs=m0.part_pairs, prim_part=m0.prim_part,
                          kind=m0.kind, R=np.stack([m.R for m in models]), o=np.stack([m.o for m in models]),
                          half=np.stack([m.half for m in models]), pair_a=m0.pair_a, pair_b=m0.pair_b,
                          pair_part=m0.pair_part)


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


def _half_width(kind, loc, half):
    """Projection half-width of primitives from ``loc`` (m, A, 3), the |components| of unit axes along
    the primitive axes; half (m, 3)."""
    box = loc[..., 0] * half[:, 0, None] + loc[..., 1] * half[:, 1, None] + loc[..., 2] * half[:, 2, None]
    az = loc[..., 2]
    cyl = half[:, 2, None] * az + half[:, 0, None] * np.sqrt(np.clip(1.0 - az * az, 0.0, None))
    k = kind[:, None]
    return np.where(k == _BOX, box, np.where(k == _CYL, cyl, half[:, 0, None]))


def _support(kind, R, half, n):
    """Projection half-width of primitives on unit axes: R (m, 3, 3), half (m, 3), n (m, A, 3)."""
    return _half_width(kind, np.abs(_mm(n, R)), half)


def _world_extent(kind, R, half):
    """Half extents (m, 3) of primitives along the world axes: :func:`_support` on the unit axes,
    whose projections ``n @ R`` are the rows of ``R`` themselves (no product formed)."""
    return _half_width(kind, np.abs(R), half)


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


#: surface samples whose closest-point directions serve as extra candidate axes: box corners
#: and edge midpoints; cylinder rims (both end circles) at this many angles
_RIM_SAMPLES = 12


@functools.cache
def _sample_tables() -> tuple[np.ndarray, np.ndarray]:
    """Unit-box sample points (S, 3): 8 corners + 12 edge midpoints (S = 20); unit-cylinder rim
    points (S, 3): both end circles at _RIM_SAMPLES angles, cut (or padded by repetition) to S."""
    sgn = np.array([[i, j, k] for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                    if (i != 0) + (j != 0) + (k != 0) >= 2], dtype=float)  # 8 corners + 12 edge midpoints
    ang = 2.0 * np.pi * np.arange(_RIM_SAMPLES) / _RIM_SAMPLES
    ring = np.stack([np.cos(ang), np.sin(ang)], axis=1)  # (Q, 2)
    loc = np.concatenate([np.concatenate([ring, np.full((_RIM_SAMPLES, 1), z)], axis=1) for z in (-1.0, 1.0)])
    loc = np.concatenate([loc, loc[: len(sgn) - len(loc)]]) if len(loc) < len(sgn) else loc[: len(sgn)]
    for x in (sgn, loc):
        x.flags.writeable = False
    return sgn, np.ascontiguousarray(loc)


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


def check_points(model: FastModel, points, *, branch: int = cad_prrr.DEFAULT_BRANCH,
                 compiled: bool | None = None) -> FastResult:
    """Interference of the tested part pairs at end-effector points (n, 3) [m]: the numpy IK
    (:func:`part_frames_batch`'s) in IK branch ``branch``, then :func:`check_joints` (``compiled``: as
    :func:`check_posed`)."""
    return point_checker(model, branch=branch, compiled=compiled)(points)


def point_checker(model: FastModel, *, branch: int = cad_prrr.DEFAULT_BRANCH, compiled: bool | None = None):
    """:func:`check_points` of ``model`` as a function of the points, for a caller that checks one design's
    points in several calls (the free workspace's bisection passes, then the interference samples): the
    steps that depend on the design only (its one-design :func:`stack_models`, the IK parameters, the leg
    geometry, and :func:`joint_tables` from the first call that runs the compiled kernel on) are taken once
    instead of at every call (the same values: each result is the one :func:`check_points` gives)."""
    g = model.design.geometry
    prm = params_np(model.design)
    geometry = LegGeometry(*(np.array([float(getattr(g, f))]) for f in LegGeometry._fields))
    batch = stack_models([model])
    tables: list = []  # joint_tables(batch, geometry) once a call may run the kernel (check_joints' rule)

    def check(points) -> FastResult:
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        ik = inverse_kinematics(prm, pts, xp=np)
        if not tables and (compiled or (compiled is None and _POSES_CHECKED[0] + len(pts) >= KERNEL_AFTER_POSES)):
            tables.append(joint_tables(batch, geometry))
        return check_joints(batch, np.zeros(len(pts), dtype=int), pts, np.asarray(ik.sliders),
                            np.asarray(ik.theta)[:, branch], np.asarray(ik.reachable), geometry,
                            tables=tables[0] if tables else None, compiled=compiled)

    return check


#: poses per pass of :func:`check_posed` (bounds the per-(pose, primitive) world tables: ~4 MB
#: of rotations per 1,000 poses of a 51-primitive layout)
CHUNK_POSES = 4096


@functools.lru_cache(maxsize=32)
def _part_pair_csr(part_names: tuple[str, ...], part_pairs: tuple[tuple[str, str], ...], pair_part: bytes
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per part pair: its two part indices, the first primitive pair and the number of primitive
    pairs (``pair_part`` is sorted: :func:`_pair_tables` appends each part pair's block in order)."""
    pp = np.frombuffer(pair_part, dtype=np.int64)
    count = np.bincount(pp, minlength=len(part_pairs))
    start = np.cumsum(count) - count
    pp_a = np.array([part_names.index(a) for a, _ in part_pairs], dtype=int)
    pp_b = np.array([part_names.index(b) for _, b in part_pairs], dtype=int)
    return pp_a, pp_b, start, count


#: poses a process checks with the numpy reference before the default switches to the compiled kernel:
#: loading it (numba's import and the cached kernel) costs ≈ 0.55 s, and the joint kernel saves ≈ 37 µs of
#: the numpy check's ≈ 40 µs per pose (14.4×; the frame kernel saved ≈ 32 µs), so it pays from ≈ 15,000
#: poses (a batched draft evaluation of 1024 designs checks ≈ 190,000; one `evaluate` at standard ≈ 220,
#: where loading it made the command 1.37× slower; docs/workspace_interference.md)
KERNEL_AFTER_POSES = 20_000
_POSES_CHECKED = [0]


@functools.cache
def availability() -> str | None:
    """None when the compiled kernel of :func:`check_posed` can run here, else why not (one line); the
    numpy reference runs then."""
    return compute.unavailable(_load_kernels, "the compiled interference kernel's module")


def _load_kernels() -> None:
    from hapticopt.analysis.prrr import _interference_kernels  # noqa: F401


def _use_kernel(n: int, compiled: bool | None) -> bool:
    """Whether a check of ``n`` more poses runs the compiled kernel (``compiled`` as :func:`check_posed`)."""
    _POSES_CHECKED[0] += n
    if compiled is None:
        return _POSES_CHECKED[0] >= KERNEL_AFTER_POSES and availability() is None
    if compiled:
        reason = availability()
        if reason is not None:
            raise RuntimeError(reason)
    return bool(compiled)


@functools.lru_cache(maxsize=32)
def _part_segments(prim_part: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The primitives grouped by part (``prim_part``: int64 bytes): their order (stable; None where they
    are in part order already, as :func:`prepare` lists them), the first position of each part's group
    in it, and the parts that have a group (for ``ufunc.reduceat``)."""
    pp = np.frombuffer(prim_part, dtype=np.int64)
    order = np.argsort(pp, kind="stable")
    parts, starts = np.unique(pp[order], return_index=True)
    return (None if np.array_equal(order, np.arange(len(pp))) else order), starts, parts


def _part_boxes(batch: PrimitiveBatch) -> tuple[np.ndarray, ...]:
    """Every part's box in its part frame (centre, half widths: (m, parts, 3) [m]) from its primitives'
    exact extents, and the tested part pairs' parts and primitive-pair blocks (:func:`_part_pair_csr`)."""
    P = len(batch.kind)
    m = len(batch.R)
    loc_ext = _world_extent(np.tile(batch.kind, m), batch.R.reshape(-1, 3, 3), batch.half.reshape(-1, 3)).reshape(m, P, 3)
    n_parts = len(batch.part_names)
    plo = np.full((m, n_parts, 3), np.inf)
    phi = np.full((m, n_parts, 3), -np.inf)
    order, starts, parts = _part_segments(np.asarray(batch.prim_part, dtype=np.int64).tobytes())
    if len(starts):  # each part's primitives' smallest and largest extent (min and max: exact, in any order)
        o, ext = (batch.o, loc_ext) if order is None else (batch.o[:, order], loc_ext[:, order])
        plo[:, parts] = np.minimum.reduceat(o - ext, starts, axis=1)
        phi[:, parts] = np.maximum.reduceat(o + ext, starts, axis=1)
    empty = ~np.isfinite(plo)  # a part without SOLID primitives is in no tested pair (_pair_tables)
    plo[empty], phi[empty] = 0.0, 0.0
    pc_all, ph_all = 0.5 * (plo + phi), 0.5 * (phi - plo)  # (m, parts, 3)
    pp_a, pp_b, start, count = _part_pair_csr(batch.part_names, batch.part_pairs,
                                              np.asarray(batch.pair_part, dtype=np.int64).tobytes())
    return pc_all, ph_all, pp_a, pp_b, start, count


def check_posed(batch: PrimitiveBatch, owner: np.ndarray, points: np.ndarray,
                frames: dict[str, tuple[np.ndarray, np.ndarray]], reachable: np.ndarray, *,
                compiled: bool | None = None) -> FastResult:
    """Interference at n posed configurations of the designs of ``batch``: pose k belongs to design
    ``owner[k]``, its parts at ``frames`` (name → world rotation (n, 3, 3), origin (n, 3) [m], as
    :func:`hapticopt.design.prrr.cad.part_frames_arrays`), ``reachable`` (n,) bool. One numpy pass
    over every pose of every design, in chunks of :data:`CHUNK_POSES` poses (the batched draft
    evaluator's path; :func:`check_points` is the one-design case).

    Per chunk: world-axis-aligned boxes of every part (from its primitives' boxes in the part frame)
    over every tested part pair; the world rotation, centre and exact world extents of every
    primitive at every pose, computed once; the primitive pairs of the part pairs that survive,
    tested on those extents (a part box contains its primitives' boxes, so this sees the same
    candidates as testing every primitive pair); the separating axes (:func:`_depth`) on the rest.

    ``compiled``: None (default) runs the numba kernel (:mod:`._interference_kernels`: the same
    stages per pose and pair, bitwise-equal depths) once it pays — from the call that takes this
    process's checked poses to :data:`KERNEL_AFTER_POSES` on, where :func:`availability` allows —
    and this numpy reference before (the depths are bit for bit the same either way); True requires
    the kernel (RuntimeError with the reason); False runs numpy."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    return _check_frames(batch, owner, pts, frames, reachable, compiled=_use_kernel(len(pts), compiled))


def _check_frames(batch: PrimitiveBatch, owner: np.ndarray, pts: np.ndarray,
                  frames: dict[str, tuple[np.ndarray, np.ndarray]], reachable: np.ndarray, *,
                  compiled: bool) -> FastResult:
    """:func:`check_posed` once the kernel is chosen (``compiled``)."""
    n = len(pts)
    owner = np.asarray(owner, dtype=int)
    reachable = np.asarray(reachable)
    depth = np.zeros((n, len(batch.part_pairs)))
    P = len(batch.kind)
    pc_all, ph_all, pp_a, pp_b, start, count = _part_boxes(batch)
    if compiled:
        _check_compiled(batch, owner, frames, reachable, depth, pc_all, ph_all, pp_a, pp_b, start, count)
        return FastResult(points=pts, reachable=reachable, collides=np.any(depth > DEPTH_TOL, axis=1),
                          depth=depth, part_pairs=batch.part_pairs)
    kind_all = np.tile(batch.kind, CHUNK_POSES)
    for s in range(0, n, CHUNK_POSES):
        e = min(n, s + CHUNK_POSES)
        _check_chunk(batch, owner[s:e], frames, s, e, reachable[s:e], depth[s:e], pc_all, ph_all,
                     pp_a, pp_b, start, count, kind_all[: (e - s) * P])
    return FastResult(points=pts, reachable=reachable, collides=np.any(depth > DEPTH_TOL, axis=1),
                      depth=depth, part_pairs=batch.part_pairs)


def _check_compiled(batch, owner, frames, reachable, depth, pc_all, ph_all, pp_a, pp_b, start, count) -> None:
    """:func:`check_posed`'s chunks through the numba kernel (``depth`` updated in place)."""
    from hapticopt.analysis.prrr import _interference_kernels as K  # loaded by availability()

    i64 = functools.partial(np.ascontiguousarray, dtype=np.int64)
    f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
    sgn, rim = _sample_tables()
    tables = (f64(pc_all), f64(ph_all), i64(pp_a), i64(pp_b), i64(start), i64(count), i64(batch.pair_a),
              i64(batch.pair_b), i64(batch.prim_part), i64(batch.kind), f64(batch.R), f64(batch.o), f64(batch.half),
              sgn, rim)
    owner = i64(owner)
    reachable = np.ascontiguousarray(reachable, dtype=np.bool_)
    for s in range(0, len(owner), CHUNK_POSES):
        e = min(len(owner), s + CHUNK_POSES)
        Rp = np.stack([frames[name][0][s:e] for name in batch.part_names], axis=1)  # (c, parts, 3, 3)
        tp = np.stack([frames[name][1][s:e] for name in batch.part_names], axis=1)  # (c, parts, 3)
        K.check_poses(f64(Rp), f64(tp), owner[s:e], reachable[s:e], *tables, depth[s:e])



class LegGeometry(NamedTuple):
    """The geometry the part frames read (:func:`hapticopt.design.prrr.cad.part_frames_arrays`), one entry
    per design of a :class:`PrimitiveBatch`, (m,) each: β [rad], d1, d2, d3 [m], θ₁ₚ [rad]."""

    beta: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    d3: np.ndarray
    theta_1p: np.ndarray


#: frame rules of :mod:`._interference_kernels` by part name prefix (cad.part_frames_arrays' parts)
_RULES = {"base": 0, "rail": 0, "screw": 0, "motor": 0, "carriage": 1, "housing": 1, "link1": 2, "link2": 3,
          "platform": 4}


@functools.lru_cache(maxsize=32)
def _frame_rules(part_names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray] | None:
    """Each part's frame rule and leg index (0, 1, 2 for legs 1, 2, 3) for
    :func:`._interference_kernels.check_joint_poses`; None where a part is not one of
    :func:`hapticopt.design.prrr.cad.part_frames_arrays`'s (its frames are then built in numpy)."""
    rule, leg = [], []
    for name in part_names:
        kind, _, i = name.partition("_")
        if kind not in _RULES or (i and not (i.isdigit() and int(i) in cad_prrr.LEGS)) or (not i) != (kind in ("base", "platform")):
            return None
        rule.append(_RULES[kind])
        leg.append(cad_prrr.LEGS.index(int(i)) if i else 0)
    return np.asarray(rule, dtype=np.int64), np.asarray(leg, dtype=np.int64)


class JointTables(NamedTuple):
    """The per-batch inputs of :func:`._interference_kernels.check_joint_poses` (:func:`joint_tables`):
    ``head`` the frame rules, ``design`` the legs' per-design vectors and lengths, ``tail`` the part
    boxes, pair tables, primitives and sample tables, each a tuple in the kernel's argument order."""

    head: tuple
    design: tuple
    tail: tuple


def joint_tables(batch: PrimitiveBatch, geometry: LegGeometry) -> JointTables | None:
    """:func:`check_joints`' per-batch tables (compute once, pass to every call on the batch); None
    where a part has no frame rule (:func:`_frame_rules`)."""
    rules = _frame_rules(batch.part_names)
    if rules is None:
        return None
    i64 = functools.partial(np.ascontiguousarray, dtype=np.int64)
    f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
    pc_all, ph_all, pp_a, pp_b, start, count = _part_boxes(batch)
    # per design: the legs' vectors (cad.leg_vectors' products as part_frames_arrays forms them)
    beta = np.asarray(geometry.beta, dtype=float)
    sb, cb = np.sin(beta), np.cos(beta)
    cs = np.array([(math.cos(gm), math.sin(gm)) for gm in GAMMAS])  # (3 legs, 2)
    c, s = cs[None, :, 0], cs[None, :, 1]
    zero = np.zeros((3,))
    U = np.stack([cs[:, 0], cs[:, 1], zero], axis=1)
    T = np.stack([-cs[:, 1], cs[:, 0], zero], axis=1)
    W = np.stack([-cb[:, None] * c, -cb[:, None] * s, np.broadcast_to(sb[:, None], (len(beta), 3))], axis=2)
    V = np.stack([sb[:, None] * c, sb[:, None] * s, np.broadcast_to(cb[:, None], (len(beta), 3))], axis=2)
    a = np.asarray(GAMMAS)[None, :] + np.asarray(geometry.theta_1p, dtype=float)[:, None]  # (m, 3 legs)
    ca, sa = np.cos(a), np.sin(a)
    Rslide = np.zeros((len(beta), 3, 3, 3))
    Rslide[..., 0, 0], Rslide[..., 1, 0] = ca, sa
    Rslide[..., 0, 1], Rslide[..., 1, 1] = -sa, ca
    Rslide[..., 2, 2] = 1.0
    return JointTables(
        head=rules,
        design=(Rslide, f64(W), f64(V), f64(U), f64(T), f64(geometry.d1), f64(geometry.d2), f64(geometry.d3)),
        tail=(f64(pc_all), f64(ph_all), i64(pp_a), i64(pp_b), i64(start), i64(count), i64(batch.pair_a),
              i64(batch.pair_b), i64(batch.prim_part), i64(batch.kind), f64(batch.R), f64(batch.o), f64(batch.half),
              *_sample_tables()))


def check_joints(batch: PrimitiveBatch, owner: np.ndarray, points: np.ndarray, sliders: np.ndarray,
                 theta: np.ndarray, reachable: np.ndarray, geometry: LegGeometry, *,
                 tables: JointTables | None = None, compiled: bool | None = None) -> FastResult:
    """:func:`check_posed` at poses given by their joint values: sliders (n, 3) [m], joint angles
    theta (n, 3 legs, ≥ 2) [rad] of one IK branch, platform at ``points`` (n, 3) [m]; ``geometry``
    per design of ``batch``. The part frames are :func:`hapticopt.design.prrr.cad.part_frames_arrays`'s:
    the compiled kernel (:func:`._interference_kernels.check_joint_poses`) builds them per pose from
    the same products in the same order (the depths are bit for bit those of :func:`check_posed` on
    ``part_frames_arrays``' frames; tested), so no per-pose frame arrays are stacked; the numpy path
    builds the frames and runs :func:`check_posed`'s. ``tables``: :func:`joint_tables` of ``batch`` and
    ``geometry`` (computed when omitted); ``compiled`` as :func:`check_posed`."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    n = len(pts)
    use = _use_kernel(n, compiled)
    owner = np.asarray(owner, dtype=int)
    sliders, theta = np.asarray(sliders, dtype=float), np.asarray(theta, dtype=float)
    if use and tables is None:
        tables = joint_tables(batch, geometry)
    if not use or tables is None:
        g = geometry
        frames = cad_prrr.part_frames_arrays(g.beta[owner], g.d1[owner], g.d2[owner], g.d3[owner],
                                             g.theta_1p[owner], sliders, theta, pts)
        return _check_frames(batch, owner, pts, frames, reachable, compiled=use)
    from hapticopt.analysis.prrr import _interference_kernels as K  # loaded by availability()

    f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
    reachable = np.ascontiguousarray(reachable, dtype=np.bool_)
    depth = np.zeros((n, len(batch.part_pairs)))
    th1, th12 = theta[:, :, 0], theta[:, :, 0] + theta[:, :, 1]
    K.check_joint_poses(*tables.head, f64(sliders), f64(np.cos(th1)), f64(np.sin(th1)), f64(np.cos(th12)),
                        f64(np.sin(th12)), f64(pts), np.ascontiguousarray(owner, dtype=np.int64), reachable,
                        *tables.design, *tables.tail, np.arange(len(batch.part_pairs), dtype=np.int64), depth)
    return FastResult(points=pts, reachable=reachable, collides=np.any(depth > DEPTH_TOL, axis=1),
                      depth=depth, part_pairs=batch.part_pairs)


@functools.cache
def numba_trig_is_numpys() -> bool:
    """Whether the compiled kernels' cos and sin (libm's, as numba calls them) are numpy's bit for bit
    here, on 100,003 seeded angles over [−2π, 2π] (θ₁ + θ₂'s range) and the edge values; numpy may use
    its own vectorised routines on some CPUs (it does for arccos and arctan2 on this project's AVX-512
    machine, where cos and sin are libm's in both). Needs :func:`availability` None."""
    from hapticopt.analysis.prrr import _interference_kernels as K

    x = np.random.default_rng(20261126).uniform(-2.0 * np.pi, 2.0 * np.pi, 100_003)
    x = np.concatenate([x, [0.0, -0.0, np.pi, -np.pi, 2.0 * np.pi, -2.0 * np.pi, np.pi / 2, 1e-300, -1e-300]])
    c, s = np.empty_like(x), np.empty_like(x)
    K.cos_sin(x, c, s)
    return bool(np.array_equal(c.view(np.int64), np.cos(x).view(np.int64))
                and np.array_equal(s.view(np.int64), np.sin(x).view(np.int64)))


def joint_cos_sin(elbow: np.ndarray, phi: np.ndarray, psi: np.ndarray, branch: int) -> tuple[np.ndarray, ...]:
    """cos and sin of θ₁ and of θ₁ + θ₂ (c1, s1, c12, s12: (n, 3 legs) each) of IK branch ``branch`` from
    the elbow angle and the in-plane angles φ, ψ (n, 3) [rad] (``kinematics.inverse_kinematics``' branch
    and wrap), bit for bit ``np.cos`` / ``np.sin`` of the ``theta`` that :func:`check_joints` takes: in one
    compiled pass (:func:`._interference_kernels.elbow_cos_sin`) where :func:`numba_trig_is_numpys`, else
    the angles compiled and numpy's cos and sin. Needs :func:`availability` None."""
    from hapticopt.analysis.prrr import _interference_kernels as K

    f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
    n = len(elbow)
    th1, th12, c1, s1, c12, s12 = (np.empty((n, 3)) for _ in range(6))
    trig = numba_trig_is_numpys()
    K.elbow_cos_sin(f64(elbow), f64(phi), f64(psi), int(branch), trig, th1, th12, c1, s1, c12, s12)
    if not trig:
        c1, s1, c12, s12 = np.cos(th1), np.sin(th1), np.cos(th12), np.sin(th12)
    return c1, s1, c12, s12


def deepest_joints(owner: np.ndarray, points: np.ndarray, sliders: np.ndarray, trig: tuple[np.ndarray, ...],
                   reachable: np.ndarray, tables: JointTables) -> tuple[np.ndarray, np.ndarray]:
    """(collides (n,), deepest part-pair overlap (n,) [m]) at poses given by their joint values: the
    compiled :func:`check_joints` (``compiled=True``) with the cos and sin of the joint angles given
    (``trig``: :func:`joint_cos_sin`'s c1, s1, c12, s12), its ``collides`` and ``depth.max(axis=1)``
    bit for bit, the kernel keeping only each pose's deepest overlap (no (n, part pairs) array).
    ``tables``: :func:`joint_tables` (not None); needs :func:`availability` None."""
    from hapticopt.analysis.prrr import _interference_kernels as K

    f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
    n = len(points)
    depth = np.zeros((n, 1))
    n_pairs = len(tables.tail[2])
    K.check_joint_poses(*tables.head, f64(sliders), *(f64(x) for x in trig), f64(points),
                        np.ascontiguousarray(owner, dtype=np.int64), np.ascontiguousarray(reachable, dtype=np.bool_),
                        *tables.design, *tables.tail, np.zeros(n_pairs, dtype=np.int64), depth)
    deepest = depth[:, 0]
    return deepest > DEPTH_TOL, deepest


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


def overlap_share(res: FastResult, *, scale: float = OVERLAP_SCALE) -> np.ndarray:
    """Per-pose collision share (n,) in [0, 1]: clip(d / scale, 0, 1) of the deepest part-pair
    overlap d [m] at the pose (0 where separated or unreachable: ``depth`` is 0 there)."""
    d = res.depth.max(axis=1) if res.depth.shape[1] else np.zeros(len(res.points))
    return np.clip(d / scale, 0.0, 1.0)


def interference_fractions(design: PrrrDesign, *, n_phi: int, n_r: int, n_z: int,
                           scale: float = OVERLAP_SCALE, wp: Any = None, model_of=None, checker_of=None
                           ) -> tuple[float, float]:
    """(removed fraction, overlap fraction) of the sampled workspace volume, from one check of
    the poses (polar-cell weights w_i of :func:`hapticopt.analysis.prrr.workspace.workspace_sample_weights`):

    * removed = Σ w_i [pose i collides] / Σ w_i — piecewise constant in the design;
    * overlap = Σ w_i clip(d_i / scale, 0, 1) / Σ w_i, d_i the deepest pair overlap at pose i —
      its continuous companion (equal to the removed fraction where every colliding pose is at
      least ``scale`` deep; docs/workspace_interference.md).

    Both 0 for an empty sample (the primitive tables are not needed then). ``wp``: the design's
    default workspace parameters, ``model_of(design)``: its primitive tables (default :func:`prepare`),
    ``checker_of(design)``: its :func:`point_checker` in :data:`ELBOW_BRANCH` (used before ``model_of``),
    when the caller has them (the registry call's shared steps)."""

    pts, w = workspace_sample_weights(design, n_phi=n_phi, n_r=n_r, n_z=n_z, wp=wp)
    if len(pts) == 0 or not w.sum() > 0:
        return 0.0, 0.0
    if checker_of is not None:
        res = checker_of(design)(pts)
    else:
        res = check_points((prepare if model_of is None else model_of)(design), pts, branch=ELBOW_BRANCH)
    return fractions_of(w, res.collides, overlap_share(res, scale=scale))


def fractions_of(w: np.ndarray, collides: np.ndarray, share: np.ndarray) -> tuple[float, float]:
    """(removed, overlap) fractions from the pose weights ``w``, collision flags and overlap shares
    (see :func:`interference_fractions`)."""
    total = w.sum()
    return float(w[collides].sum() / total), float(w @ share / total)


def removed_fraction(design: PrrrDesign, *, n_phi: int, n_r: int, n_z: int) -> float:
    """Share of the sampled workspace volume whose poses collide (the polar-cell weights of
    :func:`hapticopt.analysis.prrr.workspace.workspace_sample_weights`; 0 for an empty sample)."""
    return interference_fractions(design, n_phi=n_phi, n_r=n_r, n_z=n_z)[0]

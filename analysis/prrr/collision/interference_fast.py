"""Fast 3-PRRR link interference: convex primitives and separating axes, one numba kernel over poses.

The reference is :mod:`analysis.interference` (manifold3d meshes of the CAD parts, one exact
boolean per candidate pair, far slower). This module tests the same part pairs, built from
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
  so box–box is exact), the centre–centre direction, and the directions from surface samples of
  each primitive to their closest points on the other. Any separating axis proves separation, so
  a missing axis can only report a collision that is not there: conservative for every shape,
  exact for box–box and sphere–sphere.
* **Depth.** The smallest overlap over the candidate axes is an upper bound on the penetration
  depth [m] (exact for box–box). The reference ignores overlaps below
  :data:`analysis.interference.NOISE_MM3` (1 mm³); here a pair collides when that depth
  exceeds :data:`DEPTH_TOL` (0.1 mm): the fast model is the stricter of the two.
* **Route.** One: :func:`check_joints` takes the poses as joint values (sliders, joint angles of the
  one IK, :func:`hapticopt.design.prrr.kinematics.inverse_kinematics`) and the numba kernel
  (:mod:`._interference_kernels`) builds the part frames, prunes by part and primitive boxes and tests
  the axes per pose. Its numpy reference, which proves it right bit for bit, lives in the tests
  (``tests/analysis/prrr/interference_reference.py``): the kernel pays from one pose (docs/performance.md),
  so the package has no numpy route and every ``Compute`` backend runs it.

Usage::

    model = prepare(design)                        # once per design (part tables, ~ms)
    res = check_points(model, points)              # points (n, 3) [m]; res.collides (n,)
    frac, soft = interference_fractions(design, **INTERFERENCE_SAMPLING)  # removed / overlap fraction
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from hapticopt.analysis.compute import unavailable
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design.parts import Kind, Role
from hapticopt.design.prrr.params import GAMMAS, PrrrDesign
from hapticopt.design.prrr.kinematics import inverse_kinematics, leg_frames, params_np
from hapticopt.analysis.prrr.geometry.workspace import ELBOW_BRANCH, workspace_sample_weights


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
    ``tables`` (:class:`hapticopt.design.prrr.layout.PartTables`; ``designs``: its rows' designs,
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

def _half_width(kind, loc, half):
    """Projection half-width of primitives from ``loc`` (m, A, 3), the |components| of unit axes along
    the primitive axes; half (m, 3)."""
    box = loc[..., 0] * half[:, 0, None] + loc[..., 1] * half[:, 1, None] + loc[..., 2] * half[:, 2, None]
    az = loc[..., 2]
    cyl = half[:, 2, None] * az + half[:, 0, None] * np.sqrt(np.clip(1.0 - az * az, 0.0, None))
    k = kind[:, None]
    return np.where(k == _BOX, box, np.where(k == _CYL, cyl, half[:, 0, None]))

def _world_extent(kind, R, half):
    """Half extents (m, 3) of primitives along the world axes: :func:`_support` on the unit axes,
    whose projections ``n @ R`` are the rows of ``R`` themselves (no product formed)."""
    return _half_width(kind, np.abs(R), half)

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


def joint_tables(batch: PrimitiveBatch, geometry: LegGeometry) -> JointTables:
    """:func:`check_joints`' per-batch tables (compute once, pass to every call on the batch); ValueError
    where a part has no frame rule (:func:`_frame_rules`: not one of ``cad.part_frames_arrays``' parts)."""
    rules = _frame_rules(batch.part_names)
    if rules is None:
        raise ValueError(f"interference check: no frame rule for a part of {batch.part_names}")
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


@functools.cache
def availability() -> str | None:
    """None when the collision kernel loads here, else why not (one line)."""
    return unavailable(_load_kernels, "the compiled interference kernel's module")


def _load_kernels() -> None:
    from hapticopt.analysis.prrr.collision import _interference_kernels  # noqa: F401


def _kernels():
    """The kernel module (:mod:`._interference_kernels`); RuntimeError with :func:`availability`'s reason
    where numba cannot load it."""
    reason = availability()
    if reason is not None:
        raise RuntimeError(reason)
    from hapticopt.analysis.prrr.collision import _interference_kernels as K
    return K


def joint_trig(theta: np.ndarray) -> tuple[np.ndarray, ...]:
    """cos and sin of θ₁ and of θ₁ + θ₂ (c1, s1, c12, s12: (n, 3 legs) each, numpy's) from the joint angles
    ``theta`` (n, 3 legs, ≥ 2) [rad] of one IK branch: what the kernel reads of the angles."""
    th1 = theta[..., 0]
    th12 = th1 + theta[..., 1]
    return np.cos(th1), np.sin(th1), np.cos(th12), np.sin(th12)


def _run_kernel(owner, points, sliders, trig, reachable, tables: JointTables, col: np.ndarray, depth) -> None:
    """:func:`._interference_kernels.check_joint_poses` into ``depth`` (zeros; column map ``col``)."""
    f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
    _kernels().check_joint_poses(*tables.head, f64(sliders), *(f64(x) for x in trig), f64(points),
                                 np.ascontiguousarray(owner, dtype=np.int64),
                                 np.ascontiguousarray(reachable, dtype=np.bool_), *tables.design, *tables.tail, col,
                                 depth)


def check_joints(batch: PrimitiveBatch, owner: np.ndarray, points: np.ndarray, sliders: np.ndarray,
                 theta: np.ndarray, reachable: np.ndarray, geometry: LegGeometry, *,
                 tables: JointTables | None = None) -> FastResult:
    """Interference at n poses of the designs of ``batch`` given by their joint values: pose k of design
    ``owner[k]`` (index into ``batch`` and ``geometry``), sliders (n, 3) [m], joint angles theta (n, 3 legs,
    ≥ 2) [rad] of one IK branch, platform at ``points`` (n, 3) [m], ``reachable`` (n,) bool (unreachable
    poses are not checked: depth 0). The kernel builds the part frames of
    :func:`hapticopt.design.prrr.cad.part_frames_arrays` from these, term by term. ``tables``:
    :func:`joint_tables` of ``batch`` and ``geometry`` (computed when omitted)."""
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    tables = joint_tables(batch, geometry) if tables is None else tables
    depth = np.zeros((len(pts), len(batch.part_pairs)))
    reachable = np.asarray(reachable, dtype=bool)
    _run_kernel(owner, pts, sliders, joint_trig(np.asarray(theta, dtype=float)), reachable, tables,
                np.arange(len(batch.part_pairs), dtype=np.int64), depth)
    return FastResult(points=pts, reachable=reachable, collides=np.any(depth > DEPTH_TOL, axis=1),
                      depth=depth, part_pairs=batch.part_pairs)


def deepest_joints(owner: np.ndarray, points: np.ndarray, sliders: np.ndarray, theta: np.ndarray,
                   reachable: np.ndarray, tables: JointTables) -> tuple[np.ndarray, np.ndarray]:
    """(collides (n,), deepest part-pair overlap (n,) [m]): :func:`check_joints`' ``collides`` and
    ``depth.max(axis=1)`` bit for bit, the kernel keeping only each pose's deepest overlap (no
    (n, part pairs) array)."""
    return deepest_trig(owner, points, sliders, joint_trig(theta), reachable, tables)


def deepest_trig(owner: np.ndarray, points: np.ndarray, sliders: np.ndarray, trig: tuple[np.ndarray, ...],
                 reachable: np.ndarray, tables: JointTables) -> tuple[np.ndarray, np.ndarray]:
    """:func:`deepest_joints` from the joint angles' :func:`joint_trig` (c1, s1, c12, s12) instead of the
    angles (the batched draft evaluator's check, one call per thread's share)."""
    depth = np.zeros((len(points), 1))
    _run_kernel(owner, points, sliders, trig, reachable, tables,
                np.zeros(len(tables.tail[2]), dtype=np.int64), depth)
    deepest = depth[:, 0]
    return deepest > DEPTH_TOL, deepest


#: the legs' in-plane axes u and t (3 legs, 3), writable copies (numba compiles one signature)
_IN_PLANE = tuple(np.array(x) for x in leg_frames(0.0, xp=np)[:2])
#: the IK parameters :func:`pose_joints` reads per design, in its order
IK_FIELDS = ("beta", "d1", "d2", "d3", "d4", "r4", "b5", "stroke")


def pose_joints(idx: np.ndarray, owner: np.ndarray, points: np.ndarray, geo: dict[str, np.ndarray], branch: int,
                out: tuple[np.ndarray, ...]) -> None:
    """The joint values of elbow ``branch`` at the poses ``idx`` (rows of ``points`` (n, 3) [m], design
    ``owner[q]`` of the per-design arrays ``geo[f]`` for f in :data:`IK_FIELDS`) written into ``out`` =
    (sliders (n, 3), c1, s1, c12, s12 (n, 3), reachable (n,)): ``kinematics.inverse_kinematics``' sliders
    and reachability and :func:`joint_trig` of its angles, bit for bit, compiled per pose
    (:func:`._interference_kernels.pose_joints`, nogil)."""
    f64 = functools.partial(np.ascontiguousarray, dtype=np.float64)
    _kernels().pose_joints(np.ascontiguousarray(idx, dtype=np.int64), np.ascontiguousarray(owner, dtype=np.int64),
                           f64(points), *(f64(geo[f]) for f in IK_FIELDS), *_IN_PLANE, int(branch), *out)


def check_points(model: FastModel, points, *, branch: int = cad_prrr.DEFAULT_BRANCH) -> FastResult:
    """Interference of the tested part pairs at end-effector points (n, 3) [m] in IK branch ``branch``."""
    return point_checker(model, branch=branch)(points)


def point_checker(model: FastModel, *, branch: int = cad_prrr.DEFAULT_BRANCH):
    """:func:`check_points` of ``model`` as a function of the points, for a caller that checks one design's
    points in several calls (the free workspace's bisection passes, then the interference samples): the
    design's one-row :func:`stack_models`, IK parameters, leg geometry and :func:`joint_tables` are made
    once, at the first call."""
    g = model.design.geometry
    prm = params_np(model.design)
    geometry = LegGeometry(*(np.array([float(getattr(g, f))]) for f in LegGeometry._fields))
    batch = stack_models([model])

    @functools.cache
    def tables() -> JointTables:
        return joint_tables(batch, geometry)

    def check(points) -> FastResult:
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        ik = inverse_kinematics(prm, pts, xp=np)
        return check_joints(batch, np.zeros(len(pts), dtype=int), pts, ik.sliders, ik.theta[:, branch],
                            ik.reachable, geometry, tables=tables())

    return check


def overlap_share(res: FastResult, *, scale: float = OVERLAP_SCALE) -> np.ndarray:
    """Per-pose collision share (n,) in [0, 1]: clip(d / scale, 0, 1) of the deepest part-pair
    overlap d [m] at the pose (0 where separated or unreachable: ``depth`` is 0 there)."""
    d = res.depth.max(axis=1) if res.depth.shape[1] else np.zeros(len(res.points))
    return np.clip(d / scale, 0.0, 1.0)


def interference_fractions(design: PrrrDesign, *, n_phi: int, n_r: int, n_z: int,
                           scale: float = OVERLAP_SCALE, wp: Any = None, check=None) -> tuple[float, float]:
    """(removed fraction, overlap fraction) of the sampled workspace volume, from one check of
    the poses (polar-cell weights w_i of :func:`hapticopt.analysis.prrr.geometry.workspace.workspace_sample_weights`):

    * removed = Σ w_i [pose i collides] / Σ w_i — piecewise constant in the design;
    * overlap = Σ w_i clip(d_i / scale, 0, 1) / Σ w_i, d_i the deepest pair overlap at pose i —
      its continuous companion (equal to the removed fraction where every colliding pose is at
      least ``scale`` deep; docs/workspace_interference.md).

    Both 0 for an empty sample (the primitive tables are not needed then). ``wp``: the design's
    default workspace parameters, ``check``: its :func:`point_checker` in :data:`ELBOW_BRANCH`, where
    the caller has them (made here when omitted)."""

    pts, w = workspace_sample_weights(design, n_phi=n_phi, n_r=n_r, n_z=n_z, wp=wp)
    if len(pts) == 0 or not w.sum() > 0:
        return 0.0, 0.0
    res = (point_checker(prepare(design), branch=ELBOW_BRANCH) if check is None else check)(pts)
    return fractions_of(w, res.collides, overlap_share(res, scale=scale))


def fractions_of(w: np.ndarray, collides: np.ndarray, share: np.ndarray) -> tuple[float, float]:
    """(removed, overlap) fractions from the pose weights ``w``, collision flags and overlap shares
    (see :func:`interference_fractions`)."""
    total = w.sum()
    return float(w[collides].sum() / total), float(w @ share / total)

"""Parts as tables of primitives: the one parametric source of the CAD, the analytic mass
properties, the interference meshes and the MJCF geoms.

A part is a rigid solid described in its own frame (SI, metres) as a set of primitives:

* ``SOLID`` primitives are united (box, cylinder, sphere),
* ``HOLE`` primitives are subtracted from that union (pin bores, rail slots),
* ``OVERLAP`` primitives exist only for the analytic mass model: they are the regions counted
  twice by the solids (a boss disc overlapping the end of its link bar: a "cap segment"; a
  plate let into a block face at a slant: a "wedge") and are subtracted once. The CAD ignores them.

The CAD (:mod:`hapticopt.design.prrr.cad`, :mod:`hapticopt.design.master.cad`) turns SOLID/HOLE into OpenCASCADE
solids, :func:`manifold_of` into manifold3d meshes, and :func:`volume_properties` sums closed
forms (cap segments by a fixed Gauss–Legendre rule) without building any solid.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum, StrEnum

import math

import numpy as np

from hapticopt.design import cad_import, cad_units
from hapticopt.design.errors import InvalidDesign
import copy

_EX = np.array([1.0, 0.0, 0.0])
_EY = np.array([0.0, 1.0, 0.0])


class Kind(IntEnum):
    BOX = 0  # dims (lx, ly, lz), centred on the origin
    CYLINDER = 1  # dims (radius, height, 0), axis = local z, centred
    SPHERE = 2  # dims (radius, 0, 0)
    CAPSEG = 3  # dims (R, h, thickness): {x ≥ 0, |y| ≤ h, x² + y² ≤ R²} × |z| ≤ thickness/2
    WEDGE = 4  # dims (a, b, thickness): right triangle {x ≥ 0, y ≥ 0, x/a + y/b ≤ 1} × |z| ≤ thickness/2 (OVERLAP only)


class Role(StrEnum):
    SOLID = "solid"
    HOLE = "hole"
    OVERLAP = "overlap"


@dataclass(frozen=True, kw_only=True, eq=False, slots=True)
class Primitive:
    """One primitive in a part frame [m]: ``R`` (3, 3) columns are its local axes, ``o`` (3,) its
    centre (cap segments: the disc centre), ``dims`` (3,) as listed in :class:`Kind`."""

    kind: Kind
    role: Role
    o: np.ndarray
    R: np.ndarray
    dims: tuple[float, float, float]


@dataclass(frozen=True, kw_only=True)
class PartSpec:
    """A named rigid part: primitives in its frame, material density, owning body."""

    name: str
    body: str  # rigid body that carries the part (MJCF body name)
    density: float  # [kg/m³]
    primitives: tuple[Primitive, ...]
    material: str = ""  # name in design/materials.toml ('' for a lumped catalogue part: motor, housing)


# ---------------------------------------------------------------------------- frames
def frame(x_dir, z_dir) -> np.ndarray:
    """Rotation whose columns are x, y = z × x, z (x made orthogonal to z)."""
    z = np.asarray(z_dir, dtype=float)
    z = z / math.sqrt(z @ z)
    x = np.asarray(x_dir, dtype=float)
    x = x - (x @ z) * z
    x = x / math.sqrt(x @ x)
    y = np.array([z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]])
    out = np.empty((3, 3))
    out[:, 0], out[:, 1], out[:, 2] = x, y, z
    return out


def transform(R: np.ndarray, o) -> np.ndarray:
    """4×4 homogeneous transform from a rotation and an origin."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = o
    return T


def _prim(kind: Kind, role: Role, origin, R, dims) -> Primitive:
    return Primitive(kind=kind, role=role, o=np.asarray(origin, dtype=float), R=R, dims=dims)


def box(origin, R, lx: float, ly: float, lz: float, role: Role = Role.SOLID) -> Primitive:
    return _prim(Kind.BOX, role, origin, R, (lx, ly, lz))


def cylinder(origin, axis, radius: float, height: float, role: Role = Role.SOLID, *,
             R: np.ndarray | None = None) -> Primitive:
    """Cylinder along ``axis`` (or along the z column of a given rotation ``R``)."""
    if R is None:
        axis = np.asarray(axis, dtype=float)
        helper = _EX if abs(axis[0]) < 0.9 * math.sqrt(axis @ axis) else _EY
        R = frame(helper, axis)
    return _prim(Kind.CYLINDER, role, origin, R, (radius, height, 0.0))


def sphere(origin, radius: float) -> Primitive:
    return _prim(Kind.SPHERE, Role.SOLID, origin, np.eye(3), (radius, 0.0, 0.0))


def capseg(origin, R, radius: float, half_strip: float, thickness: float) -> Primitive:
    """Overlap of a boss disc (radius, at origin) with a bar along local +x of half-width half_strip."""
    return _prim(Kind.CAPSEG, Role.OVERLAP, origin, R, (radius, min(half_strip, radius), thickness))


def wedge(origin, R, leg_x: float, leg_y: float, thickness: float) -> Primitive:
    """Overlap of two solids that is a right triangular prism: right angle on local z through
    ``origin``, legs along local +x and +y, ``thickness`` along z (centred). Mass bookkeeping only
    (OVERLAP): the CAD, the meshes and the MJCF see the solids it is the overlap of."""
    return _prim(Kind.WEDGE, Role.OVERLAP, origin, R, (leg_x, leg_y, thickness))


def bar_with_bosses(R: np.ndarray, o, x0: float, x1: float, *, width: float, thickness: float, z: float,
                    bosses: tuple[float, ...], boss_radius: float, bore_radius: float) -> list[Primitive]:
    """A flat bar along local x from ``x0`` to ``x1`` (frame ``R``, origin ``o``), in the layer centred
    at local ``z``, with round bosses (and bores along local z) at the x positions ``bosses``.

    Bosses must lie on the bar and be at least a boss diameter apart (checked by the callers'
    design rules) so their overlaps with the bar are disjoint cap segments.
    """
    o = np.asarray(o, dtype=float)
    ex, ez = R[:, 0], R[:, 2]
    out = [box(o + ((x0 + x1) / 2) * ex + z * ez, R, x1 - x0, width, thickness)]
    flip = R @ np.diag([-1.0, -1.0, 1.0])  # local x reversed (z kept)
    for xb in bosses:
        c = o + xb * ex + z * ez
        out.append(cylinder(c, None, boss_radius, thickness, R=R))
        if xb < x1 - 1e-12:
            out.append(capseg(c, R, boss_radius, width / 2, thickness))
        if xb > x0 + 1e-12:
            out.append(capseg(c, flip, boss_radius, width / 2, thickness))
        out.append(cylinder(c, None, bore_radius, thickness, role=Role.HOLE, R=R))
    return out


# ---------------------------------------------------------------------------- mass properties
@dataclass(frozen=True, kw_only=True)
class VolumeProps:
    """Volume [m³], centroid (3,) [m] and second-moment tensor about the centroid (3, 3) [m⁵]
    (multiply by density for the inertia tensor in kg·m²), all in the part frame."""

    volume: float
    centroid: np.ndarray
    inertia: np.ndarray


_GL_X, _GL_W = np.polynomial.legendre.leggauss(24)


def _local_props(kind: np.ndarray, dims: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per primitive (n,): volume, local centroid (n, 3), second moments about the local origin in
    inertia-tensor form (n, 3, 3) (diagonal except the wedge's xy product)."""
    a, b, c = dims[:, 0], dims[:, 1], dims[:, 2]
    n = len(kind)
    v = volumes(kind, dims)
    cen = np.zeros((n, 3))
    I = np.zeros((n, 3))
    Ixy = np.zeros(n)
    m = kind == Kind.BOX
    if m.any():
        I[m] = np.stack([b[m] ** 2 + c[m] ** 2, a[m] ** 2 + c[m] ** 2, a[m] ** 2 + b[m] ** 2], axis=1) * (v[m] / 12.0)[:, None]
    m = kind == Kind.CYLINDER
    if m.any():
        r, h, vc = a[m], b[m], v[m]
        ixx = vc * (3 * r * r + h * h) / 12.0
        I[m] = np.stack([ixx, ixx, vc * r * r / 2.0], axis=1)
    m = kind == Kind.SPHERE
    if m.any():
        I[m] = (0.4 * v[m] * a[m] ** 2)[:, None] * np.ones(3)
    m = kind == Kind.CAPSEG
    if m.any():
        R_, h, t = a[m], b[m], c[m]
        # y = R sin φ, φ ∈ [−φ0, φ0]: X = R cos φ, dy = R cos φ dφ (smooth, exact up to h = R)
        phi0 = np.arcsin(np.clip(h / R_, 0.0, 1.0))
        phi = _GL_X[None, :] * phi0[:, None]
        X = R_[:, None] * np.cos(phi)
        y = R_[:, None] * np.sin(phi)
        w = _GL_W[None, :] * phi0[:, None] * X
        A = np.sum(w * X, axis=1)
        Sx = np.sum(w * X * X, axis=1) / 2.0
        xx = np.sum(w * X**3, axis=1) / 3.0 * t
        yy = np.sum(w * y * y * X, axis=1) * t
        zz = A * t**3 / 12.0
        cen[m, 0] = Sx / A
        I[m] = np.stack([yy + zz, xx + zz, xx + yy], axis=1)
    m = kind == Kind.WEDGE
    if m.any():
        # right triangle with legs p (x), q (y): ∫x² dA = p³q/12, ∫y² dA = pq³/12, ∫xy dA = p²q²/24
        p, q, t = a[m], b[m], c[m]
        A = p * q / 2.0
        xx, yy, zz = p**3 * q / 12.0 * t, p * q**3 / 12.0 * t, A * t**3 / 12.0
        cen[m, 0], cen[m, 1] = p / 3.0, q / 3.0
        I[m] = np.stack([yy + zz, xx + zz, xx + yy], axis=1)
        Ixy[m] = -(p * q) ** 2 / 24.0 * t
    out = I[:, :, None] * np.eye(3)[None]
    out[:, 0, 1] = out[:, 1, 0] = Ixy
    return v, cen, out


def volumes(kind: np.ndarray, dims: np.ndarray) -> np.ndarray:
    """Volume [m³] of each primitive (n,) of the given kinds and dims (:class:`Kind`)."""
    a, b, c = dims[:, 0], dims[:, 1], dims[:, 2]
    v = np.zeros(len(kind))
    m = kind == Kind.BOX
    v[m] = a[m] * b[m] * c[m]
    m = kind == Kind.CYLINDER
    v[m] = np.pi * a[m] * a[m] * b[m]
    m = kind == Kind.SPHERE
    v[m] = 4.0 / 3.0 * np.pi * a[m] ** 3
    m = kind == Kind.CAPSEG
    if m.any():
        R_, h, t = a[m], b[m], c[m]
        phi0 = np.arcsin(np.clip(h / R_, 0.0, 1.0))
        X = R_[:, None] * np.cos(_GL_X[None, :] * phi0[:, None])
        w = _GL_W[None, :] * phi0[:, None] * X
        v[m] = np.sum(w * X, axis=1) * t
    m = kind == Kind.WEDGE
    p, q, t = a[m], b[m], c[m]
    v[m] = p * q / 2.0 * t
    return v


def volume_properties(prims) -> VolumeProps:
    """Closed-form volume properties of a part (SOLID − OVERLAP − HOLE)."""
    return volume_properties_many([prims])[0]


def volume_properties_many(groups) -> list[VolumeProps]:
    """:func:`volume_properties` of several parts in one vectorised pass."""
    flat = [p for g in groups for p in g]
    nf, idx = len(flat), np.repeat(np.arange(len(groups)), [len(g) for g in groups])
    kind = np.array([p.kind for p in flat])
    sign = np.where(np.array([p.role == Role.SOLID for p in flat]), 1.0, -1.0)
    dims = np.array([p.dims for p in flat], dtype=float)
    R = np.array([p.R for p in flat])
    o = np.array([p.o for p in flat])
    v, c_loc, I_loc = _local_props(kind, dims)
    co = np.einsum("nij,nj->ni", R, c_loc)  # centroid offset from the primitive origin
    c = o + co
    # ∫(|r|²I − r rᵀ) about the part origin, r = o + s: I_o + v(|o|² + 2 o·co) I − v(o oᵀ + o coᵀ + co oᵀ)
    J = R @ I_loc @ R.transpose(0, 2, 1)
    scal = v * (np.einsum("ni,ni->n", o, o) + 2.0 * np.einsum("ni,ni->n", o, co))
    J[:, 0, 0] += scal
    J[:, 1, 1] += scal
    J[:, 2, 2] += scal
    J -= v[:, None, None] * (o[:, :, None] * (o + 2.0 * co)[:, None, :])
    n = len(groups)
    onehot = np.zeros((n, nf))
    onehot[idx, np.arange(nf)] = sign
    V = onehot @ v
    first = onehot @ (v[:, None] * c)
    Jt = (onehot @ J.reshape(nf, 9)).reshape(n, 3, 3)
    cen = first / V[:, None]
    # back to the centroid: J_c = J − V(|c|² I − c cᵀ), symmetrised
    Jc = Jt + V[:, None, None] * cen[:, :, None] * cen[:, None, :]
    cc = V * np.einsum("ni,ni->n", cen, cen)
    Jc[:, 0, 0] -= cc
    Jc[:, 1, 1] -= cc
    Jc[:, 2, 2] -= cc
    Jc = 0.5 * (Jc + Jc.transpose(0, 2, 1))
    return [VolumeProps(volume=float(V[k]), centroid=cen[k], inertia=Jc[k]) for k in range(n)]


# ---------------------------------------------------------------------------- manifold3d meshes
def manifold_of(spec: PartSpec, *, segments: int = 32):
    """The part as a manifold3d ``Manifold`` in its own frame, in mm."""
    import manifold3d as m3d

    def one(p: Primitive):
        d = cad_units.to_mm(np.asarray(p.dims))
        if p.kind == Kind.BOX:
            base = m3d.Manifold.cube(tuple(d), center=True)
        elif p.kind == Kind.CYLINDER:
            h = d[1] + (2.0 if p.role == Role.HOLE else 0.0)
            base = m3d.Manifold.cylinder(h, d[0], d[0], segments, True)
        else:
            base = m3d.Manifold.sphere(d[0], segments)
        M = np.zeros((3, 4))
        M[:, :3] = p.R
        M[:, 3] = cad_units.to_mm(p.o)
        return base.transform(M)

    solids = [one(p) for p in spec.primitives if p.role == Role.SOLID]
    holes = [one(p) for p in spec.primitives if p.role == Role.HOLE]
    body = m3d.Manifold.batch_boolean(solids, m3d.OpType.Add)
    if holes:
        body = body - m3d.Manifold.batch_boolean(holes, m3d.OpType.Add)
    return body


# ---------------------------------------------------------------------------- build123d solids
def location(T_m: np.ndarray):
    """build123d ``Location`` of a 4×4 transform given in m."""
    cad_import.build123d()  # imported without scikit-learn (0.55 s)
    from build123d import Location, Plane

    T = cad_units.transform_to_mm(T_m)
    return Location(Plane(origin=tuple(T[:3, 3]), x_dir=tuple(T[:3, 0]), z_dir=tuple(T[:3, 2])))


def build_solid(spec: PartSpec):
    """The OpenCASCADE solid of one part in its own frame (mm): SOLIDs fused, HOLEs cut.
    Raises :class:`InvalidDesign` if the result is not one valid solid."""
    cad_import.build123d()  # imported without scikit-learn (0.55 s)
    from build123d import Box, Cylinder, Solid, Sphere


    solids, holes = [], []
    for p in spec.primitives:
        if p.role == Role.OVERLAP:
            continue
        d = cad_units.to_mm(np.asarray(p.dims))
        if p.kind == Kind.BOX:
            s = Box(*d)
        elif p.kind == Kind.CYLINDER:
            s = Cylinder(d[0], d[1] + (2.0 if p.role == Role.HOLE else 0.0))
        else:
            s = Sphere(d[0])
        s = s.moved(location(transform(p.R, p.o)))
        (solids if p.role == Role.SOLID else holes).append(s)
    part = solids[0].fuse(*solids[1:]) if len(solids) > 1 else solids[0]
    if holes:
        part = part.cut(*holes)
    part = part.clean()
    found = part.solids()
    if len(found) != 1 or not part.is_valid:
        raise InvalidDesign(f"part {spec.name}: the CAD gives {len(found)} solids (valid={part.is_valid}); "
                            f"check the structure.* cross-sections and the geometry of this part")
    out = Solid(found[0].wrapped)
    out.label = spec.name
    return out


def build_all(specs: dict[str, PartSpec]) -> dict[str, object]:
    """Every part's solid (own frame, mm). Parts sharing a primitive table are built once and
    copied: STEP keeps one name per shared shape, so each part gets its own shape."""

    cache: dict[int, object] = {}
    out = {}
    for name, spec in specs.items():
        key = id(spec.primitives)
        if key not in cache:
            cache[key] = build_solid(spec)
        solid = copy.deepcopy(cache[key])
        solid.label = name
        out[name] = solid
    return out


def posed(solids: dict[str, object], frames: dict[str, np.ndarray]) -> dict[str, object]:
    """Parts moved to their posed frames (mm), labels kept."""
    out = {}
    for name, s in solids.items():
        m = s.moved(location(frames[name]))
        m.label = name
        out[name] = m
    return out


@dataclass(frozen=True, kw_only=True)
class JointAxis:
    """A joint of a posed mechanism: a point on its axis and the unit direction [m]."""

    name: str
    parent: str
    child: str
    point: np.ndarray
    direction: np.ndarray
    kind: str = "hinge"  # "slide" or "hinge"
    reference: float = 0.0  # joint coordinate at the pose [rad or m]

"""Draft 3-PRRR link interference: a coarse, conservative model built for batching (jax).

A candidate draft-fidelity checker for :mod:`hapticopt.analysis.prrr.free_workspace` and
:mod:`hapticopt.analysis.prrr.interference` (standard: :mod:`~hapticopt.analysis.prrr.interference_fast`,
the separating-axis model on every CAD primitive; fine: manifold3d meshes). **Not wired into any
evaluator yet**: dense over every pair it costs about twice the fast model per pose on a CPU
(``benchmarks/bench_interference_draft.py``), so it pays only with a per-design pair pruning
(docs/workspace_interference.md, "Draft model"). Every draft shape *encloses* the CAD part it
stands for, so the model never calls a colliding pose free (tested against the fast model and
manifold3d); it may call a free pose colliding.

Shapes (closed forms of the CAD layout, :func:`hapticopt.design.prrr.cad.layout`, per design):

* **capsules** (segment + radius) for the tilted moving parts: each link (the segment between
  its boss axes, radius √(max(W/2, R)² + (T/2)²) encloses the bar of width W, thickness T and the
  bosses of radius R), link2's R3 riser, the carriage's R1 bracket (clevis centre → where the bar
  meets the block), the platform's three arms (lug → stem axis), its stem and its handle ball;
* **vertical prisms** (rectangle or circle in xy, a z interval) for the parts that only slide
  along z or never move: rails, ball screws, motors (fixed) and the carriage blocks and SEA
  housings (moving with their slider; their holes ignored, so they are filled);
* **the base plate** as the half-space below its top face.

Pairs: the reference's rule (parts on different rigid bodies that no joint joins,
:func:`hapticopt.design.prrr.cad.neighbours`). Tests, all closed form, dense over
(designs × poses × pairs), one jitted vmap:

* capsule–capsule: segment–segment distance (Ericson, *Real-Time Collision Detection* §5.1.9);
* capsule–prism: the distance from a point to a vertical prism is convex along the segment;
  :data:`GOLDEN` golden-section steps bracket its minimum, and the Lipschitz bound (the bracket
  width times the segment length) makes the result a lower bound on the distance (conservative);
* prism–prism: 2-D separating axes (rectangle–rectangle exact), circle clamps, z-interval overlap;
* anything–base: lowest point below the plate top.

Depth of a pair: radius sum − distance (capsules), the smaller of the xy and z overlaps (prisms);
a pose collides where its deepest pair exceeds :data:`interference_fast.DEPTH_TOL`, as in the
fast model, and the overlap share uses the same ramp (:data:`interference_fast.OVERLAP_SCALE`).

Entry points: :func:`geometry_of` (numpy, one design), :func:`check` (poses of many designs),
:func:`free_radius_batch` (the whole free-radius search of :mod:`free_workspace`, one jitted call),
:func:`fractions_batch` (the interference evaluator's removed and overlap fractions).
"""

from __future__ import annotations

import collections
import functools
import math
from typing import NamedTuple

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design.prrr import cad
from hapticopt.design.prrr.kinematics import PrrrParams, inverse_kinematics
from hapticopt.design.prrr.params import GAMMAS, PrrrDesign

#: a pose collides when its deepest pair overlap exceeds this [m] (as interference_fast.DEPTH_TOL)
DEPTH_TOL = 1e-4
#: golden-section steps of the capsule–prism distance (bracket 0.618^24 ≈ 1e-5 of the segment)
GOLDEN = 24
#: elbow branch of the CAD (hapticopt.analysis.prrr.workspace.ELBOW_BRANCH)
BRANCH = cad.DEFAULT_BRANCH
#: traces of the jitted functions by name (tests count them: a new batch size must not retrace)
TRACES: collections.Counter = collections.Counter()


class DraftGeom(NamedTuple):
    """Draft-model dimensions of one design (scalars) or many (``(n,)`` each) [m, rad]."""

    beta: np.ndarray
    d1: np.ndarray
    d2: np.ndarray
    d3: np.ndarray
    d4: np.ndarray
    r4: np.ndarray
    b5: np.ndarray
    stroke: np.ndarray
    theta_1p: np.ndarray
    r_link: np.ndarray  # capsule radius of link1, link2 and the bracket
    r_boss: np.ndarray  # riser radius
    s_link2: np.ndarray  # link2 layer centre along w
    riser_lo: np.ndarray  # riser segment along w (link2 frame); equal ends: no riser
    riser_hi: np.ndarray
    ac_x: np.ndarray  # bracket: clevis centre (carriage frame of leg 1)
    ac_y: np.ndarray
    ac_z: np.ndarray
    be_x: np.ndarray  # bracket end on the block face
    be_y: np.ndarray
    be_z: np.ndarray
    x_in: np.ndarray  # carriage block / housing x (carriage frame)
    x_out: np.ndarray
    block_y: np.ndarray  # block half width
    z0: np.ndarray  # block and housing z (carriage frame, at D = 0)
    z1: np.ndarray
    housing_y0: np.ndarray
    housing_y1: np.ndarray
    r_p: np.ndarray
    rail_half: np.ndarray
    z_base_top: np.ndarray
    z_rail_top: np.ndarray
    screw_x: np.ndarray
    screw_y: np.ndarray
    screw_r: np.ndarray
    motor_x: np.ndarray
    motor_y: np.ndarray
    motor_r: np.ndarray
    motor_top: np.ndarray
    lug_w: np.ndarray  # lug centre offset along w (s_lug − r4)
    arm_length: np.ndarray
    r_arm: np.ndarray
    stem_bottom: np.ndarray
    ball_z: np.ndarray
    r_stem: np.ndarray
    r_ball: np.ndarray


def geometry_of(design: PrrrDesign, *, layout: cad.PrrrLayout | None = None) -> DraftGeom:
    """The draft shapes' dimensions of ``design`` from its CAD layout (raises
    :class:`~hapticopt.design.errors.InvalidDesign` where the CAD cannot lay the parts out).

    Derived only through :func:`hapticopt.design.prrr.cad.layout` and the design's fields, so a
    change of the CAD's layout rules carries over (the bracket reads ``clevis`` and ``bracket_end``)."""
    L = cad.layout(design) if layout is None else layout
    g, s, e, m = design.geometry, design.structure, design.end_effector, design.sea_module
    top = L.s_link2 + L.T / 2
    riser = L.s_lug - L.T / 2 - L.g - top
    has_riser = riser > cad.MIN_FEATURE  # as cad._link2
    vals = dict(
        beta=g.beta, d1=g.d1, d2=g.d2, d3=g.d3, d4=g.d4, r4=g.r4, b5=g.b5, stroke=g.stroke, theta_1p=g.theta_1p,
        r_link=math.hypot(max(L.W / 2, L.R_boss), L.T / 2), r_boss=L.R_boss, s_link2=L.s_link2,
        riser_lo=top if has_riser else L.s_link2, riser_hi=top + riser if has_riser else L.s_link2,
        ac_x=L.clevis[0], ac_y=L.clevis[1], ac_z=L.clevis[2],
        be_x=L.bracket_end[0], be_y=L.bracket_end[1], be_z=L.bracket_end[2],
        x_in=L.block_x[0], x_out=L.block_x[1], block_y=L.block_y, z0=L.block_z[0], z1=L.block_z[1],
        housing_y0=L.housing_y[0], housing_y1=L.housing_y[1], r_p=g.r_p, rail_half=s.rail_width / 2,
        z_base_top=L.z_base_top, z_rail_top=L.z_rail_top,
        screw_x=L.screw_xy[0], screw_y=L.screw_xy[1], screw_r=m.screw_diameter / 2,
        motor_x=L.motor_xy[0], motor_y=L.motor_xy[1], motor_r=m.motor_diameter / 2,
        motor_top=L.z_base_top + m.motor_length,
        lug_w=L.s_lug - g.r4, arm_length=L.arm_length,
        r_arm=math.hypot(max(s.stem_diameter / 2, L.R_boss), L.T / 2),
        stem_bottom=L.stem_bottom, ball_z=L.ball_z, r_stem=s.stem_diameter / 2, r_ball=e.handle_diameter / 2)
    return DraftGeom(**{k: np.float64(v) for k, v in vals.items()})


def stack(geoms: list[DraftGeom]) -> DraftGeom:
    """Many designs' dimensions along a leading axis (numpy)."""
    return DraftGeom(*(np.array(col, dtype=np.float64) for col in zip(*geoms)))


# ---------------------------------------------------------------------------- the primitive tables
# capsules: (label, part, body); prisms: (label, part, body, leg index, shape, moving)
_LEGS = (1, 2, 3)
_CAPS = tuple([c for i in _LEGS for c in ((f"bracket_{i}", f"carriage_{i}", f"carriage_{i}"),
                                          (f"link1_{i}", f"link1_{i}", f"link1_{i}"),
                                          (f"link2_{i}", f"link2_{i}", f"link2_{i}"),
                                          (f"riser_{i}", f"link2_{i}", f"link2_{i}"))]
              + [(f"arm_{i}", "platform", "platform") for i in _LEGS]
              + [("stem", "platform", "platform"), ("ball", "platform", "platform")])
_RECT, _CIRC = 0, 1
_PRISMS = tuple([p for k, i in enumerate(_LEGS) for p in (
    (f"rail_{i}", f"rail_{i}", "base", k, _RECT, False),
    (f"screw_{i}", f"screw_{i}", "base", k, _CIRC, False),
    (f"motor_{i}", f"motor_{i}", "base", k, _CIRC, False),
    (f"block_{i}", f"carriage_{i}", f"carriage_{i}", k, _RECT, True),
    (f"housing_{i}", f"housing_{i}", f"carriage_{i}", k, _RECT, True))])


def _tested(part_a: str, body_a: str, part_b: str, body_b: str) -> bool:
    return body_a != body_b and frozenset((part_a, part_b)) not in cad.neighbours()


@functools.cache
def pair_tables() -> dict[str, np.ndarray]:
    """Static pair index arrays: capsule–capsule, capsule–prism, prism–prism (moving prism first),
    and the moving prisms (the capsules and moving prisms are all tested against the base plate)."""
    cc = [(i, j) for i in range(len(_CAPS)) for j in range(i + 1, len(_CAPS))
          if _tested(_CAPS[i][1], _CAPS[i][2], _CAPS[j][1], _CAPS[j][2])]
    cp = [(i, j) for i in range(len(_CAPS)) for j in range(len(_PRISMS))
          if _tested(_CAPS[i][1], _CAPS[i][2], _PRISMS[j][1], _PRISMS[j][2])]
    pp = [(i, j) for i in range(len(_PRISMS)) for j in range(len(_PRISMS))
          if _PRISMS[i][5] and (not _PRISMS[j][5] or j > i)
          and _tested(_PRISMS[i][1], _PRISMS[i][2], _PRISMS[j][1], _PRISMS[j][2])]
    out = {"cc": np.array(cc, dtype=int).reshape(-1, 2), "cp": np.array(cp, dtype=int).reshape(-1, 2),
           "pp": np.array(pp, dtype=int).reshape(-1, 2),
           "moving": np.array([k for k, p in enumerate(_PRISMS) if p[5]], dtype=int)}
    for v in out.values():
        v.flags.writeable = False
    return out


def _rz(a):
    c, s = jnp.cos(a), jnp.sin(a)
    return jnp.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _shapes(geo: DraftGeom, p: jax.Array):
    """World capsules (a (C, 3), b (C, 3), r (C,)), prisms (angle (Pr,), centre xy (Pr, 2), half (Pr, 2),
    kind (Pr,), z interval (Pr, 2)) and reachability at end-effector point ``p`` (3,) of one design."""
    kin = PrrrParams(geo.beta, geo.d1, geo.d2, geo.d3, geo.d4, geo.r4, geo.b5, geo.stroke)
    ik = inverse_kinematics(kin, p)
    theta = ik.theta[BRANCH]  # (3 legs, 3)
    sb, cb = jnp.sin(geo.beta), jnp.cos(geo.beta)
    ez = jnp.array([0.0, 0.0, 1.0])
    ca, cb_, cr = [], [], []
    arms = []
    pa, pc, ph, pz = [], [], [], []
    for k, gamma in enumerate(GAMMAS):
        c, s = math.cos(gamma), math.sin(gamma)
        u, t = jnp.array([c, s, 0.0]), jnp.array([-s, c, 0.0])
        w = jnp.stack([-cb * c, -cb * s, sb])
        v = jnp.stack([sb * c, sb * s, cb])
        D = ik.sliders[k]
        th1, th2 = theta[k, 0], theta[k, 1]
        e1 = jnp.cos(th1) * v + jnp.sin(th1) * t
        e12 = jnp.cos(th1 + th2) * v + jnp.sin(th1 + th2) * t
        A = D * ez + geo.d1 * u + geo.d2 * t
        B = A + geo.d3 * e1
        Q = B + geo.d4 * e12
        ang = gamma + geo.theta_1p
        Rc = _rz(ang)
        ac = Rc @ jnp.stack([geo.ac_x, geo.ac_y, geo.ac_z]) + D * ez
        be = Rc @ jnp.stack([geo.be_x, geo.be_y, geo.be_z]) + D * ez
        ca += [ac, A, B + geo.s_link2 * w, Q + geo.riser_lo * w]
        cb_ += [be, B, Q + geo.s_link2 * w, Q + geo.riser_hi * w]
        cr += [geo.r_link, geo.r_link, geo.r_link, geo.r_boss]
        lug = p + geo.b5 * cb * u + geo.lug_w * w
        arms.append((lug, lug - geo.arm_length * v))
        zl, zr, zm = geo.z_base_top, geo.z_rail_top, geo.motor_top
        for cx, cy, hx, hy, za, zb in (
                (geo.r_p, 0.0, geo.rail_half, geo.rail_half, zl, zr),
                (geo.screw_x, geo.screw_y, geo.screw_r, geo.screw_r, zl, zr),
                (geo.motor_x, geo.motor_y, geo.motor_r, geo.motor_r, zl, zm),
                (0.5 * (geo.x_in + geo.x_out), 0.0, 0.5 * (geo.x_out - geo.x_in), geo.block_y,
                 D + geo.z0, D + geo.z1),
                (0.5 * (geo.x_in + geo.x_out), 0.5 * (geo.housing_y0 + geo.housing_y1),
                 0.5 * (geo.x_out - geo.x_in), 0.5 * (geo.housing_y1 - geo.housing_y0), D + geo.z0, D + geo.z1)):
            cxy = Rc[:2, :2] @ jnp.stack([jnp.asarray(cx, float), jnp.asarray(cy, float)])
            pa.append(ang)
            pc.append(cxy)
            ph.append(jnp.stack([jnp.asarray(hx, float), jnp.asarray(hy, float)]))
            pz.append(jnp.stack([za, zb]))
    for lug, end in arms:
        ca.append(lug)
        cb_.append(end)
        cr.append(geo.r_arm)
    ca += [p + jnp.stack([0.0, 0.0, geo.stem_bottom]), p + jnp.stack([0.0, 0.0, geo.ball_z])]
    cb_ += [p + jnp.stack([0.0, 0.0, geo.ball_z]), p + jnp.stack([0.0, 0.0, geo.ball_z])]
    cr += [geo.r_stem, geo.r_ball]
    caps = (jnp.stack(ca), jnp.stack(cb_), jnp.stack(cr))
    kind = jnp.array([pr[4] for pr in _PRISMS])
    prisms = (jnp.stack(pa), jnp.stack(pc), jnp.stack(ph), kind, jnp.stack(pz))
    return caps, prisms, ik.reachable


def _seg_seg(p1, q1, p2, q2):
    """Distance between segments p1q1 and p2q2 (..., 3) (Ericson §5.1.9, degenerate segments handled)."""
    eps = 1e-18
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = jnp.sum(d1 * d1, -1)
    e = jnp.sum(d2 * d2, -1)
    f = jnp.sum(d2 * r, -1)
    c = jnp.sum(d1 * r, -1)
    b = jnp.sum(d1 * d2, -1)
    a_ok, e_ok = a > eps, e > eps
    sa = jnp.where(a_ok, a, 1.0)
    se = jnp.where(e_ok, e, 1.0)
    denom = a * e - b * b
    s = jnp.where(denom > eps * jnp.maximum(a * e, eps), jnp.clip((b * f - c * e) / jnp.where(denom > 0, denom, 1.0),
                                                                  0.0, 1.0), 0.0)
    t = (b * s + f) / se
    s = jnp.where(t < 0.0, jnp.clip(-c / sa, 0.0, 1.0), jnp.where(t > 1.0, jnp.clip((b - c) / sa, 0.0, 1.0), s))
    t = jnp.clip(t, 0.0, 1.0)
    # degenerate cases
    s = jnp.where(a_ok, jnp.where(e_ok, s, jnp.clip(-c / sa, 0.0, 1.0)), 0.0)
    t = jnp.where(e_ok, jnp.where(a_ok, t, jnp.clip(f / se, 0.0, 1.0)), 0.0)
    diff = (p1 + s[..., None] * d1) - (p2 + t[..., None] * d2)
    return jnp.sqrt(jnp.sum(diff * diff, -1))


def _prism_dist(x, cxy, half, kind, z):
    """Distance from points x (..., 3), already in the prism's rotated frame, to the prism."""
    dx, dy = x[..., 0] - cxy[..., 0], x[..., 1] - cxy[..., 1]
    ex = jnp.maximum(jnp.abs(dx) - half[..., 0], 0.0)
    ey = jnp.maximum(jnp.abs(dy) - half[..., 1], 0.0)
    rect2 = ex * ex + ey * ey
    circ = jnp.maximum(jnp.sqrt(dx * dx + dy * dy) - half[..., 0], 0.0)
    h2 = jnp.where(kind == _RECT, rect2, circ * circ)
    ez = jnp.maximum(jnp.maximum(z[..., 0] - x[..., 2], x[..., 2] - z[..., 1]), 0.0)
    return jnp.sqrt(h2 + ez * ez)


_INVPHI = (math.sqrt(5.0) - 1.0) / 2.0


def _seg_prism(a, b, ang, cxy, half, kind, z):
    """Lower bound on the distance from segments ab (K, 3) to vertical prisms (K): golden section on
    the convex distance along the segment, less the Lipschitz bound of the final bracket."""
    c, s = jnp.cos(ang), jnp.sin(ang)

    def local(x):  # world → prism frame (rotation by −ang about z); the centre is rotated back too
        return jnp.stack([c * x[..., 0] + s * x[..., 1], -s * x[..., 0] + c * x[..., 1], x[..., 2]], -1)

    al, bl = local(a), local(b)
    cl = jnp.stack([c * cxy[..., 0] + s * cxy[..., 1], -s * cxy[..., 0] + c * cxy[..., 1]], -1)
    d = bl - al
    length = jnp.sqrt(jnp.sum(d * d, -1))

    def f(t):
        return _prism_dist(al + t[..., None] * d, cl, half, kind, z)

    lo = jnp.zeros_like(length)
    hi = jnp.ones_like(length)
    x1 = hi - _INVPHI * (hi - lo)
    x2 = lo + _INVPHI * (hi - lo)
    f1, f2 = f(x1), f(x2)
    for _ in range(GOLDEN):
        left = f1 <= f2  # the minimum lies in [lo, x2]
        lo, hi = jnp.where(left, lo, x1), jnp.where(left, x2, hi)
        nx1 = jnp.where(left, hi - _INVPHI * (hi - lo), x2)
        nx2 = jnp.where(left, x1, lo + _INVPHI * (hi - lo))
        fn = f(jnp.where(left, nx1, nx2))
        f1, f2 = jnp.where(left, fn, f2), jnp.where(left, f1, fn)
        x1, x2 = nx1, nx2
    mid = 0.5 * (lo + hi)
    return jnp.minimum(f(mid) - 0.5 * (hi - lo) * length, jnp.minimum(f(jnp.zeros_like(lo)), f(jnp.ones_like(lo))))


def _prism_prism(ia, ib, ang, cxy, half, kind, z):
    """Overlap depth [m] of vertical prisms (≤ 0: separated): min of the xy and the z overlaps."""
    aa, ab = ang[ia], ang[ib]
    ca, cb = cxy[ia], cxy[ib]
    ha, hb = half[ia], half[ib]
    ua = jnp.stack([jnp.cos(aa), jnp.sin(aa)], -1)
    va = jnp.stack([-jnp.sin(aa), jnp.cos(aa)], -1)
    ub = jnp.stack([jnp.cos(ab), jnp.sin(ab)], -1)
    vb = jnp.stack([-jnp.sin(ab), jnp.cos(ab)], -1)
    dc = cb - ca
    # rectangle–rectangle: 2-D separating axes (exact)
    ov = []
    for n in (ua, va, ub, vb):
        pa = ha[..., 0] * jnp.abs(jnp.sum(n * ua, -1)) + ha[..., 1] * jnp.abs(jnp.sum(n * va, -1))
        pb = hb[..., 0] * jnp.abs(jnp.sum(n * ub, -1)) + hb[..., 1] * jnp.abs(jnp.sum(n * vb, -1))
        ov.append(pa + pb - jnp.abs(jnp.sum(n * dc, -1)))
    rr = jnp.min(jnp.stack(ov), 0)

    def rect_circ(c_r, u, v, h, c_c, rad):
        rel = c_c - c_r
        loc = jnp.stack([jnp.sum(rel * u, -1), jnp.sum(rel * v, -1)], -1)
        q = jnp.clip(loc, -h, h)
        return rad - jnp.sqrt(jnp.sum((loc - q) ** 2, -1))

    rc = rect_circ(ca, ua, va, ha, cb, hb[..., 0])
    cr = rect_circ(cb, ub, vb, hb, ca, ha[..., 0])
    ccd = ha[..., 0] + hb[..., 0] - jnp.sqrt(jnp.sum(dc * dc, -1))
    ka, kb = kind[ia], kind[ib]
    xy = jnp.where(ka == _RECT, jnp.where(kb == _RECT, rr, rc), jnp.where(kb == _RECT, cr, ccd))
    zo = jnp.minimum(z[ia, 1], z[ib, 1]) - jnp.maximum(z[ia, 0], z[ib, 0])
    return jnp.minimum(xy, zo)


def _pose_depth(geo: DraftGeom, p: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(deepest pair overlap [m] (0 where none or unreachable), reachable) at pose ``p`` (3,)."""
    (ca, cb, cr), (ang, cxy, half, kind, z), reach = _shapes(geo, p)
    tab = pair_tables()
    i, j = tab["cc"][:, 0], tab["cc"][:, 1]
    d_cc = cr[i] + cr[j] - _seg_seg(ca[i], cb[i], ca[j], cb[j])
    i, j = tab["cp"][:, 0], tab["cp"][:, 1]
    d_cp = cr[i] - _seg_prism(ca[i], cb[i], ang[j], cxy[j], half[j], kind[j], z[j])
    d_pp = _prism_prism(tab["pp"][:, 0], tab["pp"][:, 1], ang, cxy, half, kind, z)
    low_caps = jnp.minimum(ca[:, 2], cb[:, 2]) - cr
    d_base = geo.z_base_top - jnp.concatenate([low_caps, z[tab["moving"], 0]])
    deepest = jnp.max(jnp.concatenate([d_cc, d_cp, d_pp, d_base]))
    return jnp.where(reach, jnp.maximum(deepest, 0.0), 0.0), reach


def _check(geo: DraftGeom, pts: jax.Array) -> tuple[jax.Array, jax.Array]:
    TRACES["check"] += 1
    return jax.vmap(jax.vmap(_pose_depth, in_axes=(None, 0)), in_axes=(0, 0))(geo, pts)


@functools.cache
def check_fn():
    """Jitted: (geometry of m designs, points (m, n, 3)) → (depth (m, n) [m], reachable (m, n))."""
    return jax.jit(_check)


def bucket(n: int) -> int:
    """Padded batch size: the next power of two ≥ n (a new size within a bucket does not recompile)."""
    return 1 << max(0, (max(n, 1) - 1).bit_length())


def _pad(geo: DraftGeom, m: int) -> DraftGeom:
    size = bucket(m)
    return DraftGeom(*(np.concatenate([np.atleast_1d(x), np.repeat(np.atleast_1d(x)[-1:], size - m)]) for x in geo))


def check(geo: DraftGeom, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(collides, reachable, depth [m]) of points ``pts`` (m, n, 3) [m] of m designs ``geo`` (stacked);
    one pose of one design: ``check(stack([geometry_of(d)]), p[None, None])``."""
    pts = np.asarray(pts, dtype=float)
    m, n = pts.shape[:2]
    size, nb = bucket(m), bucket(n)
    pp = np.zeros((size, nb, 3))
    pp[:m, :n] = pts
    pp[m:] = pp[:1] if m else 0.0
    depth, reach = check_fn()(_pad(geo, m), pp)
    depth, reach = np.asarray(depth)[:m, :n], np.asarray(reach)[:m, :n]
    return (depth > DEPTH_TOL) & reach, reach, depth

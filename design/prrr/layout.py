"""The 3-PRRR part layout, batch-first: derived dimensions, the R1 bracket, the buildability rules
and the primitive table of every part, for many designs at once.

This is the one formulation of the layout. Every formula runs on columns with a leading design axis
``(m,)`` (vectors ``(m, 3)``); a design given alone runs the same formulas on numpy scalars (the
batch of one without its axis, where numpy's per-call cost is lowest). :mod:`hapticopt.design.prrr.cad`
reads a design alone (:func:`cad.layout`, :func:`cad.carriage_bracket`, :func:`cad.part_specs`: the
CAD solids, the mass properties, the interference models, the MJCF geoms); the batched draft
evaluator reads :func:`part_tables_many` and the frame model :func:`brackets_many`. A rule is a
boolean column, and the first rule a design fails gives its
:class:`~hapticopt.design.errors.InvalidDesign` message (:meth:`Layouts.error`), the same for a
design alone or in a batch; the tables are the same bit for bit (tested).

Parts, frames and axial layering: see :mod:`hapticopt.design.prrr.cad`. Carriage-frame quantities:
x = u' (radial, towards rail i at γ_i + θ_1p), y = t', z = e_z, origin on the z axis at the slider
height D.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from hapticopt.design.errors import InvalidDesign
from hapticopt.design.parts import Kind, Role
from hapticopt.design.prrr.params import GAMMAS, PrrrDesign

#: smallest wall or feature the CAD accepts [m] (below this OCCT produces slivers)
MIN_FEATURE = 0.5e-3
LEGS = (1, 2, 3)
#: the block faces that can carry the R1 bracket (:attr:`Layouts.bracket` ``face`` indexes this)
FACES = ("side", "back", "front")


@dataclass(frozen=True, kw_only=True, eq=False)
class PartTables:
    """The part tables of ``m`` designs of one part layout, stacked (``part_specs`` order) [SI].

    ``part_names``, ``bodies`` (n_parts,); per primitive (P,): ``prim_part`` (index into the parts),
    ``kind`` (:class:`Kind` values), ``role`` (:class:`Role`); per design: ``R`` (m, P, 3, 3) axes
    (columns) in the part frame, ``o`` (m, P, 3) centres [m], ``dims`` (m, P, 3) as listed in
    :class:`Kind`, ``density`` (m, n_parts) [kg/m³], ``height`` (m,) the device height [m];
    ``index`` (m,): each row's position in the designs given to :func:`part_tables_many`.
    """

    index: np.ndarray
    part_names: tuple[str, ...]
    bodies: tuple[str, ...]
    prim_part: np.ndarray
    kind: np.ndarray
    role: tuple[Role, ...]
    R: np.ndarray
    o: np.ndarray
    dims: np.ndarray
    density: np.ndarray
    height: np.ndarray


# ---------------------------------------------------------------------------- vector helpers (m, 3)
_NEXT, _PREV = [1, 2, 0], [2, 0, 1]


def _dot(a, b):
    p = a * b
    return p[..., 0] + p[..., 1] + p[..., 2]


def _cross(a, b):
    return a[..., _NEXT] * b[..., _PREV] - a[..., _PREV] * b[..., _NEXT]


def _where(cond, a, b):
    """``np.where`` per design: ``cond`` (…,) picks ``a`` or ``b`` (…, k…) row by row (one design alone: a
    Python branch, its cheapest form)."""
    if np.ndim(cond) == 0:
        return a if cond else b
    return np.where(cond.reshape(cond.shape + (1,) * (max(np.ndim(a), np.ndim(b)) - cond.ndim)), a, b)


def _cols(x, y, z):
    """Matrices (…, 3, 3) of the column vectors (…, 3) x, y, z."""
    out = np.empty(x.shape + (3,))
    out[..., 0], out[..., 1], out[..., 2] = x, y, z
    return out


def _vec(x, y, z):
    """Rows (m, 3) of the columns (or constants) x, y, z."""
    out = np.empty(max(np.shape(x), np.shape(y), np.shape(z), key=len) + (3,))
    out[..., 0], out[..., 1], out[..., 2] = x, y, z
    return out


def _mm(x) -> str:
    return f"{float(x) * 1e3:g}"


def leg_vectors(beta, gamma: float):
    """(u, t, v, w) of the leg at ``gamma`` per row of ``beta`` (m, 3 each): seed 002's leg
    construction (see :mod:`hapticopt.design.prrr.kinematics`)."""
    c, s = math.cos(gamma), math.sin(gamma)
    cb, sb = np.cos(beta), np.sin(beta)
    zero = np.zeros_like(beta)
    return (_vec(c + zero, s + zero, zero), _vec(-s + zero, c + zero, zero), _vec(sb * c, sb * s, cb),
            _vec(-cb * c, -cb * s, sb))


class _Rules:
    """The rules of m designs in the order they are checked: the first one a row fails names it."""

    def __init__(self) -> None:
        self.oks: list[np.ndarray] = []
        self.messages: list = []

    def need(self, ok, message) -> None:
        """The rule ``ok`` (m,) bool; ``message(k)``: the :class:`InvalidDesign` text for row ``k``."""
        self.oks.append(ok)
        self.messages.append(message)

    def first(self) -> np.ndarray:
        """Per row, the index of the first rule it fails, −1 where it passes every one."""
        oks = np.stack(self.oks)
        return np.where(oks.all(axis=0), -1, np.argmin(oks, axis=0))


#: the design values the layout reads: column name → (section, field)
_FIELDS = {**{k: ("geometry", k) for k in ("beta", "r_p", "d1", "d2", "d3", "d4", "r4", "b5", "stroke", "theta_1p", "c_e")},
           **{k: ("structure", f) for k, f in dict(
               T="link_thickness", W="link_width", g="clearance", boss="boss_diameter", bore="bore_diameter",
               wall="carriage_wall", tb="base_thickness", rw="rail_width", ch="carriage_height", stem="stem_diameter",
               rho="density", base_clearance="base_clearance", base_radius="base_radius",
               sea_envelope="sea_envelope").items()}, "handle": ("end_effector", "handle_diameter"),
           **{k: ("sea_module", f) for k, f in dict(
               screw_d="screw_diameter", motor_d="motor_diameter", motor_length="motor_length",
               motor_offset="motor_radial_offset", housing_mass="housing_mass", screw_mass="screw_mass",
               motor_mass="motor_mass").items()}}
_SECTIONS = ("geometry", "structure", "end_effector", "sea_module")
#: the design values the R1 bracket reads
_BRACKET_FIELDS = ("beta", "r_p", "d1", "d2", "theta_1p", "T", "W", "g", "boss", "wall", "rw", "ch")


def _columns(designs: list[PrrrDesign] | PrrrDesign, only: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
    """One float column (m,) per :data:`_FIELDS` entry (``c_e``: the geometry's own property); ``only``:
    those entries alone. Of one design given alone: numpy scalars (the batch of one without its axis,
    where numpy's arithmetic is cheapest)."""
    keep = _FIELDS if only is None else {k: _FIELDS[k] for k in only}
    if isinstance(designs, PrrrDesign):
        sections = {sec: getattr(designs, sec) for sec in _SECTIONS}
        return {k: np.float64(getattr(sections[sec], f)) for k, (sec, f) in keep.items()}
    fields = {sec: [f for s, f in keep.values() if s == sec] for sec in _SECTIONS}
    table = np.array([[float(getattr(part, f)) for sec in _SECTIONS for part in (getattr(d, sec),)
                       for f in fields[sec]] for d in designs], dtype=float).reshape(len(designs), -1)
    names = [k for sec in _SECTIONS for k, (s, _) in keep.items() if s == sec]
    return {k: np.ascontiguousarray(table[:, j]) for j, k in enumerate(names)}


# ---------------------------------------------------------------------------- the R1 bracket
def _clevis(c: dict[str, np.ndarray]):
    """The carriage block's half width h_y and x faces x_in, x_out, the R1 axis w and the clevis centre
    Ac = A + s_clevis·w (m, 3), carriage frame, s_clevis = −(T + g)."""
    T, g = c["T"], c["g"]
    hy = (c["rw"] / 2 + g) + c["wall"]
    _, _, _, w = leg_vectors(c["beta"], 0.0)
    ca, sa = np.cos(c["theta_1p"]), np.sin(c["theta_1p"])

    def rot(x, y, z):  # R_z(−θ_1p): world (leg 1) → carriage frame
        return _vec(ca * x + sa * y, ca * y - sa * x, z)

    wc = rot(w[..., 0], w[..., 1], w[..., 2])
    Ac = rot(c["d1"], c["d2"], np.zeros_like(T)) + (-(T + g))[..., None] * wc
    return hy, c["r_p"] - hy, c["r_p"] + hy, wc, Ac


def _face(names, N, f, h, h_lo, h_hi, Ac, wc, c, forced=None) -> SimpleNamespace:
    """One block face's bracket per row (see :class:`hapticopt.design.prrr.cad.Bracket`): ``N`` its
    outward normal, ``f`` its offset N·x, ``h`` its in-face horizontal axis and ``h_lo``…``h_hi`` its
    extent along it. ``ok``: the face carries the bracket; ``reason(k)``: why not, for row k.
    ``forced`` (m,) bool: rows whose bracket is taken from this face whatever the rules say (an
    idealised root as long as the face beyond the boss where they fail), unless the clevis plane is
    parallel to it."""
    T, W, R, g, wall = c["T"], c["W"], c["boss"] / 2, c["g"], c["wall"]
    e_l = _cross(N, wc)
    nrm = np.sqrt(_dot(e_l, e_l))
    parallel = nrm < 1e-9
    e_l = e_l / nrm[..., None]
    hAc = _dot(h, Ac)
    e_l = _where((0.5 * (h_lo + h_hi) - hAc) * _dot(e_l, h) < 0.0, -e_l, e_l)  # towards the face
    # the clevis plane's section normal to e_l: e_f towards the face, e_c the side of the layer that
    # meets the face first; N = −ν e_f − μ e_c (ν² + μ² = 1, ν > 0, μ ≥ 0)
    e_f = _cross(wc, e_l)
    e_f = _where(_dot(e_f, N) > 0.0, -e_f, e_f)
    e_c = _where(_dot(wc, N) <= 0.0, wc, -wc)
    nu, mu = -_dot(e_f, N), -_dot(e_c, N)
    n0 = _dot(N, Ac) - f  # the clevis centre's height above the face plane
    depth = n0 - nu * W / 2 - mu * T / 2  # the arm's clearance from the face plane
    # section coordinates (a along e_f, c along e_c) about Ac: the layer's +T/2 side meets the face at
    # a1, the plate is let in d_in deep (≤ the wall beside the rail slot) and ends at a_end; the bonded
    # patch runs from (a1, T/2) along (μ, −ν) over width L_b
    a1 = (n0 - mu * T / 2) / nu
    d_in = np.minimum(mu * T, wall)
    a_end = a1 + d_in / nu
    L_b = _where(mu * T <= wall, T / nu, d_in / (mu * nu))
    efh, ech = _dot(e_f, h), _dot(e_c, h)
    q = (a1 * efh + T / 2 * ech, (a1 + mu * L_b) * efh + (T / 2 - nu * L_b) * ech,
         a_end * efh + T / 2 * ech)  # patch ends and deep corner along h
    qmin, qmax = np.minimum(np.minimum(q[0], q[1]), q[2]), np.maximum(np.maximum(q[0], q[1]), q[2])
    a = _dot(e_l, h)
    lo_e = _where(a > 0.0, (h_lo - hAc - qmin) / a, (h_hi - hAc - qmax) / a)
    hi_e = _where(a > 0.0, (h_hi - hAc - qmax) / a, (h_lo - hAc - qmin) / a)
    l0, l1 = np.maximum(lo_e, R + g), hi_e
    cut, short = depth < 0.0, l1 - l0 < W / 2
    if forced is not None:
        forced = forced & ~parallel
        idealised = forced & (cut | short)
        l0, l1 = _where(idealised, R + g, l0), _where(idealised, R + g + np.maximum(l1 - l0, h_hi - h_lo), l1)
    else:
        forced = np.zeros_like(parallel)
    lm = 0.5 * (l0 + l1)
    n_p = mu[..., None] * e_f - nu[..., None] * e_c  # the face plane's direction normal to e_l (along the patch)
    contact = Ac + lm[..., None] * e_l + (a1 + mu * L_b / 2)[..., None] * e_f + (T / 2 - nu * L_b / 2)[..., None] * e_c
    half = 0.5 * (l1 - l0) * np.abs(e_l[..., 2]) + 0.5 * L_b * np.abs(n_p[..., 2])
    z_off = np.maximum(-(contact[..., 2] - half), contact[..., 2] + half)
    high = z_off > 2 * c["ch"] + 1e-12
    fails = (parallel, ~forced & cut, ~forced & short, ~forced & high)
    ok = ~(parallel | fails[1] | fails[2] | fails[3])

    def reason(k: int) -> str:
        name = names[k]
        if parallel[k]:
            return f"{name} face: the clevis plane is parallel to it"
        if cut[k]:
            return f"{name} face: the arm would cut {_mm(-depth[k])} mm into the block"
        if short[k]:
            return (f"{name} face: a root {_mm(max(l1[k] - l0[k], 0.0))} mm long (allowed ≥ link_width/2 = "
                    f"{_mm(W[k] / 2)} mm)")
        return (f"{name} face: the root would meet the carriage up to {_mm(z_off[k])} mm off its centre (allowed ≤ "
                f"2·structure.carriage_height_mm = {_mm(2 * c['ch'][k])} mm)")

    return SimpleNamespace(
        ok=ok, reason=reason, clevis=Ac, axis=wc, normal=np.broadcast_to(N, Ac.shape), e_l=e_l, arm_length=l0,
        root_centre=Ac + lm[..., None] * e_l + ((a_end - W / 2) / 2)[..., None] * e_f,
        root_axes=_cols(e_l, e_f, _cross(e_l, e_f)), root_size=_vec(l1 - l0, np.maximum(a_end + W / 2, MIN_FEATURE), T),
        contact=contact, n_p=n_p, contact_size=_vec(l1 - l0, L_b, 0.0)[..., :2],
        wedge_o=Ac + lm[..., None] * e_l + a_end[..., None] * e_f + (T / 2)[..., None] * e_c,
        wedge_R=_cols(-e_f, -e_c, _cross(e_f, e_c)),  # parts.frame(−e_f, e_f × e_c), e_f ⟂ e_c
        wedge_dims=_vec(a_end - a1, _where(mu * T > 1e-12, d_in / mu, T), l1 - l0))


#: the bracket's fields (:class:`hapticopt.design.prrr.cad.Bracket`'s, row by row; ``contact`` its
#: ``contact_centre``, ``n_p`` its ``contact_axes[..., 1]``)
BRACKET_KEYS = ("clevis", "axis", "normal", "e_l", "arm_length", "root_centre", "root_axes", "root_size", "contact",
                "n_p", "contact_size", "wedge_o", "wedge_R", "wedge_dims")


def _bracket(c: dict[str, np.ndarray], hy, x_in, x_out, wc, Ac, *, checked: bool = True) -> SimpleNamespace:
    """The R1 bracket per row (:func:`hapticopt.design.prrr.cad.carriage_bracket`): the side face on
    the clevis's side (y = ±h_y, beside the rail, where seed 002's device carries R1), else the x face
    on the clevis's side. ``ok``: a face carries it; ``face``: index into :data:`FACES`;
    ``message(k)``: why no face carries row k. ``checked=False``: the side face's bracket whatever
    its rules say (the frame model's idealised carriage for designs the CAD refuses)."""
    zero = np.zeros(np.shape(hy))
    sy = _where(Ac[..., 1] > 0.0, 1.0, -1.0)
    back = Ac[..., 0] >= c["r_p"]
    side = _face(np.full(np.shape(hy), "side"), _vec(zero, sy, zero), hy, np.array([1.0, 0.0, 0.0]), x_in, x_out, Ac,
                 wc, c, forced=None if checked else zero == 0.0)
    if side.ok.all():  # no row needs the x face
        return SimpleNamespace(**{k: getattr(side, k) for k in BRACKET_KEYS}, ok=side.ok, face=np.zeros(np.shape(hy), dtype=int),
                               message=None)
    x = _face(np.where(back, "back", "front"), _vec(np.where(back, 1.0, -1.0), zero, zero), np.where(back, x_out, -x_in),
              np.array([0.0, 1.0, 0.0]), -hy, hy, Ac, wc, c)
    use = side.ok
    out = SimpleNamespace(**{k: np.where(np.reshape(use, use.shape + (1,) * (getattr(side, k).ndim - use.ndim)),
                                         getattr(side, k), getattr(x, k)) for k in BRACKET_KEYS})
    out.ok = side.ok | x.ok
    out.face = np.where(use, 0, np.where(back, 1, 2))

    def message(k: int) -> str:
        return (f"geometry.r_p_mm = {_mm(c['r_p'][k])}, geometry.theta_1p_deg = {math.degrees(c['theta_1p'][k]):.4g}, "
                f"geometry.beta_deg = {math.degrees(c['beta'][k]):g}: no face of the carriage block can carry the R1 "
                f"clevis ({side.reason(k)}; {x.reason(k)}): move the rail or change beta")

    out.message = message
    return out


def brackets(designs: list[PrrrDesign] | PrrrDesign, *, checked: bool = True) -> SimpleNamespace:
    """The R1 bracket of each design (:func:`_bracket`'s fields, one row per design; of one design
    given alone: no leading axis) [m]."""
    c = _columns(designs, _BRACKET_FIELDS)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _bracket(c, *_clevis(c), checked=checked)


def brackets_many(designs: list[PrrrDesign]) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The R1 bracket of many designs, carriage frame [m], one row per design: ``clevis`` Ac, ``axis``
    w, ``normal`` N, ``e_l``, ``arm_length``, ``root_axes`` (m, 3, 3), ``root_size`` (3 columns along
    e_l, e_f, w), ``contact`` (the patch centre), ``n_p`` and ``contact_size`` (2 columns along e_l,
    n_p), as the fields of :class:`hapticopt.design.prrr.cad.Bracket` (and the rest of :data:`BRACKET_KEYS`);
    and the indices ``rest`` of the
    designs no face carries (their rows are not a bracket; ``cad.carriage_bracket`` raises for them)."""
    b = brackets(designs)
    return {k: np.array(getattr(b, k)) for k in BRACKET_KEYS}, np.flatnonzero(~b.ok)


class Layouts(SimpleNamespace):
    """The layout of m designs, one row each [SI]: the fields of
    :class:`hapticopt.design.prrr.cad.PrrrLayout` as columns (pairs as two columns, vectors (m, 3)),
    ``height`` the device height, ``riser`` link2's R3 riser, ``bracket`` (:func:`_bracket`), the
    columns ``c`` it was computed from, and per row the first rule it fails (``failed``, −1: none)."""

    def error(self, k: int) -> InvalidDesign | None:
        """The exception of row ``k`` (its first failed rule's message), None where it can be laid out."""
        j = int(self.failed[k])
        return None if j < 0 else InvalidDesign(self.messages[j](k))


def layouts(designs: list[PrrrDesign] | PrrrDesign) -> Layouts:
    """The layout of ``designs`` (:class:`Layouts`; of one design given alone: no leading axis): derived dimensions and the buildability rules
    (a part would be degenerate: a wall thinner than :data:`MIN_FEATURE`, the R1 clevis inside the
    carriage block, no block face to carry its bracket, …), each naming the parameter to change."""
    c = _columns(designs)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _layouts(c)


def _layouts(c: dict[str, np.ndarray]) -> Layouts:
    rules = _Rules()
    need = rules.need
    beta, T, W, g = c["beta"], c["T"], c["W"], c["g"]
    R, r = c["boss"] / 2, c["bore"] / 2

    def where(k):
        return f"geometry.r_p_mm = {_mm(c['r_p'][k])}, geometry.theta_1p_deg = {math.degrees(c['theta_1p'][k]):.4g}"

    # --- cross-sections and walls
    for key, val in (("link_thickness_mm", T), ("link_width_mm", W), ("clearance_mm", g),
                     ("carriage_wall_mm", c["wall"]), ("base_thickness_mm", c["tb"])):
        need(val >= MIN_FEATURE, lambda k, key=key, val=val: f"structure.{key} = {_mm(val[k])} is too thin for the "
             f"CAD: allowed ≥ {_mm(MIN_FEATURE)} (mm)")
    need(R - r >= MIN_FEATURE, lambda k: f"structure.bore_diameter_mm = {_mm(2 * r[k])} leaves a boss wall of "
         f"{_mm(R[k] - r[k])} mm: allowed ≤ structure.boss_diameter_mm − {_mm(2 * MIN_FEATURE)} = "
         f"{_mm(2 * R[k] - 2 * MIN_FEATURE)} (mm)")
    for key, L in (("d3_mm", c["d3"]), ("d4_mm", c["d4"])):
        need(L >= 2 * R + MIN_FEATURE, lambda k, key=key, L=L: f"geometry.{key} = {_mm(L[k])} is too short for two "
             f"bosses of structure.boss_diameter_mm = {_mm(2 * R[k])}: allowed ≥ {_mm(2 * R[k] + MIN_FEATURE)} (mm)")
    need(c["handle"] > c["stem"] + 2 * MIN_FEATURE, lambda k: f"end_effector.handle_diameter_mm = {_mm(c['handle'][k])} "
         f"must exceed structure.stem_diameter_mm = {_mm(c['stem'][k])} + {_mm(2 * MIN_FEATURE)} (mm)")
    need(c["screw_d"] + 2 * MIN_FEATURE <= c["sea_envelope"], lambda k: f"sea_module.screw_diameter_mm = "
         f"{_mm(c['screw_d'][k])} does not fit the spring housing of structure.sea_envelope_mm = "
         f"{_mm(c['sea_envelope'][k])}: allowed ≤ {_mm(c['sea_envelope'][k] - 2 * MIN_FEATURE)} (mm)")
    s_link2 = T + g
    s_lug = np.maximum(c["r4"], 2 * T + 2 * g)
    # --- carriage block around the rail
    slot = c["rw"] / 2 + g
    hy, x_in, x_out, wc, Ac = _clevis(c)
    need(x_in > 0.0, lambda k: f"{where(k)}: the carriage crosses the z axis (geometry.r_p_mm must exceed "
         f"rail_width/2 + clearance + carriage_wall = {_mm(hy[k])} mm)")
    # the clevis must sit outside the block (R1 carried beside the rail, not inside the carriage)
    qx = np.minimum(np.maximum(Ac[..., 0], x_in), x_out)
    qy = np.minimum(np.maximum(Ac[..., 1], -hy), hy)
    gap = np.hypot(Ac[..., 0] - qx, Ac[..., 1] - qy)
    need(gap >= R + g, lambda k: f"{where(k)}: the R1 clevis at {_mm(np.hypot(Ac[k][0], Ac[k][1]))} mm from the z "
         f"axis lies {'inside' if gap[k] == 0 else f'{_mm(gap[k])} mm from'} the carriage block around the rail "
         f"(allowed ≥ boss radius + clearance = {_mm(R[k] + g[k])} mm): move the rail (r_p, θ_1p)")
    side = _where(Ac[..., 1] > 0, -1.0, 1.0)  # SEA housing on the side away from the clevis
    b = _bracket(c, hy, x_in, x_out, wc, Ac)
    need(b.ok, b.message)
    # the block spans the bonded patch and the clevis plane's height at its nearest point to the clevis
    # ± (W/2 + T): a block only as tall as the root would lift the base plate, rails and motors into
    # link2 of the next leg (docs/cad.md, "R1 bracket")
    hz = c["ch"] / 2
    z_patch = 0.5 * b.contact_size[..., 0] * np.abs(b.e_l[..., 2]) + 0.5 * b.contact_size[..., 1] * np.abs(b.n_p[..., 2])
    ze = Ac[..., 2] - (wc[..., 0] * (qx - Ac[..., 0]) + wc[..., 1] * (qy - Ac[..., 1])) / wc[..., 2]
    reach = W / 2 + T
    need(np.abs(ze) <= 4 * hz + 1e-12, lambda k: f"geometry.beta_deg = {math.degrees(beta[k]):g}: the clevis plane "
         f"meets the carriage {_mm(abs(ze[k]))} mm off its centre (allowed ≤ 2·structure.carriage_height_mm = "
         f"{_mm(4 * hz[k])} mm); raise beta or move the rail ({where(k)})")
    block_z = (np.minimum(np.minimum(-hz, ze - reach), b.contact[..., 2] - z_patch),
               np.maximum(np.maximum(hz, ze + reach), b.contact[..., 2] + z_patch))
    # --- SEA module: spring housing beside the block, ball screw through it, motor beside the housing
    y_a, y_b = side * hy, side * (hy + c["sea_envelope"])
    Rm = c["motor_d"] / 2
    # --- platform (frame at p): lug centres at radius lug_rho, arms along −v to the stem axis
    sb, cb = np.sin(beta), np.cos(beta)
    lug_rho = (c["b5"] - (s_lug - c["r4"])) * cb
    arm_length = lug_rho / sb
    Rs = c["stem"] / 2
    need(lug_rho - R * sb - T / 2 * cb >= Rs + MIN_FEATURE, lambda k: f"geometry.b5_mm = {_mm(c['b5'][k])} (with "
         f"beta_deg = {math.degrees(beta[k]):g}): the R3 lugs at radius {_mm(lug_rho[k])} mm run into the stem of "
         f"structure.stem_diameter_mm = {_mm(2 * Rs[k])}; raise b5 or reduce the stem/boss")
    need(arm_length <= 10 * (c["b5"] + c["r4"]), lambda k: f"geometry.beta_deg = {math.degrees(beta[k]):g} is too flat "
         f"for the platform: arms of {_mm(arm_length[k])} mm (allowed ≥ "
         f"{math.degrees(math.asin(min(1.0, lug_rho[k] / (10 * (c['b5'][k] + c['r4'][k]))))):.3g} deg)")
    lug_z = (s_lug - c["r4"]) * sb
    # --- base and rails from the carriage's lowest/highest point over the stroke
    ra, rs = b.root_axes, b.root_size
    root_half = 0.5 * rs[..., 0] * np.abs(ra[..., 2, 0]) + 0.5 * rs[..., 1] * np.abs(ra[..., 2, 1]) + 0.5 * rs[..., 2] * np.abs(
        ra[..., 2, 2])
    boss_z = T / 2 * sb + R * cb
    lo = np.minimum(np.minimum(block_z[0], b.root_centre[..., 2] - root_half), Ac[..., 2] - boss_z)
    hi = np.maximum(np.maximum(block_z[1], b.root_centre[..., 2] + root_half), Ac[..., 2] + boss_z)
    half = c["stroke"] / 2
    z_base_top = c["c_e"] - half + lo - c["base_clearance"]
    z_rail_top = c["c_e"] + half + hi + c["base_clearance"]
    failed = rules.first()
    return Layouts(
        c=c, T=T, W=W, R_boss=R, r_bore=r, g=g, s_clevis=-(T + g), s_link2=s_link2, s_lug=s_lug,
        block_x=(x_in, x_out), block_y=hy, block_z=block_z, slot=slot, side=side, clevis=Ac, wc=wc, bracket=b,
        housing_y=(np.minimum(y_a, y_b), np.maximum(y_a, y_b)),
        screw_xy=_vec(c["r_p"], side * (hy + c["sea_envelope"] / 2), 0.0)[..., :2],
        motor_xy=_vec(c["r_p"] + c["motor_offset"], side * (hy + c["sea_envelope"] + g + Rm), 0.0)[..., :2],
        lug_rho=lug_rho, arm_length=arm_length, stem_bottom=lug_z - lug_rho * cb / sb - T,
        ball_z=lug_z + boss_z + c["handle"] / 2 + 2e-3, z_base_top=z_base_top, z_rail_top=z_rail_top,
        height=np.maximum(z_rail_top, z_base_top + c["motor_length"]) - z_base_top + c["tb"],
        riser=s_lug - T / 2 - g - (s_link2 + T / 2), failed=failed, messages=rules.messages)


# ---------------------------------------------------------------------------- primitive tables
class _Table:
    """The distinct primitives of m designs in part order: per primitive its part, kind, role and
    whether only designs with link2's riser have it, and its values as (m, …) columns or constants; a
    part may repeat an earlier part's primitives (``same``: legs 2 and 3 of the moving parts)."""

    def __init__(self, shape: tuple[int, ...]) -> None:
        self.shape = shape
        self.parts: list[tuple[str, str, np.ndarray, int | None]] = []  # name, body, density, same
        self.prims: list[tuple] = []  # part, kind, role, o, R, dims, riser only

    def part(self, name: str, body: str, density, same: int | None = None) -> None:
        self.parts.append((name, body, density, same))

    def add(self, kind: Kind, role: Role, o, R, dims, riser: bool = False) -> None:
        self.prims.append((len(self.parts) - 1, kind, role, o, R, dims, riser))

    def box(self, o, R, lx, ly, lz, role: Role = Role.SOLID) -> None:
        self.add(Kind.BOX, role, o, R, (lx, ly, lz))

    def cylinder(self, o, R, radius, height, role: Role = Role.SOLID, riser: bool = False) -> None:
        self.add(Kind.CYLINDER, role, o, R, (radius, height, 0.0), riser)

    def bar(self, R, o, length, *, width, thickness, z, bosses, boss_radius, bore_radius) -> None:
        """:func:`hapticopt.design.parts.bar_with_bosses` from 0 to ``length`` > 0 with bosses at 0 and
        (when two are given) at ``length``: the bar, then per boss its disc, its cap segments inside
        the bar (towards +x at 0, −x at the end) and its bore."""
        ex, ez = R[..., 0], R[..., 2]
        self.box(o + (length / 2)[..., None] * ex + z[..., None] * ez, R, length, width, thickness)
        flip = R * np.array([-1.0, -1.0, 1.0])  # local x reversed (z kept)
        for xb, Rc in zip(bosses, (R, flip)):
            c = o + xb[..., None] * ex + z[..., None] * ez
            self.cylinder(c, R, boss_radius, thickness)
            self.add(Kind.CAPSEG, Role.OVERLAP, c, Rc, (boss_radius, np.minimum(width / 2, boss_radius), thickness))
            self.cylinder(c, R, bore_radius, thickness, role=Role.HOLE)

    def values(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``o`` (…, n, 3), ``R`` (…, n, 3, 3) and ``dims`` (…, n, 3) of the n distinct primitives."""
        shape = self.shape + (len(self.prims),)
        o, R, dims = np.empty(shape + (3,)), np.empty(shape + (3, 3)), np.empty(shape + (3,))
        for j, (_, _, _, oj, Rj, dj, _) in enumerate(self.prims):
            o[..., j, :], R[..., j, :, :] = oj, Rj
            dims[..., j, 0], dims[..., j, 1], dims[..., j, 2] = dj
        return o, R, dims

    def order(self, riser: bool) -> tuple[list[int], list[int]]:
        """(the distinct primitive of each table entry, its part) in part order, with or without the riser."""
        own: dict[int, list[int]] = {}
        for j, p in enumerate(self.prims):
            if riser or not p[6]:
                own.setdefault(p[0], []).append(j)
        src, part = [], []
        for k, (_, _, _, same) in enumerate(self.parts):
            js = own.get(k if same is None else same, [])
            src += js
            part += [k] * len(js)
        return src, part


def _tables(L: Layouts) -> _Table:
    """The primitives of every part of the layouts ``L``, each in its own frame (see
    :func:`hapticopt.design.prrr.cad.part_frames`) [m]."""
    c, b = L.c, L.bracket
    tab = _Table(np.shape(L.T))
    zero, eye, ez = np.zeros(tab.shape), np.eye(3), np.array([0.0, 0.0, 1.0])
    T, W, R, r, rho = L.T, L.W, L.R_boss, L.r_bore, c["rho"]
    zb, zr = L.z_base_top, L.z_rail_top
    tab.part("base", "base", rho)
    tab.cylinder(_vec(zero, zero, zb - c["tb"] / 2), eye, c["base_radius"], c["tb"])
    # fixed: rail at r_p·u', ball screw and motor beside it (carriage-frame xy turned to the leg)
    screw_vol = math.pi * (c["screw_d"] / 2) ** 2 * (zr - zb)
    motor_vol = math.pi * (c["motor_d"] / 2) ** 2 * (zb + c["motor_length"] - zb)
    for i, gamma in zip(LEGS, GAMMAS):
        a = gamma + c["theta_1p"]
        up, tp = _vec(np.cos(a), np.sin(a), zero), _vec(-np.sin(a), np.cos(a), zero)
        tab.part(f"rail_{i}", "base", rho)
        tab.box(c["r_p"][..., None] * up + (zb + (zr - zb) / 2)[..., None] * ez, _cols(up, tp, np.broadcast_to(ez, up.shape)), c["rw"], c["rw"], zr - zb)
        for name, xy, radius, z1, vol, mass in (
                ("screw", L.screw_xy, c["screw_d"] / 2, zr, screw_vol, c["screw_mass"]),
                ("motor", L.motor_xy, c["motor_d"] / 2, zb + c["motor_length"], motor_vol, c["motor_mass"])):
            tab.part(f"{name}_{i}", "base", mass / vol)
            tab.cylinder(xy[..., :1] * up + xy[..., 1:] * tp + ((zb + z1) / 2)[..., None] * ez, eye, radius, z1 - zb)
    # moving, the same in every leg's frame: carriage block with the rail slot, the R1 bracket (clevis arm
    # from the clevis centre to the root's near end face; the root plate let into the block face, its part
    # inside the block a wedge counted once), SEA housing beside the block, the two links
    (x0, x1), (y0, y1), (z0, z1) = L.block_x, L.housing_y, L.block_z
    zm = (z0 + z1) / 2
    housing = (x1 - x0) * (y1 - y0) * (z1 - z0)
    first = len(tab.parts)
    tab.part("carriage_1", "carriage_1", rho)
    tab.box(_vec((x0 + x1) / 2, zero, zm), eye, x1 - x0, 2 * L.block_y, z1 - z0)
    tab.box(_vec(c["r_p"], zero, zm), eye, 2 * L.slot, 2 * L.slot, z1 - z0, role=Role.HOLE)
    tab.bar(_cols(b.e_l, _cross(b.axis, b.e_l), b.axis), b.clevis, b.arm_length, width=W, thickness=T, z=zero, bosses=(zero,),
            boss_radius=R, bore_radius=r)
    tab.box(b.root_centre, b.root_axes, *np.moveaxis(b.root_size, -1, 0))
    tab.add(Kind.WEDGE, Role.OVERLAP, b.wedge_o, b.wedge_R, tuple(np.moveaxis(b.wedge_dims, -1, 0)))
    tab.part("housing_1", "carriage_1", c["housing_mass"] / housing)
    tab.box(_vec((x0 + x1) / 2, (y0 + y1) / 2, zm), eye, x1 - x0, y1 - y0, z1 - z0)
    tab.part("link1_1", "link1_1", rho)
    tab.bar(eye, np.zeros(3), c["d3"], width=W, thickness=T, z=zero, bosses=(zero, c["d3"]), boss_radius=R,
            bore_radius=r)
    tab.part("link2_1", "link2_1", rho)
    tab.bar(eye, np.zeros(3), c["d4"], width=W, thickness=T, z=L.s_link2, bosses=(zero, c["d4"]), boss_radius=R,
            bore_radius=r)
    top = L.s_link2 + T / 2  # R3 boss raised to meet the platform lug
    centre = _vec(c["d4"], zero, top + L.riser / 2)
    tab.cylinder(centre, eye, R, L.riser, riser=True)
    tab.cylinder(centre, eye, r, L.riser, role=Role.HOLE, riser=True)
    for i in LEGS[1:]:
        for k, name in enumerate(("carriage", "housing", "link1", "link2")):
            _, body, density, _ = tab.parts[first + k]
            tab.part(f"{name}_{i}", body.replace("_1", f"_{i}"), density, first + k)
    # platform (frame at p): three R3 lugs with arms to the stem axis (stem-diameter wide; their part
    # inside the stem counted once), the stem and the handle ball (its cap inside the ball counted once)
    tab.part("platform", "platform", rho)
    Rs, beta = c["stem"] / 2, c["beta"]
    for gamma in GAMMAS:
        u, t, v, w = leg_vectors(beta, gamma)
        centre = (c["b5"] * np.cos(beta))[..., None] * u + (L.s_lug - c["r4"])[..., None] * w
        Ra = _cols(-v, -t, w)  # parts.frame(−v, w): w × (−v) = −t
        tab.bar(Ra, centre, L.arm_length, width=2 * Rs, thickness=T, z=zero, bosses=(zero,), boss_radius=R,
                bore_radius=r)
        s_in = (L.lug_rho - Rs) / np.sin(beta)
        tab.box(centre + ((s_in + L.arm_length) / 2)[..., None] * Ra[..., 0], Ra, L.arm_length - s_in, 2 * Rs, T,
                role=Role.OVERLAP)
    rb = c["handle"] / 2
    cap = np.sqrt(rb * rb - Rs * Rs)
    h = L.ball_z - L.stem_bottom
    tab.cylinder(_vec(zero, zero, L.stem_bottom + h / 2), eye, Rs, h)
    tab.cylinder(_vec(zero, zero, L.ball_z - cap / 2), eye, Rs, cap, role=Role.OVERLAP)
    tab.add(Kind.SPHERE, Role.SOLID, _vec(zero, zero, L.ball_z), eye, (rb, 0.0, 0.0))
    return tab


def part_tables_many(designs: list[PrrrDesign]) -> tuple[list[PartTables], np.ndarray]:
    """The part tables of ``designs`` grouped by part layout (without, then with link2's riser), and
    the indices ``rest`` (into ``designs``) of the designs whose parts cannot be laid out (a rule fails:
    :func:`hapticopt.design.prrr.cad.part_specs` raises for them). Every design is in exactly one group
    or in ``rest``."""
    if not designs:
        return [], np.zeros(0, dtype=int)
    L = layouts(designs)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        tab = _tables(L)
        o, R, dims = tab.values()
    ok = L.failed < 0
    riser = L.riser > MIN_FEATURE
    density = np.stack(np.broadcast_arrays(*(p[2] for p in tab.parts)), axis=1)
    names, bodies = tuple(p[0] for p in tab.parts), tuple(p[1] for p in tab.parts)
    groups = []
    for flag in (False, True):
        sel = np.flatnonzero(ok & (riser == flag))
        if len(sel) == 0:
            continue
        src, part = tab.order(flag)
        rows = np.ix_(sel, src)
        groups.append(PartTables(
            index=sel, part_names=names, bodies=bodies, prim_part=np.array(part),
            kind=np.array([int(tab.prims[j][1]) for j in src]), role=tuple(tab.prims[j][2] for j in src),
            R=R[rows], o=o[rows], dims=dims[rows], density=density[sel], height=L.height[sel]))
    return groups, np.flatnonzero(~ok)

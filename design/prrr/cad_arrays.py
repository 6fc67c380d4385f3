"""Array form of the 3-PRRR part tables: :func:`hapticopt.design.prrr.cad.part_specs` and
:func:`hapticopt.design.prrr.cad.device_height` of many designs at once (numpy, one row per design).

The batched draft evaluator (``hapticopt.analysis.prrr.draft_batch``) needs the primitive tables of
every design of a batch; built design by design (``cad.layout``, ``cad.carriage_bracket``, one
:class:`~hapticopt.design.parts.Primitive` object per primitive) they cost ≈ 0.5 ms a design. Here the
same formulas run on ``(m,)`` columns: :func:`part_tables_many` returns, for each part layout (the
parts, their primitives' kinds and roles, in ``part_specs`` order; the R3 riser of link2 is the one
feature that changes it), the stacked primitive tables, densities and device height, tested equal to
the per-design functions (``tests/design/prrr/test_cad_arrays.py``).

The layout's buildability rules (``cad._need``: they raise :class:`InvalidDesign` with a message per
design) are evaluated as boolean columns. A design that fails one, or that lies within
:data:`NEAR` of a rule's threshold or of one of the layout's branch points (the bracket's face, the
signs that orient its axes, the riser) is not tabled here: it is returned in ``rest`` for the
per-design functions, which give the same exception (same message) or the same tables there, so the
verdicts never depend on rounding differences between the scalar and the array formulas.

:func:`brackets_many` is the R1 bracket alone (:func:`cad.carriage_bracket`, checked: the same face
formulas as the part tables, :func:`_bracket`), for the frame model's batched parameters; its ``rest``
are the designs no face carries or near a face rule's threshold or branch point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hapticopt.design.parts import Kind, Role
from hapticopt.design.prrr.cad import LEGS, MIN_FEATURE
from hapticopt.design.prrr.params import GAMMAS, PrrrDesign

#: half-width of the band around a rule's threshold or a branch point (lengths [m] and unit-vector
#: components) inside which a design takes the per-design path: four decades above the rounding of
#: the formulas at device size (≈ 1e-16 m), far below any real design difference
NEAR = 1e-12


@dataclass(frozen=True, kw_only=True, eq=False)
class PartTables:
    """The part tables of ``m`` designs of one part layout, stacked (``part_specs`` order) [SI].

    ``part_names``, ``bodies`` (n_parts,); per primitive (P,): ``prim_part`` (index into the parts),
    ``kind`` (:class:`Kind` values), ``role`` (:class:`Role`); per design: ``R`` (m, P, 3, 3) axes
    (columns) in the part frame, ``o`` (m, P, 3) centres [m], ``dims`` (m, P, 3) as listed in
    :class:`Kind`, ``density`` (m, n_parts) [kg/m³], ``height`` (m,) :func:`cad.device_height` [m];
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
def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _cross(a, b):
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _frame(x, z):
    """:func:`hapticopt.design.parts.frame` per row: columns x, z × x, z (m, 3, 3)."""
    z = z / np.sqrt(_dot(z, z))[..., None]
    x = x - _dot(x, z)[..., None] * z
    x = x / np.sqrt(_dot(x, x))[..., None]
    return np.stack([x, _cross(z, x), z], axis=-1)


def _vec(x, y, z):
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1).astype(float)


class _Rules:
    """Accumulates which designs pass every rule clearly (``ok``) and which lie near a threshold."""

    def __init__(self, m: int) -> None:
        self.ok = np.ones(m, bool)
        self.near = np.zeros(m, bool)

    def need(self, margin, *, strict: bool = False, exact: bool = False) -> None:
        """The rule ``margin ≥ 0`` (``> 0`` when ``strict``); ``exact``: the margin is a difference of
        two sides computed by the same operations as the per-design rule (no band needed: the sign of
        a floating-point difference is the comparison's verdict)."""
        margin = np.asarray(margin, dtype=float)
        self.ok &= margin > 0.0 if strict else margin >= 0.0
        if not exact:
            self.near |= ~(np.abs(margin) > NEAR)

    def branch(self, x) -> None:
        """A branch point at ``x = 0`` (a sign that picks a face or an orientation)."""
        self.near |= ~(np.abs(np.asarray(x, dtype=float)) > NEAR)


class _Prims:
    """Primitives of the part tables in ``part_specs`` order, one (m, …) array per field."""

    def __init__(self, m: int) -> None:
        self.m = m
        self.rows: list[tuple[int, Kind, Role, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]] = []

    def add(self, part: int, kind: Kind, role: Role, o, R, dims, present=None) -> None:
        m = self.m
        o = np.broadcast_to(np.asarray(o, dtype=float), (m, 3))
        R = np.broadcast_to(np.asarray(R, dtype=float), (m, 3, 3))
        dims = np.stack(np.broadcast_arrays(*(np.asarray(d, dtype=float) for d in dims), np.zeros(m)), axis=-1)[:, :3]
        self.rows.append((part, kind, role, o, R, dims, present))

    def box(self, part, o, R, lx, ly, lz, role=Role.SOLID, present=None):
        self.add(part, Kind.BOX, role, o, R, (lx, ly, lz), present)

    def cylinder(self, part, o, R, radius, height, role=Role.SOLID, present=None):
        self.add(part, Kind.CYLINDER, role, o, R, (radius, height, 0.0), present)

    def bar_with_bosses(self, part, R, o, x0, x1, *, width, thickness, z, bosses, boss_radius, bore_radius,
                        capseg=(), flip_capseg=()):
        """:func:`hapticopt.design.parts.bar_with_bosses` per row; ``capseg``/``flip_capseg``: the bosses
        (indices) that have the cap segment towards +x / −x (the per-design ``xb < x1``, ``xb > x0``)."""
        ex, ez = R[..., 0], R[..., 2]
        self.box(part, o + ((x0 + x1) / 2)[..., None] * ex + z[..., None] * ez, R, x1 - x0, width, thickness)
        flip = R * np.array([-1.0, -1.0, 1.0])
        for k, xb in enumerate(bosses):
            c = o + xb[..., None] * ex + z[..., None] * ez
            self.cylinder(part, c, R, boss_radius, thickness)
            if k in capseg:
                self.add(part, Kind.CAPSEG, Role.OVERLAP, c, R, (boss_radius, np.minimum(width / 2, boss_radius),
                                                                 thickness))
            if k in flip_capseg:
                self.add(part, Kind.CAPSEG, Role.OVERLAP, c, flip, (boss_radius, np.minimum(width / 2, boss_radius),
                                                                    thickness))
            self.cylinder(part, c, R, bore_radius, thickness, role=Role.HOLE)


#: the design values the part tables read: column name → (section, field)
_FIELDS = dict(
    beta=("geometry", "beta"), r_p=("geometry", "r_p"), d1=("geometry", "d1"), d2=("geometry", "d2"),
    d3=("geometry", "d3"), d4=("geometry", "d4"), r4=("geometry", "r4"), b5=("geometry", "b5"),
    stroke=("geometry", "stroke"), theta_1p=("geometry", "theta_1p"), c_e=("geometry", "c_e"),
    T=("structure", "link_thickness"), W=("structure", "link_width"), g=("structure", "clearance"),
    boss=("structure", "boss_diameter"), bore=("structure", "bore_diameter"), wall=("structure", "carriage_wall"),
    tb=("structure", "base_thickness"), rw=("structure", "rail_width"), ch=("structure", "carriage_height"),
    stem=("structure", "stem_diameter"), rho=("structure", "density"), base_clearance=("structure", "base_clearance"),
    base_radius=("structure", "base_radius"), sea_envelope=("structure", "sea_envelope"),
    handle=("end_effector", "handle_diameter"), screw_d=("sea_module", "screw_diameter"),
    motor_d=("sea_module", "motor_diameter"), motor_length=("sea_module", "motor_length"),
    motor_offset=("sea_module", "motor_radial_offset"), housing_mass=("sea_module", "housing_mass"),
    screw_mass=("sea_module", "screw_mass"), motor_mass=("sea_module", "motor_mass"))
_SECTIONS = ("geometry", "structure", "end_effector", "sea_module")


def _columns(designs: list[PrrrDesign], only: tuple[str, ...] | None = None) -> dict[str, np.ndarray]:
    """One float column (m,) per :data:`_FIELDS` entry (``c_e``: the geometry's own property); ``only``:
    those entries alone."""
    keep = _FIELDS if only is None else {k: _FIELDS[k] for k in only}
    fields = {sec: [f for s, f in keep.values() if s == sec] for sec in _SECTIONS}
    table = np.array([[float(getattr(part, f)) for sec in _SECTIONS for part in (getattr(d, sec),)
                       for f in fields[sec]] for d in designs], dtype=float).reshape(len(designs), -1)
    names = [k for sec in _SECTIONS for k, (s, _) in keep.items() if s == sec]
    return {k: np.ascontiguousarray(table[:, j]) for j, k in enumerate(names)}


def _leg_vectors(beta, gamma: float):
    c, s = math.cos(gamma), math.sin(gamma)
    cb, sb = np.cos(beta), np.sin(beta)
    zero = np.zeros_like(beta)
    return (_vec(c + zero, s + zero, zero), _vec(-s + zero, c + zero, zero), _vec(sb * c, sb * s, cb),
            _vec(-cb * c, -cb * s, sb))


def _face(rules: _Rules, N, f, h, h_lo, h_hi, Ac, wc, T, W, R, g, wall, ch) -> dict:
    """One block face of :func:`cad.carriage_bracket` (checked), per row; ``rules`` gets this face's
    rules (its ``ok``: the face can carry the bracket)."""
    e_l = _cross(N, wc)
    nrm = np.sqrt(_dot(e_l, e_l))
    rules.need(nrm - 1e-9)
    e_l = e_l / nrm[:, None]
    hAc = _dot(h, Ac)
    turn = (0.5 * (h_lo + h_hi) - hAc) * _dot(e_l, h)
    rules.branch(turn)
    e_l = np.where((turn < 0.0)[:, None], -e_l, e_l)
    e_f = _cross(wc, e_l)
    rules.branch(_dot(e_f, N))
    e_f = np.where((_dot(e_f, N) > 0.0)[:, None], -e_f, e_f)
    rules.branch(_dot(wc, N))
    e_c = np.where((_dot(wc, N) <= 0.0)[:, None], wc, -wc)
    nu, mu = -_dot(e_f, N), -_dot(e_c, N)
    n0 = _dot(N, Ac) - f
    depth = n0 - nu * W / 2 - mu * T / 2
    rules.need(depth)
    a1 = (n0 - mu * T / 2) / nu
    d_in = np.minimum(mu * T, wall)
    a_end = a1 + d_in / nu
    rules.branch(mu * T - wall)
    L_b = np.where(mu * T <= wall, T / nu, d_in / (mu * nu))
    sec_a = (a1, a1 + mu * L_b, a_end)
    sec_c = (T / 2, T / 2 - nu * L_b, T / 2)
    efh, ech = _dot(e_f, h), _dot(e_c, h)
    q = np.stack([sa * efh + sc * ech for sa, sc in zip(sec_a, sec_c)], axis=-1)
    qmin, qmax = q.min(axis=-1), q.max(axis=-1)
    a = _dot(e_l, h)
    rules.branch(a)
    lo_e = np.where(a > 0.0, (h_lo - hAc - qmin) / a, (h_hi - hAc - qmax) / a)
    hi_e = np.where(a > 0.0, (h_hi - hAc - qmax) / a, (h_lo - hAc - qmin) / a)
    l0, l1 = np.maximum(lo_e, R + g), hi_e
    rules.need(l1 - l0 - W / 2)
    lm = 0.5 * (l0 + l1)
    n_p = mu[:, None] * e_f - nu[:, None] * e_c
    a_c, c_c = a1 + mu * L_b / 2, T / 2 - nu * L_b / 2
    contact = Ac + lm[:, None] * e_l + a_c[:, None] * e_f + c_c[:, None] * e_c
    half = 0.5 * (l1 - l0) * np.abs(e_l[:, 2]) + 0.5 * L_b * np.abs(n_p[:, 2])
    zc = (contact[:, 2] - half, contact[:, 2] + half)
    rules.need(2 * ch + 1e-12 - np.maximum(-zc[0], zc[1]))
    plate = np.maximum(a_end + W / 2, MIN_FEATURE)
    rules.branch(mu * T - 1e-12)
    return dict(
        clevis=Ac, e_l=e_l, arm_length=l0, normal=np.broadcast_to(N, Ac.shape), contact=contact, n_p=n_p, patch=L_b, root_centre=Ac + lm[:, None] * e_l + ((a_end - W / 2) / 2)[:, None] * e_f,
        root_axes=np.stack([e_l, e_f, _cross(e_l, e_f)], axis=-1), root_size=(l1 - l0, plate, T), zc=zc,
        wedge_o=Ac + lm[:, None] * e_l + a_end[:, None] * e_f + (T / 2)[:, None] * e_c,
        wedge_R=_frame(-e_f, _cross(e_f, e_c)), wedge_dims=(a_end - a1, np.where(mu * T > 1e-12, d_in / mu, T), l1 - l0))


def _pick(mask, a: dict, b: dict) -> dict:
    """Row-wise choice of face ``a`` where ``mask``, else ``b``."""
    out = {}
    for k, va in a.items():
        vb = b[k]
        if isinstance(va, tuple):
            out[k] = tuple(np.where(mask, x, y) for x, y in zip(va, vb))
        else:
            va = np.asarray(va)
            out[k] = np.where(mask.reshape((-1,) + (1,) * (va.ndim - 1)), va, np.asarray(vb))
    return out


def part_tables_many(designs: list[PrrrDesign]) -> tuple[list[PartTables], np.ndarray]:
    """The part tables of ``designs`` grouped by part layout, and the indices (into ``designs``) of
    the designs not tabled here (``rest``: a rule fails or a threshold is within :data:`NEAR`; the
    per-design :func:`cad.part_specs` gives their tables or their exception). Every design is in
    exactly one group or in ``rest``."""
    m = len(designs)
    if m == 0:
        return [], np.zeros(0, dtype=int)
    c = _columns(designs)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _tables(c, m)


def _clevis(c: dict[str, np.ndarray]):
    """The carriage block's half width h_y and x faces x_in, x_out, the R1 axis w and the clevis centre
    Ac (m, 3) in the carriage frame, per row (:func:`cad.carriage_bracket`'s first lines)."""
    T, g = c["T"], c["g"]
    hy = (c["rw"] / 2 + g) + c["wall"]
    x_in, x_out = c["r_p"] - hy, c["r_p"] + hy
    _, _, _, w = _leg_vectors(c["beta"], 0.0)
    ca, sa = np.cos(-c["theta_1p"]), np.sin(-c["theta_1p"])

    def rot(x):  # cad._rot_z(−θ_1p) @ x
        return _vec(ca * x[:, 0] + -sa * x[:, 1] + 0.0 * x[:, 2], sa * x[:, 0] + ca * x[:, 1] + 0.0 * x[:, 2],
                    0.0 * x[:, 0] + 0.0 * x[:, 1] + 1.0 * x[:, 2])

    A = rot(_vec(c["d1"], c["d2"], np.zeros_like(T)))
    wc = rot(w)
    return hy, x_in, x_out, wc, A + (-(T + g))[:, None] * wc


def _bracket(rules: _Rules, c: dict[str, np.ndarray], hy, x_in, x_out, wc, Ac) -> dict:
    """:func:`cad.carriage_bracket` (checked) per row: the side face, else the x face (:func:`_face`'s
    fields of the face used); ``rules`` gets its rules (``ok``: a face carries it) and branch points."""
    m = len(hy)
    T, W, g, R = c["T"], c["W"], c["g"], c["boss"] / 2
    rules.branch(Ac[:, 1])
    sy = np.where(Ac[:, 1] > 0, 1.0, -1.0)
    rules.branch(Ac[:, 0] - c["r_p"])
    sx = np.where(Ac[:, 0] >= c["r_p"], 1.0, -1.0)
    ex, ey = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    zero = np.zeros(m)
    args = (Ac, wc, T, W, R, g, c["wall"], c["ch"])
    r_side, r_x = _Rules(m), _Rules(m)
    f_side = _face(r_side, _vec(zero, sy, zero), hy, ex, x_in, x_out, *args)
    f_x = _face(r_x, _vec(sx, zero, zero), np.where(sx > 0, x_out, -x_in), ey, -hy, hy, *args)
    rules.ok &= r_side.ok | r_x.ok
    rules.near |= r_side.near | (~r_side.ok & r_x.near)
    return _pick(r_side.ok, f_side, f_x)


#: the design values :func:`brackets_many` reads
_BRACKET_FIELDS = ("beta", "r_p", "d1", "d2", "theta_1p", "T", "W", "g", "boss", "wall", "rw", "ch")


def brackets_many(designs: list[PrrrDesign]) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """:func:`cad.carriage_bracket` (checked) of many designs, carriage frame [m], one row per design:
    ``clevis`` Ac, ``axis`` w, ``normal`` N, ``e_l``, ``arm_length``, ``root_axes`` (m, 3, 3),
    ``root_size`` (3 columns along e_l, e_f, w), ``contact`` (the patch centre), ``n_p`` and
    ``contact_size`` (2 columns along e_l, n_p) as the :class:`cad.Bracket` fields. Also the indices ``rest`` of the
    designs no face carries, or that lie within :data:`NEAR` of a face rule's threshold or of a branch
    point: their rows are not the bracket; :func:`cad.carriage_bracket` of those gives it (or its
    exception)."""
    m = len(designs)
    c = _columns(designs, _BRACKET_FIELDS)
    rules = _Rules(m)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        hy, x_in, x_out, wc, Ac = _clevis(c)
        b = _bracket(rules, c, hy, x_in, x_out, wc, Ac)
    out = dict(clevis=Ac, axis=wc, normal=b["normal"], e_l=b["e_l"], arm_length=b["arm_length"],
               root_axes=b["root_axes"], root_size=np.stack(b["root_size"], axis=-1), contact=b["contact"],
               n_p=b["n_p"], contact_size=np.stack([b["root_size"][0], b["patch"]], axis=-1))
    return out, np.flatnonzero(~(rules.ok & ~rules.near))


def _tables(c: dict[str, np.ndarray], m: int) -> tuple[list[PartTables], np.ndarray]:
    rules = _Rules(m)
    beta, T, W, g = c["beta"], c["T"], c["W"], c["g"]
    R, r = c["boss"] / 2, c["bore"] / 2
    # --- cross-sections and walls (cad.layout, same rules and order of operations)
    for val in (T, W, g, c["wall"], c["tb"]):
        rules.need(val - MIN_FEATURE, exact=True)
    rules.need(R - r - MIN_FEATURE, exact=True)
    for L in (c["d3"], c["d4"]):
        rules.need(L - (2 * R + MIN_FEATURE), exact=True)
    rules.need(c["handle"] - (c["stem"] + 2 * MIN_FEATURE), strict=True, exact=True)
    rules.need(c["sea_envelope"] - (c["screw_d"] + 2 * MIN_FEATURE), exact=True)
    s_link2 = T + g
    s_lug = np.maximum(c["r4"], 2 * T + 2 * g)
    half_slot = c["rw"] / 2 + g
    hy, x_in, x_out, wc, Ac = _clevis(c)
    rules.need(x_in, strict=True, exact=True)
    zero = np.zeros(m)
    qx = np.minimum(np.maximum(Ac[:, 0], x_in), x_out)
    qy = np.minimum(np.maximum(Ac[:, 1], -hy), hy)
    gap = np.hypot(Ac[:, 0] - qx, Ac[:, 1] - qy)
    rules.need(gap - (R + g))
    side = np.where(Ac[:, 1] > 0, -1.0, 1.0)
    b = _bracket(rules, c, hy, x_in, x_out, wc, Ac)
    hz = c["ch"] / 2
    zc = b["zc"]
    ze = Ac[:, 2] - (wc[:, 0] * (qx - Ac[:, 0]) + wc[:, 1] * (qy - Ac[:, 1])) / wc[:, 2]
    reach = W / 2 + T
    rules.need(4 * hz + 1e-12 - np.abs(ze))
    block_z = (np.minimum(np.minimum(-hz, ze - reach), zc[0]), np.maximum(np.maximum(hz, ze + reach), zc[1]))
    # --- SEA module
    y_a, y_b = side * hy, side * (hy + c["sea_envelope"])
    housing_y = (np.minimum(y_a, y_b), np.maximum(y_a, y_b))
    screw_xy = (c["r_p"], side * (hy + c["sea_envelope"] / 2))
    Rm = c["motor_d"] / 2
    motor_xy = (c["r_p"] + c["motor_offset"], side * (hy + c["sea_envelope"] + g + Rm))
    # --- platform
    sbeta, cbeta = np.sin(beta), np.cos(beta)
    lug_rho = (c["b5"] - (s_lug - c["r4"])) * cbeta
    arm_length = lug_rho / sbeta
    Rs = c["stem"] / 2
    rules.need(lug_rho - R * sbeta - T / 2 * cbeta - (Rs + MIN_FEATURE))
    rules.need(10 * (c["b5"] + c["r4"]) - arm_length)
    lug_z = (s_lug - c["r4"]) * sbeta
    stem_bottom = lug_z - lug_rho * cbeta / sbeta - T
    lug_top = lug_z + T / 2 * sbeta + R * cbeta
    ball_z = lug_top + c["handle"] / 2 + 2e-3
    # --- base and rails
    half = c["stroke"] / 2
    rc, ra, rs = b["root_centre"], b["root_axes"], b["root_size"]
    rh = 0.5 * rs[0] * np.abs(ra[:, 2, 0]) + 0.5 * rs[1] * np.abs(ra[:, 2, 1]) + 0.5 * rs[2] * np.abs(ra[:, 2, 2])
    root_z = (rc[:, 2] - rh, rc[:, 2] + rh)
    carriage_lo = np.minimum(np.minimum(block_z[0], root_z[0]), Ac[:, 2] - T / 2 * sbeta - R * cbeta)
    carriage_hi = np.maximum(np.maximum(block_z[1], root_z[1]), Ac[:, 2] + T / 2 * sbeta + R * cbeta)
    z_base_top = c["c_e"] - half + carriage_lo - c["base_clearance"]
    z_rail_top = c["c_e"] + half + carriage_hi + c["base_clearance"]
    riser = s_lug - T / 2 - g - (s_link2 + T / 2)
    rules.branch(riser - MIN_FEATURE)
    has_riser = riser > MIN_FEATURE
    height = np.maximum(z_rail_top, z_base_top + c["motor_length"]) - z_base_top + c["tb"]

    # ------------------------------------------------------------------------ primitives
    P = _Prims(m)
    eye = np.eye(3)
    names, bodies, dens = [], [], []

    def part(name: str, body: str, density) -> int:
        names.append(name)
        bodies.append(body)
        dens.append(np.broadcast_to(np.asarray(density, dtype=float), (m,)))
        return len(names) - 1

    rho = c["rho"]
    j = part("base", "base", rho)
    P.cylinder(j, _vec(zero, zero, z_base_top - c["tb"] / 2), eye, c["base_radius"], c["tb"])
    h_rail = z_rail_top - z_base_top
    ez = np.array([0.0, 0.0, 1.0])
    screw_vol = math.pi * (c["screw_d"] / 2) ** 2 * (z_rail_top - z_base_top)
    motor_vol = math.pi * (c["motor_d"] / 2) ** 2 * (z_base_top + c["motor_length"] - z_base_top)
    for i, gamma in zip(LEGS, GAMMAS):
        a_ = gamma + c["theta_1p"]
        up = _vec(np.cos(a_), np.sin(a_), zero)
        tp = _vec(-np.sin(a_), np.cos(a_), zero)
        j = part(f"rail_{i}", "base", rho)
        P.box(j, c["r_p"][:, None] * up + (z_base_top + h_rail / 2)[:, None] * ez, _frame(up, ez + 0 * up),
              c["rw"], c["rw"], h_rail)
        for name, xy, radius, z0, z1, vol, mass in (
                ("screw", screw_xy, c["screw_d"] / 2, z_base_top, z_rail_top, screw_vol, c["screw_mass"]),
                ("motor", motor_xy, c["motor_d"] / 2, z_base_top, z_base_top + c["motor_length"], motor_vol,
                 c["motor_mass"])):
            j = part(f"{name}_{i}", "base", mass / vol)
            centre = xy[0][:, None] * up + xy[1][:, None] * tp + ((z0 + z1) / 2)[:, None] * ez
            P.cylinder(j, centre, eye, radius, z1 - z0)
    (x0, x1), (z0, z1) = (x_in, x_out), block_z
    housing_vol = (x1 - x0) * (housing_y[1] - housing_y[0]) * (z1 - z0)
    wc_frame = _frame(b["e_l"], wc)
    for i in LEGS:
        j = part(f"carriage_{i}", f"carriage_{i}", rho)
        P.box(j, _vec((x0 + x1) / 2, zero, (z0 + z1) / 2), eye, x1 - x0, 2 * hy, z1 - z0)
        P.box(j, _vec(c["r_p"], zero, (z0 + z1) / 2), eye, 2 * half_slot, 2 * half_slot, z1 - z0, role=Role.HOLE)
        P.bar_with_bosses(j, wc_frame, b["clevis"], zero, b["arm_length"], width=W, thickness=T, z=zero,
                          bosses=(zero,), boss_radius=R, bore_radius=r, capseg=(0,))
        P.box(j, b["root_centre"], b["root_axes"], *b["root_size"])
        P.add(j, Kind.WEDGE, Role.OVERLAP, b["wedge_o"], b["wedge_R"], b["wedge_dims"])
        j = part(f"housing_{i}", f"carriage_{i}", c["housing_mass"] / housing_vol)
        P.box(j, _vec((x0 + x1) / 2, (housing_y[0] + housing_y[1]) / 2, (z0 + z1) / 2), eye, x1 - x0,
              housing_y[1] - housing_y[0], z1 - z0)
        j = part(f"link1_{i}", f"link1_{i}", rho)
        P.bar_with_bosses(j, eye[None], np.zeros((m, 3)), zero, c["d3"], width=W, thickness=T, z=zero,
                          bosses=(zero, c["d3"]), boss_radius=R, bore_radius=r, capseg=(0,), flip_capseg=(1,))
        j = part(f"link2_{i}", f"link2_{i}", rho)
        P.bar_with_bosses(j, eye[None], np.zeros((m, 3)), zero, c["d4"], width=W, thickness=T, z=s_link2,
                          bosses=(zero, c["d4"]), boss_radius=R, bore_radius=r, capseg=(0,), flip_capseg=(1,))
        top = s_link2 + T / 2
        rc_ = _vec(c["d4"], zero, top + riser / 2)
        P.cylinder(j, rc_, eye, R, riser, present=has_riser)
        P.cylinder(j, rc_, eye, r, riser, role=Role.HOLE, present=has_riser)
    j = part("platform", "platform", rho)
    for gamma in GAMMAS:
        u, t, v, w_ = _leg_vectors(beta, gamma)
        cen = (c["b5"] * cbeta)[:, None] * u + (s_lug - c["r4"])[:, None] * w_
        Ra = _frame(-v, w_)
        P.bar_with_bosses(j, Ra, cen, zero, arm_length, width=2 * Rs, thickness=T, z=zero, bosses=(zero,),
                          boss_radius=R, bore_radius=r, capseg=(0,))
        s_in = (lug_rho - Rs) / sbeta
        P.box(j, cen + ((s_in + arm_length) / 2)[:, None] * Ra[..., 0], Ra, arm_length - s_in, 2 * Rs, T,
              role=Role.OVERLAP)
    rb = c["handle"] / 2
    cap = np.sqrt(rb * rb - Rs * Rs)
    hs = ball_z - stem_bottom
    P.cylinder(j, _vec(zero, zero, stem_bottom + hs / 2), eye, Rs, hs)
    P.cylinder(j, _vec(zero, zero, ball_z - cap / 2), eye, Rs, cap, role=Role.OVERLAP)
    P.add(j, Kind.SPHERE, Role.SOLID, _vec(zero, zero, ball_z), eye, (rb, 0.0, 0.0))

    good = rules.ok & ~rules.near
    density = np.stack(dens, axis=1)
    groups = []
    for flag in (False, True):
        sel = np.flatnonzero(good & (has_riser == flag))
        if len(sel) == 0:
            continue
        rows = [row for row in P.rows if row[6] is None or flag]
        groups.append(PartTables(
            index=sel, part_names=tuple(names), bodies=tuple(bodies),
            prim_part=np.array([row[0] for row in rows]), kind=np.array([int(row[1]) for row in rows]),
            role=tuple(row[2] for row in rows), R=np.stack([row[4][sel] for row in rows], axis=1),
            o=np.stack([row[3][sel] for row in rows], axis=1), dims=np.stack([row[5][sel] for row in rows], axis=1),
            density=density[sel], height=height[sel]))
    return groups, np.flatnonzero(~good)

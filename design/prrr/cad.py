"""Parametric CAD of the 3-PRRR (seed 002): part tables, posed frames, build123d solids.

Parts (names used in STEP, STL, MJCF and interference reports):
``base``; per leg i = 1, 2, 3: ``rail_i`` (fixed, square bar at r_p·u'_i, u'_i at angle
γ_i + θ_1p), ``screw_i`` and ``motor_i`` (fixed: ball screw beside the rail, motor with belt and
pulleys on the base plate), ``carriage_i`` (block sliding on the rail, with a bracket carrying
the R1 clevis on one side face), ``housing_i`` (SEA spring housing and nut, on the other side
face, moving with the carriage), ``link1_i`` (R1–R2, length d3), ``link2_i`` (R2–R3, length d4, its R3 boss raised
along the axis to carry the r4 offset); ``platform`` (three R3 lugs, arms, stem, handle ball).

Axial layering (along each leg's joint direction w, measured from the plane Π through the R1
point A of seed 002's leg construction, T = link thickness, g = clearance):
carriage clevis [−3T/2−g, −T/2−g], link1 [−T/2, T/2], link2 [T/2+g, 3T/2+g], platform lug
centred at s3 = max(r4, 2T+2g). Every joint axis is the kinematic axis of
:mod:`hapticopt.design.prrr.kinematics` (tested), so neighbouring parts never share volume.

All geometry is SI here; build123d receives mm through :mod:`design.cad_units`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hapticopt.design import mass_properties as _mp
from hapticopt.design import parts as _parts
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.parts import (
    JointAxis,
    Kind,
    PartSpec,
    Role,
    bar_with_bosses,
    box,
    cylinder,
    frame,
    sphere,
    transform,
)
from hapticopt.design.prrr.params import GAMMAS, PrrrDesign
from hapticopt.design.prrr.kinematics import inverse_kinematics, params_of
from hapticopt.design.errors import InvalidInput
from hapticopt.design.prrr.kinematics import leg_chain, leg_frames

#: smallest wall or feature the CAD accepts [m] (below this OCCT produces slivers)
MIN_FEATURE = 0.5e-3
LEGS = (1, 2, 3)
EZ = np.array([0.0, 0.0, 1.0])


def leg_vectors(beta: float, gamma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(u, t, v, w) of one leg, seed 002 leg construction (see hapticopt.design.prrr.kinematics)."""
    c, s, cb, sb = math.cos(gamma), math.sin(gamma), math.cos(beta), math.sin(beta)
    u = np.array([c, s, 0.0])
    t = np.array([-s, c, 0.0])  # e_z × u
    w = np.array([-cb * c, -cb * s, sb])
    v = np.array([sb * c, sb * s, cb])
    return u, t, v, w


def rail_direction(design: PrrrDesign, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """(u', t'): radial and tangential unit vectors of the rail of the leg at ``gamma``, at angle
    γ + θ_1p about z (seed 002 θ_1p; the carriage frame's x and y axes)."""
    a = gamma + design.geometry.theta_1p
    return np.array([math.cos(a), math.sin(a), 0.0]), np.array([-math.sin(a), math.cos(a), 0.0])


def _rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two 3-vectors: ``np.cross``'s products and differences (bitwise equal), without its
    axis handling, which cost half of :func:`carriage_bracket` (measured)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@dataclass(frozen=True, kw_only=True)
class PrrrLayout:
    """Derived CAD dimensions [m] (all from the design; see module docstring). Carriage-frame
    quantities: x = u' (radial, towards rail i at γ_i + θ_1p), y = t', z = e_z, origin on the
    z axis at the slider height D."""

    T: float  # link thickness (axial)
    W: float  # link width
    R_boss: float
    r_bore: float
    g: float
    s_clevis: float  # clevis layer centre (axial, from Π)
    s_link2: float
    s_lug: float  # platform lug centre
    block_x: tuple[float, float]  # carriage block, carriage frame
    block_y: float  # half width
    block_z: tuple[float, float]
    slot: float  # half size of the rail slot
    side: float  # +1 / −1: the side (sign of y) of the SEA housing, screw and motor; the clevis is on −side
    clevis: np.ndarray  # R1 clevis centre Ac, carriage frame
    bracket: Bracket  # the R1 bracket (carriage frame)
    housing_y: tuple[float, float]  # SEA spring housing, carriage frame (x and z as the block)
    screw_xy: np.ndarray  # ball-screw axis, carriage frame
    motor_xy: np.ndarray  # motor axis, carriage frame
    lug_rho: float  # radial position of the lug centre (platform frame)
    arm_length: float  # lug centre to the stem axis
    stem_bottom: float
    ball_z: float
    z_base_top: float
    z_rail_top: float


def _need(cond: bool, message) -> None:
    """Raise :class:`InvalidDesign` with ``message()`` unless ``cond`` (message built lazily)."""
    if not cond:
        raise InvalidDesign(message())


def _mm(x: float) -> str:
    return f"{x * 1e3:g}"


def _box_z_extent(centre: np.ndarray, axes: np.ndarray, size) -> tuple[float, float]:
    """z range [m] of a box (or, with two axes, a rectangle) of the given centre, axes (columns) and sizes."""
    half = sum(0.5 * d * abs(axes[2, k]) for k, d in enumerate(size))
    return float(centre[2] - half), float(centre[2] + half)


def clevis_point(design: PrrrDesign) -> np.ndarray:
    """R1 clevis centre Ac = A + s_clevis·w of leg 1 (γ = 0) at D = 0, world frame [m]."""
    g_, s_ = design.geometry, design.structure
    u, t, v, w = leg_vectors(g_.beta, 0.0)
    return g_.d1 * u + g_.d2 * t - (s_.link_thickness + s_.clearance) * w


def carried_theta_1p(design: PrrrDesign, *, side: float = 1.0) -> float:
    """θ_1p [rad] that puts the R1 clevis directly on the carriage (seed 002's device carries R1
    on the carriage, beside the rail): the clevis boss touches the carriage block's side face
    (tangential distance from the rail axis = block half width + boss radius + clearance), the
    SEA housing on the other side (``side`` = +1: housing at +t', clevis at −t'). Depends only on
    the geometry and part sizes, not on the current θ_1p."""
    s_ = design.structure
    Ac = clevis_point(design)
    rho = math.hypot(Ac[0], Ac[1])
    hy = s_.rail_width / 2 + s_.clearance + s_.carriage_wall
    off = hy + s_.boss_diameter / 2 + s_.clearance
    _need(off < rho, lambda: f"geometry.r_p_mm / theta_1p_deg: the carriage ({_mm(2 * hy)} mm wide) cannot carry the "
          f"R1 clevis at {_mm(rho)} mm from the z axis")
    return math.atan2(Ac[1], Ac[0]) + side * math.asin(off / rho)


@dataclass(frozen=True, kw_only=True)
class Bracket:
    """The carriage's R1 bracket, carriage frame (x = u', y = t', z = e_z, origin on the z axis at
    the slider height D) [m]: an L of two plates, both in the clevis layer (link thickness T along the
    R1 axis w about Ac), so no part of it enters link1's layer.

    * **arm**: the clevis plate, link section W × T, along e_l (the clevis plane ∩ the face plane)
      from the clevis centre Ac to the root's near end face at ``arm_length``, where its whole
      W × T end section is bonded to the root (the root's end face contains it).
    * **root**: a box of thickness T in the clevis layer (axes ``root_axes`` = e_l, e_f, e_l × e_f
      = ±w; sizes ``root_size`` along them) beside the arm's end: along e_l from ``arm_length`` on,
      along e_f (the clevis plane's direction normal to e_l, towards the block face ``normal`` N)
      from the arm's far edge (−W/2) across the block face: the clevis plane meets the face at a
      slant, so the plate is let into the face. Its section in the face plane is the bonded patch
      (``contact_centre``, axes ``contact_axes`` = e_l, n_p, sizes ``contact_size``); the part
      inside the block is ``wedge`` (a right triangular prism, mass bookkeeping). It is let in at
      most ``carriage_wall`` deep (the block's material beside the rail slot); a plate that would
      need more stops there, bonded over the part of its section that crosses the face.
    """

    clevis: np.ndarray  # Ac (3,)
    axis: np.ndarray  # (3,) the R1 joint axis w (normal of the clevis layer)
    normal: np.ndarray  # N (3,): outward normal of the block face carrying the root (±x or ±y)
    e_l: np.ndarray  # (3,) arm axis, from Ac towards the root
    arm_length: float  # l_0: Ac to the root's near end face along e_l
    root_centre: np.ndarray  # (3,)
    root_axes: np.ndarray  # (3, 3) columns e_l, e_f, e_l × e_f (= ±w)
    root_size: tuple[float, float, float]  # along e_l, e_f, w
    contact_centre: np.ndarray  # (3,) centre of the bonded patch (the root's section in the face plane)
    contact_axes: np.ndarray  # (3, 2) columns e_l, n_p (the face plane's direction normal to e_l)
    contact_size: tuple[float, float]  # along e_l, n_p
    wedge: _parts.Primitive  # the root's part inside the block (OVERLAP, carriage frame)
    face: str  # "side" (the y face beside the rail, preferred) or "front"/"back" (the x faces)

    @property
    def contact_area(self) -> float:
        """Bonded area of the root on the block face [m²]."""
        return self.contact_size[0] * self.contact_size[1]

    @property
    def arm_end(self) -> np.ndarray:
        """Centre of the arm's end section, on the root's near end face [m]."""
        return self.clevis + self.arm_length * self.e_l

    @property
    def root_joint(self) -> np.ndarray:
        """J: the point of the root's axis through the patch centre (along e_f) level with the
        arm's axis (the plane through Ac normal to e_f) [m]."""
        e_f = self.root_axes[:, 1]
        return self.contact_centre - ((self.contact_centre - self.clevis) @ e_f) * e_f


def carriage_bracket(design: PrrrDesign, *, checked: bool = True) -> Bracket:
    """The R1 bracket of ``design`` (see :class:`Bracket`); raises :class:`InvalidDesign` naming r_p,
    θ_1p and β when no block face can carry it (``checked=False``: the side face's bracket without
    the rules, its root as long as the face beyond the boss where the rules fail — the frame
    model's idealised carriage for designs the CAD refuses, whose CAD-based evaluators fail on
    their own).

    The clevis is an arm of the link section in the clevis layer; it runs along e_l, the line
    where the clevis plane crosses a block face's plane, so it stays at a constant distance from
    that face, and it ends on a root plate of the same layer that reaches the face. Faces are
    tried in order: the side face on the clevis's side (y = ±h_y, beside the rail, where seed 002's
    device carries R1 and where :func:`carried_theta_1p` puts the clevis), then the x face on the
    clevis's side. A face can carry the bracket when the arm clears the block (its section lies
    outside the face plane) and the face leaves a root at least W/2 long along e_l beyond the
    clevis boss (plus the clearance) and puts the bonded patch within 2·carriage_height of the
    slider height. The bonded patch and the let-in part lie inside the block face's horizontal
    extent; the block grows in z to cover them (:func:`layout`).
    """
    g_, s_ = design.geometry, design.structure
    T, W, g = s_.link_thickness, s_.link_width, s_.clearance
    R = s_.boss_diameter / 2
    hy = s_.rail_width / 2 + g + s_.carriage_wall
    x_in, x_out = g_.r_p - hy, g_.r_p + hy
    _, _, _, w = leg_vectors(g_.beta, 0.0)
    Rz = _rot_z(-g_.theta_1p)
    wc = Rz @ w
    Ac = Rz @ np.array([g_.d1, g_.d2, 0.0]) - (T + g) * wc
    sy = 1.0 if Ac[1] > 0.0 else -1.0  # the clevis side (layout puts the SEA housing on the other)
    sx = 1.0 if Ac[0] >= g_.r_p else -1.0
    # (name, N, face offset N·x, in-face horizontal axis h, its extent on the face)
    faces = (("side", np.array([0.0, sy, 0.0]), hy, np.array([1.0, 0.0, 0.0]), (x_in, x_out)),
             ("back" if sx > 0 else "front", np.array([sx, 0.0, 0.0]), x_out if sx > 0 else -x_in,
              np.array([0.0, 1.0, 0.0]), (-hy, hy)))
    tried = []
    for k, (name, N, f, h, (h_lo, h_hi)) in enumerate(faces):
        unchecked = not checked and k == 0
        e_l = _cross3(N, wc)
        if np.linalg.norm(e_l) < 1e-9:
            tried.append(f"{name} face: the clevis plane is parallel to it")
            continue
        e_l /= np.linalg.norm(e_l)
        if (0.5 * (h_lo + h_hi) - h @ Ac) * (e_l @ h) < 0.0:
            e_l = -e_l  # towards the face
        # the clevis plane's section normal to e_l: e_f towards the face, e_c the side of the layer
        # that meets the face first; N = −ν e_f − μ e_c (ν² + μ² = 1, ν > 0, μ ≥ 0)
        e_f = _cross3(wc, e_l)
        e_f = -e_f if e_f @ N > 0.0 else e_f
        e_c = wc if wc @ N <= 0.0 else -wc
        nu, mu = float(-(e_f @ N)), float(-(e_c @ N))
        n0 = float(N @ Ac - f)  # the clevis centre's height above the face plane
        depth = n0 - nu * W / 2 - mu * T / 2  # the arm's clearance from the face plane
        # section coordinates (a along e_f, c along e_c) about Ac: the layer's +T/2 side meets the
        # face at a1, the plate is let in d_in deep (≤ the wall beside the rail slot) and ends at
        # a_end; the bonded patch runs from (a1, T/2) along (μ, −ν) over width L_b
        a1 = (n0 - mu * T / 2) / nu
        d_in = min(mu * T, s_.carriage_wall)
        a_end = a1 + d_in / nu
        L_b = T / nu if mu * T <= s_.carriage_wall else d_in / (mu * nu)
        sec = np.array([[a1, T / 2], [a1 + mu * L_b, T / 2 - nu * L_b], [a_end, T / 2]])  # patch ends, deep corner
        q = sec[:, 0] * (e_f @ h) + sec[:, 1] * (e_c @ h)  # their offsets along h
        a = e_l @ h
        if a > 0.0:
            lo_e, hi_e = (h_lo - h @ Ac - q.min()) / a, (h_hi - h @ Ac - q.max()) / a
        else:
            lo_e, hi_e = (h_hi - h @ Ac - q.max()) / a, (h_lo - h @ Ac - q.min()) / a
        l0, l1 = max(lo_e, R + g), hi_e
        forced = unchecked  # the side face, whatever the rules say
        if forced and (depth < 0.0 or l1 - l0 < W / 2):  # an idealised root: the face's length beyond the boss
            l0, l1 = R + g, R + g + max(l1 - l0, h_hi - h_lo)
        elif depth < 0.0:
            tried.append(f"{name} face: the arm would cut {_mm(-depth)} mm into the block")
            continue
        elif l1 - l0 < W / 2:
            tried.append(f"{name} face: a root {_mm(max(l1 - l0, 0.0))} mm long (allowed ≥ link_width/2 = {_mm(W / 2)} mm)")
            continue
        lm = 0.5 * (l0 + l1)
        n_p = mu * e_f - nu * e_c  # the face plane's direction normal to e_l (along the patch)
        a_c, c_c = a1 + mu * L_b / 2, T / 2 - nu * L_b / 2
        contact = Ac + lm * e_l + a_c * e_f + c_c * e_c
        zc = _box_z_extent(contact, np.stack([e_l, n_p], axis=1), (l1 - l0, L_b))
        if max(-zc[0], zc[1]) > 2 * s_.carriage_height + 1e-12 and not forced:
            tried.append(f"{name} face: the root would meet the carriage up to {_mm(max(-zc[0], zc[1]))} mm off its "
                         f"centre (allowed ≤ 2·structure.carriage_height_mm = {_mm(2 * s_.carriage_height)} mm)")
            continue
        plate = max(a_end + W / 2, MIN_FEATURE)  # (only an idealised root can have the face inside the arm)
        wedge = _parts.wedge(Ac + lm * e_l + a_end * e_f + T / 2 * e_c, _parts.frame(-e_f, _cross3(e_f, e_c)),
                             a_end - a1, d_in / mu if mu * T > 1e-12 else T, l1 - l0)
        return Bracket(clevis=Ac, axis=wc, normal=N, e_l=e_l, arm_length=float(l0),
                       root_centre=Ac + lm * e_l + (a_end - W / 2) / 2 * e_f,
                       root_axes=np.stack([e_l, e_f, _cross3(e_l, e_f)], axis=1),
                       root_size=(float(l1 - l0), float(plate), float(T)),
                       contact_centre=contact, contact_axes=np.stack([e_l, n_p], axis=1),
                       contact_size=(float(l1 - l0), float(L_b)), wedge=wedge, face=name)
    raise InvalidDesign(f"geometry.r_p_mm = {_mm(g_.r_p)}, geometry.theta_1p_deg = {math.degrees(g_.theta_1p):.4g}, "
                        f"geometry.beta_deg = {math.degrees(g_.beta):g}: no face of the carriage block can carry the R1 "
                        f"clevis ({'; '.join(tried)}): move the rail or change beta")


def layout(design: PrrrDesign) -> PrrrLayout:
    """Derived dimensions, after the buildability rules; raises :class:`InvalidDesign` naming
    the parameter when a part would be degenerate (zero-thickness wall, disconnected bracket…)."""
    g_, s_, e_, m_ = design.geometry, design.structure, design.end_effector, design.sea_module
    beta = g_.beta
    T, W, g = s_.link_thickness, s_.link_width, s_.clearance
    R, r = s_.boss_diameter / 2, s_.bore_diameter / 2
    deg = math.degrees(beta)
    where = f"geometry.r_p_mm = {_mm(g_.r_p)}, geometry.theta_1p_deg = {math.degrees(g_.theta_1p):.4g}"
    # --- cross-sections and walls
    for key, val in (("link_thickness_mm", T), ("link_width_mm", W), ("clearance_mm", g),
                     ("carriage_wall_mm", s_.carriage_wall), ("base_thickness_mm", s_.base_thickness)):
        _need(val >= MIN_FEATURE, lambda: f"structure.{key} = {_mm(val)} is too thin for the CAD: allowed ≥ {_mm(MIN_FEATURE)} (mm)")
    _need(R - r >= MIN_FEATURE,
          lambda: f"structure.bore_diameter_mm = {_mm(2 * r)} leaves a boss wall of {_mm(R - r)} mm: allowed ≤ "
          f"structure.boss_diameter_mm − {_mm(2 * MIN_FEATURE)} = {_mm(2 * R - 2 * MIN_FEATURE)} (mm)")
    for key, L in (("d3_mm", g_.d3), ("d4_mm", g_.d4)):
        _need(L >= 2 * R + MIN_FEATURE,
              lambda: f"geometry.{key} = {_mm(L)} is too short for two bosses of structure.boss_diameter_mm = {_mm(2 * R)}: "
              f"allowed ≥ {_mm(2 * R + MIN_FEATURE)} (mm)")
    _need(e_.handle_diameter > s_.stem_diameter + 2 * MIN_FEATURE,
          lambda: f"end_effector.handle_diameter_mm = {_mm(e_.handle_diameter)} must exceed structure.stem_diameter_mm "
          f"= {_mm(s_.stem_diameter)} + {_mm(2 * MIN_FEATURE)} (mm)")
    _need(m_.screw_diameter + 2 * MIN_FEATURE <= s_.sea_envelope,
          lambda: f"sea_module.screw_diameter_mm = {_mm(m_.screw_diameter)} does not fit the spring housing of "
          f"structure.sea_envelope_mm = {_mm(s_.sea_envelope)}: allowed ≤ {_mm(s_.sea_envelope - 2 * MIN_FEATURE)} (mm)")
    s_clevis, s_link2 = -(T + g), T + g
    s_lug = max(g_.r4, 2 * T + 2 * g)
    # --- carriage block around the rail (carriage frame: x = u', y = t', z = e_z, origin on the axis at D)
    half_slot = s_.rail_width / 2 + g
    hy = half_slot + s_.carriage_wall
    x_in = g_.r_p - hy
    x_out = g_.r_p + hy
    _need(x_in > 0.0, lambda: f"{where}: the carriage crosses the z axis (geometry.r_p_mm must exceed rail_width/2 + "
          f"clearance + carriage_wall = {_mm(hy)} mm)")
    u, t, v, w = leg_vectors(beta, 0.0)
    Rz = _rot_z(-g_.theta_1p)  # world (leg 1) → carriage frame
    A = Rz @ np.array([g_.d1, g_.d2, 0.0])
    wc = Rz @ w
    Ac = A + s_clevis * wc
    # the clevis must sit outside the block (R1 carried beside the rail, not inside the carriage)
    qx = min(max(Ac[0], x_in), x_out)
    qy = min(max(Ac[1], -hy), hy)
    gap = math.hypot(Ac[0] - qx, Ac[1] - qy)
    _need(gap >= R + g,
          lambda: f"{where}: the R1 clevis at {_mm(math.hypot(Ac[0], Ac[1]))} mm from the z axis lies "
          f"{'inside' if gap == 0 else f'{_mm(gap)} mm from'} the carriage block around the rail "
          f"(allowed ≥ boss radius + clearance = {_mm(R + g)} mm): move the rail (r_p, θ_1p)")
    side = -1.0 if Ac[1] > 0 else 1.0  # SEA housing on the side away from the clevis
    # R1 bracket: clevis arm + root plate let into a block face, both in the clevis layer
    # (carriage_bracket); the block grows in z to carry the whole bonded patch
    bracket = carriage_bracket(design)
    hz = s_.carriage_height / 2
    zc = _box_z_extent(bracket.contact_centre, bracket.contact_axes, bracket.contact_size)
    # the block also spans the clevis plane's height at its nearest point to the clevis ± (W/2 + T), the
    # extent issue 15 released with: a block only as tall as the root lifts the base plate, rails and
    # motors 17 mm for prrr-paper, and the motors then meet link2 of the next leg at the bottom of the
    # φ140 columns (docs/cad.md, "R1 bracket")
    ze = Ac[2] - (wc[0] * (qx - Ac[0]) + wc[1] * (qy - Ac[1])) / wc[2]
    reach = W / 2 + T
    _need(abs(ze) <= 4 * hz + 1e-12,
          lambda: f"geometry.beta_deg = {deg:g}: the clevis plane meets the carriage {_mm(abs(ze))} mm off its centre "
          f"(allowed ≤ 2·structure.carriage_height_mm = {_mm(4 * hz)} mm); raise beta or move the rail ({where})")
    block_z = (min(-hz, ze - reach, zc[0]), max(hz, ze + reach, zc[1]))
    # --- SEA module: spring housing beside the block, ball screw through it, motor beside the housing
    housing_y = tuple(sorted((side * hy, side * (hy + s_.sea_envelope))))
    screw_xy = np.array([g_.r_p, side * (hy + s_.sea_envelope / 2)])
    Rm = m_.motor_diameter / 2
    motor_xy = np.array([g_.r_p + m_.motor_radial_offset, side * (hy + s_.sea_envelope + g + Rm)])
    # --- platform (frame at p): lug centres at radius rho, arms along −v to the stem axis
    lug_rho = (g_.b5 - (s_lug - g_.r4)) * math.cos(beta)
    arm_length = lug_rho / math.sin(beta)
    Rs = s_.stem_diameter / 2
    _need(lug_rho - R * math.sin(beta) - T / 2 * math.cos(beta) >= Rs + MIN_FEATURE,
          lambda: f"geometry.b5_mm = {_mm(g_.b5)} (with beta_deg = {deg:g}): the R3 lugs at radius {_mm(lug_rho)} mm "
          f"run into the stem of structure.stem_diameter_mm = {_mm(2 * Rs)}; raise b5 or reduce the stem/boss")
    _need(arm_length <= 10 * (g_.b5 + g_.r4),
          lambda: f"geometry.beta_deg = {deg:g} is too flat for the platform: arms of {_mm(arm_length)} mm (allowed ≥ "
          f"{math.degrees(math.asin(min(1.0, lug_rho / (10 * (g_.b5 + g_.r4))))):.3g} deg)")
    lug_z = (s_lug - g_.r4) * math.sin(beta)
    stem_bottom = lug_z - lug_rho * math.cos(beta) / math.sin(beta) - T
    lug_top = lug_z + T / 2 * math.sin(beta) + R * math.cos(beta)
    ball_z = lug_top + e_.handle_diameter / 2 + 2e-3
    # --- base and rails from the carriage's lowest/highest point over the stroke
    c_e, half = g_.c_e, g_.stroke / 2
    root_z = _box_z_extent(bracket.root_centre, bracket.root_axes, bracket.root_size)
    carriage_lo = min(block_z[0], root_z[0], Ac[2] - T / 2 * math.sin(beta) - R * math.cos(beta))
    carriage_hi = max(block_z[1], root_z[1], Ac[2] + T / 2 * math.sin(beta) + R * math.cos(beta))
    z_base_top = c_e - half + carriage_lo - s_.base_clearance
    z_rail_top = c_e + half + carriage_hi + s_.base_clearance
    return PrrrLayout(T=T, W=W, R_boss=R, r_bore=r, g=g, s_clevis=s_clevis, s_link2=s_link2, s_lug=s_lug,
                      block_x=(x_in, x_out), block_y=hy, block_z=block_z, slot=half_slot, side=side, clevis=Ac,
                      bracket=bracket, housing_y=housing_y, screw_xy=screw_xy, motor_xy=motor_xy,
                      lug_rho=lug_rho, arm_length=arm_length,
                      stem_bottom=stem_bottom, ball_z=ball_z, z_base_top=z_base_top, z_rail_top=z_rail_top)


#: the eight corners of a unit box about its centre (±½ each axis)
_HALF_CORNERS = np.array([[i, j, k] for i in (-.5, .5) for j in (-.5, .5) for k in (-.5, .5)])
_HALF_CORNERS.setflags(write=False)


def envelope_radius(design: PrrrDesign, *, specs: dict[str, PartSpec] | None = None) -> float:
    """Radius [m] of the fixed parts and the carriages (with their housings) about the z axis,
    from the part tables (``specs``: :func:`part_specs` of ``design``, computed when omitted): the
    carriages only turn about z and slide along it, so their xy extent is the same at every pose.
    Exact for boxes (corners) and vertical cylinders."""
    specs = part_specs(design) if specs is None else specs
    frames = _sliding_frames(design)
    out = 0.0
    rows: dict[Kind, list] = {Kind.BOX: [], Kind.CYLINDER: []}  # (Rf, of, R, o, dims) of each primitive
    for name, spec in specs.items():
        if spec.body != "base" and not spec.body.startswith("carriage_"):
            continue
        Rf, of = frames[name]
        for p in spec.primitives:
            if p.role != Role.SOLID:
                continue
            if p.kind in rows:
                rows[p.kind].append((Rf, of, p.R, p.o, p.dims))
            else:
                o = Rf @ p.o + of
                out = max(out, math.hypot(o[0], o[1]) + p.dims[0])
    # every box and every cylinder at once: the products of the per-primitive matrices (a stacked
    # matmul makes each one's product as the 2-D one does), the extents' maximum over all (exact, in
    # any order; a NaN extent is skipped, as the loop's max(out, ·) skipped it)
    found = [out]
    for kind, prims in rows.items():
        if not prims:
            continue
        Rf, of, Rp, op, dims = (np.array(col, dtype=float) for col in zip(*prims))
        R = Rf @ Rp
        o = (Rf @ op[..., None])[..., 0] + of
        a, b, c = dims[:, 0], dims[:, 1], dims[:, 2]
        if kind == Kind.BOX:
            pts = o[:, None, :] + (_HALF_CORNERS * dims[:, None, :]) @ np.swapaxes(R, -1, -2)
            found.append(np.max(np.hypot(pts[..., 0], pts[..., 1]), axis=1))
        else:
            ends = o[:, None, :] + np.stack([-b / 2, b / 2], axis=1)[:, :, None] * R[:, None, :, 2]
            # rim of a tilted cylinder: bounded by centre radius + a (+ half its axial projection)
            found.append(np.max(np.hypot(ends[..., 0], ends[..., 1]), axis=1) + a)
    return float(np.fmax.reduce(np.concatenate([np.atleast_1d(v) for v in found])))


def _sliding_frames(design: PrrrDesign) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """World rotation (3, 3) and origin (3,) [m] of the parts that do not turn (the base's: base, rails,
    screws, motors; the carriages and their housings) with every slider at 0: :func:`part_frames_arrays`'
    values for those parts at one pose (the same operations on the same numbers), without the links'."""
    eye, zero = np.eye(3), np.zeros(3)
    out = {"base": (eye, zero)}
    theta_1p = np.reshape(np.asarray(design.geometry.theta_1p, dtype=float), (-1, 1))
    for i, gamma in zip(LEGS, GAMMAS):
        a = gamma + theta_1p  # rail_direction(design, gamma)
        ca, sa = float(np.cos(a)[0, 0]), float(np.sin(a)[0, 0])
        carriage = (np.array([[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]]), zero)  # columns u', t', e_z
        out.update({f"rail_{i}": (eye, zero), f"screw_{i}": (eye, zero), f"motor_{i}": (eye, zero),
                    f"carriage_{i}": carriage, f"housing_{i}": carriage})
    return out


def device_height(design: PrrrDesign, *, lay: PrrrLayout | None = None) -> float:
    """Height of the device [m]: base plate bottom to the rail tops or the motor tops, whichever is
    higher (seed 002 Table 1: 231 mm); ``lay``: :func:`layout` of ``design`` when the caller has it."""
    L = layout(design) if lay is None else lay
    top = max(L.z_rail_top, L.z_base_top + design.sea_module.motor_length)
    return top - L.z_base_top + design.structure.base_thickness


# ---------------------------------------------------------------------------- part tables
def _carriage(design: PrrrDesign, L: PrrrLayout) -> list:
    g_ = design.geometry
    I = np.eye(3)
    (x0, x1), hy, (z0, z1) = L.block_x, L.block_y, L.block_z
    prims = [
        box(((x0 + x1) / 2, 0.0, (z0 + z1) / 2), I, x1 - x0, 2 * hy, z1 - z0),
        box((g_.r_p, 0.0, (z0 + z1) / 2), I, 2 * L.slot, 2 * L.slot, z1 - z0, role=Role.HOLE),
    ]
    b = L.bracket
    wc = _rot_z(-g_.theta_1p) @ leg_vectors(g_.beta, 0.0)[3]
    # clevis arm (link section, clevis layer) from the clevis centre to the root's near end face, and
    # the root plate let into the block face: arm and root meet face to face; the root's part inside
    # the block (a wedge) is counted once (OVERLAP)
    arm = bar_with_bosses(frame(b.e_l, wc), b.clevis, 0.0, b.arm_length, width=L.W, thickness=L.T, z=0.0,
                          bosses=(0.0,), boss_radius=L.R_boss, bore_radius=L.r_bore)
    root = box(b.root_centre, b.root_axes, *b.root_size)
    return prims + arm + [root, b.wedge]


def _housing(design: PrrrDesign, L: PrrrLayout) -> list:
    """SEA spring housing (springs, nut, deflection encoder): a box beside the carriage block."""
    (x0, x1), (y0, y1), (z0, z1) = L.block_x, L.housing_y, L.block_z
    return [box(((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2), np.eye(3), x1 - x0, y1 - y0, z1 - z0)]


def _fixed_cylinder(design: PrrrDesign, gamma: float, xy: np.ndarray, radius: float, z0: float, z1: float) -> list:
    """A vertical cylinder at carriage-frame ``xy`` of the leg at ``gamma``, world frame, z0…z1."""
    up, tp = rail_direction(design, gamma)
    c = xy[0] * up + xy[1] * tp + (z0 + z1) / 2 * EZ
    return [cylinder(c, EZ, radius, z1 - z0)]


def _density(mass: float, prims: list) -> float:
    vol = sum(p.dims[0] * p.dims[1] * p.dims[2] if p.kind == Kind.BOX else math.pi * p.dims[0] ** 2 * p.dims[1]
              for p in prims if p.role == Role.SOLID)
    return mass / vol


def _ray_box_entry(o: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    with np.errstate(divide="ignore"):
        t1, t2 = (lo - o) / d, (hi - o) / d
    return float(np.max(np.minimum(t1, t2)))


def _link1(design: PrrrDesign, L: PrrrLayout) -> list:
    d3 = design.geometry.d3
    return bar_with_bosses(np.eye(3), np.zeros(3), 0.0, d3, width=L.W, thickness=L.T, z=0.0, bosses=(0.0, d3),
                           boss_radius=L.R_boss, bore_radius=L.r_bore)


def _link2(design: PrrrDesign, L: PrrrLayout) -> list:
    d4 = design.geometry.d4
    prims = bar_with_bosses(np.eye(3), np.zeros(3), 0.0, d4, width=L.W, thickness=L.T, z=L.s_link2,
                            bosses=(0.0, d4), boss_radius=L.R_boss, bore_radius=L.r_bore)
    top = L.s_link2 + L.T / 2
    riser = L.s_lug - L.T / 2 - L.g - top  # R3 boss raised to meet the platform lug
    if riser > MIN_FEATURE:
        c = np.array([d4, 0.0, top + riser / 2])
        prims += [cylinder(c, EZ, L.R_boss, riser), cylinder(c, EZ, L.r_bore, riser, role=Role.HOLE)]
    return prims


def _platform(design: PrrrDesign, L: PrrrLayout) -> list:
    g_, s_ = design.geometry, design.structure
    prims = []
    Rs = s_.stem_diameter / 2
    for gamma in GAMMAS:
        u, t, v, w = leg_vectors(g_.beta, gamma)
        c = g_.b5 * math.cos(g_.beta) * u + (L.s_lug - g_.r4) * w
        Ra = frame(-v, w)
        # arm from the lug axis to the stem axis, width = stem diameter, analytic up to the stem surface
        prims += bar_with_bosses(Ra, c, 0.0, L.arm_length, width=2 * Rs, thickness=L.T, z=0.0, bosses=(0.0,),
                                 boss_radius=L.R_boss, bore_radius=L.r_bore)
        s_in = (L.lug_rho - Rs) / math.sin(g_.beta)
        prims.append(box(c + (s_in + L.arm_length) / 2 * Ra[:, 0], Ra, L.arm_length - s_in, 2 * Rs, L.T,
                         role=Role.OVERLAP))
    rb = design.end_effector.handle_diameter / 2
    cap = math.sqrt(rb * rb - Rs * Rs)
    h = L.ball_z - L.stem_bottom
    prims.append(cylinder((0.0, 0.0, L.stem_bottom + h / 2), EZ, Rs, h))
    prims.append(cylinder((0.0, 0.0, L.ball_z - cap / 2), EZ, Rs, cap, role=Role.OVERLAP))
    prims.append(sphere((0.0, 0.0, L.ball_z), rb))
    return prims


def _rail(design: PrrrDesign, L: PrrrLayout, gamma: float) -> list:
    rw = design.structure.rail_width
    u, _ = rail_direction(design, gamma)
    h = L.z_rail_top - L.z_base_top
    c = design.geometry.r_p * u + (L.z_base_top + h / 2) * EZ
    return [box(c, frame(u, EZ), rw, rw, h)]


def _base(design: PrrrDesign, L: PrrrLayout) -> list:
    tb = design.structure.base_thickness
    return [cylinder((0.0, 0.0, L.z_base_top - tb / 2), EZ, design.structure.base_radius, tb)]


def part_specs(design: PrrrDesign, *, lay: PrrrLayout | None = None) -> dict[str, PartSpec]:
    """Every part in its own frame (see :func:`part_frames`), SI; ``lay``: :func:`layout` of ``design``
    when the caller has it."""
    L = layout(design) if lay is None else lay
    rho = design.structure.density
    out: dict[str, PartSpec] = {"base": PartSpec(name="base", body="base", density=rho,
                                                 primitives=tuple(_base(design, L)))}
    m_ = design.sea_module
    carriage, link1, link2, housing = (tuple(f(design, L)) for f in (_carriage, _link1, _link2, _housing))
    rho_housing = _density(m_.housing_mass, list(housing))
    for i, gamma in zip(LEGS, GAMMAS):
        out[f"rail_{i}"] = PartSpec(name=f"rail_{i}", body="base", density=rho,
                                    primitives=tuple(_rail(design, L, gamma)))
        screw = _fixed_cylinder(design, gamma, L.screw_xy, m_.screw_diameter / 2, L.z_base_top, L.z_rail_top)
        motor = _fixed_cylinder(design, gamma, L.motor_xy, m_.motor_diameter / 2, L.z_base_top,
                                L.z_base_top + m_.motor_length)
        out[f"screw_{i}"] = PartSpec(name=f"screw_{i}", body="base", density=_density(m_.screw_mass, screw),
                                     primitives=tuple(screw))
        out[f"motor_{i}"] = PartSpec(name=f"motor_{i}", body="base", density=_density(m_.motor_mass, motor),
                                     primitives=tuple(motor))
    for i in LEGS:
        out[f"carriage_{i}"] = PartSpec(name=f"carriage_{i}", body=f"carriage_{i}", density=rho, primitives=carriage)
        out[f"housing_{i}"] = PartSpec(name=f"housing_{i}", body=f"carriage_{i}", density=rho_housing,
                                       primitives=housing)
        out[f"link1_{i}"] = PartSpec(name=f"link1_{i}", body=f"link1_{i}", density=rho, primitives=link1)
        out[f"link2_{i}"] = PartSpec(name=f"link2_{i}", body=f"link2_{i}", density=rho, primitives=link2)
    out["platform"] = PartSpec(name="platform", body="platform", density=rho, primitives=tuple(_platform(design, L)))
    return out


#: parts joined by a joint or rigidly (never reported as colliding with each other)
def neighbours() -> frozenset[frozenset[str]]:
    pairs = set()
    for i in LEGS:
        pairs |= {frozenset(("base", f"rail_{i}")), frozenset((f"rail_{i}", f"carriage_{i}")),
                  frozenset((f"screw_{i}", f"housing_{i}")),  # the screw runs through its nut
                  frozenset((f"carriage_{i}", f"link1_{i}")), frozenset((f"link1_{i}", f"link2_{i}")),
                  frozenset((f"link2_{i}", "platform"))}
        for j in LEGS:
            if j != i:
                pairs.add(frozenset((f"rail_{i}", f"rail_{j}")))
    return frozenset(pairs)


# ---------------------------------------------------------------------------- pose
@dataclass(frozen=True, kw_only=True)
class PrrrPose:
    """A posed configuration: end-effector point, slider positions, joint angles, IK branch."""

    p: np.ndarray  # (3,) [m]
    sliders: np.ndarray  # (3,) [m]
    theta: np.ndarray  # (3 legs, 3) [rad]
    branch: int


#: default elbow branch of the CAD. Branch 0 (θ2 ≥ 0) puts the elbows inwards and down, where
#: the three link2 collide under the platform (2 mm³ each at home, ``analysis.interference``);
#: branch 1 puts them outwards and up, interference-free at home.
DEFAULT_BRANCH = 1


def home_point(design: PrrrDesign) -> np.ndarray:
    """The home pose p = 0 (sliders at c_e, seed 002 eq 1) [m]."""
    return np.zeros(3)


def solve_pose(design: PrrrDesign, p=(0.0, 0.0, 0.0), *, branch: int = DEFAULT_BRANCH) -> PrrrPose:
    """Inverse kinematics at ``p`` [m]; raises :class:`InvalidInput` when p is not reachable."""

    p = np.asarray(p, dtype=float)
    ik = inverse_kinematics(params_of(design), p)
    if not bool(ik.reachable):
        raise InvalidInput(f"pose = ({', '.join(f'{x * 1e3:g}' for x in p)}) mm is not reachable by {design.name}: "
                           f"reach margin {float(ik.reach_margin) * 1e3:.3g} mm (inside the workspace it is ≥ 0)")
    return PrrrPose(p=p, sliders=np.asarray(ik.sliders), theta=np.asarray(ik.theta)[branch], branch=branch)


def part_frames(design: PrrrDesign, pose: PrrrPose) -> dict[str, np.ndarray]:
    """4×4 world transform of every part frame at ``pose`` [m]."""
    posed = part_frames_batch(design, np.asarray(pose.sliders, dtype=float)[None],
                              np.asarray(pose.theta, dtype=float)[None], np.asarray(pose.p, dtype=float)[None])
    return {name: transform(R[0], o[0]) for name, (R, o) in posed.items()}


def part_frames_batch(design: PrrrDesign, sliders: np.ndarray, theta: np.ndarray, p: np.ndarray
                      ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """World rotation (n, 3, 3) and origin (n, 3) [m] of every part for n poses: ``sliders``
    (n, 3) [m], ``theta`` (n, 3 legs, ≥ 2) [rad], end-effector ``p`` (n, 3) [m]. Link frames are
    ``frame(e, w)``: columns e, w × e, w (e ⟂ w by construction)."""
    g_ = design.geometry
    return part_frames_arrays(g_.beta, g_.d1, g_.d2, g_.d3, g_.theta_1p, sliders, theta, p)


def part_frames_arrays(beta, d1, d2, d3, theta_1p, sliders: np.ndarray, theta: np.ndarray, p: np.ndarray
                       ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """:func:`part_frames_batch` with the geometry as arguments [SI]: each of ``beta``, ``d1``,
    ``d2``, ``d3``, ``theta_1p`` a scalar (one design) or an ``(n,)`` array (one design per pose,
    the batched draft evaluator's many designs in one pass)."""
    n = len(p)
    col = [np.reshape(np.asarray(x, dtype=float), (-1, 1)) for x in (beta, d1, d2, d3, theta_1p)]
    beta, d1, d2, d3, theta_1p = col
    sb, cb = np.sin(beta), np.cos(beta)
    ez = np.broadcast_to(EZ, (n, 3))
    eye = np.broadcast_to(np.eye(3), (n, 3, 3))
    zero = np.zeros((n, 3))
    out = {"base": (eye, zero)}
    for k, (i, gamma) in enumerate(zip(LEGS, GAMMAS)):
        c, s = math.cos(gamma), math.sin(gamma)
        # leg_vectors(beta, gamma), one row per pose
        u = np.broadcast_to(np.array([c, s, 0.0]), (n, 3))
        t = np.broadcast_to(np.array([-s, c, 0.0]), (n, 3))
        w = np.broadcast_to(np.concatenate([-cb * c, -cb * s, sb], axis=1), (n, 3))
        v = np.broadcast_to(np.concatenate([sb * c, sb * s, cb], axis=1), (n, 3))
        D = sliders[:, k]
        th1, th2 = theta[:, k, 0], theta[:, k, 1]
        e1 = np.cos(th1)[:, None] * v + np.sin(th1)[:, None] * t
        e12 = np.cos(th1 + th2)[:, None] * v + np.sin(th1 + th2)[:, None] * t
        A = D[:, None] * EZ + d1 * u + d2 * t
        B = A + d3 * e1
        a = gamma + theta_1p  # rail_direction(design, gamma)
        up = np.broadcast_to(np.concatenate([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1), (n, 3))
        tp = np.broadcast_to(np.concatenate([-np.sin(a), np.cos(a), np.zeros_like(a)], axis=1), (n, 3))
        out[f"rail_{i}"] = (eye, zero)
        out[f"screw_{i}"] = (eye, zero)
        out[f"motor_{i}"] = (eye, zero)
        out[f"carriage_{i}"] = (np.stack([up, tp, ez], axis=-1), D[:, None] * EZ)
        out[f"housing_{i}"] = out[f"carriage_{i}"]
        for name, x, org in ((f"link1_{i}", e1, A), (f"link2_{i}", e12, B)):
            out[name] = (np.stack([x, np.cross(w, x), w], axis=2), org)
    out["platform"] = (eye, np.asarray(p, dtype=float))
    return out


def joint_axes(design: PrrrDesign, pose: PrrrPose) -> list[JointAxis]:
    """Joint axes from the kinematics (:func:`hapticopt.design.prrr.kinematics.leg_chain`)."""

    prm = params_of(design)
    pts = leg_chain(prm, pose.sliders, pose.theta)
    W = np.asarray(leg_frames(prm.beta).w)
    out = []
    for k, i in enumerate(LEGS):
        w = W[k]
        out.append(JointAxis(name=f"slider_{i}", parent="base", child=f"carriage_{i}", kind="slide",
                             point=np.array([0.0, 0.0, pose.sliders[k]])
                             + design.geometry.r_p * rail_direction(design, GAMMAS[k])[0], direction=EZ.copy()))
        out.append(JointAxis(name=f"r1_{i}", parent=f"carriage_{i}", child=f"link1_{i}", kind="hinge",
                             point=np.asarray(pts.a[k]), direction=w))
        out.append(JointAxis(name=f"r2_{i}", parent=f"link1_{i}", child=f"link2_{i}", kind="hinge",
                             point=np.asarray(pts.b[k]), direction=w))
        out.append(JointAxis(name=f"r3_{i}", parent=f"link2_{i}", child="platform", kind="hinge",
                             point=np.asarray(pts.q[k]), direction=w))
    return out


# ---------------------------------------------------------------------------- build123d
def build_solid(spec: PartSpec):
    """One part as a build123d solid in its own frame (mm); see :func:`hapticopt.design.parts.build_solid`."""
    return _parts.build_solid(spec)


def build_parts(design: PrrrDesign) -> dict[str, object]:
    """Every part as a build123d solid in its own frame (mm); identical legs are built once."""
    return _parts.build_all(part_specs(design))


def posed(solids: dict[str, object], frames: dict[str, np.ndarray]) -> dict[str, object]:
    """Parts moved to their posed frames (mm), labels kept."""
    return _parts.posed(solids, frames)


def mass_properties(design, *, method: _mp.Method = _mp.Method.ANALYTIC, solids=None,
                    specs: dict[str, PartSpec] | None = None) -> _mp.MassProperties:
    """Mass properties of every part: closed forms (default) or OpenCASCADE's integrals of the solids
    (``specs``: :func:`part_specs` of ``design``, computed when omitted)."""
    specs = part_specs(design) if specs is None else specs
    return _mp.of(design, specs=specs, build_solids=build_parts, method=method, solids=solids)

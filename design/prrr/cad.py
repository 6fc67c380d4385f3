"""Parametric CAD of the 3-PRRR (seed 002): per-design part tables, posed frames, build123d solids.

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

The dimensions, the buildability rules and the primitives are those of
:mod:`hapticopt.design.prrr.layout` (one formulation over a leading design axis); the per-design
objects here are its row for the design, a batch of one. All geometry is SI here; build123d
receives mm through :mod:`design.cad_units`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hapticopt.design import mass_properties as _mp
from hapticopt.design import parts as _parts
from hapticopt.design.errors import InvalidDesign, InvalidInput
from hapticopt.design.parts import JointAxis, Kind, PartSpec, Primitive, Role, transform
from hapticopt.design.prrr import layout as _layout
from hapticopt.design.prrr.kinematics import inverse_kinematics, leg_chain, leg_frames, params_of
from hapticopt.design.prrr.layout import LEGS, MIN_FEATURE
from hapticopt.design.prrr.params import GAMMAS, PrrrDesign

EZ = np.array([0.0, 0.0, 1.0])


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
    wedge: Primitive  # the root's part inside the block (OVERLAP, carriage frame)
    face: str  # "side" (the y face beside the rail, preferred) or "front"/"back" (the x faces)

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

    @classmethod
    def of(cls, b, k: int) -> Bracket:
        """Row ``k`` of the layout's bracket columns ``b`` (:func:`hapticopt.design.prrr.layout.brackets`;
        ``k = ()`` for one design's)."""
        return cls(clevis=b.clevis[k], axis=b.axis[k], normal=np.array(b.normal[k]), e_l=b.e_l[k],
                   arm_length=float(b.arm_length[k]), root_centre=b.root_centre[k], root_axes=b.root_axes[k],
                   root_size=tuple(b.root_size[k].tolist()), contact_centre=b.contact[k],
                   contact_axes=np.stack([b.e_l[k], b.n_p[k]], axis=1), contact_size=tuple(b.contact_size[k].tolist()),
                   wedge=_parts.wedge(b.wedge_o[k], b.wedge_R[k], *b.wedge_dims[k].tolist()),
                   face=_layout.FACES[int(b.face[k])])


@dataclass(frozen=True, kw_only=True)
class PrrrLayout:
    """Derived CAD dimensions of one design [m] (see the module docstring). Carriage-frame
    quantities: x = u' (radial, towards rail i at γ_i + θ_1p), y = t', z = e_z, origin on the
    z axis at the slider height D."""

    T: float  # link thickness (axial)
    r_bore: float
    g: float
    s_link2: float
    s_lug: float  # platform lug centre
    block_x: tuple[float, float]  # carriage block, carriage frame
    block_y: float  # half width
    block_z: tuple[float, float]
    slot: float  # half size of the rail slot
    side: float  # +1 / −1: the side (sign of y) of the SEA housing, screw and motor; the clevis is on −side
    bracket: Bracket  # the R1 bracket (carriage frame)
    ball_z: float
    z_base_top: float
    z_rail_top: float
    height: float  # the device height (:func:`device_height`)
    rows: _layout.Layouts = field(repr=False)  # the layout of the design alone, all its columns (its part tables)


def layout(design: PrrrDesign) -> PrrrLayout:
    """Derived dimensions, after the buildability rules; raises :class:`InvalidDesign` naming
    the parameter when a part would be degenerate (zero-thickness wall, disconnected bracket…)."""
    L = _layout.layouts(design)
    err = L.error(())
    if err is not None:
        raise err
    one = {k: float(getattr(L, k)) for k in ("T", "r_bore", "g", "s_link2", "s_lug", "block_y", "slot", "side", "ball_z",
                                                 "z_base_top", "z_rail_top", "height")}
    return PrrrLayout(**one, block_x=tuple(map(float, L.block_x)), block_z=tuple(map(float, L.block_z)),
                      bracket=Bracket.of(L.bracket, ()), rows=L)


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
    b = _layout.brackets(design, checked=checked)
    if not b.ok:
        raise InvalidDesign(b.message(()))
    return Bracket.of(b, ())


def carried_theta_1p(design: PrrrDesign, *, side: float = 1.0) -> float:
    """θ_1p [rad] that puts the R1 clevis directly on the carriage (seed 002's device carries R1
    on the carriage, beside the rail): the clevis boss touches the carriage block's side face
    (tangential distance from the rail axis = block half width + boss radius + clearance), the
    SEA housing on the other side (``side`` = +1: housing at +t', clevis at −t'). Depends only on
    the geometry and part sizes, not on the current θ_1p."""
    g_, s_ = design.geometry, design.structure
    # the clevis centre Ac = A − (T + g)·w of leg 1 (γ = 0, w = (−cos β, 0, sin β)) at D = 0, world frame
    Ac = (g_.d1 + (s_.link_thickness + s_.clearance) * math.cos(g_.beta), g_.d2)
    rho = math.hypot(Ac[0], Ac[1])
    hy = s_.rail_width / 2 + s_.clearance + s_.carriage_wall
    off = hy + s_.boss_diameter / 2 + s_.clearance
    if not off < rho:
        raise InvalidDesign(f"geometry.r_p_mm / theta_1p_deg: the carriage ({2 * hy * 1e3:g} mm wide) cannot carry "
                            f"the R1 clevis at {rho * 1e3:g} mm from the z axis")
    return math.atan2(Ac[1], Ac[0]) + side * math.asin(off / rho)


#: the eight corners of a unit box about its centre (±½ each axis)
_HALF_CORNERS = np.array([[i, j, k] for i in (-.5, .5) for j in (-.5, .5) for k in (-.5, .5)])
_HALF_CORNERS.setflags(write=False)


def envelope_radius(design: PrrrDesign, *, specs: dict[str, PartSpec] | None = None) -> float:
    """Radius [m] of the fixed parts and the carriages (with their housings) about the z axis,
    from the part tables (``specs``: :func:`part_specs` of ``design``, computed when omitted): the
    carriages only turn about z and slide along it, so their xy extent is the same at every pose.
    Exact for boxes (corners) and vertical cylinders."""
    specs = part_specs(design) if specs is None else specs
    frames = {name: (R[0], o[0]) for name, (R, o) in part_frames_batch(design, np.zeros((1, 3)), np.zeros((1, 3, 2)),
                                                                      np.zeros((1, 3))).items()}
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
        a, b = dims[:, 0], dims[:, 1]
        if kind == Kind.BOX:
            pts = o[:, None, :] + (_HALF_CORNERS * dims[:, None, :]) @ np.swapaxes(R, -1, -2)
            found.append(np.max(np.hypot(pts[..., 0], pts[..., 1]), axis=1))
        else:
            ends = o[:, None, :] + np.stack([-b / 2, b / 2], axis=1)[:, :, None] * R[:, None, :, 2]
            # rim of a tilted cylinder: bounded by centre radius + a (+ half its axial projection)
            found.append(np.max(np.hypot(ends[..., 0], ends[..., 1]), axis=1) + a)
    return float(np.fmax.reduce(np.concatenate([np.atleast_1d(v) for v in found])))


def device_height(design: PrrrDesign, *, lay: PrrrLayout | None = None) -> float:
    """Height of the device [m]: base plate bottom to the rail tops or the motor tops, whichever is
    higher (seed 002 Table 1: 231 mm); ``lay``: :func:`layout` of ``design`` when the caller has it."""
    return (layout(design) if lay is None else lay).height


def part_specs(design: PrrrDesign, *, lay: PrrrLayout | None = None) -> dict[str, PartSpec]:
    """Every part in its own frame (see :func:`part_frames`), SI: the layout's primitive tables
    (:mod:`hapticopt.design.prrr.layout`) of ``design``; the parts of the three legs that are the
    same in each leg's frame share one primitive tuple (built and integrated once). ``lay``:
    :func:`layout` of ``design`` when the caller has it."""
    L = (layout(design) if lay is None else lay).rows
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        tab = _layout._tables(L)
        o, R, dims = tab.values()
    dims = dims.tolist()
    riser = bool(L.riser > MIN_FEATURE)
    prims: dict[int, list] = {}
    for j, (p, kind, role, *_, riser_only) in enumerate(tab.prims):
        if riser or not riser_only:
            prims.setdefault(p, []).append(Primitive(kind=kind, role=role, o=o[j], R=R[j], dims=tuple(dims[j])))
    shared: dict[int, tuple] = {}
    out = {}
    for k, (name, body, density, same) in enumerate(tab.parts):
        src = k if same is None else same
        if src not in shared:
            shared[src] = tuple(prims.get(src, ()))
        made = float(density) == design.structure.density  # the parts of the mechanism's material
        out[name] = PartSpec(name=name, body=body, density=float(density), primitives=shared[src],
                             material=design.structure.material if made else "")
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
        # the leg's vectors (hapticopt.design.prrr.layout.leg_vectors), one row per pose
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
        a = gamma + theta_1p  # the rail's radial direction u' at γ + θ_1p
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
        a = GAMMAS[k] + design.geometry.theta_1p  # the rail's radial direction u' at γ + θ_1p
        out.append(JointAxis(name=f"slider_{i}", parent="base", child=f"carriage_{i}", kind="slide",
                             point=np.array([0.0, 0.0, pose.sliders[k]])
                             + design.geometry.r_p * np.array([math.cos(a), math.sin(a), 0.0]), direction=EZ.copy()))
        out.append(JointAxis(name=f"r1_{i}", parent=f"carriage_{i}", child=f"link1_{i}", kind="hinge",
                             point=np.asarray(pts.a[k]), direction=w))
        out.append(JointAxis(name=f"r2_{i}", parent=f"link1_{i}", child=f"link2_{i}", kind="hinge",
                             point=np.asarray(pts.b[k]), direction=w))
        out.append(JointAxis(name=f"r3_{i}", parent=f"link2_{i}", child="platform", kind="hinge",
                             point=np.asarray(pts.q[k]), direction=w))
    return out


# ---------------------------------------------------------------------------- build123d
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

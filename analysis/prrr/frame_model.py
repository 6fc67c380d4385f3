"""3-D Timoshenko frame model of the 3-PRRR's closed-loop structure (float64; numpy or jax).

One core, :func:`frame_arrays`, written against an array module ``xp``: :func:`solve_frame` runs
it with numpy for a single design (no compilation: the CLI path, ~4 ms), :func:`solve_frame_jax`
and :func:`solve_frame_batch` with ``jax.numpy`` under jit/vmap (batches, gradients); tested equal.
The jax path assembles each leg's stiffness on the columns where each element's map can be nonzero
(:func:`_supports`, a static pattern of the topology), not on dense 12 × n maps; the batch's inputs
come from :func:`frame_params_many` (arrays over the batch). The batched draft evaluator computes the
frame outside XLA: in a batch padded to :data:`KERNEL_AFTER_DESIGNS` or more (:func:`legs_kernel_ready`), :func:`condense_home_many` takes
the legs' points at the home pose over the batch in numpy (:func:`home_legs_many`) and a numba kernel builds
each leg's elements, springs and maps, assembles and condenses it; before that it jits only the legs'
unassembled terms (:func:`frame_leg_terms`) and assembles and condenses them over designs
(:func:`condense_terms_many`: Cholesky along each leg's chain of DOFs). Both equal to the single path to
1e-9 (docs/runs.md "The frame group outside XLA", docs/performance.md).

Each link is a 12-DOF Timoshenko beam (axial, torsion, two bending planes with shear) of the
rectangular cross-section in ``design.structure``; the three revolute joints of every leg
release the rotation about their axis w_i; the sliders are locked (optionally with the SEA
spring in series along z). The model is assembled at any pose from the leg points of
:func:`hapticopt.design.prrr.kinematics.leg_chain`, condensed onto the end-effector node and turned
into the Cartesian stiffness for a load applied Δz above the end-effector.

Structure of one leg i (points in the seed-digest leg construction; S is the rail point):

    S = D_i e_z + r_p (cos θ_1p u_i + sin θ_1p t_i)  (slider carriage on the rail; clamped, or sliding in z on the SEA spring)
    S → A      carriage arm (d1/d2 offset)              beam, or rigid (``Offsets.RIGID``); with pins (default)
               the carriage as the CAD builds it (``design.prrr.cad.carriage_bracket``): block rigid
               on its rail slot, the bracket's root plate let into a block face (C), root beam C → J,
               the clevis arm bonded on the root's end face (E) and running E → Ac in the clevis
               layer; both bonds two half-spaces (:func:`bond_stiffness`), see :func:`bracket_frame`
    A   R1     hinge about w_i
    A → B      link d3                                   beam
    B   R2     hinge about w_i
    B → B'     link d4 (in-plane part), B' = Q − r4 w_i  beam
    B' → Q     r4 offset along the joint axis            beam, or rigid
    Q   R3     hinge about w_i
    Q → P      platform arm, Q − P = b5 cos β u_i        beam, or rigid
    P          end-effector node (shared by the three legs); the handle P → P + Δz e_z is rigid

Joint zones (``FrameOptions.joint_zones``, default on): the beam ends within the joint boss radius
(``structure.boss_diameter / 2``) of a joint axis point (A, B, Q) or of the end-effector hub P
are rigid (clipped to 40 % of a beam's length); the rail end S and the d4/r4 corner B' have none.
Without them the node-to-node beams ignore the bosses and the overlap of the links at the joints,
and the bonded frame came out ~30 % softer than the solid FEA (docs/structure.md).

Pin joints (``FrameOptions.pins``, default on): the members sit in their CAD layers along w
(``hapticopt.design.prrr.cad.layout``: carriage clevis, link1, link2, platform lug, pitch λ = link thickness
+ clearance) and each revolute joint is the bonded pin across the clearance gap between two
layers. ``PinModel.NECK`` (default): the bosses are rigid up to the gap mid-plane and the joint is
a spring there: two half-spaces loaded through the pin's circular section (Gazetas 1991) in series
with the short neck (:func:`neck_stiffness`); the hinge release is at the pin's link-side end.
Not tuned: it lands within 8 % of the CAD solid FEA per axis (docs/structure.md), where the plane
frame without pins (``pins=False``: all members in one plane, joints only rigid zones) is 95–155 %
stiffer and ``PinModel.BEAM`` (a free pin beam over the whole pitch λ, an upper bound on the
joint's compliance) 46 % softer. See :func:`_leg_stiffness_pins`.

Cross-section orientation: the width b (``link_width``) lies in the plane normal to the joint
axis, the thickness t (``link_thickness``) along the joint axis (local z = w projected normal to
the beam); for the r4 segment, which runs along w, the width continues the d4 link's direction.
Every beam (including the offsets when they are beams) has the link section. Torsion constant
of the rectangle: Roark's J = b t³[1/3 − 0.21 (t/b)(1 − t⁴/12b⁴)] (b ≥ t); shear coefficient of
the rectangle: Cowper's κ = 10(1+ν)/(12+11ν).

Joints are exact kinematic releases, not penalty springs: the link side of a hinge carries the
DOFs of its master node plus one hinge rotation φ about w (θ_link = θ_master + φ w); rigid
offsets are rigid-body maps (u_s = u_m + θ_m × r). Every node's six DOFs are a linear map G
(6 × N) of the N free DOFs, and K = Σ_e G_eᵀ K_e G_e.

Outputs (SI): 6×6 compliance at P, the 3×3 compliance and the per-axis stiffness
k_i = 1 / C_ii (force along axis i, displacement along i) at the load point P + Δz e_z, the
elastic centre (the height h above P that least-squares decouples rotation from a lateral
force, equivalently where the lateral compliance is smallest), the stiffness there, and a
1-norm condition number of the Jacobi-scaled stiffness matrix.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from enum import StrEnum
from typing import NamedTuple

import jax
import jax.numpy as jnp
import jax.scipy.linalg
import numpy as np

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis import compute
from hapticopt.design.errors import InvalidDesign
from hapticopt.design.prrr import layout as prrr_layout
from hapticopt.design.prrr.cad import carriage_bracket
from hapticopt.design.prrr.kinematics import PrrrParams, inverse_kinematics, leg_chain, leg_frames, params_np

#: Above this 1-norm condition number (Jacobi-scaled K) a result is reported as ill-conditioned.
COND_LIMIT = 1e12
#: At or above this condition number the matrix is numerically singular (1/eps ≈ 4.5e15 in float64;
#: three decades above COND_LIMIT, so a rounding-level change of the estimate never flips the verdict).
SINGULAR_COND = 1e15
#: At or above this cancellation on the condensed stiffness's diagonal (Σ_legs |K_PP,aa| + |(K_Pi K_ii⁻¹ K_iP)_aa|
#: over |K_P,aa|, largest over a) :func:`condense_many` returns NaN (digits left ≈ 16 − log10 of it).
#: Measured (home pose, draft batch, 512 designs in the bundled problem's bounds and the batch test's
#: sample): 10^4.2–10^5.5 for every design the single path solves; 10^16.7 at β = 89.999999° (singular).
CANCELLATION_LIMIT = 1e8
#: Default load height above the end-effector [m] (seed 002 Table 3: Δz = 58 mm).
LOAD_HEIGHT = 0.058
_EZ = np.array([0.0, 0.0, 1.0])


class Joints(StrEnum):
    """How the revolute joints are modelled."""

    RELEASED = "released"  # rotation about the joint axis free (the mechanism)
    BONDED = "bonded"  # pins bonded: the joint transmits all six components (for FEA comparison)


class PinModel(StrEnum):
    """How a pin joint between two layered members deforms (``FrameOptions(pins=True)``)."""

    NECK = "neck"  # bosses rigid; the bonded pin's neck across the gap: half-space constriction springs
    BEAM = "beam"  # a Timoshenko pin beam bending freely over the whole layer pitch (an upper bound)


class Offsets(StrEnum):
    """How the carriage arm, the r4 offset and the platform arms are modelled."""

    BEAM = "beam"  # beams of the link cross-section
    RIGID = "rigid"  # rigid links


@dataclass(frozen=True, kw_only=True)
class FrameOptions:
    """Static modelling choices (they change the topology, so they are jit-static)."""

    joints: Joints = Joints.RELEASED
    offsets: Offsets = Offsets.BEAM
    sea: bool = False  # SEA springs in series along z between slider and rail (else locked)
    branch: int = 0  # elbow branch of the IK: 0 (θ2 ≥ 0) or 1 (θ2 ≤ 0)
    joint_zones: bool = True  # beam ends within the boss radius of a joint (A, B, Q) or of P are rigid
    pins: bool = True  # CAD layering: members in their layers along w, joined through pins of the bore
    pin_model: PinModel = PinModel.NECK  # with pins: constriction springs at the gap, or free pin beams


class Section(NamedTuple):
    """Rectangular cross-section and isotropic material [SI]; scalars or a batch (n,)."""

    width: jax.Array  # in-plane width b [m]
    thickness: jax.Array  # thickness t along the joint axis [m]
    youngs_modulus: jax.Array  # E [Pa]
    poisson_ratio: jax.Array  # ν [-]


class FrameParams(NamedTuple):
    """Everything the frame model reads from a design [SI] (a jax pytree, batchable)."""

    kin: PrrrParams
    r_p: jax.Array  # rail radius [m]
    theta_1p: jax.Array  # rail angle from u_i about z [rad] (seed 002 θ_1p)
    section: Section
    spring: jax.Array  # SEA spring k [N/m] (used with ``FrameOptions(sea=True)``)
    joint_zone: jax.Array  # radius of the rigid joint zone (the joint boss) [m]
    pin_diameter: jax.Array  # pin (bore) diameter [m] (``FrameOptions(pins=True)``)
    layer: jax.Array  # layer pitch along the joint axis, link thickness + clearance [m]
    lug_offset: jax.Array  # platform lug layer above the kinematic R3 point along w, s_lug − r4 [m]
    stem_radius: jax.Array  # platform stem radius; the platform arms are stem_diameter wide [m]
    bracket_points: jax.Array  # (3, 3) C, J, E of the R1 bracket, carriage frame (x = u', y = t', z) [m] (bracket_frame)
    root_zref: jax.Array  # (3,) thickness direction (±w) of the bracket's root beam, carriage frame
    root_section: jax.Array  # (2,) root beam width (along the arm e_l) and thickness (along w) [m]
    bracket_bonds: jax.Array  # (2, 6, 6) root-on-block and arm-on-root bond stiffness, carriage frame, [u; θ] [SI]


def frame_params_of(design, xp=jnp) -> FrameParams:
    """Frame-model parameters of one :class:`hapticopt.design.prrr.params.PrrrDesign` (``xp=np``: numpy arrays)."""
    s = design.structure
    g = design.geometry
    kin = PrrrParams(*(xp.asarray(x) for x in params_np(design)))
    sec = Section(*(xp.asarray(float(x)) for x in (s.link_width, s.link_thickness, s.youngs_modulus, s.poisson_ratio)))
    layer = float(s.link_thickness) + float(s.clearance)  # hapticopt.design.prrr.cad.layout: s_link2 = T + g
    s_lug = max(float(g.r4), 2.0 * layer)  # hapticopt.design.prrr.cad.layout: s_lug = max(r4, 2T + 2g)
    return FrameParams(kin=kin, r_p=xp.asarray(float(g.r_p)), theta_1p=xp.asarray(float(g.theta_1p)), section=sec,
                       spring=xp.asarray(float(design.actuator.spring)),
                       joint_zone=xp.asarray(0.5 * float(s.boss_diameter)),
                       pin_diameter=xp.asarray(float(s.bore_diameter)), layer=xp.asarray(layer),
                       lug_offset=xp.asarray(s_lug - float(g.r4)),
                       stem_radius=xp.asarray(0.5 * float(s.stem_diameter)),
                       **{k: xp.asarray(v) for k, v in bracket_frame(design).items()})


def bracket_frame(design) -> dict[str, np.ndarray]:
    """The carriage's R1 bracket as the frame carries it, carriage frame [SI] (numpy).

    From :func:`hapticopt.design.prrr.cad.carriage_bracket` (the CAD's one formula; unchecked, so a
    design whose bracket the CAD refuses still gets a frame, as its links do): the block is
    rigid (clamped on its rail slot); the root plate (clevis layer) is let into a block face and
    bonded over its section in the face plane (centre C, a rectangle contact_size[0] along e_l ×
    contact_size[1] along n_p); the root is a beam of its own section (width along e_l, thickness
    T along w) from C along the plate (−e_f) to J, the point of that line level with the clevis arm
    (J → E rigid inside the root); the clevis arm (link section) is bonded over its whole W × T end
    section at E on the root's end face and runs E → Ac in the clevis layer. Each bond is
    :func:`bond_stiffness` of its patch (two half-spaces, as the pin necks).

    Returns ``bracket_points`` (3, 3) = C, J, E; ``root_zref`` (3,) = the root's thickness direction
    (±w); ``root_section`` (2,) = (width along e_l, thickness T); ``bracket_bonds`` (2, 6, 6) = root
    on block, arm on root.
    """
    s_ = design.structure
    b = _bracket_of(design)
    e_l, _, e_n = b.root_axes.T
    lr, _, tr = b.root_size
    N, n_p = b.normal, b.contact_axes[:, 1]
    lc, wc_ = b.contact_size
    E_, nu = float(s_.youngs_modulus), float(s_.poisson_ratio)
    k_root = bond_stiffness(lc * wc_, (lc * wc_**3 / 12.0, wc_ * lc**3 / 12.0), lc * wc_ * (lc**2 + wc_**2) / 12.0,
                            (N, e_l, n_p), E_, nu)  # I about e_l: distances along n_p
    W, T = float(s_.link_width), float(s_.link_thickness)
    w = b.axis
    e_m = np.cross(w, e_l)
    k_arm = bond_stiffness(W * T, (W * T**3 / 12.0, T * W**3 / 12.0), W * T * (W**2 + T**2) / 12.0,
                           (e_l, e_m, w), E_, nu)  # I about e_m: distances along w
    return {"bracket_points": np.stack([b.contact_centre, b.root_joint, b.arm_end]), "root_zref": e_n,
            "root_section": np.array([lr, tr]), "bracket_bonds": np.stack([k_root, k_arm])}


def bond_stiffness(area: float, moments: tuple[float, float], polar: float, axes, E: float, nu: float) -> np.ndarray:
    """6×6 stiffness [SI] of two elastic half-spaces bonded over a flat patch, in the axes given.

    ``axes`` = (normal n, e_1, e_2) (unit, orthogonal), ``moments`` = (I_1, I_2) the patch's
    second moments about e_1 and e_2 through its centroid, ``polar`` = J = I_1 + I_2, ``area`` = A.
    The pin neck's construction (:func:`neck_stiffness`) with zero gap: each side an elastic
    half-space loaded through a rigid disc (Gazetas 1991, Table 1) — K_z = 2Ea/(1−ν²) along n,
    K_h = 8Ga/(2−ν) across it with a = √(A/π); rocking K_r = 4Ea³/(3(1−ν²)) about e_k with
    a⁴ = 4I_k/π; torsion K_t = 16Ga³/3 with a⁴ = 2J/π — the two sides in series (halved).
    A circular patch gives exactly ``neck_stiffness(d, 0)`` (tested).
    """
    G = E / (2.0 * (1.0 + nu))
    (i1, i2), j = moments, polar
    a_t = np.sqrt(area / np.pi)
    a1, a2 = (4.0 * i1 / np.pi) ** 0.25, (4.0 * i2 / np.pi) ** 0.25
    a_j = (2.0 * j / np.pi) ** 0.25
    k_r1, k_r2 = (4.0 * E * a**3 / (3.0 * (1.0 - nu**2)) for a in (a1, a2))
    n, e1, e2 = (np.asarray(x, dtype=float) for x in axes)
    kt = 8.0 * G * a_t / (2.0 - nu) * (np.eye(3) - np.outer(n, n)) + 2.0 * E * a_t / (1.0 - nu**2) * np.outer(n, n)
    kr = k_r1 * np.outer(e1, e1) + k_r2 * np.outer(e2, e2) + 16.0 * G * a_j**3 / 3.0 * np.outer(n, n)
    return 0.5 * np.block([[kt, np.zeros((3, 3))], [np.zeros((3, 3)), kr]])


def frame_params_many(designs) -> FrameParams:
    """:func:`frame_params_of` (``xp=np``) of many designs stacked along a leading batch axis (numpy):
    the scalar fields, the carriage's brackets (:func:`_brackets_many`: the array form of
    :func:`hapticopt.design.prrr.cad.carriage_bracket`, per design only where that form leaves a design
    out) and their bond stiffnesses as arrays over the batch. Equal to stacking :func:`frame_params_of`
    (tested: the scalar fields bitwise, the bracket's fields to 1e-12 of their largest entry)."""
    g = [d.geometry for d in designs]
    s = [d.structure for d in designs]

    def col(objs, name):
        return np.array([float(getattr(o, name)) for o in objs])

    kin = PrrrParams(*(col(g, f) for f in ("beta", "d1", "d2", "d3", "d4", "r4", "b5", "stroke")))
    sec = Section(*(col(s, f) for f in ("link_width", "link_thickness", "youngs_modulus", "poisson_ratio")))
    layer = sec.thickness + col(s, "clearance")  # hapticopt.design.prrr.cad.layout: s_link2 = T + g
    s_lug = np.maximum(kin.r4, 2.0 * layer)  # hapticopt.design.prrr.cad.layout: s_lug = max(r4, 2T + 2g)
    br = _brackets_many(designs, sec)
    return FrameParams(kin=kin, r_p=col(g, "r_p"), theta_1p=col(g, "theta_1p"), section=sec,
                       spring=np.array([float(d.actuator.spring) for d in designs]),
                       joint_zone=0.5 * col(s, "boss_diameter"), pin_diameter=col(s, "bore_diameter"), layer=layer,
                       lug_offset=s_lug - kin.r4, stem_radius=0.5 * col(s, "stem_diameter"), **br)


def _brackets_many(designs, sec: Section) -> dict[str, np.ndarray]:
    """:func:`bracket_frame` of many designs (leading batch axis): the brackets over the batch
    (:func:`hapticopt.design.prrr.layout.brackets_many`, the array form of
    :func:`hapticopt.design.prrr.cad.carriage_bracket`, from :data:`BRACKET_ARRAYS_FROM` designs on; its
    ``rest``, the designs no face carries or near a rule's threshold or branch point, and the designs of a
    smaller batch by the per-design function, as :func:`bracket_frame`), the bonds' :func:`bond_stiffness`
    over the batch (:func:`_bond_stiffness_many`)."""
    if len(designs) < BRACKET_ARRAYS_FROM:
        each = [_bracket_fields(_bracket_of(d)) for d in designs]
        b = {k: np.array([f[k] for f in each], dtype=float) for k in each[0]}
    else:
        b, rest = prrr_layout.brackets_many(designs)
        for i in rest:
            for k, v in _bracket_fields(_bracket_of(designs[i])).items():
                b[k][i] = v
    Ac, e_l, e_f, arm_length = b["clevis"], b["root_axes"][:, :, 0], b["root_axes"][:, :, 1], b["arm_length"]
    contact = b["contact"]
    # cad.Bracket.root_joint and .arm_end over the batch
    root_joint = contact - np.sum((contact - Ac) * e_f, axis=-1)[:, None] * e_f
    pts = np.stack([contact, root_joint, Ac + arm_length[:, None] * e_l], axis=1)
    zref, size = b["root_axes"][:, :, 2], b["root_size"][:, [0, 2]]
    N, n_p, w = b["normal"], b["n_p"], b["axis"]
    lc, wc = b["contact_size"][:, 0], b["contact_size"][:, 1]
    E_, nu = sec.youngs_modulus, sec.poisson_ratio
    k_root = _bond_stiffness_many(lc * wc, (lc * wc**3 / 12.0, wc * lc**3 / 12.0), lc * wc * (lc**2 + wc**2) / 12.0,
                                  (N, e_l, n_p), E_, nu)
    W, T = sec.width, sec.thickness
    e_m = _cross(w, e_l, np)
    k_arm = _bond_stiffness_many(W * T, (W * T**3 / 12.0, T * W**3 / 12.0), W * T * (W**2 + T**2) / 12.0,
                                 (e_l, e_m, w), E_, nu)
    return {"bracket_points": pts, "root_zref": np.ascontiguousarray(zref), "root_section": np.ascontiguousarray(size),
            "bracket_bonds": np.stack([k_root, k_arm], axis=1)}


#: :func:`frame_params_many` takes the brackets from their array form from this many designs on (per
#: design below). Measured side by side (frame_params_many, medians of 30, load 3.0): 1 design 0.79 ms
#: arrays vs 0.25 per design; 4: 0.76 vs 0.49; 8: 0.83 vs 0.87; 16: 1.00 vs 1.60; 64: 1.30 vs 10.5.
BRACKET_ARRAYS_FROM = 8


def _bracket_of(design):
    """:func:`bracket_frame`'s bracket: :func:`hapticopt.design.prrr.cad.carriage_bracket`, unchecked where
    the CAD refuses it."""
    try:
        return carriage_bracket(design)
    except InvalidDesign:
        return carriage_bracket(design, checked=False)


def _bracket_fields(b) -> dict:
    """The fields of :func:`hapticopt.design.prrr.layout.brackets_many` of one :class:`cad.Bracket`."""
    return dict(clevis=b.clevis, axis=b.axis, normal=b.normal, e_l=b.e_l, arm_length=b.arm_length,
                root_axes=b.root_axes, root_size=b.root_size, contact=b.contact_centre, n_p=b.contact_axes[:, 1],
                contact_size=b.contact_size)


def _bond_stiffness_many(area, moments, polar, axes, E, nu) -> np.ndarray:
    """:func:`bond_stiffness` over a batch: every scalar (n,), every axis (n, 3); (n, 6, 6)."""
    G = E / (2.0 * (1.0 + nu))
    (i1, i2), j = moments, polar
    a_t = np.sqrt(area / np.pi)
    a1, a2 = (4.0 * i1 / np.pi) ** 0.25, (4.0 * i2 / np.pi) ** 0.25
    a_j = (2.0 * j / np.pi) ** 0.25
    k_r1, k_r2 = (4.0 * E * a**3 / (3.0 * (1.0 - nu**2)) for a in (a1, a2))
    n, e1, e2 = axes

    def outer(a, b):
        return a[:, :, None] * b[:, None, :]

    def c(x):
        return x[:, None, None]

    nn = outer(n, n)
    kt = c(8.0 * G * a_t / (2.0 - nu)) * (np.eye(3) - nn) + c(2.0 * E * a_t / (1.0 - nu**2)) * nn
    kr = c(k_r1) * outer(e1, e1) + c(k_r2) * outer(e2, e2) + c(16.0 * G * a_j**3 / 3.0) * nn
    out = np.zeros((len(area), 6, 6))
    out[:, :3, :3], out[:, 3:, 3:] = 0.5 * kt, 0.5 * kr
    return out


def stack_frame_params(designs) -> FrameParams:
    """Parameters of many designs stacked along a leading batch axis (jax arrays of
    :func:`frame_params_many`)."""
    return jax.tree.map(jnp.asarray, frame_params_many(designs))


# ----------------------------------------------------------------------------- beam element
class SectionProperties(NamedTuple):
    area: jax.Array  # A [m²]
    i_y: jax.Array  # second moment about local y (bending in the local xz plane) [m⁴]
    i_z: jax.Array  # second moment about local z (bending in the local xy plane) [m⁴]
    torsion: jax.Array  # Saint-Venant torsion constant J [m⁴]
    shear_coefficient: jax.Array  # κ [-]
    shear_modulus: jax.Array  # G [Pa]


def section_properties(section: Section, xp=jnp) -> SectionProperties:
    """Rectangle of width b (local y) and thickness t (local z)."""
    b, t, E, nu = section
    lo, hi = xp.minimum(b, t), xp.maximum(b, t)
    r = lo / hi
    torsion = hi * lo**3 * (1.0 / 3.0 - 0.21 * r * (1.0 - r**4 / 12.0))  # Roark, Table 10.7 case 4
    return SectionProperties(
        area=b * t,
        i_y=b * t**3 / 12.0,
        i_z=t * b**3 / 12.0,
        torsion=torsion,
        shear_coefficient=10.0 * (1.0 + nu) / (12.0 + 11.0 * nu),  # Cowper (1966), rectangle
        shear_modulus=E / (2.0 * (1.0 + nu)),
    )


def circle_properties(diameter: jax.Array, E: jax.Array, nu: jax.Array, xp=jnp) -> SectionProperties:
    """Solid circle (the pins): A = πd²/4, I = πd⁴/64, J = πd⁴/32, Cowper's κ = 6(1+ν)/(7+6ν)."""
    i = np.pi * diameter**4 / 64.0
    return SectionProperties(area=np.pi * diameter**2 / 4.0, i_y=i, i_z=i, torsion=2.0 * i,
                             shear_coefficient=6.0 * (1.0 + nu) / (7.0 + 6.0 * nu),  # Cowper (1966), circle
                             shear_modulus=E / (2.0 * (1.0 + nu)))


def neck_stiffness(diameter: jax.Array, gap: jax.Array, E: jax.Array, nu: jax.Array, xp=jnp) -> jax.Array:
    """Stiffness of a bonded pin joint across its clearance gap: (axial, lateral, rocking, torsion).

    Two solid bosses (pin bonded in its bore: one material) joined by the pin's neck of radius
    a = d/2 across the gap g. Each boss is an elastic half-space loaded through a rigid circular
    disc of radius a (Gazetas 1991, Table 1, surface foundation; Johnson, Contact Mechanics §3.x):
    K_z = 2Ea/(1−ν²), K_h = 8Ga/(2−ν), K_r = 4Ea³/(3(1−ν²)), K_t = 16Ga³/3; the two bosses in
    series halve each. The neck itself (a Timoshenko stub of length g, ends held parallel) adds
    g/EA, g³/12EI + g/κGA, g/EI, g/GJ in series. Units: N/m for forces, N·m/rad for moments.
    """
    a = 0.5 * diameter
    G = E / (2.0 * (1.0 + nu))
    p = circle_properties(diameter, E, nu, xp)
    half = xp.stack([2.0 * E * a / (1.0 - nu**2), 8.0 * G * a / (2.0 - nu),
                     4.0 * E * a**3 / (3.0 * (1.0 - nu**2)), 16.0 * G * a**3 / 3.0])
    stub = xp.stack([gap / (E * p.area), gap**3 / (12.0 * E * p.i_y) + gap / (p.shear_coefficient * G * p.area),
                     gap / (E * p.i_y), gap / (G * p.torsion)])
    return 1.0 / (2.0 / half + stub)


def _neck_matrix(w: jax.Array, k: jax.Array, xp=jnp) -> jax.Array:
    """6×6 global stiffness of an axisymmetric joint about axis w with k = (axial, lateral, rocking, torsion)."""
    ww = w[:, None] * w[None, :]
    eye = xp.eye(3)
    kt = k[1] * (eye - ww) + k[0] * ww
    kr = k[2] * (eye - ww) + k[3] * ww
    return _blockdiag2(kt, kr, xp)


def _bending_patterns(idx: tuple[int, int, int, int], sign: float) -> np.ndarray:
    """Constant 12×12 patterns of one bending plane: coefficients of 12, ±6L, (4+Φ)L², (2−Φ)L²."""
    m12 = np.array([[1, 0, -1, 0], [0, 0, 0, 0], [-1, 0, 1, 0], [0, 0, 0, 0]], float)
    ms = sign * np.array([[0, 1, 0, 1], [1, 0, -1, 0], [0, -1, 0, -1], [1, 0, -1, 0]], float)
    ma = np.array([[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]], float)
    mb = np.array([[0, 0, 0, 0], [0, 0, 0, 1], [0, 0, 0, 0], [0, 1, 0, 0]], float)
    out = np.zeros((4, 12, 12))
    for k, m in enumerate((m12, ms, ma, mb)):
        out[k][np.ix_(idx, idx)] = m
    return out


def _pair_pattern(i: int, j: int) -> np.ndarray:
    out = np.zeros((12, 12))
    out[np.ix_((i, j), (i, j))] = [[1.0, -1.0], [-1.0, 1.0]]
    return out


#: (10, 12, 12): axial, torsion, then the 4 patterns of bending in xy (u_y, θ_z), then in xz (u_z, θ_y)
_PATTERNS = np.concatenate([_pair_pattern(0, 6)[None], _pair_pattern(3, 9)[None],
                            _bending_patterns((1, 5, 7, 11), 1.0), _bending_patterns((2, 4, 8, 10), -1.0)])


def beam_local_stiffness(length: jax.Array, E: jax.Array, props: SectionProperties, xp=jnp) -> jax.Array:
    """12×12 Timoshenko beam stiffness in local axes (x along the beam); leading batch axes broadcast.

    DOFs [u_x, u_y, u_z, θ_x, θ_y, θ_z] at node 1 then node 2. Exact for end loads: a clamped
    element under a tip force P has δ = PL³/3EI + PL/(κGA) (Przemieniecki, Theory of Matrix
    Structural Analysis, §5.6).
    """
    L = length
    G, k = props.shear_modulus, props.shear_coefficient
    A = props.area
    phi_y = 12.0 * E * props.i_z / (k * G * A * L**2)  # bending in xy (u_y, θ_z)
    phi_z = 12.0 * E * props.i_y / (k * G * A * L**2)  # bending in xz (u_z, θ_y)
    cy = E * props.i_z / ((1.0 + phi_y) * L**3)
    cz = E * props.i_y / ((1.0 + phi_z) * L**3)
    coef = xp.stack([
        E * A / L, G * props.torsion / L,
        12.0 * cy, 6.0 * L * cy, (4.0 + phi_y) * L**2 * cy, (2.0 - phi_y) * L**2 * cy,
        12.0 * cz, 6.0 * L * cz, (4.0 + phi_z) * L**2 * cz, (2.0 - phi_z) * L**2 * cz,
    ], axis=-1)
    return (coef @ xp.asarray(_PATTERNS.reshape(10, 144))).reshape(coef.shape[:-1] + (12, 12))


def _cross(a, b, xp=jnp):
    """a × b for 3-vectors along the last axis (explicit: numpy's cross is slow on tiny arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return xp.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def beam_axes(x1: jax.Array, x2: jax.Array, zref: jax.Array, xp=jnp) -> tuple[jax.Array, jax.Array]:
    """Rotation R (rows: local x, y, z in global coordinates) and length of the beam x1→x2.

    Local z is ``zref`` made normal to the beam axis (the thickness direction); y = z × x.
    """
    d = x2 - x1
    length = xp.sqrt(xp.sum(d**2, axis=-1))
    ex = d / length[..., None]
    z = zref - xp.sum(zref * ex, axis=-1)[..., None] * ex
    ez = z / xp.sqrt(xp.sum(z**2, axis=-1))[..., None]
    ey = _cross(ez, ex, xp)
    return xp.stack([ex, ey, ez], axis=-2), length


def _blockdiag2(a, b, xp=jnp):
    """blockdiag(a, b) over the last two axes (leading batch axes shared)."""
    za = xp.zeros(a.shape[:-1] + (b.shape[-1],))
    zb = xp.zeros(b.shape[:-1] + (a.shape[-1],))
    return xp.concatenate([xp.concatenate([a, za], axis=-1), xp.concatenate([zb, b], axis=-1)], axis=-2)


def beam_global_stiffness(x1, x2, zref, section: Section, a1=0.0, a2=0.0, xp=jnp,
                          props: SectionProperties | None = None) -> jax.Array:
    """12×12 stiffness of the beam x1→x2 [m] in global axes, on the DOFs of x1 and x2.

    Leading batch axes broadcast (one call assembles all of a leg's elements: the numpy path's speed).

    ``a1``, ``a2`` [m]: rigid end zones (each clipped to 40 % of the length); the flexible
    Timoshenko part spans the rest and is tied to the nodes by rigid maps.
    ``xp``: the array module (``jax.numpy``, or ``numpy`` for the jit-free single-design path).
    ``props``: section properties overriding the rectangle of ``section`` (E is read from ``section``).
    """
    R, length = beam_axes(x1, x2, zref, xp)
    a1 = xp.minimum(xp.asarray(a1), 0.4 * length)
    a2 = xp.minimum(xp.asarray(a2), 0.4 * length)
    props = section_properties(section, xp) if props is None else props
    k = beam_local_stiffness(length - a1 - a2, section.youngs_modulus, props, xp)
    # T = blockdiag(R, R, R, R) @ blockdiag(rigid(a1 ex), rigid(−a2 ex)) = blockdiag(R M1, R M2),
    # R·rigid(r) = [[R, −R[r]×], [0, R]]
    ex = R[..., 0, :]
    R4 = xp.einsum("ab,...ij->...aibj", xp.asarray(np.eye(4)), R).reshape(R.shape[:-2] + (12, 12))
    T = R4 @ _blockdiag2(rigid_map(a1[..., None] * ex, xp), rigid_map(-a2[..., None] * ex, xp), xp)
    return xp.swapaxes(T, -1, -2) @ k @ T


#: Levi-Civita ε_ijk: [r]× = −ε·r, one contraction instead of nine stacked entries (the numpy path's cost)
_EPS = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _EPS[_i, _j, _k], _EPS[_i, _k, _j] = 1.0, -1.0
#: rigid_map(r) = I₆ + _RIGID·r (top-right block −[r]× = ε·r)
_RIGID = np.zeros((6, 6, 3))
_RIGID[:3, 3:, :] = _EPS
_EYE6 = np.eye(6)


def _skew(r: jax.Array, xp=jnp) -> jax.Array:
    """[r]× (the cross-product matrix: [r]× a = r × a); leading batch axes broadcast."""
    return -(r @ xp.asarray(_EPS.reshape(9, 3).T)).reshape(r.shape[:-1] + (3, 3))


def rigid_map(r: jax.Array, xp=jnp) -> jax.Array:
    """6×6 map of a master node's DOFs to a point offset by ``r`` on a rigid body (batch axes broadcast)."""
    return xp.asarray(_EYE6) + (r @ xp.asarray(_RIGID.reshape(36, 3).T)).reshape(r.shape[:-1] + (6, 6))


def cantilever_compliance(length, section: Section, *, direction, zref, n_elements: int = 1) -> np.ndarray:
    """6×6 tip compliance [SI] of a clamped prismatic beam along ``direction`` (n equal elements).

    A plain reference assembly (numpy path of the element) used to check it against closed forms.
    """
    section = Section(*(np.asarray(x, dtype=float) for x in section))
    direction = np.asarray(direction, dtype=float)
    direction = direction / np.linalg.norm(direction)
    n = n_elements
    K = np.zeros((6 * (n + 1), 6 * (n + 1)))
    for e in range(n):
        x1 = direction * length * e / n
        x2 = direction * length * (e + 1) / n
        K[6 * e:6 * e + 12, 6 * e:6 * e + 12] += beam_global_stiffness(x1, x2, np.asarray(zref, dtype=float),
                                                                       section, xp=np)
    Kf = K[6:, 6:]
    return np.linalg.inv(Kf)[-6:, -6:]


# ----------------------------------------------------------------------------- the 3-PRRR frame
def _leg_layout(options: FrameOptions) -> tuple[int, dict[str, int]]:
    """Static DOF layout of one leg: [P (6) | internal DOFs]; first index of each block (−1: absent).

    With pins, "Ap", "B2", "Q2" are the link-side ends of the R1, R2, R3 pins; "Bp" (the r4 corner)
    is then absent (the riser rides rigidly on link2's R3 end).
    """
    hinge = options.joints == Joints.RELEASED
    beam_off = options.offsets == Offsets.BEAM
    pins = bool(options.pins)
    n, idx = 6, {}
    carriage = beam_off and pins  # the CAD's bracket: root base, root end, arm end
    for name, size in (("sea", 1 if options.sea else 0), ("Rb", 6 if carriage else 0), ("Rj", 6 if carriage else 0),
                       ("Ae", 6 if carriage else 0), ("A", 6 if beam_off else 0), ("Ap", 6 if pins else 0),
                       ("phi1", int(hinge)), ("B", 6), ("B2", 6 if pins else 0), ("phi2", int(hinge)),
                       ("Bp", 6 if beam_off and not pins else 0), ("Qp", 6 if beam_off else 0),
                       ("Q2", 6 if pins else 0), ("phi3", int(hinge))):
        idx[name] = n if size else -1
        n += size
    return n, idx


def dof_count(options: FrameOptions = FrameOptions()) -> int:
    """Number of free DOFs of the assembled frame (end-effector node + three legs' internal DOFs)."""
    n_leg = _leg_layout(options)[0]
    return 6 + 3 * (n_leg - 6)


def _free(n: int, i: int, xp=jnp) -> jax.Array:
    """Selector (6 × n) of the six DOFs starting at ``i`` (a constant, made once per (n, i): read-only)."""
    return xp.asarray(_selector(n, i))


@functools.cache
def _selector(n: int, i: int) -> np.ndarray:
    out = np.zeros((6, n))
    out[:, i:i + 6] = np.eye(6)
    out.setflags(write=False)
    return out


def _hinge(G: jax.Array, i: int, w: jax.Array, xp=jnp) -> jax.Array:
    """G with the hinge rotation DOF ``i`` added about ``w`` to its rotation rows (i < 0: none)."""
    if i < 0:
        return G
    onehot = np.zeros(G.shape[1])
    onehot[i] = 1.0
    return G + xp.concatenate([xp.zeros((3, G.shape[1])), w[:, None] * xp.asarray(onehot)[None, :]], axis=0)


def _map(fn, xp, *args):
    """``jax.vmap(fn)(*args)`` for jax; a loop stacked along axis 0 for numpy (same results)."""
    if xp is jnp:
        return jax.vmap(fn)(*args)
    outs = [fn(*(a[k] for a in args)) for k in range(args[0].shape[0])]
    if isinstance(outs[0], tuple):
        return tuple(np.stack(col) for col in zip(*outs))
    return np.stack(outs)


def _leg_stiffness(w, S, A, B, Q, bracket, p, r4, d4, section: Section, spring, zone, options: FrameOptions, xp=jnp,
                   fp: FrameParams | None = None, zones_on=1.0, parts_only: bool = False):
    """Stiffness (n×n) of one leg on its DOFs [P | internal], and the node maps G (5, 6, n).

    ``parts_only``: return the leg's (elements, springs) instead, as :func:`_assemble` takes them
    (:func:`_supports` reads their maps' nonzero columns).

    ``bracket`` = (points (3, 3) C, J, E; root thickness direction (3,); bonds (2, 6, 6)), world
    axes: the carriage's R1 bracket (:func:`bracket_frame`), used with pins (the plane frame keeps
    a carriage arm of the link section from the rail point S).
    """
    if options.pins:
        return _leg_stiffness_pins(w, S, A, B, Q, bracket, p, r4, d4, section, spring, zone, options, xp, fp,
                                   zones_on, parts_only)
    n, L = _leg_layout(options)
    beam_off = options.offsets == Offsets.BEAM
    Bp = Q - r4 * w
    e4 = (Bp - B) / d4
    G_P = _free(n, 0, xp)
    G_S = _slider_map(n, L, options, xp)
    elems = []  # (G1, G2, x1, x2, zref, a1, a2)
    a = zone
    if beam_off:
        G_Ac = _free(n, L["A"], xp)
        elems.append((G_S, G_Ac, S, A, w, 0.0 * a, a))  # carriage arm
    else:
        G_Ac = rigid_map(A - S, xp) @ G_S
    G_Al = _hinge(G_Ac, L["phi1"], w, xp)  # R1
    G_Bc = _free(n, L["B"], xp)
    elems.append((G_Al, G_Bc, A, B, w, a, a))  # link d3
    G_Bl = _hinge(G_Bc, L["phi2"], w, xp)  # R2
    if beam_off:
        G_Qp = _free(n, L["Qp"], xp)
        elems.append((G_Qp, G_P, Q, p, w, a, a))  # platform arm
    else:
        G_Qp = rigid_map(Q - p, xp) @ G_P
    G_Ql = _hinge(G_Qp, L["phi3"], w, xp)  # R3
    if beam_off:
        G_Bp = _free(n, L["Bp"], xp)
        elems.append((G_Bp, G_Ql, Bp, Q, _cross(w, e4, xp), 0.0 * a, a))  # r4 offset along w
    else:
        G_Bp = rigid_map(Bp - Q, xp) @ G_Ql  # B' rides rigidly on the link side of R3
    elems.append((G_Bl, G_Bp, B, Bp, w, a, 0.0 * a))  # link d4
    link = section_properties(section, xp)
    if parts_only:
        return [e + (link,) for e in elems], []
    K = _assemble(n, L, [e + (link,) for e in elems], section, spring, options, xp)
    G_nodes = xp.stack([G_S, G_Ac, G_Bc, G_Bp, G_Qp])
    return K, G_nodes, xp.stack([S, A, B, Bp, Q])


def _slider_map(n, L, options: FrameOptions, xp=jnp):
    G_S = np.zeros((6, n))
    if options.sea:
        G_S[2, L["sea"]] = 1.0  # the carriage slides in z on the SEA spring
    return xp.asarray(G_S)


def _assemble(n, L, elems, section: Section, spring, options: FrameOptions, xp=jnp, springs=()):
    """K = Σ_e G_eᵀ K_e G_e (+ the SEA spring) of elements (G1, G2, x1, x2, zref, a1, a2, props).

    ``springs``: (D, K_s) pairs, D the 6×n relative motion across a joint spring of stiffness K_s.

    The jax path multiplies only the columns where each map can be nonzero (:func:`_supports`, a
    static pattern of the topology) and adds the small products into K block by block; the dense
    products (12 × n maps, n = 63 per leg with pins) were most of the batched frame's time on a CPU,
    and the nonzero terms and their order in each product are the same. The numpy path keeps the
    dense form (one call per product: its cost is call overhead, not arithmetic).
    """
    Ge, Ke = _element_maps(elems, section, xp)
    if xp is np:
        K = xp.sum(xp.swapaxes(Ge, -1, -2) @ Ke @ Ge, axis=0)  # Σ_e G_eᵀ K_e G_e
        if springs:
            D = xp.stack([s[0] for s in springs])  # (S, 6, n)
            Ks = xp.stack([s[1] for s in springs])
            K = K + xp.sum(xp.swapaxes(D, -1, -2) @ Ks @ D, axis=0)
    else:
        sup_e, sup_s = _supports(options)
        if len(sup_e) != len(elems) or len(sup_s) != len(springs):
            raise AssertionError("frame topology differs from its support pattern")  # a programming error
        terms = [(Ge[k], Ke[k], c) for k, c in enumerate(sup_e)]
        terms += [(d, k_s, c) for (d, k_s), c in zip(springs, sup_s)]
        K = _sparse_sum(n, terms, xp)
    if options.sea:
        sel = np.zeros((n, n))
        sel[L["sea"], L["sea"]] = 1.0
        K = K + spring * xp.asarray(sel)
    return 0.5 * (K + K.T)


def _element_maps(elems, section: Section, xp=jnp):
    """Stacked maps [G1; G2] (E, 12, n) and global stiffness (E, 12, 12) of elements (G1, G2, x1, x2,
    zref, a1, a2, props)."""
    Ge = xp.stack([xp.concatenate([e[0], e[1]], axis=0) for e in elems])  # (E, 12, n)
    X1, X2, Z, A1, A2 = (xp.stack([e[k] for e in elems]) for k in (2, 3, 4, 5, 6))
    PR = tuple(xp.stack([e[7][f] for e in elems]) for f in range(6))
    Ke = beam_global_stiffness(X1, X2, Z, section, A1, A2, xp, props=SectionProperties(*PR))  # (E, 12, 12)
    return Ge, Ke


@functools.cache
def term_columns(options: FrameOptions) -> np.ndarray:
    """(T, M) int: the leg DOFs of each stiffness term of :func:`frame_leg_terms` (elements, joint
    springs, then the SEA spring with ``options.sea``), :func:`_supports` padded with each term's first
    column (its map is zero there)."""
    sup_e, sup_s = _supports(options)
    cols = list(sup_e) + list(sup_s)
    if options.sea:
        cols.append(np.array([_leg_layout(options)[1]["sea"]]))
    M = max(len(c) for c in cols)
    return np.stack([np.concatenate([c, np.full(M - len(c), c[0])]) for c in cols])


def _leg_terms(elems, springs, section: Section, spring, options: FrameOptions, xp=jnp):
    """One leg's stiffness as terms: the maps G (T, 12, M) of every term on :func:`term_columns`, the
    joint springs' (and the SEA spring's) stiffness K_s (S, 12, 12), padded with zeros, and the
    elements' parameters (E, 18) (:func:`element_stiffness` turns them into their 12 × 12 blocks);
    K_leg = sym(Σ_t G_tᵀ K_t G_t), elements first."""
    cols = term_columns(options)
    n = elems[0][0].shape[-1]
    maps = [xp.concatenate([e[0], e[1]], axis=0) for e in elems] + [d for d, _ in springs]
    stiff = [k_s for _, k_s in springs]
    if options.sea:
        sel = np.zeros((1, n))
        sel[0, _leg_layout(options)[1]["sea"]] = 1.0
        maps.append(xp.asarray(sel))
        stiff.append(xp.reshape(spring, (1, 1)))
    G = []
    for t, g in enumerate(maps):
        c = cols[t]
        m = 1 + int(np.count_nonzero(c[1:] != c[0]))  # the padding repeats c[0]
        g = _take_cols(g, _runs(c[:m]), xp)
        r = g.shape[0]
        g = xp.concatenate([g, xp.zeros((r, len(c) - m))], axis=1)
        G.append(xp.concatenate([g, xp.zeros((12 - r, len(c)))], axis=0))
    K = [xp.concatenate([xp.concatenate([k, xp.zeros((k.shape[0], 12 - k.shape[0]))], axis=1),
                         xp.zeros((12 - k.shape[0], 12))], axis=0) for k in stiff]
    E = section.youngs_modulus
    P = xp.stack([xp.concatenate([e[2], e[3], e[4], xp.stack([xp.asarray(x, dtype=float) for x in (e[5], e[6]) + e[7]]),
                                  xp.reshape(E, (1,))]) for e in elems])
    return xp.stack(G), xp.stack(K), P


def element_stiffness(P, xp=jnp):
    """12 × 12 global stiffness of elements given by their parameters ``P`` (..., 18) = x1, x2, zref (3
    each) [m], end zones a1, a2 [m], section (area, i_y, i_z, torsion, κ, G) and E [SI] (the rows of
    :func:`frame_leg_terms`): :func:`beam_global_stiffness`."""
    props = SectionProperties(*(P[..., 11 + f] for f in range(6)))
    sec = Section(None, None, P[..., 17], None)
    return beam_global_stiffness(P[..., 0:3], P[..., 3:6], P[..., 6:9], sec, P[..., 9], P[..., 10], xp, props=props)


def _runs(cols: np.ndarray) -> list[tuple[int, int]]:
    """Contiguous runs [start, stop) of the sorted column indices ``cols``."""
    cuts = np.flatnonzero(np.diff(cols) != 1) + 1
    return [(int(r[0]), int(r[-1]) + 1) for r in np.split(cols, cuts)]


def _take_cols(G, runs, xp=jnp):
    """The columns of ``G`` in ``runs`` (static slices: no gather)."""
    parts = [G[:, a:b] for a, b in runs]
    return parts[0] if len(parts) == 1 else xp.concatenate(parts, axis=1)


def _sparse_sum(n: int, terms, xp=jnp):
    """Σ Gᵀ K G (n × n) over ``terms`` (G (r × n), K (r × r), the columns where G can be nonzero):
    each product on those columns, added into K over a static block grid (slices and one
    concatenation; no scatter)."""
    cuts = {0, n}
    for _, _, cols in terms:
        for a, b in _runs(cols):
            cuts.update((a, b))
    edges = sorted(cuts)
    segs = list(zip(edges[:-1], edges[1:]))
    blocks: dict[tuple[int, int], object] = {}
    for G, K, cols in terms:
        runs = _runs(cols)
        g = _take_cols(G, runs, xp)
        small = xp.swapaxes(g, -1, -2) @ K @ g  # (m, m) on ``cols``
        # each run is a union of whole segments: local offset of every segment it covers
        local, off = [], 0
        for a, b in runs:
            for i, (s0, s1) in enumerate(segs):
                if a <= s0 and s1 <= b:
                    local.append((i, off + s0 - a, s1 - s0))
            off += b - a
        for i, ri, ni in local:
            for j, rj, nj in local:
                piece = small[ri:ri + ni, rj:rj + nj]
                blocks[i, j] = piece if (i, j) not in blocks else blocks[i, j] + piece
    rows = []
    for i, (a0, a1) in enumerate(segs):
        row = [blocks[i, j] if (i, j) in blocks else xp.zeros((a1 - a0, b1 - b0)) for j, (b0, b1) in enumerate(segs)]
        rows.append(xp.concatenate(row, axis=1))
    return xp.concatenate(rows, axis=0)


@functools.lru_cache(maxsize=None)
def _supports(options: FrameOptions) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    """Columns where each element's map [G1; G2] and each spring's map D can be nonzero, for the
    topology of ``options``: the leg built by the numpy path from generic (seeded random) inputs,
    twice; a structural zero is zero for any input, any other entry is nonzero for generic ones,
    and a zero that a particular design makes is only multiplied, not dropped."""
    rng = np.random.default_rng(0)
    found = None
    for _ in range(2):
        r = lambda *shape: rng.uniform(0.5, 1.5, shape)  # noqa: E731
        w = r(3)
        w /= np.linalg.norm(w)
        sec = Section(*r(4))
        fp = FrameParams(kin=PrrrParams(*r(8)), r_p=r(), theta_1p=r(), section=sec, spring=r(), joint_zone=r(),
                         pin_diameter=r(), layer=r(), lug_offset=r(), stem_radius=r(), bracket_points=r(3, 3),
                         root_zref=r(3), root_section=r(2), bracket_bonds=r(2, 6, 6))
        elems, springs = _leg_stiffness(w, r(3), r(3), r(3), r(3), (r(3, 3), r(3), r(2, 6, 6)), r(3), r(), r(), sec,
                                        r(), r(), options, xp=np, fp=fp, zones_on=1.0, parts_only=True)
        nz = [np.any(np.concatenate([e[0], e[1]], axis=0) != 0.0, axis=0) for e in elems]
        nz += [np.any(s[0] != 0.0, axis=0) for s in springs]
        found = nz if found is None else [a | b for a, b in zip(found, nz)]
    cols = tuple(np.flatnonzero(m) for m in found)
    return cols[:len(elems)], cols[len(elems):]


def _leg_stiffness_pins(w, S, A, B, Q, bracket, p, r4, d4, section: Section, spring, zone, options: FrameOptions, xp,
                        fp: FrameParams, zones_on, parts_only: bool = False):
    """One leg with the CAD's axial layering (``FrameOptions(pins=True)``, hapticopt.design.prrr.cad layers).

    Along w from the plane Π of A, B, B' (λ = link thickness + clearance): carriage clevis at −λ,
    link1 at 0, link2 at λ, platform lug at s_lug = max(r4, 2λ) (the kinematic Q is at r4).
    Each revolute joint joins two members' layers λ apart: ``PinModel.NECK``, a neck spring
    (:func:`neck_stiffness`) at the gap mid-plane, rigidly tied to both layers (the bosses with the
    pin bonded in them); ``PinModel.BEAM``, a pin beam of the bore diameter along w over the whole
    λ. The hinge (released joints) is at the pin's link-side end. R3's pin joins
    the lug (s_lug) to link2's R3 boss at s_lug − λ; the riser between link2's layer and that
    point (s_lug − 2λ long, 0 for prrr-paper) is the boss column with the pin bonded in it, taken
    rigid. The platform arm runs from the lug along −v to the stem axis, stem_diameter wide,
    rigid inside the stem radius (the stem and handle are rigid, like the FEA's rigid region).
    """
    n, L = _leg_layout(options)
    beam_off = options.offsets == Offsets.BEAM
    lam, s_q = fp.layer, fp.lug_offset  # lug layer above Q: s_lug − r4
    sb = w[2]  # sin β (w = −cos β u + sin β e_z)
    a = zone
    Ac = A - lam * w  # carriage clevis layer
    B2 = B + lam * w  # link2 layer at R2
    Bp2 = Q - r4 * w + lam * w  # link2 layer at the r4 corner (its R3 boss)
    Ql = Q + s_q * w  # platform lug
    Q2 = Ql - lam * w  # link2's end of the R3 pin
    v = _cross(w, _cross(_EZ * xp.ones(()), w, xp), xp)  # e_z made normal to w, = v of the leg frame
    v = v / xp.sqrt(xp.sum(v**2))
    Pa = Ql - (xp.sqrt(xp.sum((Ql[:2] - p[:2]) ** 2)) / sb) * v  # arm meets the stem axis
    e1 = (B - A) / xp.sqrt(xp.sum((B - A) ** 2))  # a normal of w (pins are round: any normal)
    G_P = _free(n, 0, xp)
    G_S = _slider_map(n, L, options, xp)
    link = section_properties(section, xp)
    pin = circle_properties(fp.pin_diameter, section.youngs_modulus, section.poisson_ratio, xp)
    arm = section_properties(Section(2.0 * fp.stem_radius, section.thickness, section.youngs_modulus,
                                     section.poisson_ratio), xp)
    zero = 0.0 * a
    elems = []  # (G1, G2, x1, x2, zref, a1, a2, props)
    springs = []
    if beam_off:
        G_Ac = _free(n, L["A"], xp)
        (C, Jr, E), z_root, bonds = bracket
        G_Rb, G_Rj, G_E = _free(n, L["Rb"], xp), _free(n, L["Rj"], xp), _free(n, L["Ae"], xp)
        root = section_properties(Section(fp.root_section[0], fp.root_section[1], section.youngs_modulus,
                                          section.poisson_ratio), xp)
        springs.append((G_Rb - rigid_map(C - S, xp) @ G_S, bonds[0]))  # root bonded on the rigid block at C
        elems.append((G_Rb, G_Rj, C, Jr, z_root, zero, zero, root))  # root beam C → J
        springs.append((G_E - rigid_map(E - Jr, xp) @ G_Rj, bonds[1]))  # arm bonded on the root's end face at E
        elems.append((G_E, G_Ac, E, Ac, w, zero, a, link))  # clevis arm E → Ac, in the clevis layer
        G_Ql = _free(n, L["Qp"], xp)
        elems.append((G_Ql, G_P, Ql, Pa, w, a, zones_on * fp.stem_radius / sb, arm))  # platform arm
    else:
        G_Ac = rigid_map(Ac - S, xp) @ G_S
        G_Ql = rigid_map(Ql - p, xp) @ G_P
    G_Pa = rigid_map(Pa - p, xp) @ G_P
    if beam_off:  # the arm's stem end rides on the rigid stem
        elems[-1] = elems[-1][:1] + (G_Pa,) + elems[-1][2:]
    if options.pin_model == PinModel.NECK:
        k_neck = neck_stiffness(fp.pin_diameter, fp.layer - section.thickness, section.youngs_modulus,
                                section.poisson_ratio, xp)
        K_neck = _neck_matrix(w, k_neck, xp)

    def pin_joint(G1, G2, x1, x2):
        if options.pin_model == PinModel.BEAM:
            elems.append((G1, G2, x1, x2, e1, zero, zero, pin))
        else:  # bosses rigid up to the gap mid-plane, the neck spring there
            mid = 0.5 * (x1 + x2)
            springs.append((rigid_map(mid - x2, xp) @ G2 - rigid_map(mid - x1, xp) @ G1, K_neck))

    G_Ap = _free(n, L["Ap"], xp)
    pin_joint(G_Ac, G_Ap, Ac, A)  # R1 pin
    G_Bc = _free(n, L["B"], xp)
    elems.append((_hinge(G_Ap, L["phi1"], w, xp), G_Bc, A, B, w, a, a, link))  # link d3
    G_B2 = _free(n, L["B2"], xp)
    pin_joint(G_Bc, G_B2, B, B2)  # R2 pin
    G_Q2 = _free(n, L["Q2"], xp)
    pin_joint(G_Ql, G_Q2, Ql, Q2)  # R3 pin
    G_Q2l = _hinge(G_Q2, L["phi3"], w, xp)
    G_Bp = rigid_map(Bp2 - Q2, xp) @ G_Q2l  # rigid riser
    elems.append((_hinge(G_B2, L["phi2"], w, xp), G_Bp, B2, Bp2, w, a, a, link))  # link d4 (R3 boss at Bp2)
    if parts_only:
        return elems, springs
    K = _assemble(n, L, elems, section, spring, options, xp, springs)
    G_nodes = xp.stack([G_S, G_Ac, G_Bc, G_Bp, G_Ql])
    return K, G_nodes, xp.stack([S, Ac, B, Bp2, Ql])


def _factorised(A: jax.Array, xp=jnp):
    """``B ↦ A⁻¹ B`` for a stack of matrices, factorising once on the jax path (LU), where the
    three solves of :func:`_inverse_norm1` would otherwise each refactorise; numpy's tiny solves
    are dominated by call overhead, so it calls ``solve`` directly."""
    if xp is np:
        return lambda B: np.linalg.solve(A, B)
    lu = jax.scipy.linalg.lu_factor(A)
    return lambda B: jax.scipy.linalg.lu_solve(lu, B)


def _inverse_norm1(solve, y: jax.Array, xp=jnp) -> jax.Array:
    """Hager's estimate of ‖A⁻¹‖₁ (Higham 1988, LAPACK xLACON, two steps) for symmetric A.

    ``y`` = A⁻¹ (1/n)·1, the first step (solved together with the condensation's right-hand
    sides). A lower bound, in practice within a small factor of the truth: enough to flag a
    condition number of 1e12, at 2 extra solves instead of the n of an explicit inverse.
    """
    n = y.shape[-1]
    xi = xp.where(y >= 0.0, 1.0, -1.0)
    z = solve(xi[..., None])[..., 0]  # A⁻ᵀ ξ = A⁻¹ ξ
    j = xp.argmax(xp.abs(z), axis=-1)
    e_j = (xp.arange(n)[None, :] == j[:, None]).astype(float)
    y2 = solve(e_j[..., None])[..., 0]
    return xp.maximum(xp.sum(xp.abs(y), axis=-1), xp.sum(xp.abs(y2), axis=-1))


def _cond1(Ks: jax.Array, Ks_inv: jax.Array, xp=jnp) -> jax.Array:
    """1-norm condition number from a matrix and its inverse."""
    return xp.max(xp.sum(xp.abs(Ks), axis=-2), axis=-1) * xp.max(xp.sum(xp.abs(Ks_inv), axis=-2), axis=-1)


def frame_arrays(fp: FrameParams, p: jax.Array, load_height: jax.Array, options: FrameOptions,
                 branch: jax.Array | int | None = None, zones_on: jax.Array | float | None = None,
                 xp=jnp) -> dict:
    """Assemble and solve the frame of one design at end-effector position ``p`` (3,) [m].

    Each leg's internal DOFs are condensed statically onto the end-effector node
    (K_P = Σ_legs K_PP − K_Pi K_ii⁻¹ K_iP, Jacobi-scaled solves); the legs are independent
    given P, so they are assembled and condensed in parallel (``vmap`` over the legs).
    ``branch`` and ``zones_on`` (1.0/0.0) override ``options.branch``/``options.joint_zones`` as
    traced values, so they do not trigger a recompilation. ``xp`` is the array module: ``jax.numpy``
    (jit, vmap over designs, gradients) or ``numpy`` (one design, no compilation; same code).
    Three steps, each usable alone: :func:`frame_legs` (the legs' stiffness), :func:`condense_legs`
    (the solves), :func:`compliance_outputs` (everything read from the condensed stiffness); the
    batched draft evaluator runs the first under jit and the other two outside XLA
    (:func:`condense_many`).

    Returns a dict of arrays [SI]: ``compliance_ee`` (6×6 at P, [u; θ] per [F; M]),
    ``compliance_load`` (3×3 at P + Δz e_z), ``stiffness_load`` (3,), ``elastic_centre``
    (height above P [m]), ``stiffness_elastic_centre`` (3,), ``coupling_residual`` (rotation per
    lateral force left at the elastic centre over that at P, Frobenius norms; 0 = exact
    decoupling), ``condition`` (estimate: the largest 1-norm condition number of the
    Jacobi-scaled leg-internal (Hager's estimate) and condensed (exact) matrices), ``reachable``, ``reach_margin`` [m];
    and, for plots, ``nodes`` (3, 5, 3) [m] (S, A, B, B', Q per leg), ``node_maps`` (3, 5, 6, n)
    and ``recovery`` (3, n−6, 6): internal DOFs of leg i are −recovery[i] @ [u_P; θ_P].
    """
    K, G_nodes, nodes, ik = frame_legs(fp, p, options, branch=branch, zones_on=zones_on, xp=xp)
    contrib, cond_legs, recovery = condense_legs(K, xp)
    out = compliance_outputs(xp.sum(contrib, axis=0), xp.max(cond_legs), load_height, xp)
    out.update(reachable=ik.reachable, reach_margin=ik.reach_margin, nodes=nodes, node_maps=G_nodes,
               recovery=recovery)
    return out


def _leg_inputs(fp: FrameParams, p, options: FrameOptions, branch, zones_on, xp):
    """The leg function and its per-leg arguments (leg axis first), and the IK of ``p``."""
    kin = fp.kin
    p = xp.asarray(p, dtype=float)
    ik = inverse_kinematics(kin, p, xp=xp)
    branch = options.branch if branch is None else branch
    zones_on = float(options.joint_zones) if zones_on is None else zones_on
    theta = xp.take(ik.theta, branch, axis=0)
    pts = leg_chain(kin, ik.sliders, theta, xp=xp)
    f = leg_frames(kin.beta, xp=xp)
    u_rail = xp.cos(fp.theta_1p) * f.u + xp.sin(fp.theta_1p) * f.t  # carriage frame x (u'), per leg
    t_rail = -xp.sin(fp.theta_1p) * f.u + xp.cos(fp.theta_1p) * f.t  # carriage frame y (t')
    S = ik.sliders[:, None] * _EZ + fp.r_p * u_rail
    Rc = xp.stack([u_rail, t_rail, xp.broadcast_to(xp.asarray(_EZ), u_rail.shape)], axis=-1)  # (3 legs, 3, 3)
    # the R1 bracket (carriage frame) in world axes, per leg: points, root direction, bonds
    bp = ik.sliders[:, None, None] * _EZ + xp.einsum("lij,kj->lki", Rc, fp.bracket_points)  # (3 legs, 3, 3)
    zr = xp.einsum("lij,j->li", Rc, fp.root_zref)
    R6 = _blockdiag2(Rc, Rc, xp)[:, None]  # (3 legs, 1, 6, 6)
    Kb = R6 @ fp.bracket_bonds @ xp.swapaxes(R6, -1, -2)  # (3 legs, 2, 6, 6)

    leg = functools.partial(_leg_stiffness, p=p, r4=kin.r4, d4=kin.d4, section=fp.section, spring=fp.spring,
                            zone=fp.joint_zone * zones_on, options=options, xp=xp, fp=fp, zones_on=zones_on)
    return leg, (f.w, S, pts.a, pts.b, pts.q, bp, zr, Kb), ik


def frame_legs(fp: FrameParams, p: jax.Array, options: FrameOptions, branch: jax.Array | int | None = None,
               zones_on: jax.Array | float | None = None, xp=jnp):
    """The three legs' stiffness of one design at ``p`` (3,) [m] (the first step of :func:`frame_arrays`).

    Returns ``K`` (3, n, n) on each leg's DOFs [P (6) | internal] (symmetric), the node maps
    (3, 5, 6, n), the nodes (3, 5, 3) [m] and the inverse kinematics of ``p``.
    """
    leg, args, ik = _leg_inputs(fp, p, options, branch, zones_on, xp)
    K, G_nodes, nodes = _map(lambda w, s, a, b, q, pts_b, z_b, k_b: leg(w, s, a, b, q, (pts_b, z_b, k_b)), xp, *args)
    return K, G_nodes, nodes, ik


def frame_leg_terms(fp: FrameParams, p: jax.Array, options: FrameOptions, xp=jnp):
    """:func:`frame_legs`' stiffness as its terms, unassembled (the batched draft evaluator's jitted step;
    :func:`condense_terms_many` builds the elements, assembles and solves outside XLA): per leg the maps
    G (3, T, 12, M) on the columns :func:`term_columns` ``(options)``, the springs' stiffness K_s
    (3, S, 12, 12) and the elements' parameters (3, E, 18) (:func:`element_stiffness`), each leg's
    K = sym(Σ_t G_tᵀ K_t G_t) with the elements' terms first; and the inverse kinematics of ``p``. The
    same elements, springs and maps as :func:`frame_legs`."""
    leg, args, ik = _leg_inputs(fp, p, options, None, None, xp)

    def one(w, s, a, b, q, pts_b, z_b, k_b):
        elems, springs = leg(w, s, a, b, q, (pts_b, z_b, k_b), parts_only=True)
        return _leg_terms(elems, springs, fp.section, fp.spring, options, xp)

    G, K, P = _map(one, xp, *args)
    return G, K, P, ik


def condense_legs(K: jax.Array, xp=jnp):
    """Static condensation of legs onto the end-effector node (the second step of :func:`frame_arrays`).

    ``K`` (L, n, n): L legs' stiffness on [P (6) | internal]; any number of legs (the batched
    numpy path passes designs × 3). Returns each leg's K_PP − K_Pi K_ii⁻¹ K_iP (L, 6, 6), its
    Jacobi-scaled internal matrix's 1-norm condition estimate (L,) and K_ii⁻¹ K_iP (L, n−6, 6).
    """
    Kpp, Kpi, Kii = K[:, :6, :6], K[:, :6, 6:], K[:, 6:, 6:]
    d = 1.0 / xp.sqrt(xp.abs(xp.diagonal(Kii, axis1=-2, axis2=-1)))  # (L, n_int)
    Kii_s = d[:, :, None] * Kii * d[:, None, :]
    n_int = Kii.shape[-1]
    solve = _factorised(Kii_s, xp)
    probe = xp.ones((K.shape[0], n_int, 1)) / n_int
    sol = solve(xp.concatenate([d[:, :, None] * xp.swapaxes(Kpi, -1, -2), probe], axis=-1))
    recovery = d[:, :, None] * sol[:, :, :6]  # K_ii⁻¹ K_iP
    cond_legs = xp.max(xp.sum(xp.abs(Kii_s), axis=-2), axis=-1) * _inverse_norm1(solve, sol[:, :, 6], xp)
    return Kpp - Kpi @ recovery, cond_legs, recovery


def compliance_outputs(KP: jax.Array, cond_legs: jax.Array, load_height, xp=jnp) -> dict:
    """Everything :func:`frame_arrays` reads from the condensed stiffness ``KP`` (..., 6, 6) at P (the
    third step); ``cond_legs`` (...,) the legs' largest condition estimate. Leading batch axes
    broadcast (the batched numpy path); the keys of :func:`frame_arrays` but the IK's and the plots'."""
    KP = 0.5 * (KP + xp.swapaxes(KP, -1, -2))
    dP = 1.0 / xp.sqrt(xp.abs(xp.diagonal(KP, axis1=-2, axis2=-1)))
    KP_s = dP[..., :, None] * KP * dP[..., None, :]
    KP_s_inv = xp.linalg.inv(KP_s)
    cond = xp.maximum(cond_legs, _cond1(KP_s, KP_s_inv, xp))
    C = dP[..., :, None] * KP_s_inv * dP[..., None, :]
    C = 0.5 * (C + xp.swapaxes(C, -1, -2))

    def at_height(h):
        S = -_skew(xp.asarray(h)[..., None] * xp.asarray(_EZ), xp)  # u_L = u_P + θ × (h e_z)
        H = xp.concatenate([xp.broadcast_to(xp.eye(3), S.shape), S], axis=-1)
        return H @ C @ xp.swapaxes(H, -1, -2)

    # elastic centre: rotation per lateral force θ = (C_θu + h C_θθ [e_z]×) F, F ∈ span(e_x, e_y);
    # the h minimising ‖·‖_F (exact decoupling when it exists; also minimises the lateral compliance)
    E = _skew(xp.asarray(_EZ), xp)
    M0 = C[..., 3:, :2]
    M1 = (C[..., 3:, 3:] @ E)[..., :, :2]
    h_ec = -xp.sum(M0 * M1, axis=(-2, -1)) / xp.sum(M1 * M1, axis=(-2, -1))
    residual = xp.sqrt(xp.sum((M0 + h_ec[..., None, None] * M1) ** 2, axis=(-2, -1))
                       / (xp.sum(M0**2, axis=(-2, -1)) + 1e-300))
    C_load = at_height(load_height)
    C_ec = at_height(h_ec)
    return {
        "compliance_ee": C,
        "compliance_load": C_load,
        "stiffness_load": 1.0 / xp.diagonal(C_load, axis1=-2, axis2=-1),
        "elastic_centre": h_ec,
        "stiffness_elastic_centre": 1.0 / xp.diagonal(C_ec, axis1=-2, axis2=-1),
        "coupling_residual": residual,
        "condition": cond,
    }


@functools.cache
def kernel_availability() -> str | None:
    """None when the compiled kernel of :func:`condense_many` can run here, else why not (one line); the
    numpy path runs then."""
    return compute.unavailable(_load_kernels, "the compiled frame kernel's module")


def _load_kernels() -> None:
    from hapticopt.analysis.prrr import _frame_kernels  # noqa: F401


def assemble_terms(G, Kt, cols: np.ndarray, n: int) -> np.ndarray:
    """Legs' stiffness (L, n, n) from their terms (:func:`frame_leg_terms`; ``G`` (L, T, 12, M), ``Kt``
    (L, T, 12, 12), ``cols`` (T, M)) with numpy: sym(Σ_t G_tᵀ K_t G_t) scattered onto ``cols``."""
    G, Kt = np.asarray(G, dtype=float), np.asarray(Kt, dtype=float)
    K = np.zeros((G.shape[0], n, n))
    for t, c in enumerate(cols):
        m = 1 + int(np.count_nonzero(c[1:] != c[0]))  # the padding repeats c[0] (its map columns are zero)
        small = np.swapaxes(G[:, t, :, :m], -1, -2) @ Kt[:, t] @ G[:, t, :, :m]  # (L, m, m)
        K[:, c[:m, None], c[None, :m]] += small  # c[:m] distinct: no index repeats within a term
    return 0.5 * (K + np.swapaxes(K, -1, -2))


def condense_many(K, load_height, *, compiled: bool | None = None) -> dict[str, np.ndarray]:
    """:func:`condense_legs` and :func:`compliance_outputs` of many designs outside XLA (numpy arrays).

    ``K`` (n, 3, N, N): each design's legs' stiffness (:func:`frame_legs`). ``compiled``: None (default)
    runs the numba kernel (:mod:`._frame_kernels`: a Cholesky factorisation along each leg's chain of
    DOFs, over its nonzero entries) where numba loads, else the numpy path (:func:`condense_legs` with
    ``xp=numpy`` on the (3n, N, N) stack: LAPACK's LU per leg); True / False force one. Returns the keys
    of :func:`compliance_outputs`, each with a leading axis n. NaN rows: a leg whose scaled internal
    matrix is not positive definite (the kernel), and a design whose condensation K_P = Σ (K_PP −
    K_Pi K_ii⁻¹ K_iP) cancels by :data:`CANCELLATION_LIMIT` or more on its diagonal (either path):
    there its numbers, and a verdict read from them, are rounding that differs between eliminations;
    the batched draft evaluator solves such a design again by the single path.
    """
    K = np.ascontiguousarray(K, dtype=float)
    n, legs, N = K.shape[0], K.shape[1], K.shape[-1]
    flat = K.reshape(n * legs, N, N)
    if compiled is None:
        compiled = kernel_availability() is None
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if compiled:
            from hapticopt.analysis.prrr._frame_kernels import condense_legs_kernel
            contrib, cond, gross = np.empty((n * legs, 6, 6)), np.empty(n * legs), np.empty((n * legs, 6))
            condense_legs_kernel(flat, contrib, cond, np.empty((n * legs, N - 6, 6)), gross)
        else:
            contrib, cond, recovery = condense_legs(flat, np)
            removed = np.einsum("lai,lia->la", flat[:, :6, 6:], recovery)  # diagonal of K_Pi K_ii⁻¹ K_iP
            gross = np.abs(np.diagonal(flat[:, :6, :6], axis1=-2, axis2=-1)) + np.abs(removed)
        return _outputs_many(contrib, cond, gross, n, legs, load_height)


#: :func:`condense_terms_many` runs its numba kernel from the call that takes this process's designs to
#: this many on. Measured: loading it (numba's import and the cached kernel) ≈ 0.34 s in a fresh process
#: (load 1.3); it saves ≈ 0.37 ms per design (numpy path 0.44 ms, kernel 0.07 at 256 designs, load 2.6), so
#: it pays from ≈ 900 designs (a batch of one pays the numpy path's 0.86 ms, not the load).
KERNEL_AFTER_DESIGNS = 1_000
_DESIGNS_CONDENSED = [0]


def condense_terms_many(G, Ks, P, options: FrameOptions, load_height, *,
                        compiled: bool | None = None) -> dict[str, np.ndarray]:
    """:func:`condense_many` of legs given as their terms (:func:`frame_leg_terms` of n designs: ``G``
    (n, 3, T, 12, M), ``Ks`` (n, 3, S, 12, 12), ``P`` (n, 3, E, 18)): the numba kernel builds each
    element's stiffness (over the nonzeros of its local matrix and its transformation), assembles each
    leg (the products over the nonzero entries of the maps) and condenses it in one pass; the numpy path
    builds the elements with :func:`element_stiffness`, assembles with :func:`assemble_terms` and calls
    :func:`condense_many` (LAPACK's LU). Same outputs (both equal to the
    single path to 1e-9) and NaN rules. ``compiled``: None (default) runs the kernel once it pays (from
    the call that takes this process's designs to :data:`KERNEL_AFTER_DESIGNS` on, where
    :func:`kernel_availability` allows) and numpy before; True / False force one."""
    cols = term_columns(options)
    N = _leg_layout(options)[0]
    G, Ks, P = (np.asarray(x, dtype=float) for x in (G, Ks, P))
    n, legs = G.shape[:2]
    G, Ks, P = (np.ascontiguousarray(x.reshape((n * legs,) + x.shape[2:])) for x in (G, Ks, P))
    _DESIGNS_CONDENSED[0] += n
    if compiled is None:
        compiled = _DESIGNS_CONDENSED[0] >= KERNEL_AFTER_DESIGNS and kernel_availability() is None
    if not compiled:
        K = assemble_terms(G, np.concatenate([element_stiffness(P, np), Ks], axis=1), cols, N)
        return condense_many(K.reshape(n, legs, N, N), load_height, compiled=False)
    from hapticopt.analysis.prrr._frame_kernels import assemble_condense_kernel
    contrib, cond, gross = np.empty((n * legs, 6, 6)), np.empty(n * legs), np.empty((n * legs, 6))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        assemble_condense_kernel(G, Ks, P, _PATTERNS, np.ascontiguousarray(cols, dtype=np.int64), N, contrib, cond,
                                 gross)
        return _outputs_many(contrib, cond, gross, n, legs, load_height)


def legs_kernel_ready(size: int) -> bool:
    """Whether :func:`condense_home_many` takes a batch padded to ``size`` designs (the batched draft
    evaluator then computes no frame terms in XLA): from :data:`KERNEL_AFTER_DESIGNS` designs a batch on,
    where :func:`kernel_availability` allows. A rule by the padded size, not by the designs this process
    has seen: a padded size then always compiles the same jitted core (a count crossed within a process
    would trace it again)."""
    return size >= KERNEL_AFTER_DESIGNS and kernel_availability() is None


def home_legs_many(fp: FrameParams) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The legs' inputs of the frame at the home pose p = 0 (default :class:`FrameOptions`: elbow branch 0,
    joint zones on) of n designs (``fp`` numpy, leading batch axis), numpy over the batch: what
    :func:`_leg_inputs` gives one design (:func:`~hapticopt.design.prrr.kinematics.inverse_kinematics`,
    ``leg_chain``, the bracket in world axes), term by term the same operations (to rounding).

    Returns (legs, ik): ``legs`` ``w``, ``S``, ``A``, ``B``, ``Q`` (n, 3, 3), ``bracket_points`` (n, 3, 3, 3),
    ``root_zref`` (n, 3, 3), ``bonds`` (n, 3, 2, 6, 6) [SI]; ``ik`` ``reachable`` (n,) and ``reach_margin``
    (n,) [m] of p = 0.
    """
    kin = fp.kin
    n = len(kin.beta)

    def s(x):
        return np.asarray(x, dtype=float)[:, None]

    def b(x):
        return np.asarray(x, dtype=float)[:, None, None]

    f = leg_frames(b(kin.beta), xp=np)
    u, t = np.broadcast_to(f.u, (n, 3, 3)), np.broadcast_to(f.t, (n, 3, 3))
    v, w = f.v, f.w
    # kinematics.inverse_kinematics at p = 0
    r5 = kin.b5 * np.sin(kin.beta)
    q = np.zeros((1, 3)) - b(kin.b5) * w + b(r5) * _EZ
    rel = q - (b(kin.d1) * u + b(kin.d2) * t)
    sliders = (np.sum(rel * w, axis=-1) - s(kin.r4)) / s(np.sin(kin.beta))
    rel = rel - sliders[..., None] * _EZ
    rho_v, rho_t = np.sum(rel * v, axis=-1), np.sum(rel * t, axis=-1)
    rho2 = rho_v**2 + rho_t**2
    d3, d4 = s(kin.d3), s(kin.d4)
    c2 = (rho2 - d3**2 - d4**2) / (2.0 * d3 * d4)
    reach_ok = np.abs(c2) <= 1.0 + 1e-12
    c2 = np.clip(c2, -1.0, 1.0)
    elbow, s2, rho = np.arccos(c2), np.sqrt(1.0 - c2**2), np.sqrt(rho2)
    phi, psi = np.arctan2(rho_t, rho_v), np.arctan2(d4 * s2, d3 + d4 * c2)
    th1 = np.mod(phi - psi + np.pi, 2.0 * np.pi) - np.pi  # branch 0 (θ2 = elbow ≥ 0)
    c_e = -(kin.b5 + kin.r4) / np.sin(kin.beta) + r5 + kin.d1 / np.tan(kin.beta)  # kinematics.slider_offset
    half = s(kin.stroke / 2.0)
    s_dev = sliders - s(c_e)
    stroke_ok = np.abs(s_dev) <= half * (1.0 + 1e-12)
    margin = np.minimum(np.minimum(rho - np.abs(d3 - d4), d3 + d4 - rho), half - np.abs(s_dev))
    ik = {"reachable": np.all(reach_ok & stroke_ok, axis=-1), "reach_margin": np.min(margin, axis=-1)}

    def e(angle):
        return np.cos(angle)[..., None] * v + np.sin(angle)[..., None] * t

    A = sliders[..., None] * _EZ + b(kin.d1) * u + b(kin.d2) * t  # kinematics.leg_chain
    B = A + b(kin.d3) * e(th1)
    Q = B + b(kin.d4) * e(th1 + elbow) + b(kin.r4) * w
    c1, s1 = np.cos(b(fp.theta_1p)), np.sin(b(fp.theta_1p))
    u_rail, t_rail = c1 * u + s1 * t, -s1 * u + c1 * t
    S = sliders[..., None] * _EZ + b(fp.r_p) * u_rail
    Rc = np.stack([u_rail, t_rail, np.broadcast_to(_EZ, u_rail.shape)], axis=-1)  # (n, 3 legs, 3, 3)
    bp = sliders[..., None, None] * _EZ + np.einsum("nlij,nkj->nlki", Rc, fp.bracket_points)
    zr = np.einsum("nlij,nj->nli", Rc, fp.root_zref)
    R6 = np.zeros((n, 3, 1, 6, 6))
    R6[..., :3, :3], R6[..., 3:, 3:] = Rc[:, :, None], Rc[:, :, None]
    Kb = R6 @ np.asarray(fp.bracket_bonds)[:, None] @ np.swapaxes(R6, -1, -2)
    return {"w": w, "S": S, "A": A, "B": B, "Q": Q, "bracket_points": bp, "root_zref": zr, "bonds": Kb}, ik


def condense_home_many(fp: FrameParams, load_height) -> dict[str, np.ndarray]:
    """:func:`condense_terms_many` of :func:`frame_leg_terms` (default :class:`FrameOptions`, home pose p = 0)
    of n designs, without the terms: :func:`home_legs_many` (numpy over the batch) and the numba kernel
    ``_frame_kernels.home_legs_condense_kernel``, which builds each leg's elements, springs and maps (on the
    terms' columns) and assembles and condenses it as ``assemble_condense_kernel``. Returns the keys of
    :func:`compliance_outputs` and the IK's ``reachable`` and ``reach_margin`` (leading axis n); the NaN
    rules of :func:`condense_many`. Needs the kernel (:func:`kernel_availability`)."""
    from hapticopt.analysis.prrr._frame_kernels import home_legs_condense_kernel

    options = FrameOptions()
    N, lay = _leg_layout(options)
    fp = jax.tree.map(lambda x: np.asarray(x, dtype=float), fp)
    legs, ik = home_legs_many(fp)
    n = len(fp.kin.beta)
    sec = fp.section
    E, nu = sec.youngs_modulus, sec.poisson_ratio
    props = [section_properties(sec, np),
             section_properties(Section(fp.root_section[:, 0], fp.root_section[:, 1], E, nu), np),
             section_properties(Section(2.0 * fp.stem_radius, sec.thickness, E, nu), np)]
    k_neck = neck_stiffness(fp.pin_diameter, fp.layer - sec.thickness, E, nu, np)  # (4, n)
    sc = np.column_stack([fp.joint_zone * 1.0, fp.layer, fp.lug_offset, fp.stem_radius, fp.kin.r4, E, *k_neck,
                          *(np.broadcast_to(np.asarray(x, dtype=float), (n,)) for p_ in props for x in p_)])
    geo = np.stack([legs[k] for k in ("w", "S", "A", "B", "Q")], axis=2)  # (n, 3 legs, 5, 3)
    geo = np.concatenate([geo, legs["bracket_points"], legs["root_zref"][:, :, None]], axis=2).reshape(3 * n, 9, 3)
    lay_idx = np.array([lay[k] for k in ("Rb", "Rj", "Ae", "A", "Ap", "phi1", "B", "B2", "phi2", "Qp", "Q2",
                                         "phi3")], dtype=np.int64)
    _DESIGNS_CONDENSED[0] += n
    contrib, cond, gross = np.empty((3 * n, 6, 6)), np.empty(3 * n), np.empty((3 * n, 6))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        home_legs_condense_kernel(np.ascontiguousarray(geo), np.ascontiguousarray(legs["bonds"].reshape(3 * n, 2, 6, 6)),
                                  np.ascontiguousarray(np.repeat(sc, 3, axis=0)), lay_idx, _PATTERNS,
                                  np.ascontiguousarray(term_columns(options), dtype=np.int64), N, contrib, cond, gross)
        out = _outputs_many(contrib, cond, gross, n, 3, load_height)
    return {**out, "reach_margin": ik["reach_margin"], "reachable": ik["reachable"]}  # the XLA route's order


def _outputs_many(contrib, cond, gross, n: int, legs: int, load_height) -> dict[str, np.ndarray]:
    """:func:`compliance_outputs` of n designs from their legs' condensation (legs × n flattened), NaN
    rows where the condensation cancels by :data:`CANCELLATION_LIMIT` or more."""
    KP = np.sum(contrib.reshape(n, legs, 6, 6), axis=1)
    cancel = np.max(np.sum(gross.reshape(n, legs, 6), axis=1) / np.abs(np.diagonal(KP, axis1=-2, axis2=-1)), axis=1)
    out = compliance_outputs(KP, np.max(cond.reshape(n, legs), axis=1), np.asarray(load_height, dtype=float), np)
    bad = ~(cancel < CANCELLATION_LIMIT)  # NaN too
    for v in out.values():
        v[bad] = np.nan
    return out


_PLOT_ONLY = ("nodes", "node_maps", "recovery")


@functools.lru_cache(maxsize=None)
def _compiled(joints: Joints, offsets: Offsets, sea: bool, batched: bool, full: bool, pins: bool,
              pin_model: PinModel):
    options = FrameOptions(joints=joints, offsets=offsets, sea=sea, pins=pins, pin_model=pin_model)

    def fn(fp, p, h, branch, zones_on):
        out = frame_arrays(fp, p, h, options, branch=branch, zones_on=zones_on)
        if not full:
            out = {k: v for k, v in out.items() if k not in _PLOT_ONLY}
        return out

    if batched:
        fn = jax.vmap(fn, in_axes=(0, None, None, None, None))
    return jax.jit(fn)


def _call(fp, p, load_height, options: FrameOptions, batched: bool, full: bool):
    if options.branch not in (0, 1):
        raise ValueError(f"FrameOptions.branch = {options.branch!r}: allowed 0 or 1")
    fn = _compiled(Joints(options.joints), Offsets(options.offsets), bool(options.sea), batched, full,
                   bool(options.pins), PinModel(options.pin_model))
    return fn(fp, jnp.asarray(p, dtype=float), jnp.asarray(load_height, dtype=float),
              jnp.asarray(options.branch), jnp.asarray(float(options.joint_zones)))


def solve_frame(fp: FrameParams, *, p=(0.0, 0.0, 0.0), load_height: float = LOAD_HEIGHT,
                options: FrameOptions = FrameOptions()) -> dict[str, np.ndarray]:
    """Frame model of one design, numpy path (no compilation, ~1 ms); numpy arrays [SI].

    The same :func:`frame_arrays` as the jax path (:func:`solve_frame_jax`, tested equal to
    1e-12); a numerically singular matrix falls back to the jax path, which returns inf/NaN
    instead of raising.
    """
    if options.branch not in (0, 1):
        raise ValueError(f"FrameOptions.branch = {options.branch!r}: allowed 0 or 1")
    fp_np = jax.tree.map(lambda x: np.asarray(x, dtype=float), fp)
    try:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            out = frame_arrays(fp_np, np.asarray(p, dtype=float), np.asarray(float(load_height)), options, xp=np)
    except np.linalg.LinAlgError:
        return solve_frame_jax(fp, p=p, load_height=load_height, options=options)
    return {k: np.asarray(v) for k, v in out.items()}


def solve_frame_jax(fp: FrameParams, *, p=(0.0, 0.0, 0.0), load_height: float = LOAD_HEIGHT,
                    options: FrameOptions = FrameOptions()) -> dict[str, np.ndarray]:
    """Frame model of one design, jax path (jit-compiled once per joints/offsets/sea); numpy arrays."""
    out = _call(fp, p, load_height, options, False, True)
    return {k: np.asarray(v) for k, v in out.items()}


def solve_frame_batch(fp: FrameParams, *, p=(0.0, 0.0, 0.0), load_height: float = LOAD_HEIGHT,
                      options: FrameOptions = FrameOptions()) -> dict[str, np.ndarray]:
    """Frame model of a batch of designs (``fp`` with a leading axis n); arrays with leading n."""
    out = _call(fp, p, load_height, options, True, False)
    return {k: np.asarray(v) for k, v in out.items()}


def closed_form_tip_deflection(load: float, length: float, E: float, inertia: float, kappa: float,
                               G: float, area: float) -> float:
    """Timoshenko cantilever tip deflection [m]: PL³/(3EI) + PL/(κGA)."""
    return load * length**3 / (3.0 * E * inertia) + load * length / (kappa * G * area)


__all__ = [
    "BRACKET_ARRAYS_FROM", "CANCELLATION_LIMIT", "COND_LIMIT", "KERNEL_AFTER_DESIGNS", "LOAD_HEIGHT", "FrameOptions", "FrameParams", "Joints", "Offsets", "Section",
    "beam_global_stiffness", "beam_local_stiffness", "cantilever_compliance", "circle_properties",
    "closed_form_tip_deflection", "bond_stiffness", "bracket_frame", "compliance_outputs", "condense_legs",
    "assemble_terms", "condense_home_many", "condense_many", "condense_terms_many", "home_legs_many", "legs_kernel_ready", "frame_leg_terms", "frame_legs", "kernel_availability", "term_columns",
    "dof_count", "element_stiffness", "frame_arrays", "frame_params_many", "frame_params_of", "section_properties", "solve_frame",
    "solve_frame_batch", "solve_frame_jax", "stack_frame_params",
]

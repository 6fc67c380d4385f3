"""3-D Timoshenko frame model of the 3-PRRR's closed-loop structure (float64; numpy or jax).

One core, :func:`frame_arrays`, written against an array module ``xp``: :func:`solve_frame` runs it
with numpy for one design (no compilation: the CLI path), :func:`solve_frame_jax` with ``jax.numpy``
under jit (its fallback where numpy's solve raises, and gradients). The batched draft
evaluator jits only the legs' unassembled terms (:func:`frame_leg_terms`) and assembles and condenses
them outside XLA (:mod:`.frame_condense`). Beam elements, sections and joint springs: :mod:`.frame_beam`.

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
               layer; both bonds two half-spaces (:func:`.frame_beam.bond_stiffness`), see :mod:`.frame_params`
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
Every beam (including the offsets when they are beams) has the link section (:mod:`.frame_beam`).

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

import jax
import jax.numpy as jnp
import jax.scipy.linalg
import numpy as np

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.prrr.structure.frame_beam import (Section, SectionProperties, _blockdiag2, _cross, _neck_matrix,
                                                _skew, beam_global_stiffness, circle_properties, neck_stiffness,
                                                rigid_map, section_properties)
from hapticopt.analysis.prrr.structure.frame_params import FrameParams, frame_params_of
from hapticopt.design.prrr.cad import DEFAULT_BRANCH
from hapticopt.design.prrr.kinematics import PrrrParams, inverse_kinematics, leg_chain, leg_frames

#: Above this 1-norm condition number (Jacobi-scaled K) a result is reported as ill-conditioned.
COND_LIMIT = 1e12
#: At or above this condition number the matrix is numerically singular (1/eps ≈ 4.5e15 in float64;
#: three decades above COND_LIMIT, so a rounding-level change of the estimate never flips the verdict).
SINGULAR_COND = 1e15
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
    # elbow branch of the IK: 0 (θ2 ≥ 0) or 1 (θ2 ≤ 0). Default: the branch the device is assembled in, the
    # CAD's (design.prrr.cad.DEFAULT_BRANCH = 1; branch 0's link2 collide under the platform, docs/cad.md)
    branch: int = DEFAULT_BRANCH
    joint_zones: bool = True  # beam ends within the boss radius of a joint (A, B, Q) or of P are rigid
    pins: bool = True  # CAD layering: members in their layers along w, joined through pins of the bore
    pin_model: PinModel = PinModel.NECK  # with pins: constriction springs at the gap, or free pin beams


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
    axes: the carriage's R1 bracket (:mod:`.frame_params`), used with pins (the plane frame keeps
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

    The jax path multiplies only the columns where each map can be nonzero (:func:`_supports`) and
    adds the small products into K block by block (no dense 12 × n products under XLA); the numpy path
    keeps the dense form (one call per product: its cost is call overhead, not arithmetic).
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
    elements' parameters (E, 18) (:func:`.frame_beam.element_stiffness` turns them into their 12 × 12 blocks);
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
    traced values (no recompilation). ``xp``: ``jax.numpy`` or ``numpy`` (same code). Three steps,
    each usable alone: :func:`frame_legs` (the legs' stiffness), :func:`condense_legs` (the solves),
    :func:`compliance_outputs` (everything read from the condensed stiffness).

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
    :func:`.frame_condense.condense_terms_many` builds the elements, assembles and solves outside XLA): per leg the maps
    G (3, T, 12, M) on the columns :func:`term_columns` ``(options)``, the springs' stiffness K_s
    (3, S, 12, 12) and the elements' parameters (3, E, 18) (:func:`.frame_beam.element_stiffness`), each leg's
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


@functools.lru_cache(maxsize=None)
def _compiled(joints: Joints, offsets: Offsets, sea: bool, pins: bool, pin_model: PinModel):
    options = FrameOptions(joints=joints, offsets=offsets, sea=sea, pins=pins, pin_model=pin_model)
    return jax.jit(lambda fp, p, h, branch, zones_on: frame_arrays(fp, p, h, options, branch=branch, zones_on=zones_on))


def solve_frame(fp: FrameParams, *, p=(0.0, 0.0, 0.0), load_height: float = LOAD_HEIGHT,
                options: FrameOptions = FrameOptions()) -> dict[str, np.ndarray]:
    """Frame model of one design, numpy path (no compilation); numpy arrays [SI].

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
    if options.branch not in (0, 1):
        raise ValueError(f"FrameOptions.branch = {options.branch!r}: allowed 0 or 1")
    fn = _compiled(Joints(options.joints), Offsets(options.offsets), bool(options.sea), bool(options.pins),
                   PinModel(options.pin_model))
    out = fn(fp, jnp.asarray(p, dtype=float), jnp.asarray(load_height, dtype=float), jnp.asarray(options.branch),
             jnp.asarray(float(options.joint_zones)))
    return {k: np.asarray(v) for k, v in out.items()}


def frame_parts(fp, p, options: FrameOptions = FrameOptions()):
    """The frame model of one design at pose ``p`` (3,) [m] with its members kept: per leg (w, elements,
    springs, K), the condensation (each leg's K_PP − K_Pi K_ii⁻¹ K_iP, condition estimates, recovery
    K_ii⁻¹ K_iP) and the inverse kinematics; the steps of :func:`frame_arrays` (numpy path), whose
    elements the strength's member stresses need (:mod:`.strength`). Raises ``LinAlgError`` where numpy's solve does."""
    n, L = _leg_layout(options)
    leg, args, ik = _leg_inputs(fp, np.asarray(p, dtype=float), options, None, None, np)
    legs = []
    for k in range(3):
        w, S, A, B, Q, bp, zr, Kb = (a[k] for a in args)
        elems, springs = leg(w, S, A, B, Q, (bp, zr, Kb), parts_only=True)
        legs.append((w, elems, springs, _assemble(n, L, elems, fp.section, fp.spring, options, np, springs)))
    contrib, cond_legs, recovery = condense_legs(np.stack([g[3] for g in legs]), np)
    return legs, contrib, cond_legs, recovery, ik


@functools.lru_cache(maxsize=4)
def home_frame(design):
    """(numpy frame parameters, :func:`frame_parts` at the home pose with the default options) of
    ``design``: made once per design and process for the stiffness evaluator's home solve
    (:func:`.stiffness.structural_stiffness`) and the strength's draft pose (:mod:`.strength`), which share it."""
    fp = frame_params_of(design, xp=np)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return fp, frame_parts(fp, np.zeros(3))


def home_arrays(design, load_height: float) -> dict[str, np.ndarray]:
    """:func:`solve_frame` of ``design`` at the home pose with the default options, from
    :func:`home_frame` (the same steps: the same numbers)."""
    fp, (legs, contrib, cond_legs, recovery, ik) = home_frame(design)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = compliance_outputs(np.sum(contrib, axis=0), np.max(cond_legs),
                                    np.asarray(float(load_height)), np)
    out.update(reachable=ik.reachable, reach_margin=ik.reach_margin)
    return {k: np.asarray(v) for k, v in out.items()}


__all__ = [
    "COND_LIMIT", "LOAD_HEIGHT", "SINGULAR_COND", "FrameOptions", "FrameParams", "Joints", "Offsets", "PinModel",
    "Section", "compliance_outputs", "condense_legs", "frame_arrays", "frame_leg_terms",
    "frame_legs", "frame_params_of", "frame_parts", "home_arrays", "home_frame", "solve_frame", "solve_frame_jax",
    "term_columns",
]

"""3-D Timoshenko frame model of the 3-PRRR's closed-loop structure (jax, float64, batched).

Each link is a 12-DOF Timoshenko beam (axial, torsion, two bending planes with shear) of the
rectangular cross-section in ``design.structure``; the three revolute joints of every leg
release the rotation about their axis w_i; the sliders are locked (optionally with the SEA
spring in series along z). The model is assembled at any pose from the leg points of
:func:`analysis.prrr_kinematics.leg_chain`, condensed onto the end-effector node and turned
into the Cartesian stiffness for a load applied Δz above the end-effector.

Structure of one leg i (points in the seed-digest leg construction; S is the rail point):

    S = D_i e_z + r_p u_i  (slider carriage on the rail; clamped, or sliding in z on the SEA spring)
    S → A      carriage arm (d1/d2 offset)              beam, or rigid (``Offsets.RIGID``)
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
import numpy as np

import analysis  # noqa: F401  (float64)
from analysis.prrr_kinematics import PrrrParams, inverse_kinematics, leg_chain, leg_frames, params_of

#: Above this 1-norm condition number (Jacobi-scaled K) a result is reported as ill-conditioned.
COND_LIMIT = 1e12
#: Default load height above the end-effector [m] (seed 002 Table 3: Δz = 58 mm).
LOAD_HEIGHT = 0.058
_EZ = np.array([0.0, 0.0, 1.0])


class Joints(StrEnum):
    """How the revolute joints are modelled."""

    RELEASED = "released"  # rotation about the joint axis free (the mechanism)
    BONDED = "bonded"  # pins bonded: the joint transmits all six components (for FEA comparison)


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
    section: Section
    spring: jax.Array  # SEA spring k [N/m] (used with ``FrameOptions(sea=True)``)
    joint_zone: jax.Array  # radius of the rigid joint zone (the joint boss) [m]


def frame_params_of(design) -> FrameParams:
    """Frame-model parameters of one :class:`design.prrr.PrrrDesign`."""
    s = design.structure
    sec = Section(*(jnp.asarray(float(x)) for x in (s.link_width, s.link_thickness, s.youngs_modulus, s.poisson_ratio)))
    return FrameParams(kin=params_of(design), r_p=jnp.asarray(float(design.geometry.r_p)), section=sec,
                       spring=jnp.asarray(float(design.actuator.spring)),
                       joint_zone=jnp.asarray(0.5 * float(s.boss_diameter)))


def stack_frame_params(designs) -> FrameParams:
    """Parameters of many designs stacked along a leading batch axis."""
    each = [frame_params_of(d) for d in designs]
    return jax.tree.map(lambda *xs: jnp.stack(xs), *each)


# ----------------------------------------------------------------------------- beam element
class SectionProperties(NamedTuple):
    area: jax.Array  # A [m²]
    i_y: jax.Array  # second moment about local y (bending in the local xz plane) [m⁴]
    i_z: jax.Array  # second moment about local z (bending in the local xy plane) [m⁴]
    torsion: jax.Array  # Saint-Venant torsion constant J [m⁴]
    shear_coefficient: jax.Array  # κ [-]
    shear_modulus: jax.Array  # G [Pa]


def section_properties(section: Section) -> SectionProperties:
    """Rectangle of width b (local y) and thickness t (local z)."""
    b, t, E, nu = section
    lo, hi = jnp.minimum(b, t), jnp.maximum(b, t)
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


def beam_local_stiffness(length: jax.Array, E: jax.Array, props: SectionProperties) -> jax.Array:
    """12×12 Timoshenko beam stiffness in local axes (x along the beam).

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
    coef = jnp.stack([
        E * A / L, G * props.torsion / L,
        12.0 * cy, 6.0 * L * cy, (4.0 + phi_y) * L**2 * cy, (2.0 - phi_y) * L**2 * cy,
        12.0 * cz, 6.0 * L * cz, (4.0 + phi_z) * L**2 * cz, (2.0 - phi_z) * L**2 * cz,
    ])
    return jnp.tensordot(coef, _PATTERNS, axes=1)


def beam_axes(x1: jax.Array, x2: jax.Array, zref: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Rotation R (rows: local x, y, z in global coordinates) and length of the beam x1→x2.

    Local z is ``zref`` made normal to the beam axis (the thickness direction); y = z × x.
    """
    d = x2 - x1
    length = jnp.sqrt(jnp.sum(d**2))
    ex = d / length
    z = zref - jnp.dot(zref, ex) * ex
    ez = z / jnp.sqrt(jnp.sum(z**2))
    ey = jnp.cross(ez, ex)
    return jnp.stack([ex, ey, ez]), length


def beam_global_stiffness(x1, x2, zref, section: Section, a1=0.0, a2=0.0) -> jax.Array:
    """12×12 stiffness of the beam x1→x2 [m] in global axes, on the DOFs of x1 and x2.

    ``a1``, ``a2`` [m]: rigid end zones (each clipped to 40 % of the length); the flexible
    Timoshenko part spans the rest and is tied to the nodes by rigid maps.
    """
    R, length = beam_axes(x1, x2, zref)
    a1 = jnp.minimum(a1, 0.4 * length)
    a2 = jnp.minimum(a2, 0.4 * length)
    k = beam_local_stiffness(length - a1 - a2, section.youngs_modulus, section_properties(section))
    T = jnp.kron(jnp.eye(4), R)
    rig = jnp.zeros((12, 12)).at[:6, :6].set(rigid_map(a1 * R[0])).at[6:, 6:].set(rigid_map(-a2 * R[0]))
    T = T @ rig
    return T.T @ k @ T


def _skew(r: jax.Array) -> jax.Array:
    return jnp.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def rigid_map(r: jax.Array) -> jax.Array:
    """6×6 map of a master node's DOFs to a point offset by ``r`` on a rigid body."""
    top = jnp.concatenate([jnp.eye(3), -_skew(r)], axis=1)
    bottom = jnp.concatenate([jnp.zeros((3, 3)), jnp.eye(3)], axis=1)
    return jnp.concatenate([top, bottom], axis=0)


@functools.partial(jax.jit, static_argnames=("n_elements",))
def cantilever_compliance(length, section: Section, *, direction, zref, n_elements: int = 1) -> jax.Array:
    """6×6 tip compliance [SI] of a clamped prismatic beam along ``direction`` (n equal elements).

    A plain reference assembly used to check the element against closed forms.
    """
    direction = jnp.asarray(direction, dtype=float)
    direction = direction / jnp.linalg.norm(direction)
    n = n_elements
    K = jnp.zeros((6 * (n + 1), 6 * (n + 1)))
    for e in range(n):
        x1 = direction * length * e / n
        x2 = direction * length * (e + 1) / n
        Ke = beam_global_stiffness(x1, x2, jnp.asarray(zref, dtype=float), section)
        K = K.at[6 * e:6 * e + 12, 6 * e:6 * e + 12].add(Ke)
    Kf = K[6:, 6:]
    return jnp.linalg.inv(Kf)[-6:, -6:]


# ----------------------------------------------------------------------------- the 3-PRRR frame
def _leg_layout(options: FrameOptions) -> tuple[int, dict[str, int]]:
    """Static DOF layout of one leg: [P (6) | internal DOFs]; first index of each block (−1: absent)."""
    hinge = options.joints == Joints.RELEASED
    beam_off = options.offsets == Offsets.BEAM
    n, idx = 6, {}
    for name, size in (("sea", 1 if options.sea else 0), ("A", 6 if beam_off else 0), ("phi1", int(hinge)),
                       ("B", 6), ("phi2", int(hinge)), ("Bp", 6 if beam_off else 0),
                       ("Qp", 6 if beam_off else 0), ("phi3", int(hinge))):
        idx[name] = n if size else -1
        n += size
    return n, idx


def dof_count(options: FrameOptions = FrameOptions()) -> int:
    """Number of free DOFs of the assembled frame (end-effector node + three legs' internal DOFs)."""
    n_leg = _leg_layout(options)[0]
    return 6 + 3 * (n_leg - 6)


def _free(n: int, i: int) -> jax.Array:
    return jnp.zeros((6, n)).at[:, i:i + 6].set(jnp.eye(6))


def _hinge(G: jax.Array, i: int, w: jax.Array) -> jax.Array:
    return G if i < 0 else G.at[3:6, i].add(w)


def _leg_stiffness(w, S, A, B, Q, p, r4, d4, section: Section, spring, zone, options: FrameOptions):
    """Stiffness (n×n) of one leg on its DOFs [P | internal], and the node maps G (5, 6, n)."""
    n, L = _leg_layout(options)
    beam_off = options.offsets == Offsets.BEAM
    Bp = Q - r4 * w
    e4 = (Bp - B) / d4
    G_P = _free(n, 0)
    G_S = jnp.zeros((6, n))
    if options.sea:
        G_S = G_S.at[2, L["sea"]].set(1.0)  # the carriage slides in z on the SEA spring
    elems = []  # (G1, G2, x1, x2, zref, a1, a2)
    a = zone
    if beam_off:
        G_Ac = _free(n, L["A"])
        elems.append((G_S, G_Ac, S, A, w, 0.0 * a, a))  # carriage arm
    else:
        G_Ac = rigid_map(A - S) @ G_S
    G_Al = _hinge(G_Ac, L["phi1"], w)  # R1
    G_Bc = _free(n, L["B"])
    elems.append((G_Al, G_Bc, A, B, w, a, a))  # link d3
    G_Bl = _hinge(G_Bc, L["phi2"], w)  # R2
    if beam_off:
        G_Qp = _free(n, L["Qp"])
        elems.append((G_Qp, G_P, Q, p, w, a, a))  # platform arm
    else:
        G_Qp = rigid_map(Q - p) @ G_P
    G_Ql = _hinge(G_Qp, L["phi3"], w)  # R3
    if beam_off:
        G_Bp = _free(n, L["Bp"])
        elems.append((G_Bp, G_Ql, Bp, Q, jnp.cross(w, e4), 0.0 * a, a))  # r4 offset along w
    else:
        G_Bp = rigid_map(Bp - Q) @ G_Ql  # B' rides rigidly on the link side of R3
    elems.append((G_Bl, G_Bp, B, Bp, w, a, 0.0 * a))  # link d4
    Ge = jnp.stack([jnp.concatenate([g1, g2], axis=0) for g1, g2, *_ in elems])  # (E, 12, n)
    X1, X2, Z, A1, A2 = (jnp.stack([e[k] for e in elems]) for k in (2, 3, 4, 5, 6))
    Ke = jax.vmap(beam_global_stiffness, in_axes=(0, 0, 0, None, 0, 0))(X1, X2, Z, section, A1, A2)  # (E, 12, 12)
    K = jnp.einsum("eia,eij,ejb->ab", Ge, Ke, Ge)
    if options.sea:
        K = K.at[L["sea"], L["sea"]].add(spring)
    K = 0.5 * (K + K.T)
    G_nodes = jnp.stack([G_S, G_Ac, G_Bc, G_Bp, G_Qp])
    return K, G_nodes, jnp.stack([S, A, B, Bp, Q])


def _cond1(Ks: jax.Array, Ks_inv: jax.Array) -> jax.Array:
    """1-norm condition number from a matrix and its inverse."""
    return jnp.max(jnp.sum(jnp.abs(Ks), axis=-2), axis=-1) * jnp.max(jnp.sum(jnp.abs(Ks_inv), axis=-2), axis=-1)


def frame_arrays(fp: FrameParams, p: jax.Array, load_height: jax.Array, options: FrameOptions,
                 branch: jax.Array | int | None = None, zones_on: jax.Array | float | None = None) -> dict:
    """Assemble and solve the frame of one design at end-effector position ``p`` (3,) [m].

    Each leg's internal DOFs are condensed statically onto the end-effector node
    (K_P = Σ_legs K_PP − K_Pi K_ii⁻¹ K_iP, Jacobi-scaled solves); the legs are independent
    given P, so they are assembled and condensed in parallel (``vmap`` over the legs).
    ``branch`` and ``zones_on`` (1.0/0.0) override ``options.branch``/``options.joint_zones`` as
    traced values, so they do not trigger a recompilation.

    Returns a dict of arrays [SI]: ``compliance_ee`` (6×6 at P, [u; θ] per [F; M]),
    ``compliance_load`` (3×3 at P + Δz e_z), ``stiffness_load`` (3,), ``elastic_centre``
    (height above P [m]), ``stiffness_elastic_centre`` (3,), ``coupling_residual`` (rotation per
    lateral force left at the elastic centre over that at P, Frobenius norms; 0 = exact
    decoupling), ``condition`` (estimate: the largest 1-norm condition number of the
    Jacobi-scaled leg-internal and condensed matrices), ``reachable``, ``reach_margin`` [m];
    and, for plots, ``nodes`` (3, 5, 3) [m] (S, A, B, B', Q per leg), ``node_maps`` (3, 5, 6, n)
    and ``recovery`` (3, n−6, 6): internal DOFs of leg i are −recovery[i] @ [u_P; θ_P].
    """
    kin = fp.kin
    p = jnp.asarray(p, dtype=float)
    ik = inverse_kinematics(kin, p)
    branch = options.branch if branch is None else branch
    zones_on = float(options.joint_zones) if zones_on is None else zones_on
    theta = jnp.take(ik.theta, branch, axis=0)
    pts = leg_chain(kin, ik.sliders, theta)
    f = leg_frames(kin.beta)
    S = ik.sliders[:, None] * _EZ + fp.r_p * f.u

    leg = functools.partial(_leg_stiffness, p=p, r4=kin.r4, d4=kin.d4, section=fp.section, spring=fp.spring,
                            zone=fp.joint_zone * zones_on, options=options)
    K, G_nodes, nodes = jax.vmap(lambda w, s, a, b, q: leg(w, s, a, b, q))(f.w, S, pts.a, pts.b, pts.q)
    Kpp, Kpi, Kii = K[:, :6, :6], K[:, :6, 6:], K[:, 6:, 6:]
    d = 1.0 / jnp.sqrt(jnp.abs(jnp.diagonal(Kii, axis1=-2, axis2=-1)))  # (3, n_int)
    Kii_s = d[:, :, None] * Kii * d[:, None, :]
    n_int = Kii.shape[-1]
    rhs = jnp.concatenate([jnp.broadcast_to(jnp.eye(n_int), Kii.shape),
                           d[:, :, None] * jnp.swapaxes(Kpi, -1, -2)], axis=-1)
    sol = jnp.linalg.solve(Kii_s, rhs)
    cond_legs = _cond1(Kii_s, sol[:, :, :n_int])
    recovery = d[:, :, None] * sol[:, :, n_int:]  # K_ii⁻¹ K_iP
    KP = jnp.sum(Kpp - Kpi @ recovery, axis=0)
    KP = 0.5 * (KP + KP.T)
    dP = 1.0 / jnp.sqrt(jnp.abs(jnp.diagonal(KP)))
    KP_s = dP[:, None] * KP * dP[None, :]
    KP_s_inv = jnp.linalg.inv(KP_s)
    cond = jnp.maximum(jnp.max(cond_legs), _cond1(KP_s, KP_s_inv))
    C = dP[:, None] * KP_s_inv * dP[None, :]
    C = 0.5 * (C + C.T)

    def at_height(h):
        H = jnp.concatenate([jnp.eye(3), -_skew(h * _EZ)], axis=1)  # u_L = u_P + θ × (h e_z)
        return H @ C @ H.T

    # elastic centre: rotation per lateral force θ = (C_θu + h C_θθ [e_z]×) F, F ∈ span(e_x, e_y);
    # the h minimising ‖·‖_F (exact decoupling when it exists; also minimises the lateral compliance)
    E = _skew(_EZ)
    M0 = C[3:, :3][:, :2]
    M1 = (C[3:, 3:] @ E)[:, :2]
    h_ec = -jnp.sum(M0 * M1) / jnp.sum(M1 * M1)
    residual = jnp.sqrt(jnp.sum((M0 + h_ec * M1) ** 2) / (jnp.sum(M0**2) + 1e-300))
    C_load = at_height(load_height)
    C_ec = at_height(h_ec)
    return {
        "compliance_ee": C,
        "compliance_load": C_load,
        "stiffness_load": 1.0 / jnp.diagonal(C_load),
        "elastic_centre": h_ec,
        "stiffness_elastic_centre": 1.0 / jnp.diagonal(C_ec),
        "coupling_residual": residual,
        "condition": cond,
        "reachable": ik.reachable,
        "reach_margin": ik.reach_margin,
        "nodes": nodes,
        "node_maps": G_nodes,
        "recovery": recovery,
    }


_PLOT_ONLY = ("nodes", "node_maps", "recovery")


@functools.lru_cache(maxsize=None)
def _compiled(joints: Joints, offsets: Offsets, sea: bool, batched: bool, full: bool):
    options = FrameOptions(joints=joints, offsets=offsets, sea=sea)

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
    fn = _compiled(Joints(options.joints), Offsets(options.offsets), bool(options.sea), batched, full)
    return fn(fp, jnp.asarray(p, dtype=float), jnp.asarray(load_height, dtype=float),
              jnp.asarray(options.branch), jnp.asarray(float(options.joint_zones)))


def solve_frame(fp: FrameParams, *, p=(0.0, 0.0, 0.0), load_height: float = LOAD_HEIGHT,
                options: FrameOptions = FrameOptions()) -> dict[str, np.ndarray]:
    """Frame model of one design (jit-compiled once per ``options``); numpy arrays [SI]."""
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
    "COND_LIMIT", "LOAD_HEIGHT", "FrameOptions", "FrameParams", "Joints", "Offsets", "Section",
    "beam_global_stiffness", "beam_local_stiffness", "cantilever_compliance", "closed_form_tip_deflection",
    "dof_count", "frame_arrays", "frame_params_of", "section_properties", "solve_frame",
    "solve_frame_batch", "stack_frame_params",
]

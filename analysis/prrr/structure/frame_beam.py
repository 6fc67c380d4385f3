"""Beam elements, sections and joint springs of the 3-D Timoshenko frame (float64; numpy or jax).

The pieces :mod:`hapticopt.analysis.prrr.structure.frame_model` assembles, each written against an array module
``xp`` (``jax.numpy`` under jit/vmap, or ``numpy``) with leading batch axes broadcast: the rectangular
link section (Roark's torsion constant J = b t³[1/3 − 0.21 (t/b)(1 − t⁴/12b⁴)], b ≥ t; Cowper's shear
coefficient κ = 10(1+ν)/(12+11ν)) and the pins' circle, the 12-DOF Timoshenko beam in local and global
axes with rigid end zones, rigid-body maps, and the bonded joints' springs (two elastic half-spaces
through a patch: :func:`neck_stiffness`, :func:`bond_stiffness`). Units SI; DOFs [u; θ] per node.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)


class Section(NamedTuple):
    """Rectangular cross-section and isotropic material [SI]; scalars or a batch (n,)."""

    width: jax.Array  # in-plane width b [m]
    thickness: jax.Array  # thickness t along the joint axis [m]
    youngs_modulus: jax.Array  # E [Pa]
    poisson_ratio: jax.Array  # ν [-]


def bond_stiffness(area, moments, polar, axes, E, nu) -> np.ndarray:
    """(n, 6, 6) stiffness [SI] of two elastic half-spaces bonded over a flat patch, in the axes given,
    for n patches (numpy): every scalar (n,), every axis (n, 3).

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
    k, T = _beam_local(x1, x2, zref, section, a1, a2, xp, props)
    return xp.swapaxes(T, -1, -2) @ k @ T


def _beam_local(x1, x2, zref, section: Section, a1, a2, xp, props: SectionProperties | None):
    """The flexible part's local stiffness k (12 × 12) and the map T (12 × 12) of the nodes' global DOFs
    to its ends' local DOFs (rigid end zones a1, a2 clipped to 40 % of the length)."""
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
    return k, T


def beam_end_forces(x1, x2, zref, section: Section, a1=0.0, a2=0.0, d=None, xp=np,
                    props: SectionProperties | None = None):
    """End forces of the flexible part of the beam x1→x2 in its local axes, (..., 12, m) [N, N·m]:
    [N, V_y, V_z, T, M_y, M_z] at its first end, then at its second, for m cases of the nodes' global
    displacements ``d`` (..., 12, m) [m, rad] (the same axes, end zones and section as
    :func:`beam_global_stiffness`). The forces act on the beam; with no load along it, its internal
    force resultants are largest at these ends (the boss edges)."""
    k, T = _beam_local(x1, x2, zref, section, a1, a2, xp, props)
    return k @ (T @ d)


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


def element_stiffness(P, xp=jnp):
    """12 × 12 global stiffness of elements given by their parameters ``P`` (..., 18) = x1, x2, zref (3
    each) [m], end zones a1, a2 [m], section (area, i_y, i_z, torsion, κ, G) and E [SI] (the rows of
    :func:`frame_leg_terms`): :func:`beam_global_stiffness`."""
    props = SectionProperties(*(P[..., 11 + f] for f in range(6)))
    sec = Section(None, None, P[..., 17], None)
    return beam_global_stiffness(P[..., 0:3], P[..., 3:6], P[..., 6:9], sec, P[..., 9], P[..., 10], xp, props=props)


def closed_form_tip_deflection(load: float, length: float, E: float, inertia: float, kappa: float,
                               G: float, area: float) -> float:
    """Timoshenko cantilever tip deflection [m]: PL³/(3EI) + PL/(κGA)."""
    return load * length**3 / (3.0 * E * inertia) + load * length / (kappa * G * area)


"""Rigid-body dynamics of the surgical master from its mass properties: M(q), Coriolis, G(q).

    M(q) q̈ + C(q, q̇) q̇ + G(q) = τ        (seed 003 eq 3)

Every moving part is a rigid body attached to one of the link frames of
:func:`hapticopt.design.master.kinematics.link_frames` (turret, upper arm, driver link, coupler, forearm,
handle) with its mass, its centre of mass and its inertia tensor about the CoM, both in the
frame's axes. The parallelogram is exact: each body's pose is a function of (θ1, θ2, θ3) only,
so the reduced (3-DOF) dynamics follow from the kinetic and potential energy:

* M(q) = Σ_b m_b J_b,vᵀ J_b,v + J_b,ωᵀ (R_b I_b R_bᵀ) J_b,ω + diag(rotor inertia), with the
  CoM Jacobian J_b,v = ∂c_b/∂q and the angular-velocity Jacobian from ∂R_b/∂q_i R_bᵀ (autodiff);
* C(q, q̇)q̇ from the Christoffel symbols of M;
* G(q) = ∂V/∂q, V = g Σ_b m_b z_b(q).

Nothing of the seed-003 gravity form [0, G1 cos θ2, G2 sin θ3] (eq 4) is typed in here: it
follows from the geometry (bodies rotating with θ2 have heights ∝ sin θ2, those rotating with
θ3 heights ∝ −cos θ3), and the tests check it. ``G1 = M g P_x`` and ``G2 = M g P_z`` (eq 10–11)
define the centre-of-mass offset P of the moving links used by the unbalance analysis;
P_x is along the upper arm, P_z along the forearm (downwards at θ2 = θ3 = 0).

Mass properties come from :func:`analytic_mass_properties` (slender rods, point-like
counterweights and handle) unless a list of :class:`BodyMass` is given (e.g. from the CAD).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design.master import kinematics as mk
from hapticopt.design.master.mass import FRAMES, BodyMass, analytic_mass_properties, bodies_from_mass_properties  # noqa: F401
from hapticopt.design.master.params import MasterDesign
from hapticopt.design.units import GRAVITY
from hapticopt.analysis.master import dynamics_numpy as mn
from hapticopt.design.errors import InvalidDesign


#: names of the counterweight bodies (analytic model and CAD part table); every other moving body is a "link"
COUNTERWEIGHTS = ("upper_counterweight", "forearm_counterweight")


class MassModel(NamedTuple):
    """Dynamics parameters as a jax pytree [SI]; nb = number of bodies."""

    kin: mk.MasterParams
    mass: jax.Array  # (nb,) [kg]
    com: jax.Array  # (nb, 3) [m] in the body's link frame
    inertia: jax.Array  # (nb, 3, 3) [kg·m²] about the CoM, link-frame axes
    frame: jax.Array  # (nb, 6) one-hot selection of the link frame
    rotor_inertia: jax.Array  # (3,) [kg·m²] reflected rotor + capstan inertia per joint
    viscous: jax.Array  # (3,) [N·m·s/rad]
    coulomb: jax.Array  # (3,) [N·m]
    gravity: jax.Array  # [m/s²]
    counterweight: jax.Array  # (nb,) 1.0 for the counterweight bodies, 0.0 for the links (compensation model)


def model_of(design: MasterDesign, bodies: tuple[BodyMass, ...] | None = None, *, gravity: float = GRAVITY) -> MassModel:
    """The dynamics model of a design (analytic mass properties unless ``bodies`` is given)."""
    bodies = analytic_mass_properties(design) if bodies is None else tuple(bodies)
    for b in bodies:
        if b.frame not in FRAMES:
            raise ValueError(f"body {b.name!r}: frame {b.frame!r} is not one of {', '.join(FRAMES)}")
    sel = np.zeros((len(bodies), len(FRAMES)))
    for i, b in enumerate(bodies):
        sel[i, FRAMES.index(b.frame)] = 1.0
    a = design.actuators
    return MassModel(
        kin=mk.MasterParams(*(np.asarray(float(v)) for v in mk.params_of(design))),
        mass=np.asarray([b.mass for b in bodies], dtype=float),
        com=np.asarray([b.com for b in bodies], dtype=float).reshape(-1, 3),
        inertia=np.asarray([b.inertia for b in bodies], dtype=float).reshape(-1, 3, 3),
        frame=sel,
        rotor_inertia=np.full(3, a.rotor_inertia),
        viscous=np.full(3, a.viscous),
        coulomb=np.full(3, a.coulomb),
        gravity=np.asarray(float(gravity)),
        counterweight=np.asarray([1.0 if b.name in COUNTERWEIGHTS else 0.0 for b in bodies]),
    )


def _body_poses(model: MassModel, q: jax.Array) -> tuple[jax.Array, jax.Array]:
    """World CoM (nb, 3) and rotation (nb, 3, 3) of every body at a single q (3,)."""
    fr = mk.link_frames(model.kin, q)
    origins = jnp.stack([f.origin for f in fr])  # (6, 3)
    rots = jnp.stack([f.rotation for f in fr])  # (6, 3, 3)
    o = model.frame @ origins
    R = jnp.einsum("bf,fij->bij", model.frame, rots)
    return o + jnp.einsum("bij,bj->bi", R, model.com), R


def potential_energy(model: MassModel, q: jax.Array) -> jax.Array:
    """V(q) = g Σ m_b z_b [J] at a single q (3,)."""
    c, _ = _body_poses(model, q)
    return model.gravity * jnp.sum(model.mass * c[:, 2])


def _mass_matrix_single(model: MassModel, q: jax.Array) -> jax.Array:
    c_fn = lambda qq: _body_poses(model, qq)[0]  # noqa: E731
    R_fn = lambda qq: _body_poses(model, qq)[1]  # noqa: E731
    Jv = jax.jacfwd(c_fn)(q)  # (nb, 3, 3 joints)
    R = R_fn(q)
    dR = jax.jacfwd(R_fn)(q)  # (nb, 3, 3, 3 joints)
    W = jnp.einsum("bikn,bjk->bijn", dR, R)  # ∂R/∂q_n Rᵀ: skew (nb, 3, 3, n)
    Jw = jnp.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)  # vee → (nb, 3, n)
    I_world = jnp.einsum("bij,bjk,blk->bil", R, model.inertia, R)
    M = jnp.einsum("b,bin,bim->nm", model.mass, Jv, Jv) + jnp.einsum("bin,bij,bjm->nm", Jw, I_world, Jw)
    return M + jnp.diag(model.rotor_inertia)


def _broadcast(fn, model: MassModel, q: jax.Array):
    q = jnp.asarray(q, dtype=float)
    if q.ndim == 1:
        return fn(model, q)
    flat = q.reshape(-1, 3)
    out = jax.vmap(lambda qq: fn(model, qq))(flat)
    return out.reshape(q.shape[:-1] + out.shape[1:])


def _gravity_single(model: MassModel, q: jax.Array) -> jax.Array:
    return jax.grad(lambda qq: potential_energy(model, qq))(q)


def _coriolis_single(model: MassModel, q: jax.Array, qd: jax.Array) -> jax.Array:
    dM = jax.jacfwd(lambda qq: _mass_matrix_single(model, qq))(q)  # (i, j, k) = ∂M_ij/∂q_k
    # c_i = Σ_jk (∂M_ij/∂q_k − ½ ∂M_jk/∂q_i) q̇_j q̇_k
    return jnp.einsum("ijk,j,k->i", dM, qd, qd) - 0.5 * jnp.einsum("jki,j,k->i", dM, qd, qd)


_mass_matrix_jit = jax.jit(lambda model, q: _broadcast(_mass_matrix_single, model, q))
_gravity_jit = jax.jit(lambda model, q: _broadcast(_gravity_single, model, q))
_coriolis_jit = jax.jit(jax.vmap(_coriolis_single, in_axes=(None, 0, 0)))


def mass_matrix(model: MassModel, q: jax.Array) -> jax.Array:
    """Joint-space inertia M(q) (…, 3, 3) [kg·m²] including the rotor inertia."""
    return _mass_matrix_jit(model, q)


def gravity_torque(model: MassModel, q: jax.Array) -> jax.Array:
    """G(q) = ∂V/∂q (…, 3) [N·m]: the torque the motors must supply to hold the arm still."""
    return _gravity_jit(model, q)


def coriolis(model: MassModel, q: jax.Array, qd: jax.Array) -> jax.Array:
    """Coriolis and centrifugal torques C(q, q̇) q̇ (…, 3) [N·m]."""
    q, qd = jnp.broadcast_arrays(jnp.asarray(q, dtype=float), jnp.asarray(qd, dtype=float))
    out = _coriolis_jit(model, q.reshape(-1, 3), qd.reshape(-1, 3))
    return out.reshape(q.shape)


def moving_mass(model: MassModel) -> float:
    """M of seed 003 eq 8–9: the total mass of the links that move with θ2/θ3 [kg] (not the turret)."""
    return float(np.sum(np.asarray(model.mass) * (1.0 - np.asarray(model.frame)[:, 0])))


class GravityParameters(NamedTuple):
    """Coefficients of G = [0, G1 cos θ2, G2 sin θ3] (seed 003 eq 4) and the CoM offset (eq 10–11)."""

    G1: float  # [N·m]
    G2: float  # [N·m]
    moving_mass: float  # M [kg]
    com_offset: tuple[float, float]  # (P_x, P_z) = (G1, G2)/(M g) [m]; (0, 0) if M = 0


def gravity_parameters(model: MassModel) -> GravityParameters:
    """G1, G2 read off the general G(q) at θ2 = 0 (cos θ2 = 1) and θ3 = 90° (sin θ3 = 1).

    Uses the NumPy mirror of :func:`gravity_torque` (:mod:`hapticopt.analysis.master.dynamics_numpy`, no jit).
    """

    G = mn.gravity_torque(model, np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.5 * np.pi]]))
    G1, G2 = float(G[0, 1]), float(G[1, 2])
    M = moving_mass(model)
    Mg = M * float(model.gravity)
    P = (G1 / Mg, G2 / Mg) if Mg > 0 else (0.0, 0.0)
    return GravityParameters(G1=G1, G2=G2, moving_mass=M, com_offset=P)


def balancing_counterweights(design: MasterDesign, bodies: tuple[BodyMass, ...] | None = None) -> tuple[float, float]:
    """Counterweight masses (upper, forearm) [kg] at the design's distances giving perfect balance (P = 0).

    G1 and G2 are affine in the upper and forearm counterweight masses respectively (each
    counterweight's height depends on one joint only), so two evaluations of G give the exact
    zero. Raises :class:`design.errors.InvalidDesign` if a distance is zero (nothing to balance
    with) or the balance needs a negative mass.
    """

    cw = design.counterweights
    for dist, key in ((cw.upper_distance, "upper_distance_mm"), (cw.forearm_distance, "forearm_distance_mm")):
        if dist <= 0.0:
            raise InvalidDesign(f"counterweights.{key} = 0 cannot balance the arm: allowed > 0 (mm)")

    def params_for(mu: float, mf: float) -> GravityParameters:
        d = dataclasses.replace(design, counterweights=dataclasses.replace(cw, upper_mass=mu, forearm_mass=mf))
        b = None if bodies is None else _with_counterweights(bodies, mu, mf)
        return gravity_parameters(model_of(d, b))

    g0 = params_for(0.0, 0.0)
    g1 = params_for(1.0, 1.0)
    mu = -g0.G1 / (g1.G1 - g0.G1)
    mf = -g0.G2 / (g1.G2 - g0.G2)
    for m, key in ((mu, "upper_mass_kg"), (mf, "forearm_mass_kg")):
        if m < 0.0:
            raise InvalidDesign(f"counterweights.{key}: perfect balance needs {m:g} kg < 0 at the given distance: "
                                "allowed ≥ 0 (kg); move the counterweight to the other side")
    return float(mu), float(mf)


def counterweights_for_com_offset(design: MasterDesign, com_offset: tuple[float, float]) -> tuple[float, float]:
    """Counterweight masses (upper, forearm) [kg] at the design's distances that put the CoM offset
    at ``com_offset`` = (P_x, P_z) [m] (seed 003 eq 10–11); (0, 0) gives perfect balance.

    G1, G2 and M are affine in the two counterweight masses, so G1 − M g P_x = 0 and
    G2 − M g P_z = 0 is a 2×2 linear system, set up from three evaluations of the general G.
    Negative masses are returned as they are (the caller decides); analytic mass model only.
    """
    cw = design.counterweights

    def residual(mu: float, mf: float) -> np.ndarray:
        d = dataclasses.replace(design, counterweights=dataclasses.replace(cw, upper_mass=mu, forearm_mass=mf))
        gp = gravity_parameters(model_of(d))
        Mg = gp.moving_mass * GRAVITY
        return np.array([gp.G1 - Mg * com_offset[0], gp.G2 - Mg * com_offset[1]])

    r0 = residual(0.0, 0.0)
    A = np.stack([residual(1.0, 0.0) - r0, residual(0.0, 1.0) - r0], axis=1)
    mu, mf = np.linalg.solve(A, -r0)
    return float(mu), float(mf)


def _with_counterweights(bodies: tuple[BodyMass, ...], mu: float, mf: float) -> tuple[BodyMass, ...]:
    out = []
    for b in bodies:
        if b.name == "upper_counterweight":
            b = dataclasses.replace(b, mass=mu)
        elif b.name == "forearm_counterweight":
            b = dataclasses.replace(b, mass=mf)
        out.append(b)
    return tuple(out)

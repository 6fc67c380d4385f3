"""Kinematics of the PHANToM-type surgical master (seed 003): FK, IK, analytic Jacobian, link frames.

Vectorised with jax, float64. Every function takes ``q`` of shape ``(..., 3)`` [rad] (or ``p``
of shape ``(..., 3)`` [m]) and broadcasts over the leading axes.

Frame convention (base frame, z up)
-----------------------------------
* Origin on the θ1 (turret) axis at the base plate; z up; at θ1 = 0 the arm moves in the
  x–z plane and reaches towards +x; y = z × x.
* The shoulder S = (0, 0, h) (h = ``geometry.shoulder_height``) carries the θ2 and θ3 axes,
  both horizontal and normal to the arm plane. In the arm plane use the radial unit vector
  e_ρ = (cos θ1, sin θ1, 0) and e_z; an in-plane direction at elevation a is
  e(a) = cos a·e_ρ + sin a·e_z.
* θ2 is the elevation of the upper arm (length L5) above the horizontal:
  u(θ2) = e(θ2) = c2·e_ρ + s2·e_z. The elbow is E = S + L5·u.
* θ3 is the forearm angle set through the parallelogram, measured from the downward vertical
  towards +ρ: f(θ3) = s3·e_ρ − c3·e_z (θ3 = 0: forearm hanging straight down). The handle is
  p = E + L4·f, i.e. with ρ = L5 c2 + L4 s3:  p = (ρ c1, ρ s1, h + L5 s2 − L4 c3).
  This is the published PHANToM structure (Çavuşoğlu et al. 2002); it reproduces the
  seed-003 gravity form G = [0, G1 cos θ2, G2 sin θ3] (eq 4) and a Jacobian whose
  determinant is ρ·L4·L5·cos(θ2 − θ3) (seed 003 eq 2/5: ∝ cos(θ2 − θ3)).
* The interior (parallelogram) angle between upper arm and forearm at the elbow is
  φ = 90° − θ2 + θ3 (seed 003's joint-range variable); the arm is singular at φ = 0° or 180°
  (cos(θ2 − θ3) = sin φ = 0) and on the turret axis (ρ = 0).
* Parallelogram: the θ3 driver link (length d = ``geometry.driver_link``) points from S in
  direction −f (opposite to the forearm), the coupler runs from the driver tip S − d·f parallel
  to the upper arm to the forearm's rear extension E − d·f.
* θ2 and θ3 are rotations about the horizontal joint axis a = e_ρ × e_z = (sin θ1, −cos θ1, 0)
  (right-hand rule): a positive rotation lifts the upper arm and swings the forearm forward.
  In the turret frame this is the axis (0, −1, 0).

Link frames (for CAD posing, :func:`link_frames`): every link has a local frame with its x axis
along the link, its y axis along the joint axis a (turret-frame (0, −1, 0)) and z = x × y. Origins: turret at the base origin (frame = Rz(θ1)); upper arm at S, x along u;
driver link at S, x along −f; coupler at the driver tip, x along u; forearm at E, x along f;
handle at p, oriented as the forearm.
"""

from __future__ import annotations

from typing import NamedTuple

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design.master.params import MasterDesign

HALF_PI = 0.5 * np.pi


class MasterParams(NamedTuple):
    """Kinematic parameters as a jax pytree [SI]; each entry a scalar or a batch ``(n,)``."""

    upper_arm: jax.Array  # L5 [m]
    forearm: jax.Array  # L4 [m]
    driver_link: jax.Array  # d [m]
    shoulder_height: jax.Array  # h [m]
    theta1_min: jax.Array  # [rad]
    theta1_max: jax.Array
    theta3_min: jax.Array
    theta3_max: jax.Array
    parallelogram_min: jax.Array  # limits of φ = 90° − θ2 + θ3 [rad]
    parallelogram_max: jax.Array


def params_of(design: MasterDesign) -> MasterParams:
    """Kinematic parameters of one design."""
    g, j = design.geometry, design.joints
    vals = (g.upper_arm, g.forearm, g.driver_link, g.shoulder_height, j.theta1_min, j.theta1_max,
            j.theta3_min, j.theta3_max, j.parallelogram_min, j.parallelogram_max)
    return MasterParams(*(jnp.asarray(float(v)) for v in vals))


def stack_params(designs: list[MasterDesign]) -> MasterParams:
    """Parameters of many designs stacked along a leading batch axis (for ``jax.vmap``)."""
    each = [params_of(d) for d in designs]
    return MasterParams(*(jnp.stack(col) for col in zip(*each)))


def _as_params(design_or_params: MasterDesign | MasterParams) -> MasterParams:
    return design_or_params if isinstance(design_or_params, MasterParams) else params_of(design_or_params)


def parallelogram_angle(q: jax.Array) -> jax.Array:
    """φ = 90° − θ2 + θ3 [rad], the elbow's interior angle (seed 003 joint-range variable)."""
    q = jnp.asarray(q)
    return HALF_PI - q[..., 1] + q[..., 2]


def q_from_theta3_phi(theta1: jax.Array, theta3: jax.Array, phi: jax.Array) -> jax.Array:
    """Joint vector (…, 3) from θ1, θ3 and the parallelogram angle φ (θ2 = 90° + θ3 − φ)."""
    theta1, theta3, phi = jnp.broadcast_arrays(jnp.asarray(theta1), jnp.asarray(theta3), jnp.asarray(phi))
    return jnp.stack([theta1, HALF_PI + theta3 - phi, theta3], axis=-1)


def reach(params: MasterParams, q: jax.Array) -> jax.Array:
    """Horizontal distance ρ = L5 cos θ2 + L4 sin θ3 of the handle from the θ1 axis [m]."""
    q = jnp.asarray(q)
    return params.upper_arm * jnp.cos(q[..., 1]) + params.forearm * jnp.sin(q[..., 2])


def forward_kinematics(params: MasterParams, q: jax.Array) -> jax.Array:
    """Handle position p (…, 3) [m] from joint angles q (…, 3) [rad]."""
    q = jnp.asarray(q)
    t1, t2, t3 = q[..., 0], q[..., 1], q[..., 2]
    rho = params.upper_arm * jnp.cos(t2) + params.forearm * jnp.sin(t3)
    z = params.shoulder_height + params.upper_arm * jnp.sin(t2) - params.forearm * jnp.cos(t3)
    return jnp.stack([rho * jnp.cos(t1), rho * jnp.sin(t1), z], axis=-1)


def jacobian(params: MasterParams, q: jax.Array) -> jax.Array:
    """Analytic Jacobian ∂p/∂q (…, 3, 3) [m/rad]; det = ρ·L4·L5·cos(θ2 − θ3).

    Columns: θ1 → ρ·(−s1, c1, 0); θ2 → L5·(−s2 c1, −s2 s1, c2); θ3 → L4·(c3 c1, c3 s1, s3)
    (seed 003 eq 2 in this frame convention).
    """
    q = jnp.asarray(q)
    t1, t2, t3 = q[..., 0], q[..., 1], q[..., 2]
    c1, s1, c2, s2, c3, s3 = jnp.cos(t1), jnp.sin(t1), jnp.cos(t2), jnp.sin(t2), jnp.cos(t3), jnp.sin(t3)
    L5, L4 = params.upper_arm, params.forearm
    rho = L5 * c2 + L4 * s3
    zero = jnp.zeros_like(rho)
    col1 = jnp.stack([-rho * s1, rho * c1, zero], axis=-1)
    col2 = jnp.stack([-L5 * s2 * c1, -L5 * s2 * s1, L5 * c2 + zero], axis=-1)
    col3 = jnp.stack([L4 * c3 * c1, L4 * c3 * s1, L4 * s3 + zero], axis=-1)
    return jnp.stack([col1, col2, col3], axis=-1)


class IkSolution(NamedTuple):
    """Inverse kinematics of handle positions p (…, 3)."""

    q: jax.Array  # (…, 3) joint angles [rad]; elbow branch 0 < φ < 180°
    reachable: jax.Array  # (…,) bool: |L5 − L4| ≤ |p − S| ≤ L5 + L4 (in the arm plane)
    in_range: jax.Array  # (…,) bool: reachable and inside the joint ranges


def inverse_kinematics(params: MasterParams, p: jax.Array, *, rho_sign: float = 1.0) -> IkSolution:
    """Joint angles reaching handle positions ``p`` (…, 3) [m].

    θ1 = atan2(y, x) for ``rho_sign = +1`` (handle in front of the turret axis, the default);
    ``rho_sign = −1`` gives the solution with the handle behind the axis (θ1 + π). The elbow
    branch is the one with 0 < φ < 180° (the parallelogram's working branch). Points out of
    reach get clipped angles and ``reachable = False``; nothing here returns NaN.
    """
    p = jnp.asarray(p)
    x, y = p[..., 0], p[..., 1]
    t1 = jnp.arctan2(rho_sign * y, rho_sign * x)
    rho = rho_sign * jnp.sqrt(x**2 + y**2)
    z = p[..., 2] - params.shoulder_height
    L5, L4 = params.upper_arm, params.forearm
    r2 = rho**2 + z**2
    cphi = (L5**2 + L4**2 - r2) / (2.0 * L5 * L4)
    reachable = jnp.abs(cphi) <= 1.0 + 1e-12
    phi = jnp.arccos(jnp.clip(cphi, -1.0, 1.0))
    # p − S = e(θ2)-rotation of (L5 − L4 cos φ, −L4 sin φ)
    t2 = jnp.arctan2(z, rho) - jnp.arctan2(-L4 * jnp.sin(phi), L5 - L4 * jnp.cos(phi))
    t2 = jnp.arctan2(jnp.sin(t2), jnp.cos(t2))
    t3 = t2 + phi - HALF_PI
    q = jnp.stack([t1, t2, t3], axis=-1)
    return IkSolution(q=q, reachable=reachable, in_range=reachable & in_joint_range(params, q))


def joint_range_margin(design_or_params: MasterDesign | MasterParams, q: jax.Array) -> jax.Array:
    """Smallest distance [rad] of q (…, 3) to a joint limit; negative outside the ranges."""
    prm = _as_params(design_or_params)
    q = jnp.asarray(q)
    phi = parallelogram_angle(q)
    m1 = jnp.minimum(q[..., 0] - prm.theta1_min, prm.theta1_max - q[..., 0])
    m3 = jnp.minimum(q[..., 2] - prm.theta3_min, prm.theta3_max - q[..., 2])
    mp = jnp.minimum(phi - prm.parallelogram_min, prm.parallelogram_max - phi)
    return jnp.minimum(jnp.minimum(m1, m3), mp)


def in_joint_range(design_or_params: MasterDesign | MasterParams, q: jax.Array, *, tol: float = 1e-12) -> jax.Array:
    """True where q (…, 3) lies in the joint ranges (θ1, θ3 and φ = 90° − θ2 + θ3), limits included."""
    return joint_range_margin(design_or_params, q) >= -tol


class Frame(NamedTuple):
    """A rigid frame: origin (…, 3) [m] and rotation (…, 3, 3) whose columns are the local axes."""

    origin: jax.Array
    rotation: jax.Array


class LinkFrames(NamedTuple):
    """Pose of every moving link (see the module docstring for each frame's definition)."""

    turret: Frame
    upper_arm: Frame
    driver_link: Frame
    coupler: Frame
    forearm: Frame
    handle: Frame


def _frame_from_x(origin: jax.Array, x_axis: jax.Array, y_axis: jax.Array) -> Frame:
    z_axis = jnp.cross(x_axis, y_axis)
    return Frame(origin=origin, rotation=jnp.stack([x_axis, y_axis, z_axis], axis=-1))


def link_frames(params: MasterParams, q: jax.Array) -> LinkFrames:
    """Frames of the turret, upper arm, driver link, coupler, forearm and handle at q (…, 3)."""
    q = jnp.asarray(q)
    t1, t2, t3 = q[..., 0], q[..., 1], q[..., 2]
    c1, s1 = jnp.cos(t1), jnp.sin(t1)
    zero, one = jnp.zeros_like(t1), jnp.ones_like(t1)
    e_rho = jnp.stack([c1, s1, zero], axis=-1)
    e_z = jnp.stack([zero, zero, one], axis=-1)
    axis = jnp.stack([s1, -c1, zero], axis=-1)  # θ2/θ3 joint axis a = e_ρ × e_z
    u = jnp.cos(t2)[..., None] * e_rho + jnp.sin(t2)[..., None] * e_z
    f = jnp.sin(t3)[..., None] * e_rho - jnp.cos(t3)[..., None] * e_z
    origin0 = jnp.zeros_like(e_rho)
    shoulder = origin0 + jnp.asarray(params.shoulder_height)[..., None] * e_z
    L5 = jnp.asarray(params.upper_arm)[..., None]
    L4 = jnp.asarray(params.forearm)[..., None]
    d = jnp.asarray(params.driver_link)[..., None]
    elbow = shoulder + L5 * u
    tip = elbow + L4 * f
    driver_tip = shoulder - d * f
    turret = Frame(origin=origin0, rotation=jnp.stack([e_rho, -axis, e_z], axis=-1))
    return LinkFrames(
        turret=turret,
        upper_arm=_frame_from_x(shoulder, u, axis),
        driver_link=_frame_from_x(shoulder, -f, axis),
        coupler=_frame_from_x(driver_tip, u, axis),
        forearm=_frame_from_x(elbow, f, axis),
        handle=_frame_from_x(tip, f, axis),
    )



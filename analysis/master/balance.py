"""Gravity unbalance of the surgical master: force field, maximum force, exact unbalance radius.

Seed 003 (eq 4–12). With the motors off, the hand must hold the gravity torque G(q):
Jᵀ F = G, so the unbalance force at the handle is F = J⁻ᵀ G (eq 5). G has the form
[0, G1 cos θ2, G2 sin θ3] with G1 = M g P_x, G2 = M g P_z (eq 4, 10–11; derived, not assumed,
in :mod:`hapticopt.analysis.master.dynamics`), so at every pose the force is a *linear map of the CoM
offset* P = (P_x, P_z):

    F(q) = A(q) P,    A(q) = M g · J_p(q)⁻ᵀ · diag(cos θ2, sin θ3)      (2×2, in-plane)

(θ1 only turns the force about the vertical; |F| does not depend on it.) Hence

* the admissible region R = {P : max_q |A(q) P| ≤ T} is convex and symmetric; its boundary in
  direction d lies at ρ(d) = T / max_q |A(q) d|;
* the unbalance radius (largest circle about the balance point P = 0 inside R) is exactly
  r = min_d ρ(d) = T / max_q σ_max(A(q)), and the worst direction is the right singular vector
  of A at the maximising pose.

The maxima over the workspace (the rectangle of θ3 and φ = 90° − θ2 + θ3 ranges) are found on
a grid refined by successive zooms around the best point (closed-form 2×2 singular values, so
this is cheap). Poses within ``SINGULAR_MARGIN`` of the parallelogram singularity
(cos(θ2 − θ3) = sin φ → 0) are excluded and the result's status says so; nothing reported is
ever inf or NaN.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.status import Status
from hapticopt.design.master.params import MasterDesign
from hapticopt.design.units import GRAVITY
from hapticopt.design.master import kinematics as mk

FORCE_JND_N = 0.1  # [N] seed 003: 10 % JND of the 1 N mean surgical force
SINGULAR_MARGIN = np.deg2rad(2.0)  # [rad] poses with φ within this of 0° or 180° are excluded

#: grid size per axis and zoom levels of the workspace maximisation per fidelity
_GRID = {Fidelity.DRAFT: (21, 0), Fidelity.STANDARD: (41, 4), Fidelity.FINE: (161, 6)}
_N_DIRECTIONS = {Fidelity.DRAFT: 45, Fidelity.STANDARD: 90, Fidelity.FINE: 360}  # over [0°, 180°)
_REGION_GRID = {Fidelity.DRAFT: 21, Fidelity.STANDARD: 31, Fidelity.FINE: 161}  # region boundary (plot, overlap)


@dataclass(frozen=True, kw_only=True)
class Workspace:
    """The (θ3, φ) rectangle of the joint ranges with the singular strip removed [rad]."""

    theta3: tuple[float, float]
    phi: tuple[float, float]
    clipped: bool  # True if the design's φ range reached into the singular margin


def workspace_of(design: MasterDesign, margin: float = SINGULAR_MARGIN) -> Workspace:
    j = design.joints
    lo, hi = max(j.parallelogram_min, margin), min(j.parallelogram_max, np.pi - margin)
    clipped = lo != j.parallelogram_min or hi != j.parallelogram_max
    if lo >= hi:  # the whole φ range is singular: keep one representative pose
        lo = hi = float(np.clip(0.5 * (j.parallelogram_min + j.parallelogram_max), margin, np.pi - margin))
    return Workspace(theta3=(j.theta3_min, j.theta3_max), phi=(lo, hi), clipped=clipped)


def unbalance_maps(L5: float, L4: float, Mg: float, theta3: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """A(q) (…, 2, 2) [N/m]: the in-plane unbalance force (ρ, z) per unit CoM offset (P_x, P_z)."""
    t2 = 0.5 * np.pi + theta3 - phi
    s2, c2, s3, c3 = np.sin(t2), np.cos(t2), np.sin(theta3), np.cos(theta3)
    det = -L5 * L4 * np.sin(phi)  # det J_p = −L4 L5 cos(θ2 − θ3), cos(θ2 − θ3) = sin φ
    # J_p = [[−L5 s2, L4 c3], [L5 c2, L4 s3]];  J_p⁻ᵀ = (1/det) [[L4 s3, −L5 c2], [−L4 c3, −L5 s2]]
    a11 = L4 * s3 * c2 / det
    a12 = -L5 * c2 * s3 / det
    a21 = -L4 * c3 * c2 / det
    a22 = -L5 * s2 * s3 / det
    return Mg * np.stack([np.stack([a11, a12], -1), np.stack([a21, a22], -1)], -2)


def _sigma_max(A: np.ndarray) -> np.ndarray:
    """Largest singular value of 2×2 matrices (closed form)."""
    fro2 = np.sum(A**2, axis=(-2, -1))
    det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    return np.sqrt(0.5 * (fro2 + np.sqrt(np.maximum(fro2**2 - 4.0 * det**2, 0.0))))


def _maximise(fn, ws: Workspace, n: int, levels: int) -> tuple[float, float, float]:
    """max of fn(θ3, φ) over the rectangle: grid, then zooms around the best point. Returns (value, θ3, φ)."""
    (a0, a1), (b0, b1) = ws.theta3, ws.phi
    t = np.linspace(a0, a1, n)
    p = np.linspace(b0, b1, n)
    T, P = np.meshgrid(t, p, indexing="ij")
    v = fn(T, P)
    k = int(np.argmax(v))
    best = (float(v.flat[k]), float(T.flat[k]), float(P.flat[k]))
    ht, hp = (a1 - a0) / max(n - 1, 1), (b1 - b0) / max(n - 1, 1)
    for _ in range(levels):
        t = np.clip(np.linspace(best[1] - 2 * ht, best[1] + 2 * ht, 11), a0, a1)
        p = np.clip(np.linspace(best[2] - 2 * hp, best[2] + 2 * hp, 11), b0, b1)
        T, P = np.meshgrid(t, p, indexing="ij")
        v = fn(T, P)
        k = int(np.argmax(v))
        if v.flat[k] >= best[0]:
            best = (float(v.flat[k]), float(T.flat[k]), float(P.flat[k]))
        ht, hp = ht * 0.4, hp * 0.4
    return best


@dataclass(frozen=True, kw_only=True)
class MasterBalance:
    """Gravity-unbalance analysis of one design [SI]."""

    threshold: float  # [N]
    moving_mass: float  # M [kg]
    G1: float  # [N·m] eq 4
    G2: float  # [N·m]
    com_offset: tuple[float, float]  # (P_x, P_z) [m] eq 10–11
    max_force: float  # max over the workspace of |F| [N]
    max_force_pose: tuple[float, float, float]  # q [rad] where it occurs (θ1 = 0)
    radius: float  # unbalance radius [m]
    worst_direction: tuple[float, float]  # unit CoM direction limiting the radius
    worst_pose: tuple[float, float, float]  # q [rad] maximising σ_max(A)
    region_angles: np.ndarray = field(repr=False)  # (n,) direction angles ψ of the region boundary [rad]
    region_radii: np.ndarray = field(repr=False)  # (n,) boundary distance ρ(ψ) [m]
    ellipse_axes: tuple[float, float]  # paper-style 45° ellipse fit: semi-axes along (1, 1) and (1, −1) [m]
    ellipse_overlap: float  # area(E ∩ R) / area(E ∪ R)
    fit_axes: tuple[float, float]  # free-tilt ellipse with the region's area second moments: semi-axes (major, minor) [m]
    fit_tilt: float  # angle of its major axis from the P_x axis, in [0, π) [rad] (seed 003: 40°–45°)
    balancing_masses: tuple[float, float]  # counterweights (upper, forearm) for P = 0 [kg]; NaN-free (0, 0) if impossible
    status: Status = Status.OK
    message: str = ""

    @property
    def inside(self) -> bool:
        """True if the design's CoM offset lies inside the unbalance circle."""
        return float(np.hypot(*self.com_offset)) <= self.radius

    def metrics(self) -> dict[str, object]:
        return {
            "max_unbalance_force_N": float(self.max_force),
            "unbalance_radius_mm": float(self.radius * 1e3),
            "com_offset_mm": [float(x * 1e3) for x in self.com_offset],
            "com_inside_unbalance_radius": bool(self.inside),
            "unbalance_ellipse_axes_mm": [float(x * 1e3) for x in self.ellipse_axes],
            "unbalance_ellipse_overlap_pct": float(100.0 * self.ellipse_overlap),
            "unbalance_ellipse_fit_mm": [float(x * 1e3) for x in self.fit_axes],
            "unbalance_ellipse_tilt_deg": float(np.rad2deg(self.fit_tilt)),
            "balancing_counterweights_kg": [float(x) for x in self.balancing_masses],
            "moving_mass_kg": float(self.moving_mass),
        }


def force_field(design: MasterDesign, q: np.ndarray, model: md.MassModel | None = None) -> np.ndarray:
    """Unbalance force F = J⁻ᵀ G(q) (…, 3) [N] from the general dynamics (reference path, jax)."""
    from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
    import jax.numpy as jnp


    model = md.model_of(design) if model is None else model
    q = jnp.asarray(q, dtype=float)
    J = mk.jacobian(model.kin, q)
    G = md.gravity_torque(model, q)
    return np.asarray(jnp.linalg.solve(jnp.swapaxes(J, -1, -2), G[..., None])[..., 0])


def evaluate(design: MasterDesign, *, fidelity: Fidelity = Fidelity.STANDARD, threshold: float = FORCE_JND_N,
             model: md.MassModel | None = None) -> MasterBalance:
    """Unbalance force and radius of ``design`` over its joint-range workspace.

    Status ``ok`` when the unbalance force stays ≤ ``threshold`` [N] everywhere in the joint
    ranges; ``not-met`` (numbers kept) when it does not; ``singular`` when the φ range reaches the
    parallelogram singularity; ``failed`` without a moving mass.
    """
    model = md.model_of(design) if model is None else model
    gp = md.gravity_parameters(model)
    return evaluate_parameters(design, gp, fidelity=fidelity, threshold=threshold)


def evaluate_parameters(design: MasterDesign, gp: md.GravityParameters, *, fidelity: Fidelity = Fidelity.STANDARD,
                        threshold: float = FORCE_JND_N) -> MasterBalance:
    """As :func:`evaluate` from already computed gravity parameters (the fast path of sweeps)."""
    fidelity = Fidelity(fidelity)
    n, levels = _GRID[fidelity]
    L5, L4 = design.geometry.upper_arm, design.geometry.forearm
    ws = workspace_of(design)
    status, message = Status.OK, ""
    if ws.clipped:
        status = Status.SINGULAR
        message = (f"the φ range reaches the parallelogram singularity (cos(θ2 − θ3) = 0): poses within "
                   f"{np.rad2deg(SINGULAR_MARGIN):g}° of it are excluded")
    Mg = gp.moving_mass * GRAVITY
    P = np.asarray(gp.com_offset)
    try:
        masses = md.balancing_counterweights(design)
    except ValueError:
        masses = (0.0, 0.0)
    if Mg <= 0.0:
        empty = np.linspace(0.0, np.pi, 2)
        return MasterBalance(
            threshold=threshold, moving_mass=gp.moving_mass, G1=gp.G1, G2=gp.G2, com_offset=(0.0, 0.0),
            max_force=0.0, max_force_pose=(0.0, 0.0, 0.0), radius=0.0, worst_direction=(1.0, 0.0),
            worst_pose=(0.0, 0.0, 0.0), region_angles=empty, region_radii=np.zeros(2), ellipse_axes=(0.0, 0.0),
            ellipse_overlap=0.0, fit_axes=(0.0, 0.0), fit_tilt=0.0, balancing_masses=masses, status=Status.FAILED,
            message="no moving mass: the CoM offset and the unbalance radius are undefined")

    def q_of(t3: float, ph: float) -> tuple[float, float, float]:
        return (0.0, float(0.5 * np.pi + t3 - ph), float(t3))

    # force magnitude of the design itself
    def fmag(T, Ph):
        return np.linalg.norm(unbalance_maps(L5, L4, Mg, T, Ph) @ P, axis=-1)

    fmax, t3f, phf = _maximise(fmag, ws, n, levels)
    if status is Status.OK and fmax > threshold:  # the requirement this evaluator reports (numbers kept)
        status = Status.NOT_MET
        message = (f"the unbalance force reaches {fmax:.4g} N in the joint ranges: allowed ≤ {threshold:g} N "
                   f"(seed 003: the JND, 10 % of the 1 N mean surgical force)")
    # unbalance radius: T / max σ_max(A)
    smax, t3s, phs = _maximise(lambda T, Ph: _sigma_max(unbalance_maps(L5, L4, Mg, T, Ph)), ws, n, levels)
    radius = threshold / smax
    A_w = unbalance_maps(L5, L4, Mg, np.asarray(t3s), np.asarray(phs))
    worst = np.linalg.svd(A_w)[2][0]
    # boundary of the admissible region ρ(ψ) = T / max_q |A(q) d(ψ)|; symmetric, ρ(ψ + π) = ρ(ψ)
    k = _N_DIRECTIONS[fidelity]
    half = np.linspace(0.0, np.pi, k, endpoint=False)
    m = _REGION_GRID[fidelity]
    (a0, a1), (b0, b1) = ws.theta3, ws.phi
    T, Ph = np.meshgrid(np.linspace(a0, a1, m), np.linspace(b0, b1, m), indexing="ij")
    A = unbalance_maps(L5, L4, Mg, T.ravel(), Ph.ravel())  # (m², 2, 2)
    D = np.stack([np.cos(half), np.sin(half)], 0)  # (2, k)
    gains = np.sqrt(np.max(np.sum((A @ D) ** 2, axis=1), axis=0))  # (k,) max_q |A d|
    gains = np.maximum(gains, smax * 1e-12)  # finite: max |A d| ≥ 0 can only vanish on a null direction
    psi = np.concatenate([half, half + np.pi])
    radii = np.tile(threshold / gains, 2)

    # paper-style ellipse (eq 7/12): axes along the diagonals, semi-axes = exact region extent there
    def extent(direction: np.ndarray) -> float:
        g, _, _ = _maximise(lambda T_, P_: np.linalg.norm(unbalance_maps(L5, L4, Mg, T_, P_) @ direction, axis=-1),
                            ws, n, levels)
        return float(threshold / max(g, smax * 1e-12))

    ax = (extent(np.array([1.0, 1.0]) / np.sqrt(2)), extent(np.array([1.0, -1.0]) / np.sqrt(2)))
    fit_axes, fit_tilt = moment_ellipse(psi, radii)
    rho_e = _ellipse_radius(psi, ax[0], ax[1])
    inter = np.sum(np.minimum(radii, rho_e) ** 2)
    union = np.sum(np.maximum(radii, rho_e) ** 2)
    return MasterBalance(
        threshold=threshold, moving_mass=gp.moving_mass, G1=gp.G1, G2=gp.G2, com_offset=(float(P[0]), float(P[1])),
        max_force=float(fmax), max_force_pose=q_of(t3f, phf), radius=float(radius),
        worst_direction=(float(worst[0]), float(worst[1])), worst_pose=q_of(t3s, phs), region_angles=psi,
        region_radii=radii, ellipse_axes=(float(ax[0]), float(ax[1])), ellipse_overlap=float(inter / union),
        fit_axes=fit_axes, fit_tilt=fit_tilt,
        balancing_masses=masses, status=status, message=message)


def moment_ellipse(psi: np.ndarray, radii: np.ndarray) -> tuple[tuple[float, float], float]:
    """The ellipse with the same area second moments as the star-shaped region ρ(ψ) about its centre.

    ``psi`` uniform over [0, 2π). ∫∫ x xᵀ dA = ∫ ρ⁴/4 · d dᵀ dψ with d = (cos ψ, sin ψ); a uniform
    ellipse with semi-axes (a, b) has ∫∫ x xᵀ dA / area = diag(a², b²)/4, so a, b = 2·√eig and the
    tilt is the major eigenvector's angle. Returns ((a, b) [m], tilt in [0, π) [rad]).
    """
    dpsi = 2 * np.pi / len(psi)
    d = np.stack([np.cos(psi), np.sin(psi)])
    area = 0.5 * np.sum(radii**2) * dpsi
    S = np.einsum("in,jn,n->ij", d, d, radii**4 / 4.0) * dpsi / area
    w, v = np.linalg.eigh(S)
    tilt = float(np.arctan2(v[1, 1], v[0, 1]) % np.pi)
    return (float(2 * np.sqrt(w[1])), float(2 * np.sqrt(max(w[0], 0.0)))), tilt


def _ellipse_radius(psi: np.ndarray, a: float, b: float) -> np.ndarray:
    """Polar radius of an ellipse with semi-axis a along (1, 1)/√2 and b along (1, −1)/√2."""
    u = np.cos(psi - np.pi / 4)
    v = np.sin(psi - np.pi / 4)
    return 1.0 / np.sqrt((u / a) ** 2 + (v / b) ** 2)

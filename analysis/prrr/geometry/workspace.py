"""3-PRRR workspace: volume, largest inscribed vertical cylinder, footprint, Jacobian constancy.

Structure exploited (seed 002, seed digest "A leg geometry consistent with eq (1)"):

* **Stroke.** Slider i sits at D_i = c_e + z − cot β · (u_i·p) (eq 1 with the constant J), so
  |D_i − c_e| ≤ L/2 is a pair of planes per leg. At a point (x, y) the reachable z form the
  interval [−L/2 + cot β·max_i a_i, L/2 + cot β·min_i a_i], a_i = u_i·(x, y): its height is
  h(x, y) = L − cot β (max_i a_i − min_i a_i), piecewise linear in (x, y).
* **Planar reach.** The in-plane R1→R3 vector of leg i is
  ρ = ((a_i − c_u)/sin β, b_i − d2), c_u = d1 − (b5 + r4) cos β, b_i = t_i·(x, y); it does
  not depend on z. Reach |d3 − d4| ≤ |ρ| ≤ d3 + d4 is an elliptic annulus in (x, y).
* **Joint limits.** The only joint whose range changes the reachable set of a translational
  leg by itself is the elbow θ2: |ρ|² = d3² + d4² + 2 d3 d4 cos θ2, so an elbow range
  θ2 ∈ [θ2_min, θ2_max] (absolute value) shrinks the annulus radii. Seed 002 gives none; the
  folded elbow is kept a joint-boss radius from its singularity (:func:`fold_margin`), which
  sets the inner radius; the parts' stops are checked by :mod:`hapticopt.analysis.prrr.geometry.joint_limits`.
  ``WorkspaceParams`` carries the annulus radii and callers may pass tighter ones.

So the workspace is {(x, y) reached by every leg} × z-interval(x, y), and

* **volume** = ∫∫ max(h, 0) dA over the reach region. Along every ray from the z axis the
  reach region is a union of r-intervals with closed-form ends (roots of one quadratic per
  leg and annulus edge) and h is linear in r, so the radial integral is exact; the angle is
  integrated by the midpoint rule over one third of the circle (the region has 3-fold
  symmetry). The angular integrand has kinks, so the error falls as O(n_φ⁻²) (docs/workspace.md).
* **largest inscribed cylinder**: a vertical cylinder of radius R centred on the z axis has
  height H(R) = L − 2R cot β (a disc of radius R spreads max_i a_i − min_i a_i by 2R) as long
  as the disc lies in the reach region, i.e. R ≤ R_reach, the distance from the z axis to the
  edge of the annulus (one leg suffices: every leg sees the same annulus in its own frame).
  "Largest" means **largest volume** πR²H(R): R* = min(R_reach, L tan β / 3). Centring on the
  z axis is optimal for H at any R, and, when the reach region is convex (d3 = d4 or the axis
  outside every hole), also for R (the feasible centres form a convex 3-fold-symmetric set,
  which contains its centroid, the axis). R_reach is computed exactly (sampled start, Newton
  on the ellipse parameter).
* **footprint**: the body in xy (fixed parts, carriages with SEA modules, as built by ``hapticopt.design.prrr.cad``;
  Table 1's "device size" φ260 mm); ``link_sweep_diameter_mm`` is what the R1, R2, R3 bosses sweep over the
  reach region (CAD's elbow branch), ``device_diameter_mm`` the larger: Table 2's elbows swing outside the body.
* **Jacobian constancy**: the IK slider map is differentiated by central differences at
  sampled workspace points; the largest relative deviation of cond₂ from the analytic
  cond₂(J) is reported.

All fidelity levels share these closed forms; they differ in the number of rays (volume
accuracy), the radial samples of the footprint, and (fine only) link interference.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any, NamedTuple

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import jax
import jax.numpy as jnp
import numpy as np
from threadpoolctl import ThreadpoolController

from hapticopt.analysis.compute import DEFAULT, Backend, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.prrr.kinematics import PrrrParams, condition_2norm, inverse_kinematics, jacobian
from hapticopt.analysis.status import Status
from hapticopt.design.prrr.params import GAMMAS, PrrrDesign
from hapticopt.design.errors import HapticoptError
from hapticopt.analysis import interference
from hapticopt.design.prrr import cad as cad_prrr

_GAMMA = np.asarray(GAMMAS)
_THIRD = 2.0 * math.pi / 3.0

def base_envelope(design: PrrrDesign, *, specs: dict | None = None) -> float:
    """Radius [m] of the fixed parts' and carriages' envelope in xy, as built by the CAD (base plate, rails,
    screws, motors, carriages with their SEA housings: ``cad.envelope_radius``); :func:`fallback_envelope`
    where the CAD cannot lay the parts out."""
    try:
        return cad_prrr.envelope_radius(design, specs=specs)
    except HapticoptError:
        return fallback_envelope(design)


def fallback_envelope(design: PrrrDesign) -> float:
    """:func:`base_envelope` where the CAD cannot lay the parts out [m]: the base plate and the rail
    circle r_p + rail_width/2 (a lower bound)."""
    g, s = design.geometry, design.structure
    return max(s.base_radius, g.r_p + s.rail_width / 2.0)


#: Elbow branch of the links' swept extent: the CAD's (``cad.DEFAULT_BRANCH``: elbows outwards, θ2 ≤ 0).
ELBOW_BRANCH = 1

#: Default required cylinder [m] for ``workspace_height_at_diameter_mm`` (seed 002 Table 1: φ140 × 89 mm).
DEFAULT_REQUIRED_DIAMETER, DEFAULT_REQUIRED_HEIGHT = 0.140, 0.089


@dataclass(frozen=True, kw_only=True)
class Sampling:
    """Static sampling of one fidelity level (shapes are static for jit)."""

    n_phi: int  # rays over one third of the circle (volume quadrature)
    n_r: int  # radial samples per ray (footprint, Jacobian check)
    interference: bool  # remove poses with link interference (needs analysis.interference)


SAMPLING: dict[Fidelity, Sampling] = {
    Fidelity.DRAFT: Sampling(n_phi=48, n_r=8, interference=False),
    Fidelity.STANDARD: Sampling(n_phi=192, n_r=16, interference=False),
    Fidelity.FINE: Sampling(n_phi=1536, n_r=32, interference=True),
}

_N_ELLIPSE = 64  # start samples for the distance to the annulus edge
_NEWTON = 8
_FD_STEP = 1e-4  # [m] central-difference step of the Jacobian check (the map is affine)


def fold_margin(design: PrrrDesign) -> float:
    """Smallest in-plane R1–R3 distance |ρ| [m] the legs may take: the folded-elbow singularity
    (R3 axis on R1 axis, |ρ| = 0 when d3 = d4, leaves the leg's rotation about that axis
    unconstrained) is kept one joint-boss radius away (the R3 boss stays off the R1 axis). The
    elbow limit it gives is |θ2| ≤ acos((ρ_min² − d3² − d4²) / (2 d3 d4)); the workspace's inner
    reach hole is |ρ| < max(|d3 − d4|, ρ_min) (issue 15: joint limits from the hardware)."""
    return design.structure.boss_diameter / 2.0


class WorkspaceParams(NamedTuple):
    """Parameters of the workspace computation [SI]; scalars, or ``(n,)`` for a batch."""

    beta: jax.Array
    d1: jax.Array
    d2: jax.Array
    d3: jax.Array
    d4: jax.Array
    r4: jax.Array
    b5: jax.Array
    stroke: jax.Array
    rho_min: jax.Array  # inner reach radius |ρ| (|d3 − d4| without elbow limits)
    rho_max: jax.Array  # outer reach radius (d3 + d4 without elbow limits)
    rail_envelope: jax.Array  # radius of the base plate / carriage / SEA envelope [m]
    boss_radius: jax.Array  # joint boss radius [m]
    required_radius: jax.Array  # radius of the required cylinder [m]


def workspace_params(design: PrrrDesign, *, required_diameter: float = DEFAULT_REQUIRED_DIAMETER,
                     rho_min: float | None = None, rho_max: float | None = None,
                     specs: dict | None = None, envelope: float | None = None) -> WorkspaceParams:
    """Workspace parameters of one design; ``rho_min``/``rho_max`` override the reach annulus
    (e.g. from elbow limits: |ρ|² = d3² + d4² + 2 d3 d4 cos θ2); ``specs``: the design's part
    tables when the caller has them (:func:`base_envelope`); ``envelope``: its :func:`base_envelope`
    when the caller has it [m] (the batched draft evaluator computes every design's at once)."""
    g, s = design.geometry, design.structure
    lo = max(abs(g.d3 - g.d4), fold_margin(design)) if rho_min is None else rho_min
    hi = g.d3 + g.d4 if rho_max is None else rho_max
    vals = (g.beta, g.d1, g.d2, g.d3, g.d4, g.r4, g.b5, g.stroke, lo, hi,
            base_envelope(design, specs=specs) if envelope is None else envelope, s.boss_diameter / 2.0,
            required_diameter / 2.0)
    return WorkspaceParams(*(np.float64(v) for v in vals))


def workspace_params_many(designs: list[PrrrDesign], envelope: np.ndarray, *,
                          required_diameter: float = DEFAULT_REQUIRED_DIAMETER) -> list[WorkspaceParams]:
    """:func:`workspace_params` (default reach annulus) of many designs whose :func:`base_envelope`
    the caller has (``envelope`` (n,) [m]), from one (n, 13) table: the same operations per value,
    so each row equals the per-design result bit for bit (tested)."""
    g = [d.geometry for d in designs]
    d3 = np.array([x.d3 for x in g])
    d4 = np.array([x.d4 for x in g])
    boss = np.array([d.structure.boss_diameter for d in designs]) / 2.0
    cols = [np.array([getattr(x, f) for x in g], dtype=np.float64) for f in ("beta", "d1", "d2")]
    cols += [d3, d4] + [np.array([getattr(x, f) for x in g], dtype=np.float64) for f in ("r4", "b5", "stroke")]
    cols += [np.maximum(np.abs(d3 - d4), boss), d3 + d4, np.asarray(envelope, dtype=np.float64), boss,
             np.full(len(g), required_diameter / 2.0)]
    return [WorkspaceParams(*row) for row in np.stack(cols, axis=1)]


def stack(params: list[WorkspaceParams]) -> WorkspaceParams:
    """Stack many parameter sets along a leading batch axis (jax arrays, for ``jax.vmap``)."""
    return WorkspaceParams(*(jnp.asarray(np.array(col, dtype=np.float64)) for col in zip(*params)))


def _kin_params(wp: WorkspaceParams) -> PrrrParams:
    return PrrrParams(beta=wp.beta, d1=wp.d1, d2=wp.d2, d3=wp.d3, d4=wp.d4, r4=wp.r4, b5=wp.b5, stroke=wp.stroke)


def _c_u(wp: WorkspaceParams, xp):
    """u-coordinate of the reach-ellipse centre in every leg's frame [m]."""
    return wp.d1 - (wp.b5 + wp.r4) * xp.cos(wp.beta)


#: Newton steps on the ellipse angle need a curvature above this fraction of its terms' size
CURVATURE_REL = 1e-9
#: a volume below this fraction of L·ρ_max² is a rounding sliver: the workspace is empty
EMPTY_VOLUME_REL = 1e-12


def _edge_distance(wp: WorkspaceParams, rho, xp):
    """Distance from the z axis to the ellipse |ρ| = rho (leg frame: centre (c_u, d2),
    semi-axes rho·sin β along u and rho along t). Sampled start, then safeguarded Newton on
    the ellipse angle (analytic derivatives)."""
    s, cu, d2 = xp.sin(wp.beta), _c_u(wp, xp), wp.d2
    ax, bx = rho * s, rho

    def f(th):
        return (cu + ax * xp.cos(th)) ** 2 + (d2 + bx * xp.sin(th)) ** 2

    th = xp.linspace(0.0, 2.0 * math.pi, _N_ELLIPSE, endpoint=False)
    th0 = th[xp.argmin(f(th))]
    step_max = 2.0 * math.pi / _N_ELLIPSE
    if xp is np and all(np.ndim(v) == 0 for v in (cu, ax, bx, d2, th0)):
        t = _newton_scalar(cu, ax, bx, d2, th0, step_max)
        return xp.sqrt(xp.minimum(f(t), f(th0)))
    t = th0
    for _ in range(_NEWTON):  # fixed count: unrolled under jit
        c, sn = xp.cos(t), xp.sin(t)
        x, y = cu + ax * c, d2 + bx * sn
        g1 = 2.0 * (-x * ax * sn + y * bx * c)
        g2 = 2.0 * ((ax * sn) ** 2 - x * ax * c + (bx * c) ** 2 - y * bx * sn)
        # a Newton step only where the curvature is clearly positive: g2 above CURVATURE_REL of the
        # size of its terms (decades above their rounding), never on the sign of a rounding-level g2
        g2_scale = 2.0 * ((ax * sn) ** 2 + xp.abs(x * ax * c) + (bx * c) ** 2 + xp.abs(y * bx * sn))
        ok = g2 > CURVATURE_REL * g2_scale
        step = xp.where(ok, g1 / xp.where(ok, g2, 1.0), 0.0)
        t = t - xp.clip(step, -step_max, step_max)
    return xp.sqrt(xp.minimum(f(t), f(th0)))


def _newton_scalar(cu, ax, bx, d2, t, step_max):
    """:func:`_edge_distance`'s Newton steps for one design with numpy (scalars): the same operations on
    the same numbers as Python floats (IEEE double arithmetic either way; the cosine and sine still
    numpy's), the selections (``where``, ``clip``, ``abs``) as Python conditionals, which pick the same
    numbers (on numpy scalars each ``where`` or ``clip`` call cost ≈ 1–4 µs, most of the one-design
    workspace core)."""
    cu, ax, bx, d2, t = (float(v) for v in (cu, ax, bx, d2, t))
    for _ in range(_NEWTON):
        c, sn = float(np.cos(t)), float(np.sin(t))
        x, y = cu + ax * c, d2 + bx * sn
        g1 = 2.0 * (-x * ax * sn + y * bx * c)
        g2 = 2.0 * ((ax * sn) ** 2 - x * ax * c + (bx * c) ** 2 - y * bx * sn)
        g2_scale = 2.0 * ((ax * sn) ** 2 + abs(x * ax * c) + (bx * c) ** 2 + abs(y * bx * sn))
        step = g1 / g2 if g2 > CURVATURE_REL * g2_scale else 0.0
        t = t - min(max(step, -step_max), step_max)  # clip (NaN stays NaN, as numpy's)
    return np.float64(t)


def _ray_intervals(wp: WorkspaceParams, phi, xp):
    """Reach ∩ stroke along rays at angles ``phi`` (n,): sorted breakpoints (n, 8), the
    inclusion flag of each of the 7 segments between them, the stroke spread g (n,), the
    outer interval [lo, hi] (n,) and the holes."""
    s = xp.sin(wp.beta)
    cu = _c_u(wp, xp)
    psi = phi[:, None] - _GAMMA[None, :]  # (n, 3 legs)
    c, sn = xp.cos(psi), xp.sin(psi)
    A = c**2 / s**2 + sn**2
    Bh = c * cu / s**2 + sn * wp.d2
    C = cu**2 / s**2 + wp.d2**2

    def roots(rho):
        disc = Bh**2 - A * (C - rho**2)
        sq = xp.sqrt(xp.maximum(disc, 0.0))
        return (Bh - sq) / A, (Bh + sq) / A, disc >= 0.0

    olo, ohi, ook = roots(wp.rho_max)
    ilo, ihi, iok = roots(wp.rho_min)
    g = xp.max(c, axis=1) - xp.min(c, axis=1)  # spread of u_i·(cos φ, sin φ), in [1.5, √3]
    # (the stroke's ray length per ray; g[..., None] and [..., 0] keep it one value per ray when the
    # parameters are given per ray as (n, 1) columns: workspace_sample_weights_many)
    r_stroke = (wp.stroke * xp.tan(wp.beta) / g[..., None])[..., 0]
    lo = xp.maximum(0.0, xp.max(olo, axis=1))
    hi = xp.minimum(r_stroke, xp.min(ohi, axis=1))
    hi = xp.where(xp.all(ook, axis=1), xp.maximum(hi, lo), lo)
    ilo = xp.where(iok, ilo, 0.0)
    ihi = xp.where(iok, ihi, 0.0)
    bps = xp.concatenate([lo[:, None], hi[:, None],
                          xp.clip(ilo, lo[:, None], hi[:, None]),
                          xp.clip(ihi, lo[:, None], hi[:, None])], axis=1)
    bps = xp.sort(bps, axis=1)
    mid = 0.5 * (bps[:, :-1] + bps[:, 1:])  # (n, 7)
    holes = (ilo, ihi, iok)
    return bps, ~_in_hole(mid, holes, xp), g, lo, hi, holes


def _in_hole(r, holes, xp):
    """Whether radii ``r`` (n, m) on each ray lie strictly inside a leg's inner reach hole."""
    ilo, ihi, iok = holes
    return xp.any(iok[:, None, :] & (ilo[:, None, :] < r[..., None]) & (r[..., None] < ihi[:, None, :]), axis=-1)


def _direction(x, y, xp):
    """(cos, sin) of arctan2(y, x) without the arctangent: (x, y)/|(x, y)|, and (1, 0) at the origin."""
    n = xp.sqrt(x**2 + y**2)
    pos = n > 0.0
    n = xp.where(pos, n, 1.0)
    return xp.where(pos, x / n, 1.0), xp.where(pos, y / n, 0.0)


def workspace_core(wp: WorkspaceParams, *, n_phi: int, n_r: int, xp=np) -> dict:
    """All workspace quantities of one design in SI.

    Pure and written against an array namespace ``xp``: numpy for one design (no jit compile
    on the CLI path), ``jax.numpy`` under ``jax.vmap``/``jax.jit`` for batches. Same
    operations in the same order, so both agree to rounding.
    """
    cot = 1.0 / xp.tan(wp.beta)
    L = wp.stroke
    s = xp.sin(wp.beta)
    dphi = _THIRD / n_phi
    phi = (xp.arange(n_phi) + 0.5) * dphi
    bps, keep, g, lo, hi, holes = _ray_intervals(wp, phi, xp)
    a, b = bps[:, :-1], bps[:, 1:]
    radial = L * (b**2 - a**2) / 2.0 - cot * g[:, None] * (b**3 - a**3) / 3.0
    volume = 3.0 * dphi * xp.sum(xp.where(keep, radial, 0.0))

    # largest inscribed vertical cylinder about the z axis (max volume πR²(L − 2R cot β))
    cu = _c_u(wp, xp)
    rho0_2 = (cu / s) ** 2 + wp.d2**2  # |ρ|² of the axis point
    axis_in = (rho0_2 <= wp.rho_max**2) & (rho0_2 >= wp.rho_min**2)
    r_reach = xp.minimum(_edge_distance(wp, wp.rho_max, xp), _edge_distance(wp, wp.rho_min, xp))
    r_reach = xp.where(axis_in, r_reach, 0.0)
    r_cyl = xp.minimum(r_reach, L * xp.tan(wp.beta) / 3.0)
    h_cyl = xp.where(r_cyl > 0.0, L - 2.0 * r_cyl * cot, 0.0)
    h_req = xp.where(wp.required_radius <= r_reach, xp.maximum(L - 2.0 * wp.required_radius * cot, 0.0), 0.0)

    # links' swept extent over n_r radii per ray spanning [lo, hi] (reach region in xy)
    frac = xp.linspace(0.0, 1.0, n_r)
    r = lo[:, None] + frac[None, :] * (hi - lo)[:, None]  # (n_phi, n_r)
    mask = (hi > lo)[:, None] & ~_in_hole(r, holes, xp)
    gam = _GAMMA
    ca, sa = xp.cos(phi[:, None, None] - gam), xp.sin(phi[:, None, None] - gam)  # (n_phi, 1, 3)
    rv = (r[..., None] * ca - cu) / s  # in-plane R1→R3 vector per leg, (n_phi, n_r, 3)
    rt = r[..., None] * sa - wp.d2
    c2 = xp.clip((rv**2 + rt**2 - wp.d3**2 - wp.d4**2) / (2.0 * wp.d3 * wp.d4), -1.0, 1.0)  # cos θ2
    s2 = (1.0 - 2.0 * ELBOW_BRANCH) * xp.sqrt(1.0 - c2**2)  # sin θ2 on the elbow branch
    # θ1 = atan2(rt, rv) − atan2(d4 sin θ2, d3 + d4 cos θ2) through its cosine and sine (no inverse
    # trigonometry, costly in batched XLA float64); a zero vector has the angle 0, as arctan2(0, 0)
    ca1, sa1 = _direction(rv, rt, xp)
    cg, sg = _direction(wp.d3 + wp.d4 * c2, wp.d4 * s2, xp)
    c1, s1 = ca1 * cg + sa1 * sg, sa1 * cg - ca1 * sg  # cos θ1, sin θ1
    c12, s12 = c1 * c2 - s1 * s2, s1 * c2 + c1 * s2  # cos, sin of θ1 + θ2
    # xy of the R2 axis point B in leg coordinates (u, t): A + d3·(cos θ1 sin β, sin θ1)
    bu, bt = wp.d1 + wp.d3 * c1 * s, wp.d2 + wp.d3 * s1
    qu = bu + wp.d4 * c12 * s - wp.r4 * xp.cos(wp.beta)
    qt = bt + wp.d4 * s12
    radius = xp.maximum(xp.sqrt(bu**2 + bt**2), xp.sqrt(qu**2 + qt**2))
    link_extent = xp.max(xp.where(mask[..., None], radius, 0.0))
    link_extent = xp.maximum(link_extent, xp.sqrt(wp.d1**2 + wp.d2**2)) + wp.boss_radius
    footprint = 2.0 * wp.rail_envelope

    # tangent roots leave rounding-sized slivers: below EMPTY_VOLUME_REL · L ρ_max² counts as empty
    empty = ~(volume > EMPTY_VOLUME_REL * L * wp.rho_max**2)
    return {
        "volume": xp.maximum(volume, 0.0),
        "reach_radius": r_reach,
        "cylinder_radius": r_cyl,
        "cylinder_height": h_cyl,
        "height_at_required": h_req,
        "footprint_diameter": footprint,
        "link_extent": link_extent,
        "empty": empty,
    }


@functools.cache
def _batched(n_phi: int, n_r: int):
    fn = functools.partial(workspace_core, n_phi=n_phi, n_r=n_r, xp=jnp)
    return jax.jit(jax.vmap(fn))


def sample_points(wp: WorkspaceParams, *, n_phi: int, n_r: int, n_z: int) -> np.ndarray:
    """Points of the reach ∩ stroke workspace [m], (m, 3): ``n_r`` radii on each of ``n_phi``
    rays per third of the circle (rotated copies fill the other two thirds), ``n_z`` heights
    spanning each column's z interval (inset by 1 % so every point is strictly inside)."""
    return _sample_points(wp, n_phi=n_phi, n_r=n_r, n_z=n_z)[0]


def _sample_points(wp: WorkspaceParams, *, n_phi: int, n_r: int, n_z: int) -> tuple:
    """:func:`sample_points` and its rays' outer intervals ``lo``, ``hi`` (n_phi,) [m] (for
    :func:`workspace_sample_weights`, which weighs the points by them)."""
    wpn = WorkspaceParams(*(np.asarray(v, dtype=float) for v in wp))
    phi = (np.arange(n_phi) + 0.5) * (_THIRD / n_phi)
    _, _, _, lo, hi, holes = _ray_intervals(wpn, phi, np)
    frac = (np.arange(n_r) + 0.5) / n_r
    r = lo[:, None] + frac[None, :] * (hi - lo)[:, None]
    mask = (hi > lo)[:, None] & ~_in_hole(r, holes, np)
    phis = np.concatenate([phi, phi + _THIRD, phi - _THIRD])
    r3 = np.concatenate([r, r, r])
    m3 = np.concatenate([mask, mask, mask])
    x, y = r3 * np.cos(phis)[:, None], r3 * np.sin(phis)[:, None]
    a = x[..., None] * np.cos(_GAMMA) + y[..., None] * np.sin(_GAMMA)
    cot = 1.0 / np.tan(float(wpn.beta))
    z0 = -wpn.stroke / 2.0 + cot * a.max(axis=-1)
    z1 = wpn.stroke / 2.0 + cot * a.min(axis=-1)
    ok = m3 & (z1 > z0)
    tz = 0.01 + 0.98 * (np.arange(n_z) + 0.5) / n_z
    z = z0[ok][:, None] + tz[None, :] * (z1 - z0)[ok][:, None]
    xy = np.stack([x[ok], y[ok]], axis=-1)
    xyz = np.concatenate([np.repeat(xy, n_z, axis=0), z.reshape(-1, 1)], axis=1)
    return xyz, lo, hi


@jax.jit
def _fd_condition(kp: PrrrParams, pts: jax.Array) -> tuple[jax.Array, jax.Array]:
    """cond₂ of the central-difference Jacobian of the IK slider map at ``pts`` (m, 3), and
    the analytic cond₂(J)."""
    eye = jnp.eye(3) * _FD_STEP
    plus = inverse_kinematics(kp, pts[:, None, :] + eye).sliders  # (m, 3 directions, 3 legs)
    minus = inverse_kinematics(kp, pts[:, None, :] - eye).sliders
    jinv = jnp.swapaxes((plus - minus) / (2.0 * _FD_STEP), -1, -2)  # rows legs, columns directions
    return condition_2norm(jinv), condition_2norm(jacobian(kp.beta))  # cond(J⁻¹) = cond(J)


def jacobian_constancy(design: PrrrDesign, *, n_phi: int = 24, n_r: int = 6, n_z: int = 3) -> tuple[float, int]:
    """Largest relative deviation of the finite-difference cond₂ from the analytic one over
    sampled workspace points (uses the geometric IK of :mod:`hapticopt.design.prrr.kinematics`, not
    the closed forms of this module), and the number of points."""
    wp = workspace_params(design)
    pts = sample_points(wp, n_phi=n_phi, n_r=n_r, n_z=n_z)
    if len(pts) == 0:
        return 0.0, 0
    cond_fd, cond = _fd_condition(_kin_params(wp), jnp.asarray(pts))
    dev = np.abs(np.asarray(cond_fd) - float(cond)) / float(cond)
    return float(dev.max()), len(pts)


#: rays per third of the circle of the closure test (the workspace's draft volume sampling)
CLOSURE_RAYS = 48


def _closure_params(design: PrrrDesign) -> WorkspaceParams:
    """Workspace parameters with the pure kinematic annulus (no fold margin); the envelope, which
    does not change emptiness, is left at 0 (no CAD call)."""
    g, s = design.geometry, design.structure
    vals = (g.beta, g.d1, g.d2, g.d3, g.d4, g.r4, g.b5, g.stroke, abs(g.d3 - g.d4), g.d3 + g.d4, 0.0,
            s.boss_diameter / 2.0, DEFAULT_REQUIRED_DIAMETER / 2.0)
    return WorkspaceParams(*(np.float64(v) for v in vals))


#: closure verdicts kept (design → message; oldest dropped first): a whole chunk of the batched draft
#: evaluator, whose designs are asked several times. A memo of a pure function: it never changes the route.
CLOSURE_CACHE = 4096
#: distinct designs of one :func:`closure_many` call from which it takes the jitted pass (fewer: numpy one
#: by one, no compile)
CLOSURE_BATCH_AFTER = 16
_closures: dict[PrrrDesign, str] = {}


def closure(design: PrrrDesign) -> str:
    """'' when some pose closes every leg within its reach and slider stroke, else why not (remembered:
    :data:`CLOSURE_CACHE`)."""
    found = _closures.get(design)
    if found is None:
        found = _remember(design, _closure_message(design) if _closure_empty(design) else "")
    return found


def _closure_empty(design: PrrrDesign) -> bool:
    """Whether no pose closes the chain: the numpy workspace core at :data:`CLOSURE_RAYS` rays."""
    return bool(workspace_core(_closure_params(design), n_phi=CLOSURE_RAYS, n_r=2)["empty"])


def _remember(design: PrrrDesign, message: str) -> str:
    if len(_closures) >= CLOSURE_CACHE:
        _closures.pop(next(iter(_closures)), None)
    _closures[design] = message
    return message


def closure_many(designs: list[PrrrDesign], *, compute: Compute = DEFAULT) -> list[str]:
    """:func:`closure` of every design, remembered for the later :func:`closure` calls. The route follows
    the call alone: :data:`CLOSURE_BATCH_AFTER` distinct designs or more go through one jitted pass
    (:func:`closure_batch`) unless ``compute`` says numpy; fewer take :func:`closure` one by one. Both give
    the same verdicts: the emptiness threshold ``EMPTY_VOLUME_REL`` lies four decades above float64
    rounding (tested on designs that close, do not close, and have almost no workspace)."""
    unique = list(dict.fromkeys(designs))
    if len(unique) < CLOSURE_BATCH_AFTER or compute.backend is Backend.NUMPY:
        return [closure(d) for d in designs]
    found: dict[PrrrDesign, str] = {}
    for k in range(0, len(unique), CLOSURE_CACHE // 2):  # a pass never drops its own designs
        part = unique[k:k + CLOSURE_CACHE // 2]
        found.update((d, _remember(d, message)) for d, message in zip(part, closure_batch(part)))
    return [found[d] for d in designs]


def closure_batch(designs: list[PrrrDesign]) -> list[str]:
    """:func:`closure` of many designs in one vmapped, jitted call (the batch padded to the next power
    of two: one compile per padded size), uncached."""
    if not designs:
        return []
    n = len(designs)
    size = 1 << (n - 1).bit_length()
    cols = [np.array(col, dtype=np.float64) for col in zip(*(_closure_params(d) for d in designs))]
    padded = WorkspaceParams(*(np.concatenate([c, np.repeat(c[-1:], size - n)]) for c in cols))
    empty = np.asarray(_batched(CLOSURE_RAYS, 2)(padded)["empty"])[:n]
    return [_closure_message(d) if e else "" for d, e in zip(designs, empty.tolist())]


def _closure_message(design: PrrrDesign) -> str:
    g = design.geometry
    # the nearest the z axis (the home pose) comes to a leg's reach: |ρ| of the axis point
    c_u = g.d1 - (g.b5 + g.r4) * math.cos(g.beta)
    rho_axis = math.hypot(c_u / math.sin(g.beta), g.d2)
    return (f"the chain does not close: no end-effector position is reached by every leg within "
            f"|d3 − d4| ≤ |ρ| ≤ d3 + d4 = {(g.d3 + g.d4) * 1e3:.4g} mm and the slider stroke "
            f"{g.stroke * 1e3:.4g} mm (|ρ| = {rho_axis * 1e3:.4g} mm at the home pose)")


@dataclass(frozen=True, kw_only=True)
class PrrrWorkspace:
    """Workspace of one 3-PRRR design [SI]."""

    volume: float  # [m³] reach ∩ stroke (the same at every fidelity; after interference: ``free_volume``)
    reach_radius: float  # [m] distance from the z axis to the reach edge
    cylinder_diameter: float  # [m] largest-volume vertical cylinder on the z axis
    cylinder_height: float  # [m]
    required_diameter: float  # [m]
    height_at_required: float  # [m] height of a cylinder of the required diameter (0 if it does not fit)
    footprint_diameter: float  # [m] device body in xy (fixed parts and carriages; seed 002's "device size")
    link_sweep_diameter: float = 0.0  # [m] links' swept extent over the reach region (elbow branch of the CAD)
    condition_deviation: float | None = None  # fine only: max relative deviation of the FD cond₂
    condition_points: int = 0  # points of the constancy check
    interference_removed: float | None = None  # fine only: fraction of sampled volume lost to interference
    free_volume: float | None = None  # fine only: [m³] volume after removing the colliding share
    fidelity: Fidelity = Fidelity.STANDARD
    status: Status = Status.OK
    message: str = ""

    @property
    def footprint_ratio(self) -> float:
        """Inscribed-cylinder diameter over footprint diameter (seed 002: φ140 / φ260)."""
        return self.cylinder_diameter / self.footprint_diameter if self.footprint_diameter > 0 else 0.0

    @property
    def device_diameter(self) -> float:
        """The whole device's diameter in xy [m]: the body's footprint or the links' sweep over the reach region,
        whichever is larger (a housing of the body's size alone would be struck by the elbows)."""
        return max(self.footprint_diameter, self.link_sweep_diameter)

    def metrics(self) -> dict[str, object]:
        """Engineering-unit metrics (names carry their units)."""
        out: dict[str, object] = {
            "workspace_volume_mm3": self.volume * 1e9,
            "workspace_cylinder_diameter_mm": self.cylinder_diameter * 1e3,
            "workspace_cylinder_height_mm": self.cylinder_height * 1e3,
            "workspace_height_at_diameter_mm": self.height_at_required * 1e3,
            "workspace_required_diameter_mm": self.required_diameter * 1e3,
            "footprint_diameter_mm": self.footprint_diameter * 1e3,
            "link_sweep_diameter_mm": self.link_sweep_diameter * 1e3,
            "device_diameter_mm": self.device_diameter * 1e3,
            "workspace_footprint_ratio": self.footprint_ratio,
        }
        if self.condition_deviation is not None:
            out["jacobian_condition_deviation"] = self.condition_deviation
        if self.interference_removed is not None:
            out["workspace_interference_removed_fraction"] = self.interference_removed
        if self.free_volume is not None:
            out["workspace_free_volume_mm3"] = self.free_volume * 1e9
        return out


def _result(arrays: dict, required_radius: float, fidelity: Fidelity,
            required_height: float = DEFAULT_REQUIRED_HEIGHT) -> PrrrWorkspace:
    return _result_of({k: float(np.asarray(v)) for k, v in arrays.items()}, required_radius, fidelity,
                      required_height)


def result_rows(arrays: dict) -> list[dict[str, float]]:
    """Per-design rows of Python floats of stacked :func:`workspace_core` arrays (leading axis: the
    batched draft evaluator's designs), converted in one pass per array: the values ``_result``
    converts one by one (``empty`` as 0.0 or 1.0)."""
    cols = {k: np.asarray(v, dtype=float).tolist() for k, v in arrays.items()}
    return [dict(zip(cols, vals)) for vals in zip(*cols.values())]


def _result_of(vals: dict[str, float], required_radius: float, fidelity: Fidelity,
               required_height: float = DEFAULT_REQUIRED_HEIGHT) -> PrrrWorkspace:
    """The result from one design's :func:`workspace_core` values as Python floats (:func:`result_rows`)."""
    if not all(math.isfinite(v) for v in vals.values()):  # never report NaN: zero and say so
        return PrrrWorkspace(volume=0.0, reach_radius=0.0, cylinder_diameter=0.0, cylinder_height=0.0,
                             required_diameter=2.0 * required_radius, height_at_required=0.0,
                             footprint_diameter=0.0, fidelity=fidelity, status=Status.FAILED,
                             message="workspace computation gave a non-finite value")
    empty = bool(vals["empty"])
    status, message = Status.OK, ""
    if empty:
        status, message = Status.EMPTY, "no point is reached by every leg within the slider stroke"
    elif vals["height_at_required"] < required_height:
        # the requirement this evaluator reports: the φD × H cylinder fits reach and stroke
        # (a margin of the height in metres, decades above rounding; 89 mm vs prrr-paper's 89.17 mm)
        status = Status.NOT_MET
        fits = (f"height {vals['height_at_required'] * 1e3:.4g} mm at that diameter"
                if vals["height_at_required"] > 0.0 else "that diameter does not fit")
        message = (f"the required φ{2e3 * required_radius:g} × {required_height * 1e3:g} mm cylinder does not fit "
                   f"reach and stroke: {fits} (reach radius {vals['reach_radius'] * 1e3:.4g} mm)")
    zero = 0.0 if empty else 1.0
    return PrrrWorkspace(
        volume=zero * vals["volume"],
        reach_radius=zero * vals["reach_radius"],
        cylinder_diameter=zero * 2.0 * vals["cylinder_radius"],
        cylinder_height=zero * vals["cylinder_height"],
        required_diameter=2.0 * required_radius,
        height_at_required=zero * vals["height_at_required"],
        footprint_diameter=vals["footprint_diameter"],
        link_sweep_diameter=2.0 * vals["link_extent"],
        fidelity=fidelity,
        status=status,
        message=message,
    )


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD,
             required_diameter: float = DEFAULT_REQUIRED_DIAMETER,
             required_height: float = DEFAULT_REQUIRED_HEIGHT,
             interference: bool | None = None, shared: Any = None) -> PrrrWorkspace:
    """Workspace of ``design``: reach and stroke at every level; at fine fidelity also the
    numerical check of the constant Jacobian and link interference.

    ``required_diameter`` [m]: the diameter of ``workspace_height_at_diameter_mm``;
    ``required_height`` [m]: the height it must reach. Status ``ok`` when that cylinder fits
    reach and stroke; ``not-met`` (numbers kept) when it does not; ``empty`` when no point is
    reached; ``not-assemblable`` when the chain does not close at all
    (:func:`hapticopt.analysis.prrr.geometry.assembly.closure`; the metrics are then 0, exactly).
    ``interference``: check link interference with the manifold3d reference on the 216 poses of
    :data:`INTERFERENCE_SAMPLING` (default: the fidelity's setting, fine only); it gives
    ``workspace_free_volume_mm3`` (``workspace_volume_mm3`` is reach-and-stroke at every level).
    The inscribed-cylinder metrics are always reach-and-stroke; the collision-free cylinder is
    :mod:`hapticopt.analysis.prrr.collision.free_workspace`. The fast model for the
    optimiser is a separate evaluator, :mod:`hapticopt.analysis.prrr.collision.interference`. ``shared``: the
    registry call's :class:`hapticopt.analysis.prrr.shared.DesignSteps` of ``design`` (the envelope).
    """
    fidelity = Fidelity(fidelity)
    smp = SAMPLING[fidelity]
    wp = workspace_params(design, required_diameter=required_diameter,
                          envelope=None if shared is None else shared.envelope(design))
    core = (workspace_core(wp, n_phi=smp.n_phi, n_r=smp.n_r, xp=np) if shared is None
            else shared.workspace_core(design, wp, n_phi=smp.n_phi, n_r=smp.n_r))
    result = _assembled(design, _result(core, required_diameter / 2.0, fidelity, required_height))
    if fidelity is Fidelity.FINE:
        dev, n = jacobian_constancy(design)
        result = dataclasses.replace(result, condition_deviation=dev, condition_points=n)
    if (smp.interference if interference is None else interference) and result.status.metrics_hold \
            and result.status is not Status.EMPTY:
        result = _with_interference(design, result)
    return result


def evaluate_batch(designs: list[PrrrDesign], *, fidelity: Fidelity = Fidelity.STANDARD,
                   required_diameter: float = DEFAULT_REQUIRED_DIAMETER,
                   required_height: float = DEFAULT_REQUIRED_HEIGHT) -> list[PrrrWorkspace]:
    """Reach-and-stroke workspace of many designs in one vmapped, jitted call (the fine-level
    Jacobian check and interference are not batched). Agrees with :func:`evaluate` to
    rounding on every batched metric."""
    fidelity = Fidelity(fidelity)
    if not designs:
        return []
    wp = stack([workspace_params(d, required_diameter=required_diameter) for d in designs])
    return [_assembled(d, _result(r, required_diameter / 2.0, fidelity, required_height))
            for d, r in zip(designs, batch_arrays(wp, fidelity=fidelity))]


def _assembled(design: PrrrDesign, result: PrrrWorkspace) -> PrrrWorkspace:
    """``result``, or ``not-assemblable`` when the chain does not close (its metrics, 0, stay)."""
    from_status = result.status in (Status.OK, Status.NOT_MET, Status.EMPTY)
    blocked = closure(design) if from_status else ""
    if not blocked:
        return result
    return dataclasses.replace(result, status=Status.NOT_ASSEMBLABLE, message=blocked)


def batch_arrays(wp: WorkspaceParams, *, fidelity: Fidelity = Fidelity.STANDARD) -> list[dict[str, np.ndarray]]:
    """Per-design SI arrays of a stacked batch ``wp`` (leading axis n); compiled once per
    fidelity and batch size."""
    smp = SAMPLING[Fidelity(fidelity)]
    out = _batched(smp.n_phi, smp.n_r)(wp)
    out = {k: np.asarray(v) for k, v in out.items()}
    n = out["volume"].shape[0]
    return [{k: v[i] for k, v in out.items()} for i in range(n)]


#: sampling of the interference checks (3·n_phi·n_r·n_z = 216 poses at most)
INTERFERENCE_SAMPLING = dict(n_phi=6, n_r=4, n_z=3)


def workspace_sample_weights(design: PrrrDesign, *, n_phi: int, n_r: int, n_z: int,
                             specs: dict | None = None, wp: WorkspaceParams | None = None
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Workspace sample points (m, 3) [m] (:func:`sample_points`) and their volume weights (m,)
    [m³] (polar cells: r·Δr·Δφ·Δz); ``specs``: the design's part tables when the caller has them
    (:func:`workspace_params`); ``wp``: its default :func:`workspace_params` when the caller has them."""
    wp = workspace_params(design, specs=specs) if wp is None else wp
    pts, lo, hi = _sample_points(wp, n_phi=n_phi, n_r=n_r, n_z=n_z)  # the rays' intervals once, for both
    if len(pts) == 0:
        return pts, np.zeros(0)
    r = np.hypot(pts[:, 0], pts[:, 1])
    ang = np.mod(np.arctan2(pts[:, 1], pts[:, 0]), _THIRD)
    k = np.clip((ang / (_THIRD / n_phi)).astype(int), 0, n_phi - 1)
    a = pts[:, :2] @ np.stack([np.cos(_GAMMA), np.sin(_GAMMA)])
    cot = 1.0 / math.tan(design.geometry.beta)
    dz = np.maximum(design.geometry.stroke - cot * (a.max(axis=1) - a.min(axis=1)), 0.0) / n_z
    weights = r * (hi - lo)[k] / n_r * (_THIRD / n_phi) * dz
    return pts, weights


def _max3(a: np.ndarray) -> np.ndarray:
    """``a.max(axis=-1)`` of a last axis of 3, elementwise (maximum is exact: the same floats, NaN kept)."""
    return np.maximum(np.maximum(a[..., 0], a[..., 1]), a[..., 2])


def _min3(a: np.ndarray) -> np.ndarray:
    """``a.min(axis=-1)`` of a last axis of 3, elementwise (the same floats, NaN kept)."""
    return np.minimum(np.minimum(a[..., 0], a[..., 1]), a[..., 2])


@functools.cache
def _blas() -> ThreadpoolController:
    return ThreadpoolController()  # once: it enumerates the loaded BLAS libraries


def workspace_sample_weights_many(designs: list[PrrrDesign], wps: list[WorkspaceParams], *, n_phi: int, n_r: int,
                                  n_z: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """:func:`workspace_sample_weights` of many designs (their default :func:`workspace_params` ``wps``) in
    one numpy pass over the rays of every design: the same elementwise operations on longer arrays, so each
    design's points and weights equal the per-design function's bit for bit (tested)."""
    n = len(designs)
    if n == 0:
        return []
    cols = [np.array([float(w[k]) for w in wps]) for k in range(len(WorkspaceParams._fields))]
    wpn = WorkspaceParams(*(np.repeat(col, n_phi)[:, None] for col in cols))  # one row per ray
    phi1 = (np.arange(n_phi) + 0.5) * (_THIRD / n_phi)
    _, _, _, lo, hi, holes = _ray_intervals(wpn, np.tile(phi1, n), np)
    # sample_points, with a leading design axis
    frac = (np.arange(n_r) + 0.5) / n_r
    r = lo[:, None] + frac[None, :] * (hi - lo)[:, None]
    mask = ((hi > lo)[:, None] & ~_in_hole(r, holes, np)).reshape(n, n_phi, n_r)
    r = r.reshape(n, n_phi, n_r)
    phis = np.concatenate([phi1, phi1 + _THIRD, phi1 - _THIRD])
    r3 = np.concatenate([r, r, r], axis=1)
    m3 = np.concatenate([mask, mask, mask], axis=1)
    x, y = r3 * np.cos(phis)[None, :, None], r3 * np.sin(phis)[None, :, None]
    a = x[..., None] * np.cos(_GAMMA) + y[..., None] * np.sin(_GAMMA)
    beta, stroke = cols[0], cols[7]
    cot = np.array([1.0 / np.tan(b) for b in beta])[:, None, None]  # sample_points: np.tan of the float
    # the largest and smallest of the three legs' a by pairwise maximum and minimum (``a.max(axis=-1)``'s floats)
    z0 = -stroke[:, None, None] / 2.0 + cot * _max3(a)
    z1 = stroke[:, None, None] / 2.0 + cot * _min3(a)
    ok = m3 & (z1 > z0)
    tz = 0.01 + 0.98 * (np.arange(n_z) + 0.5) / n_z
    z = z0[ok][:, None] + tz[None, :] * (z1 - z0)[ok][:, None]
    xy = np.stack([x[ok], y[ok]], axis=-1)
    pts = np.concatenate([np.repeat(xy, n_z, axis=0), z.reshape(-1, 1)], axis=1)
    counts = ok.reshape(n, -1).sum(axis=1) * n_z
    owner = np.repeat(np.arange(n), counts)
    # workspace_sample_weights' polar-cell weights
    rr = np.hypot(pts[:, 0], pts[:, 1])
    # each point's ray within the third (the per-design function bins its angle: every point lies at its
    # ray's mid-bin angle, r > 0, so the bin is the ray's index)
    k = np.repeat(np.broadcast_to((np.arange(3 * n_phi) % n_phi)[None, :, None], ok.shape)[ok], n_z)
    cot_w = np.array([1.0 / math.tan(d.geometry.beta) for d in designs])  # the per-design math.tan
    stroke_w = np.array([d.geometry.stroke for d in designs])
    with _blas().limit(limits=1, user_api="blas"):  # one thread: OpenBLAS's threads spin on 2 cores
        a = pts[:, :2] @ np.stack([np.cos(_GAMMA), np.sin(_GAMMA)])  # the per-design product, bit for bit
    dz = np.maximum(stroke_w[owner] - cot_w[owner] * (_max3(a) - _min3(a)), 0.0) / n_z
    w = rr * (hi - lo)[owner * n_phi + k] / n_r * (_THIRD / n_phi) * dz
    ends = np.cumsum(counts)
    return [(pts[e - c:e], w[e - c:e]) for e, c in zip(ends.tolist(), counts.tolist())]


def interference_samples(design: PrrrDesign, *, n_phi: int, n_r: int, n_z: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Workspace sample points (m, 3) [m], their volume weights (m,) [m³] (polar cells:
    r·Δr·Δφ·Δz) and whether each pose is free of link interference (``analysis.interference``,
    the CAD's parts and elbow branch)."""

    pts, weights = workspace_sample_weights(design, n_phi=n_phi, n_r=n_r, n_z=n_z)
    if len(pts) == 0:
        return pts, weights, np.zeros(0, dtype=bool)
    model = interference.prepare(design)
    free = np.array([res.ok for res in interference.check_poses(model, pts, branch=ELBOW_BRANCH)])
    return pts, weights, free


def _with_interference(design: PrrrDesign, result: PrrrWorkspace) -> PrrrWorkspace:
    """Remove the sampled share of the volume whose poses have link interference. The result is
    a subset of the reach-only workspace by construction (poses are only removed)."""

    try:
        _, w, free = interference_samples(design, **INTERFERENCE_SAMPLING)
    except HapticoptError as exc:  # the CAD cannot build this design's parts
        return dataclasses.replace(result, message=f"interference not checked: {exc}")
    removed = float(w[~free].sum() / w.sum()) if w.sum() > 0 else 0.0
    message = result.message
    if removed > 0:
        message = (message + "; " if message else "") + \
            f"link interference at {int((~free).sum())} of {len(free)} sampled poses"
    return dataclasses.replace(result, free_volume=result.volume * (1.0 - removed), interference_removed=removed,
                               message=message)


def cylinder_z_range(design: PrrrDesign, result: PrrrWorkspace) -> tuple[float, float]:
    """z extent [m] of the inscribed cylinder (home pose at z = 0): ±(L/2 − R cot β)."""
    g = design.geometry
    half = g.stroke / 2.0 - result.cylinder_diameter / 2.0 / math.tan(g.beta)
    return -half, half

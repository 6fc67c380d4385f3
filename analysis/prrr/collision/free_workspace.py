"""Collision-free workspace of the 3-PRRR: the largest vertical cylinder about z that every leg
reaches within the slider stroke and where no two parts collide, at every height.

Seed 002's design goal is the xy workspace over the device size **without link interference**
(φ140 mm of a φ260 mm device, Table 1). The reach-only cylinder of
:mod:`hapticopt.analysis.prrr.geometry.workspace` ignores the parts; this evaluator removes the poses where
parts collide. Every metric means the same at every fidelity; fidelity changes the sampling
and the checker only (fast separating-axis model of
:mod:`hapticopt.analysis.prrr.collision.interference_fast` at draft and standard, the manifold3d meshes of
:mod:`hapticopt.analysis.interference` at fine, the reference).

Structure used (the reason one pose per column suffices):

* **Moving parts translate together in z.** At fixed (x, y) the in-plane leg vectors do not
  depend on z (seed digest, eq 1): moving the end-effector by δz moves every slider by δz and
  keeps every joint angle, so carriages, housings, links and platform translate rigidly. A pair of
  moving parts collides in a whole column or nowhere in it.
* **Fixed parts are prisms standing on the base plate** (rails, screws, motors, the plate): a
  moving part lowered by δ can only meet more of them (their cross-section is the same at every
  height down to the plate). So a column is collision-free for every height above z iff it is
  at z.
* A cylinder of radius R has height H(R) = L − 2R cot β, centred on the home pose
  (:func:`hapticopt.analysis.prrr.geometry.workspace.cylinder_z_range`); every cylinder containing a
  column at radius r reaches down at most to −H(r)/2. The column at (r, φ) is checked once, at
  z = −H(r)/2: free there ⇒ free in every cylinder that contains it (conservative for cylinders
  larger than r, exact for R = r).

Free radius R_free: on each of ``n_phi`` rays over one third of the circle (the device is
3-fold symmetric) the columns at ``n_r`` radii up to the reach-and-stroke limit are checked; the
first colliding radius is refined by ``n_bisect`` bisections. R_free is the smallest free radius
over the rays (0 when the axis itself collides). Rays sample the angle: a collision between rays
can be missed (measured against a dense reference in ``docs/workspace_interference.md``,
``scripts/accuracy/accuracy_free_workspace.py``).

Metrics (engineering units at the edge):

* ``workspace_free_radius_mm`` — R_free, the largest collision-free disc about z (radius);
* ``workspace_free_cylinder_diameter_mm`` / ``…_height_mm`` — the largest-volume collision-free
  cylinder: R* = min(R_free, L tan β / 3) (the same convention as the reach-only cylinder);
* ``workspace_free_height_at_diameter_mm`` — height of the collision-free cylinder of the
  required diameter (0 when it is not free or not reachable);
* ``workspace_free_footprint_ratio`` — free cylinder diameter over the footprint diameter;
* ``workspace_free_device_ratio`` — free cylinder diameter over the whole device's diameter
  (``device_diameter_mm`` of the workspace evaluator: the body or the links' sweep, whichever is larger).
  The ratio over the footprint rewards links that reach far outside the body; this one does not.

Status: ``ok`` when the required cylinder (φ140 × 89 mm, seed 002 Table 1) is reachable and
collision-free; ``not-met`` (numbers kept: an optimiser steers on them) when reach and stroke
alone miss it, ``collides`` (numbers kept) when reach and stroke hold it but parts collide in it;
``empty`` when no workspace exists; ``not-assemblable`` (NaN) when the chain does not close or
the CAD cannot lay the parts out (:mod:`hapticopt.analysis.prrr.geometry.assembly`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticopt.analysis import interference
from hapticopt.analysis.compute import DEFAULT, Compute
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.collision import interference_fast
from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.prrr.geometry.workspace import SAMPLING as WS_SAMPLING
from hapticopt.analysis.prrr.geometry.workspace import (  # noqa: F401  (DEFAULT_REQUIRED_HEIGHT re-exported)
    DEFAULT_REQUIRED_DIAMETER,
    DEFAULT_REQUIRED_HEIGHT,
    ELBOW_BRANCH,
    workspace_core,
    workspace_params,
)
from hapticopt.analysis.status import Status
from hapticopt.design.errors import HapticoptError
from hapticopt.design.prrr.params import PrrrDesign

_THIRD = 2.0 * math.pi / 3.0


class Checker:
    """Which interference model decides a pose."""

    FAST = "fast"  # interference_fast (separating axes on the part primitives)
    MESH = "mesh"  # analysis.interference (manifold3d booleans), the reference


@dataclass(frozen=True, kw_only=True)
class FreeSampling:
    n_phi: int  # rays over one third of the circle
    n_r: int  # coarse radii per ray
    n_bisect: int  # bisections of the first colliding interval
    checker: str


SAMPLING: dict[Fidelity, FreeSampling] = {
    Fidelity.DRAFT: FreeSampling(n_phi=8, n_r=8, n_bisect=3, checker=Checker.FAST),
    Fidelity.STANDARD: FreeSampling(n_phi=16, n_r=12, n_bisect=4, checker=Checker.FAST),
    Fidelity.FINE: FreeSampling(n_phi=16, n_r=10, n_bisect=3, checker=Checker.MESH),
}


@dataclass(frozen=True, kw_only=True)
class FreeWorkspace:
    """Collision-free workspace of one design [SI]."""

    free_radius: float  # [m]
    cylinder_diameter: float  # [m] largest-volume collision-free cylinder about z
    cylinder_height: float  # [m]
    required_diameter: float  # [m]
    required_height: float  # [m]
    height_at_required: float  # [m] height of the free cylinder of the required diameter (0: not free)
    footprint_diameter: float  # [m]
    device_diameter: float  # [m] the body or the links' sweep, whichever is larger (workspace.device_diameter)
    poses: int  # poses checked
    colliding: int  # of which colliding
    fidelity: Fidelity
    wall_s: float
    status: Status = Status.OK
    message: str = ""

    @property
    def footprint_ratio(self) -> float:
        return self.cylinder_diameter / self.footprint_diameter if self.footprint_diameter > 0 else 0.0

    @property
    def device_ratio(self) -> float:
        return self.cylinder_diameter / self.device_diameter if self.device_diameter > 0 else 0.0

    def metrics(self) -> dict[str, float]:
        return {
            "workspace_free_radius_mm": self.free_radius * 1e3,
            "workspace_free_cylinder_diameter_mm": self.cylinder_diameter * 1e3,
            "workspace_free_cylinder_height_mm": self.cylinder_height * 1e3,
            "workspace_free_height_at_diameter_mm": self.height_at_required * 1e3,
            "workspace_free_footprint_ratio": self.footprint_ratio,
            "workspace_free_device_ratio": self.device_ratio,
        }


def column_poses_of(stroke, beta, phi, r) -> np.ndarray:
    """Check poses (…, 3) [m] of the columns at angles ``phi`` and radii ``r`` of designs of stroke [m] and
    β [rad] (scalars, or arrays broadcast with ``phi`` and ``r``: one design per column in the batched draft
    evaluator): z = −H(r)/2 = −L/2 + r cot β, the lowest point of the smallest cylinder containing the column."""
    phi, r = np.broadcast_arrays(np.asarray(phi, dtype=float), np.asarray(r, dtype=float))
    z = -np.asarray(stroke) / 2.0 + r / np.tan(beta)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def _collides_fn(design: PrrrDesign, checker: str, check=None):
    """``collides(points)`` (bool per point: parts collide or the point is unreachable) by ``checker``;
    ``check``: the design's fast point checker in the elbow branch where the caller has one."""
    if checker == Checker.FAST:
        if check is None:
            check = interference_fast.point_checker(interference_fast.prepare(design), branch=ELBOW_BRANCH)

        def collides(pts: np.ndarray) -> np.ndarray:
            res = check(pts)
            return res.collides | ~res.reachable
    else:
        model = interference.prepare(design)

        def collides(pts: np.ndarray) -> np.ndarray:
            return np.array([not r.ok for r in interference.check_poses(model, pts, branch=ELBOW_BRANCH)], dtype=bool)
    return collides


def free_radius(design: PrrrDesign, r_max: float, *, n_phi: int, n_r: int, n_bisect: int,
                checker: str = Checker.FAST, check=None) -> tuple[float, int, int]:
    """(R_free [m], poses checked, poses colliding): largest radius ≤ ``r_max`` whose columns are
    collision-free on every ray (see the module docstring): :func:`free_radius_many` of the one design.
    ``check``: the design's :func:`~hapticopt.analysis.prrr.collision.interference_fast.point_checker` in the elbow
    branch (made here when omitted; fast checker only)."""
    if r_max <= 0.0:
        return 0.0, 0, 0
    collides = _collides_fn(design, checker, check)
    g = design.geometry
    r_free, n_checked, n_hit = free_radius_many(
        lambda owner, phi, r: collides(column_poses_of(g.stroke, g.beta, phi, r)),
        np.array([r_max]), n_phi=n_phi, n_r=n_r, n_bisect=n_bisect)
    return float(r_free[0]), int(n_checked[0]), int(n_hit[0])


def free_radius_many(collides, r_max: np.ndarray, *, n_phi: int, n_r: int, n_bisect: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`free_radius` of m designs at once (each r_max > 0): ``collides(owner, phi, r)`` says
    whether the columns (design ``owner``, angle ``phi``, radius ``r``; 1-D arrays) collide. Every
    pass checks the columns of every design together (one call per pass: the coarse grid, then
    each bisection). Returns R_free [m], poses checked and poses colliding, each (m,)."""
    r_max = np.asarray(r_max, dtype=float)
    m = len(r_max)
    phi = (np.arange(n_phi) + 0.5) * (_THIRD / n_phi)
    radii = r_max[:, None] * np.arange(0, n_r + 1) / n_r  # (m, n_r + 1): includes the axis (r = 0) and r_max
    # the axis column is one pose for every ray: pose 0 of each design, then its n_phi × n_r grid
    owner = np.repeat(np.arange(m), 1 + n_phi * n_r)
    ph = np.concatenate([np.zeros((m, 1)), np.broadcast_to(phi[:, None], (n_phi, n_r)).reshape(1, -1).repeat(m, 0)],
                        axis=1).ravel()
    rr = np.concatenate([np.zeros((m, 1)), np.broadcast_to(radii[:, None, 1:], (m, n_phi, n_r)).reshape(m, -1)],
                        axis=1).ravel()
    hit = np.asarray(collides(owner, ph, rr)).reshape(m, 1 + n_phi * n_r)
    n_checked = np.full(m, 1 + n_phi * n_r)
    n_hit = hit.sum(axis=1)
    axis_hit = hit[:, 0]
    grid = hit[:, 1:].reshape(m, n_phi, n_r)
    first = np.where(grid.any(axis=2), grid.argmax(axis=2), n_r)  # (m, n_phi) index into radii[1:]
    lo = np.take_along_axis(radii, first, axis=1)  # last free radius (radii[k] is the free one before radii[k + 1])
    hi = np.where(first < n_r, np.take_along_axis(radii, np.minimum(first + 1, n_r), axis=1), r_max[:, None])
    open_ = (first < n_r) & ~axis_hit[:, None]
    for _ in range(n_bisect):
        if not open_.any():
            break
        mid = 0.5 * (lo + hi)
        d, k = np.nonzero(open_)
        h = np.asarray(collides(d, phi[k], mid[d, k]))
        np.add.at(n_checked, d, 1)
        np.add.at(n_hit, d, h.astype(int))
        hi[d, k] = np.where(h, mid[d, k], hi[d, k])
        lo[d, k] = np.where(h, lo[d, k], mid[d, k])
    r_free = np.min(np.where(open_, lo, r_max[:, None]), axis=1)
    r_free = np.where(axis_hit, 0.0, r_free)
    return r_free, n_checked, n_hit


def reach_limit(design: PrrrDesign, core: dict) -> float:
    """Largest radius [m] the cylinder may take by reach and stroke: r ≤ R_reach (``core``: the
    design's :func:`hapticopt.analysis.prrr.geometry.workspace.workspace_core`) and r < L tan β / 2 (a height)."""
    g = design.geometry
    return min(float(core["reach_radius"]), 0.5 * g.stroke * math.tan(g.beta))


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD,
             required_diameter: float = DEFAULT_REQUIRED_DIAMETER,
             required_height: float = DEFAULT_REQUIRED_HEIGHT, shared: Any = None,
             compute: Compute = DEFAULT) -> FreeWorkspace:  # one route for one design (the registry passes it to every entry alike)
    """Collision-free workspace metrics of ``design`` (see the module docstring); ``shared``: the
    registry call's :class:`hapticopt.analysis.prrr.shared.DesignSteps` of ``design`` (the envelope, the
    reach core and the fast point checker, each taken once per call)."""
    fidelity = Fidelity(fidelity)
    smp = SAMPLING[fidelity]
    t0 = time.perf_counter()
    wp = workspace_params(design, required_diameter=required_diameter,
                          envelope=None if shared is None else shared.envelope(design))
    # the reach radius, emptiness and footprint (all this reads of the core) do not depend on n_r
    core = workspace_core(wp, n_phi=48, n_r=2) if shared is None else shared.reach_core(design, wp, n_phi=48, n_r=2)
    # the links' sweep (it depends on the radial sampling): the workspace evaluator's core at this fidelity
    ws = WS_SAMPLING[fidelity]
    swept = (workspace_core(wp, n_phi=ws.n_phi, n_r=ws.n_r) if shared is None
             else shared.workspace_core(design, wp, n_phi=ws.n_phi, n_r=ws.n_r))
    core = {**core, "link_extent": swept["link_extent"]}
    r_max = reach_limit(design, core)
    if bool(core["empty"]) or r_max <= 0.0:
        return finish(design, core, None, fidelity=fidelity, t0=t0, required_diameter=required_diameter,
                      required_height=required_height)
    try:
        check = shared.point_checker(design) if shared is not None and smp.checker == Checker.FAST else None
        found = free_radius(design, r_max, n_phi=smp.n_phi, n_r=smp.n_r, n_bisect=smp.n_bisect, checker=smp.checker,
                            check=check)
    except HapticoptError as exc:  # the CAD cannot lay this design's parts out
        found = exc
    return finish(design, core, found, fidelity=fidelity, t0=t0, required_diameter=required_diameter,
                  required_height=required_height)


def finish(design: PrrrDesign, core: dict, found: tuple[float, int, int] | Exception | None, *, fidelity: Fidelity,
           t0: float, required_diameter: float = DEFAULT_REQUIRED_DIAMETER,
           required_height: float = DEFAULT_REQUIRED_HEIGHT, blocked: str | None = None) -> FreeWorkspace:
    """The result from the reach core and ``found`` = (R_free, poses, colliding), the CAD's error, or
    None when there is no workspace to check: the one place of the verdict (single and batched).
    ``blocked``: ``assembly.check(design, with_parts=True)`` where the caller knows it (the batch, for
    designs whose part tables it built: their parts are laid out), None to ask it here."""
    fidelity = Fidelity(fidelity)
    smp = SAMPLING[fidelity]
    g = design.geometry
    footprint = float(core["footprint_diameter"])
    device = max(footprint, 2.0 * float(core["link_extent"]))  # the body or the links' sweep (workspace.device_diameter)
    cot = 1.0 / math.tan(g.beta)

    def result(r_free: float, poses: int, colliding: int, status: Status, message: str) -> FreeWorkspace:
        r_cyl = min(r_free, g.stroke * math.tan(g.beta) / 3.0)
        h_cyl = g.stroke - 2.0 * r_cyl * cot if r_cyl > 0 else 0.0
        r_req = required_diameter / 2.0
        h_req = max(g.stroke - 2.0 * r_req * cot, 0.0) if r_req <= r_free else 0.0
        return FreeWorkspace(free_radius=r_free, cylinder_diameter=2.0 * r_cyl, cylinder_height=h_cyl,
                             required_diameter=required_diameter, required_height=required_height,
                             height_at_required=h_req, footprint_diameter=footprint, device_diameter=device, poses=poses,
                             colliding=colliding, fidelity=fidelity, wall_s=time.perf_counter() - t0,
                             status=status, message=message)

    def unusable(status: Status, message: str) -> FreeWorkspace:
        out = result(0.0, 0, 0, status, message)
        nan = float("nan")
        return FreeWorkspace(**{**out.__dict__, "free_radius": nan, "cylinder_diameter": nan,
                                "cylinder_height": nan, "height_at_required": nan})

    if blocked is None:
        blocked = assembly.check(design, with_parts=True)
    if blocked:
        return unusable(Status.NOT_ASSEMBLABLE, blocked)
    if found is None:
        return result(0.0, 0, 0, Status.EMPTY, "no point is reached by every leg within the slider stroke")
    if isinstance(found, Exception):  # the parts are laid out but a pose's parts cannot be placed
        return unusable(Status.FAILED, f"collision-free workspace not computed: {found}")
    r_free, n, hit = found
    r_max = reach_limit(design, core)
    out = result(r_free, n, hit, Status.OK, "")
    if out.height_at_required < required_height - 1e-12:
        # reach and stroke alone: the height of the required cylinder with r_free = r_max
        h_reach = max(g.stroke - 2.0 * required_diameter / 2.0 * cot, 0.0) \
            if required_diameter / 2.0 <= r_max else 0.0
        cause = Status.COLLIDES if h_reach >= required_height - 1e-12 else Status.NOT_MET
        why = (f"{hit} of {n} checked poses collide ({smp.checker} check)" if cause is Status.COLLIDES else
               f"reach and stroke alone give it {h_reach * 1e3:.4g} mm of height")
        return FreeWorkspace(**{**out.__dict__, "status": cause, "message": (
            f"the collision-free workspace misses the required φ{required_diameter * 1e3:g} × "
            f"{required_height * 1e3:g} mm cylinder: free radius {r_free * 1e3:.4g} mm, {why}")})
    return out

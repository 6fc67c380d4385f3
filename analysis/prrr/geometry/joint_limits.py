"""Joint limits of the 3-PRRR from the hardware, against the joint ranges the workspace needs.

Seed 002 gives no joint limits. Three sources bound each leg's revolute joints:

* **Folded-elbow singularity** (R3 axis on R1 axis): the elbow is kept a joint-boss radius away,
  |ρ| ≥ ρ_min (:func:`hapticopt.analysis.prrr.geometry.workspace.fold_margin`), i.e.
  |θ2| ≤ acos((ρ_min² − d3² − d4²)/(2 d3 d4)); the workspace's reach hole already honours it.
* **Parts' stops**: each joint turned from the home pose until its two parts meet
  (:func:`hapticopt.analysis.interference.joint_limits`, manifold3d, 2° steps; fine fidelity only,
  ~seconds). The 3-PRRR's links sit on separate layers along the joint axes, so these stops are
  usually absent (``free``).
* **Neighbour-rail clearance**: the links must not reach another leg's rail, carriage or SEA
  module; that is a pose-dependent collision, checked over the workspace by
  :mod:`hapticopt.analysis.prrr.collision.free_workspace`, not a joint range.

Reported: the range each joint sweeps over the collision-free cylinder (IK on a grid of it, the
CAD's elbow branch), and the smallest margin to the limits above (negative: a limit cuts the
cylinder; status ``not-met``, as when part of the cylinder is out of reach; ``not-assemblable``
when the chain does not close, or, at fine fidelity, the CAD cannot lay the parts out).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from hapticopt.analysis import interference
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.geometry import assembly
from hapticopt.analysis.prrr.collision import free_workspace as FW
from hapticopt.design.prrr.kinematics import params_np
from hapticopt.analysis.prrr.geometry.workspace import ELBOW_BRANCH, fold_margin
from hapticopt.analysis.status import Status
from hapticopt.design.errors import HapticoptError
from hapticopt.design.prrr.kinematics import PrrrParams, inverse_kinematics, slider_offset
from hapticopt.design.prrr.params import PrrrDesign


@dataclass(frozen=True, kw_only=True)
class PrrrJointLimits:
    elbow_limit: float  # [rad] |θ2| ≤ this (folded-elbow margin)
    used: dict[str, tuple[float, float]]  # joint → (min, max) over the required cylinder [rad]
    stops: dict[str, tuple[float, float]] | None  # joint → collision-free range from the parts (fine only) [rad]
    margin: float  # [rad] smallest distance of a used range to a limit (negative: violated)
    wall_s: float
    status: Status = Status.OK
    message: str = ""

    def metrics(self) -> dict[str, object]:
        out: dict[str, object] = {"joint_elbow_limit_deg": math.degrees(self.elbow_limit),
                                  "joint_limit_margin_deg": math.degrees(self.margin)}
        for name, (lo, hi) in self.used.items():
            out[f"joint_range_{name}_deg"] = [math.degrees(lo), math.degrees(hi)]
        return out


@functools.lru_cache(maxsize=16)
def _plane(radius: float, n_phi: int, n_r: int) -> tuple[np.ndarray, np.ndarray]:
    """x, y (n_phi, n_r) [m] of the cylinder grid's points off the axis (polar grid incl. the rim); they
    depend on the radius and the counts only: made once for each (read-only)."""
    phi = np.linspace(0.0, 2.0 * math.pi, n_phi, endpoint=False)
    r = np.linspace(0.0, radius, n_r + 1)[1:]
    P, R = np.meshgrid(phi, r, indexing="ij")
    x, y = R * np.cos(P), R * np.sin(P)
    x.setflags(write=False)
    y.setflags(write=False)
    return x, y


def _levels(stroke, beta, radius: float, n_z: int, xp):
    """The grid's heights (n_z,) [m]: the cylinder of height L − 2R cot β about the home pose, shrunk
    by 1e-9 so that its rim stays inside the stroke."""
    h = xp.maximum(stroke - 2.0 * radius / xp.tan(beta), 0.0)
    return xp.linspace(-h / 2, h / 2, n_z) * (1.0 - 1e-9)


class JointRanges(NamedTuple):
    """What the verdict reads of the angles over the cylinder grid: per joint the (min, max)
    over the reachable points and every leg (lo, hi (3,) [rad]; ±inf where none is reachable), their
    largest |θ2| [rad] (−inf where none) and the number of points out of reach or stroke."""

    lo: Any
    hi: Any
    top: Any
    n_out: Any


def cylinder_ranges_of(params: PrrrParams, radius: float, *, n_phi: int = 24, n_r: int = 6, n_z: int = 3,
                       xp=np) -> JointRanges:
    """:class:`JointRanges` over the cylinder grid of ``radius`` about z (height L − 2R cot β about the
    home pose: ``n_phi`` × ``n_r`` polar points incl. the rim, and the axis, at ``n_z`` heights) without the
    IK of every point: the in-plane angles do not depend on the height (the slider takes it up: w·e_z =
    sin β, so the slider moves with z one for one and the in-plane vector is unchanged), so the IK runs
    once per in-plane point at z = 0, and the grid's heights z_k enter only the stroke test, slider
    s0 + z_k. Equal to the IK of every grid point up to rounding (tested to 1e-12 relative with equal
    counts, on designs in and out of reach; the grid's rim keeps 1e-9 of the stroke, decades above
    rounding). ``xp``: numpy (one design) or jax.numpy (the batched draft evaluator's vmap)."""
    X, Y = _plane(float(radius), n_phi, n_r)
    xy = np.concatenate([np.stack([X.ravel(), Y.ravel()], axis=-1), np.zeros((1, 2))])  # (P, 2), the axis last
    ik = inverse_kinematics(params, xp.asarray(np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)), xp=xp)
    z = _levels(params.stroke, params.beta, radius, n_z, xp)
    s_dev = ik.sliders[:, None, :] + z[None, :, None] - slider_offset(params, xp=xp)  # (P, n_z, 3 legs)
    half = params.stroke / 2.0
    ok = xp.all(ik.reach_ok[:, None, :] & (xp.abs(s_dev) <= half * (1.0 + 1e-12)), axis=-1)  # (P, n_z)
    th = ik.theta[:, ELBOW_BRANCH]  # (P, 3 legs, 3 joints)
    seen = xp.any(ok, axis=1)
    lo = xp.min(xp.where(seen[:, None, None], th, xp.inf), axis=(0, 1))
    hi = xp.max(xp.where(seen[:, None, None], th, -xp.inf), axis=(0, 1))
    top = xp.max(xp.where(seen[:, None], xp.abs(th[..., 1]), -xp.inf))
    return JointRanges(lo=lo, hi=hi, top=top, n_out=ok.size - xp.sum(ok))


def grid_size(*, n_phi: int = 24, n_r: int = 6, n_z: int = 3) -> int:
    """Number of points of the cylinder grid (:func:`cylinder_ranges_of`)."""
    return (n_phi * n_r + 1) * n_z


def elbow_limit(design: PrrrDesign) -> float:
    """|θ2| limit [rad] of the folded-elbow margin (module docstring)."""
    g = design.geometry
    rho_min = max(abs(g.d3 - g.d4), fold_margin(design))
    c2 = (rho_min**2 - g.d3**2 - g.d4**2) / (2.0 * g.d3 * g.d4)
    return math.acos(min(1.0, max(-1.0, c2)))


def evaluate(design: PrrrDesign, *, fidelity: Fidelity = Fidelity.STANDARD,
             required_diameter: float = FW.DEFAULT_REQUIRED_DIAMETER) -> PrrrJointLimits:
    """Joint ranges over the required cylinder against the hardware limits."""
    fidelity = Fidelity(fidelity)
    t0 = time.perf_counter()
    nan = float("nan")
    blocked = assembly.check(design, with_parts=fidelity is Fidelity.FINE)  # the parts' stops: fine only
    if blocked:
        return PrrrJointLimits(elbow_limit=nan, used={}, stops=None, margin=nan, wall_s=time.perf_counter() - t0,
                               status=Status.NOT_ASSEMBLABLE, message=blocked)
    ranges = cylinder_ranges_of(params_np(design), required_diameter / 2.0, xp=np)
    return from_ranges_many([design], JointRanges(*(np.asarray(x)[None] for x in ranges)), n_points=grid_size(),
                            fidelity=fidelity, t0=t0, required_diameter=required_diameter)[0]


def from_ranges_many(designs: list[PrrrDesign], ranges: JointRanges, *, n_points: int, fidelity: Fidelity,
                     t0: float, required_diameter: float = FW.DEFAULT_REQUIRED_DIAMETER) -> list[PrrrJointLimits]:
    """The result of every design from its stacked :class:`JointRanges` (leading axis: the designs;
    :func:`cylinder_ranges_of`'s, numpy for one design or jax under the batched draft evaluator's vmap)
    over a grid of ``n_points``: the one place of the verdict."""
    lo, hi = np.asarray(ranges.lo, dtype=float).tolist(), np.asarray(ranges.hi, dtype=float).tolist()
    top, n_out = np.asarray(ranges.top, dtype=float).tolist(), np.asarray(ranges.n_out).tolist()
    return [_verdict(d, n_points, n_out[i], (lo[i], hi[i]) if n_out[i] < n_points else None, top[i],
                     fidelity=fidelity, t0=t0, required_diameter=required_diameter) for i, d in enumerate(designs)]


def _verdict(design: PrrrDesign, n_points: int, n_out: int, ranges: tuple | None, top: float, *,
             fidelity: Fidelity, t0: float, required_diameter: float) -> PrrrJointLimits:
    """The result from the number of grid points and of those out of reach, the per-joint (min, max)
    of the reachable points' angles (None: none is reachable) and their largest |θ2| [rad]."""
    fidelity = Fidelity(fidelity)
    elbow = elbow_limit(design)
    nan = float("nan")
    if ranges is None:
        return PrrrJointLimits(elbow_limit=elbow, used={}, stops=None, margin=nan, wall_s=time.perf_counter() - t0,
                               status=Status.EMPTY, message="the required cylinder is not reachable")
    lo, hi = ranges
    used = {f"r{j + 1}": (float(lo[j]), float(hi[j])) for j in range(3)}
    margin = elbow - top
    stops = None
    if fidelity is Fidelity.FINE:
        try:
            lims = interference.joint_limits(design)
        except HapticoptError as exc:
            return PrrrJointLimits(elbow_limit=elbow, used=used, stops=None, margin=nan,
                                   wall_s=time.perf_counter() - t0, status=Status.FAILED,
                                   message=f"joint stops not computed: {exc}")
        stops = {}
        for lim in lims:
            j = lim.joint.split("_")[0]  # r1_1 → r1 (leg 1; the legs are identical by symmetry)
            stops[j] = (lim.lo, lim.hi)
            if not lim.free:
                lo, hi = used[j]
                margin = min(margin, lo - lim.lo, lim.hi - hi)
    status, message = Status.OK, ""
    problems = []
    if n_out:  # the ranges below hold for the reachable part only
        problems.append(f"{n_out} of {n_points} grid points of the φ{required_diameter * 1e3:g} mm "
                        f"cylinder are out of reach or stroke")
    if margin < 0.0:
        problems.append(f"a joint limit cuts the φ{required_diameter * 1e3:g} mm cylinder by "
                        f"{math.degrees(-margin):.3g} deg")
    if problems:
        status, message = Status.NOT_MET, "; ".join(problems)
    return PrrrJointLimits(elbow_limit=elbow, used=used, stops=stops, margin=margin,
                           wall_s=time.perf_counter() - t0, status=status, message=message)

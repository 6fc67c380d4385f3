"""Joint limits of the 3-PRRR from the hardware, against the joint ranges the workspace needs.

Seed 002 gives no joint limits. Three sources bound each leg's revolute joints:

* **Folded-elbow singularity** (R3 axis on R1 axis): the elbow is kept a joint-boss radius away,
  |ρ| ≥ ρ_min (:func:`hapticopt.analysis.prrr.workspace.fold_margin`), i.e.
  |θ2| ≤ acos((ρ_min² − d3² − d4²)/(2 d3 d4)); the workspace's reach hole already honours it.
* **Parts' stops**: each joint turned from the home pose until its two parts meet
  (:func:`hapticopt.analysis.interference.joint_limits`, manifold3d, 2° steps; fine fidelity only,
  ~seconds). The 3-PRRR's links sit on separate layers along the joint axes, so these stops are
  usually absent (``free``).
* **Neighbour-rail clearance**: the links must not reach another leg's rail, carriage or SEA
  module; that is a pose-dependent collision, checked over the workspace by
  :mod:`hapticopt.analysis.prrr.free_workspace`, not a joint range.

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

import numpy as np

from hapticopt.analysis import interference
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import assembly, free_workspace as FW
from hapticopt.design.prrr.kinematics import params_np
from hapticopt.analysis.prrr.workspace import ELBOW_BRANCH, fold_margin
from hapticopt.analysis.status import Status
from hapticopt.design.errors import HapticoptError
from hapticopt.design.prrr.kinematics import inverse_kinematics
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


def cylinder_grid(design: PrrrDesign, radius: float, *, n_phi: int = 24, n_r: int = 6, n_z: int = 3) -> np.ndarray:
    """Points (m, 3) [m] of the vertical cylinder of ``radius`` about z (height L − 2R cot β,
    centred on the home pose), polar grid incl. the rim and the axis."""
    g = design.geometry
    return cylinder_grid_of(g.stroke, g.beta, radius, n_phi=n_phi, n_r=n_r, n_z=n_z, xp=np)


def cylinder_grid_of(stroke, beta, radius: float, *, n_phi: int = 24, n_r: int = 6, n_z: int = 3, xp=np):
    """:func:`cylinder_grid` from the stroke [m] and β [rad] (``xp``: numpy, or ``jax.numpy`` under
    the batched draft evaluator's vmap)."""
    h = xp.maximum(stroke - 2.0 * radius / xp.tan(beta), 0.0)
    z = xp.linspace(-h / 2, h / 2, n_z) * (1.0 - 1e-9)
    x, y = _grid_xy(float(radius), n_phi, n_r, n_z)
    Z = xp.broadcast_to(z, x.shape)
    pts = xp.stack([xp.asarray(x), xp.asarray(y), Z], axis=-1).reshape(-1, 3)
    zero = xp.zeros(n_z)
    return xp.concatenate([pts, xp.stack([zero, zero, z], axis=1)])


@functools.lru_cache(maxsize=16)
def _grid_xy(radius: float, n_phi: int, n_r: int, n_z: int) -> tuple[np.ndarray, np.ndarray]:
    """x and y (n_phi, n_r, n_z) [m] of :func:`cylinder_grid_of`'s polar grid, which depend on the
    radius and the counts only: made once for each (read-only; the grid took ≈ 40 % of a one-design
    joint-limit evaluation without the IK)."""
    phi = np.linspace(0.0, 2.0 * math.pi, n_phi, endpoint=False)
    r = np.linspace(0.0, radius, n_r + 1)[1:]
    P, R = np.meshgrid(phi, r, indexing="ij")
    P, R = np.repeat(P[..., None], n_z, axis=-1), np.repeat(R[..., None], n_z, axis=-1)
    x, y = R * np.cos(P), R * np.sin(P)
    x.setflags(write=False)
    y.setflags(write=False)
    return x, y


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
    pts = cylinder_grid(design, required_diameter / 2.0)
    # plain floats: numpy throughout (jax scalars would send every operation to XLA one by one)
    ik = inverse_kinematics(params_np(design), pts, xp=np)
    th = np.asarray(ik.theta)[:, ELBOW_BRANCH]  # (m, 3 legs, 3)
    return from_angles(design, th, np.asarray(ik.reachable), fidelity=fidelity, t0=t0,
                       required_diameter=required_diameter)


def from_angles(design: PrrrDesign, th: np.ndarray, ok: np.ndarray, *, fidelity: Fidelity, t0: float,
                required_diameter: float = FW.DEFAULT_REQUIRED_DIAMETER) -> PrrrJointLimits:
    """The result from the joint angles ``th`` (m, 3 legs, 3) [rad] of the CAD's elbow branch at the
    :func:`cylinder_grid` points and whether each is reachable (numpy, or a row of the batched
    draft evaluator): the one place of the verdict."""
    n_out = int((~ok).sum())
    if n_out == len(ok):
        return _verdict(design, len(ok), n_out, None, math.nan, fidelity=fidelity, t0=t0,
                        required_diameter=required_diameter)
    # the reachable points' angles joint-major, (3 joints, points · legs) contiguous: each joint's range
    # and the largest |θ2| as reductions along rows (min and max: exact, so the same values as over the
    # (points, legs) axes of ``th[ok]``, in a third of the time)
    by_joint = np.ascontiguousarray(np.moveaxis(np.asarray(th, dtype=float), 2, 0)[:, ok]).reshape(3, -1)
    lo, hi = by_joint.min(axis=1), by_joint.max(axis=1)
    return _verdict(design, len(ok), n_out, (lo, hi), float(np.abs(by_joint[1]).max()), fidelity=fidelity, t0=t0,
                    required_diameter=required_diameter)


def from_angles_many(designs: list[PrrrDesign], th: np.ndarray, ok: np.ndarray, *, fidelity: Fidelity, t0: float,
                     required_diameter: float = FW.DEFAULT_REQUIRED_DIAMETER) -> list[PrrrJointLimits]:
    """:func:`from_angles` of every design from the stacked angles ``th`` (n, m, 3 legs, 3) [rad] and
    reachability ``ok`` (n, m) (the batched draft evaluator's): the ranges and the largest |θ2| over
    the reachable points of every design in one masked numpy pass (a minimum or maximum picks one of
    the same numbers, so the same values), the verdict of each design by the same rule. The angles are
    laid out joint-major first, (n, 3 joints, m, 3 legs), so that each reduction runs over contiguous
    memory (a masked minimum over the middle axes of (1024, 435, 3, 3) took 179 ms, joint-major 12.5 ms
    plus an 8 ms copy, load ≈ 6)."""
    ok = np.asarray(ok, dtype=bool)
    by_joint = np.ascontiguousarray(np.moveaxis(np.asarray(th, dtype=float), 3, 1))  # (n, 3 joints, m, 3 legs)
    where = ok[:, None, :, None]
    lo = np.min(by_joint, axis=(2, 3), where=where, initial=np.inf)  # (n, 3 joints)
    hi = np.max(by_joint, axis=(2, 3), where=where, initial=-np.inf)
    top = np.max(np.abs(by_joint[:, 1]), axis=(1, 2), where=ok[:, :, None], initial=-np.inf).tolist()
    n_out = (~ok).sum(axis=1).tolist()
    m = ok.shape[1]
    lo, hi = lo.tolist(), hi.tolist()
    return [_verdict(d, m, n_out[i], (lo[i], hi[i]) if n_out[i] < m else None, top[i], fidelity=fidelity, t0=t0,
                     required_diameter=required_diameter) for i, d in enumerate(designs)]


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

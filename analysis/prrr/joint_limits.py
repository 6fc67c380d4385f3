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

import math
import time
from dataclasses import dataclass

import numpy as np

from hapticopt.analysis import interference
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr import assembly, free_workspace as FW
from hapticopt.analysis.prrr.workspace import ELBOW_BRANCH, fold_margin
from hapticopt.analysis.status import Status
from hapticopt.design.errors import HapticoptError
from hapticopt.design.prrr.kinematics import inverse_kinematics, params_of
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
    h = max(g.stroke - 2.0 * radius / math.tan(g.beta), 0.0)
    phi = np.linspace(0.0, 2.0 * math.pi, n_phi, endpoint=False)
    r = np.linspace(0.0, radius, n_r + 1)[1:]
    z = np.linspace(-h / 2, h / 2, n_z) * (1.0 - 1e-9)
    P, R, Z = np.meshgrid(phi, r, z, indexing="ij")
    pts = np.stack([R * np.cos(P), R * np.sin(P), Z], axis=-1).reshape(-1, 3)
    return np.concatenate([pts, np.stack([np.zeros(n_z), np.zeros(n_z), z], axis=1)])


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
    g = design.geometry
    rho_min = max(abs(g.d3 - g.d4), fold_margin(design))
    c2 = (rho_min**2 - g.d3**2 - g.d4**2) / (2.0 * g.d3 * g.d4)
    elbow = math.acos(min(1.0, max(-1.0, c2)))
    pts = cylinder_grid(design, required_diameter / 2.0)
    ik = inverse_kinematics(params_of(design), pts, xp=np)
    th = np.asarray(ik.theta)[:, ELBOW_BRANCH]  # (m, 3 legs, 3)
    ok = np.asarray(ik.reachable)
    if not ok.any():
        return PrrrJointLimits(elbow_limit=elbow, used={}, stops=None, margin=nan, wall_s=time.perf_counter() - t0,
                               status=Status.EMPTY, message="the required cylinder is not reachable")
    th = th[ok]
    used = {f"r{j + 1}": (float(th[..., j].min()), float(th[..., j].max())) for j in range(3)}
    margin = elbow - float(np.abs(th[..., 1]).max())
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
    if not ok.all():  # the ranges below hold for the reachable part only
        problems.append(f"{int((~ok).sum())} of {len(ok)} grid points of the φ{required_diameter * 1e3:g} mm "
                        f"cylinder are out of reach or stroke")
    if margin < 0.0:
        problems.append(f"a joint limit cuts the φ{required_diameter * 1e3:g} mm cylinder by "
                        f"{math.degrees(-margin):.3g} deg")
    if problems:
        status, message = Status.NOT_MET, "; ".join(problems)
    return PrrrJointLimits(elbow_limit=elbow, used=used, stops=stops, margin=margin,
                           wall_s=time.perf_counter() - t0, status=status, message=message)

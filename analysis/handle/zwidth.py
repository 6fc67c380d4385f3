"""Evaluator: the handle's Z-width map (exact sampled loop) over virtual damping × stiffness.

Grid: B_e from 0 to ``DAMPING_MAX`` linearly, K_e from ``STIFFNESS_RANGE`` log-spaced; the
margin of every cell and the exact boundary K_e(B_e) (``stability.zwidth_map``), at the
described handle's T and hand. Points per axis by fidelity (draft 10, standard 20, fine 40).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.handle import stability as hs
from hapticopt.analysis.handle.model import N_PER_MM, from_design
from hapticopt.analysis.status import Status
from hapticopt.design.handle.params import HandleDesign

POINTS = {Fidelity.DRAFT: 10, Fidelity.STANDARD: 20, Fidelity.FINE: 40}
DAMPING_MAX_N_S_PER_M = 1900.0
STIFFNESS_RANGE_N_PER_M = (100.0, 1e6)  # 0.1 … 1000 N/mm


@dataclass(frozen=True, kw_only=True)
class ZWidthResult:
    map: hs.ZWidthMap
    eq18_boundary_N_per_m: np.ndarray  #: the Padé closed form at each B_e (no upper bound on B_e)
    status: Status
    message: str = ""

    def metrics(self) -> dict[str, object]:
        b = self.map.boundary_N_per_m / N_PER_MM
        ok = np.isfinite(b)
        return {
            "zwidth_wall_damping_Ns_per_m": self.map.wall_damping_N_s_per_m.tolist(),
            "zwidth_boundary_N_per_mm": [float(x) if math.isfinite(x) else None for x in b],
            "zwidth_peak_stiffness_N_per_mm": float(np.max(b[ok])) if ok.any() else math.nan,
            "zwidth_peak_damping_Ns_per_m": (float(self.map.wall_damping_N_s_per_m[ok][np.argmax(b[ok])])
                                             if ok.any() else math.nan),
            "zwidth_max_stable_damping_Ns_per_m": (float(self.map.wall_damping_N_s_per_m[ok].max())
                                                   if ok.any() else math.nan),
            "zwidth_stable_fraction": float(np.mean(self.map.stable)),
        }


def evaluate(design: HandleDesign, *, fidelity: Fidelity = Fidelity.STANDARD) -> ZWidthResult:
    h = from_design(design)
    n = POINTS[Fidelity(fidelity)]
    B = np.linspace(0.0, DAMPING_MAX_N_S_PER_M, n)
    K = np.geomspace(*STIFFNESS_RANGE_N_PER_M, n)
    zm = hs.zwidth_map(h, B, K)
    eq18 = np.array([hs.eq18_stiffness_limit(h.with_(wall_damping_N_s_per_m=float(b))) for b in B])
    ok = np.isfinite(zm.boundary_N_per_m)
    if ok.any():
        return ZWidthResult(map=zm, eq18_boundary_N_per_m=eq18, status=Status.OK)
    return ZWidthResult(map=zm, eq18_boundary_N_per_m=eq18, status=Status.EMPTY,
                        message="no B_e of the grid has a stable wall stiffness")

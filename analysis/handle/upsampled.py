"""Evaluator: the handle's largest stable wall stiffness with prediction + B-spline upsampling.

For the described handle, wall damping and hand, at its firmware's l2/l1 = L: the exact limit of
the lifted multi-rate loop (``analysis.control.upsampling.lifted_stiffness_limit``) for each
variant — no upsampling, eq (23) as printed, and as intended (the segment from the update point
to the predicted point). The lifted analysis is linear, so the AR predictor is its polynomial
limit (2, −1) (``fallback_coefficients``; an online fit on a slowly varying history converges to
it: docs/seed000.md, online-fit table within 4 % of it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hapticopt.analysis.control import upsampling as up
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.handle.model import N_PER_MM, from_design, wall_plant
from hapticopt.analysis.status import Status
from hapticopt.design.handle.params import HandleDesign


@dataclass(frozen=True, kw_only=True)
class UpsampledResult:
    upsampling: int  #: L
    limits_N_per_mm: dict[str, float]  #: variant value -> limit (NaN unless found)
    statuses: dict[str, str]  #: variant value -> lifted limit status
    status: Status
    message: str = ""

    def metrics(self) -> dict[str, object]:
        out: dict[str, object] = {"upsampling": self.upsampling}
        none = self.limits_N_per_mm[up.Variant.NONE.value]
        for v, lim in self.limits_N_per_mm.items():
            out[f"max_stable_stiffness_{v}_N_per_mm"] = lim
            if v != up.Variant.NONE.value:
                out[f"upsampling_{v}_vs_none_pct"] = 100.0 * (lim / none - 1.0)
        out["upsampling_default_variant"] = up.DEFAULT_VARIANT.value
        return out


def evaluate(design: HandleDesign, *, fidelity: Fidelity = Fidelity.STANDARD) -> UpsampledResult:
    del fidelity  # eigenvalues of the lifted matrix: no accuracy knob
    h = from_design(design)
    L = int(design.firmware.upsampling)
    order = int(design.firmware.ar_order)
    plant = wall_plant(h)
    ref = 2.0 * h.damping_N_s_per_m / (h.period_s * h.transmission)
    limits, statuses = {}, {}
    for v in up.Variant:
        fw = up.Firmware(period_s=h.period_s, upsampling=L, wall_damping_N_s_per_m=h.wall_damping_N_s_per_m,
                         variant=v, order=order, window=int(design.firmware.ar_window),
                         coefficients=tuple(up.fallback_coefficients(order)))
        lim = up.lifted_stiffness_limit(plant, fw, reference_N_per_m=ref)
        limits[v.value] = lim.value_N_per_m / N_PER_MM if lim.status == "ok" else math.nan
        statuses[v.value] = lim.status
    bad = {v: s for v, s in statuses.items() if s != "ok"}
    if not bad:
        return UpsampledResult(upsampling=L, limits_N_per_mm=limits, statuses=statuses, status=Status.OK)
    unstable = any(s == "unstable_without_wall" for s in bad.values())
    return UpsampledResult(upsampling=L, limits_N_per_mm=limits, statuses=statuses,
                           status=Status.UNSTABLE if unstable else Status.FAILED,
                           message="; ".join(f"{v}: {s}" for v, s in bad.items()))

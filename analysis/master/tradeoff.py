"""Seed 003's trade-off: sweep the counterweights down from perfect balance.

Both counterweights are scaled by the same fraction s of their perfect-balance masses
(:func:`hapticopt.analysis.master.dynamics.balancing_counterweights`); at each s the maximum unbalance
force over the workspace and the transparency bandwidth (x, z) at the default pose are
evaluated. Lighter counterweights → larger unbalance force, lower inertia, higher bandwidth.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hapticopt.analysis.master import balance as mb
from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master import transparency as mt
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.master.params import MasterDesign

FRACTIONS = (1.0, 0.95, 0.9, 0.85, 0.8, 0.75, 0.7, 0.65, 0.6, 0.55, 0.5, 0.45, 0.4, 0.35, 0.3)


def counterweight_sweep(design: MasterDesign, fractions: tuple[float, ...] = FRACTIONS, *,
                        fidelity: Fidelity = Fidelity.STANDARD) -> list[dict[str, float]]:
    """Rows (engineering units) of the counterweight sweep of ``design``."""
    mu, mf = md.balancing_counterweights(design)
    pose = mt.default_pose(design)
    rows = []
    for s in fractions:
        cw = dataclasses.replace(design.counterweights, upper_mass=s * mu, forearm_mass=s * mf)
        d = dataclasses.replace(design, counterweights=cw)
        model = md.model_of(d)
        bal = mb.evaluate(d, fidelity=fidelity, model=model)
        tr = mt.evaluate(d, fidelity=Fidelity.STANDARD, pose=pose, model=model)
        rows.append({
            "counterweight_fraction": float(s),
            "counterweight_mass_kg": float(s * (mu + mf)),
            "upper_counterweight_kg": float(s * mu),
            "forearm_counterweight_kg": float(s * mf),
            "com_offset_mm": float(np.hypot(*bal.com_offset) * 1e3),
            "unbalance_radius_mm": float(bal.radius * 1e3),
            "max_unbalance_force_N": float(bal.max_force),
            "transparency_bandwidth_x_Hz": float(tr.bandwidth[0]),
            "transparency_bandwidth_z_Hz": float(tr.bandwidth[1]),
        })
    return rows


def unbalance_boundary(design: MasterDesign, *, threshold: float = mb.FORCE_JND_N,
                       fidelity: Fidelity = Fidelity.STANDARD) -> float:
    """The counterweight fraction s* < 1 of the sweep at which the maximum unbalance force reaches
    ``threshold`` [N] (the 0.1 N JND boundary); bisection, the force is monotone in 1 − s here."""
    mu, mf = md.balancing_counterweights(design)

    def force(s: float) -> float:
        cw = dataclasses.replace(design.counterweights, upper_mass=s * mu, forearm_mass=s * mf)
        return mb.evaluate(dataclasses.replace(design, counterweights=cw), fidelity=fidelity).max_force - threshold

    lo, hi = 0.0, 1.0  # force(lo) > 0 ≥ force(hi)
    if force(lo) <= 0.0:
        return 0.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if force(mid) > 0.0 else (lo, mid)
    return hi


def rows_to_csv(rows: list[dict[str, float]]) -> str:
    keys = list(rows[0])
    lines = [",".join(keys)] + [",".join(f"{r[k]:.9g}" for k in keys) for r in rows]
    return "\n".join(lines) + "\n"

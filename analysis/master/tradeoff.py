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

FRACTIONS = (1.0, 0.99, 0.98, 0.97, 0.95, 0.9, 0.8, 0.6, 0.4, 0.2, 0.0)


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
            "upper_counterweight_kg": float(s * mu),
            "forearm_counterweight_kg": float(s * mf),
            "com_offset_mm": float(np.hypot(*bal.com_offset) * 1e3),
            "unbalance_radius_mm": float(bal.radius * 1e3),
            "max_unbalance_force_N": float(bal.max_force),
            "transparency_bandwidth_x_Hz": float(tr.bandwidth[0]),
            "transparency_bandwidth_z_Hz": float(tr.bandwidth[1]),
        })
    return rows


def rows_to_csv(rows: list[dict[str, float]]) -> str:
    keys = list(rows[0])
    lines = [",".join(keys)] + [",".join(f"{r[k]:.9g}" for k in keys) for r in rows]
    return "\n".join(lines) + "\n"

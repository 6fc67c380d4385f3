"""Can a design of a bundled 3-PRRR problem fit Table 1's envelope with its links counted?

    python scripts/envelope_feasibility.py N SEED [PROBLEM]     # default PROBLEM: prrr-workspace

Draws N designs uniformly within PROBLEM's variable bounds (numpy seed SEED), evaluates them at draft
fidelity (the registry's batch) and prints how many can be built, the smallest whole-device diameter
(``device_diameter_mm``: body or link sweep) overall and among designs with a collision-free
φ140 × 89 mm cylinder, and how many fit seed 002 Table 1's φ260 × 231 mm with and without that cylinder.
The source of the numbers quoted in ``optim/problems/prrr-workspace.toml``'s header.
"""

from __future__ import annotations

import sys

import numpy as np

from hapticopt.analysis import registry
from hapticopt.design import io
from hapticopt.design.errors import InvalidDesign
from hapticopt.optim.problem import load_problem

#: seed 002 Table 1: device φ260 × 231 mm
TABLE1 = (260.0, 231.0)


def main(n: int, seed: int, problem: str = "prrr-workspace") -> None:
    p = load_problem(problem)
    base = p.base
    rng = np.random.default_rng(seed)
    designs = []
    for _ in range(n):
        try:
            designs.append(io.apply_overrides(base, [f"{v.key}={rng.uniform(v.lower, v.upper)!r}" for v in p.variables]))
        except InvalidDesign:
            continue
    evs = registry.evaluate_batch(designs, fidelity="draft")
    rows = np.array([[ev.metrics().get(k, np.nan) for k in ("device_diameter_mm", "device_height_mm",
                                                            "workspace_free_height_at_diameter_mm")]
                     for ev in evs if str(ev.statuses["statics"]) != "not-assemblable"], dtype=float).reshape(-1, 3)
    dd, hh, free = rows.T
    has = free >= 89.0
    inside = (dd <= TABLE1[0]) & (hh <= TABLE1[1])
    print(f"{len(designs)} designs, {len(rows)} can be built")
    print(f"smallest device diameter {np.nanmin(dd, initial=np.inf):.1f} mm; with a collision-free φ140 × 89 mm "
          f"cylinder {np.min(dd[has], initial=np.inf):.1f} mm ({has.sum()} designs)")
    print(f"inside φ{TABLE1[0]:g} × {TABLE1[1]:g} mm: {inside.sum()}; of them with the free cylinder: {(inside & has).sum()}")


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]), *sys.argv[3:4])

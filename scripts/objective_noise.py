"""How much does a bundled problem's draft objective move for tiny design moves?

    python scripts/objective_noise.py PROBLEM [KEY=VALUE ...]     # e.g. prrr-workspace geometry.d2_mm=84.7

At the problem's start (or its variables set to the given values), each variable is moved in 20 steps of
0.005 mm (lengths) or 0.005 mm at 100 mm radius (angles, 5e-5 rad ≈ 0.00286 deg) and the objective
evaluated at draft fidelity (the registry's batch). Prints, per variable, the largest relative change
between neighbouring steps and over the 21 points: the objective's noise against the optimiser's step.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from hapticopt.analysis import registry
from hapticopt.optim.problem import load_problem


def main(name: str, sets: list[str]) -> None:
    p = load_problem(name)
    x0 = np.array(p.start, dtype=float)
    given = dict(s.split("=", 1) for s in sets)
    for j, v in enumerate(p.variables):
        if v.key in given:
            x0[j] = float(given[v.key])
    ref = p.objective.metric
    for j, v in enumerate(p.variables):
        step = 0.005 if v.key.endswith("_mm") else math.degrees(0.005 / 100.0)
        xs = np.repeat(x0[None], 21, axis=0)
        xs[:, j] += (np.arange(21) - 10) * step
        evs = registry.evaluate_batch([p.design_at(tuple(x)) for x in xs], fidelity="draft")
        f = np.array([ref.value(ev.metrics()) for ev in evs])
        jump = np.nanmax(np.abs(np.diff(f)) / np.abs(f[:-1]))
        span = (np.nanmax(f) - np.nanmin(f)) / abs(f[10])
        print(f"{v.key:26s} step {step:.3g}: largest step-to-step change {100 * jump:.4f} %, over ±10 steps "
              f"{100 * span:.4f} % (f = {f[10]:.6g})")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])

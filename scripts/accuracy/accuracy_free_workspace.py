"""Accuracy vs time of the collision-free cylinder (analysis/prrr/collision/free_workspace.py).

Reference: manifold3d (analysis/interference.py) on a dense column grid, ≥ 5000 poses (40 rays
over one third of the circle × 128 radii up to the reach-and-stroke limit, each column checked at
its lowest height, −H(r)/2), the free radius = the smallest first-colliding radius over the rays
(minus nothing: the grid step, 0.56 mm, bounds its own error). Each fidelity level's free
diameter is compared with it, with the median wall time of 3 runs (1 for fine).

Usage: ``python scripts/accuracy/accuracy_free_workspace.py [--designs paper legacy optimum]``; prints
a markdown table.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time


from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.prrr.collision import free_workspace as FW
from hapticopt.analysis.prrr.geometry.workspace import workspace_core, workspace_params
from hapticopt.design import io

DESIGNS = {
    "prrr-paper": [],
    "θ_1p = 0": ["geometry.theta_1p_deg=0"],
    "r_p = 100": ["geometry.r_p_mm=100"],
}


def reference_radius(design, *, n_phi: int = 40, n_r: int = 128) -> tuple[float, int]:
    g = design.geometry
    core = workspace_core(workspace_params(design), n_phi=48, n_r=2)
    r_max = min(float(core["reach_radius"]), 0.5 * g.stroke * math.tan(g.beta))
    r, n, _ = FW.free_radius(design, r_max, n_phi=n_phi, n_r=n_r, n_bisect=0, checker=FW.Checker.MESH)
    return r, n


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--designs", nargs="*", default=list(DESIGNS))
    args = ap.parse_args()
    base = io.load_preset("prrr-paper")
    print("| design | level | checker | poses | free diameter [mm] | error vs reference [mm] | median time [s] |")
    print("|---|---|---|---|---|---|---|")
    for name in args.designs:
        d = io.apply_overrides(base, DESIGNS[name])
        t0 = time.perf_counter()
        ref, n_ref = reference_radius(d)
        t_ref = time.perf_counter() - t0
        print(f"| {name} | reference | mesh | {n_ref} | {2e3 * ref:.2f} | 0 | {t_ref:.1f} |")
        for level in Fidelity:
            runs = 1 if level is Fidelity.FINE else 3
            times, res = [], None
            for _ in range(runs):
                t0 = time.perf_counter()
                res = FW.evaluate(d, fidelity=level)
                times.append(time.perf_counter() - t0)
            smp = FW.SAMPLING[level]
            print(f"| {name} | {level} | {smp.checker} | {res.poses} | {2e3 * res.free_radius:.2f} | "
                  f"{2e3 * (res.free_radius - ref):+.2f} | {statistics.median(times):.3f} |")


if __name__ == "__main__":
    main()

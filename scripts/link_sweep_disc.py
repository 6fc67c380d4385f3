"""What do Table 2's links sweep over a workspace disc, on each elbow branch?

    python scripts/link_sweep_disc.py [RADIUS_MM ...]      # default radii: 0 50 70 71.25

For prrr-paper's kinematics (seed 002 Table 2 lengths; r_p and the parts play no part) the largest
distance from the z axis of the R2 axis point B and the R3 axis point Q of any leg, over every end-effector
position (x, y) within a disc of the given radius (z does not matter: the in-plane leg vectors are
independent of z), plus the boss radius: the diameter the links sweep if the device is used only within
that disc. Same construction as the workspace evaluator's ``link_sweep_diameter_mm`` (which takes the
whole reach region). Used in docs/cad.md ("What Table 2's links sweep").
"""

from __future__ import annotations

import math
import sys

import numpy as np

from hapticopt.design import io
from hapticopt.design.prrr.params import GAMMAS


def sweep_diameter(design, radius: float, branch: int, n_r: int = 61, n_phi: int = 721) -> float:
    g, s = design.geometry, design.structure
    sb, cb = math.sin(g.beta), math.cos(g.beta)
    cu = g.d1 - (g.b5 + g.r4) * cb  # the reach ellipse centre's u-coordinate (workspace._c_u)
    r = np.linspace(0.0, radius, n_r)[:, None]
    phi = np.linspace(0.0, 2.0 * math.pi, n_phi)[None, :]
    x, y = r * np.cos(phi), r * np.sin(phi)
    most = 0.0
    for gam in GAMMAS:
        u, t = x * math.cos(gam) + y * math.sin(gam), -x * math.sin(gam) + y * math.cos(gam)
        rv, rt = (u - cu) / sb, t - g.d2
        c2 = np.clip((rv**2 + rt**2 - g.d3**2 - g.d4**2) / (2.0 * g.d3 * g.d4), -1.0, 1.0)
        s2 = (1.0 - 2.0 * branch) * np.sqrt(1.0 - c2**2)
        th1 = np.arctan2(rt, rv) - np.arctan2(g.d4 * s2, g.d3 + g.d4 * c2)
        th12 = th1 + np.arctan2(s2, c2)
        bu, bt = g.d1 + g.d3 * np.cos(th1) * sb, g.d2 + g.d3 * np.sin(th1)
        qu, qt = bu + g.d4 * np.cos(th12) * sb - g.r4 * cb, bt + g.d4 * np.sin(th12)
        most = max(most, float(np.hypot(bu, bt).max()), float(np.hypot(qu, qt).max()))
    return 2.0 * (most + s.boss_diameter / 2.0)


def main(radii_mm: list[float]) -> None:
    d = io.load_preset("prrr-paper")
    for R in radii_mm:
        print(f"disc radius {R:g} mm: sweep diameter branch 0 {sweep_diameter(d, R * 1e-3, 0) * 1e3:.1f} mm, "
              f"branch 1 (the CAD's) {sweep_diameter(d, R * 1e-3, 1) * 1e3:.1f} mm")


if __name__ == "__main__":
    main([float(a) for a in sys.argv[1:]] or [0.0, 50.0, 70.0, 71.25])

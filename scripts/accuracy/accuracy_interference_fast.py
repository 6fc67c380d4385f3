"""Regenerate the agreement and timing tables of docs/workspace_interference.md.

Run: ``.venv/bin/python scripts/accuracy/accuracy_interference_fast.py`` (prints Markdown; ~1 min:
the manifold3d reference costs ~20 ms a pose). Designs: prrr-paper, the prrr-workspace optimum
found without the interference constraint (beta 59.06°, d2 = d3 = d4 ≈ 75.82 mm, stroke
184.84 mm, r_p 99.56 mm), the optimum of the constrained problem when
``cad_out/prrr-workspace/optimum.toml`` exists, and four random designs of the problem's box
(seeded) that the CAD can build. Poses: the 216 of ``prrr_workspace.INTERFERENCE_SAMPLING``.
Times: median of 7 warm calls on the machine it runs on.
"""

from __future__ import annotations

import sys

import time
from pathlib import Path

import numpy as np

from hapticopt.analysis import interference as itf
from hapticopt.analysis.prrr.collision import interference_fast as F
from hapticopt.analysis.prrr.geometry import workspace as W
from hapticopt.design.prrr import cad as cad_prrr
from hapticopt.design import io
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from timing import median_wall  # noqa: E402  (benchmarks/timing.py)

OLD_OPTIMUM = ["geometry.beta_deg=59.0563", "geometry.d2_mm=75.8151", "geometry.d3_mm=75.8225",
               "geometry.d4_mm=75.8223", "geometry.stroke_mm=184.838", "geometry.r_p_mm=99.5627"]
BOX = [("geometry.beta_deg", 30, 70), ("geometry.d2_mm", 40, 120), ("geometry.d3_mm", 50, 120),
       ("geometry.d4_mm", 50, 120), ("geometry.stroke_mm", 120, 220), ("geometry.r_p_mm", 60, 140)]


def designs() -> list:
    paper = io.load_preset("prrr-paper")
    out = [("prrr-paper", paper), ("optimum without the constraint", io.apply_overrides(paper, OLD_OPTIMUM))]
    new = Path("cad_out/prrr-workspace/optimum.toml")
    if new.exists():
        out.append(("optimum with the constraint", io.load_design(new)))
    rng = np.random.default_rng(7)
    k = 0
    while k < 4:
        vals = [f"{key}={rng.uniform(lo, hi):.3f}" for key, lo, hi in BOX]
        try:
            d = io.apply_overrides(paper, vals)
            cad_prrr.layout(d)
        except ValueError:
            continue
        if W.evaluate(d, fidelity="draft", interference=False).status != W.Status.OK:
            continue
        out.append((f"random {k}", d))
        k += 1
    return out


def main() -> None:
    print("| design | poses | colliding (manifold3d / fast) | same verdict | removed (manifold3d) | "
          "removed (fast) | fast only | manifold3d only | fast [ms] | manifold3d [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, d in designs():
        pts, w = W.workspace_sample_weights(d, **W.INTERFERENCE_SAMPLING)
        t0 = time.perf_counter()
        ref = ~np.array([r.ok for r in itf.check_poses(d, pts, branch=W.ELBOW_BRANCH)])
        t_ref = time.perf_counter() - t0
        fast = F.check_points(F.prepare(d), pts, branch=W.ELBOW_BRANCH).collides
        t_fast = median_wall(lambda: F.removed_fraction(d, **W.INTERFERENCE_SAMPLING))
        print(f"| {name} | {len(pts)} | {ref.sum()} / {fast.sum()} | {(ref == fast).mean():.3f} | "
              f"{w[ref].sum() / w.sum():.3f} | {w[fast].sum() / w.sum():.3f} | {(fast & ~ref).sum()} | "
              f"{(ref & ~fast).sum()} | {t_fast * 1e3:.1f} | {t_ref:.2f} |")


if __name__ == "__main__":
    main()

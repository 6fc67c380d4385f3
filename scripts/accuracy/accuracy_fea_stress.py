"""Regenerate the tables of docs/structure_stress.md (von Mises stress of the solid FEA).

Run: ``.venv/bin/python scripts/accuracy/accuracy_fea_stress.py [--prrr LEVEL ...]`` (prints Markdown).
Cantilever (200 × 20 × 10 mm, unit tip shear along y, as tests/analysis/fem/test_solid.py): element
stress against σ_xx = −P (L − x) y / I; ``--prrr``: the CAD solid of prrr-paper with bonded
pins (hapticopt.analysis.prrr.structure.fea_cad) at the given mesh levels, 1 N along x at Δz = 58 mm. Stress-step
times are the median of 5 calls on the machine it runs on.
"""

from __future__ import annotations

import sys
from pathlib import Path

import argparse
import time

import numpy as np

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.fem import solid as fea, stress as fea_stress
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from timing import median_wall  # noqa: E402  (benchmarks/timing.py)

L, B, T, E, NU = 0.2, 0.02, 0.01, 68.9e9, 0.33
I_Z, C = T * B**3 / 12.0, B / 2.0


def cantilever(size: float) -> str:
    mesh = fea.cantilever_mesh(length=L, width=B, thickness=T, size=size)

    loads = fea.tip_shear_loads(mesh, B * T)  # unit total force along +y

    sol = fea.solve_elasticity(mesh, youngs_modulus=E, poisson_ratio=NU, fixed="clamp", loads=loads)
    uv, ue = fea_stress.p2_nodal_values(sol.basis, sol.displacements[:, 0])
    row = [f"{size * 1e3:.1f}", f"{mesh.tets.shape[1]}", f"{sol.n_dofs}"]
    for edges in (ue, None):
        st = fea_stress.element_stress(mesh.points, mesh.tets, uv, edges, youngs_modulus=E, poisson_ratio=NU)
        x, y = st.centroids[0], st.centroids[1]
        sel = (x > 0.3 * L) & (x < 0.7 * L)
        err = (st.stress[:, 0, 0] + (L - x) * y / I_Z) / ((L - x) * C / I_Z)
        row.append(f"{100 * np.abs(err[sel]).max():.2f} %")
    st = fea_stress.element_stress(mesh.points, mesh.tets, uv, ue, youngs_modulus=E, poisson_ratio=NU)
    vx, vy = mesh.points[0][mesh.tets], mesh.points[1][mesh.tets]
    fibre = (np.abs(np.abs(vy) - C) < 1e-9) & (np.abs(vx - 0.5 * L) < 0.1 * L)
    ratio = st.von_mises_vertices[fibre] / ((L - vx[fibre]) * C / I_Z)
    wall = median_wall(lambda: fea_stress.element_stress(mesh.points, mesh.tets, uv, ue, youngs_modulus=E,
                                                          poisson_ratio=NU), 5, warm=False)
    row += [f"{100 * (ratio.min() - 1):+.1f} … {100 * (ratio.max() - 1):+.1f} %",
            f"{st.max_von_mises * 1e-6:.3f} / {st.peak_von_mises * 1e-6:.3f}", f"{wall * 1e3:.0f}"]
    return "| " + " | ".join(row) + " |"


def prrr(level: int) -> str:
    from hapticopt.analysis.prrr.structure import fea_cad
    from hapticopt.design import io

    d = io.load_preset("prrr-paper")
    t = time.perf_counter()
    r = fea_cad.cad_fea(d, level=level, keep_fields=True)
    t_fea = time.perf_counter() - t
    s = d.structure

    def step():
        return fea_stress.element_stress(r.mesh.points, r.mesh.tets, r.displacement, r.displacement_edges,
                                         youngs_modulus=s.youngs_modulus, poisson_ratio=s.poisson_ratio)

    st = step()
    wall = median_wall(step, 5, warm=False)
    where = [n for n, v in r.mesh.node_sets.items() if np.isin(r.mesh.tets[:, st.max_element], v).all()]
    xm = np.round(st.max_location * 1e3, 1)
    return (f"| {level} | {r.size * 1e3:.2f} | {r.mesh.tets.shape[1]} | {r.n_dofs} | {t_fea:.0f} | "
            f"{st.max_von_mises * 1e-6:.3f} | ({xm[0]}, {xm[1]}, {xm[2]}) {', '.join(where)} | "
            f"{st.peak_von_mises * 1e-6:.3f} | {np.percentile(st.von_mises, 99) * 1e-6:.3f} | {wall * 1e3:.0f} |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--prrr", type=int, nargs="*", default=[])
    args = ap.parse_args()
    print("| size mm | tets | DOFs | σ_xx err P2 | σ_xx err P1 | top fibre σ_vM vs Mc/I | max / peak MPa/N | stress ms |")
    print("|---|---|---|---|---|---|---|---|")
    for size in (0.01, T / fea.REFINEMENT_RATIO, 0.005):
        print(cantilever(size), flush=True)
    if args.prrr:
        print()
        print("| level | size mm | tets | DOFs | FEA s | max σ_vM MPa/N | where (mm, part) | vertex peak MPa/N | 99th pct MPa/N | stress ms |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for level in args.prrr:
            print(prrr(level), flush=True)


if __name__ == "__main__":
    main()

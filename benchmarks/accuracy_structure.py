"""Accuracy vs wall time of the structural-stiffness models (table for docs/structure.md).

    .venv/bin/python benchmarks/accuracy_structure.py            # cantilever levels 0..3
    .venv/bin/python benchmarks/accuracy_structure.py --prrr 0    # + 3-PRRR solid at those levels

Cantilever: FEA levels against Timoshenko's closed form and their Richardson extrapolation.
3-PRRR: the frame model (released and bonded joints) and the bonded-joint solid FEA.
"""

from __future__ import annotations

import argparse
import time

import jax.numpy as jnp

from analysis import fea
from analysis import frame_model as fm
from analysis.structural_stiffness import structural_stiffness
from design import io

L, B, T, E, NU = 0.2, 0.02, 0.01, 68.9e9, 0.33


def cantilever(levels: list[int]) -> None:
    sec = fm.Section(jnp.asarray(B), jnp.asarray(T), jnp.asarray(E), jnp.asarray(NU))
    pr = fm.section_properties(sec)
    ref = fm.closed_form_tip_deflection(1.0, L, E, float(pr.i_z), float(pr.shear_coefficient),
                                        float(pr.shear_modulus), B * T)
    t0 = time.perf_counter()
    c = float(fm.cantilever_compliance(L, sec, direction=(1.0, 0.0, 0.0), zref=(0.0, 0.0, 1.0))[1, 1])
    print("| model | size mm | DOFs | CG its | wall s | compliance µm/N | vs closed form |")
    print("|---|---|---|---|---|---|---|")
    print(f"| frame (1 Timoshenko element) | – | 12 | – | {time.perf_counter() - t0:.3f} | {c * 1e6:.6f} | "
          f"{c / ref - 1:+.2e} |")
    vals = []
    for k in levels:
        size = T / fea.REFINEMENT_RATIO**k
        r = fea.cantilever_fea(length=L, width=B, thickness=T, youngs_modulus=E, poisson_ratio=NU, size=size)
        vals.append(r.compliance)
        print(f"| FEA P2 level {k} | {size * 1e3:.2f} | {r.n_dofs} | {r.iterations} | {r.wall_s:.1f} | "
              f"{r.compliance * 1e6:.6f} | {r.compliance / ref - 1:+.2%} |")
    if len(vals) >= 3:
        rich = fea.richardson(*vals[-3:])
        print(f"| Richardson (last 3) | – | – | – | – | {rich.extrapolated * 1e6:.6f} | "
              f"{rich.extrapolated / ref - 1:+.2%} (order {rich.order:.2f}) |")


def prrr(levels: list[int]) -> None:
    d = io.load_preset("prrr-paper")
    for joints in (fm.Joints.RELEASED, fm.Joints.BONDED):
        t0 = time.perf_counter()
        r = structural_stiffness(d, options=fm.FrameOptions(joints=joints))
        print(f"frame {joints}: k = {r.stiffness_load / 1e3} N/mm, elastic centre {r.elastic_centre * 1e3:.2f} mm, "
              f"{time.perf_counter() - t0:.2f} s (incl. compile)")
    bonded = structural_stiffness(d, options=fm.FrameOptions(joints=fm.Joints.BONDED)).stiffness_load
    for k in levels:
        r = fea.prrr_fea(d, level=k, keep_fields=False)
        print(f"FEA level {k}: size {r.size * 1e3:.1f} mm, {r.n_dofs} DOFs, CG its {r.iterations}, "
              f"{r.wall_s:.1f} s {r.timings_s}; k = {r.stiffness_load / 1e3} N/mm; "
              f"frame(bonded)/FEA − 1 = {bonded / r.stiffness_load - 1}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--levels", type=int, nargs="*", default=[0, 1, 2, 3])
    ap.add_argument("--prrr", type=int, nargs="*", default=None)
    args = ap.parse_args()
    cantilever(args.levels)
    if args.prrr is not None:
        prrr(args.prrr)

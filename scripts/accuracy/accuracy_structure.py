"""Accuracy vs wall time of the structural-stiffness models (table for docs/structure.md).

    .venv/bin/python scripts/accuracy/accuracy_structure.py            # cantilever levels 0..3
    .venv/bin/python scripts/accuracy/accuracy_structure.py --levels --cad -1 0 1   # CAD solid, bonded pins
    .venv/bin/python scripts/accuracy/accuracy_structure.py --levels --beta          # β sweep of the frame model
    .venv/bin/python scripts/accuracy/accuracy_structure.py --levels --variants 2    # frame vs CAD FEA, design variants

Cantilever: FEA levels against Timoshenko's closed form and their Richardson extrapolation.
3-PRRR: the frame model against the CAD solid's FEA (bonded pins).
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import jax.numpy as jnp
import numpy as np

from hapticopt.analysis.fem import solid as fea
from hapticopt.analysis.prrr.structure import fea_cad
from hapticopt.analysis.prrr.structure import frame_beam
from hapticopt.analysis.prrr.structure import frame_model as fm
from hapticopt.analysis.prrr.structure.stiffness import structural_stiffness
from hapticopt.design import io

L, B, T, E, NU = 0.2, 0.02, 0.01, 68.9e9, 0.33


def cantilever(levels: list[int]) -> None:
    sec = fm.Section(jnp.asarray(B), jnp.asarray(T), jnp.asarray(E), jnp.asarray(NU))
    pr = fm.section_properties(sec)
    ref = frame_beam.closed_form_tip_deflection(1.0, L, E, float(pr.i_z), float(pr.shear_coefficient),
                                        float(pr.shear_modulus), B * T)
    t0 = time.perf_counter()
    K = frame_beam.beam_global_stiffness(np.zeros(3), np.array([L, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]),
                                         fm.Section(*(np.asarray(x) for x in (B, T, E, NU))), xp=np)
    c = float(np.linalg.inv(K[6:, 6:])[1, 1])  # the clamped element's tip compliance
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


def cad(levels: list[int], rigid: str = "stem") -> None:
    """CAD solid with bonded pins (hapticopt.analysis.prrr.structure.fea_cad): levels, Richardson per axis, frame comparison."""
    import numpy as np


    d = io.load_preset("prrr-paper")
    rows = []
    print("| level | size mm | DOFs | CG its (x, y, z) | mesh s | assemble s | solver setup s | solve s | wall s | "
          "k_x, k_y, k_z N/mm |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for k in levels:
        r = fea_cad.cad_fea(d, level=k, rigid=rigid)
        t = r.timings_s
        rows.append(r)
        print(f"| {k} | {r.size * 1e3:.1f} | {r.n_dofs} | {r.iterations} | {t['mesh']:.1f} | {t['assemble']:.1f} | "
              f"{t['setup']:.1f} | {t['solve']:.1f} | {r.wall_s:.1f} | "
              f"{', '.join(f'{x / 1e3:.1f}' for x in r.stiffness_load)} |", flush=True)
    if len(rows) >= 3:
        # extrapolate the compliance (the FE quantity that converges monotonically)
        c = np.array([1.0 / r.stiffness_load for r in rows[-3:]])
        ks = []
        for i in range(3):
            rich = fea.richardson(*c[:, i])
            ks.append((1.0 / rich.extrapolated, rich.order))
        print("Richardson (last 3 levels, compliance): k∞ = "
              + ", ".join(f"{k / 1e3:.1f} N/mm (order {p:.2f})" for k, p in ks))
        for r in rows:
            err = [r.stiffness_load[i] / ks[i][0] - 1 for i in range(3)]
            print(f"level size {r.size * 1e3:.1f} mm: error vs extrapolated " + ", ".join(f"{e:+.2%}" for e in err)
                  + f" in {r.wall_s:.1f} s")
    reference = np.array([k for k, _ in ks]) if len(rows) >= 3 else rows[-1].stiffness_load
    print("| frame model (bonded, CAD branch 1) | k_x, k_y, k_z N/mm | frame/FEA − 1 | ms |\n|---|---|---|---|")
    variants = {"pins as bonded necks (default)": fm.FrameOptions(),
                "pin beams over the layer pitch": fm.FrameOptions(pin_model=fm.PinModel.BEAM),
                "plane frame, rigid joint zones (pins=False)": fm.FrameOptions(pins=False)}
    for name, options in variants.items():
        options = dataclasses.replace(options, joints=fm.Joints.BONDED, branch=1)
        structural_stiffness(d, options=options)
        t0 = time.perf_counter()
        for _ in range(20):
            fr = structural_stiffness(d, options=options).stiffness_load
        ms = (time.perf_counter() - t0) / 20 * 1e3
        print(f"| {name} | {', '.join(f'{x / 1e3:.1f}' for x in fr)} | "
              f"{', '.join(f'{x:+.1%}' for x in fr / reference - 1)} | {ms:.1f} |")


#: designs around prrr-paper for the frame-vs-FEA check beyond one point: (label, section, field, value SI)
VARIANTS = (("prrr-paper", None, None, None),
            ("bore 6 mm", "structure", "bore_diameter", 0.006),
            ("bore 10 mm", "structure", "bore_diameter", 0.010),
            ("link thickness 8 mm", "structure", "link_thickness", 0.008),
            ("link width 16 mm", "structure", "link_width", 0.016),
            ("clearance 1.5 mm", "structure", "clearance", 0.0015),
            ("β = 45°", "geometry", "beta", 0.7853981633974483))


def cad_variants(level: int) -> None:
    """Frame (default, bonded, CAD branch) vs the CAD FEA at ``level`` over design variants."""
    import numpy as np

    d0 = io.load_preset("prrr-paper")
    print(f"| design | CAD FEA level {level}, k_x, k_y, k_z N/mm | frame (necks) | frame/FEA − 1 | plane frame/FEA − 1 "
          "| FEA wall s |")
    print("|---|---|---|---|---|---|")
    for label, section, name, value in VARIANTS:
        d = d0 if section is None else dataclasses.replace(
            d0, **{section: dataclasses.replace(getattr(d0, section), **{name: value})})
        r = fea_cad.cad_fea(d, level=level)
        bonded = fm.FrameOptions(joints=fm.Joints.BONDED, branch=r.branch)
        fr = structural_stiffness(d, options=bonded).stiffness_load
        plane = structural_stiffness(d, options=dataclasses.replace(bonded, pins=False)).stiffness_load
        fmt = lambda v: ", ".join(f"{x / 1e3:.1f}" for x in v)  # noqa: E731
        pct = lambda v: ", ".join(f"{x:+.1%}" for x in v)  # noqa: E731
        print(f"| {label} | {fmt(r.stiffness_load)} | {fmt(fr)} | {pct(fr / r.stiffness_load - 1)} | "
              f"{pct(plane / r.stiffness_load - 1)} | {r.wall_s:.0f} |", flush=True)
        assert np.all(np.isfinite(r.stiffness_load))


def beta_sweep() -> None:
    """Lateral stiffness of prrr-paper with β varied (docs/structure.md, "β sweep")."""
    import numpy as np

    d = io.load_preset("prrr-paper")
    betas = (30, 35, 40, 45, 50, 55, 60, 65, 70)
    rows = {"k_x at Δz = 58 mm (default)": [], "k_x at the elastic centre": [], "k_x at P (Δz = 0)": [],
            "elastic centre height [mm]": [], "k_z at Δz = 58 mm": []}
    variants = {"branch 1": fm.FrameOptions(branch=1), "plane frame (pins=False)": fm.FrameOptions(pins=False),
                "pin beams (PinModel.BEAM)": fm.FrameOptions(pin_model=fm.PinModel.BEAM),
                "bonded joints": fm.FrameOptions(joints=fm.Joints.BONDED)}
    rows.update({f"variant k_x at 58 mm: {name}": [] for name in variants})
    for b in betas:
        db = dataclasses.replace(d, geometry=dataclasses.replace(d.geometry, beta=float(np.deg2rad(b))))
        r = structural_stiffness(db)
        rows["k_x at Δz = 58 mm (default)"].append(r.stiffness_load[0])
        rows["k_x at the elastic centre"].append(r.stiffness_elastic_centre[0])
        rows["k_x at P (Δz = 0)"].append(structural_stiffness(db, load_height=0.0).stiffness_load[0])
        rows["elastic centre height [mm]"].append(r.elastic_centre * 1e6)  # printed /1e3 below
        rows["k_z at Δz = 58 mm"].append(r.stiffness_load[2])
        for name, options in variants.items():
            rows[f"variant k_x at 58 mm: {name}"].append(structural_stiffness(db, options=options).stiffness_load[0])
    print("| β | " + " | ".join(f"{b}°" for b in betas) + " |")
    print("|---|" + "---|" * len(betas))
    for name, vals in rows.items():
        print(f"| {name} | " + " | ".join(f"{v / 1e3:.1f}" for v in vals) + " |")


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--levels", type=int, nargs="*", default=[0, 1, 2, 3])
    ap.add_argument("--cad", type=int, nargs="*", default=None)
    ap.add_argument("--rigid", default="stem", choices=("stem", "ball"))
    ap.add_argument("--beta", action="store_true", help="β sweep of the frame model")
    ap.add_argument("--variants", type=int, default=None, metavar="LEVEL",
                    help="frame vs CAD FEA at this level over design variants around prrr-paper")
    args = ap.parse_args()
    if args.levels:
        cantilever(args.levels)
    if args.cad is not None:
        cad(args.cad, args.rigid)
    if args.beta:
        beta_sweep()
    if args.variants is not None:
        cad_variants(args.variants)

"""Released-joint CAD FEA (hapticopt.analysis.fem.hinge) vs the released frame model, prrr-paper at home.

    OMP_NUM_THREADS=1 .venv/bin/python scripts/accuracy/accuracy_hinge.py --levels 0 1 2
    OMP_NUM_THREADS=1 .venv/bin/python scripts/accuracy/accuracy_hinge.py --levels 0 1 2 3 4   # + the k∞ + c h^p fit (~7 min)
    OMP_NUM_THREADS=1 .venv/bin/python scripts/accuracy/accuracy_hinge.py --levels 2 --side swapped

Prints the markdown level table of docs/structure_hinge.md (unknowns, CG iterations, wall time,
k per axis), Richardson extrapolation over the last three levels, and frame/FEA ratios.
Runs one FEA at a time (2-core machine).
"""

from __future__ import annotations

import argparse

import numpy as np


def frame_rows(d) -> list[tuple[str, np.ndarray]]:
    from hapticopt.analysis.prrr.structure import frame_model as fm
    from hapticopt.design.prrr.cad import DEFAULT_BRANCH

    fp = fm.frame_params_of(d)
    rows = []
    for label, opts in (
        ("frame, released, pins (NECK)", fm.FrameOptions(joints=fm.Joints.RELEASED, branch=DEFAULT_BRANCH, pins=True,
                                                         pin_model=fm.PinModel.NECK)),
        ("frame, released, pins (BEAM)", fm.FrameOptions(joints=fm.Joints.RELEASED, branch=DEFAULT_BRANCH, pins=True,
                                                         pin_model=fm.PinModel.BEAM)),
        ("frame, released, no pins", fm.FrameOptions(joints=fm.Joints.RELEASED, branch=DEFAULT_BRANCH, pins=False)),
    ):
        rows.append((label, np.asarray(fm.solve_frame(fp, options=opts)["stiffness_load"]) * 1e-3))
    return rows


def main() -> None:
    from hapticopt.analysis.fem import solid as fea
    from hapticopt.analysis.prrr.structure import fea_cad
    from hapticopt.design import io

    ap = argparse.ArgumentParser()
    ap.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--side", default="frame", choices=["frame", "swapped"])
    ap.add_argument("--bonded", action="store_true", help="also the bonded CAD at each level")
    args = ap.parse_args()
    d = io.load_preset("prrr-paper")
    print("| level | size mm | unknowns (ties) | CG its (x, y, z) | mesh / assemble / reduce / solver setup / solve s | wall s "
          "| k_x, k_y, k_z N/mm |")
    print("|---|---|---|---|---|---|---|")
    ks = []
    for k in args.levels:
        r = fea_cad.cad_fea(d, level=k, joints="released", release_side=args.side)
        t = r.timings_s
        kk = r.stiffness_load * 1e-3
        ks.append(kk)
        print(f"| {k} | {r.size * 1e3:.1f} | {r.n_dofs} | {', '.join(map(str, r.iterations))} | "
              f"{t['mesh']:.1f} / {t['assemble']:.1f} / {t['reduce']:.1f} / {t['setup']:.1f} / {t['solve']:.1f} | "
              f"{r.wall_s:.1f} | {kk[0]:.1f}, {kk[1]:.1f}, {kk[2]:.1f} |", flush=True)
        if args.bonded:
            b = fea_cad.cad_fea(d, level=k)
            kb = b.stiffness_load * 1e-3
            print(f"|   bonded {k} | | {b.n_dofs} | {', '.join(map(str, b.iterations))} | | {b.wall_s:.1f} | "
                  f"{kb[0]:.1f}, {kb[1]:.1f}, {kb[2]:.1f} |", flush=True)
    best = ks[-1]
    if len(ks) >= 3:
        rich = [fea.richardson(*(x[a] for x in ks[-3:])) for a in range(3)]
        ext = np.array([r.extrapolated for r in rich])
        print(f"| Richardson ({', '.join(map(str, args.levels[-3:]))}) | | | | | | "
              f"{ext[0]:.1f}, {ext[1]:.1f}, {ext[2]:.1f} (orders {', '.join(f'{r.order:.2g}' for r in rich)}) |")
        if all(r.order > 0.5 for r in rich):  # asymptotic (differences shrinking); else the finest level
            best = ext
    if len(ks) >= 4:  # irregular level differences: fit k = k∞ + c h^p over all levels instead
        from scipy.optimize import curve_fit

        h = np.array([fea_cad.cad_level_size(d, k) for k in args.levels]) * 1e3
        fits = [curve_fit(lambda x, a, c, p: a + c * x**p, h, [x[a] for x in ks], p0=(ks[-1][a], 0.1, 1.5),
                          maxfev=10000)[0] for a in range(3)]
        best = np.array([f[0] for f in fits])
        print(f"| fit k∞ + c h^p ({', '.join(map(str, args.levels))}) | | | | | | "
              f"{best[0]:.1f}, {best[1]:.1f}, {best[2]:.1f} (p = {', '.join(f'{f[2]:.2f}' for f in fits)}) |")
    print()
    print("| model | k_x, k_y, k_z N/mm | frame / FEA |")
    print("|---|---|---|")
    ref = "extrapolated" if best is not ks[-1] else f"level {args.levels[-1]}"
    print(f"| CAD FEA, released ({args.side}), {ref} | {best[0]:.1f}, {best[1]:.1f}, {best[2]:.1f} | – |")
    for label, kf in frame_rows(d):
        ratio = kf / best
        print(f"| {label} | {kf[0]:.1f}, {kf[1]:.1f}, {kf[2]:.1f} | {ratio[0]:.3f}, {ratio[1]:.3f}, {ratio[2]:.3f} |")


if __name__ == "__main__":
    main()

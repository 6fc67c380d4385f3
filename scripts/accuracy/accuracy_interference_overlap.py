"""Continuity of ``interference_overlap_fraction`` against the step ``interference_removed_fraction``.

Regenerates the continuity table of docs/workspace_interference.md. Run:
``.venv/bin/python scripts/accuracy/accuracy_interference_overlap.py`` (prints Markdown; ~1–2 min on the
2-core machine). Sweeps one design variable at a time finely around a design (default: the
prrr-workspace optimum of the step-constrained run, commit 12e33d8, docs/optimisation.md) and, at
every interval where the step metric jumps (> 0.002), and at the ``--flag`` intervals where the companion
changes most between neighbouring samples, bisects 40 times towards the largest change: a change that survives at an interval width of
~1e-12 of the span is a jump, one that shrinks with the interval is a steep but continuous ramp.
``--plot PATH`` writes both metrics along each sweep as an SVG (matplotlib).
"""

from __future__ import annotations

import argparse

import numpy as np

from hapticopt.analysis.prrr.collision import interference_fast as F
from hapticopt.analysis.prrr.geometry import workspace as W
from hapticopt.design import io

# the prrr-workspace optimum with the step constraint (cad_out/prrr-workspace/optimum.toml of the
# run documented in docs/optimisation.md, commit 12e33d8)
STEP_OPTIMUM = ["geometry.beta_deg=57.035581000819", "geometry.d2_mm=77.9848002283854",
                "geometry.d3_mm=73.9316796078444", "geometry.d4_mm=79.3338793692093",
                "geometry.stroke_mm=180.260544633171", "geometry.r_p_mm=101.546119285948"]
JUMP = 2e-3
SWEEPS = [("geometry.beta_deg", 1.5), ("geometry.r_p_mm", 3.0), ("geometry.d3_mm", 3.0)]


def fractions(base, key: str, x: float) -> tuple[float, float]:
    return F.interference_fractions(io.apply_overrides(base, [f"{key}={float(x)!r}"]), **W.INTERFERENCE_SAMPLING)


def refine(base, key: str, a: float, b: float, which: int, n: int = 40) -> tuple[float, float, float, float]:
    """Bisect [a, b] towards the half with the larger change of metric ``which`` (0 step, 1
    companion). Returns (location, final width, |Δ step|, |Δ companion|) over the last interval."""
    fa, fb = fractions(base, key, a), fractions(base, key, b)
    for _ in range(n):
        m = 0.5 * (a + b)
        fm = fractions(base, key, m)
        if abs(fm[which] - fa[which]) >= abs(fb[which] - fm[which]):
            b, fb = m, fm
        else:
            a, fa = m, fm
    return 0.5 * (a + b), b - a, abs(fb[0] - fa[0]), abs(fb[1] - fa[1])


def sweep(base, key: str, half_span: float, n: int, flag: int) -> dict:
    x0 = float(io.design_to_dict(base)[key.split(".")[0]][key.split(".")[1]])
    xs = np.linspace(x0 - half_span, x0 + half_span, n)
    vals = np.array([fractions(base, key, x) for x in xs])
    d = np.abs(np.diff(vals, axis=0))
    rows = []
    top = np.argsort(d[:, 1])[-flag:]  # the companion's largest neighbour changes
    # the step metric also drifts continuously (the weights move with the design): a jump is a
    # change of more than JUMP between neighbours (one pose group is ≥ 9/216 of the poses)
    for i in sorted(set(np.flatnonzero(d[:, 0] > JUMP)) | set(top)):
        which = 0 if d[i, 0] > JUMP else 1
        loc, width, dstep, dsoft = refine(base, key, xs[i], xs[i + 1], which)
        rows.append(dict(loc=loc, width=width, coarse_step=d[i, 0], coarse_soft=d[i, 1], dstep=dstep, dsoft=dsoft))
    return dict(key=key, x0=x0, xs=xs, vals=vals, rows=rows, h=xs[1] - xs[0])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=301)
    ap.add_argument("--flag", type=int, default=4)
    ap.add_argument("--plot", default="")
    args = ap.parse_args()
    base = io.apply_overrides(io.load_preset("prrr-paper"), STEP_OPTIMUM)
    results = [sweep(base, key, hs, args.n, args.flag) for key, hs in SWEEPS]
    print(f"overlap scale δ = {F.OVERLAP_SCALE * 1e3:g} mm; {args.n} samples a sweep; intervals flagged where the "
          f"step metric changes by > {JUMP:g} or the companion has one of its {args.flag} largest changes, then bisected 40×\n")
    print("| variable | around | sample step | location | coarse Δ step / Δ companion | after bisection: width | Δ step | Δ companion |")
    print("|---|---|---|---|---|---|---|---|")
    for r in results:
        for row in r["rows"]:
            print(f"| {r['key']} | {r['x0']:.4f} | {r['h']:.4f} | {row['loc']:.6f} | {row['coarse_step']:.4f} / "
                  f"{row['coarse_soft']:.4f} | {row['width']:.1e} | {row['dstep']:.4f} | {row['dsoft']:.2e} |")
    print()
    for r in results:
        d = np.abs(np.diff(r["vals"], axis=0))
        print(f"{r['key']}: step range {r['vals'][:, 0].min():.4f}–{r['vals'][:, 0].max():.4f}, "
              f"{int((d[:, 0] > JUMP).sum())} step jumps (largest {d[:, 0].max():.4f}); companion range "
              f"{r['vals'][:, 1].min():.4f}–{r['vals'][:, 1].max():.4f}, largest neighbour change {d[:, 1].max():.4f}; "
              f"largest residual companion jump after bisection "
              f"{max([row['dsoft'] for row in r['rows']], default=0.0):.2e}")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axs = plt.subplots(1, len(results), figsize=(4.5 * len(results), 3.4))
        for ax, r in zip(np.atleast_1d(axs), results):
            ax.plot(r["xs"], r["vals"][:, 0], drawstyle="steps-mid", label="removed (step)")
            ax.plot(r["xs"], r["vals"][:, 1], label=f"overlap (δ {F.OVERLAP_SCALE * 1e3:g} mm)")
            ax.axvline(r["x0"], color="0.6", lw=0.8)
            ax.set_xlabel(r["key"])
        np.atleast_1d(axs)[0].set_ylabel("fraction of sampled volume")
        np.atleast_1d(axs)[0].legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(args.plot)
        print(f"\nplot: {args.plot}")


if __name__ == "__main__":
    main()

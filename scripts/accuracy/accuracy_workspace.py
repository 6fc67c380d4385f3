"""Regenerate the accuracy-vs-time tables of docs/workspace.md (issue 4).

Run: ``.venv/bin/python scripts/accuracy/accuracy_workspace.py`` (prints Markdown). Times are the
median of warm calls (jit compiled beforehand) on the machine it runs on.
"""

from __future__ import annotations

import sys
from pathlib import Path

import functools

import numpy as np

from hapticopt.analysis.master import workspace as M
from hapticopt.analysis.prrr.geometry import workspace as W
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design import io
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from timing import median_wall  # noqa: E402  (benchmarks/timing.py)


def prrr_tables() -> list[str]:
    d = io.load_preset("prrr-paper")
    g = d.geometry
    wp = W.workspace_params(d)
    ref = W.workspace_core(wp, n_phi=65536, n_r=256)
    v_ref, f_ref = float(ref["volume"]), float(ref["footprint_diameter"])
    cyl_ref = 2 * (g.d3 + g.d4 - g.d2)  # closed form (seed digest)
    h_ref = g.stroke - 0.140 / np.tan(g.beta)
    out = ["### 3-PRRR (prrr-paper), reach and stroke",
           "",
           f"Reference: volume and footprint at n_φ = 65536, n_r = 256 (V = {v_ref * 1e9:.6e} mm³, "
           f"footprint {f_ref * 1e3:.3f} mm); cylinder φ{cyl_ref * 1e3:.2f} mm and height at φ140 "
           f"{h_ref * 1e3:.3f} mm in closed form.",
           "",
           "| level | n_φ (per third) | n_r | volume rel. error | cylinder ⌀ error [mm] | height@φ140 error [mm] | footprint rel. error | time [ms] |",
           "|---|---|---|---|---|---|---|---|"]
    for f in Fidelity:
        s = W.SAMPLING[f]
        r = W.evaluate(d, fidelity=f, interference=False)
        t = median_wall(functools.partial(W.evaluate, d, fidelity=f, interference=False))
        out.append(f"| {f} | {s.n_phi} | {s.n_r} | {abs(r.volume - v_ref) / v_ref:.2e} | "
                   f"{abs(r.cylinder_diameter - cyl_ref) * 1e3:.1e} | {abs(r.height_at_required - h_ref) * 1e3:.1e} | "
                   f"{abs(r.footprint_diameter - f_ref) / f_ref:.2e} | {t * 1e3:.2f} |")
    t_fine = median_wall(functools.partial(W.evaluate, d, fidelity=Fidelity.FINE), n=1)
    out += ["", f"fine with interference (216 poses, manifold3d) and the Jacobian check: {t_fine:.2f} s.", ""]
    out += ["Volume convergence in n_φ (midpoint rule in angle, exact radial integral):", "",
            "| n_φ | rel. error | observed order |", "|---|---|---|"]
    prev = None
    for n in (12, 24, 48, 96, 192, 384, 768, 1536):
        e = abs(float(W.workspace_core(wp, n_phi=n, n_r=2)["volume"]) - v_ref) / v_ref
        order = "" if prev is None else f"{np.log(prev / e) / np.log(2):.2f}"
        out.append(f"| {n} | {e:.3e} | {order} |")
        prev = e
    return out


def master_tables() -> list[str]:
    d = io.load_preset("master-paper")
    prm = M.mk.params_of(d)
    ref = {k: np.asarray(v) for k, v in M.conditioning_core(prm, n_gauss=768).items()}
    box = np.asarray(M.DEFAULT_BOX)
    centre = np.asarray(M.evaluate(d, fidelity=Fidelity.FINE).box_centre)
    cov_ref = float(M.coverage_of(prm, box, centre, 160))
    out = ["### Surgical master (master-paper)", "",
           f"Reference: volume and GCI with 768² Gauss points (V = {float(ref['volume']) * 1e9:.6e} mm³, "
           f"GCI = {float(ref['gci']):.6f}); coverage with 160³ cells at the fine level's box centre "
           f"({cov_ref:.5f}).", "",
           "| level | Gauss pts | box cells | volume rel. error | GCI abs. error | coverage abs. error | κ₂ max | time [ms] |",
           "|---|---|---|---|---|---|---|---|"]
    for f in Fidelity:
        s = M.SAMPLING[f]
        r = M.evaluate(d, fidelity=f)
        t = median_wall(functools.partial(M.evaluate, d, fidelity=f), n=5)
        out.append(f"| {f} | {s.n_gauss}² | {s.n_box}³ | {abs(r.volume - float(ref['volume'])) / float(ref['volume']):.2e} | "
                   f"{abs(r.global_conditioning_index - float(ref['gci'])):.2e} | {abs(r.coverage - cov_ref):.2e} | "
                   f"{r.condition_max:.4g} | {t * 1e3:.2f} |")
    return out


if __name__ == "__main__":
    print("\n".join(prrr_tables() + [""] + master_tables()))

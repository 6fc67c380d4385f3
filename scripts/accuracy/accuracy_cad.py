"""Accuracy of the analytic mass model against the CAD, and the CAD timings, for docs/cad.md.

Run: .venv/bin/python scripts/accuracy/accuracy_cad.py
Prints a markdown table per design: per-part mass and inertia error of :func:`mass_properties.analytic`
against :func:`mass_properties.from_cad` (OpenCASCADE volume integrals), and the time per call of
each (CPU time, this machine).
"""

from __future__ import annotations

import time

from hapticopt.design import export as design_export
from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np

from hapticopt.design import io
from hapticopt.design import mass_properties as mp

DESIGNS = {
    "prrr-paper": ("prrr-paper", []),
    "prrr β=35.26° slim": ("prrr-paper", ["geometry.beta_deg=35.26", "structure.link_width_mm=14",
                                          "structure.link_thickness_mm=6", "structure.boss_diameter_mm=18",
                                          "structure.stem_diameter_mm=8"]),
    "master-paper": ("master-paper", []),
}


def cpu_per_call(f, n: int) -> float:
    f()
    t = time.process_time()
    for _ in range(n):
        f()
    return (time.process_time() - t) / n


def main() -> None:
    for label, (preset, sets) in DESIGNS.items():
        d = io.apply_overrides(io.load_preset(preset), sets)
        ana, cad = design_export.mass_properties(d), design_export.mass_properties(d, method=mp.Method.CAD)
        print(f"\n### {label}\n")
        print("| part | mass CAD (g) | mass error | inertia error (Frobenius) | CoM offset (mm) |")
        print("|---|---|---|---|---|")
        for name, c in cad.parts.items():
            a = ana.parts[name]
            print(f"| {name} | {c.mass * 1e3:.2f} | {a.mass / c.mass - 1:+.3%} | "
                  f"{np.linalg.norm(a.inertia - c.inertia) / np.linalg.norm(c.inertia):.3%} | "
                  f"{np.linalg.norm(a.com - c.com) * 1e3:.3f} |")
        t_a = cpu_per_call(lambda: design_export.mass_properties(d), 300)
        t_c = cpu_per_call(lambda: design_export.mass_properties(d, method=mp.Method.CAD), 2)
        print(f"\ntotal mass {cad.total_mass:.4f} kg (analytic {ana.total_mass:.4f} kg); "
              f"analytic {t_a * 1e3:.3f} ms, CAD (build + integrals) {t_c:.3f} s per design "
              f"(CPU time): speed ratio {t_c / t_a:.0f}×")


if __name__ == "__main__":
    main()

"""Regenerate the accuracy-vs-time tables of docs/master.md (issue 5).

Run: ``.venv/bin/python scripts/accuracy/accuracy_master.py`` (prints Markdown). Times: median wall
time and CPU time (process_time) per call of warm calls on the machine it runs on.
"""

from __future__ import annotations

import dataclasses
import time

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
import numpy as np

from hapticopt.analysis.master import balance as mb
from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master import sweep as ms
from hapticopt.analysis.master import transparency as mt
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.design.io import load_preset


def timed(f, n: int) -> tuple[float, float, object]:
    out = f()
    walls, cpu0 = [], time.process_time()
    for _ in range(n):
        t = time.perf_counter()
        f()
        walls.append(time.perf_counter() - t)
    return float(np.median(walls)), (time.process_time() - cpu0) / n, out


def main() -> None:
    base = load_preset("master-paper")
    mu, mf = md.counterweights_for_com_offset(base, (0.004, 0.001))
    d = dataclasses.replace(base, counterweights=dataclasses.replace(base.counterweights, upper_mass=mu,
                                                                      forearm_mass=mf))
    ref = mb.evaluate(d, fidelity=Fidelity.FINE)
    print("| unbalance (CoM offset (4, 1) mm) | radius [mm] | rel. err vs fine | max force [N] | rel. err | wall [ms] | CPU [ms] |")
    print("|---|---|---|---|---|---|---|")
    for fid in Fidelity:
        wall, cpu, r = timed(lambda fid=fid: mb.evaluate(d, fidelity=fid), 5 if fid is Fidelity.FINE else 20)
        print(f"| {fid} | {r.radius * 1e3:.6f} | {abs(r.radius / ref.radius - 1):.1e} | {r.max_force:.6f} | "
              f"{abs(r.max_force / ref.max_force - 1):.1e} | {wall * 1e3:.1f} | {cpu * 1e3:.1f} |")
    model = md.model_of(base)
    print()
    print("| transparency (master-paper) | bandwidth x, z [Hz] | wall [ms] | CPU [ms] |")
    print("|---|---|---|---|")
    wall, cpu, r = timed(lambda: mt.evaluate(base, model=model, fidelity=Fidelity.DRAFT), 50)
    print(f"| frequency domain at the pose (seed 003 controller) | {r.bandwidth[0]:.5f}, {r.bandwidth[1]:.5f} | "
          f"{wall * 1e3:.2f} | {cpu * 1e3:.2f} |")
    for fid, n in ((Fidelity.STANDARD, 10), (Fidelity.FINE, 3)):
        wall, cpu, r = timed(lambda fid=fid: mt.evaluate(base, model=model, fidelity=fid), n)
        print(f"| worst case over the workspace ({fid}) | {r.worst_bandwidth[0]:.5f}, {r.worst_bandwidth[1]:.5f} | "
              f"{wall * 1e3:.1f} | {cpu * 1e3:.1f} |")
    for axis in ("x", "z"):
        c0 = time.process_time()
        s = ms.sweep(base, axis)
        print(f"| MuJoCo sine sweep {axis}, open loop (4 freqs, 3 periods, dt 0.25 ms, 1 kHz hold) | {s.bandwidth:.5f} "
              f"(freq. domain {s.predicted:.5f}, error {100 * s.relative_error:.2f} %) | {s.wall_time * 1e3:.0f} | "
              f"{(time.process_time() - c0) * 1e3:.0f} |")
    from hapticopt.analysis.loop.scene import load_scene
    from hapticopt.analysis.master.mujoco_plant import simulate

    for name in ("master-transparency", "master-protocol-x", "master-protocol-z"):
        c0 = time.process_time()
        r = simulate(base, load_scene(name))
        m = r.measures
        if "bandwidth_error_pct" in m:
            val = (f"{m['transparency_bandwidth_Hz']:.5f} (freq. domain {m['predicted_bandwidth_Hz']:.5f}, "
                   f"error {m['bandwidth_error_pct']:.2f} %)")
        else:
            val = (f"|G_T(1 Hz)| {m['transparency_gain_at_motion']:.6f} (freq. domain "
                   f"{m['predicted_transparency_gain']:.6f}, error {m['transparency_gain_error_pct']:.1e} %)")
        print(f"| scene {name} (firmware, links compensated) | {val} | {r.wall_time * 1e3:.0f} | "
              f"{(time.process_time() - c0) * 1e3:.0f} |")


if __name__ == "__main__":
    main()

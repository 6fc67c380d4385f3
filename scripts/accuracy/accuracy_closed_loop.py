"""Accuracy vs time of the lumped closed loop (regenerates the tables in docs/closed_loop.md).

Run: .venv/bin/python scripts/accuracy/accuracy_closed_loop.py
1. Coulomb-friction substeps: free-space residual force and stiffness-25 rendered stiffness vs a
   40-substep reference, with the median run time of a 3 s scene.
2. Sampling off (continuous-time limit): rendered stiffness vs controller oversampling.
3. K_x limit vs K_p: eigenvalues (continuous), simulation with sampling off and with sampling on.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from hapticopt.analysis.prrr.loop import closed_loop as cl
from hapticopt.analysis.prrr.loop import stability as sb
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.scene import Effect, load_scene
from hapticopt.analysis.prrr.loop.zwidth import StabilityProbe
from hapticopt.design import io


def timed(st, reps=5):
    sim = cl.Simulator(st)
    tr = sim.run()
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        tr = sim.run()
        ts.append(time.perf_counter() - t0)
    return cl.metrics_from_traces(tr, st), float(np.median(ts))


def main() -> None:
    d = io.load_preset("prrr-paper")
    print("## friction substeps (3 s scenes, 1 kHz)")
    print("| substeps | free-space residual [N] | err vs 40 | time [ms] | stiffness-25 K [N/mm] | err vs 40 | time [ms] |")
    print("|---|---|---|---|---|---|---|")
    rows = {}
    for n in (40, 1, 2, 5, 10, 20):
        a, ta = timed(cl.setup(d, dataclasses.replace(load_scene("free-space"), substeps=n)))
        b, tb = timed(cl.setup(d, dataclasses.replace(load_scene("stiffness-25"), substeps=n)))
        rows[n] = (a.residual_force_rms, ta, b.rendered_stiffness * 1e-3, tb)
    ref = rows[40]
    for n, (r, ta, k, tb) in rows.items():
        print(f"| {n} | {r:.4f} | {abs(r - ref[0]) / ref[0] * 100:.2f} % | {ta * 1e3:.1f} | {k:.4f} | "
              f"{abs(k - ref[2]) / ref[2] * 100:.3f} % | {tb * 1e3:.1f} |")

    print("\n## sampling off: oversampling of the controller (stiffness-25, no friction, no quantisation)")
    sc = dataclasses.replace(load_scene("stiffness-25"), effects=load_scene("stiffness-25").effects
                             - {Effect.SAMPLING, Effect.QUANTIZATION, Effect.COULOMB_FRICTION})
    for f in Fidelity:
        st = cl.setup(d, sc, fidelity=f)
        m, t = timed(st, reps=2)
        print(f"| {f} | {cl.OVERSAMPLE[f]} | {m.rendered_stiffness * 1e-3:.5f} N/mm | {t * 1e3:.0f} ms |")

    print("\n## K_x limit vs K_p (zero virtual damping) [N/mm]")
    print("| K_p | eigenvalues | sim, sampling off | sim, sampling on (1 kHz) |")
    print("|---|---|---|---|")
    base = load_scene("z-width")
    off = dataclasses.replace(base, effects=base.effects - {Effect.SAMPLING, Effect.QUANTIZATION, Effect.SATURATION})
    on = dataclasses.replace(base, effects=base.effects - {Effect.QUANTIZATION, Effect.SATURATION}, duration=2.0)
    for kp in (2.0, 5.0, 10.0, 45.0, 100.0, 500.0):
        eig = sb.continuous_stiffness_limit(d, kp=kp, axis=0)
        from hapticopt.analysis.prrr.loop.zwidth import bisect_boundary
        s_off = bisect_boundary(StabilityProbe(d, off, kp=kp), np.zeros(1), 0.5 * eig, 2 * eig, iters=10)[0]
        s_on = bisect_boundary(StabilityProbe(d, on, kp=kp), np.zeros(1), 1e2, 1e6, iters=14)[0]
        print(f"| {kp:g} | {eig * 1e-3:.3f} | {s_off * 1e-3:.3f} | {s_on * 1e-3:.3f} |")


if __name__ == "__main__":
    main()

"""Seed 000 accuracy tables (regenerates the tables of docs/seed000.md). Markdown on stdout.

Run: PYTHONPATH=<shim> .venv/bin/python scripts/accuracy/accuracy_seed000.py
1. Padé hold 2/(2+sT) vs exact ZOH: K_e limit per T (B_e = 0 and the paper's 30 g/s).
2. Upsampling variants on the handle (T = 1 ms): K_e limit by the lifted analysis and by
   simulation, per l2/l1, with median wall times of 5 runs; online AR fit (simulation only).
3. Operator: eq (22) vs the exact critical operator stiffness; limit vs k_h.
4. Z-width boundary vs B_e (exact) against eq (18).
"""

from __future__ import annotations

import statistics
import time

import numpy as np
from hapticopt.analysis.control import upsampling as up
from hapticopt.analysis.handle import model as hm
from hapticopt.analysis.handle import stability as hs
from threadpoolctl import threadpool_limits

H = hm.HANDLE_PAPER
BE = hm.PAPER_WALL_DAMPING_N_S_PER_M
CV = np.array([2.0, -1.0])
RUNS = 5


def timed(fn, n=RUNS):
    out, ts = None, []
    for _ in range(n):
        t = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t)
    return out, statistics.median(ts)


def pade_table() -> None:
    print("### Padé hold vs exact ZOH (K_e limit, N/mm)\n")
    print("| T [ms] | Padé, B_e = 0 | exact, B_e = 0 | Padé − exact | Padé, B_e = 30 g/s | exact, B_e = 30 g/s | Padé − exact |")
    print("|---|---|---|---|---|---|---|")
    T = np.array([0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0]) * 1e-3
    a = hs.pade_vs_exact(H, T)
    b = hs.pade_vs_exact(H.with_(wall_damping_N_s_per_m=BE), T)
    for i, t in enumerate(T):
        print(f"| {t * 1e3:g} | {a.pade_N_per_mm[i]:.4f} | {a.exact_N_per_mm[i]:.4f} | {100 * a.relative_difference[i]:+.3f} % "
              f"| {b.pade_N_per_mm[i]:.4f} | {b.exact_N_per_mm[i]:.4f} | {100 * b.relative_difference[i]:+.3f} % |")
    print()


def upsampling_table() -> None:
    plant = hm.wall_plant(H)
    base = hs.stiffness_limit(H).value_N_per_m
    print(f"### Upsampling variants on the handle (T = 1 ms, B_e = 0, AR(2) = (2, −1) fixed); "
          f"single-rate exact limit {base / 1e3:.4f} N/mm\n")
    print("| l2/l1 | variant | analysis [N/mm] | vs none | simulation [N/mm] | sim − analysis | analysis time | simulation time |")
    print("|---|---|---|---|---|---|---|---|")
    for L in (1, 2, 4, 10):
        for v in up.Variant:
            f = up.Firmware(period_s=1e-3, upsampling=L, variant=v, coefficients=CV)
            lim, ta = timed(lambda f=f: up.lifted_stiffness_limit(plant, f, reference_N_per_m=base))
            K = lim.value_N_per_m
            sim, ts = timed(lambda f=f, K=K: up.simulated_stiffness_limit(plant, f, stiffness_range_N_per_m=(0.3 * K, 3 * K),
                                                                 duration_s=3.0, points=10))
            print(f"| {L} | {v.value} | {K / 1e3:.4f} | {100 * (K / base - 1):+.1f} % | {sim.value_N_per_m / 1e3:.4f} "
                  f"| {100 * (sim.value_N_per_m / K - 1):+.2f} % | {ta * 1e3:.1f} ms | {ts:.2f} s |")
    print("\nOnline least-squares AR(2) fit over 16 samples (nonlinear loop, simulation only):\n")
    print("| l2/l1 | variant | simulation [N/mm] | vs none (exact) | fixed-coefficient analysis [N/mm] | time |")
    print("|---|---|---|---|---|---|")
    for L in (4,):
        for v in (up.Variant.AS_PRINTED, up.Variant.AS_INTENDED):
            f = up.Firmware(period_s=1e-3, upsampling=L, variant=v, order=2, window=16)
            K = up.lifted_stiffness_limit(plant, up.Firmware(period_s=1e-3, upsampling=L, variant=v, coefficients=CV),
                                          reference_N_per_m=base).value_N_per_m
            sim, ts = timed(lambda f=f, K=K: up.simulated_stiffness_limit(plant, f, stiffness_range_N_per_m=(0.3 * K, 3 * K),
                                                                 duration_s=3.0, points=10, online_fit=True))
            print(f"| {L} | {v.value} | {sim.value_N_per_m / 1e3:.4f} ({sim.status}) | {100 * (sim.value_N_per_m / base - 1):+.1f} % "
                  f"| {K / 1e3:.4f} | {ts:.2f} s |")
    print()


def upsampling_with_operator_table() -> None:
    """Lifted analysis with a hand: b_h chosen so that the single-rate limit is Table 1's mean
    without the method (3.86 N/mm), and the same with k_h = 300 N/m, m_h = 50 g."""
    from scipy.optimize import brentq

    bh = brentq(lambda b: hs.stiffness_limit(H.with_(operator=hm.hand(damping=b))).value_N_per_mm - 3.86,
                0.0, 1.0)
    print(f"### Upsampling with an operator (analysis; b_h = {bh:.4f} N·s/m gives 3.86 N/mm single-rate)\n")
    print("| operator | l2/l1 | as printed vs none | as intended vs none |")
    print("|---|---|---|---|")
    for name, op in (("b_h", hm.hand(damping=bh)),
                     ("b_h, k_h = 300 N/m, m_h = 50 g", hm.hand(damping=bh, stiffness=300.0, mass=0.05))):
        h = H.with_(operator=op)
        base = hs.stiffness_limit(h).value_N_per_m
        for L in (2, 4, 10):
            r = [up.lifted_stiffness_limit(hm.wall_plant(h), up.Firmware(period_s=1e-3, upsampling=L, variant=v, coefficients=CV),
                                           reference_N_per_m=base).value_N_per_m / base - 1
                 for v in (up.Variant.AS_PRINTED, up.Variant.AS_INTENDED)]
            print(f"| {name} | {L} | {100 * r[0]:+.1f} % | {100 * r[1]:+.1f} % |")
    print()


def operator_table() -> None:
    print("### Operator stiffness (B_e = 30 g/s, T = 1 ms)\n")
    print("| K_e [N/mm] | eq (22) with R² [N/mm] | exact ZOH critical k_h [N/mm] |")
    print("|---|---|---|")
    h = H.with_(wall_damping_N_s_per_m=BE)
    for Ke in (3.0, 5.0, 10.0, 20.0):
        hk = h.with_(wall_stiffness_N_per_m=Ke * 1e3)
        print(f"| {Ke:g} | {hs.eq22_critical_operator_stiffness(hk) / 1e3:.2f} | {hs.critical_operator_stiffness(hk) / 1e3:.2f} |")
    print("\n| k_h [N/mm] | limit, Padé [N/mm] | limit, exact [N/mm] |")
    print("|---|---|---|")
    for kh in (0.0, 1.0, 10.0, 100.0, 231.6, 1000.0):
        p = hs.max_stable_stiffness_N_per_mm(h, operator_stiffness_N_per_m=kh * 1e3, hold=hm.Hold.PADE)
        e = hs.max_stable_stiffness_N_per_mm(h, operator_stiffness_N_per_m=kh * 1e3)
        print(f"| {kh:g} | {p:.3f} | {e:.3f} |")
    print()


def zwidth_table() -> None:
    B = np.linspace(0.0, 1900.0, 20)
    K = np.geomspace(1e2, 1e6, 20)
    z, t = timed(lambda: hs.zwidth_map(H, B, K))
    print(f"### Z-width boundary (exact loop, T = 1 ms; 20 × 20 map in {t * 1e3:.0f} ms, median of {RUNS})\n")
    print("| B_e [N·s/m] | exact limit [N/mm] | eq (18) [N/mm] | status |")
    print("|---|---|---|---|")
    for i in range(0, 20, 2):
        e18 = hs.eq18_stiffness_limit(H.with_(wall_damping_N_s_per_m=float(B[i])))
        print(f"| {B[i]:.0f} | {z.boundary_N_per_m[i] / 1e3:.2f} | {e18 / 1e3:.2f} | {z.boundary_status[i].value} |")
    print()


if __name__ == "__main__":
    with threadpool_limits(1):
        pade_table()
        operator_table()
        zwidth_table()
        upsampling_with_operator_table()
        upsampling_table()

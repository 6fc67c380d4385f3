"""Accuracy vs time for seed 001 (regenerates the tables in docs/seed001.md).

Run: PYTHONPATH=<shim> python scripts/accuracy/accuracy_seed001.py
1. Learned-K error ‖K − K*‖/‖K*‖ vs data length and number of sampling intervals (1 ms RK4),
   with iterations, rcond of the data matrix and the median wall time of data phase + PI.
2. Learned-K error vs the RK4 step of the data phase (0.5 s, 50 intervals).
3. FIC / OIC / IOIC tracking-error and force RMS (Figs 4–6).
4. The boundary-layer width θ of eq 26 (not printed): joint errors and torque chattering vs θ
   (``--theta`` prints only this table).
5. Two-link NTSMTC: joint errors and torques vs step size, difference to a 0.1 ms reference,
   median wall time of a 15 s run (compiled), and the effect of the 200π rad/s terms of eq 34.
Medians of 5 runs. Prints markdown.
"""

from __future__ import annotations

import dataclasses
import statistics
import time

import numpy as np

from hapticopt.analysis.control import impedance_learning as il
from hapticopt.analysis.control import two_link as tl

REPS = 5


def median_wall(fn, n=REPS):
    fn()
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def learn(duration, n_intervals, substeps, noise=il.ExplorationNoise.printed()):
    cfg = il.OuterLoopConfig()
    a, b, q, r = cfg.matrices()
    k0 = np.array([cfg.k0])
    data = il.collect_data(a, b, k0, noise, np.array([-0.4, 0.0, 0.0]), duration=duration,
                           n_intervals=n_intervals, substeps=substeps)
    return il.policy_iteration(data, k0, q, r, eps=cfg.eps)


def table_learning():
    cfg = il.OuterLoopConfig()
    a, b, q, r = cfg.matrices()
    k_star = il.riccati_optimum(a, b, q, r).k
    print("### Learned K vs data length and sampling intervals (RK4 1 ms, printed noise eq 28)\n")
    print("| data [s] | intervals | status | iterations | rcond | ‖K−K*‖/‖K*‖ | wall [ms] |")
    print("|---|---|---|---|---|---|---|")
    for duration in (0.1, 0.2, 0.5, 1.0):
        for n in (5, 10, 20, 50, 100):
            sub = int(round(duration / n / 1e-3))
            if sub < 1 or abs(duration / n / 1e-3 - sub) > 1e-9:
                continue
            res = learn(duration, n, sub)
            err = np.linalg.norm(res.k - k_star) / np.linalg.norm(k_star)
            wall = median_wall(lambda: learn(duration, n, sub)) * 1e3
            print(f"| {duration:g} | {n} | {res.status.value} | {res.iterations} | "
                  f"{res.rcond:.1e} | {err:.1e} | {wall:.1f} |")
    print()
    print("### Learned K vs RK4 step of the data phase (0.5 s, 50 intervals)\n")
    print("| step [ms] | ‖K−K*‖/‖K*‖ | iterations | wall [ms] |")
    print("|---|---|---|---|")
    for sub in (1, 2, 5, 10, 20, 50):
        res = learn(0.5, 50, sub)
        err = np.linalg.norm(res.k - k_star) / np.linalg.norm(k_star)
        wall = median_wall(lambda: learn(0.5, 50, sub)) * 1e3
        print(f"| {10 / sub:g} | {err:.1e} | {res.iterations} | {wall:.1f} |")
    print()
    print("### Learned K over noise seeds (seeded random multi-sines: ten frequencies log-uniform in "
          f"[{il.MULTISINE_BAND[0]:.1f}, {il.MULTISINE_BAND[1]:g}] rad/s, random phases; 0.5 s, 50 intervals, 1 ms)\n")
    print("| seed | iterations | rcond | ‖K−K*‖/‖K*‖ |")
    print("|---|---|---|---|")
    for seed in range(5):
        res = learn(0.5, 50, 10, il.ExplorationNoise.multisine(seed))
        err = np.linalg.norm(res.k - k_star) / np.linalg.norm(k_star)
        print(f"| {seed} | {res.iterations} | {res.rcond:.1e} | {err:.1e} |")
    res = learn(0.5, 50, 10, il.ExplorationNoise.zero())
    print(f"| no noise | {res.status.value} (rank {res.rank}) | {res.rcond:.1e} | NaN |")
    print()


def table_outer():
    cfg = il.OuterLoopConfig()
    res = il.simulate_outer_loop(cfg)
    hard = il.simulate_outer_loop(dataclasses.replace(cfg, soft=False))
    print(f"### FIC / OIC / IOIC (Figs 4–6), learned K = {np.round(res.learning.k[0], 4)}, "
          f"K* = {np.round(res.optimum.k[0], 4)}\n")
    print("| controller | RMS e_p 0–15 s [m] | RMS f 0–15 s [N] | RMS e_p 1–15 s [m] | "
          "RMS f 1–15 s [N] | RMS e_p 5–15 s [m] | RMS f 5–15 s [N] |")
    print("|---|---|---|---|---|---|---|")
    for tr in (res.fic, res.oic, res.ioic):
        cells = []
        for t0 in (0.0, 1.0, 5.0):
            e, f = tr.rms(t0, 15.0)
            cells += [f"{e:.4f}", f"{f:.4f}"]
        print(f"| {tr.strategy.value.upper()} | " + " | ".join(cells) + " |")
    for name, tr in (("soft switch", res.ioic), ("no soft switch", hard.ioic)):
        sel = (tr.t[1:] >= cfg.t_learn - 1e-12) & (tr.t[1:] <= 2.0)
        du = np.abs(np.diff(tr.u))[sel].max()
        print(f"\nIOIC {name}: peak |Δu| per 1 ms sample in 0.5–2 s: {du:.4f} m/s²", end="")
    print("\n")


def table_two_link():
    ref = tl.simulate(tl.TwoLinkConfig(outer=il.OuterLoopConfig(step=1e-4)))
    print("### Two-link NTSMTC vs step size (15 s; reference 0.1 ms)\n")
    print("| step [ms] | max abs e1 t≥0.5 s [rad] | max abs e2 [rad] | max abs τ1 [N·m] | max abs τ2 [N·m] | "
          "‖e − e_ref‖∞ on 10 ms grid [rad] | compile+run [s] | wall [s] |")
    print("|---|---|---|---|---|---|---|---|")
    for step in (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4):
        cfg = tl.TwoLinkConfig(outer=il.OuterLoopConfig(step=step))
        t0 = time.perf_counter()
        r = tl.simulate(cfg)
        cold = time.perf_counter() - t0
        stride_r = int(round(0.01 / step))
        stride_ref = int(round(0.01 / 1e-4))
        diff = np.abs(r.e[::stride_r] - ref.e[::stride_ref]).max()
        wall = median_wall(lambda: tl.simulate(cfg), n=REPS if step >= 5e-4 else 3)
        e = r.max_abs_error(0.5)
        tau = r.max_abs_torque()
        print(f"| {step * 1e3:g} | {e[0]:.2e} | {e[1]:.2e} | {tau[0]:.1f} | {tau[1]:.1f} | "
              f"{diff:.1e} | {cold:.2f} | {wall:.3f} |")
    print()
    print("### Effect of the 0.2 sin/cos(200πt) terms of eq 34\n")
    print("| step [ms] | fast terms | max abs e1 [rad] | max abs e2 [rad] | mean e2 5–10 s [rad] |")
    print("|---|---|---|---|---|")
    for step in (1e-2, 1e-4):
        for amp in (0.0, 0.2):
            cfg = tl.TwoLinkConfig(outer=il.OuterLoopConfig(step=step), fast_disturbance=amp)
            r = tl.simulate(cfg)
            e = r.max_abs_error(0.5)
            sel = (r.t >= 5.5) & (r.t <= 9.9)
            print(f"| {step * 1e3:g} | {amp:g} | {e[0]:.3e} | {e[1]:.3e} | "
                  f"{r.e[sel, 1].mean():.3e} |")
    r = tl.simulate(tl.TwoLinkConfig())
    print("\n### Two-link torques by window (1 ms)\n")
    print("| window [s] | max abs τ1 [N·m] | max abs τ2 [N·m] |")
    print("|---|---|---|")
    for a_, b_ in ((0.0, 0.5), (0.5, 4.9), (4.9, 5.5), (5.5, 9.9), (9.9, 10.5), (10.5, 15.0)):
        sel = (r.t >= a_) & (r.t <= b_)
        m = np.abs(r.tau[sel]).max(axis=0)
        print(f"| {a_:g}–{b_:g} | {m[0]:.1f} | {m[1]:.1f} |")
    print()


def table_theta():
    print("### NTSMTC boundary layer θ (eq 26, not printed) vs Fig 10 (two-link, 1 ms, 15 s)\n")
    print("| θ [rad/s] | max abs e1 t≥0.5 s [rad] | max abs e2 [rad] | e / Fig 10 (3e-3, 6e-3) "
          "| torque variation 0.5–4.9 s [N·m/s] (τ1, τ2) |")
    print("|---|---|---|---|---|")
    for theta in (0.01, 0.05, 0.2, 0.5, 1.0, 2.0, 5.0):
        r = tl.simulate(tl.TwoLinkConfig(ctrl=dataclasses.replace(tl.TwoLinkConfig().ctrl, theta=theta)))
        e = r.max_abs_error(0.5)
        sel = (r.t >= 0.5) & (r.t < 4.9)
        tv = np.abs(np.diff(r.tau[sel], axis=0)).sum(axis=0) / 4.4
        print(f"| {theta:g} | {e[0]:.2e} | {e[1]:.2e} | {e[0] / 3e-3:.2f}, {e[1] / 6e-3:.2f} | {tv[0]:.1f}, {tv[1]:.1f} |")
    print()


if __name__ == "__main__":
    import sys

    if "--theta" in sys.argv:
        table_theta()
        sys.exit(0)
    if "--seeds" in sys.argv:
        table_learning()
        sys.exit(0)
    table_learning()
    table_outer()
    table_theta()
    table_two_link()

"""Seed 000 on the 3-PRRR (issue 17): upsampling variants and the operator effect. Markdown on stdout.

Run: PYTHONPATH=<shim> .venv/bin/python scripts/accuracy/accuracy_seed000_prrr.py [--plot docs/img/prrr_operator_effect.png]
1. Upsampling on the 3-PRRR's SEA loop (prrr-paper, K_p = 45, T = 1 ms, x axis, B_v = 0): K_v limit
   by the exact lifted analysis (analysis/prrr/multirate) and by the compiled closed-loop simulation
   (analysis/prrr/zwidth.StabilityProbe, decay criterion, 1 s runs, geometric bisection 12 steps),
   none / as printed / as intended for l2/l1 = 1, 2, 4, 10; and with the encoders' quantisation
   (bundled z-width scene) by simulation only.
2. The operator effect: K_v limit vs the hand's stiffness k_h at K_p = 45 and 100, for a pure hand
   spring and for the scenes' hand (m_h = 0.3 kg, b_h = 50 N·s/m): the continuous closed form
   (multirate.hand_limit_closed_form), the exact sampled loop (T = 1 ms), the crossing frequency
   and the force loop's frequency ω_f. With --plot, the figure of docs/seed000.md.
3. The force loop's gain margin on the deflection feedback (k x̂ scaled by g until ρ(𝓛) = 1) at
   K_v = 5 N/mm, per variant: why quantisation breaks the literal spline.
"""

from __future__ import annotations

import dataclasses
import statistics
import sys
import time

import numpy as np
from hapticopt.analysis.control.upsampling import Predictor, Variant
from hapticopt.analysis.loop.operator import Operator
from hapticopt.analysis.loop.scene import StabilityCriterion, load_scene
from hapticopt.analysis.prrr.loop import multirate as mr, zwidth
from hapticopt.design import io
from threadpoolctl import threadpool_limits

D = io.load_preset("prrr-paper")


def simulated(settings: mr.LoopSettings, scene=None) -> float:
    sc = scene or dataclasses.replace(mr.linear_scene(settings), stability=StabilityCriterion.DECAY, duration=1.0)
    probe = zwidth.StabilityProbe(D, sc)
    return float(zwidth.bisect_boundary(probe, np.zeros(1), 0.2e3, 60e3, iters=12)[0])


def upsampling_table() -> None:
    print("### Upsampling on the 3-PRRR (prrr-paper, K_p = 45, T = 1 ms, x, B_v = 0)\n")
    print("| l2/l1 | variant | exact analysis [N/mm] | vs none | simulation [N/mm] | sim − analysis | "
          "with quantisation, simulation [N/mm] | analysis time |")
    print("|---|---|---|---|---|---|---|---|")
    base = mr.stiffness_limit(D, mr.LoopSettings()).value_N_per_m
    zw = load_scene("z-width")
    for L in (1, 2, 4, 10):
        for v in Variant:
            s = mr.LoopSettings(upsampling=L, variant=v)
            ts = []
            for _ in range(3):
                t = time.perf_counter()
                lim = mr.stiffness_limit(D, s).value_N_per_m
                ts.append(time.perf_counter() - t)
            sim = simulated(s)
            q = simulated(s, dataclasses.replace(zw, controller=dataclasses.replace(
                zw.controller, interpolation=L, interpolation_variant=v)))
            qs = f"{q / 1e3:.2f}" if q > 0.2e3 else "< 0.2 (unstable at every K)"
            print(f"| {L} | {v.value} | {lim / 1e3:.3f} | {100 * (lim / base - 1):+.2f} % | {sim / 1e3:.3f} | "
                  f"{100 * (sim / lim - 1):+.2f} % | {qs} | {1e3 * statistics.median(ts):.0f} ms |")
    print()


KH = np.concatenate([[0.0], np.geomspace(0.1e3, 300e3, 40)])
HANDS = {"pure spring (m_h = b_h = 0)": (0.0, 0.0), "scene hand (m_h = 0.3 kg, b_h = 50 N·s/m)": (0.3, 50.0)}


def operator_rows(kp: float, mass: float, damping: float):
    rows = []
    for kh in KH:
        op = Operator(mass=mass, damping=damping, stiffness=float(kh))
        cf = mr.hand_limit_closed_form(D, force_gain=kp, operator=op)
        ex = mr.stiffness_limit(D, mr.LoopSettings(force_gain=kp, operator=op))
        rows.append((kh, cf, ex.value_N_per_m))
    return rows


def operator_table(plot: str | None) -> None:
    print("### The operator effect on the 3-PRRR (x axis, T = 1 ms; continuous = T → 0 closed form)\n")
    print("| K_p | hand | k_h [N/mm] | continuous limit [N/mm] | sampled limit [N/mm] | crossing ω [rad/s] | ω_f [rad/s] |")
    print("|---|---|---|---|---|---|---|")
    data = {}
    for kp in (45.0, 100.0):
        for name, (m, b) in HANDS.items():
            rows = operator_rows(kp, m, b)
            data[(kp, name)] = rows
            for kh, cf, ex in rows:
                if kh in (0.0,) or np.isclose(kh, [1e3, 5e3, 20e3, 50e3, 100e3, 300e3], rtol=0.08).any():
                    exs = f"{ex / 1e3:.2f}" if np.isfinite(ex) else "— (unstable without a wall)"
                    print(f"| {kp:g} | {name} | {kh / 1e3:.3g} | {cf.stiffness_N_per_m / 1e3:.2f} | {exs} | "
                          f"{cf.crossing_rad_s:.0f} | {cf.force_loop_rad_s:.0f} |")
    print()
    if plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(7.5, 7))
        colors = {45.0: "tab:blue", 100.0: "tab:red"}
        for (kp, name), rows in data.items():
            kh = np.array([r[0] for r in rows[1:]]) / 1e3
            cont = np.array([r[1].stiffness_N_per_m for r in rows[1:]]) / 1e3
            samp = np.array([r[2] for r in rows[1:]]) / 1e3
            w = np.array([r[1].crossing_rad_s for r in rows[1:]])
            ls = "-" if "scene" in name else ":"
            a1.plot(kh, cont, ls, color=colors[kp], label=f"K_p = {kp:g}, {name.split(' (')[0]}, continuous")
            a1.plot(kh, samp, "o", ms=2.5, color=colors[kp], alpha=0.6)
            a2.plot(kh, w, ls, color=colors[kp], label=f"K_p = {kp:g}, {name.split(' (')[0]}: crossing ω")
            a2.axhline(rows[0][1].force_loop_rad_s, color=colors[kp], lw=0.8, ls="--")
        a1.set_xscale("log")
        a1.set_ylim(25.0, 70.0)
        a1.set_ylabel("max stable K_v along x [N/mm]")
        a1.set_title("3-PRRR wall limit vs hand stiffness (lines: T → 0 closed form; dots: exact loop, T = 1 ms)",
                     fontsize=9)
        a1.legend(fontsize=7)
        a2.set_xscale("log")
        a2.set_ylabel("ω of the crossing pole pair [rad/s]")
        a2.set_xlabel("hand stiffness k_h [N/mm]")
        a2.text(0.12, 175, "ω_f, K_p = 45", color=colors[45.0], fontsize=8)
        a2.text(0.12, 258, "ω_f, K_p = 100", color=colors[100.0], fontsize=8)
        a2.legend(fontsize=7, loc="upper left")
        fig.tight_layout()
        fig.savefig(plot, dpi=100)
        print(f"wrote {plot}", file=sys.stderr)


def gain_margin_table() -> None:
    from hapticopt.analysis.loop.scene import resolve
    from hapticopt.analysis.prrr.loop.lumped_plant import build_model, discretise

    print("### Gain margin of the force loop on the deflection feedback (K_v = 5 N/mm, linear loop)\n")
    print("| l2/l1 | variant | g at ρ(𝓛) = 1 (scan 1 … 4, step 0.025) |")
    print("|---|---|---|")
    for L, v in ((1, Variant.NONE), (2, Variant.AS_PRINTED), (2, Variant.AS_INTENDED), (4, Variant.AS_PRINTED),
                 (4, Variant.AS_INTENDED), (10, Variant.AS_PRINTED), (10, Variant.AS_INTENDED)):
        s = mr.LoopSettings(upsampling=L, variant=v)
        sc = mr.linear_scene(s)
        m = build_model(D, sc, resolve(sc))
        disc = discretise(m, s.period_s / L)
        gs = np.arange(1.0, 4.0001, 0.025)
        first = next((g for g in gs if mr.axis_margin(
            D, s, 5e3, _plant=(dataclasses.replace(m, spring=g * m.spring), disc)) < 0.0), None)
        print(f"| {L} | {v.value} | {'> 4' if first is None else f'{first:.3f}'} |")
    print()


def online_predictor_table() -> None:
    """The online position predictor (controller.predictor = online, AR(2) over 16 positions per axis) against
    the fixed command extrapolation (2, −1): simulated K_v limit (nonlinear loop: no lifted analysis)."""
    print("### The online position predictor on the 3-PRRR (prrr-paper, K_p = 45, T = 1 ms, x, B_v = 0; simulation)\n")
    print("| l2/l1 | variant | fixed (2, −1) on the command [N/mm] | online AR(2)/16 on the positions [N/mm] | "
          "online vs fixed | with quantisation, online [N/mm] |")
    print("|---|---|---|---|---|---|")
    zw = load_scene("z-width")
    for L in (2, 4, 10):
        for v in (Variant.AS_PRINTED, Variant.AS_INTENDED):
            s = mr.LoopSettings(upsampling=L, variant=v)
            base = dataclasses.replace(mr.linear_scene(s), stability=StabilityCriterion.DECAY, duration=1.0)
            fixed = simulated(s, base)
            online = simulated(s, dataclasses.replace(base, controller=dataclasses.replace(
                base.controller, predictor=Predictor.ONLINE)))
            q = simulated(s, dataclasses.replace(zw, controller=dataclasses.replace(
                zw.controller, interpolation=L, interpolation_variant=v, predictor=Predictor.ONLINE)))
            qs = f"{q / 1e3:.2f}" if q > 0.2e3 else "< 0.2 (unstable at every K)"
            print(f"| {L} | {v.value} | {fixed / 1e3:.3f} | {online / 1e3:.3f} | {100 * (online / fixed - 1):+.2f} % | {qs} |")
    print()


if __name__ == "__main__":
    plot = sys.argv[sys.argv.index("--plot") + 1] if "--plot" in sys.argv else None
    if "--online-only" in sys.argv:
        with threadpool_limits(1):
            online_predictor_table()
        sys.exit(0)
    with threadpool_limits(1):
        operator_table(plot)
        gain_margin_table()
        if "--no-upsampling" not in sys.argv:
            upsampling_table()
            online_predictor_table()

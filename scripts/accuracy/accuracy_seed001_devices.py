"""Seed 001's controllers in our devices (regenerates the device tables of docs/seed001.md).

Run: PYTHONPATH=<shim> python scripts/accuracy/accuracy_seed001_devices.py
1. FIC / OIC / IOIC (seed 001 Figs 4–6) on the master (IOIC + NTSMTC, MuJoCo, scene master-ioic)
   and on the 3-PRRR (IOIC over the SEA force loops, lumped plant, scene prrr-ioic): learned gain
   against the Riccati optimum of eq 6, the impedance, RMS impedance error e_p = x − x_d and
   interaction force after learning (t ≥ 1 s), IOIC/OIC ratios, tracking error x − x_r, peak joint
   torques / motor commands, wall time (median of 3).
2. Hard case: the data phase without exploration noise (status, rank, rcond).
3. What limits the learned gain on each device: the master without encoder quantization; the
   3-PRRR with other tracking stiffnesses.
4. ``--exploration``: the learned M, B, K against the Riccati optimum (the status's three errors)
   under eq 28 as printed and five seeded random multi-sines (``ioic.noise_seed``), and under eq 28
   scaled by 0 … 10 (the data matrix's rcond against the learned impedance: the sweep behind
   ``impedance_learning.RCOND_MIN``). The scaled runs replace the scene's noise through
   ``ioic_online.outer_config`` (no scene key scales it); 1.2 s runs (learning at 0.5 s).
Prints markdown. With ``--figure PATH`` it instead draws the IOIC runs of both devices
(x_d, x_r, x along the axis; the force f; the gain K(t)) to PATH (docs/figures/seed001_devices.png).
"""

from __future__ import annotations

import dataclasses
import statistics
import time

from hapticopt.analysis import verify
from hapticopt.analysis.loop.scene import Effect, IoicStrategy, load_scene
from hapticopt.design.io import load_preset

REPS = 1  # wall times below are single runs on a shared machine
DEVICES = (("master", "master-paper", "master-ioic"), ("3-PRRR", "prrr-paper", "prrr-ioic"))


def run(design, scene, reps=1):
    ts, r = [], None
    for _ in range(reps):
        t0 = time.perf_counter()
        r = verify.simulate(design, scene)
        ts.append(time.perf_counter() - t0)
    return r, statistics.median(ts)


def fmt(v, f="{:.4g}"):
    return "—" if v is None else f.format(v)


def errs(m):
    vals = [m.get(f"impedance_{k}_rel_error") for k in ("mass", "damping", "stiffness")]
    return "—" if any(v is None for v in vals) else ", ".join(f"{100 * v:+.1f} %" for v in vals)


def _with_noise(design, scene, noise):
    """Run ``scene`` with the outer loop's exploration replaced by ``noise``."""
    from hapticopt.analysis.control import ioic_online

    orig = ioic_online.outer_config
    ioic_online.outer_config = lambda sc, T: dataclasses.replace(orig(sc, T), noise=noise)
    try:
        return verify.simulate(design, scene)
    finally:
        ioic_online.outer_config = orig


def table_exploration():
    from hapticopt.analysis.control import impedance_learning as il

    print("### Exploration: eq 28 as printed, seeded random multi-sines, eq 28 scaled (1.2 s runs)\n")
    print("| device | exploration | status | learning | rcond | ‖K−K*‖/‖K*‖ | M, B, K error to M*, B*, K* |")
    print("|---|---|---|---|---|---|---|")
    for dev, preset, name in DEVICES:
        design, base = load_preset(preset), load_scene(name)
        base = dataclasses.replace(base, duration=1.2)
        cases = [("eq 28 as printed", base)]
        cases += [(f"multi-sine seed {k}", dataclasses.replace(base, ioic=dataclasses.replace(base.ioic, noise_seed=k)))
                  for k in range(5)]
        rows = [(label, verify.simulate(design, sc)) for label, sc in cases]
        printed = il.ExplorationNoise.printed()
        for scale in (0.0, 1e-3, 1e-2, 0.1, 10.0):
            noise = dataclasses.replace(printed, amplitudes=tuple(a * scale for a in printed.amplitudes))
            rows.append((f"eq 28 × {scale:g}", _with_noise(design, base, noise)))
        for label, r in rows:
            m = r.metrics()
            print(f"| {dev} | {label} | {r.status} | {m['learning_status']} | {m['data_matrix_rcond']:.1e} "
                  f"| {fmt(m['gain_rel_error_to_optimum'], '{:.2e}')} | {errs(m)} |")
    print()


def table_strategies():
    print("### FIC / OIC / IOIC on the devices (after learning: t ≥ 1 s)\n")
    print("| device | strategy | status | ‖K−K*‖/‖K*‖ | M [kg] | B [N·s/m] | K [N/m] | M, B, K error to M*, B*, K* "
          "| RMS e_p [mm] | RMS f [N] "
          "| RMS e_p / OIC | RMS f / OIC | tracking RMS / peak [mm] | peak torque [N·m] or command [N] | wall [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for dev, preset, name in DEVICES:
        design, base = load_preset(preset), load_scene(name)
        rows = {}
        for strat in (IoicStrategy.FIC, IoicStrategy.OIC, IoicStrategy.IOIC):
            sc = dataclasses.replace(base, ioic=dataclasses.replace(base.ioic, strategy=strat))
            r, wall = run(design, sc, REPS)
            rows[strat] = (r.metrics(), wall, r.status)
        oic = rows[IoicStrategy.OIC][0]
        for strat, (m, wall, status) in rows.items():
            peak = m.get("joint_torque_peak_Nm") or m.get("motor_command_peak_N")
            peak_s = ", ".join(f"{v:.3g}" for v in peak) if isinstance(peak, list) else fmt(peak, "{:.4g}")
            print(f"| {dev} | {strat.value} | {status} | {fmt(m['gain_rel_error_to_optimum'], '{:.2e}')} "
                  f"| {fmt(m['impedance_mass_kg'])} | {fmt(m['impedance_damping_Ns_per_m'])} "
                  f"| {fmt(m['impedance_stiffness_N_per_m'])} | {errs(m)} | {fmt(m['impedance_error_rms_after_learning_mm'])} "
                  f"| {fmt(m['interaction_force_rms_after_learning_N'])} "
                  f"| {m['impedance_error_rms_after_learning_mm'] / oic['impedance_error_rms_after_learning_mm']:.4f} "
                  f"| {m['interaction_force_rms_after_learning_N'] / oic['interaction_force_rms_after_learning_N']:.4f} "
                  f"| {m['tracking_error_rms_mm']:.3g} / {m['tracking_error_peak_mm']:.3g} | {peak_s} | {wall:.2f} |")
        m = rows[IoicStrategy.IOIC][0]
        print(f"\n{dev}: Riccati optimum M* = {m['optimal_impedance_mass_kg']:.4f} kg, "
              f"B* = {m['optimal_impedance_damping_Ns_per_m']:.4f} N·s/m, K* = {m['optimal_impedance_stiffness_N_per_m']:.4f} N/m; "
              f"learned gain {['%.4f' % v for v in m['gain_SI']]} vs K* {['%.4f' % v for v in m['optimal_gain_SI']]}; "
              f"{m['learning_iterations']} iterations, rcond {m['data_matrix_rcond']:.2e}\n")


def table_hard_cases():
    print("### Data phase without exploration noise (eq 8's rank condition)\n")
    print("| device | status | learning status | rank / unknowns | rcond | learned gain | message |")
    print("|---|---|---|---|---|---|---|")
    for dev, preset, name in DEVICES:
        base = load_scene(name)
        sc = dataclasses.replace(base, duration=1.5, ioic=dataclasses.replace(base.ioic, exploration=False))
        r, _ = run(load_preset(preset), sc)
        m = r.metrics()
        print(f"| {dev} | {r.status} | {m['learning_status']} | {m['data_matrix_rank']} / {m['data_matrix_unknowns']} "
              f"| {m['data_matrix_rcond']:.1e} | {m['gain_SI']} | {r.message[:90]} |")
    print()


def table_limits():
    print("### What limits the learned gain on the device\n")
    print("| device | variant | ‖K−K*‖/‖K*‖ | learned K | tracking RMS [mm] |")
    print("|---|---|---|---|---|")
    variants = []
    base = load_scene("master-ioic")
    variants.append(("master", "master-paper", "as bundled", base))
    variants.append(("master", "master-paper", "no encoder quantization",
                     dataclasses.replace(base, effects=base.effects - {Effect.QUANTIZATION})))
    fast = dataclasses.replace(base.ntsmtc, lambda1=(30.0,) * 3, lambda2=(30.0,) * 3)
    variants.append(("master", "master-paper", "NTSMTC λ1 = λ2 = 30 1/s (§4.2: 3)", dataclasses.replace(base, ntsmtc=fast)))
    variants.append(("master", "master-paper", "λ = 30 1/s, no quantization",
                     dataclasses.replace(base, ntsmtc=fast, effects=base.effects - {Effect.QUANTIZATION})))
    base = load_scene("prrr-ioic")
    for k in (5.0, 10.0, 20.0):
        variants.append(("3-PRRR", "prrr-paper", f"tracking stiffness {k:g} N/mm",
                         dataclasses.replace(base, ioic=dataclasses.replace(base.ioic, tracking_stiffness=k * 1e3))))
    variants.append(("3-PRRR", "prrr-paper", "10 N/mm, no quantization, no gravity",
                     dataclasses.replace(base, effects=base.effects - {Effect.QUANTIZATION, Effect.GRAVITY})))
    for dev, preset, label, sc in variants:
        r, _ = run(load_preset(preset), sc)
        m = r.metrics()
        k = m["gain_SI"]
        print(f"| {dev} | {label} | {fmt(m['gain_rel_error_to_optimum'], '{:.2e}')} "
              f"| {'—' if k is None else [round(v, 4) for v in k]} | {fmt(m['tracking_error_rms_mm'], '{:.3g}')} |")
    print()


def figure(path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(3, 2, figsize=(11, 7.5), sharex=True)
    for col, (dev, preset, name) in enumerate(DEVICES):
        design, base = load_preset(preset), load_scene(name)
        for strat, style in ((IoicStrategy.FIC, ":"), (IoicStrategy.OIC, "--"), (IoicStrategy.IOIC, "-")):
            sc = dataclasses.replace(base, ioic=dataclasses.replace(base.ioic, strategy=strat))
            r = verify.simulate(design, sc)
            rec = r.record
            x0 = rec.x_r[0]
            if strat == IoicStrategy.IOIC:
                ax[0, col].plot(rec.t, (rec.x_d - x0) * 1e3, "k", lw=0.8, label="x_d")
                ax[0, col].plot(rec.t, (rec.x_r - x0) * 1e3, "C1", lw=1.2, label="x_r (IOIC)")
                ax[0, col].plot(rec.t, (rec.x - x0) * 1e3, "C0--", lw=0.8, label="x (IOIC)")
                for i, lab in enumerate(("K1 [1/s²]", "K2 [1/s]", "10·K3 [1/kg]")):
                    ax[2, col].plot(rec.t, rec.gain[:, i] * (10 if i == 2 else 1), f"C{i}", label=lab)
                    k = r.metrics()["optimal_gain_SI"][i] * (10 if i == 2 else 1)
                    ax[2, col].axhline(k, color=f"C{i}", ls=":", lw=0.8)
            ax[1, col].plot(rec.t, rec.f, "C3" + style, lw=1.0, label=f"f, {strat.value.upper()}")
        ax[0, col].set_title(f"{dev} ({name})")
        ax[0, col].set_ylabel("position − start [mm]")
        ax[1, col].set_ylabel("operator force f [N]")
        ax[2, col].set_ylabel("gain (dotted: Riccati K*)")
        ax[2, col].set_xlabel("t [s]")
        for a in ax[:, col]:
            a.legend(fontsize=7, loc="upper right")
            a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


if __name__ == "__main__":
    import sys

    if "--exploration" in sys.argv:
        table_exploration()
        sys.exit(0)
    if "--strategies" in sys.argv:
        table_strategies()
        sys.exit(0)
    if "--limits" in sys.argv:
        table_limits()
        sys.exit(0)
    if "--figure" in sys.argv:
        figure(sys.argv[sys.argv.index("--figure") + 1])
        sys.exit(0)
    table_strategies()
    table_hard_cases()
    table_limits()

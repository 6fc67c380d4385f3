"""Accuracy-vs-time table of the MuJoCo 3-PRRR (docs/multibody.md): solver settings vs closed-chain
violation, platform rotation, closure error (and the force error it makes at 25 N/mm), energy drift
of the undamped oscillator, and wall time.

Run: ``.venv/bin/python scripts/accuracy/accuracy_mujoco.py`` (≈ 1 min on the 2-core machine).
"""

from __future__ import annotations

import sys
from pathlib import Path

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.prrr.loop.mujoco_model import (
    Integrator,
    LinkMasses,
    ModelOptions,
    Platform,
    SolverSettings,
    stress_probe,
)
from hapticopt.design import io

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "analysis" / "prrr" / "loop"))
from test_mujoco_model import oscillator_energy  # noqa: E402

DESIGN = io.load_preset("prrr-paper")
DEFAULT_IMP = (0.9, 0.95, 0.001, 0.5, 2.0)
CASES = [
    ("MuJoCo defaults (dt 2 ms, solref 0.02, solimp 0.9)", SolverSettings(
        timestep=2e-3, integrator=Integrator.EULER, solref=(0.02, 1.0), solimp=DEFAULT_IMP)),
    ("dt 0.1 ms, solref 0.002, default solimp", SolverSettings(
        timestep=1e-4, integrator=Integrator.EULER, solref=(0.002, 1.0), solimp=DEFAULT_IMP)),
    ("draft: Euler dt 0.25 ms, solref 2dt, solimp 0.9999", SolverSettings(
        timestep=2.5e-4, integrator=Integrator.EULER, solref=(5e-4, 1.0))),
    ("standard: Euler dt 0.1 ms, solref 2dt, solimp 0.9999", SolverSettings(
        timestep=1e-4, integrator=Integrator.EULER, solref=(2e-4, 1.0))),
    ("implicitfast dt 0.1 ms, solref 2dt, solimp 0.9999", SolverSettings(
        timestep=1e-4, integrator=Integrator.IMPLICITFAST, solref=(2e-4, 1.0))),
    ("RK4 dt 0.1 ms, solref 2dt, solimp 0.9999", SolverSettings(
        timestep=1e-4, integrator=Integrator.RK4, solref=(2e-4, 1.0))),
    ("fine: RK4 dt 25 us, solref 2dt, solimp 0.9999", SolverSettings(
        timestep=2.5e-5, integrator=Integrator.RK4, solref=(5e-5, 1.0))),
]


def main() -> None:
    print("| settings | links | violation mm | rotation mrad | closure mm | force err @25 N/mm N "
          "| energy drift % (10 periods) | wall s per sim s |")
    print("|---|---|---|---|---|---|---|---|")
    for name, solver in CASES:
        for lm in LinkMasses:
            r = stress_probe(DESIGN, ModelOptions(platform=Platform.FREE, link_masses=lm, motor_dynamics=False,
                                                  solver=solver), duration=0.5)
            try:
                e, per = oscillator_energy(lm, solver)
                drift = f"{(e[-per:].mean() - e[:per].mean()) / e[:per].mean() * 100:+.3f}"
            except Exception as exc:  # noqa: BLE001 - a diverging setting is a table entry
                drift = f"failed ({type(exc).__name__})"
            h = r.health
            flag = "" if r.finite and not r.warnings else f" ({', '.join(r.warnings) or 'non-finite'})"
            print(f"| {name}{flag} | {lm.value} | {h.violation * 1e3:.3g} | {h.rotation * 1e3:.3g} | "
                  f"{h.closure * 1e3:.3g} | {h.closure * 25e3:.3g} | {drift} | {r.wall_s / 0.5:.2f} |", flush=True)


if __name__ == "__main__":
    main()

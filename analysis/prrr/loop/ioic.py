"""The 3-PRRR in its IOIC firmware mode (seed 001) on the lumped SEA plant.

Plant: the lumped two-mass SEA model of :mod:`hapticopt.analysis.prrr.loop.lumped_plant` (seed 002 eq 6–7,
the scene's effects, Coulomb friction by the same implicit velocity-level solve) without the
seed-000 hand body; the eq-2 operator's force −f e_axis acts on the output sliders as Jᵀ(−f e_axis),
held over the period (as the master's), and f is advanced exactly over each period with the
period's mean error p_axis − x_d (its time constant K_r/K_f = 0.1 s in §4.1 is 100 periods).
Without an operator body nothing but friction damps the output: the seed-002 SEA force loop
(K_p = 45) against a free end-effector without Coulomb friction grows (docs/seed001.md),
so the bundled scene keeps friction on. Firmware:
:class:`hapticopt.analysis.prrr.loop.firmware_ioic.PrrrIoicController` (counts rounded when
``quantization`` is on, the handle force sensor −f e_axis).

Metrics: the outer loop's (:func:`hapticopt.analysis.control.ioic_online.outer_metrics`) and the
inner loop's — motor commands, force tracking of the SEA loops (Cartesian actuator force vs F).
Status as :mod:`hapticopt.analysis.master.ioic` (``not-met`` when the learned M, B or K is outside the
tolerance of the Riccati optimum).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hapticopt.analysis.control import impedance_learning as il
from hapticopt.analysis.control import ioic_online
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.scene import Effect, FirmwareMode, Scene, require_mode, resolve
from hapticopt.analysis.loop.traces import OVERSAMPLE, Traces
from hapticopt.analysis.prrr.loop import firmware
from hapticopt.analysis.prrr.loop.firmware_ioic import PrrrIoicConfig, PrrrIoicController
from hapticopt.analysis.loop.operator import force_step
from hapticopt.analysis.prrr.loop.closed_loop import FRICTION_SUBSTEPS
from hapticopt.analysis.prrr.loop.lumped_plant import (FRICTION_ITERS, build_model, discretise, observables,
                                                 sensor_values, solve_friction)
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidInput


@dataclass(frozen=True, kw_only=True)
class PrrrIoicResult:
    """A 3-PRRR IOIC run: metrics with units, status, records."""

    scene: str
    status: Status
    message: str
    measures: dict[str, Any]
    stable: bool
    unstable_at: float | None
    effects: tuple[str, ...]
    notes: tuple[str, ...]
    reason: str
    period: float
    wall_time: float
    learning: il.LearningResult | None
    record: ioic_online.OuterRecord = field(repr=False, compare=False)
    commands: np.ndarray = field(repr=False, compare=False)  # (N, 3) motor commands [N]
    traces: Traces | None = field(default=None, repr=False, compare=False)

    def metrics(self) -> dict[str, Any]:
        out: dict[str, Any] = {"stable": self.stable, "unstable_at_s": self.unstable_at}
        out.update(self.measures)
        out.update({"backend": "lumped", "backend_reason": self.reason, "device": "prrr",
                    "firmware_mode": FirmwareMode.IOIC.value, "effects": list(self.effects),
                    "controller_period_ms": self.period * 1e3, "wall_time_s": self.wall_time})
        return out


def simulate(design: Any, scene: Scene, *, fidelity: Fidelity = Fidelity.STANDARD) -> PrrrIoicResult:
    """Run a 3-PRRR scene in the IOIC firmware mode on the lumped SEA plant with the eq-2 operator."""
    require_mode(scene, FirmwareMode.IOIC, "the 3-PRRR's IOIC firmware (hapticopt.analysis.prrr.loop.ioic)")
    res = resolve(scene)
    fx = res.effects
    if scene.controller.interpolation != 1:
        raise InvalidInput(f"scene {scene.name}: controller.interpolation = {scene.controller.interpolation}: the IOIC "
                           "mode holds its commands over the period: allowed 1")
    if res.backend.value != "lumped":
        raise InvalidInput(f"scene {scene.name}: the IOIC mode of the 3-PRRR runs on the lumped plant: set backend = "
                           "\"auto\" and effects.link_dynamics = false")
    T = scene.controller.period if Effect.SAMPLING in fx else scene.controller.period / OVERSAMPLE[fidelity]
    t0 = time.perf_counter()
    plant_res = dataclasses.replace(res, effects=fx - {Effect.OPERATOR})
    model = build_model(design, scene, plant_res)
    base, gains = firmware.build(design, scene, plant_res, period=T)
    s, op = scene.ioic, scene.operator
    ax = s.axis
    J = model.J
    e_ax = np.eye(3)[ax]
    substeps = scene.substeps or (FRICTION_SUBSTEPS[fidelity] if Effect.COULOMB_FRICTION in fx else 1)
    disc = discretise(model, T / substeps)
    G = disc.Bld[model.out_vel] if model.coulomb > 0.0 else None
    p_start = model.x0[model.out_pos] @ J.T if model.out_pos is not None else np.zeros(3)
    cfg = PrrrIoicConfig(base=base, gains=gains, outer=ioic_online.outer_config(scene, T), axis=ax,
                         x_start=tuple(map(float, p_start)), motion=scene.motion, mass=design.end_effector.mass,
                         tracking_stiffness=s.tracking_stiffness, tracking_damping=s.tracking_damping)
    ctl = PrrrIoicController(cfg)
    res_m = float(gains.resolution)
    quantize = Effect.QUANTIZATION in fx
    q = np.round if quantize else (lambda a: a)
    delay_ticks = int(round(scene.time_delay / T)) if Effect.TIME_DELAY in fx else 0
    N = max(1, int(round(scene.duration / T)))
    x = model.x0.copy()
    lam = np.zeros(3)
    f = 0.0
    u_last = np.zeros(3)
    slider, _ = sensor_values(model, x, u_last)
    ctl.reset(q(np.asarray(slider) / res_m))
    X, XR, XD, F = (np.zeros(N) for _ in range(4))
    K, CMD, P, FREF, FACT = (np.zeros((N, 3)) for _ in range(5))
    delay = [np.zeros((1, 3))] * delay_ticks
    stop = -1
    for k in range(N):
        slider, defl = sensor_values(model, x, u_last)
        hand = -f * e_ax
        p_now = x[model.out_pos] @ J.T
        cmd = ctl.step(q(np.asarray(slider) / res_m), q(np.asarray(defl) / res_m), hand)
        if delay:
            delay.append(cmd)
            cmd = delay.pop(0)
        x_d = ctl.x_d
        X[k], XR[k], XD[k], F[k] = p_now[ax], ctl.x_r, x_d, f
        K[k], CMD[k], FREF[k] = ctl.outer.last_gain, cmd[0], ctl.last_force
        u_last = cmd[0]
        ext = disc.Bld @ (J.T @ hand)  # the operator's force on the output sliders, held
        for _ in range(substeps):
            x = disc.Ad @ x + disc.Bud @ u_last + disc.cd + ext
            if G is not None:
                lam = solve_friction(np, x[model.out_vel], G, model.coulomb, lam, FRICTION_ITERS)
                x = x + disc.Bld @ lam
        p, _, _, f_act, _ = observables(model, x, u_last, lam)
        P[k], FACT[k] = p, f_act
        f = force_step(op, f, 0.5 * (p_now[ax] + float(p[ax])) - x_d, T)
        if not (np.all(np.isfinite(x)) and math.isfinite(f) and np.all(np.abs(np.asarray(p) - p_start) < 1.0)):
            stop = k
            break
    end = N if stop < 0 else stop
    t = np.arange(N) * T
    rec = ioic_online.OuterRecord(t=t[:end], x=X[:end], x_r=XR[:end], x_d=XD[:end], f=F[:end], gain=K[:end])
    strategy = il.Strategy(s.strategy.value)
    learning = ctl.outer.learning
    after = s.learn_time + s.switch_time
    measures = ioic_online.outer_metrics(rec, strategy=strategy, learning=learning,
                                         optimum=ioic_online.optimum_of(scene), after=after)
    measures.update({
        "motor_command_peak_N": float(np.max(np.abs(CMD[:end]))) if end else None,
        "force_tracking_rms_N": float(np.sqrt(np.mean(np.sum((FACT[:end] - FREF[:end]) ** 2, axis=1)))) if end else None,
        "off_axis_drift_peak_mm": float(np.max(np.abs(np.delete(P[:end] - p_start, ax, axis=1)))) * 1e3 if end else None,
    })
    stable = stop < 0
    status, message = ioic_online.run_status(stable=stable, unstable_at=(stop + 1) * T, strategy=strategy,
                                             learning=learning, problems=[], measures=measures)
    measures = ioic_online.clean_metrics(measures, status=status)
    traces = Traces(period=T, energy=np.zeros((N, 1)), saturated=np.zeros((N, 1), dtype=bool),
                    stop_tick=np.array([stop]), position=P[:, None], hand_force=(-F[:, None, None] * e_ax),
                    actuator_force=FACT[:, None], force_reference=FREF[:, None], velocity=np.zeros((N, 1, 3)))
    return PrrrIoicResult(scene=scene.name, status=status, message=message, measures=measures, stable=stable,
                          unstable_at=None if stable else (stop + 1) * T, effects=tuple(res.effect_names()),
                          notes=res.notes, reason=res.reason, period=T, wall_time=time.perf_counter() - t0,
                          learning=learning, record=rec, commands=CMD[:end], traces=traces)

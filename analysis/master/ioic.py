"""The surgical master in its IOIC firmware mode (seed 001) on the MuJoCo multibody plant.

Plant: :class:`hapticopt.analysis.master.mujoco_plant.MasterPlant` without the seed-000 hand body
(the eq-2 operator is a force source, not a body); the scene's effects apply as in every master
scene (gravity, joint friction, rotor inertia, torque limit). Operator: seed 001 eq 2,
K_r ḟ + K_f f = K_c (x − x_d), x the handle position along the learning axis, advanced exactly
over each controller period with the period's mean error (its time constant K_r/K_f = 0.1 s in
§4.1 is 100 periods); it pushes on the handle with −f along the axis (applied as the generalised
force J_siteᵀF). Firmware: :class:`hapticopt.analysis.master.firmware_ioic.MasterIoicController`
(encoder counts, rounded when ``quantization`` is on, and the handle force sensor; torques held).

Result: the outer loop's metrics (:func:`hapticopt.analysis.control.ioic_online.outer_metrics`:
learned impedance against the Riccati optimum of eq 6 for the scene's operator model, impedance
and tracking error, interaction force) and the joint torques and joint tracking errors of the
inner loop. Status: ``ok`` only when the run is stable, the parallelogram stays closed and (IOIC)
the learning returned ``ok`` with each of the learned M, B, K within the tolerance of the optimum
(:data:`hapticopt.analysis.control.ioic_online.IMPEDANCE_TOLERANCE`, else ``not-met`` naming the three
errors, numbers kept); a refused learning is ``singular`` (data not exciting) or ``failed`` (not
converged) with the performance metrics null.
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
from hapticopt.analysis.control.sliding_mode import NTSMTCParams
from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.mujoco_solver import SolverSettings
from hapticopt.analysis.loop.operator import force_step
from hapticopt.analysis.loop.scene import Effect, FirmwareMode, Scene, require_mode, resolve
from hapticopt.analysis.loop.traces import OVERSAMPLE, Traces
from hapticopt.analysis.master import dynamics as md
from hapticopt.analysis.master.firmware_ioic import MasterIoicConfig, MasterIoicController, ModelKey
from hapticopt.analysis.master.mujoco_plant import RUNAWAY, VIOLATION_TOL, MasterPlant
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidInput

@dataclass(frozen=True, kw_only=True)
class MasterIoicResult:
    """A master IOIC run: metrics with units, status, records."""

    scene: str
    status: Status
    message: str
    measures: dict[str, Any]
    stable: bool
    unstable_at: float | None
    violation: float  # [m]
    warnings: tuple[str, ...]
    effects: tuple[str, ...]
    notes: tuple[str, ...]
    reason: str
    period: float
    substeps: int
    wall_time: float
    learning: il.LearningResult | None
    record: ioic_online.OuterRecord = field(repr=False, compare=False)
    torque: np.ndarray = field(repr=False, compare=False)  # (N, 3) [N·m]
    joint_error: np.ndarray = field(repr=False, compare=False)  # (N, 3) [rad]
    traces: Traces | None = field(default=None, repr=False, compare=False)

    def metrics(self) -> dict[str, Any]:
        out: dict[str, Any] = {"stable": self.stable, "unstable_at_s": self.unstable_at}
        out.update(self.measures)
        out.update({
            "backend": "multibody", "backend_reason": self.reason, "device": "master",
            "firmware_mode": FirmwareMode.IOIC.value, "effects": list(self.effects),
            "constraint_violation_mm": self.violation * 1e3, "constraint_health_ok": self.violation <= VIOLATION_TOL,
            "mujoco_warnings": list(self.warnings), "controller_period_ms": self.period * 1e3,
            "plant_substeps": self.substeps, "wall_time_s": self.wall_time,
        })
        return out


def simulate(design: Any, scene: Scene, *, fidelity: Fidelity = Fidelity.STANDARD, reason: str | None = None,
             solver: SolverSettings | None = None) -> MasterIoicResult:
    """Run a master scene in the IOIC firmware mode on the MuJoCo plant."""
    import mujoco

    if getattr(design, "device", None) != "master":
        raise InvalidInput(f"scene {scene.name} is a master scene; design {getattr(design, 'name', '?')!r} is a "
                           f"{getattr(design, 'device', '?')}")
    require_mode(scene, FirmwareMode.IOIC, "the master's IOIC firmware (hapticopt.analysis.master.ioic)")
    res = resolve(scene)
    fx = res.effects
    T = scene.controller.period if Effect.SAMPLING in fx else scene.controller.period / OVERSAMPLE[fidelity]
    t0 = time.perf_counter()
    plant_res = dataclasses.replace(res, effects=res.effects - {Effect.OPERATOR})
    plant = MasterPlant(design, scene, plant_res, period=T, fidelity=fidelity, solver=solver)
    m, d = plant.model, plant.data
    s = scene.ioic
    ax = s.axis
    g = design.geometry
    c = scene.controller
    nt = scene.ntsmtc
    cfg = MasterIoicConfig(
        period=T, counts_per_rev=design.actuators.encoder_counts, q0=tuple(map(float, plant.q0)),
        upper_arm=g.upper_arm, forearm=g.forearm, shoulder_height=g.shoulder_height, axis=ax,
        x_start=tuple(map(float, plant.x0)), motion=scene.motion, outer=ioic_online.outer_config(scene, T),
        ntsmtc=NTSMTCParams(lambda1=nt.lambda1, lambda2=nt.lambda2, a=nt.a, b=nt.b, mu=nt.mu, beta=nt.beta,
                            eta=nt.eta, theta=nt.theta),
        velocity_alpha=math.exp(-2 * math.pi * c.velocity_filter * T) if c.velocity_filter > 0 else 0.0,
        torque_limit=design.actuators.torque_limit, saturation=Effect.SATURATION in fx,
        gravity=Effect.GRAVITY in fx)
    ctl = MasterIoicController(cfg, ModelKey(design=design, model=md.model_of(design)))
    op = scene.operator
    N = max(1, int(round(scene.duration / T)))
    quantize = Effect.QUANTIZATION in fx
    delay_ticks = int(round(scene.time_delay / T)) if Effect.TIME_DELAY in fx else 0
    scale = design.actuators.encoder_counts / (2.0 * math.pi)
    qa, q0 = plant.act_qpos, plant.q0
    plant.reset()

    def counts() -> np.ndarray:
        cnt = (d.qpos[qa] - q0) * scale
        return np.round(cnt) if quantize else cnt

    e_ax = np.eye(3)[ax]
    jac = np.zeros((3, m.nv))
    f = 0.0
    hand = -f * e_ax
    ctl.reset(counts())
    X, XR, XD, F, EF = (np.zeros(N) for _ in range(5))
    K = np.zeros((N, 3))
    TAU, QE, P = np.zeros((N, 3)), np.zeros((N, 3)), np.zeros((N, 3))
    delay = [np.zeros((1, 3))] * delay_ticks
    stop = -1
    x_prev = float(d.site_xpos[plant.site][ax])
    n_closure = plant.n_closure
    for k in range(N):
        cmd = ctl.step(counts(), hand)
        if delay:
            delay.append(cmd)
            cmd = delay.pop(0)
        d.ctrl[:] = cmd[0]
        mujoco.mj_jacSite(m, d, jac, None, plant.site)
        d.qfrc_applied[:] = jac.T @ hand
        mujoco.mj_step(m, d, nstep=plant.substeps)
        p = d.site_xpos[plant.site].copy()
        x_new = float(p[ax])
        X[k], XR[k], XD[k], F[k] = x_prev, ctl.x_r, ctl.x_d, f
        K[k], TAU[k], QE[k], P[k] = ctl.outer.last_gain, cmd[0], ctl.joint_error, p
        if d.efc_pos.shape[0] >= n_closure:
            EF[k] = np.abs(d.efc_pos[:n_closure]).max()
        f = force_step(op, f, 0.5 * (x_prev + x_new) - ctl.x_d, T)
        hand = -f * e_ax
        x_prev = x_new
        if not (np.all(np.isfinite(p)) and np.all(np.abs(p - plant.x0) <= RUNAWAY) and math.isfinite(f)
                and d.time >= (k + 0.5) * T):
            stop = k
            break
    end = N if stop < 0 else stop
    t = np.arange(N) * T
    rec = ioic_online.OuterRecord(t=t[:end], x=X[:end], x_r=XR[:end], x_d=XD[:end], f=F[:end], gain=K[:end])
    strategy = il.Strategy(s.strategy.value)
    learning = ctl.outer.learning
    after = s.learn_time + s.switch_time
    measures = ioic_online.outer_metrics(rec, strategy=strategy, learning=learning, optimum=ioic_online.optimum_of(scene),
                                         after=after)
    sel = t[:end] >= after - 1e-9
    measures.update({
        "joint_torque_peak_Nm": [float(v) for v in np.max(np.abs(TAU[:end]), axis=0)] if end else None,
        "joint_torque_rms_Nm": [float(v) for v in np.sqrt(np.mean(TAU[:end] ** 2, axis=0))] if end else None,
        "joint_error_peak_mrad": [float(v) * 1e3 for v in np.max(np.abs(QE[:end]), axis=0)] if end else None,
        "joint_error_peak_after_learning_mrad": ([float(v) * 1e3 for v in np.max(np.abs(QE[:end][sel]), axis=0)]
                                                 if sel.any() else None),
        "off_axis_drift_peak_mm": float(np.max(np.abs(np.delete(P[:end] - plant.x0, ax, axis=1)))) * 1e3 if end else None,
        "torque_saturated_fraction": (float(np.mean(np.any(np.abs(TAU[:end]) >= design.actuators.torque_limit
                                                            * (1 - 1e-12), axis=1))) if end else None),
    })
    stable = stop < 0
    violation = float(EF[:end].max()) if end else 0.0
    warns = plant.warnings()
    problems = []
    if violation > VIOLATION_TOL:
        problems.append(f"parallelogram closure violation {violation * 1e3:.3g} mm > {VIOLATION_TOL * 1e3:g} mm")
    if warns:
        problems.append("MuJoCo warnings: " + ", ".join(warns))
    status, message = ioic_online.run_status(stable=stable, unstable_at=(stop + 1) * T, strategy=strategy,
                                             learning=learning, problems=problems, measures=measures)
    measures = ioic_online.clean_metrics(measures, status=status)
    traces = Traces(period=T, energy=np.zeros((N, 1)), saturated=np.zeros((N, 1), dtype=bool),
                    stop_tick=np.array([stop]), position=P[:, None], hand_force=(-F[:, None, None] * e_ax),
                    velocity=np.zeros((N, 1, 3)))
    return MasterIoicResult(
        scene=scene.name, status=status, message=message, measures=measures, stable=stable,
        unstable_at=None if stable else (stop + 1) * T, violation=violation, warnings=warns,
        effects=tuple(res.effect_names()), notes=res.notes, reason=reason or res.reason, period=T,
        substeps=plant.substeps, wall_time=time.perf_counter() - t0, learning=learning, record=rec,
        torque=TAU[:end], joint_error=QE[:end], traces=traces)

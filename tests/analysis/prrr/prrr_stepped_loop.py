"""Plain tick-by-tick closed loops, the references the fused loops are tested against (as MuJoCo keeps
``py_rollout`` in ``rollout_test.py``): :func:`run_with_plant` over any :class:`hapticopt.analysis.loop.plant.Plant`
and :class:`LumpedPlant`, the lumped model stepped in numpy. Imported by the tests of this folder (its
conftest puts the folder on ``sys.path``)."""

from __future__ import annotations

import numpy as np

from hapticopt.analysis.loop.plant import Observation, Plant, Sensors
from hapticopt.analysis.loop.scene import StabilityCriterion
from hapticopt.analysis.loop.traces import Traces
from hapticopt.analysis.prrr.loop import firmware
from hapticopt.analysis.prrr.loop.closed_loop import Setup
from hapticopt.analysis.prrr.loop.lumped_plant import (FRICTION_ITERS, LumpedModel, discretise, observables, sensor_values,
                                                  solve_friction)


class LumpedPlant:
    """The :class:`hapticopt.analysis.loop.plant.Plant` on the lumped model (plain numpy, one device): the plain
    reference of the fused, compiled update in ``hapticopt.analysis.prrr.loop.closed_loop``."""

    backend = "lumped"

    def __init__(self, model: LumpedModel, period: float, substeps: int) -> None:
        self.model = model
        self.substeps = substeps
        self.disc = discretise(model, period / substeps)
        S = model.friction_map
        self.G = S @ self.disc.Bld[model.out_vel] @ S.T if S is not None else None
        self.reset()

    def reset(self) -> None:
        self.x = self.model.x0.copy()
        self.u = np.zeros(3)
        self.lam = np.zeros(3)  # slider-space friction force
        self.mu = np.zeros(0 if self.model.friction_map is None else self.model.friction_map.shape[0])

    def sensors(self) -> Sensors:
        slider, defl = sensor_values(self.model, self.x, self.u)
        return Sensors(slider=np.asarray(slider), deflection=np.asarray(defl))

    def advance(self, commands: np.ndarray) -> None:
        commands = np.atleast_2d(commands)
        per = self.substeps // commands.shape[0]
        d = self.disc
        for j in range(self.substeps):
            self.u = commands[j // per]
            x = d.Ad @ self.x + d.Bud @ self.u + d.cd
            S = self.model.friction_map
            if S is not None:
                self.mu = solve_friction(np, S @ x[self.model.out_vel], self.G, self.model.friction_limit, self.mu,
                                         FRICTION_ITERS)
                self.lam = S.T @ self.mu
                x = x + d.Bld @ self.lam
            self.x = x

    def observe(self) -> Observation:
        p, v, hand, f, e = observables(self.model, self.x, self.u, self.lam)
        return Observation(position=p, velocity=v, hand_force=hand, actuator_force=f, energy=float(e))


def run_with_plant(plant: Plant, controller: firmware.FirmwareController, st: Setup) -> Traces:
    """Plain Python closed loop for any :class:`hapticopt.analysis.loop.plant.Plant` (the reference of the fused loops)."""
    res = float(st.gains.resolution)
    N = st.ticks
    q = np.round if st.quantize else (lambda a: a)
    plant.reset()
    s = plant.sensors()
    controller.reset(q(s.slider / res))
    delay: list[np.ndarray] = [np.zeros((st.cfg.interpolation, 3))] * st.delay_ticks
    rec = {k: np.zeros((N, 1, 3)) for k in ("position", "velocity", "hand_force", "actuator_force", "force_reference")}
    energy = np.zeros((N, 1))
    sat = np.zeros((N, 1), dtype=bool)
    stop = -1
    limit = float(st.gains.motor_limit)
    explode = (1e6 if st.scene.stability == StabilityCriterion.DECAY else 1e3) * st.energy_scale
    for k in range(N):
        s = plant.sensors()
        cmd = controller.step(q(s.slider / res), q(s.deflection / res))
        if st.delay_ticks:
            delay.append(cmd)
            cmd = delay.pop(0)
        plant.advance(cmd)
        o = plant.observe()
        e = o.energy + 0.5 * float(np.dot(np.asarray(st.gains.stiffness), o.position**2))
        if not (np.all(np.isfinite(o.position)) and e < explode and np.all(np.abs(o.position) < 1.0)):
            stop = k
            break
        sat[k, 0] = st.cfg.saturation and bool(np.any(np.abs(cmd) >= limit * (1 - 1e-12)))
        energy[k, 0] = e
        for name, val in (("position", o.position), ("velocity", o.velocity), ("hand_force", o.hand_force),
                          ("actuator_force", o.actuator_force), ("force_reference", controller.last_force)):
            rec[name][k, 0] = val
    if stop >= 0:
        for arr in (*rec.values(), energy, sat):
            arr[stop:] = arr[stop - 1] if stop > 0 else 0
    return Traces(period=st.period, energy=energy, saturated=sat, stop_tick=np.array([stop]), **rec)

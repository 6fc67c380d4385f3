"""Design map of the firmware: for each (controller period T, force-loop gain K_p) of a scene,
the free-space residual (simulated), the K limit on the scene's axis and the force-loop bandwidth.

Seed 002 gives K_p = 45 only for its identification experiment and never states the loop
rate; both set what the hand feels in free space (the viscous residual ≈ ξ v_rms / (λ²(1 + ηK_p)))
and where the sampled loop loses stability. This map is the picture an engineer picks the
firmware rate from.

Per point:

* ``residual`` — the scene's [report] quantity (the paper's definition, e.g. Fig 14's RMS of F_x)
  from the closed-loop simulation (:mod:`hapticopt.analysis.prrr.loop.closed_loop`), all K_p of one T
  in one batched run of one compiled loop shared by every T (the period is an argument); NaN where
  that run is unstable.
* ``stiffness_limit`` — the largest stable virtual stiffness on the scene's measure axis (zero
  virtual damping) from the exact discrete analysis (eigenvalues of the sampled loop's transition
  matrix, :func:`hapticopt.analysis.prrr.loop.stability.sampled_stiffness_limit`); with
  ``simulate_limits`` also by bisection on simulated decay runs (the check of the analysis).
* ``bandwidth`` — −3 dB bandwidth of the sampled force loop with the output locked (eq 8 + ZOH).
* ``verdict`` — :class:`Verdict`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from hapticopt.analysis.fidelity import Fidelity
from hapticopt.analysis.loop.scene import Effect, EnvKind, Scene, StabilityCriterion
from hapticopt.analysis.prrr.loop import stability
from hapticopt.analysis.prrr.loop.closed_loop import Simulator, batch_gains, classify, metrics_from_traces, setup
from hapticopt.design.errors import InvalidInput
from hapticopt.design.prrr.params import PrrrDesign

#: limits of the map's axes (the hard cases of issue 19 sit on them)
PERIOD_RANGE = (1e-6, 0.1)  # [s]
GAIN_RANGE = (0.0, 1e6)


class Verdict(StrEnum):
    OK = "ok"  # the scene's run is stable; every metric is finite
    UNSTABLE = "unstable"  # the simulated run went unstable (residual NaN)
    NO_FORCE_LOOP = "no_force_loop"  # K_p = 0: the motors are not commanded; nothing is rendered (K limit ∞)


@dataclass(frozen=True, kw_only=True)
class DesignMap:
    scene: str
    axis: int
    periods: np.ndarray  # (nT,) [s]
    force_gains: np.ndarray  # (nK,)
    residual: np.ndarray  # (nT, nK) [N] (the scene's report quantity), NaN where unstable
    stable: np.ndarray  # (nT, nK) bool, simulated
    verdict: np.ndarray  # (nT, nK) str (Verdict values)
    stiffness_limit: np.ndarray  # (nT, nK) [N/m], exact discrete analysis; inf without a force loop
    bandwidth: np.ndarray  # (nT, nK) [Hz], sampled force loop; NaN where it is unstable, 0 for K_p = 0
    force_loop_stable: np.ndarray  # (nT, nK) bool
    stiffness_limit_simulated: np.ndarray | None = None  # (nT, nK) [N/m] bisection on simulated decay runs
    wall_time: float = 0.0

    def metrics(self) -> dict[str, object]:
        def fin(a: np.ndarray, f: float = 1.0) -> list[list[float | None]]:
            return [[float(v) * f if math.isfinite(v) else None for v in row] for row in a]

        out: dict[str, object] = {
            "map_scene": self.scene,
            "map_axis": "xyz"[self.axis],
            "map_period_ms": [float(t) * 1e3 for t in self.periods],
            "map_force_gain": [float(k) for k in self.force_gains],
            "map_residual_N": fin(self.residual),
            "map_verdict": [[str(v) for v in row] for row in self.verdict],
            "map_stiffness_limit_N_per_mm": fin(self.stiffness_limit, 1e-3),
            "map_force_loop_bandwidth_Hz": fin(self.bandwidth),
            "map_wall_time_s": self.wall_time,
        }
        if self.stiffness_limit_simulated is not None:
            out["map_stiffness_limit_simulated_N_per_mm"] = fin(self.stiffness_limit_simulated, 1e-3)
        return out


def _check(periods: np.ndarray, gains: np.ndarray) -> None:
    for name, vals, (lo, hi), unit, f in (("period_ms", periods, PERIOD_RANGE, "ms", 1e3),
                                          ("force_gain", gains, GAIN_RANGE, "-", 1.0)):
        for v in vals:
            if not (math.isfinite(v) and lo <= v <= hi) or (name == "period_ms" and v <= 0):
                raise InvalidInput(f"design map: {name} = {v * f:g} is out of range: allowed {lo * f:g} "
                                   f"{'<' if name == 'period_ms' else '≤'} {name} ≤ {hi * f:g} {unit}")


def _with(scene: Scene, *, period: float, duration: float | None = None) -> Scene:
    c = dataclasses.replace(scene.controller, period=period)
    return dataclasses.replace(scene, controller=c, duration=scene.duration if duration is None else duration)


def simulated_stiffness_limits(design: PrrrDesign, scene: Scene, *, period: float, force_gains: np.ndarray,
                               axis: int, fidelity: Fidelity = Fidelity.STANDARD, lo: float = 1e3,
                               hi: float = 1e6, iters: int = 12) -> np.ndarray:
    """Largest stable K on ``axis`` per K_p [N/m] by geometric bisection on simulated decay runs.

    The scene is turned into the linear decay test the exact analysis describes: released 1 mm
    off the anchor, nobody holding the handle, no friction, gravity, quantisation or saturation,
    zero virtual damping, 1 s. All K_p of the batch and every bisection step run batched.
    """
    keep = {Effect.SEA_COMPLIANCE, Effect.MOTOR_DYNAMICS, Effect.VISCOUS_FRICTION, Effect.SAMPLING}
    off = [0.0, 0.0, 0.0]
    off[axis] = 1e-3
    sc = dataclasses.replace(_with(scene, period=period, duration=1.0), effects=frozenset(scene.effects & keep),
                             stability=StabilityCriterion.DECAY, initial_offset=tuple(off), report=None,
                             environment=dataclasses.replace(scene.environment, kind=EnvKind.SPRING,
                                                             stiffness=(0.0, 0.0, 0.0), damping=(0.0, 0.0, 0.0)))
    st = setup(design, sc, fidelity=fidelity)
    sim = Simulator(st, record=False)
    kp = np.asarray(force_gains, dtype=float)
    n = len(kp)

    def probe(K: np.ndarray) -> np.ndarray:
        Kv = np.zeros((n, 3))
        Kv[:, axis] = K
        tr = sim.run(batch_gains(st.gains, stiffness=Kv, damping=np.zeros((n, 3)), kp=kp), batch=n)
        return classify(tr, st)[0]

    a, b = np.full(n, lo), np.full(n, hi)
    ok_lo, ok_hi = probe(a), probe(b)
    for _ in range(iters):
        mid = np.sqrt(a * b)
        ok = probe(mid)
        a, b = np.where(ok, mid, a), np.where(ok, b, mid)
    out = np.where(ok_hi, np.inf, np.sqrt(a * b))
    return np.where(ok_lo, out, 0.0)


def design_map(design: PrrrDesign, scene: Scene, *, periods, force_gains, fidelity: Fidelity = Fidelity.STANDARD,
               simulate_limits: bool = False, duration: float | None = None) -> DesignMap:
    """The (T, K_p) map of ``scene`` (normally ``free-space-x``): see the module docstring.

    ``duration`` [s] overrides the scene's (the residual is averaged after the first 0.5 s).
    """
    if scene.device != "prrr":
        raise InvalidInput(f"design map: scene {scene.name} is written for the {scene.device}; the map is the "
                           "3-PRRR's (its SEA force loop)")
    if scene.report is None:
        raise InvalidInput(f"design map: scene {scene.name} has no [report] quantity to map: use free-space-x or "
                           "free-space-y")
    Ts = np.asarray(periods, dtype=float).ravel()
    kps = np.asarray(force_gains, dtype=float).ravel()
    _check(Ts, kps)
    t0 = time.perf_counter()
    nT, nK = len(Ts), len(kps)
    axis = scene.measure_axis
    residual = np.full((nT, nK), np.nan)
    stable = np.zeros((nT, nK), dtype=bool)
    limit = np.zeros((nT, nK))
    bw = np.full((nT, nK), np.nan)
    fl_ok = np.zeros((nT, nK), dtype=bool)
    sim_limit = np.zeros((nT, nK)) if simulate_limits else None
    setups = [setup(design, _with(scene, period=T, duration=duration), fidelity=fidelity) for T in Ts]
    # one compiled loop for every T (the period is an argument): the longest run sets the chunk length
    sim = Simulator(setups[int(np.argmax([st.ticks for st in setups]))], period_free=True)
    for i, T in enumerate(Ts):
        st = setups[i]
        tr = sim.run(batch_gains(st.gains, kp=kps), batch=nK, setup=st)
        alpha = stability.velocity_alpha(T, scene.controller.velocity_filter)
        for j, kp in enumerate(kps):
            r = metrics_from_traces(tr, st, j)
            stable[i, j] = r.stable
            if r.stable and r.paper_metric is not None:
                residual[i, j] = r.paper_metric
            if kp == 0.0:
                limit[i, j], bw[i, j], fl_ok[i, j] = math.inf, 0.0, True
            else:
                limit[i, j] = stability.sampled_stiffness_limit(design, axis=axis, T=T, kp=kp, alpha=alpha,
                                                                rtol=1e-4)
                fl_ok[i, j], bw[i, j] = stability.sampled_force_loop_bandwidth(design, T=T, kp=kp)
        if sim_limit is not None:
            sim_limit[i] = simulated_stiffness_limits(design, scene, period=T, force_gains=kps, axis=axis,
                                                      fidelity=fidelity)
    verdict = np.where(kps[None, :] == 0.0, str(Verdict.NO_FORCE_LOOP),
                       np.where(stable, str(Verdict.OK), str(Verdict.UNSTABLE)))
    return DesignMap(scene=scene.name, axis=axis, periods=Ts, force_gains=kps, residual=residual, stable=stable,
                     verdict=verdict, stiffness_limit=limit, bandwidth=bw, force_loop_stable=fl_ok,
                     stiffness_limit_simulated=sim_limit, wall_time=time.perf_counter() - t0)

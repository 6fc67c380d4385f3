"""Seed 001's outer loop as firmware: the IOIC reference generator, one tick at a time.

:mod:`.impedance_learning` reproduces the paper with the plant inside one RK4; on a device the
outer loop runs in the firmware at the controller period T and sees only samples. Per tick k
(t_k = kT) :class:`OnlineIoic` reads the measured interaction force f_k [N] and the operator's
desired position x_d(t_k) [m], forms X_k = [e_p, ė_p, f] with e_p = x_r − x_d, ė_p = ẋ_r (x_d is
piecewise constant), and returns the impedance reference x_r, ẋ_r and ẍ_r = u_k for the inner
loop, with u_k = −K(t_k) X_k (+ v_n(t_k) during the data phase, eq 8) held over the period; the
reference is integrated exactly for a held u (x_r += ẋ_r T + u T²/2, ẋ_r += u T).

Strategies (seed 001 Figs 4–6): FIC keeps K_0, OIC uses the model optimum K* (eq 6 with the
operator model the scene declares — the firmware is told K*, it does not compute it), IOIC
records X_k and u_k over the data phase, builds the Kronecker data of eq 7 by the trapezoid rule
on the samples (u is held, so ∫u Xᵀ over a tick is u_k times the trapezoid of X), runs the policy
iteration of eq 9 (:func:`.impedance_learning.policy_iteration`, which refuses non-exciting data)
at t = t_learn and soft-switches (eq 10) to the learned gain over T_s; when learning is refused it
keeps K_0 and the refusal is the run's status.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from hapticopt.analysis.loop.operator import state_space
from hapticopt.analysis.loop.scene import Scene
from hapticopt.analysis.status import Status
from hapticopt.design.errors import InvalidInput

from . import impedance_learning as il


@dataclasses.dataclass(frozen=True, kw_only=True)
class OnlineIoicConfig:
    """period T [s]; k0, k_star (3,) [1/s², 1/s, 1/kg]; q (3, 3), r (1, 1) of eq 6; learn_time,
    switch_time [s]; intervals of the data phase (each a whole number of periods)."""

    period: float
    strategy: il.Strategy
    k0: tuple[float, float, float]
    k_star: tuple[float, float, float]
    q: tuple[float, float, float]
    r: float
    learn_time: float
    intervals: int
    switch_time: float
    noise: il.ExplorationNoise
    eps: float = 1e-8

    def __post_init__(self) -> None:
        if not (math.isfinite(self.period) and self.period > 0):
            raise ValueError(f"OnlineIoicConfig.period = {self.period!r} s: must be finite and > 0")
        per = self.learn_time / self.intervals / self.period
        if round(per) < 1 or abs(per - round(per)) > 1e-6:
            raise ValueError(f"OnlineIoicConfig: the sampling interval learn_time/intervals = "
                             f"{self.learn_time / self.intervals:g} s must be a whole number ≥ 1 of periods "
                             f"({self.period:g} s)")

    @property
    def ticks_per_interval(self) -> int:
        return int(round(self.learn_time / self.intervals / self.period))

    @property
    def learn_ticks(self) -> int:
        return self.ticks_per_interval * self.intervals


def data_from_samples(x: np.ndarray, u: np.ndarray, period: float, ticks_per_interval: int) -> il.LearningData:
    """Eq 7's data from tick samples: x (N+1, n) at t_k, u (N, m) held over [t_k, t_k+1)."""
    n_ticks = u.shape[0]
    n_int = n_ticks // ticks_per_interval
    xx = np.einsum("ki,kj->kij", x, x)
    ixx_tick = 0.5 * period * (xx[:-1] + xx[1:])  # trapezoid of X Xᵀ over each tick
    ix_tick = 0.5 * period * (x[:-1] + x[1:])
    iux_tick = np.einsum("km,kj->kmj", u, ix_tick)
    shape = (n_int, ticks_per_interval)
    ixx = ixx_tick[: n_int * ticks_per_interval].reshape(shape + ixx_tick.shape[1:]).sum(axis=1)
    iux = iux_tick[: n_int * ticks_per_interval].reshape(shape + iux_tick.shape[1:]).sum(axis=1)
    idx = ticks_per_interval * np.arange(n_int + 1)
    t = period * np.arange(n_ticks + 1)
    return il.LearningData(t=t[idx], x=x[idx], ixx=ixx, iux=iux, t_fine=t, x_fine=x,
                           u_fine=np.concatenate([u, u[-1:]]))


class OnlineIoic:
    """The IOIC outer loop of one Cartesian axis, stepped by the firmware each period."""

    def __init__(self, cfg: OnlineIoicConfig) -> None:
        self.cfg = cfg
        self._k0 = np.asarray(cfg.k0, dtype=float)
        self._kstar = np.asarray(cfg.k_star, dtype=float)
        self.learning: il.LearningResult | None = None
        self.reset(0.0)

    def reset(self, x_start: float) -> None:
        """Reference at rest at the handle's start position x_start [m]."""
        self.x_r, self.v_r = float(x_start), 0.0
        self._tick = 0
        self._xs: list[np.ndarray] = []
        self._us: list[float] = []
        self.learning = None
        self._k1 = self._kstar if self.cfg.strategy is il.Strategy.OIC else self._k0

    def gain(self, t: float) -> np.ndarray:
        """K in use at t [s] (eq 10 after the data phase for IOIC)."""
        cfg = self.cfg
        if cfg.strategy is not il.Strategy.IOIC:
            return self._k1
        if t < cfg.learn_time - 1e-9 * cfg.period:
            return self._k0
        return il.soft_switch(t, self._k0, self._k1, t_start=cfg.learn_time, t_switch=cfg.switch_time)[0]

    def _learn(self, x_now: np.ndarray) -> None:
        cfg = self.cfg
        x = np.array(self._xs + [x_now])
        data = data_from_samples(x, np.array(self._us)[:, None], cfg.period, cfg.ticks_per_interval)
        self.learning = il.policy_iteration(data, self._k0, np.diag(cfg.q), np.array([[cfg.r]]), eps=cfg.eps)
        if self.learning.status is il.LearningStatus.OK:
            self._k1 = self.learning.k[0]

    def step(self, x_d: float, f: float) -> tuple[float, float, float, np.ndarray]:
        """(x_r [m], ẋ_r [m/s], ẍ_r [m/s²], X (3,)) for this period, from the desired position
        x_d [m] and the measured force f [N] at its start."""
        cfg = self.cfg
        k, T = self._tick, cfg.period
        t = k * T
        X = np.array([self.x_r - x_d, self.v_r, f])
        learning = cfg.strategy is il.Strategy.IOIC and k < cfg.learn_ticks
        if cfg.strategy is il.Strategy.IOIC and k == cfg.learn_ticks:
            self._learn(X)
        K = self.gain(t)
        u = -float(K @ X)
        if learning:
            u += float(cfg.noise(t + 0.5 * T))  # the noise at the period's midpoint (held)
            self._xs.append(X)
            self._us.append(u)
        x_r, v_r = self.x_r, self.v_r
        self.x_r = x_r + v_r * T + 0.5 * u * T * T
        self.v_r = v_r + u * T
        self._tick = k + 1
        self.last_gain = K
        return x_r, v_r, u, X


# ------------------------------------------------------------------------------------ device runs
@dataclasses.dataclass(frozen=True, kw_only=True)
class OuterRecord:
    """Per-tick records of a device run along the learning axis, grid t (N,) [s]: x (N,) the
    handle position [m], x_r, x_d (N,) [m], f (N,) the operator force [N], gain (N, 3)."""

    t: np.ndarray
    x: np.ndarray
    x_r: np.ndarray
    x_d: np.ndarray
    f: np.ndarray
    gain: np.ndarray


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(v)))) if v.size else math.nan


#: Default tolerance of the learned impedance: IOIC is ``ok`` only when each of M_d, B_d, K_d is within
#: this relative error of the Riccati optimum M*, B*, K* (eq 33). 10 % is the force JND seed 003 uses
#: for its 0.1 N threshold (a 10 % lighter or softer impedance is at the edge of what a hand feels).
IMPEDANCE_TOLERANCE = 0.10


def impedance_errors(k_used: np.ndarray, optimum: il.OptimalImpedance) -> tuple[float, float, float]:
    """Signed relative errors (M/M* − 1, B/B* − 1, K/K* − 1) of the impedance of gain ``k_used`` (eq 5)."""
    m, b, k = il.impedance_from_gain(k_used)
    return m / optimum.mass - 1.0, b / optimum.damping - 1.0, k / optimum.stiffness - 1.0


def outer_metrics(rec: OuterRecord, *, strategy: il.Strategy, learning: il.LearningResult | None,
                  optimum: il.OptimalImpedance, after: float,
                  tolerance: float = IMPEDANCE_TOLERANCE) -> dict[str, object]:
    """The outer loop's metrics of a device run: learned vs model-optimal impedance (M, B, K and
    their relative errors, with the ``tolerance`` the status applies), the impedance error
    e_p = x − x_d, the tracking error x − x_r and the interaction force, over the whole run and
    over t ≥ ``after`` [s] (after learning and the soft switch)."""
    k_star = optimum.k[0]
    if strategy is il.Strategy.IOIC:
        k_used = learning.k[0] if learning is not None else np.full(3, np.nan)
    else:
        k_used = k_star if strategy is il.Strategy.OIC else rec.gain[0]
    m_l, b_l, k_l = il.impedance_from_gain(k_used)
    err_m, err_b, err_k = impedance_errors(k_used, optimum)
    sel = rec.t >= after - 1e-9
    out: dict[str, object] = {
        "ioic_strategy": strategy.value,
        "learning_status": "not_run" if learning is None else learning.status.value,
        "learning_iterations": None if learning is None else learning.iterations,
        "data_matrix_rank": None if learning is None else learning.rank,
        "data_matrix_unknowns": None if learning is None else learning.n_unknowns,
        "data_matrix_rcond": None if learning is None else learning.rcond,
        "gain_SI": [float(v) for v in k_used],  # [K_d/M_d 1/s², B_d/M_d 1/s, 1/M_d 1/kg]
        "optimal_gain_SI": [float(v) for v in k_star],
        "gain_rel_error_to_optimum": float(np.linalg.norm(k_used - k_star) / np.linalg.norm(k_star)),
        "impedance_mass_kg": m_l, "impedance_damping_Ns_per_m": b_l, "impedance_stiffness_N_per_m": k_l,
        "optimal_impedance_mass_kg": optimum.mass, "optimal_impedance_damping_Ns_per_m": optimum.damping,
        "optimal_impedance_stiffness_N_per_m": optimum.stiffness,
        "impedance_mass_rel_error": err_m, "impedance_damping_rel_error": err_b,
        "impedance_stiffness_rel_error": err_k, "impedance_tolerance": tolerance,
        "impedance_error_rms_mm": _rms(rec.x - rec.x_d) * 1e3,
        "impedance_error_rms_after_learning_mm": _rms((rec.x - rec.x_d)[sel]) * 1e3,
        "interaction_force_rms_N": _rms(rec.f),
        "interaction_force_rms_after_learning_N": _rms(rec.f[sel]),
        "interaction_force_peak_N": float(np.max(np.abs(rec.f))) if rec.f.size else math.nan,
        "tracking_error_rms_mm": _rms(rec.x - rec.x_r) * 1e3,
        "tracking_error_peak_mm": float(np.max(np.abs(rec.x - rec.x_r))) * 1e3 if rec.x.size else math.nan,
        "reference_error_rms_after_learning_mm": _rms((rec.x_r - rec.x_d)[sel]) * 1e3,
    }
    return out


def learning_verdict(strategy: il.Strategy, learning: il.LearningResult | None) -> tuple[bool, str]:
    """(ok, message): IOIC is ok only when policy iteration returned ``ok``."""
    if strategy is not il.Strategy.IOIC:
        return True, ""
    if learning is None:
        return False, "not_run: the run ended before the data phase did"
    if learning.status is il.LearningStatus.OK:
        return True, ""
    return False, f"{learning.status.value}: {learning.message} (the firmware kept K_0)"


#: performance metrics nulled when the status is not ok
PERFORMANCE = ("impedance_error_rms_mm", "impedance_error_rms_after_learning_mm", "interaction_force_rms_N",
               "interaction_force_rms_after_learning_N", "interaction_force_peak_N", "tracking_error_rms_mm",
               "tracking_error_peak_mm", "reference_error_rms_after_learning_mm", "joint_torque_peak_Nm",
               "joint_torque_rms_Nm", "joint_error_peak_mrad", "joint_error_peak_after_learning_mrad",
               "gain_SI", "gain_rel_error_to_optimum", "impedance_mass_kg", "impedance_damping_Ns_per_m",
               "impedance_stiffness_N_per_m", "impedance_mass_rel_error", "impedance_damping_rel_error",
               "impedance_stiffness_rel_error", "motor_command_peak_N", "force_tracking_rms_N", "off_axis_drift_peak_mm")


def outer_config(scene: Scene, period: float) -> OnlineIoicConfig:
    """The outer loop of a scene: K* from eq 6 with the scene's eq-2 operator (the model)."""
    s = scene.ioic
    a, b = state_space(scene.operator)
    opt = il.riccati_optimum(a, b, np.diag(s.state_weights), np.array([[s.input_weight]]))
    if not s.exploration:
        noise = il.ExplorationNoise.zero()
    elif s.noise_seed >= 0:
        noise = il.ExplorationNoise.multisine(s.noise_seed)
    else:
        noise = il.ExplorationNoise.printed()
    try:
        return OnlineIoicConfig(
            period=period, strategy=il.Strategy(s.strategy.value), k0=s.initial_gain,
            k_star=tuple(float(v) for v in opt.k[0]), q=s.state_weights, r=s.input_weight, learn_time=s.learn_time,
            intervals=s.intervals, switch_time=s.switch_time, noise=noise, eps=s.tolerance)
    except ValueError as exc:
        raise InvalidInput(f"scene {scene.name}: ioic: {exc}") from None


def optimum_of(scene: Scene) -> il.OptimalImpedance:
    s = scene.ioic
    a, b = state_space(scene.operator)
    return il.riccati_optimum(a, b, np.diag(s.state_weights), np.array([[s.input_weight]]))


def _finite_or_none(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [_finite_or_none(x) for x in v]
    return v


def clean_metrics(measures: dict[str, Any], *, status: Status) -> dict[str, Any]:
    """NaN → None (JSON null); with a status whose numbers do not hold (:attr:`Status.metrics_hold`:
    unstable, singular, failed) the performance metrics are null too; ``not-met`` keeps them."""
    out = dict(measures)
    if not status.metrics_hold:
        for key in PERFORMANCE:
            if key in out:
                out[key] = None
    return {k: _finite_or_none(v) for k, v in out.items()}


def impedance_verdict(strategy: il.Strategy, measures: dict[str, Any]) -> tuple[bool, str]:
    """(ok, message): a learned impedance is ok only when each of M, B, K is within
    ``measures["impedance_tolerance"]`` of the Riccati optimum; FIC and OIC are not judged (their gains
    are given, not learned)."""
    if strategy is not il.Strategy.IOIC:
        return True, ""
    tol = float(measures["impedance_tolerance"])
    errs = [(name, measures[f"impedance_{key}_rel_error"]) for name, key in
            (("M", "mass"), ("B", "damping"), ("K", "stiffness"))]
    if all(e is not None and math.isfinite(e) and abs(e) <= tol for _, e in errs):
        return True, ""
    text = ", ".join(f"{name} {100 * e:+.1f} %" for name, e in errs)
    return False, (f"learned impedance off the Riccati optimum (eq 33) by {text}: allowed ±{100 * tol:g} % each "
                   f"(M {measures['impedance_mass_kg']:.4g} vs {measures['optimal_impedance_mass_kg']:.4g} kg, "
                   f"B {measures['impedance_damping_Ns_per_m']:.4g} vs "
                   f"{measures['optimal_impedance_damping_Ns_per_m']:.4g} N·s/m, "
                   f"K {measures['impedance_stiffness_N_per_m']:.4g} vs "
                   f"{measures['optimal_impedance_stiffness_N_per_m']:.4g} N/m)")


def run_status(*, stable: bool, unstable_at: float | None, strategy: il.Strategy,
               learning: il.LearningResult | None, problems: list[str],
               measures: dict[str, Any] | None = None) -> tuple[Status, str]:
    """The run's status: ``unstable``; a refused learning ``singular`` (not exciting) or ``failed``;
    ``failed`` for any other problem (plant health); ``not-met`` when the learned M, B or K is
    outside the tolerance of the optimum (``measures`` from :func:`outer_metrics`; the message names
    the three errors); ``ok`` otherwise."""
    ok_learn, learn_msg = learning_verdict(strategy, learning)
    msgs = []
    if not stable:
        status = Status.UNSTABLE
        msgs.append(f"unstable: detected at t = {unstable_at:.4g} s")
    elif not ok_learn:
        refused = learning is not None and learning.status is il.LearningStatus.NOT_EXCITING
        status = Status.SINGULAR if refused else Status.FAILED
        msgs.append(learn_msg)
    else:
        status = Status.OK
    msgs += problems
    if problems and status == Status.OK:
        status = Status.FAILED
    if status == Status.OK and measures is not None:
        ok_imp, imp_msg = impedance_verdict(strategy, measures)
        if not ok_imp:
            status = Status.NOT_MET
            msgs.append(imp_msg)
    return status, "; ".join(msgs)

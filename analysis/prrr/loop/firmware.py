"""The firmware controller of the 3-PRRR (seed 002 eq 9–13), one fixed period T per step.

It sees only what the device's firmware sees: slider encoder counts and spring-deflection
counts (integers when quantisation is on). Per tick:

1. p = J · (counts · resolution)                         (eq 1, positions from home)
2. ṗ̂: first-order low-passed difference (cut-off f_c; plain backward difference if f_c = 0)
3. F_r = −K_v (p − p_r) − B_v ṗ̂ (diagonal), or the virtual box of eq 13 (inside / outside), or a
   prescribed force A sin(2πft + φ) per axis (a phase per axis draws Fig 9's force circle),
   + friction compensation F_fc·tanh(ṗ̂/v_ε) in x and y, + weight compensation in z
4. f_r = Jᵀ F_r                                           (spring-force references per leg)
5. per-SEA force loop F = K_p (f_r − k x̂) + K_i ∫(f_r − k x̂) (rigid: F = f_r/η; ideal: F = f_r)
6. optional seed 000 prediction and cubic B-spline (eq 23) giving L output samples per period;
   ``interpolation_variant`` picks the segment (``analysis.control.upsampling.Variant``; default as
   intended, the one that does not lower the stable stiffness: docs/seed000.md, 3-PRRR section).
   ``predictor`` fixed: the command is extrapolated, f_{i+1} = Σ a_j f_{i−j} (and f_{i+2} by the same
   recursion); online (the paper's method): an AR(p) model fitted per axis by least squares to the last
   ``ar_window`` positions predicts p̂_{i+1}, p̂_{i+2}, and steps 2–5 run at the predicted positions (the
   spring deflection held at this tick's reading, the integral chained over the predicted errors)
7. motor-force saturation |F| ≤ F_max/η (anti-windup: the integral is clamped too)

Steps 1–5 and 7 are written once, in :mod:`hapticopt.analysis.prrr.loop.firmware_law` (over separate x, y, z
components, from a few primitives). Here they run on jax arrays: :func:`step` (compiled once per structure,
batched over any leading axis and fused with the lumped plant in one compiled loop: the Z-width map runs hundreds
of controllers in one call) adds step 6 around them. Structure (which terms exist) is static in
:class:`FirmwareConfig`: a term that is off is not traced, so it costs nothing. :class:`FirmwareController` wraps
:func:`step` as an object with ``step(sensors)``. The MuJoCo loops step one controller per tick between
``mj_step`` calls, where a jax dispatch per tick would cost more than the physics: :class:`ScalarController`
runs the same law on Python floats (interpolation 1), and the compiled MuJoCo loop runs it compiled by numba
(:mod:`hapticopt.analysis.prrr.loop._mujoco_kernel`); ``tests/analysis/prrr/loop/test_firmware_law.py`` holds the
three equal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.control.upsampling import (AR_RCOND_BAND, DEFAULT_VARIANT, Predictor, Variant,
                                                   fallback_coefficients, spline_weights)
from hapticopt.design.prrr.kinematics import jacobian
from hapticopt.analysis.loop.scene import BoxMode, Effect, EnvKind, Resolution, Scene
from hapticopt.analysis.prrr.loop.firmware_law import (ENV_BOX_INSIDE, ENV_BOX_OUTSIDE, ENV_FORCE, ENV_FREE,
                                                       ENV_SPRING, LOOP_IDEAL, LOOP_RIGID, LOOP_SEA, PYTHON, Ops,
                                                       make_law)
from hapticopt.design.errors import InvalidInput
from hapticopt.design.prrr.params import PrrrDesign
from hapticopt.design.units import GRAVITY

#: cubic uniform B-spline basis of seed 000 eq (23)
BSPLINE = np.array([[-1.0, 3.0, -3.0, 1.0], [3.0, -6.0, 3.0, 0.0], [-3.0, 0.0, 3.0, 0.0], [1.0, 4.0, 1.0, 0.0]]) / 6.0

#: instrumentation: how often each optional term was traced into a compiled controller
#: (tests use it to show that an effect that is off is never evaluated)
TRACE_COUNTS: dict[str, int] = {}


def _traced(name: str) -> None:
    TRACE_COUNTS[name] = TRACE_COUNTS.get(name, 0) + 1


class ForceLoop(StrEnum):
    SEA = "sea"  # P(I) loop on the measured spring force
    RIGID = "rigid"  # no spring to measure: F = f_r / η
    IDEAL = "ideal"  # no motor dynamics: the command is the spring force


@dataclass(frozen=True, kw_only=True)
class FirmwareConfig:
    """Structure of the control law (static: hashable, one compiled step per value)."""

    period: float  # T [s]
    env: EnvKind = EnvKind.SPRING
    box_mode: BoxMode = BoxMode.INSIDE
    force_loop: ForceLoop = ForceLoop.SEA
    integral: bool = False
    saturation: bool = True
    friction_compensation: bool = False
    gravity_compensation: bool = False
    interpolation: int = 1
    ar: tuple[float, ...] = (2.0, -1.0)
    interpolation_variant: Variant = DEFAULT_VARIANT
    velocity_alpha: float = 0.0  # low-pass pole of the velocity estimate, exp(−2π f_c T)
    # seed 000's predictor as the paper runs it (interpolation > 1 only): AR(ar_order) fitted per axis to the
    # last ar_window positions at every tick, the rendered force and the force loop's command computed at
    # the predicted positions (``online_predictions``); FIXED extrapolates the command with ``ar``
    predictor: Predictor = Predictor.FIXED
    ar_order: int = 2
    ar_window: int = 16

    @property
    def online(self) -> bool:
        return self.predictor is Predictor.ONLINE and self.interpolation > 1


class Gains(NamedTuple):
    """Numbers of the control law [SI]; every entry may carry leading batch axes."""

    J: jax.Array  # (3, 3)
    resolution: jax.Array  # [m/count]
    spring: jax.Array  # k [N/m]
    efficiency: jax.Array  # η
    stiffness: jax.Array  # (…, 3) K_v [N/m]
    damping: jax.Array  # (…, 3) B_v [N·s/m]
    anchor: jax.Array  # (3,) [m]
    half_size: jax.Array  # (3,) [m]
    wall_stiffness: jax.Array  # [N/m]
    wall_damping: jax.Array  # [N·s/m]
    force_amplitude: jax.Array  # (…, 3) [N]
    force_omega: jax.Array  # (…,) [rad/s]
    force_phase: jax.Array  # (…, 3) [rad]
    kp: jax.Array  # (…,) K_p
    ki: jax.Array  # (…,) K_i [1/s]
    motor_limit: jax.Array  # [N]
    friction_comp: jax.Array  # [N]
    friction_comp_velocity: jax.Array  # [m/s]
    weight: jax.Array  # M g [N]
    period: jax.Array | None = None  # T [s] as an argument (None: the compiled-in cfg.period)
    velocity_alpha: jax.Array | None = None  # velocity-filter pole as an argument (None: cfg.velocity_alpha)


class State(NamedTuple):
    tick: jax.Array  # () int
    p_prev: jax.Array  # (…, 3) [m]
    velocity: jax.Array  # (…, 3) [m/s]
    integral: jax.Array  # (…, 3) [N]
    history: jax.Array  # (…, 3, 3) last three outputs f_{i−2}, f_{i−1}, f_i (interpolation)
    positions: jax.Array | None = None  # (…, ar_window, 3) last positions, oldest first (online predictor)


def build(design: PrrrDesign, scene: Scene, resolution: Resolution, *, period: float | None = None
          ) -> tuple[FirmwareConfig, Gains]:
    """Controller structure and gains for ``design`` in ``scene`` (period defaults to the scene's T)."""
    fx = resolution.effects
    cs, env, a = scene.controller, scene.environment, design.actuator
    T = cs.period if period is None else period
    if scene.output_locked or (Effect.MOTOR_DYNAMICS in fx and Effect.SEA_COMPLIANCE in fx):
        loop = ForceLoop.SEA
    elif Effect.MOTOR_DYNAMICS not in fx:
        loop = ForceLoop.IDEAL
    else:
        loop = ForceLoop.RIGID
    alpha = math.exp(-2.0 * math.pi * cs.velocity_filter * T) if cs.velocity_filter > 0 else 0.0
    order = cs.ar_order if cs.ar_order is not None else 2
    window = cs.ar_window if cs.ar_window is not None else 16
    if window < 2 * order:
        raise InvalidInput(f"scene {scene.name}: controller.ar_window = {window} is out of range: allowed ≥ "
                           f"2·ar_order = {2 * order} (samples; at least as many regression equations as coefficients)")
    cfg = FirmwareConfig(
        period=T, env=env.kind, box_mode=env.box_mode, force_loop=loop,
        integral=loop == ForceLoop.SEA and cs.integral_gain > 0,
        saturation=Effect.SATURATION in fx,
        friction_compensation=Effect.COULOMB_FRICTION in fx and cs.friction_compensation > 0,
        gravity_compensation=Effect.GRAVITY in fx and cs.gravity_compensation,
        interpolation=cs.interpolation, ar=cs.ar_coefficients, velocity_alpha=alpha,
        interpolation_variant=cs.interpolation_variant, predictor=cs.predictor, ar_order=order, ar_window=window,
    )
    J = np.asarray(jacobian(design.geometry.beta, xp=np))
    limit = a.force_limit if loop == ForceLoop.IDEAL else a.force_limit / a.efficiency
    # numpy float64: jitted steps take them as arguments as is (no per-entry device transfer here)
    f64 = lambda v: np.asarray(v, dtype=np.float64)  # noqa: E731
    gains = Gains(
        J=f64(J), resolution=f64(a.encoder_resolution), spring=f64(a.spring), efficiency=f64(a.efficiency),
        stiffness=f64(env.stiffness), damping=f64(env.damping), anchor=f64(env.anchor), half_size=f64(env.half_size),
        wall_stiffness=f64(env.wall_stiffness), wall_damping=f64(env.wall_damping),
        force_amplitude=f64(env.force_amplitude), force_omega=f64(2.0 * math.pi * env.force_frequency),
        force_phase=f64(env.force_phase),
        kp=f64(cs.force_gain), ki=f64(cs.integral_gain), motor_limit=f64(limit),
        friction_comp=f64(cs.friction_compensation), friction_comp_velocity=f64(cs.friction_compensation_velocity),
        weight=f64(design.end_effector.mass * GRAVITY),
    )
    return cfg, gains


def init_state(cfg: FirmwareConfig, gains: Gains, slider_counts: jax.Array) -> State:
    """State at power-up: the first reading is the previous position; nothing integrated."""
    J = tuple(gains.J[..., i, j] for i in range(3) for j in range(3))
    p = _stack(LAW.position(gains.resolution, J, _axes(slider_counts)))
    zeros = jnp.zeros_like(p)
    positions = None
    if cfg.online:  # at power-up the history is the first reading (at rest): the fit falls back until motion
        positions = jnp.broadcast_to(p[..., None, :], p.shape[:-1] + (cfg.ar_window, 3)) + 0.0
    return State(tick=jnp.asarray(0), p_prev=p, velocity=zeros, integral=zeros,
                 history=jnp.zeros(p.shape[:-1] + (3, 3)), positions=positions)


def interpolation_weights(cfg: FirmwareConfig) -> np.ndarray:
    """(L, 5) weights of [f_{i−2}, f_{i−1}, f_i, f̂_{i+1}, f̂_{i+2}] for the L output samples (eq 23) of
    the configured variant (as printed: the first four; as intended: the last four; none: f_i)."""
    return spline_weights(cfg.interpolation, cfg.interpolation_variant)


def predictions(ar: tuple[float, ...], history):
    """(f̂_{i+1}, f̂_{i+2}) by the AR recursion from history (…, 3, 3) = [f_{i−2}, f_{i−1}, f_i]."""
    pred = sum(a * history[..., 2 - j, :] for j, a in enumerate(ar))
    newest = [pred, history[..., 2, :], history[..., 1, :]]  # f̂_{i+1}, f_i, f_{i−1}
    pred2 = sum(a * newest[j] for j, a in enumerate(ar))
    return pred, pred2


def fit_ar_axes(positions, order: int):
    """Least-squares AR(order) coefficients per axis of ``positions`` (…, W, 3), oldest first, as
    :func:`hapticopt.analysis.control.upsampling.fit_ar` fits one axis: (…, 3, order) coefficients and a
    (…, 3) mask of the axes that fitted (rcond of the regression above ``AR_RCOND_BAND``); the others get
    the fallback (2, −1, 0, …)."""
    W = positions.shape[-2]
    n_eq = W - order
    x = jnp.swapaxes(positions, -1, -2)  # (…, 3, W)
    X = jnp.stack([x[..., order - 1 - j: order - 1 - j + n_eq] for j in range(order)], axis=-1)  # (…, 3, n_eq, p)
    y = x[..., order:]
    U, sv, Vt = jnp.linalg.svd(X, full_matrices=False)
    smax = sv[..., 0]
    rc = jnp.where(smax > 0.0, sv[..., -1] / jnp.where(smax > 0.0, smax, 1.0), 0.0)
    ok = rc > AR_RCOND_BAND
    safe = jnp.where(ok[..., None], sv, 1.0)
    coef = jnp.einsum("...ji,...j->...i", Vt, jnp.einsum("...ji,...j->...i", U, y) / safe)
    fallback = jnp.asarray(fallback_coefficients(order))
    return jnp.where(ok[..., None], coef, fallback), ok


def online_predictions(cfg: FirmwareConfig, positions):
    """(p̂_{i+1}, p̂_{i+2}, fitted mask) by the per-axis AR fit of the last ``ar_window`` positions."""
    a, ok = fit_ar_axes(positions, cfg.ar_order)  # (…, 3, p)
    newest = [positions[..., -1 - j, :] for j in range(cfg.ar_order)]  # p_i, p_{i−1}, …
    p1 = sum(a[..., j] * newest[j] for j in range(cfg.ar_order))
    newest2 = [p1] + newest[:-1]
    p2 = sum(a[..., j] * newest2[j] for j in range(cfg.ar_order))
    return p1, p2, ok


def _jax_ops(note) -> Ops:
    return Ops(where=jnp.where, sign=jnp.sign, sin=jnp.sin, tanh=jnp.tanh, clip=jnp.clip, and_=jnp.logical_and,
               not_=jnp.logical_not, note=note)


#: the law on jax arrays (each component carries the batch axes); QUIET: the same without trace notes (the
#: renders at predicted positions)
LAW, QUIET = make_law(_jax_ops(_traced)), make_law(_jax_ops(lambda name: None))


def _axes(x, n: int = 3) -> tuple:
    """The last axis of ``x`` as n separate components."""
    return tuple(x[..., i] for i in range(n))


def _stack(components, like=0.0) -> jax.Array:
    """(…, 3) from three components, broadcast to a common shape with ``like`` (the batch a constant term lacks)."""
    return jnp.stack(jnp.broadcast_arrays(*components, like)[:3], axis=-1)


def _flags(cfg: FirmwareConfig) -> tuple[int, ...]:
    """The law's structure flags (:data:`hapticopt.analysis.prrr.loop.firmware_law.FLG`) of ``cfg``."""
    if cfg.env == EnvKind.BOX:
        env = ENV_BOX_INSIDE if cfg.box_mode == BoxMode.INSIDE else ENV_BOX_OUTSIDE
    else:
        env = {EnvKind.FREE: ENV_FREE, EnvKind.SPRING: ENV_SPRING, EnvKind.FORCE: ENV_FORCE}[cfg.env]
    loop = {ForceLoop.SEA: LOOP_SEA, ForceLoop.RIGID: LOOP_RIGID, ForceLoop.IDEAL: LOOP_IDEAL}[cfg.force_loop]
    return (env, int(cfg.friction_compensation), int(cfg.gravity_compensation), loop, int(cfg.integral),
            int(cfg.saturation), int(cfg.velocity_alpha > 0.0))


def _law_arguments(cfg: FirmwareConfig, gains: Gains, T, alpha) -> tuple:
    """(par, flg, J, K, B, anchor, half, famp, fphase) of the law for the jax step: components of ``gains``."""
    g = gains
    par = (g.resolution, T, alpha, g.wall_stiffness, g.wall_damping, g.force_omega, g.friction_comp,
           g.friction_comp_velocity, g.weight, g.spring, g.kp, g.ki * T, g.motor_limit, g.efficiency)
    J = tuple(g.J[..., i, j] for i in range(3) for j in range(3))
    vec = tuple(_axes(jnp.broadcast_to(x, jnp.shape(x)[:-1] + (3,)) if jnp.ndim(x) else jnp.broadcast_to(x, (3,)))
                for x in (g.stiffness, g.damping, g.anchor, g.half_size, g.force_amplitude, g.force_phase))
    return (par, _flags(cfg), J, *vec)


def step(cfg: FirmwareConfig, gains: Gains, state: State, slider_counts: jax.Array, deflection_counts: jax.Array
         ) -> tuple[State, jax.Array, jax.Array]:
    """One control period. Returns (new state, commands (…, L, 3) [N], F_r (…, 3) [N])."""
    T = cfg.period if gains.period is None else gains.period
    alpha = cfg.velocity_alpha if gains.velocity_alpha is None else gains.velocity_alpha
    args = _law_arguments(cfg, gains, T, alpha)
    par, flg, J = args[:3]
    env = args[3:]
    dc = _axes(deflection_counts)
    pc, vc, ic, Fc, oc = LAW.command(*args, _axes(state.p_prev), _axes(state.velocity), _axes(state.integral),
                                     state.tick, _axes(slider_counts), dc)
    p, v, integral, F, out = (_stack(c, pc[0]) for c in (pc, vc, ic, Fc, oc))
    history, positions = state.history, state.positions
    if cfg.interpolation > 1:
        _traced("interpolation")
        history = jnp.concatenate([history[..., 1:, :], out[..., None, :]], axis=-2)
        if cfg.online:
            # seed 000 as the paper runs it: predict the positions, render the force there, and give the
            # force loop's command at the predicted positions
            _traced("online_predictor")
            positions = jnp.concatenate([positions[..., 1:, :], p[..., None, :]], axis=-2)
            p1, p2, _ = online_predictions(cfg, positions)
            p1, p2 = _axes(p1), _axes(p2)
            v1 = QUIET.velocity(par, flg, p1, pc, vc)
            v2 = QUIET.velocity(par, flg, p2, p1, v1)
            preds, ik = [], ic
            for k, (pk, vk) in enumerate(((p1, v1), (p2, v2)), start=1):
                Fk = QUIET.render(par, flg, *env, pk, vk, state.tick + k)
                # the command the force loop would give at tick i + k: the integral runs on (chained
                # over the predicted errors), the spring deflection is this tick's measurement
                uk, ik = QUIET.force_loop(par, flg, QUIET.legs(J, Fk), dc, ik)
                preds.append(_stack(uk, pc[0]))
            pred, pred2 = preds
        else:
            pred, pred2 = predictions(cfg.ar, history)
        ctrl = jnp.concatenate([history, pred[..., None, :], pred2[..., None, :]], axis=-2)  # (…, 5, 3)
        W = jnp.asarray(interpolation_weights(cfg))
        cmd = jnp.einsum("lj,...jk->...lk", W, ctrl)
    else:
        cmd = out[..., None, :]
    cmd = LAW.saturate(par, flg, cmd)
    new = State(tick=state.tick + 1, p_prev=p, velocity=v, integral=integral, history=history, positions=positions)
    return new, cmd, F


def scalar_arguments(cfg: FirmwareConfig, gains: Gains) -> tuple[list, ...]:
    """(par, flg, J, K, B, anchor, half, famp, fphase) of the law on floats (Python lists) for one controller."""
    if cfg.interpolation > 1:
        raise ValueError("the scalar firmware law runs interpolation 1; L > 1 is the jax step's "
                         "(hapticopt.analysis.prrr.loop.firmware.FirmwareController)")
    g = {k: np.asarray(v, dtype=np.float64) for k, v in gains._asdict().items() if v is not None}
    f = lambda name: float(g[name])  # noqa: E731
    v3 = lambda name: np.broadcast_to(g[name], (3,)).tolist()  # noqa: E731
    par = [f("resolution"), cfg.period, cfg.velocity_alpha, f("wall_stiffness"), f("wall_damping"), f("force_omega"),
           f("friction_comp"), f("friction_comp_velocity"), f("weight"), f("spring"), f("kp"), f("ki") * cfg.period,
           f("motor_limit"), f("efficiency")]
    return (par, list(_flags(cfg)), g["J"].ravel().tolist(), v3("stiffness"), v3("damping"), v3("anchor"),
            v3("half_size"), v3("force_amplitude"), v3("force_phase"))


class ScalarController:
    """The law on Python floats for one controller at interpolation 1 (``reset``, ``step``, ``last_force``: the
    interface of :class:`FirmwareController` without a jax dispatch per tick). The compiled MuJoCo loop runs
    the same law on its ``args`` and ``state`` (:mod:`hapticopt.analysis.prrr.loop._mujoco_kernel`)."""

    def __init__(self, cfg: FirmwareConfig, gains: Gains) -> None:
        self.cfg, self.gains, self.period = cfg, gains, cfg.period
        self.args = scalar_arguments(cfg, gains)
        self.state = [0.0] * 12  # p_prev, velocity, integral, F_r
        self.tick = 0
        self._ready = False

    @property
    def last_force(self) -> np.ndarray:
        """F_r of the last tick (3,) [N]."""
        return np.array(self.state[9:12])

    def reset(self, slider_counts: Any) -> None:
        """Power-up: the first reading is the previous position; nothing integrated."""
        self.state = [float(x) for x in PYTHON.position(self.args[0][0], self.args[2], slider_counts)] + [0.0] * 9
        self.tick = 0
        self._ready = True

    def step(self, slider_counts: Any, deflection_counts: Any) -> np.ndarray:
        """Commands (1, 3) [N] for this period from the counts read at its start (lists or arrays)."""
        if not self._ready:
            self.reset(slider_counts)
        s = self.state
        p, v, ig, F, out = PYTHON.tick(*self.args, (s[0], s[1], s[2]), (s[3], s[4], s[5]), (s[6], s[7], s[8]),
                                       self.tick, slider_counts, deflection_counts)
        self.state = [float(x) for x in (*p, *v, *ig, *F)]
        self.tick += 1
        return np.array([out])


class FirmwareController:
    """The control law as an object: fixed period, ``step(sensors) -> commands``.

    ``sensors`` are counts (slider encoder, spring deflection), each shape (3,). The step is
    compiled once; per-call cost is the jit dispatch (the runner fuses it into its compiled loop
    instead, see ``hapticopt.analysis.prrr.loop.closed_loop``).
    """

    def __init__(self, cfg: FirmwareConfig, gains: Gains) -> None:
        self.cfg = cfg
        self.gains = gains
        self.period = cfg.period
        self._step = jax.jit(lambda g, s, a, b: step(cfg, g, s, a, b))
        self._init = jax.jit(lambda g, a: init_state(cfg, g, a))  # compiled as in the fused loop (same roundings)
        self.state: State | None = None
        self.last_force: np.ndarray = np.zeros(3)

    def reset(self, slider_counts: np.ndarray) -> None:
        self.state = self._init(self.gains, jnp.asarray(slider_counts, dtype=jnp.float64))

    def step(self, slider_counts: np.ndarray, deflection_counts: np.ndarray) -> np.ndarray:
        """Commands (L, 3) [N] for this period from the counts read at its start."""
        if self.state is None:
            self.reset(slider_counts)
        self.state, cmd, F = self._step(self.gains, self.state, jnp.asarray(slider_counts, dtype=jnp.float64),
                                        jnp.asarray(deflection_counts, dtype=jnp.float64))
        self.last_force = np.asarray(F)
        return np.asarray(cmd)


def controller(cfg: FirmwareConfig, gains: Gains) -> ScalarController | FirmwareController:
    """The law for a Python loop: :class:`ScalarController` at interpolation 1, else :class:`FirmwareController`."""
    return ScalarController(cfg, gains) if cfg.interpolation == 1 else FirmwareController(cfg, gains)

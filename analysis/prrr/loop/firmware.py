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

The law is a pure function :func:`step` on arrays (jax, compiled once per structure, batched
over any leading axis and fused with the lumped plant in one compiled loop: the Z-width map runs hundreds of
controllers in one call). Structure (which terms exist) is static in :class:`FirmwareConfig`: a term that is
off is not traced, so it costs nothing. :class:`FirmwareController` wraps it as an object with
``step(sensors)``. The MuJoCo loops step one controller per tick between ``mj_step`` calls, where a jax dispatch
per tick would cost more than the physics: they run the same law written for one controller on scalars
(:func:`hapticopt.analysis.prrr.loop.firmware_law.tick`, compiled there by numba; without interpolation),
held equal to this one in ``tests/analysis/prrr/loop/test_firmware_law.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from hapticopt.design import jax_config  # noqa: F401  (float64 before any jax array)
from hapticopt.analysis.control.upsampling import (AR_RCOND_BAND, DEFAULT_VARIANT, Predictor, Variant,
                                                   fallback_coefficients, spline_weights)
from hapticopt.design.prrr.kinematics import jacobian
from hapticopt.analysis.loop.scene import BoxMode, Effect, EnvKind, Resolution, Scene
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
    p = (slider_counts * gains.resolution) @ gains.J.T
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


def _render(cfg: FirmwareConfig, gains: Gains, p, v, tick, T, *, trace: bool = True):
    """F_r (…, 3) [N] at position p, velocity v, tick (step 3 of the module docstring)."""
    note = _traced if trace else (lambda name: None)
    delta = p - gains.anchor
    if cfg.env == EnvKind.FREE:
        F = jnp.zeros_like(p)
    elif cfg.env == EnvKind.SPRING:
        note("spring")
        F = -gains.stiffness * delta - gains.damping * v
    elif cfg.env == EnvKind.BOX:
        note("box")
        depth = jnp.abs(delta) - gains.half_size  # > 0: beyond the wall on that axis
        sgn = jnp.sign(delta)
        if cfg.box_mode == BoxMode.INSIDE:  # eq 13, inside: every axis beyond its wall pushes back
            F = jnp.where(depth > 0.0, -gains.wall_stiffness * sgn * depth - gains.wall_damping * v, 0.0)
        else:  # outside: all axes within → push out along the shallowest axis
            inside = jnp.all(depth < 0.0, axis=-1, keepdims=True)
            axis = jnp.argmax(depth, axis=-1)[..., None]
            pick = jnp.arange(3) == axis
            F = jnp.where(inside & pick, gains.wall_stiffness * sgn * (-depth) - gains.wall_damping * v, 0.0)
    else:  # FORCE: prescribed force reference
        note("force")
        t = tick * T
        F = gains.force_amplitude * jnp.sin(gains.force_omega[..., None] * t + gains.force_phase) + jnp.zeros_like(p)
    if cfg.friction_compensation:
        note("friction_compensation")
        comp = gains.friction_comp * jnp.tanh(v / gains.friction_comp_velocity)
        F = F + comp * jnp.array([1.0, 1.0, 0.0])
    if cfg.gravity_compensation:
        note("gravity_compensation")
        F = F + gains.weight * jnp.array([0.0, 0.0, 1.0])
    return F


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


def _force_loop(cfg: FirmwareConfig, gains: Gains, f_ref, deflection_counts, integral, T, *, trace: bool = True):
    """(command before interpolation, integral) from the spring-force references f_ref (step 5)."""
    note = _traced if trace else (lambda name: None)
    if cfg.force_loop == ForceLoop.SEA:
        note("force_loop")
        err = f_ref - gains.spring * (deflection_counts * gains.resolution)
        out = gains.kp[..., None] * err
        if cfg.integral:
            note("integral")
            integral = integral + gains.ki[..., None] * T * err
            if cfg.saturation:
                integral = jnp.clip(integral, -gains.motor_limit, gains.motor_limit)
            out = out + integral
    elif cfg.force_loop == ForceLoop.RIGID:
        out = f_ref / gains.efficiency
    else:
        out = f_ref
    return out, integral


def step(cfg: FirmwareConfig, gains: Gains, state: State, slider_counts: jax.Array, deflection_counts: jax.Array
         ) -> tuple[State, jax.Array, jax.Array]:
    """One control period. Returns (new state, commands (…, L, 3) [N], F_r (…, 3) [N])."""
    T = cfg.period if gains.period is None else gains.period
    p = (slider_counts * gains.resolution) @ gains.J.T
    diff = (p - state.p_prev) / T
    alpha = None
    if cfg.velocity_alpha > 0.0:  # structure: whether the filter exists; its pole may be an argument
        alpha = cfg.velocity_alpha if gains.velocity_alpha is None else gains.velocity_alpha
        v = alpha * state.velocity + (1.0 - alpha) * diff
    else:
        v = diff
    F = _render(cfg, gains, p, v, state.tick, T)
    f_ref = F @ gains.J  # Jᵀ F_r, per leg
    out, integral = _force_loop(cfg, gains, f_ref, deflection_counts, state.integral, T)
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

            def vel(v_prev, new, old):
                d = (new - old) / T
                return d if alpha is None else alpha * v_prev + (1.0 - alpha) * d

            v1 = vel(v, p1, p)
            v2 = vel(v1, p2, p1)
            preds, ik = [], integral
            for k, (pk, vk) in enumerate(((p1, v1), (p2, v2)), start=1):
                Fk = _render(cfg, gains, pk, vk, state.tick + k, T, trace=False)
                # the command the force loop would give at tick i + k: the integral runs on (chained
                # over the predicted errors), the spring deflection is this tick's measurement
                uk, ik = _force_loop(cfg, gains, Fk @ gains.J, deflection_counts, ik, T, trace=False)
                preds.append(uk)
            pred, pred2 = preds
        else:
            pred, pred2 = predictions(cfg.ar, history)
        ctrl = jnp.concatenate([history, pred[..., None, :], pred2[..., None, :]], axis=-2)  # (…, 5, 3)
        W = jnp.asarray(interpolation_weights(cfg))
        cmd = jnp.einsum("lj,...jk->...lk", W, ctrl)
    else:
        cmd = out[..., None, :]
    if cfg.saturation:
        _traced("saturation")
        cmd = jnp.clip(cmd, -gains.motor_limit, gains.motor_limit)
    new = State(tick=state.tick + 1, p_prev=p, velocity=v, integral=integral, history=history, positions=positions)
    return new, cmd, F


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
        self.state: State | None = None
        self.last_force: np.ndarray = np.zeros(3)

    def reset(self, slider_counts: np.ndarray) -> None:
        self.state = init_state(self.cfg, self.gains, jnp.asarray(slider_counts, dtype=jnp.float64))

    def step(self, slider_counts: np.ndarray, deflection_counts: np.ndarray) -> np.ndarray:
        """Commands (L, 3) [N] for this period from the counts read at its start."""
        if self.state is None:
            self.reset(slider_counts)
        self.state, cmd, F = self._step(self.gains, self.state, jnp.asarray(slider_counts, dtype=jnp.float64),
                                        jnp.asarray(deflection_counts, dtype=jnp.float64))
        self.last_force = np.asarray(F)
        return np.asarray(cmd)

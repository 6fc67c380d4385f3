"""Closed-loop scenes: what to simulate, read from TOML, and which physics (effects) it calls for.

A scene names the duration, the controller settings, the virtual environment, the operator
(a mass-spring-damper hand, seed 000 eq 1, driven by a reference motion) or an initial
perturbation, and the **effects** switched on. An effect that is off is absent from the plant
and from the controller (it is not evaluated at all, see ``tests/analysis/prrr/loop/test_closed_loop.py``).

:func:`resolve` turns a scene into the effect set actually simulated and the backend that
can simulate it, with the reason: the lumped plant (``hapticopt.analysis.prrr.loop.lumped_plant``) when the effects
allow it, the multibody MuJoCo plant (``hapticopt.analysis.prrr.loop.mujoco_plant``, ``hapticopt.analysis.master.mujoco_plant``) for
``link_dynamics`` (with or without gravity on the links) and for the surgical master at all.
A scene (``backend = "lumped" | "multibody"``) or the caller may force a backend; forcing the
lumped plant onto a scene it cannot simulate is refused with a one-line error, never silently run.

TOML keys carry their unit (``period_ms``, ``stiffness_N_per_mm``); values are stored in SI.
Every invalid value raises :class:`design.errors.InvalidInput` with a one-line message naming
the scene, the key, the value and what is allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from hapticopt.design import bundled, tomlsafe
from hapticopt.design.errors import InvalidInput, short, short_key
from hapticopt.design.paths import check_name
from hapticopt.analysis.control.upsampling import DEFAULT_VARIANT, Predictor, Variant
from hapticopt.analysis.loop.assumptions import Assumption
from hapticopt.analysis.loop.assumptions import parse as parse_assumptions
from hapticopt.analysis.loop.operator import Operator, OperatorKind


class Effect(StrEnum):
    """Physics a scene can switch on or off."""

    SEA_COMPLIANCE = "sea_compliance"  # the series spring k; off: rigid transmission
    MOTOR_DYNAMICS = "motor_dynamics"  # motor-side mass M_m and the force loop; off: ideal force source
    COULOMB_FRICTION = "coulomb_friction"  # stick-slip friction of the output sliders (+ its compensation)
    VISCOUS_FRICTION = "viscous_friction"  # screw viscous friction ξ (motor side)
    GRAVITY = "gravity"  # weight of the end-effector mass M (+ its compensation)
    SAMPLING = "sampling"  # controller at period T with zero-order hold; off: continuous-time limit
    QUANTIZATION = "quantization"  # encoder and spring-deflection counts are integers
    SATURATION = "saturation"  # motor-force limit
    OPERATOR = "operator"  # mass-spring-damper hand driven by the reference motion
    TIME_DELAY = "time_delay"  # commands reach the plant ``time_delay_ms`` late
    LINK_DYNAMICS = "link_dynamics"  # distributed link inertia: needs the multibody backend


#: devices a scene can be written for
DEVICES = ("prrr", "master", "handle")

#: effects on when a scene's [effects] table does not mention them
DEFAULT_EFFECTS: frozenset[Effect] = frozenset(Effect) - {Effect.TIME_DELAY, Effect.LINK_DYNAMICS}


class EnvKind(StrEnum):
    FREE = "free"  # zero impedance
    SPRING = "spring"  # F_r = −K_v (p − anchor) − B_v ṗ
    BOX = "box"  # virtual box of eq 13
    FORCE = "force"  # prescribed end-effector force F_r(t) = A sin(2πft) (force-loop tests)


class BoxMode(StrEnum):
    INSIDE = "inside"  # keep the end-effector inside: walls act on every axis beyond its wall
    OUTSIDE = "outside"  # keep it out: acts when all axes are within, along the shallowest axis


class FrictionLocation(StrEnum):
    """Where the ``coulomb_friction`` effect acts (seed 002 blames the R joints, §4.3)."""

    SLIDERS = "sliders"  # F_c on each output slider (``actuator.coulomb_friction_N``)
    R_JOINTS = "r_joints"  # τ_c on each of the nine R joints (``structure.joint_friction_Nm``), through each leg's IK
    BOTH = "both"


class PaperQuantity(StrEnum):
    """A seed experiment's reported quantity, computed the paper's way (:mod:`hapticopt.analysis.loop.paper`)."""

    HAND_FORCE_AXIS_RMS = "hand_force_axis_rms"  # Fig 14: RMS of the measured force along the driven axis
    FORCE_ERROR_AXIS_RMS = "force_error_axis_rms"  # Fig 8: RMS of (F − F_r) along one axis
    FORCE_ERROR_PLANE_RMS = "force_error_plane_rms"  # Fig 9/10: RMS of |F − F_r| in a plane
    STIFFNESS_ERROR_PCT = "stiffness_error_pct"  # Fig 15: rendered vs commanded stiffness


class StabilityCriterion(StrEnum):
    DRIVEN = "driven"  # energy explodes beyond the scene's energy scale, or state runs away
    DECAY = "decay"  # + the energy of the last window exceeds the window before (growth)


class FirmwareMode(StrEnum):
    """What the firmware does (``[controller] mode``)."""

    IMPEDANCE = "impedance"  # render the scene's virtual environment (seed 002 / seed 003 firmware)
    IOIC = "ioic"  # seed 001: learned optimal impedance (outer loop) over the device's inner loop


class MotionShape(StrEnum):
    SINE = "sine"  # offset + amplitude·sin(2πft + phase)
    SQUARE = "square"  # offset ± amplitude, +amplitude on the first half period (seed 001 §4.1)


class IoicStrategy(StrEnum):
    """Outer-loop gain of the IOIC firmware mode (seed 001 Figs 4–6)."""

    FIC = "fic"  # fixed impedance K_0 throughout
    OIC = "oic"  # the model optimum K* (Riccati, eq 6) throughout
    IOIC = "ioic"  # K_0 + exploration for the data phase, policy iteration, soft switch (eq 7–10)


@dataclass(frozen=True, kw_only=True)
class IoicSettings:
    """Seed 001's outer loop on a device (``[ioic]``); defaults are §4.1's (eq 27, 28, 31)."""

    strategy: IoicStrategy = IoicStrategy.IOIC
    axis: int = 0  # Cartesian axis of the learned impedance (0 = x)
    state_weights: tuple[float, float, float] = (1.0, 1.0, 1.0)  # diag Q of eq 6 [1/m², s²/m², 1/N²]
    input_weight: float = 0.01  # R of eq 6 [s⁴/m²]
    initial_gain: tuple[float, float, float] = (10.0, 4.0, 0.2)  # K_0 = [K/M, B/M, 1/M] [1/s², 1/s, 1/kg] (eq 31)
    learn_time: float = 0.5  # data phase [s]
    intervals: int = 50  # sampling intervals of the data phase
    switch_time: float = 0.5  # T_s of eq 10 [s]
    exploration: bool = True  # exploration noise v_n of eq 28 during the data phase
    noise_seed: int = -1  # −1: eq 28 as printed; ≥ 0: a seeded random multi-sine (ExplorationNoise.multisine)
    tolerance: float = 1e-8  # ε of ‖P_k − P_{k−1}‖_F
    tracking_stiffness: float = 2e3  # 3-PRRR: Cartesian spring towards x_r [N/m]
    tracking_damping: float = 40.0  # 3-PRRR: Cartesian damper towards ẋ_r [N·s/m]


@dataclass(frozen=True, kw_only=True)
class NtsmtcSettings:
    """Seed 001's NTSMTC inner loop (eq 13–17, 26) per joint of the master (``[ntsmtc]``);
    defaults: §4.2 (λ1 = λ2 = 3, a = 5, b = 3, μ = 0.005, β = (0.5, 1), η = 1.5), the third joint
    as the second; θ of eq 26 is ours."""

    lambda1: tuple[float, float, float] = (3.0, 3.0, 3.0)  # [1/s]
    lambda2: tuple[float, float, float] = (3.0, 3.0, 3.0)  # [1/s]
    a: int = 5
    b: int = 3
    mu: float = 0.005  # [rad]
    beta: tuple[float, float, float] = (0.5, 1.0, 1.0)  # [1/s]
    eta: float = 1.5  # [rad/s²]
    theta: float = 0.05  # [rad/s]


class DynamicsCompensation(StrEnum):
    """Which bodies' inertia (and Coriolis) a model-based controller compensates (master, seed 003)."""

    NONE = "none"  # open-loop impedance rendering τ = Jᵀ F_D
    LINKS = "links"  # the links' model without the counterweights (seed 003's reading, docs/master.md)
    FULL = "full"  # every moving body, counterweights included


@dataclass(frozen=True, kw_only=True)
class ControllerSettings:
    mode: FirmwareMode = FirmwareMode.IMPEDANCE
    period: float = 1e-3  # T [s]
    force_gain: float = 45.0  # K_p [-] (seed 002 Table 4 experiments)
    integral_gain: float = 0.0  # K_i [1/s]
    velocity_filter: float = 100.0  # first-order low-pass cut-off of the velocity estimate [Hz]; 0 = plain difference
    friction_compensation: float = 0.0  # [N] added in x and y along the estimated velocity (seed 002: 3 N)
    friction_compensation_velocity: float = 2e-3  # [m/s] width of the tanh sign used by the compensation
    gravity_compensation: bool = True
    dynamics_compensation: DynamicsCompensation = DynamicsCompensation.NONE  # master: model-based M q̈ + C q̇
    interpolation: int = 1  # output samples per period (seed 000 eq 23); 1 = off
    ar_coefficients: tuple[float, ...] = (2.0, -1.0)  # f_{i+1} = Σ a_j f_{i−j}
    # which eq (23) spline segment (analysis.control.upsampling.Variant); default: the one that does
    # not lower the stable stiffness (docs/seed000.md)
    interpolation_variant: Variant = DEFAULT_VARIANT
    # seed 000 section 4: the AR coefficients fixed (ar_coefficients) or fitted online to the last
    # ar_window positions at every update; None = the device's default (the handle: its design's
    # [firmware] ar_order / ar_window; otherwise 2 and 16)
    predictor: Predictor = Predictor.FIXED
    ar_order: int | None = None  # p [samples]
    ar_window: int | None = None  # regression window [samples], ≥ 2p


@dataclass(frozen=True, kw_only=True)
class Environment:
    kind: EnvKind = EnvKind.FREE
    stiffness: tuple[float, float, float] = (0.0, 0.0, 0.0)  # K_v [N/m]
    damping: tuple[float, float, float] = (0.0, 0.0, 0.0)  # B_v [N·s/m]
    anchor: tuple[float, float, float] = (0.0, 0.0, 0.0)  # p_r [m]
    half_size: tuple[float, float, float] = (0.01, 0.01, 0.01)  # box half-sizes [m]
    wall_stiffness: float = 25e3  # K_b [N/m]
    wall_damping: float = 0.0  # B_b [N·s/m]
    box_mode: BoxMode = BoxMode.INSIDE
    force_amplitude: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [N]
    force_frequency: float = 1.0  # [Hz]
    force_phase: tuple[float, float, float] = (0.0, 0.0, 0.0)  # F_r,a = A_a sin(2πft + φ_a) [rad]


@dataclass(frozen=True, kw_only=True)
class Motion:
    """Reference motion of the hand: offset + amplitude·sin(2πft + phase), per axis."""

    amplitude: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [m]
    frequency: float = 1.0  # [Hz]
    phase: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [rad]
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [m]
    shape: MotionShape = MotionShape.SINE

    def square(self, t: float) -> float:
        """The square wave's sign at t [s]: +1 on [0, 1/(2f)), −1 on [1/(2f), 1/f), ... (a
        1e-9-period nudge puts the edge samples on the new level)."""
        phase = math.fmod(t * self.frequency + 1e-9, 1.0)
        return 1.0 if phase < 0.5 else -1.0


@dataclass(frozen=True, kw_only=True)
class ZWidthSettings:
    axis: int = 0  # 0 = x, 1 = y, 2 = z
    stiffness_range: tuple[float, float] = (1e3, 100e3)  # [N/m]
    damping_range: tuple[float, float] = (0.0, 2000.0)  # [N·s/m]
    points: int = 20


@dataclass(frozen=True, kw_only=True)
class PaperReport:
    """What a scene replicates: the seed's quantity, its axes, and the value the paper reports."""

    quantity: PaperQuantity
    axes: tuple[int, ...] = (0,)
    value: float | None = None  # the paper's number in the quantity's unit (N or %)
    source: str = ""  # e.g. "seed 002 Fig 14a"
    # values the paper does not give and their sources (hapticopt.analysis.loop.assumptions)
    assumptions: tuple[Assumption, ...] = ()


@dataclass(frozen=True, kw_only=True)
class Scene:
    name: str
    description: str = ""
    duration: float = 3.0  # [s]
    controller: ControllerSettings = field(default_factory=ControllerSettings)
    environment: Environment = field(default_factory=Environment)
    operator: Operator = field(default_factory=Operator)
    motion: Motion = field(default_factory=Motion)
    initial_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # end-effector start [m]
    effects: frozenset[Effect] = DEFAULT_EFFECTS
    time_delay: float = 0.0  # [s], used when Effect.TIME_DELAY is on
    substeps: int = 0  # plant substeps per controller period; 0 = by fidelity
    output_locked: bool = False  # clamp the output sliders (force-loop tests, eq 8)
    stability: StabilityCriterion = StabilityCriterion.DRIVEN
    measure_axis: int = 0  # axis of the rendered-stiffness fit
    zwidth: ZWidthSettings = field(default_factory=ZWidthSettings)
    device: str = "prrr"  # which device the scene is written for: "prrr" (3-PRRR SEA) or "master"
    sweep_factors: tuple[float, ...] = ()  # master: sine sweep at these × the frequency-domain bandwidth
    sweep_periods: int = 3  # periods per sweep frequency (the first one settles)
    backend: "Backend | None" = None  # forced backend; None = the resolver chooses
    ioic: IoicSettings = field(default_factory=IoicSettings)  # controller.mode = "ioic"
    ntsmtc: NtsmtcSettings = field(default_factory=NtsmtcSettings)  # the master's IOIC inner loop
    friction_location: FrictionLocation = FrictionLocation.SLIDERS
    report: PaperReport | None = None  # the seed experiment this scene replicates


def require_mode(scene: Scene, mode: FirmwareMode, who: str) -> None:
    """Refuse (one line) a scene whose firmware mode ``who`` does not run."""
    if scene.controller.mode != mode:
        raise InvalidInput(f"scene {scene.name}: controller.mode = {scene.controller.mode.value!r} is not run by "
                           f"{who}: allowed {mode.value!r} (hapticopt.analysis.verify dispatches by mode)")


# ---------------------------------------------------------------------------------------- parsing
_AXES = {"x": 0, "y": 1, "z": 2}


class _Reader:
    """Reads one TOML table with one-line errors; remembers the keys it consumed."""

    def __init__(self, table: Any, where: str) -> None:
        if not isinstance(table, dict):
            raise InvalidInput(f"{where} must be a table, got {short(table)}")
        self.table = table
        self.where = where
        self.used: set[str] = set()

    def _get(self, key: str) -> Any:
        self.used.add(key)
        return self.table.get(key)

    def num(self, key: str, default: float, *, scale: float = 1.0, lo: float = -math.inf, hi: float = math.inf,
            lo_open: bool = False, unit: str = "") -> float:
        v = self._get(key)
        if v is None:
            return default * scale  # defaults are given in the key's unit
        allowed = f"{'<' if lo_open else '≤'} {key} ≤ {hi:g}"
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InvalidInput(f"{self.where}.{key} = {short(v)} must be a finite number: allowed {lo:g} {allowed} {unit}".rstrip())
        if v < lo or v > hi or (lo_open and v == lo):
            raise InvalidInput(f"{self.where}.{key} = {v:g} is out of range: allowed {lo:g} {allowed} {unit}".rstrip())
        return float(v) * scale

    def integer(self, key: str, default: int, *, lo: int, hi: int) -> int:
        v = self._get(key)
        if v is None:
            return default
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise InvalidInput(f"{self.where}.{key} = {short(v)} must be a whole number: allowed {lo} ≤ {key} ≤ {hi}")
        return v

    def flag(self, key: str, default: bool) -> bool:
        v = self._get(key)
        if v is None:
            return default
        if not isinstance(v, bool):
            raise InvalidInput(f"{self.where}.{key} = {short(v)} must be true or false")
        return v

    def vec(self, key: str, default: tuple[float, ...], *, n: int = 3, scale: float = 1.0,
            lo: float = -math.inf, hi: float = math.inf, unit: str = "") -> tuple[float, ...]:
        v = self._get(key)
        if v is None:
            return tuple(float(x) * scale for x in default)
        if (not isinstance(v, list) or len(v) != n
                or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) for x in v)):
            raise InvalidInput(f"{self.where}.{key} = {short(v)} must be a list of {n} finite numbers ({unit or '-'})")
        for x in v:
            if x < lo or x > hi:
                raise InvalidInput(f"{self.where}.{key} = {short(v)} is out of range: allowed {lo:g} ≤ each ≤ {hi:g} {unit}".rstrip())
        return tuple(float(x) * scale for x in v)

    def choice(self, key: str, enum: type[StrEnum], default: StrEnum) -> Any:
        v = self._get(key)
        if v is None:
            return default
        try:
            return enum(v)
        except ValueError:
            allowed = ", ".join(e.value for e in enum)
            raise InvalidInput(f"{self.where}.{key} = {short(v)} is not known: allowed {allowed}") from None

    def axis(self, key: str, default: int) -> int:
        v = self._get(key)
        if v is None:
            return default
        if not isinstance(v, str) or v not in _AXES:
            raise InvalidInput(f"{self.where}.{key} = {short(v)} is not an axis: allowed x, y, z")
        return _AXES[v]

    def done(self) -> None:
        extra = sorted(set(self.table) - self.used)
        if extra:
            allowed = ", ".join(sorted(self.used))
            raise InvalidInput(f"{self.where}.{short_key(extra[0])} is not a known key: allowed {allowed}")


def scene_from_dict(data: dict[str, Any], *, source: str = "scene") -> Scene:
    """Build a :class:`Scene` from a TOML-shaped mapping (edge units). Raises :class:`InvalidInput`."""
    top = _Reader(data, source)
    name = top._get("name")
    check_name(name, f"{source}.name")
    description = top._get("description") or ""
    device = top._get("device") or "prrr"
    if not isinstance(device, str) or device not in DEVICES:
        raise InvalidInput(f"{source}.device = {short(device)} is not known: allowed {', '.join(DEVICES)}")
    backend_key = top._get("backend")
    if not isinstance(backend_key, (str, type(None))):
        raise InvalidInput(f"{source}.backend = {short(backend_key)} is not known: allowed auto, lumped, multibody")
    if backend_key in (None, "auto"):
        backend = None
    else:
        try:
            backend = Backend(backend_key)
        except ValueError:
            raise InvalidInput(f"{source}.backend = {short(backend_key)} is not known: allowed auto, lumped, multibody") from None
    if not isinstance(description, str):
        raise InvalidInput(f"{source}.description = {short(description)} must be a string")
    where = f"scene {name}"
    top.where = where
    duration = top.num("duration_s", 3.0, lo=0.0, hi=3600.0, lo_open=True, unit="s")

    c = _Reader(data.get("controller", {}), f"{where}: controller")
    top.used.add("controller")
    ar = c._get("ar_coefficients")
    if ar is None:
        ar_t: tuple[float, ...] = (2.0, -1.0)
    elif (isinstance(ar, list) and 1 <= len(ar) <= 3
          and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in ar)):
        ar_t = tuple(float(x) for x in ar)
    else:
        raise InvalidInput(f"{where}: controller.ar_coefficients = {short(ar)} must be a list of 1 to 3 finite numbers")
    predictor = c.choice("predictor", Predictor, Predictor.FIXED)
    ar_order = c.integer("ar_order", 0, lo=1, hi=16) if c.table.get("ar_order") is not None else None
    ar_window = c.integer("ar_window", 0, lo=2, hi=4096) if c.table.get("ar_window") is not None else None
    if predictor is Predictor.FIXED and (ar_order is not None or ar_window is not None):
        raise InvalidInput(f"{where}: controller.ar_order / ar_window apply to predictor = \"online\" only "
                           f"(predictor = \"fixed\" uses ar_coefficients)")
    if predictor is Predictor.ONLINE and ar is not None:
        raise InvalidInput(f"{where}: controller.ar_coefficients = {short(ar)} applies to predictor = \"fixed\" only "
                           f"(predictor = \"online\" fits them; set ar_order and ar_window instead)")
    if ar_order is not None and ar_window is not None and ar_window < 2 * ar_order:
        raise InvalidInput(f"{where}: controller.ar_window = {ar_window} is out of range: allowed ≥ 2·ar_order = "
                           f"{2 * ar_order} (samples; at least as many regression equations as coefficients)")
    controller = ControllerSettings(
        mode=c.choice("mode", FirmwareMode, FirmwareMode.IMPEDANCE),
        period=c.num("period_ms", 1.0, scale=1e-3, lo=0.0, hi=100.0, lo_open=True, unit="ms"),
        force_gain=c.num("force_gain", 45.0, lo=0.0, hi=1e9, unit="(N motor force per N spring-force error)"),
        integral_gain=c.num("integral_gain_per_s", 0.0, lo=0.0, hi=1e9, unit="1/s"),
        velocity_filter=c.num("velocity_filter_Hz", 100.0, lo=0.0, hi=1e7, unit="Hz"),
        friction_compensation=c.num("friction_compensation_N", 0.0, lo=0.0, hi=1e4, unit="N"),
        friction_compensation_velocity=c.num("friction_compensation_velocity_mm_per_s", 2.0, scale=1e-3,
                                             lo=0.0, hi=1e4, lo_open=True, unit="mm/s"),
        gravity_compensation=c.flag("gravity_compensation", True),
        dynamics_compensation=c.choice("dynamics_compensation", DynamicsCompensation, DynamicsCompensation.NONE),
        interpolation=c.integer("interpolation", 1, lo=1, hi=64),
        ar_coefficients=ar_t,
        interpolation_variant=c.choice("interpolation_variant", Variant, DEFAULT_VARIANT),
        predictor=predictor,
        ar_order=ar_order,
        ar_window=ar_window,
    )
    c.done()

    e = _Reader(data.get("environment", {}), f"{where}: environment")
    top.used.add("environment")
    env = Environment(
        kind=e.choice("kind", EnvKind, EnvKind.FREE),
        stiffness=e.vec("stiffness_N_per_mm", (0.0,) * 3, scale=1e3, lo=0.0, hi=1e9, unit="N/mm"),
        damping=e.vec("damping_Ns_per_m", (0.0,) * 3, lo=-1e9, hi=1e9, unit="N·s/m"),
        anchor=e.vec("anchor_mm", (0.0,) * 3, scale=1e-3, lo=-1e3, hi=1e3, unit="mm"),
        half_size=e.vec("half_size_mm", (10.0,) * 3, scale=1e-3, lo=0.0, hi=1e3, unit="mm"),
        wall_stiffness=e.num("wall_stiffness_N_per_mm", 25.0, scale=1e3, lo=0.0, hi=1e9, unit="N/mm"),
        wall_damping=e.num("wall_damping_Ns_per_m", 0.0, lo=-1e9, hi=1e9, unit="N·s/m"),
        box_mode=e.choice("box_mode", BoxMode, BoxMode.INSIDE),
        force_amplitude=e.vec("force_amplitude_N", (0.0,) * 3, lo=-1e6, hi=1e6, unit="N"),
        force_frequency=e.num("force_frequency_Hz", 1.0, lo=0.0, hi=1e5, unit="Hz"),
        force_phase=e.vec("force_phase_deg", (0.0,) * 3, scale=math.pi / 180.0, lo=-360.0, hi=360.0, unit="deg"),
    )
    e.done()

    o = _Reader(data.get("operator", {}), f"{where}: operator")
    top.used.add("operator")
    kind = o.choice("kind", OperatorKind, OperatorKind.MASS_SPRING_DAMPER)
    if kind == OperatorKind.FORCE_EQ2:  # seed 001 eq 2
        operator = Operator.eq2(
            k_r=o.num("force_time_constant_s", 0.5, lo=0.0, hi=100.0, lo_open=True, unit="s"),
            k_f=o.num("force_decay", 5.0, lo=0.0, hi=1e6, lo_open=True, unit="(dimensionless)"),
            k_c=o.num("force_gain_N_per_m", 20.0, lo=0.0, hi=1e9, lo_open=True, unit="N/m"),
        )
    else:  # seed 000 eq 1
        operator = Operator(
            mass=o.num("mass_kg", 0.3, lo=0.0, hi=100.0, unit="kg"),
            damping=o.num("damping_Ns_per_m", 50.0, lo=0.0, hi=1e6, unit="N·s/m"),
            stiffness=o.num("stiffness_N_per_mm", 20.0, scale=1e3, lo=0.0, hi=1e7, unit="N/mm"),
        )
    o.done()

    m = _Reader(data.get("motion", {}), f"{where}: motion")
    top.used.add("motion")
    motion = Motion(
        amplitude=m.vec("amplitude_mm", (0.0,) * 3, scale=1e-3, lo=0.0, hi=500.0, unit="mm"),
        frequency=m.num("frequency_Hz", 1.0, lo=0.0, hi=1e4, unit="Hz"),
        phase=m.vec("phase_deg", (0.0,) * 3, scale=math.pi / 180.0, lo=-360.0, hi=360.0, unit="deg"),
        offset=m.vec("offset_mm", (0.0,) * 3, scale=1e-3, lo=-500.0, hi=500.0, unit="mm"),
        shape=m.choice("shape", MotionShape, MotionShape.SINE),
    )
    m.done()

    i = _Reader(data.get("initial", {}), f"{where}: initial")
    top.used.add("initial")
    initial = i.vec("offset_mm", (0.0,) * 3, scale=1e-3, lo=-500.0, hi=500.0, unit="mm")
    i.done()

    ef = _Reader(data.get("effects", {}), f"{where}: effects")
    top.used.add("effects")
    effects = {eff for eff in Effect if ef.flag(eff.value, eff in DEFAULT_EFFECTS)}
    delay = ef.num("time_delay_ms", 0.0, scale=1e-3, lo=0.0, hi=1e4, unit="ms")
    friction_location = ef.choice("friction_location", FrictionLocation, FrictionLocation.SLIDERS)
    ef.done()

    s = _Reader(data.get("simulation", {}), f"{where}: simulation")
    top.used.add("simulation")
    substeps = s.integer("substeps", 0, lo=0, hi=10000)
    locked = s.flag("output_locked", False)
    criterion = s.choice("stability", StabilityCriterion, StabilityCriterion.DRIVEN)
    axis = s.axis("measure_axis", 0)
    sw = s._get("sweep_factors")
    if sw is None:
        sweep: tuple[float, ...] = ()
    elif (isinstance(sw, list) and 2 <= len(sw) <= 20 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and 0.01 <= x <= 100 for x in sw)):
        sweep = tuple(sorted(float(x) for x in sw))
    else:
        raise InvalidInput(f"{where}: simulation.sweep_factors = {short(sw)} must be a list of 2 to 20 numbers in "
                           "[0.01, 100] (multiples of the frequency-domain bandwidth)")
    sweep_periods = s.integer("sweep_periods", 3, lo=2, hi=1000)
    s.done()

    z = _Reader(data.get("zwidth", {}), f"{where}: zwidth")
    top.used.add("zwidth")
    zw = ZWidthSettings(
        axis=z.axis("axis", 0),
        stiffness_range=z.vec("stiffness_N_per_mm", (1.0, 100.0), n=2, scale=1e3, lo=0.0, hi=1e9, unit="N/mm"),
        damping_range=z.vec("damping_Ns_per_m", (0.0, 2000.0), n=2, lo=-1e9, hi=1e9, unit="N·s/m"),
        points=z.integer("points", 20, lo=2, hi=1000),
    )
    z.done()

    io = _Reader(data.get("ioic", {}), f"{where}: ioic")
    top.used.add("ioic")
    m0 = io.num("initial_mass_kg", 5.0, lo=0.0, hi=1e6, lo_open=True, unit="kg")
    b0 = io.num("initial_damping_Ns_per_m", 20.0, lo=0.0, hi=1e9, unit="N·s/m")
    k0 = io.num("initial_stiffness_N_per_m", 50.0, lo=0.0, hi=1e9, unit="N/m")
    noise_seed = io._get("noise_seed")
    if noise_seed is not None and (isinstance(noise_seed, bool) or not isinstance(noise_seed, int)
                                   or not 0 <= noise_seed < 2**32):
        raise InvalidInput(f"{where}: ioic.noise_seed = {short(noise_seed)} must be a whole number: allowed "
                           "0 ≤ noise_seed < 2^32 (absent: eq 28's phases as printed)")
    ioic = IoicSettings(
        strategy=io.choice("strategy", IoicStrategy, IoicStrategy.IOIC),
        axis=io.axis("axis", 0),
        state_weights=tuple(io.vec("state_weights", (1.0, 1.0, 1.0), lo=0.0, hi=1e12,
                                   unit="(Q of eq 6, SI: 1/m², s²/m², 1/N²)")),
        input_weight=io.num("input_weight", 0.01, lo=0.0, hi=1e12, lo_open=True, unit="(R of eq 6, s⁴/m²)"),
        initial_gain=(k0 / m0, b0 / m0, 1.0 / m0),
        learn_time=io.num("learn_s", 0.5, lo=0.0, hi=60.0, lo_open=True, unit="s"),
        intervals=io.integer("intervals", 50, lo=1, hi=100000),
        switch_time=io.num("switch_s", 0.5, lo=0.0, hi=60.0, lo_open=True, unit="s"),
        exploration=io.flag("exploration", True),
        noise_seed=-1 if noise_seed is None else noise_seed,
        tolerance=io.num("tolerance", 1e-8, lo=0.0, hi=1.0, lo_open=True, unit="(‖P_k − P_k−1‖_F)"),
        tracking_stiffness=io.num("tracking_stiffness_N_per_mm", 2.0, scale=1e3, lo=0.0, hi=1e6, lo_open=True,
                                  unit="N/mm"),
        tracking_damping=io.num("tracking_damping_Ns_per_m", 40.0, lo=0.0, hi=1e6, unit="N·s/m"),
    )
    io.done()

    nt = _Reader(data.get("ntsmtc", {}), f"{where}: ntsmtc")
    top.used.add("ntsmtc")
    a_exp, b_exp = nt.integer("a", 5, lo=1, hi=99), nt.integer("b", 3, lo=1, hi=99)
    if not (a_exp % 2 == 1 and b_exp % 2 == 1 and 0.5 < b_exp / a_exp < 1.0):
        raise InvalidInput(f"{where}: ntsmtc.a = {a_exp}, ntsmtc.b = {b_exp} must be odd with 1/2 < b/a < 1 "
                           "(seed 001 eq 14)")
    ntsmtc = NtsmtcSettings(
        lambda1=tuple(nt.vec("lambda1_per_s", (3.0,) * 3, lo=0.0, hi=1e6, unit="1/s")),
        lambda2=tuple(nt.vec("lambda2_per_s", (3.0,) * 3, lo=0.0, hi=1e6, unit="1/s")),
        a=a_exp, b=b_exp,
        mu=nt.num("mu_rad", 0.005, lo=0.0, hi=1.0, lo_open=True, unit="rad"),
        beta=tuple(nt.vec("beta_per_s", (0.5, 1.0, 1.0), lo=0.0, hi=1e6, unit="1/s")),
        eta=nt.num("eta_rad_per_s2", 1.5, lo=0.0, hi=1e6, lo_open=True, unit="rad/s²"),
        theta=nt.num("theta_rad_per_s", 0.05, lo=0.0, hi=1e3, lo_open=True, unit="rad/s"),
    )
    nt.done()
    report = None
    if "report" in data:
        r = _Reader(data["report"], f"{where}: report")
        quantity = r.choice("quantity", PaperQuantity, None)
        if quantity is None:
            allowed = ", ".join(q.value for q in PaperQuantity)
            raise InvalidInput(f"{where}: report.quantity is missing: allowed {allowed}")
        axes_key = r._get("axes")
        if axes_key is None:
            axes: tuple[int, ...] = (axis,)
        elif (isinstance(axes_key, str) and 1 <= len(axes_key) <= 2 and all(ch in _AXES for ch in axes_key)
              and len(set(axes_key)) == len(axes_key)):
            axes = tuple(_AXES[ch] for ch in axes_key)
        else:
            raise InvalidInput(f"{where}: report.axes = {short(axes_key)} must name one or two different axes: "
                               "allowed \"x\", \"y\", \"z\", \"xy\", \"xz\", \"yz\"")
        if quantity == PaperQuantity.FORCE_ERROR_PLANE_RMS and len(axes) != 2:
            raise InvalidInput(f"{where}: report.axes = {short(axes_key)} must name a plane (two axes) for "
                               f"quantity = \"{quantity.value}\"")
        if quantity != PaperQuantity.FORCE_ERROR_PLANE_RMS and len(axes) != 1:
            raise InvalidInput(f"{where}: report.axes = {short(axes_key)} must name one axis for "
                               f"quantity = \"{quantity.value}\"")
        source = r._get("source") or ""
        if not isinstance(source, str):
            raise InvalidInput(f"{where}: report.source = {short(source)} must be a string")
        unit = "%" if quantity == PaperQuantity.STIFFNESS_ERROR_PCT else "N"
        value_key = "paper_value_pct" if unit == "%" else "paper_value_N"
        value = r._get(value_key)
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                  or not math.isfinite(value) or value < 0):
            raise InvalidInput(f"{where}: report.{value_key} = {short(value)} must be a finite number ≥ 0 {unit}")
        listed = r._get("assumptions")
        assumed = () if listed is None else parse_assumptions(listed, f"{where}: report.assumptions")
        r.done()
        top.used.add("report")
        report = PaperReport(quantity=quantity, axes=axes, value=None if value is None else float(value),
                             source=source, assumptions=assumed)
    top.done()

    ioic_mode = controller.mode == FirmwareMode.IOIC
    if ioic_mode != (operator.kind == OperatorKind.FORCE_EQ2):
        raise InvalidInput(f"{where}: operator.kind = {operator.kind.value!r} with controller.mode = "
                           f"{controller.mode.value!r}: the eq-2 operator (kind = \"force_eq2\") goes with "
                           "controller.mode = \"ioic\" and only with it")
    if not ioic_mode:
        for table in ("ioic", "ntsmtc"):
            if table in data:
                raise InvalidInput(f"{where}: [{table}] is read only with controller.mode = \"ioic\"")
        if motion.shape != MotionShape.SINE:
            raise InvalidInput(f"{where}: motion.shape = {motion.shape.value!r} drives the eq-2 operator only: allowed "
                               "\"sine\" with controller.mode = \"impedance\"")
    else:
        if Effect.OPERATOR not in effects:
            raise InvalidInput(f"{where}: effects.operator = false: controller.mode = \"ioic\" learns from the "
                               "operator's force (seed 001 eq 2)")
        if device != "master" and "ntsmtc" in data:
            raise InvalidInput(f"{where}: [ntsmtc] is the master's inner loop; the 3-PRRR's inner loop is its SEA "
                               "force loop (controller.force_gain)")
        if device == "master" and any(k in data.get("ioic", {}) for k in ("tracking_stiffness_N_per_mm",
                                                                         "tracking_damping_Ns_per_m")):
            raise InvalidInput(f"{where}: ioic.tracking_* set the 3-PRRR's Cartesian tracking; the master tracks "
                               "x_r with NTSMTC ([ntsmtc])")
        if ioic.learn_time / ioic.intervals < controller.period * (1 - 1e-9):
            raise InvalidInput(f"{where}: ioic.intervals = {ioic.intervals} gives intervals of "
                               f"{ioic.learn_time / ioic.intervals * 1e3:g} ms, shorter than the controller period "
                               f"{controller.period * 1e3:g} ms")
        if motion.frequency <= 0.0:
            raise InvalidInput(f"{where}: motion.frequency_Hz = 0: the eq-2 operator's desired position x_d needs a "
                               "frequency > 0")

    if Effect.TIME_DELAY in effects:
        ticks = delay / controller.period
        if delay <= 0.0 or abs(ticks - round(ticks)) > 1e-6 * max(1.0, ticks):
            raise InvalidInput(f"{where}: effects.time_delay_ms = {delay * 1e3:g} must be a positive whole number of "
                               f"controller periods ({controller.period * 1e3:g} ms) when time_delay is on")
    if substeps and substeps % controller.interpolation:
        raise InvalidInput(f"{where}: simulation.substeps = {substeps} must be a multiple of "
                           f"controller.interpolation = {controller.interpolation}")
    if zw.stiffness_range[0] >= zw.stiffness_range[1] or zw.damping_range[0] > zw.damping_range[1]:
        raise InvalidInput(f"{where}: zwidth ranges must be increasing, got stiffness {zw.stiffness_range} N/m, "
                           f"damping {zw.damping_range} N·s/m")
    if env.kind == EnvKind.FREE and (any(env.stiffness) or any(env.damping)):
        raise InvalidInput(f"{where}: environment.kind = \"free\" renders zero impedance: remove stiffness_N_per_mm "
                           "and damping_Ns_per_m or use kind = \"spring\"")
    return Scene(name=name, description=description, duration=duration, controller=controller, environment=env,
                 operator=operator, motion=motion, initial_offset=initial, effects=frozenset(effects),
                 time_delay=delay if Effect.TIME_DELAY in effects else 0.0, substeps=substeps,
                 output_locked=locked, stability=criterion, measure_axis=axis, zwidth=zw, device=device,
                 backend=backend, sweep_factors=sweep, sweep_periods=sweep_periods, ioic=ioic, ntsmtc=ntsmtc,
                 friction_location=friction_location, report=report)


SCENES = "hapticopt.analysis.scenes"


def scene_names() -> list[str]:
    """Names of the bundled scenes."""
    return bundled.names(SCENES)


def load_scene(name_or_path: str | Path) -> Scene:
    """A bundled scene by name, or a scene TOML file by path."""
    found = bundled.read(SCENES, "scene", name_or_path)
    text, source = found.text, found.source
    data = tomlsafe.loads(text, source=source)
    return scene_from_dict(data, source=source)


# --------------------------------------------------------------------------------------- resolving
class Backend(StrEnum):
    LUMPED = "lumped"  # hapticopt.analysis.prrr.loop.lumped_plant: two-mass SEA per leg + constant M_e (eq 6, 7)
    MULTIBODY = "multibody"  # MuJoCo plant (issue 8)


#: backends that can be run (the multibody plant of issue 8 exists)
AVAILABLE_BACKENDS: frozenset[Backend] = frozenset({Backend.LUMPED, Backend.MULTIBODY})


@dataclass(frozen=True, kw_only=True)
class Resolution:
    """The effects actually simulated and the backend that simulates them."""

    effects: frozenset[Effect]
    backend: Backend
    reason: str
    notes: tuple[str, ...] = ()  # effects dropped because nothing they act on is present

    def effect_names(self) -> list[str]:
        return sorted(e.value for e in self.effects)


def multibody_need(scene: Scene) -> str | None:
    """Why ``scene`` needs the multibody plant (None: the lumped plant is exact for it)."""
    if scene.device == "master":
        return ("the surgical master: its serial/parallelogram chain has pose-dependent inertia, gravity and "
                "Jacobian, which only the multibody plant (hapticopt.design.master.mjcf) models")
    if Effect.LINK_DYNAMICS in scene.effects and Effect.GRAVITY in scene.effects:
        return ("link_dynamics and gravity are on: distributed link inertia and the links' weight at their own "
                "CoMs need the multibody plant")
    if Effect.LINK_DYNAMICS in scene.effects:
        return "link_dynamics is on: distributed link inertia needs the multibody plant"
    return None


def resolve(scene: Scene, *, available: frozenset[Backend] = AVAILABLE_BACKENDS,
            force: Backend | None = None) -> Resolution:
    """The resolved effect set and backend of ``scene``; raises :class:`InvalidInput` if none can run it.

    ``force`` (or the scene's own ``backend`` key; ``force`` wins) overrides the choice; forcing
    the lumped plant onto a scene that needs the multibody one is an error, never a silent run.
    """
    effects = set(scene.effects)
    notes: list[str] = []
    if scene.device == "handle":
        return _resolve_handle(scene, effects, force if force is not None else scene.backend)
    need = multibody_need(scene)
    force = force if force is not None else scene.backend
    if need is not None:
        if force == Backend.LUMPED:
            what = "the master" if scene.device == "master" else "link_dynamics"
            raise InvalidInput(f"scene {scene.name}: backend = lumped cannot simulate {what} ({need.split(':')[0]}); "
                               "use backend = multibody" + ("" if scene.device == "master"
                                                            else " or switch effects.link_dynamics off"))
        if Backend.MULTIBODY not in available:
            raise InvalidInput(f"scene {scene.name}: link_dynamics requires the multibody backend (not available); "
                               "switch effects.link_dynamics off to use the lumped plant")
        backend, reason = Backend.MULTIBODY, need
    else:
        backend = Backend.LUMPED
        reason = ("no effect needs the multibody backend: the lumped two-mass SEA model (seed 002 eq 6) with the "
                  "constant equivalent mass M_e (eq 7) is exact for the 3-PRRR's rigid translational dynamics")
        if force == Backend.MULTIBODY:
            backend = Backend.MULTIBODY
            reason = f"forced multibody (the resolver would pick lumped: {reason})"
    if Effect.MOTOR_DYNAMICS not in effects and Effect.VISCOUS_FRICTION in effects:
        effects.discard(Effect.VISCOUS_FRICTION)
        notes.append("viscous_friction dropped: it acts on the motor side, absent without motor_dynamics")
    if Effect.MOTOR_DYNAMICS not in effects and Effect.SEA_COMPLIANCE in effects:
        notes.append("motor_dynamics off: the spring force equals its reference (ideal force source)")
    if scene.device == "master":
        for eff, why in ((Effect.SEA_COMPLIANCE, "the master's capstan drives have no series spring"),
                         (Effect.LINK_DYNAMICS, "the master's links are always multibody")):
            if eff in effects:
                effects.discard(eff)
                notes.append(f"{eff.value} dropped: {why}")
    if scene.output_locked and Effect.OPERATOR in effects:
        effects.discard(Effect.OPERATOR)
        notes.append("operator dropped: the output sliders are locked")
    if scene.output_locked and Effect.COULOMB_FRICTION in effects:
        effects.discard(Effect.COULOMB_FRICTION)
        notes.append("coulomb_friction dropped: the output sliders are locked")
    if scene.output_locked and Effect.GRAVITY in effects:
        effects.discard(Effect.GRAVITY)
        notes.append("gravity dropped: the output sliders are locked")
    if scene.output_locked and Effect.MOTOR_DYNAMICS not in effects:
        raise InvalidInput(f"scene {scene.name}: simulation.output_locked = true needs motor_dynamics and "
                           "sea_compliance on (it tests the SEA force loop)")
    if scene.output_locked and Effect.SEA_COMPLIANCE not in effects:
        raise InvalidInput(f"scene {scene.name}: simulation.output_locked = true needs sea_compliance on")
    return Resolution(effects=frozenset(effects), backend=backend, reason=reason, notes=tuple(notes))


#: effects the handle's per-axis loop (``hapticopt.analysis.handle.closed_loop``) models
HANDLE_EFFECTS: frozenset[Effect] = frozenset({Effect.SAMPLING, Effect.OPERATOR, Effect.TIME_DELAY})


def _resolve_handle(scene: Scene, effects: set[Effect], force: Backend | None) -> Resolution:
    """Seed 000's handle: one lumped axis (mass, damping, the hand), always the lumped backend."""
    if force == Backend.MULTIBODY:
        raise InvalidInput(f"scene {scene.name}: backend = multibody cannot simulate the handle (it has no multibody "
                           "model); use backend = lumped or auto")
    if Effect.SAMPLING not in effects:
        raise InvalidInput(f"scene {scene.name}: effects.sampling = false is not simulated on the handle (its "
                           "zero-order hold is what the scenes test): switch it on")
    dropped = sorted(e.value for e in effects - HANDLE_EFFECTS)
    notes = [f"not modelled on the handle, dropped: {', '.join(dropped)}"] if dropped else []
    return Resolution(effects=frozenset(effects & HANDLE_EFFECTS), backend=Backend.LUMPED,
                      reason=("seed 000's handle, one axis: tip mass I/R² (+ hand), damping B_m/R², exact "
                              "zero-order hold per output sample (analysis.handle.closed_loop)"),
                      notes=tuple(notes))
